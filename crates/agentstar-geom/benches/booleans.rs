//! Booleans side by side: the BSP kernel (`csg::Kernel::Bsp`) and the robust one
//! (`csg::Kernel::Robust`: `boolmesh`, a pure-Rust port of Manifold's kernel) on the cases
//! agents met (issue 16): speed (median wall time of whole chains), whether the result is a
//! closed solid, its volume against the exact or the other kernel's value, and failures.
//!
//! Run with `cargo bench -p agentstar-geom --bench booleans`. `AGENTSTAR_BENCH_REPS` sets
//! the repetitions per case (default 3), `AGENTSTAR_BENCH_DEADLINE_S` the kernels'
//! deadline per chain (default 60 s, as a scene would stop it), `AGENTSTAR_BENCH_ONLY` a
//! substring of the case names to run.

use agentstar_geom::csg::{self, Budget, Kernel, Op};
use agentstar_geom::primitives::{bevelled_box, cuboid, cylinder, uv_sphere};
use agentstar_geom::{TriMesh, Vector3};
use std::time::{Duration, Instant};

/// A chain `start op₁ m₁ op₂ m₂ …` evaluated left to right, as a scene script would.
struct Case {
    name: &'static str,
    start: TriMesh,
    steps: Vec<(Op, TriMesh)>,
    /// The exact volume where it is known in closed form.
    exact_volume: Option<f64>,
}

fn cases() -> Vec<Case> {
    let mut out = Vec::new();

    // A bevelled plate united with a bevelled body standing on it (overlapping by 1 cm).
    let plate = bevelled_box(1.0, 0.6, 0.05, 0.01, 4).expect("plate");
    let body = bevelled_box(0.6, 0.4, 0.3, 0.03, 4)
        .expect("body")
        .translated(Vector3::new(0.0, 0.0, 0.025 + 0.15 - 0.01));
    out.push(Case {
        name: "bevelled plate + bevelled body",
        start: plate,
        steps: vec![(Op::Union, body)],
        exact_volume: None,
    });

    // A keyboard: a slab and 13 × 5 key boxes, united one by one (`slab = slab + key`).
    let slab_size = (0.45, 0.16, 0.02);
    let keys = |sink: f64, bevel: f64| -> Vec<(Op, TriMesh)> {
        let mut v = Vec::new();
        for row in 0..5 {
            for col in 0..13 {
                let key = if bevel > 0.0 {
                    bevelled_box(0.028, 0.024, 0.012, bevel, 2).expect("key")
                } else {
                    cuboid(0.028, 0.024, 0.012).expect("key")
                };
                let x = -0.2 + col as f64 * (0.4 / 12.0);
                let y = -0.06 + row as f64 * 0.03;
                let z = slab_size.2 / 2.0 + 0.006 - sink;
                v.push((Op::Union, key.translated(Vector3::new(x, y, z))));
            }
        }
        v
    };
    let slab = cuboid(slab_size.0, slab_size.1, slab_size.2).expect("slab");
    let slab_volume = slab_size.0 * slab_size.1 * slab_size.2;
    out.push(Case {
        name: "slab + 65 keys (flush)",
        start: slab.clone(),
        steps: keys(0.0, 0.0),
        exact_volume: Some(slab_volume + 65.0 * 0.028 * 0.024 * 0.012),
    });
    out.push(Case {
        name: "slab + 65 keys (sunk 2 mm)",
        start: slab.clone(),
        steps: keys(0.002, 0.0),
        exact_volume: Some(slab_volume + 65.0 * 0.028 * 0.024 * 0.010),
    });
    out.push(Case {
        name: "bevelled slab + 65 bevelled keys",
        start: bevelled_box(slab_size.0, slab_size.1, slab_size.2, 0.004, 3).expect("slab"),
        steps: keys(0.002, 0.002),
        exact_volume: None,
    });

    // A thick shell: a fine sphere minus a slightly shifted fine sphere.
    out.push(Case {
        name: "sphere(1,200,100) - sphere(0.9,200,100) shifted",
        start: uv_sphere(1.0, 200, 100).expect("sphere"),
        steps: vec![(
            Op::Difference,
            uv_sphere(0.9, 200, 100)
                .expect("sphere")
                .translated(Vector3::new(0.05, 0.0, 0.0)),
        )],
        exact_volume: None,
    });

    // A chain of 50 differences: a plate drilled with 50 holes (10 × 5).
    let mut holes = Vec::new();
    for i in 0..10 {
        for j in 0..5 {
            let h = cylinder(0.02, 0.2, 32)
                .expect("hole")
                .translated(Vector3::new(
                    -0.45 + i as f64 * 0.1,
                    -0.2 + j as f64 * 0.1,
                    0.0,
                ));
            holes.push((Op::Difference, h));
        }
    }
    let ngon = 0.02 * 0.02 * 16.0 * (2.0 * std::f64::consts::PI / 32.0).sin();
    out.push(Case {
        name: "plate - 50 holes (chain)",
        start: cuboid(1.0, 0.5, 0.05).expect("plate"),
        steps: holes,
        exact_volume: Some(1.0 * 0.5 * 0.05 - 50.0 * ngon * 0.05),
    });
    out
}

struct Outcome {
    seconds: f64,
    result: Result<TriMesh, String>,
}

/// One chain through `csg::boolean` with `kernel` (the robust kernel as shipped: its worker
/// thread, the conversions and the closed-result check included).
fn run(case: &Case, kernel: Kernel, deadline: Duration) -> Outcome {
    let t = Instant::now();
    let budget = Budget {
        deadline: Some(t + deadline),
        ..Budget::default()
    };
    let mut acc = case.start.clone();
    let mut result = Ok(());
    for (k, (op, m)) in case.steps.iter().enumerate() {
        match csg::boolean(&acc, m, *op, kernel, budget) {
            Ok(next) => acc = next,
            Err(e) => {
                result = Err(format!("step {}: {e}", k + 1));
                break;
            }
        }
    }
    Outcome {
        seconds: t.elapsed().as_secs_f64(),
        result: result.map(|()| acc),
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

struct Summary {
    median_s: f64,
    text: String,
    volume: Option<f64>,
}

fn summarise(runs: Vec<Outcome>) -> Summary {
    let mut times: Vec<f64> = runs.iter().map(|o| o.seconds).collect();
    let median_s = median(&mut times);
    match &runs[0].result {
        Ok(m) => Summary {
            median_s,
            text: format!(
                "{} triangles, {}",
                m.triangles.len(),
                if m.is_watertight() {
                    "closed"
                } else {
                    "NOT closed"
                }
            ),
            volume: Some(m.volume()),
        },
        Err(e) => Summary {
            median_s,
            text: format!("failed: {e}"),
            volume: None,
        },
    }
}

fn env_num<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let reps: usize = env_num("AGENTSTAR_BENCH_REPS", 3).max(1);
    let deadline = Duration::from_secs_f64(env_num("AGENTSTAR_BENCH_DEADLINE_S", 60.0));
    let only = std::env::var("AGENTSTAR_BENCH_ONLY").unwrap_or_default();
    println!(
        "| case | BSP median (s) | BSP result | robust median (s) | robust result | BSP / robust | volume BSP | volume robust | exact |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for case in cases() {
        if !case.name.contains(&only) {
            continue;
        }
        let bsp = summarise(
            (0..reps)
                .map(|_| run(&case, Kernel::Bsp, deadline))
                .collect(),
        );
        let bm = summarise(
            (0..reps)
                .map(|_| run(&case, Kernel::Robust, deadline))
                .collect(),
        );
        let vol = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.6}"));
        // A ratio of times only where both finished the whole chain.
        let ratio = if bsp.volume.is_some() && bm.volume.is_some() {
            format!("{:.1}", bsp.median_s / bm.median_s.max(1e-9))
        } else {
            "—".to_string()
        };
        println!(
            "| {} | {:.4} | {} | {:.4} | {} | {} | {} | {} | {} |",
            case.name,
            bsp.median_s,
            bsp.text,
            bm.median_s,
            bm.text,
            ratio,
            vol(bsp.volume),
            vol(bm.volume),
            vol(case.exact_volume),
        );
    }
}

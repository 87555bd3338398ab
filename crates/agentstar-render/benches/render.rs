//! The renderer benchmark of `shared/bench/README.md`: one evaluation = set a pose, render
//! the silhouette of `mesh5k.obj`, compute IoU against a fixed target. Prints medians.
//!
//! Run with `cargo bench -p agentstar-render`. Set `AGENTSTAR_BENCH_MESH` to the OBJ path
//! when `../shared/bench/mesh5k.obj` is not beside the repository.

use agentstar_geom::pose::Similarity;
use agentstar_geom::{
    KinematicTree, Material, ObjectModel, Part, PinholeCamera, Point3, SurfaceAppearance, Texture,
    TriMesh, UnitQuaternion, Vector3,
};
use agentstar_render::scene::{fill_instances, InstanceBuilder};
use agentstar_render::{ScoreTarget, SilhouetteRenderer};
use std::time::Instant;

struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

fn load_obj(path: &std::path::Path) -> TriMesh {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let mut m = TriMesh::default();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let v: Vec<f64> = it.take(3).map(|s| s.parse().expect("number")).collect();
                m.positions.push(Point3::new(v[0], v[1], v[2]));
            }
            Some("f") => {
                let idx: Vec<u32> = it
                    .map(|s| {
                        s.split('/')
                            .next()
                            .expect("index")
                            .parse::<u32>()
                            .expect("index")
                            - 1
                    })
                    .collect();
                for k in 1..idx.len() - 1 {
                    m.triangles.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    m
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn setup(
    name: &str,
    model: &ObjectModel,
    camera: PinholeCamera,
    z_range: (f64, f64),
    target_z: f64,
) {
    let q = nalgebra::Quaternion::new(0.9, 0.3, -0.2, 0.25);
    let target_pose = Similarity {
        scale: 1.0,
        rotation: UnitQuaternion::from_quaternion(q),
        translation: Vector3::new(0.05, -0.03, target_z),
    };
    let mut renderer = SilhouetteRenderer::new(camera.width, camera.height);
    let mut instances = Vec::new();
    fill_instances(model, &[], &target_pose, &mut instances);
    let target =
        ScoreTarget::new(renderer.render(&camera, &instances).clone(), None).expect("target");
    let mut rng = Rng(2026);
    let poses = random_poses(&mut rng, 1000, |rng| {
        Vector3::new(
            rng.uniform() * 0.6 - 0.3,
            rng.uniform() * 0.4 - 0.2,
            z_range.0 + rng.uniform() * (z_range.1 - z_range.0),
        )
    });
    let eval = |renderer: &mut SilhouetteRenderer,
                builder: &mut InstanceBuilder,
                instances: &mut Vec<_>,
                pose: &Similarity|
     -> f64 {
        builder.build(model, &[], pose, instances);
        target.gate(renderer.render(&camera, instances))
    };
    // Warm up, then time each evaluation in batches of 10 to stay above timer resolution.
    let mut builder = InstanceBuilder::default();
    let mut sink = 0.0;
    for p in &poses {
        sink += eval(&mut renderer, &mut builder, &mut instances, p);
    }
    let mut per_eval_us = Vec::new();
    for _round in 0..5 {
        for chunk in poses.chunks(10) {
            let t0 = Instant::now();
            for p in chunk {
                sink += eval(&mut renderer, &mut builder, &mut instances, p);
            }
            per_eval_us.push(t0.elapsed().as_secs_f64() * 1e6 / chunk.len() as f64);
        }
    }
    let med = median(&mut per_eval_us);
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let reps = 20;
    let t0 = Instant::now();
    std::thread::scope(|s| {
        for t in 0..threads {
            let poses = &poses;
            let eval = &eval;
            s.spawn(move || {
                let mut r = SilhouetteRenderer::new(camera.width, camera.height);
                let mut inst = Vec::new();
                let mut b = InstanceBuilder::default();
                let mut acc = 0.0;
                for _ in 0..reps {
                    for p in poses.iter().skip(t).step_by(threads) {
                        acc += eval(&mut r, &mut b, &mut inst, p);
                    }
                }
                acc
            });
        }
    });
    let all_rate = (reps * poses.len()) as f64 / t0.elapsed().as_secs_f64();
    println!(
        "{name}: {}x{}, target {} px: median {:.1} µs/eval on 1 thread ({:.0} evals/s); {:.0} evals/s on {threads} threads ({:.2}x)  [checksum {:.3}]",
        camera.width,
        camera.height,
        target.mask().count(),
        med,
        1e6 / med,
        all_rate,
        all_rate * med / 1e6,
        sink
    );
}

/// `n` poses of unit scale, each a uniformly random rotation (drawn first) at the
/// translation `translation` draws.
fn random_poses(
    rng: &mut Rng,
    n: usize,
    mut translation: impl FnMut(&mut Rng) -> Vector3,
) -> Vec<Similarity> {
    (0..n)
        .map(|_| {
            let q =
                nalgebra::Quaternion::new(rng.normal(), rng.normal(), rng.normal(), rng.normal());
            Similarity {
                scale: 1.0,
                rotation: UnitQuaternion::from_quaternion(q),
                translation: translation(rng),
            }
        })
        .collect()
}

/// One colour evaluation: the full render of the pose and the textured model shaded from
/// it (what every colour view and the appearance terms pay per image), at setup B's camera.
fn colour_setup(model: &ObjectModel, camera: PinholeCamera) {
    let mut rng = Rng(2027);
    let poses = random_poses(&mut rng, 100, |_| Vector3::new(0.0, 0.0, 1.2));
    let mut renderer = agentstar_render::FullRenderer::default();
    let mut instances = Vec::new();
    let mut builder = InstanceBuilder::default();
    let mut per_eval_us = Vec::new();
    let mut sink = 0u64;
    for round in 0..4 {
        for p in &poses {
            let t0 = Instant::now();
            builder.build(model, &[], p, &mut instances);
            let buffers = renderer.render(&camera, &instances);
            let img = agentstar_render::views::shade_model(
                model,
                &instances,
                &camera,
                buffers,
                agentstar_render::views::ShadeOptions::default(),
            );
            sink += u64::from(img.get_pixel(camera.width / 2, camera.height / 2)[0]);
            if round > 0 {
                per_eval_us.push(t0.elapsed().as_secs_f64() * 1e6);
            }
        }
    }
    println!(
        "colour (textured, setup B camera): median {:.0} µs per full render + textured shade  [checksum {sink}]",
        median(&mut per_eval_us)
    );
}

/// The mesh with a 256×256 texture over texture coordinates from its x and z.
fn textured(mesh: &TriMesh) -> Part {
    let rgb: Vec<u8> = (0..256u32 * 256)
        .flat_map(|k| {
            let (x, y) = (k % 256, k / 256);
            [x as u8, y as u8, ((x / 32 + y / 32) % 2 * 255) as u8]
        })
        .collect();
    let texture = std::sync::Arc::new(Texture::new("bench", 256, 256, rgb).expect("texture"));
    let b = mesh.bounds();
    let e = b.extent();
    let uv: Vec<[[f32; 2]; 3]> = mesh
        .triangles
        .iter()
        .map(|t| {
            t.map(|i| {
                let p = mesh.positions[i as usize];
                [
                    ((p.x - b.min.x) / e.x) as f32,
                    ((p.z - b.min.z) / e.z) as f32,
                ]
            })
        })
        .collect();
    let surface = SurfaceAppearance::new(
        vec![Material {
            name: "print".into(),
            color: [1.0; 3],
            texture: Some(texture),
        }],
        vec![0; mesh.triangles.len()],
        Some(uv),
        None,
    )
    .expect("surface");
    Part::new("mesh5k", mesh.clone(), [0.7; 3])
        .with_surface(std::sync::Arc::new(surface))
        .expect("part")
}

fn main() {
    let default =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/bench/mesh5k.obj");
    let path = std::env::var_os("AGENTSTAR_BENCH_MESH")
        .map(std::path::PathBuf::from)
        .unwrap_or(default);
    let mesh = load_obj(&path);
    println!(
        "mesh: {} vertices, {} triangles, watertight: {}",
        mesh.positions.len(),
        mesh.triangles.len(),
        mesh.is_watertight()
    );
    let textured_model = ObjectModel {
        tree: KinematicTree::rigid(1),
        parts: vec![textured(&mesh)],
    };
    let model = ObjectModel {
        tree: KinematicTree::rigid(1),
        parts: vec![Part::new("mesh5k", mesh, [0.7; 3])],
    };
    setup(
        "setup A",
        &model,
        PinholeCamera::new(300.0, 300.0, 160.0, 120.0, 320, 240).expect("camera"),
        (2.5, 3.5),
        3.0,
    );
    setup(
        "setup B",
        &model,
        PinholeCamera::new(600.0, 600.0, 320.0, 240.0, 640, 480).expect("camera"),
        (1.0, 1.4),
        1.2,
    );
    colour_setup(
        &textured_model,
        PinholeCamera::new(600.0, 600.0, 320.0, 240.0, 640, 480).expect("camera"),
    );
}

//! How wide the boundary band must be: on the hard suite's captures (640×480, 2 px
//! segmenter-like mask noise, hands), the visible IoU and the band IoU of the true poses and
//! of the true poses rotated by a small angle about the object's pivot, for several band
//! widths. Prints one table row per (band, error) with the share of frames at or over the
//! 0.98 gate. `cargo run --release -p agentstar-bench --example band_calibration [objects]`.

use agentstar_bench::suite::{hard_sequence, HARD_OBJECTS};
use agentstar_render::{PosedModel, ScoreTarget, SilhouetteRenderer};
use agentstar_track::update::{apply_object_rotation, rotation_vector_deg};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let objects: Vec<&str> = if args.is_empty() {
        HARD_OBJECTS.to_vec()
    } else {
        args.iter().map(String::as_str).collect()
    };
    let bands = [0.0, 1.0, 1.5, 2.0, 2.5, 3.0];
    let errors_deg = [0.0, 1.0, 2.0, 3.0, 5.0];
    // Six axes in the camera frame: ±x, ±y, ±z, and the diagonals' mean is in between.
    let axes = [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.577, 0.577, 0.577],
        [-0.577, 0.577, 0.577],
        [0.577, -0.577, 0.577],
    ];
    let gates = [0.98, 0.99, 0.995];
    // (gate, band, error) → (frames at the gate, frames)
    let mut pass = vec![vec![vec![(0usize, 0usize); errors_deg.len()]; bands.len()]; gates.len()];
    let mut worst_true = vec![1.0f64; bands.len()];
    for (i, o) in HARD_OBJECTS.iter().enumerate() {
        if !objects.contains(o) {
            continue;
        }
        let spec = hard_sequence(o, 300 + i as u64);
        let cap = agentstar_synth::synthesize(&spec.synth).expect("synthesis");
        let cam = cap.camera;
        let mut r = SilhouetteRenderer::new(cam.width, cam.height);
        for f in &cap.frames {
            let pivot = cap.model.pivot(&f.states);
            for (b, &band) in bands.iter().enumerate() {
                let t = ScoreTarget::new(f.mask.clone(), f.hand.clone())
                    .expect("target")
                    .with_band(band);
                for (e, &err) in errors_deg.iter().enumerate() {
                    let poses: Vec<_> = if err == 0.0 {
                        vec![f.camera_from_object]
                    } else {
                        axes.iter()
                            .map(|a| {
                                let q = rotation_vector_deg([a[0] * err, a[1] * err, a[2] * err]);
                                apply_object_rotation(&f.camera_from_object, cap.scale, &pivot, &q)
                            })
                            .collect()
                    };
                    for p in poses {
                        let posed =
                            PosedModel::new(&cap.model, &f.states, &p.with_scale(cap.scale));
                        let s = t.score(r.render(&cam, &posed.instances));
                        let g = s.iou_band.or(s.iou_visible).unwrap_or(0.0);
                        if err == 0.0 {
                            worst_true[b] = worst_true[b].min(g);
                        }
                        for (k, gate) in gates.iter().enumerate() {
                            pass[k][b][e].1 += 1;
                            pass[k][b][e].0 += usize::from(g >= *gate);
                        }
                    }
                }
            }
        }
        eprintln!("{o}: {} frames", cap.frames.len());
    }
    for (k, gate) in gates.iter().enumerate() {
        println!("\nGate {gate}:\n");
        println!(
            "| band (px) | worst true pose | {} |",
            errors_deg.map(|e| format!("≥ {gate} at {e}°")).join(" | ")
        );
        println!("|---|---|{}", "---|".repeat(errors_deg.len()));
        for (b, &band) in bands.iter().enumerate() {
            let cells: Vec<String> = pass[k][b]
                .iter()
                .map(|(p, n)| format!("{:.0}% ({p}/{n})", 100.0 * *p as f64 / (*n).max(1) as f64))
                .collect();
            println!("| {band} | {:.4} | {} |", worst_true[b], cells.join(" | "));
        }
    }
}

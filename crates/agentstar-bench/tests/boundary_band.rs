//! The boundary band on the hard suite's captures: true poses on masks with a segmenter's
//! 2 px boundary noise fail the 0.98 gate without the band and pass it with the band, which
//! still ranks the true pose above the same pose turned by 3°. (It does not fail every 3°
//! error: on these captures 70% of 3° turns still pass at 2 px, see docs/scoring.md.)

use agentstar_bench::suite::hard_sequence;
use agentstar_render::{PosedModel, ScoreTarget, SilhouetteRenderer, DEFAULT_BAND_PX};
use agentstar_track::update::{apply_object_rotation, rotation_vector_deg};

const GATE: f64 = 0.98;

#[test]
fn true_poses_on_noisy_masks_pass_the_band_gate_and_outrank_a_3_degree_error() {
    // Two objects of the hard suite, six keyframes each at 640×480 with hands.
    let mut true_visible = Vec::new();
    let mut true_band = Vec::new();
    let mut turned_band = Vec::new();
    for (object, seed) in [("kettle", 303), ("drawerbox", 305)] {
        let mut spec = hard_sequence(object, seed);
        spec.synth.frames = 6;
        let cap = agentstar_synth::synthesize(&spec.synth).expect("synthesis");
        assert_eq!(spec.synth.mask_noise_px, 2.0);
        let cam = cap.camera;
        let mut r = SilhouetteRenderer::new(cam.width, cam.height);
        for f in &cap.frames {
            let t = ScoreTarget::new(f.mask.clone(), f.hand.clone())
                .expect("target")
                .with_band(DEFAULT_BAND_PX);
            let mut score = |pose: &agentstar_geom::pose::ObjectPose| {
                let posed = PosedModel::new(&cap.model, &f.states, &pose.with_scale(cap.scale));
                t.score(r.render(&cam, &posed.instances))
            };
            let s = score(&f.camera_from_object);
            true_visible.push(s.iou_visible.expect("visible"));
            true_band.push(s.iou_band.expect("band"));
            // 3° about each camera axis through the object's pivot.
            let pivot = cap.model.pivot(&f.states);
            let mut turns = Vec::new();
            for axis in [[3.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 3.0]] {
                let turned = apply_object_rotation(
                    &f.camera_from_object,
                    cap.scale,
                    &pivot,
                    &rotation_vector_deg(axis),
                );
                turns.push(score(&turned).iou_band.expect("band"));
            }
            turned_band.push((*true_band.last().expect("true"), turns));
        }
    }
    // Without the band the noise alone fails true poses; with it every true pose passes.
    assert!(
        true_visible.iter().any(|&v| v < GATE),
        "visible IoU of the true poses: {true_visible:?}"
    );
    assert!(
        true_band.iter().all(|&v| v >= GATE),
        "band IoU of the true poses: {true_band:?}"
    );
    // On every frame the true pose scores a higher band IoU than its 3° turns on average,
    // and than the worst of them by a clear margin.
    for (truth, turns) in &turned_band {
        let mean = turns.iter().sum::<f64>() / turns.len() as f64;
        let worst = turns.iter().copied().fold(1.0, f64::min);
        assert!(*truth > mean, "true {truth} against 3° turns {turns:?}");
        assert!(
            *truth > worst + 0.005,
            "true {truth} against 3° turns {turns:?}"
        );
    }
}

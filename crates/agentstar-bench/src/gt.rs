//! Ground truth (`gt.json`, loaded or built in memory) in the evaluator's form.

use crate::BenchError;
use agentstar_data::gt::GroundTruth;
use agentstar_eval::sequence::{GtJoint, GtSequence};
use agentstar_geom::Vector3;

/// The ground truth of `frames` (frame names, in order) as a [`GtSequence`]. Fails, naming
/// the file, when a frame lacks a part's pose or a joint's state.
pub fn gt_sequence(gt: &GroundTruth, frames: &[String]) -> Result<GtSequence, BenchError> {
    let bad = |m: String| BenchError::GroundTruth(format!("{}: {m}", gt.path.display()));
    let names: Vec<String> = gt.meshes.keys().cloned().collect();
    let index = |n: &str| {
        names
            .iter()
            .position(|x| x == n)
            .ok_or_else(|| bad(format!("unknown part `{n}`")))
    };
    let mut poses = Vec::with_capacity(frames.len());
    for f in frames {
        let mut row = Vec::with_capacity(names.len());
        for n in &names {
            row.push(
                gt.pose(f, n)
                    .ok_or_else(|| bad(format!("frame `{f}` has no pose for part `{n}`")))?,
            );
        }
        poses.push(row);
    }
    let joints = gt
        .file
        .joints
        .iter()
        .map(|j| {
            let states = frames
                .iter()
                .map(|f| {
                    j.states.get(f).copied().ok_or_else(|| {
                        bad(format!("joint `{}` has no state for frame `{f}`", j.name))
                    })
                })
                .collect::<Result<Vec<f64>, _>>()?;
            Ok(GtJoint {
                name: j.name.clone(),
                revolute: j.kind != "prismatic",
                parent: index(&j.parent)?,
                child: index(&j.child)?,
                axis: Vector3::from(j.axis),
                origin: Vector3::from(j.origin),
                states,
            })
        })
        .collect::<Result<Vec<_>, BenchError>>()?;
    Ok(GtSequence {
        base_part: index(&gt.file.base_part)?,
        meshes: gt.meshes.values().cloned().collect(),
        part_names: names,
        poses,
        joints,
    })
}

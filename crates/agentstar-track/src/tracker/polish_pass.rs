//! The last polish: every keyframe's pose, once the passes over the sequence have chosen its
//! basin, polished in a box a few degrees wide ([`crate::hypotheses::polish_last`]).

use super::*;
use crate::hypotheses::polish_last;

/// Seeds of the last polish: frame `i`'s is the tracker's seed plus this times `i + 1`.
const POLISH_SEED_STRIDE: u64 = 3_000_017;

/// Every frame but the `fixed` ones polished where it scores higher
/// ([`crate::hypotheses::polish_last`] in the tracker's polish window, the round outline's
/// turn held): the frames whose pose moved, and by how much at most (degrees of rotation).
///
/// Why a pass of its own (2026-12-06): the refinements the tracker runs stop on the
/// silhouette score's ridges 1–6° from the best pose (the 20-keyframe benchmark's worst
/// frame 2.2° and 3.1° of joint off), and ending every refinement with CMA-ES instead took
/// them to about 1° but changed which basins the later passes chose (the hard suite lost 6
/// of 21 sequences). Run last, the same search polishes and chooses nothing.
pub(super) fn polish_pass(
    s: &Searcher<'_>,
    frames: &[TrackFrame<'_>],
    (poses, scores): (&mut [GenPose], &mut [f64]),
    fixed: &[bool],
    log: &mut Log<'_>,
) -> Result<(), TrackError> {
    let window = LocalWindow::polish();
    let polished: Vec<Option<(GenPose, f64)>> = poses
        .par_iter()
        .enumerate()
        .map(|(i, pose)| {
            if fixed.get(i).copied().unwrap_or(false) {
                return Ok(None);
            }
            let problem = s.problem_of(&frames[i], pose);
            let seed = s.cfg.seed + POLISH_SEED_STRIDE * (i as u64 + 1);
            let (p, score, n) = polish_last(&problem, pose, &window, seed)?;
            s.evals.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
            Ok(Some((p, score)))
        })
        .collect::<Result<_, TrackError>>()?;
    let mut moved = 0;
    let mut most_deg: f64 = 0.0;
    for (i, r) in polished.into_iter().enumerate() {
        let Some((p, score)) = r else { continue };
        if p != poses[i] {
            moved += 1;
            most_deg = most_deg.max(
                poses[i]
                    .pose
                    .rotation
                    .angle_to(&p.pose.rotation)
                    .to_degrees(),
            );
        }
        poses[i] = p;
        scores[i] = score;
    }
    log.push(format!(
        "last polish: {moved} of {} frame(s) moved, at most {most_deg:.2}°",
        poses.len()
    ));
    Ok(())
}

//! The frames of a video import that SfM sees: the keyframes and the frames between them,
//! each with its object and hand masks.

use crate::{FrameRole, SfmError, SfmFrame};
use agentstar_data::images::load_mask;
use agentstar_import::video::{stem, FrameFiles, MaskFolder};
use std::path::Path;

/// The indices SfM uses: every frame from the first keyframe to the last, thinned evenly to
/// at most `max_frames` (never below the keyframes, which are always kept).
pub fn select_frames(keyframes: &[usize], max_frames: usize) -> Vec<usize> {
    let (Some(&first), Some(&last)) = (keyframes.first(), keyframes.last()) else {
        return vec![];
    };
    let span = last - first + 1;
    let room = max_frames.saturating_sub(keyframes.len());
    let between = span - keyframes.len();
    let stride = if between <= room {
        1
    } else {
        between.div_ceil(room.max(1)).max(1) + 1
    };
    let mut out: Vec<usize> = (first..=last)
        .filter(|i| keyframes.binary_search(i).is_ok() || (i - first) % stride == 0)
        .collect();
    if out.len() > max_frames.max(keyframes.len()) {
        out.retain(|i| keyframes.binary_search(i).is_ok());
    }
    out
}

/// SfM frames for `indices` of `frames`, their masks found as the capture import finds them
/// (by file stem, [`MaskFolder`]); a frame without a hand mask shows no hands.
/// Frames between keyframes without an object mask are left out (their object would bring
/// features that move with it) and named in the second list, unless the capture keeps them
/// (`in_between`, sorted: they need cameras, and their masks).
pub fn sfm_frames(
    frames: &FrameFiles,
    masks: &Path,
    hands: Option<&Path>,
    keyframes: &[usize],
    in_between: &[usize],
    indices: &[usize],
) -> Result<(Vec<SfmFrame>, Vec<String>), SfmError> {
    let mask_folder = MaskFolder::open(masks)?;
    let mask_of = mask_folder.assign(frames)?;
    let hand_of = match hands {
        Some(h) => Some(MaskFolder::open(h)?.assign(frames)?),
        None => None,
    };
    let mut out = vec![];
    let mut skipped = vec![];
    for &i in indices {
        let path = &frames.paths[i];
        let s = stem(path);
        let keyframe = keyframes.binary_search(&i).is_ok();
        let kept = in_between.binary_search(&i).is_ok();
        let file_name = path
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| SfmError::Input(format!("{}: not a UTF-8 file name", path.display())))?
            .to_string();
        let Some(mask_path) = &mask_of[i] else {
            if keyframe || kept {
                return Err(mask_folder.missing(path).into());
            }
            skipped.push(file_name);
            continue;
        };
        let mut excluded = load_mask(mask_path)?;
        if let Some(Some(h)) = hand_of.as_ref().map(|f| &f[i]) {
            let hand = load_mask(h)?;
            if (hand.width(), hand.height()) == (excluded.width(), excluded.height()) {
                excluded = excluded.or(&hand);
            } else {
                return Err(SfmError::Input(format!(
                    "{}: hand mask is {}×{}, the object mask {}×{}",
                    h.display(),
                    hand.width(),
                    hand.height(),
                    excluded.width(),
                    excluded.height()
                )));
            }
        }
        out.push(SfmFrame {
            file_name,
            stem: s,
            excluded,
            role: if keyframe {
                FrameRole::Keyframe
            } else if kept {
                FrameRole::InBetween
            } else {
                FrameRole::Helper
            },
        });
    }
    Ok((out, skipped))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_between_keyframes_are_thinned_and_keyframes_kept() {
        let keys = [0, 10, 20, 30];
        assert_eq!(select_frames(&keys, 100), (0..=30).collect::<Vec<_>>());
        let few = select_frames(&keys, 10);
        assert!(few.len() <= 10, "{few:?}");
        for k in keys {
            assert!(few.contains(&k), "{few:?}");
        }
        assert_eq!(select_frames(&keys, 2), keys.to_vec());
        assert!(select_frames(&[], 10).is_empty());
    }
}

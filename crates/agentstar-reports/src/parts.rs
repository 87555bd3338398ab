//! Parts that sit on the object's mask in some keyframes and off it in others: a part
//! modelled rigid that moves against the body (play-test 17: a lever on a hinge, modelled as
//! a peg, looked like a long bar in some keyframes and a small cube in others), or a joint
//! whose state or axis is wrong in those frames. `score` reports them.

use serde::{Deserialize, Serialize};

/// A part's pixels in view (outside the hands) in one frame, and the share of them that lie
/// outside the object's mask.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartInFrame {
    pub frame: String,
    pub pixels: u64,
    pub off_share: f64,
}

/// A part off the mask in some keyframes only ([`parts_off_mask`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartOffMask {
    pub part: String,
    /// Whether a joint moves the part (then its state or axis may be wrong in those frames);
    /// else it is rigid with the body, and may need a joint.
    pub jointed: bool,
    /// Every frame where at least [`PART_MIN_PIXELS`] of it is in view, most off first.
    pub frames: Vec<PartInFrame>,
    /// The median over those frames of the share off the mask.
    pub median_off_share: f64,
}

/// The fewest pixels of a part in view for its frame to count: a part seen edge-on, a strip a
/// few pixels wide along the outline, lies within a segmenter's 1–2 px of boundary noise
/// (play-test 17's label sleeve, 44 px in view at the outline, was 75% off the mask).
pub const PART_MIN_PIXELS: u64 = 100;

/// A part is reported when, in its worst frame, at least this share of its pixels in view lies
/// off the mask...
pub const PART_OFF_SHARE: f64 = 0.4;

/// ...and that share exceeds the part's median share over the frames by at least this: a thin
/// part at a segmenter's noisy boundary is a little off the mask in every frame, a part that
/// moves is on it in some and off it in others.
pub const PART_OFF_SPREAD: f64 = 0.25;

/// The frames it needs: the median means nothing over fewer.
pub const PART_MIN_FRAMES: usize = 3;

/// The parts off the mask in some frames only. `counts`: per frame, its name and each part's
/// (pixels in view outside the hands, of them outside the object mask), indexed like `parts`
/// (each part's name and whether a joint moves it).
pub fn parts_off_mask(
    counts: &[(String, Vec<(u64, u64)>)],
    parts: &[(String, bool)],
) -> Vec<PartOffMask> {
    let mut found = Vec::new();
    for (k, (name, jointed)) in parts.iter().enumerate() {
        let mut frames: Vec<PartInFrame> = counts
            .iter()
            .filter_map(|(frame, c)| {
                let &(pixels, off) = c.get(k)?;
                (pixels >= PART_MIN_PIXELS).then(|| PartInFrame {
                    frame: frame.clone(),
                    pixels,
                    off_share: off as f64 / pixels as f64,
                })
            })
            .collect();
        if frames.len() < PART_MIN_FRAMES {
            continue;
        }
        let mut shares: Vec<f64> = frames.iter().map(|f| f.off_share).collect();
        shares.sort_by(f64::total_cmp);
        let median = shares[shares.len() / 2];
        let worst = shares[shares.len() - 1];
        if worst >= PART_OFF_SHARE && worst - median >= PART_OFF_SPREAD {
            frames.sort_by(|a, b| b.off_share.total_cmp(&a.off_share));
            found.push(PartOffMask {
                part: name.clone(),
                jointed: *jointed,
                frames,
                median_off_share: median,
            });
        }
    }
    found
}

/// The lines a person reads: each part, its worst frames and its best, and what to check.
pub fn parts_off_mask_text(parts: &[PartOffMask]) -> String {
    let mut text = String::new();
    if parts.is_empty() {
        return text;
    }
    text.push_str("parts off the object mask in some keyframes only (share of the part's pixels in view, outside the hands, that lie off the mask):\n");
    for p in parts {
        let share = |f: &PartInFrame| format!("{:.0}% in {}", 100.0 * f.off_share, f.frame);
        let worst: Vec<String> = p
            .frames
            .iter()
            .take_while(|f| f.off_share >= PART_OFF_SHARE)
            .take(4)
            .map(share)
            .collect();
        let best = p.frames.last().map(share).unwrap_or_default();
        let what = if p.jointed {
            "its joint's state or axis may be wrong in those frames: compare them with `render` (`side`) and `mechanism`"
        } else {
            "it is rigid with the body in the model: if it moves against the body (a lever, a lid, a door), give it a joint; else check its size and place there"
        };
        text.push_str(&format!(
            "  {} ({}): {}; {} (median {:.0}%): {what}\n",
            p.part,
            if p.jointed { "jointed" } else { "rigid" },
            worst.join(", "),
            best,
            100.0 * p.median_off_share
        ));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(per_frame: &[(u64, u64)]) -> Vec<(String, Vec<(u64, u64)>)> {
        per_frame
            .iter()
            .enumerate()
            .map(|(k, &c)| (format!("{k:06}.png"), vec![(1000, 10), c]))
            .collect()
    }

    #[test]
    fn a_part_off_the_mask_in_some_frames_only_is_named_and_a_steadily_noisy_one_is_not() {
        let parts = [("body".to_string(), false), ("peg".to_string(), false)];
        // On the mask in three frames, half off it in two: named, worst first.
        let moved = frames(&[(100, 5), (100, 60), (100, 8), (100, 45), (100, 4)]);
        let found = parts_off_mask(&moved, &parts);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].part, "peg");
        assert_eq!(found[0].frames[0].frame, "000001.png");
        assert!((found[0].frames[0].off_share - 0.6).abs() < 1e-12);
        assert!((found[0].median_off_share - 0.08).abs() < 1e-12);
        let text = parts_off_mask_text(&found);
        assert!(
            text.contains(
                "peg (rigid): 60% in 000001.png, 45% in 000003.png; 4% in 000004.png (median 8%)"
            ) && text.contains("give it a joint"),
            "{text}"
        );
        // A thin part 40–50% off in every frame (a noisy boundary): not named.
        let noisy = frames(&[(100, 42), (100, 50), (100, 45), (100, 48), (100, 44)]);
        assert!(parts_off_mask(&noisy, &parts).is_empty());
        // Too few pixels in the frames where it is off, or too few frames: not named.
        let small = frames(&[(100, 5), (90, 75), (100, 8), (20, 15), (100, 4)]);
        assert!(parts_off_mask(&small, &parts).is_empty());
        assert!(parts_off_mask(&moved[..2], &parts).is_empty());
        assert_eq!(parts_off_mask_text(&[]), "");
    }
}

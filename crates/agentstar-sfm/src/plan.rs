//! Which frames structure from motion reconstructs from, which pairs of frames it matches,
//! and which frames it registers afterwards against the reconstructed model.
//!
//! A clip has far more frames than SfM needs: neighbouring frames of a 30 fps video differ by
//! a fraction of a degree, so matching every frame with its ten neighbours spends most of its
//! time on pairs with no parallax. The reconstruction runs on an evenly strided subset (at
//! most `reconstruct_max` frames over the whole clip), each matched with its next `overlap`
//! frames of the subset, with longer links at twice, four times … the overlap (up to
//! [`LONG_LINKS_SPAN`] times it) that hold the scale along the orbit, and the first and the
//! last frames of the subset matched with each other in case the camera comes back (loop
//! detection by a vocabulary tree needs a tree file we cannot download at run time). Every
//! other frame that needs a camera is then matched with its nearest reconstructed frames on
//! either side and registered against the model's 3-D points (PnP), which costs a few pairs
//! a frame instead of a place in the bundle adjustment.

/// Frames whose longer side is below this many pixels are doubled before SIFT (COLMAP's
/// `SiftExtraction.first_octave` −1); larger ones start at their own resolution (0), which
/// takes about a fifth of the time and finds about a quarter of the features.
pub const UPSAMPLE_BELOW_PX: u32 = 640;

/// COLMAP's first SIFT octave for frames of `size`.
pub fn first_octave(size: [u32; 2]) -> i32 {
    if size[0].max(size[1]) < UPSAMPLE_BELOW_PX {
        -1
    } else {
        0
    }
}

/// Longer links reach at most this many times the overlap.
pub const LONG_LINKS_SPAN: usize = 4;
/// Frames at either end of the subset matched with the other end (loop closure of an orbit
/// that comes back).
pub const LOOP_FRAMES: usize = 3;
/// Reconstructed frames on each side that a registered frame is matched with.
pub const REGISTER_NEIGHBOURS: usize = 1;

/// Positions (into `0..n`) of at most `max` evenly spaced frames, the first and the last
/// always among them.
pub fn stride_subset(n: usize, max: usize) -> Vec<usize> {
    if n == 0 {
        return vec![];
    }
    let m = max.clamp(2, n.max(2)).min(n);
    if m == n {
        return (0..n).collect();
    }
    let mut out: Vec<usize> = (0..m)
        .map(|i| ((i as f64) * (n - 1) as f64 / (m - 1) as f64).round() as usize)
        .collect();
    out.dedup();
    out
}

/// Pairs of positions into a subset of `m` frames in video order: each with its next
/// `overlap`, the longer links, and the loop-closure pairs between both ends. Each pair once,
/// the smaller position first, sorted.
pub fn subset_pairs(m: usize, overlap: usize) -> Vec<(usize, usize)> {
    let overlap = overlap.max(1);
    let mut pairs = vec![];
    for i in 0..m {
        for j in i + 1..=(i + overlap).min(m.saturating_sub(1)) {
            pairs.push((i, j));
        }
        let mut step = 2 * overlap;
        while step <= LONG_LINKS_SPAN * overlap && i + step < m {
            pairs.push((i, i + step));
            step *= 2;
        }
    }
    if m > 2 * LOOP_FRAMES + overlap {
        for i in 0..LOOP_FRAMES {
            for j in m - LOOP_FRAMES..m {
                pairs.push((i, j));
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// For each frame to register (its position in the clip), the reconstructed frames
/// (positions in the clip, sorted) it is matched with: the [`REGISTER_NEIGHBOURS`] nearest
/// on each side, or more on one side where the other has fewer.
pub fn registration_pairs(reconstructed: &[usize], to_register: &[usize]) -> Vec<(usize, usize)> {
    let mut pairs = vec![];
    for &r in to_register {
        let split = reconstructed.partition_point(|&s| s < r);
        let before = &reconstructed[..split];
        let after = &reconstructed[split..];
        let want = 2 * REGISTER_NEIGHBOURS;
        let from_before = REGISTER_NEIGHBOURS
            .max(want.saturating_sub(after.len()))
            .min(before.len());
        let from_after = (want - from_before).min(after.len());
        for &s in before.iter().rev().take(from_before) {
            pairs.push((s, r));
        }
        for &s in after.iter().take(from_after) {
            pairs.push((r, s));
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_frames_are_doubled_before_sift() {
        assert_eq!(first_octave([320, 240]), -1);
        assert_eq!(first_octave([480, 640]), 0);
        assert_eq!(first_octave([1920, 1080]), 0);
    }

    #[test]
    fn a_stride_keeps_both_ends_and_at_most_the_cap() {
        assert_eq!(stride_subset(5, 10), vec![0, 1, 2, 3, 4]);
        let s = stride_subset(191, 48);
        assert_eq!(s.len(), 48);
        assert_eq!((s[0], s[47]), (0, 190));
        let gaps: Vec<usize> = s.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(gaps.iter().all(|g| (3..=5).contains(g)), "{gaps:?}");
        assert_eq!(stride_subset(10, 1), vec![0, 9]);
        assert!(stride_subset(0, 5).is_empty());
        assert_eq!(stride_subset(1, 5), vec![0]);
    }

    #[test]
    fn pairs_link_neighbours_longer_steps_and_both_ends() {
        let p = subset_pairs(30, 3);
        assert!(p.contains(&(0, 1)) && p.contains(&(0, 3)) && !p.contains(&(0, 4)));
        // Longer links at 6 and 12, not at 24 (past 4 × 3).
        assert!(p.contains(&(2, 8)) && p.contains(&(2, 14)) && !p.contains(&(2, 26)));
        assert!(!p.contains(&(2, 9)));
        // The loop: the first three with the last three.
        assert!(p.contains(&(0, 29)) && p.contains(&(2, 27)) && !p.contains(&(3, 29)));
        assert!(p.windows(2).all(|w| w[0] < w[1]));
        // A short subset: every pair within the overlap, no loop pairs beyond them.
        assert_eq!(subset_pairs(3, 5), vec![(0, 1), (0, 2), (1, 2)]);
        assert!(subset_pairs(1, 5).is_empty());
    }

    #[test]
    fn a_registered_frame_is_matched_with_its_nearest_reconstructed_frames() {
        let rec = [0, 4, 8, 12];
        let p = registration_pairs(&rec, &[5, 6]);
        assert_eq!(p, vec![(4, 5), (4, 6), (5, 8), (6, 8)]);
        // At the end of the clip, both come from before it.
        let p = registration_pairs(&rec, &[13]);
        assert_eq!(p, vec![(8, 13), (12, 13)]);
        // Before the first.
        let p = registration_pairs(&[3, 6, 9], &[1]);
        assert_eq!(p, vec![(1, 3), (1, 6)]);
    }
}

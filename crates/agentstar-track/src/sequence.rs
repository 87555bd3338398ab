//! The sequence-level choice: one hypothesis per keyframe for the whole sequence, by dynamic
//! programming over frames (Viterbi). A frame's own cost says how badly a hypothesis explains
//! its mask; the step cost between consecutive frames' hypotheses says how implausible the
//! motion between them is. A wrong basin then survives only if its frames explain their
//! masks as well and its steps are as plausible: never merely because its neighbours were
//! chained from it, since every frame's alternatives stay on the table.

/// The path of least total cost: `unary[i][a]` is the cost of hypothesis `a` at frame `i`,
/// `step(i, a, b)` the cost of going from hypothesis `a` at frame `i − 1` to `b` at frame `i`.
/// Returns one index per frame (empty when there are no frames; a frame with no hypotheses
/// is an error of the caller and yields an empty path). Ties go to the lower index.
pub fn cheapest_path(unary: &[Vec<f64>], step: &dyn Fn(usize, usize, usize) -> f64) -> Vec<usize> {
    if unary.is_empty() || unary.iter().any(Vec::is_empty) {
        return vec![];
    }
    let mut cost: Vec<f64> = unary[0].clone();
    let mut back: Vec<Vec<usize>> = vec![vec![0; unary[0].len()]];
    for (i, row) in unary.iter().enumerate().skip(1) {
        let mut next = vec![f64::INFINITY; row.len()];
        let mut from = vec![0usize; row.len()];
        for (b, u) in row.iter().enumerate() {
            for (a, c) in cost.iter().enumerate() {
                let total = c + step(i, a, b) + u;
                if total < next[b] {
                    next[b] = total;
                    from[b] = a;
                }
            }
        }
        cost = next;
        back.push(from);
    }
    let mut last = 0;
    for (k, c) in cost.iter().enumerate() {
        if *c < cost[last] {
            last = k;
        }
    }
    let mut path = vec![last; unary.len()];
    for i in (1..unary.len()).rev() {
        path[i - 1] = back[i][path[i]];
    }
    path
}

/// [`cheapest_path`] with a cost on three consecutive frames besides: `bend(i, z, a, b)` for
/// hypothesis `z` at frame `i − 2`, `a` at `i − 1` and `b` at `i` (a change of velocity where
/// hypotheses are angles). Dynamic programming over pairs of consecutive hypotheses: K³ work
/// per frame for K hypotheses. Infinite unary costs prune. Ties go to the lower indices.
pub fn cheapest_path_bent(
    unary: &[Vec<f64>],
    step: &dyn Fn(usize, usize, usize) -> f64,
    bend: &dyn Fn(usize, usize, usize, usize) -> f64,
) -> Vec<usize> {
    let n = unary.len();
    if n < 3 || unary.iter().any(Vec::is_empty) {
        return cheapest_path(unary, step);
    }
    // cost[(a, b)]: the cheapest path ending with `a` at frame i − 1 and `b` at frame i.
    let (k0, k1) = (unary[0].len(), unary[1].len());
    let mut cost = vec![f64::INFINITY; k0 * k1];
    for a in 0..k0 {
        for b in 0..k1 {
            cost[a * k1 + b] = unary[0][a] + unary[1][b] + step(1, a, b);
        }
    }
    // back[i][(a, b)]: the best hypothesis at frame i − 2 for the pair ending at frame i.
    let mut back: Vec<Vec<usize>> = vec![vec![], vec![]];
    let mut width = k1;
    for i in 2..n {
        let (ka, kb) = (unary[i - 1].len(), unary[i].len());
        let kz = unary[i - 2].len();
        let mut next = vec![f64::INFINITY; ka * kb];
        let mut from = vec![0usize; ka * kb];
        for a in 0..ka {
            for b in 0..kb {
                let local = unary[i][b];
                if !local.is_finite() {
                    continue;
                }
                let local = local + step(i, a, b);
                for z in 0..kz {
                    let c = cost[z * width + a];
                    if !c.is_finite() {
                        continue;
                    }
                    let total = c + local + bend(i, z, a, b);
                    if total < next[a * kb + b] {
                        next[a * kb + b] = total;
                        from[a * kb + b] = z;
                    }
                }
            }
        }
        cost = next;
        back.push(from);
        width = kb;
    }
    let best = (0..cost.len()).fold(0, |m, k| if cost[k] < cost[m] { k } else { m });
    let mut path = vec![0usize; n];
    path[n - 1] = best % width;
    path[n - 2] = best / width;
    for i in (2..n).rev() {
        let kb = unary[i].len();
        path[i - 2] = back[i][path[i - 1] * kb + path[i]];
    }
    path
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chained_wrong_block_loses_to_the_consistent_path() {
        // Two hypotheses per frame: 0 "right", 1 "flipped". Frames 2–4 were chained into the
        // flip and score it slightly higher one by one, but the step into and out of the
        // block costs more than the block gains.
        let unary = vec![
            vec![0.0, 3.0],
            vec![0.0, 3.0],
            vec![0.2, 0.0],
            vec![0.2, 0.0],
            vec![0.2, 0.0],
            vec![0.0, 3.0],
        ];
        let step = |_: usize, a: usize, b: usize| if a == b { 0.0 } else { 2.0 };
        assert_eq!(cheapest_path(&unary, &step), vec![0; 6]);
        // A block whose frames clearly need the other hypothesis takes it.
        let unary = vec![
            vec![0.0, 3.0],
            vec![5.0, 0.0],
            vec![5.0, 0.0],
            vec![0.0, 3.0],
        ];
        assert_eq!(cheapest_path(&unary, &step), vec![0, 1, 1, 0]);
        assert!(cheapest_path(&[], &step).is_empty());
        assert!(cheapest_path(&[vec![1.0], vec![]], &step).is_empty());
    }

    #[test]
    fn a_bend_cost_carries_a_steady_turn_across_frames_that_say_nothing() {
        // Angles 0, 10, …, 90 as hypotheses. Frames 0–2 say they turn 0°, 10°, 20°; frames 3
        // and 4 say nothing. With steps free and bends costed, the turn goes on at 10° a frame.
        let angles: Vec<f64> = (0..10).map(|k| 10.0 * k as f64).collect();
        let says = |deg: f64| -> Vec<f64> {
            angles
                .iter()
                .map(|&a| if a == deg { 0.0 } else { 1.0 })
                .collect()
        };
        let unary = vec![
            says(0.0),
            says(10.0),
            says(20.0),
            vec![0.0; 10],
            vec![0.0; 10],
        ];
        let free = |_: usize, _: usize, _: usize| 0.0;
        let bend = |_: usize, z: usize, a: usize, b: usize| {
            ((angles[b] - angles[a]) - (angles[a] - angles[z])).abs() / 100.0
        };
        assert_eq!(
            cheapest_path_bent(&unary, &free, &bend),
            vec![0, 1, 2, 3, 4]
        );
        // Without the bend, the frames that say nothing take the lowest index.
        assert_eq!(cheapest_path(&unary, &free), vec![0, 1, 2, 0, 0]);
        // Infinite costs prune; fewer than three frames is the first-order path.
        let mut pruned = unary.clone();
        pruned[3] = vec![f64::INFINITY; 10];
        pruned[3][5] = 0.0;
        assert_eq!(cheapest_path_bent(&pruned, &free, &bend)[3], 5);
        assert_eq!(cheapest_path_bent(&unary[..2], &free, &bend), vec![0, 1]);
    }
}

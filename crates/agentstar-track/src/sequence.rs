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
}

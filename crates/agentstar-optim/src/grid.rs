//! Grid search: the Cartesian product of `linspace(lo, hi, steps)` per dimension, then
//! optional refinement passes that re-centre every window on the best point and shrink its
//! half-span, keeping the step counts. Every scored point is kept with its pass.

use crate::{check_bounds, Bounds, OptimError};

#[derive(Debug, Clone, PartialEq)]
pub struct GridConfig {
    /// Steps per dimension (1 gives the midpoint).
    pub steps: Vec<usize>,
    pub refine_passes: usize,
    pub shrink: f64,
    /// Refuse grids with more points than this per pass.
    pub max_points: usize,
}

#[derive(Debug, Clone, PartialEq)]
pub struct GridPoint {
    pub x: Vec<f64>,
    pub f: f64,
    pub pass: usize,
}

fn linspace(lo: f64, hi: f64, steps: usize) -> Vec<f64> {
    if steps <= 1 {
        return vec![0.5 * (lo + hi)];
    }
    (0..steps)
        .map(|i| lo + (hi - lo) * i as f64 / (steps - 1) as f64)
        .collect()
}

/// Every point of every pass, in scoring order. `f` is minimised; points of a pass are
/// handed to `f` as one batch (so callers can score them in parallel).
pub fn grid_search(
    f: &mut dyn FnMut(&[Vec<f64>]) -> Vec<f64>,
    bounds: &Bounds,
    cfg: &GridConfig,
) -> Result<Vec<GridPoint>, OptimError> {
    check_bounds(bounds)?;
    if cfg.steps.len() != bounds.len() {
        return Err(OptimError::Config(format!(
            "{} step counts for {} dimensions",
            cfg.steps.len(),
            bounds.len()
        )));
    }
    if !(cfg.shrink > 0.0 && cfg.shrink <= 1.0) {
        return Err(OptimError::Config(format!(
            "shrink {} must be in (0, 1]",
            cfg.shrink
        )));
    }
    let total: usize = cfg.steps.iter().map(|&s| s.max(1)).product();
    if total > cfg.max_points {
        return Err(OptimError::Config(format!("the grid has {total} points per pass, over the limit of {}; use fewer steps or differential evolution", cfg.max_points)));
    }
    let mut windows: Vec<(f64, f64)> = bounds.to_vec();
    let mut out: Vec<GridPoint> = Vec::new();
    for pass in 0..=cfg.refine_passes {
        let axes: Vec<Vec<f64>> = windows
            .iter()
            .zip(&cfg.steps)
            .map(|(&(lo, hi), &s)| linspace(lo, hi, s))
            .collect();
        let mut points = Vec::with_capacity(total);
        let mut idx = vec![0usize; axes.len()];
        loop {
            points.push(
                idx.iter()
                    .zip(&axes)
                    .map(|(&i, a)| a[i])
                    .collect::<Vec<f64>>(),
            );
            let mut d = axes.len();
            loop {
                if d == 0 {
                    break;
                }
                d -= 1;
                idx[d] += 1;
                if idx[d] < axes[d].len() {
                    break;
                }
                idx[d] = 0;
                if d == 0 {
                    d = usize::MAX;
                    break;
                }
            }
            if d == usize::MAX || axes.is_empty() {
                break;
            }
        }
        let values = f(&points);
        for (x, v) in points.into_iter().zip(values) {
            out.push(GridPoint {
                x,
                f: if v.is_nan() { f64::INFINITY } else { v },
                pass,
            });
        }
        let best = out
            .iter()
            .min_by(|a, b| a.f.total_cmp(&b.f))
            .map(|p| p.x.clone())
            .unwrap_or_default();
        windows = windows
            .iter()
            .zip(bounds)
            .zip(&best)
            .map(|((&(lo, hi), &(blo, bhi)), &c)| {
                let half = 0.5 * (hi - lo) * cfg.shrink;
                ((c - half).max(blo), (c + half).min(bhi))
            })
            .collect();
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refinement_closes_in_on_the_minimum() {
        let mut batch = |xs: &[Vec<f64>]| {
            xs.iter()
                .map(|x| (x[0] - 0.37).powi(2) + (x[1] + 0.21).powi(2))
                .collect::<Vec<f64>>()
        };
        let cfg = GridConfig {
            steps: vec![5, 5],
            refine_passes: 6,
            shrink: 0.5,
            max_points: 1000,
        };
        let pts = grid_search(&mut batch, &[(-1.0, 1.0), (-1.0, 1.0)], &cfg).expect("grid");
        assert_eq!(pts.len(), 25 * 7);
        let best = pts.iter().min_by(|a, b| a.f.total_cmp(&b.f)).expect("best");
        assert!(best.f < 1e-3, "{best:?}");
        assert_eq!(pts.iter().filter(|p| p.pass == 0).count(), 25);
        assert!(grid_search(&mut batch, &[(-1.0, 1.0)], &cfg).is_err());
        let big = GridConfig {
            steps: vec![1000, 1000],
            refine_passes: 0,
            shrink: 0.5,
            max_points: 20000,
        };
        assert!(grid_search(&mut batch, &[(-1.0, 1.0), (-1.0, 1.0)], &big)
            .expect_err("too big")
            .to_string()
            .contains("1000000 points"));
    }
}

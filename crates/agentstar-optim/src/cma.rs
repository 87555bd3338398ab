//! Bounded CMA-ES: the (μ/μ_w, λ) covariance matrix adaptation evolution strategy with
//! the default settings of Hansen's tutorial ("The CMA Evolution Strategy: A Tutorial",
//! 2016), searching in box-normalised coordinates (each dimension's span mapped to 1).
//!
//! It learns the covariance of the steps that paid, so it follows a narrow valley that is
//! not aligned with the axes, where a simplex or a coordinate search stalls: a
//! silhouette's score along an out-of-plane turn coupled to a sideways shift is one.
//! Samples outside the box are clamped before they are evaluated, and the clamped point
//! is the one the strategy learns from. The sample's standard-normal preimage comes from
//! the Cholesky factor of the covariance, not its eigendecomposition: any square root
//! gives the same distribution, and a triangular solve is all a small box needs.

use crate::{check_bounds, Bounds, OptimError, Rng};

#[derive(Debug, Clone, PartialEq)]
pub struct CmaConfig {
    pub max_evals: usize,
    /// The first step size, as a fraction of each dimension's span.
    pub initial_step: f64,
    /// Stop when the step size times the largest axis of the covariance, in span
    /// fractions, is below this.
    pub xtol: f64,
    /// Stop when the best values of the last generations ([`STALL_GENERATIONS`] and the
    /// current one) span less than this.
    pub ftol: f64,
    pub seed: u64,
}

impl Default for CmaConfig {
    fn default() -> Self {
        CmaConfig {
            max_evals: 1000,
            initial_step: 0.1,
            xtol: 1e-4,
            ftol: 1e-9,
            seed: 0,
        }
    }
}

/// Generations over which the best value must move by more than `ftol`.
pub const STALL_GENERATIONS: usize = 20;

#[derive(Debug, Clone, PartialEq)]
pub struct CmaResult {
    /// The best point evaluated (not the distribution's mean).
    pub x: Vec<f64>,
    pub f: f64,
    pub nfev: usize,
    pub generations: usize,
}

/// Minimises `f` over `bounds` from `x0` (clamped into the box). NaN values count as +∞.
/// Deterministic for `cfg.seed`.
pub fn cma_es(
    f: &mut dyn FnMut(&[f64]) -> f64,
    bounds: &Bounds,
    x0: &[f64],
    cfg: &CmaConfig,
) -> Result<CmaResult, OptimError> {
    check_bounds(bounds)?;
    let n = bounds.len();
    if x0.len() != n {
        return Err(OptimError::Config(format!(
            "start has {} values for {n} dimensions",
            x0.len()
        )));
    }
    if !(cfg.initial_step.is_finite() && cfg.initial_step > 0.0) {
        return Err(OptimError::Config(format!(
            "initial_step must be positive, got {}",
            cfg.initial_step
        )));
    }
    let spans: Vec<f64> = bounds.iter().map(|&(lo, hi)| hi - lo).collect();
    // Normalised coordinates u ∈ [0, 1] per dimension; a zero span stays at its value.
    let to_x = |u: &[f64]| -> Vec<f64> {
        u.iter()
            .zip(bounds)
            .map(|(&v, &(lo, hi))| (lo + v * (hi - lo)).clamp(lo, hi))
            .collect()
    };
    let mut nfev = 0usize;
    let mut eval = |u: &[f64], nfev: &mut usize| -> f64 {
        *nfev += 1;
        let v = f(&to_x(u));
        if v.is_nan() {
            f64::INFINITY
        } else {
            v
        }
    };
    let mut mean: Vec<f64> = x0
        .iter()
        .zip(bounds)
        .zip(&spans)
        .map(|((&v, &(lo, hi)), &s)| {
            if s > 0.0 {
                (v.clamp(lo, hi) - lo) / s
            } else {
                0.0
            }
        })
        .collect();
    let mut best_u = mean.clone();
    let mut best_f = if cfg.max_evals > 0 {
        eval(&mean, &mut nfev)
    } else {
        f64::INFINITY
    };
    if n == 0 {
        return Ok(CmaResult {
            x: to_x(&best_u),
            f: best_f,
            nfev,
            generations: 0,
        });
    }

    let nf = n as f64;
    let lambda = 4 + (3.0 * nf.ln()).floor() as usize;
    let mu = lambda / 2;
    let raw: Vec<f64> = (0..mu)
        .map(|i| (mu as f64 + 0.5).ln() - ((i + 1) as f64).ln())
        .collect();
    let total: f64 = raw.iter().sum();
    let weights: Vec<f64> = raw.iter().map(|w| w / total).collect();
    let mu_eff = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
    let c_sigma = (mu_eff + 2.0) / (nf + mu_eff + 5.0);
    let d_sigma = 1.0 + 2.0 * (((mu_eff - 1.0) / (nf + 1.0)).sqrt() - 1.0).max(0.0) + c_sigma;
    let c_c = (4.0 + mu_eff / nf) / (nf + 4.0 + 2.0 * mu_eff / nf);
    let c_1 = 2.0 / ((nf + 1.3).powi(2) + mu_eff);
    let c_mu = (1.0 - c_1).min(2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((nf + 2.0).powi(2) + mu_eff));
    let chi_n = nf.sqrt() * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));

    let mut sigma = cfg.initial_step;
    // Covariance (row-major, symmetric) and its lower Cholesky factor.
    let mut cov = identity(n);
    let mut chol = identity(n);
    let mut p_sigma = vec![0.0; n];
    let mut p_c = vec![0.0; n];
    let mut rng = Rng::new(cfg.seed);
    let mut history: Vec<f64> = Vec::new();
    let mut generations = 0;
    let mut zs = vec![vec![0.0; n]; lambda];
    let mut ys = vec![vec![0.0; n]; lambda];
    let mut values = vec![0.0; lambda];
    while nfev + lambda <= cfg.max_evals {
        generations += 1;
        for k in 0..lambda {
            let z: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
            let y = lower_times(&chol, &z);
            // The clamped sample is the one learnt from: its step and preimage.
            let u: Vec<f64> = (0..n)
                .map(|d| (mean[d] + sigma * y[d]).clamp(0.0, 1.0))
                .collect();
            let y: Vec<f64> = (0..n).map(|d| (u[d] - mean[d]) / sigma).collect();
            let z = lower_solve(&chol, &y);
            values[k] = eval(&u, &mut nfev);
            if values[k] < best_f {
                best_f = values[k];
                best_u = u;
            }
            zs[k] = z;
            ys[k] = y;
        }
        let mut order: Vec<usize> = (0..lambda).collect();
        order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
        let y_w: Vec<f64> = (0..n)
            .map(|d| (0..mu).map(|i| weights[i] * ys[order[i]][d]).sum())
            .collect();
        let z_w: Vec<f64> = (0..n)
            .map(|d| (0..mu).map(|i| weights[i] * zs[order[i]][d]).sum())
            .collect();
        for d in 0..n {
            mean[d] = (mean[d] + sigma * y_w[d]).clamp(0.0, 1.0);
        }
        let ps_gain = (c_sigma * (2.0 - c_sigma) * mu_eff).sqrt();
        for d in 0..n {
            p_sigma[d] = (1.0 - c_sigma) * p_sigma[d] + ps_gain * z_w[d];
        }
        let ps_norm = p_sigma.iter().map(|v| v * v).sum::<f64>().sqrt();
        let decay = 1.0 - (1.0 - c_sigma).powi(2 * generations as i32);
        let h_sigma = ps_norm / decay.sqrt() / chi_n < 1.4 + 2.0 / (nf + 1.0);
        let pc_gain = (c_c * (2.0 - c_c) * mu_eff).sqrt();
        for d in 0..n {
            p_c[d] = (1.0 - c_c) * p_c[d] + if h_sigma { pc_gain * y_w[d] } else { 0.0 };
        }
        let lost = if h_sigma {
            0.0
        } else {
            c_1 * c_c * (2.0 - c_c)
        };
        for r in 0..n {
            for c in 0..=r {
                let rank_mu: f64 = (0..mu)
                    .map(|i| weights[i] * ys[order[i]][r] * ys[order[i]][c])
                    .sum();
                let v = (1.0 - c_1 - c_mu + lost) * cov[r * n + c]
                    + c_1 * p_c[r] * p_c[c]
                    + c_mu * rank_mu;
                cov[r * n + c] = v;
                cov[c * n + r] = v;
            }
        }
        sigma *= ((c_sigma / d_sigma) * (ps_norm / chi_n - 1.0)).exp();
        // Never wider than the box: a step of a whole span samples only its walls.
        sigma = sigma.min(1.0);
        if !cholesky(&cov, n, &mut chol) {
            // Lost definiteness to rounding: start the shape again, keep the step.
            cov = identity(n);
            chol = identity(n);
            p_c.iter_mut().for_each(|v| *v = 0.0);
        }
        history.push(values[order[0]]);
        let widest = (0..n).map(|d| cov[d * n + d].sqrt()).fold(0.0, f64::max);
        if sigma * widest < cfg.xtol {
            break;
        }
        if history.len() > STALL_GENERATIONS {
            let recent = &history[history.len() - STALL_GENERATIONS - 1..];
            let (lo, hi) = recent
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                    (a.min(v), b.max(v))
                });
            if hi - lo < cfg.ftol {
                break;
            }
        }
    }
    Ok(CmaResult {
        x: to_x(&best_u),
        f: best_f,
        nfev,
        generations,
    })
}

fn identity(n: usize) -> Vec<f64> {
    let mut m = vec![0.0; n * n];
    for d in 0..n {
        m[d * n + d] = 1.0;
    }
    m
}

/// `l · z` for a lower-triangular `l` (row-major).
fn lower_times(l: &[f64], z: &[f64]) -> Vec<f64> {
    let n = z.len();
    (0..n)
        .map(|r| (0..=r).map(|c| l[r * n + c] * z[c]).sum())
        .collect()
}

/// `z` with `l · z = y` for a lower-triangular `l` with a positive diagonal.
fn lower_solve(l: &[f64], y: &[f64]) -> Vec<f64> {
    let n = y.len();
    let mut z = vec![0.0; n];
    for r in 0..n {
        let s: f64 = (0..r).map(|c| l[r * n + c] * z[c]).sum();
        z[r] = (y[r] - s) / l[r * n + r];
    }
    z
}

/// The lower Cholesky factor of the symmetric `a` into `l`; false when `a` is not
/// positive definite (to rounding).
fn cholesky(a: &[f64], n: usize, l: &mut [f64]) -> bool {
    l.iter_mut().for_each(|v| *v = 0.0);
    for r in 0..n {
        for c in 0..=r {
            let s: f64 = (0..c).map(|k| l[r * n + k] * l[c * n + k]).sum();
            if r == c {
                let d = a[r * n + r] - s;
                if d.is_nan() || d <= 1e-300 || !d.is_finite() {
                    return false;
                }
                l[r * n + r] = d.sqrt();
            } else {
                l[r * n + c] = (a[r * n + c] - s) / l[c * n + c];
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rotated, ill-conditioned quadratic valley (condition 10⁴ along a diagonal).
    fn valley(x: &[f64]) -> f64 {
        let n = x.len() as f64;
        let along: f64 = x.iter().map(|v| v - 0.3).sum::<f64>() / n.sqrt();
        let dist2: f64 = x.iter().map(|v| (v - 0.3).powi(2)).sum();
        let across2 = dist2 - along * along;
        along * along + 1e4 * across2
    }

    #[test]
    fn follows_a_rotated_narrow_valley_to_its_minimum() {
        let bounds = vec![(-1.0, 1.0); 7];
        let r = cma_es(
            &mut |x| valley(x),
            &bounds,
            &[0.9; 7],
            &CmaConfig {
                max_evals: 6000,
                initial_step: 0.1,
                seed: 3,
                ..Default::default()
            },
        )
        .expect("cma");
        assert!(r.f < 1e-6, "{r:?}");
        for v in &r.x {
            assert!((v - 0.3).abs() < 1e-2, "{r:?}");
        }
        assert!(r.nfev <= 6000);
    }

    #[test]
    fn respects_the_box_and_is_deterministic_for_its_seed() {
        // The unconstrained minimum lies outside: the answer is on the wall.
        let bounds = [(-1.0, 1.0), (0.0, 2.0)];
        let cfg = CmaConfig {
            max_evals: 800,
            seed: 11,
            ..Default::default()
        };
        let mut f = |x: &[f64]| (x[0] - 3.0).powi(2) + (x[1] - 0.5).powi(2);
        let a = cma_es(&mut f, &bounds, &[0.0, 1.0], &cfg).expect("cma");
        let b = cma_es(&mut f, &bounds, &[0.0, 1.0], &cfg).expect("cma");
        assert_eq!(a, b);
        assert!(
            (a.x[0] - 1.0).abs() < 1e-3 && (a.x[1] - 0.5).abs() < 1e-3,
            "{a:?}"
        );
        for (v, &(lo, hi)) in a.x.iter().zip(&bounds) {
            assert!(*v >= lo && *v <= hi);
        }
    }

    #[test]
    fn never_returns_worse_than_its_start_and_counts_every_evaluation() {
        let mut calls = 0;
        let r = cma_es(
            &mut |x| {
                calls += 1;
                if x[0] == 0.25 {
                    -1.0
                } else {
                    x[0].abs()
                }
            },
            &[(-1.0, 1.0)],
            &[0.25],
            &CmaConfig {
                max_evals: 50,
                ..Default::default()
            },
        )
        .expect("cma");
        assert_eq!(r.f, -1.0);
        assert_eq!(r.x, vec![0.25]);
        assert_eq!(r.nfev, calls);
        assert!(r.nfev <= 50);
    }

    #[test]
    fn rejects_a_bad_start_or_step() {
        let mut f = |x: &[f64]| x[0];
        assert!(cma_es(&mut f, &[(0.0, 1.0)], &[0.0, 0.0], &CmaConfig::default()).is_err());
        let cfg = CmaConfig {
            initial_step: 0.0,
            ..Default::default()
        };
        assert!(cma_es(&mut f, &[(0.0, 1.0)], &[0.0], &cfg).is_err());
        assert!(cma_es(&mut f, &[(1.0, 0.0)], &[0.0], &CmaConfig::default()).is_err());
    }

    #[test]
    fn nan_values_are_never_chosen() {
        let r = cma_es(
            &mut |x| if x[0] > 0.5 { f64::NAN } else { -x[0] },
            &[(0.0, 1.0)],
            &[0.1],
            &CmaConfig {
                max_evals: 300,
                ..Default::default()
            },
        )
        .expect("cma");
        assert!(r.f.is_finite() && r.x[0] <= 0.5, "{r:?}");
    }
}

//! Bounded Nelder–Mead: the standard reflection, expansion, contraction and shrink steps,
//! with every vertex clamped into the box. Used to polish a search's winner.

use crate::{check_bounds, Bounds, OptimError};

#[derive(Debug, Clone, PartialEq)]
pub struct NelderMeadConfig {
    pub max_evals: usize,
    /// Initial simplex step as a fraction of each dimension's span.
    pub initial_step: f64,
    /// Stop when the simplex's value spread is below this.
    pub ftol: f64,
    /// Stop when the simplex's size (in box fractions) is below this.
    pub xtol: f64,
}

impl Default for NelderMeadConfig {
    fn default() -> Self {
        NelderMeadConfig {
            max_evals: 200,
            initial_step: 0.05,
            ftol: 1e-9,
            xtol: 2e-4,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct NelderMeadResult {
    pub x: Vec<f64>,
    pub f: f64,
    pub nfev: usize,
}

pub fn nelder_mead(
    f: &mut dyn FnMut(&[f64]) -> f64,
    bounds: &Bounds,
    x0: &[f64],
    cfg: &NelderMeadConfig,
) -> Result<NelderMeadResult, OptimError> {
    check_bounds(bounds)?;
    let n = bounds.len();
    let clamp = |x: &mut Vec<f64>| {
        for (v, &(lo, hi)) in x.iter_mut().zip(bounds) {
            *v = v.clamp(lo, hi);
        }
    };
    let mut nfev = 0;
    let mut eval = |x: &[f64], nfev: &mut usize| {
        *nfev += 1;
        let v = f(x);
        if v.is_nan() {
            f64::INFINITY
        } else {
            v
        }
    };
    let mut start = x0.to_vec();
    clamp(&mut start);
    let mut simplex = vec![start.clone()];
    for d in 0..n {
        let span = bounds[d].1 - bounds[d].0;
        let mut v = start.clone();
        let step = cfg.initial_step * span;
        v[d] = if v[d] + step <= bounds[d].1 {
            v[d] + step
        } else {
            v[d] - step
        };
        simplex.push(v);
    }
    let mut values: Vec<f64> = Vec::with_capacity(n + 1);
    for v in &simplex {
        if nfev >= cfg.max_evals {
            break;
        }
        values.push(eval(v, &mut nfev));
    }
    if values.len() < simplex.len() {
        let best = (0..values.len())
            .min_by(|&a, &b| values[a].total_cmp(&values[b]))
            .unwrap_or(0);
        return Ok(NelderMeadResult {
            x: simplex[best].clone(),
            f: values.get(best).copied().unwrap_or(f64::INFINITY),
            nfev,
        });
    }
    let spans: Vec<f64> = bounds
        .iter()
        .map(|&(lo, hi)| (hi - lo).max(1e-300))
        .collect();
    while nfev < cfg.max_evals {
        let mut order: Vec<usize> = (0..=n).collect();
        order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
        simplex = order.iter().map(|&i| simplex[i].clone()).collect();
        values = order.iter().map(|&i| values[i]).collect();
        let size = simplex[1..]
            .iter()
            .map(|v| {
                v.iter()
                    .zip(&simplex[0])
                    .zip(&spans)
                    .map(|((a, b), s)| ((a - b) / s).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        if (values[n] - values[0]).abs() <= cfg.ftol && size <= cfg.xtol {
            break;
        }
        let centroid: Vec<f64> = (0..n)
            .map(|d| simplex[..n].iter().map(|v| v[d]).sum::<f64>() / n as f64)
            .collect();
        let towards = |t: f64| -> Vec<f64> {
            let mut p: Vec<f64> = (0..n)
                .map(|d| centroid[d] + t * (simplex[n][d] - centroid[d]))
                .collect();
            clamp(&mut p);
            p
        };
        let xr = towards(-1.0);
        let fr = eval(&xr, &mut nfev);
        if fr < values[0] {
            let xe = towards(-2.0);
            let fe = if nfev < cfg.max_evals {
                eval(&xe, &mut nfev)
            } else {
                f64::INFINITY
            };
            if fe < fr {
                simplex[n] = xe;
                values[n] = fe;
            } else {
                simplex[n] = xr;
                values[n] = fr;
            }
        } else if fr < values[n - 1] {
            simplex[n] = xr;
            values[n] = fr;
        } else {
            let (xc, fc) = if fr < values[n] {
                let xc = towards(-0.5);
                let fc = eval(&xc, &mut nfev);
                (xc, fc)
            } else {
                let xc = towards(0.5);
                let fc = eval(&xc, &mut nfev);
                (xc, fc)
            };
            if fc < values[n].min(fr) {
                simplex[n] = xc;
                values[n] = fc;
            } else {
                for i in 1..=n {
                    if nfev >= cfg.max_evals {
                        break;
                    }
                    let mut p: Vec<f64> = (0..n)
                        .map(|d| simplex[0][d] + 0.5 * (simplex[i][d] - simplex[0][d]))
                        .collect();
                    clamp(&mut p);
                    values[i] = eval(&p, &mut nfev);
                    simplex[i] = p;
                }
            }
        }
    }
    let best = (0..=n)
        .min_by(|&a, &b| values[a].total_cmp(&values[b]))
        .unwrap_or(0);
    Ok(NelderMeadResult {
        x: simplex[best].clone(),
        f: values[best],
        nfev,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polishes_a_quadratic_and_respects_bounds() {
        let r = nelder_mead(
            &mut |x| (x[0] - 0.2).powi(2) + 3.0 * (x[1] + 0.4).powi(2),
            &[(-1.0, 1.0), (-1.0, 1.0)],
            &[0.5, 0.5],
            &NelderMeadConfig {
                max_evals: 400,
                ..Default::default()
            },
        )
        .expect("nm");
        assert!(r.f < 1e-7, "{r:?}");
        // The unconstrained minimum lies outside: the answer is on the boundary.
        let r = nelder_mead(
            &mut |x| (x[0] - 3.0).powi(2),
            &[(-1.0, 1.0)],
            &[0.0],
            &NelderMeadConfig::default(),
        )
        .expect("nm");
        assert!((r.x[0] - 1.0).abs() < 1e-6 && r.nfev <= 200);
    }
}

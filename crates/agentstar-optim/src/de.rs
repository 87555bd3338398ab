//! Differential evolution, `best1bin` as SciPy implements it with immediate updating:
//! Latin-hypercube initial population (optionally holding the current state), dithered
//! mutation, binomial crossover with one forced component, out-of-box components redrawn
//! uniformly, the best member kept at index 0, and SciPy's convergence test
//! `std(energies) ≤ atol + tol · |mean(energies)|`, checked only once `min_generations`
//! generations have run (SciPy checks from the first, so a population that starts flat
//! stops before it has searched). Minimises.

use crate::nelder_mead::{nelder_mead, NelderMeadConfig};
use crate::rng::Rng;
use crate::{check_bounds, Bounds, OptimError};

#[derive(Debug, Clone, PartialEq)]
pub struct DeConfig {
    /// Population multiplier: population = max(5, popsize · dimensions).
    pub popsize: usize,
    /// Mutation factor drawn uniformly per generation from this range (equal ends: fixed F).
    pub mutation: (f64, f64),
    pub recombination: f64,
    /// Relative tolerance of the convergence test (SciPy's `tol`).
    pub tol: f64,
    /// Absolute tolerance of the convergence test, in the objective's units (SciPy's `atol`).
    pub atol: f64,
    /// Generations that always run (budget permitting) before convergence may stop the
    /// search: an initial population scoring within the tolerance has not yet explored.
    pub min_generations: usize,
    /// Total objective evaluations, the initial population included.
    pub max_evals: usize,
    pub seed: u64,
    /// Evaluations of a bounded Nelder–Mead polish from the best point (0 = none).
    pub polish_evals: usize,
}

impl Default for DeConfig {
    fn default() -> Self {
        DeConfig {
            popsize: 8,
            mutation: (0.5, 1.0),
            recombination: 0.8,
            tol: 0.01,
            atol: 0.0,
            min_generations: 0,
            max_evals: 600,
            seed: 17,
            polish_evals: 0,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Termination {
    Converged,
    MaxEvals,
    /// Every bound is a point: nothing to search.
    FixedBounds,
}

impl Termination {
    pub fn as_str(&self) -> &'static str {
        match self {
            Termination::Converged => "converged",
            Termination::MaxEvals => "max_evals",
            Termination::FixedBounds => "fixed_bounds",
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct DeResult {
    pub x: Vec<f64>,
    pub f: f64,
    pub nfev: usize,
    pub polish_nfev: usize,
    pub population_size: usize,
    pub generations: usize,
    /// Best energy after the initial population and after each generation.
    pub generation_best: Vec<f64>,
    pub termination: Termination,
}

fn to_real(u: &[f64], bounds: &Bounds) -> Vec<f64> {
    u.iter()
        .zip(bounds)
        .map(|(&v, &(lo, hi))| lo + v * (hi - lo))
        .collect()
}

/// Minimises `f` over `bounds`. `x0` (clamped into the box) replaces population member 0.
pub fn differential_evolution(
    f: &mut dyn FnMut(&[f64]) -> f64,
    bounds: &Bounds,
    x0: Option<&[f64]>,
    cfg: &DeConfig,
) -> Result<DeResult, OptimError> {
    check_bounds(bounds)?;
    if !(0.0..=1.0).contains(&cfg.recombination)
        || cfg.mutation.0 > cfg.mutation.1
        || cfg.mutation.0 < 0.0
        || cfg.mutation.1 > 2.0
    {
        return Err(OptimError::Config(format!(
            "recombination {} must be in [0, 1] and mutation {:?} within [0, 2]",
            cfg.recombination, cfg.mutation
        )));
    }
    let n = bounds.len();
    let mut rng = Rng::new(cfg.seed);
    let mut nfev = 0usize;
    let mut eval = |u: &[f64], nfev: &mut usize| -> f64 {
        *nfev += 1;
        let v = f(&to_real(u, bounds));
        if v.is_nan() {
            f64::INFINITY
        } else {
            v
        }
    };
    if n == 0 || bounds.iter().all(|&(lo, hi)| lo == hi) {
        let u = vec![0.0; n];
        let v = eval(&u, &mut nfev);
        return Ok(DeResult {
            x: to_real(&u, bounds),
            f: v,
            nfev,
            polish_nfev: 0,
            population_size: 1,
            generations: 0,
            generation_best: vec![v],
            termination: Termination::FixedBounds,
        });
    }
    let np = (cfg.popsize * n).max(5);
    // Latin hypercube in the unit box.
    let mut pop: Vec<Vec<f64>> = vec![vec![0.0; n]; np];
    let seg = 1.0 / np as f64;
    for d in 0..n {
        let mut col: Vec<f64> = (0..np)
            .map(|i| seg * rng.uniform() + i as f64 * seg)
            .collect();
        rng.shuffle(&mut col);
        for (member, v) in pop.iter_mut().zip(col) {
            member[d] = v;
        }
    }
    if let Some(x0) = x0 {
        pop[0] = x0
            .iter()
            .zip(bounds)
            .map(|(&v, &(lo, hi))| {
                if hi > lo {
                    ((v.clamp(lo, hi) - lo) / (hi - lo)).clamp(0.0, 1.0)
                } else {
                    0.0
                }
            })
            .collect();
    }
    let budget = cfg.max_evals.max(1);
    let mut energy = vec![f64::INFINITY; np];
    for i in 0..np {
        if nfev >= budget {
            break;
        }
        energy[i] = eval(&pop[i], &mut nfev);
    }
    let best = (0..np)
        .min_by(|&a, &b| energy[a].total_cmp(&energy[b]))
        .unwrap_or(0);
    pop.swap(0, best);
    energy.swap(0, best);
    let mut generation_best = vec![energy[0]];
    let mut termination = Termination::MaxEvals;
    let mut generations = 0;
    let converged = |energy: &[f64]| {
        let finite: Vec<f64> = energy.iter().copied().filter(|e| e.is_finite()).collect();
        if finite.len() < energy.len() {
            return false;
        }
        let mean = finite.iter().sum::<f64>() / finite.len() as f64;
        let var = finite.iter().map(|e| (e - mean) * (e - mean)).sum::<f64>() / finite.len() as f64;
        var.sqrt() <= cfg.atol + cfg.tol * mean.abs()
    };
    'outer: while nfev < budget {
        if generations >= cfg.min_generations && converged(&energy) {
            termination = Termination::Converged;
            break;
        }
        let fmut = if cfg.mutation.0 == cfg.mutation.1 {
            cfg.mutation.0
        } else {
            rng.range(cfg.mutation.0, cfg.mutation.1)
        };
        for c in 0..np {
            if nfev >= budget {
                break 'outer;
            }
            // Two distinct members other than the candidate.
            let r0 = loop {
                let r = rng.below(np);
                if r != c {
                    break r;
                }
            };
            let r1 = loop {
                let r = rng.below(np);
                if r != c && r != r0 {
                    break r;
                }
            };
            let fill = rng.below(n);
            let mut trial = pop[c].clone();
            for d in 0..n {
                if d == fill || rng.uniform() < cfg.recombination {
                    trial[d] = pop[0][d] + fmut * (pop[r0][d] - pop[r1][d]);
                }
            }
            for v in &mut trial {
                if !(0.0..=1.0).contains(v) {
                    *v = rng.uniform();
                }
            }
            let e = eval(&trial, &mut nfev);
            if e <= energy[c] {
                pop[c] = trial;
                energy[c] = e;
                if e < energy[0] {
                    pop.swap(0, c);
                    energy.swap(0, c);
                }
            }
        }
        generations += 1;
        generation_best.push(energy[0]);
    }
    if termination == Termination::MaxEvals
        && generations >= cfg.min_generations
        && converged(&energy)
    {
        termination = Termination::Converged;
    }
    let mut x = to_real(&pop[0], bounds);
    let mut fbest = energy[0];
    let mut polish_nfev = 0;
    if cfg.polish_evals > 0 {
        let nm = NelderMeadConfig {
            max_evals: cfg.polish_evals,
            ..NelderMeadConfig::default()
        };
        let r = nelder_mead(&mut |p: &[f64]| f(p), bounds, &x, &nm)?;
        polish_nfev = r.nfev;
        if r.f < fbest {
            x = r.x;
            fbest = r.f;
        }
    }
    Ok(DeResult {
        x,
        f: fbest,
        nfev,
        polish_nfev,
        population_size: np,
        generations,
        generation_best,
        termination,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere(x: &[f64]) -> f64 {
        x.iter().map(|v| (v - 0.3) * (v - 0.3)).sum()
    }

    fn rastrigin(x: &[f64]) -> f64 {
        10.0 * x.len() as f64
            + x.iter()
                .map(|v| v * v - 10.0 * (std::f64::consts::TAU * v).cos())
                .sum::<f64>()
    }

    fn rosenbrock(x: &[f64]) -> f64 {
        (0..x.len() - 1)
            .map(|i| 100.0 * (x[i + 1] - x[i] * x[i]).powi(2) + (1.0 - x[i]).powi(2))
            .sum()
    }

    #[test]
    fn converges_on_analytic_functions_within_budget() {
        let b = vec![(-5.0, 5.0); 4];
        let r = differential_evolution(
            &mut |x| sphere(x),
            &b,
            None,
            &DeConfig {
                max_evals: 4000,
                tol: 1e-8,
                ..DeConfig::default()
            },
        )
        .expect("de");
        assert!(r.f < 1e-6, "sphere {}", r.f);
        assert!(r.nfev <= 4000);
        let b = vec![(-5.12, 5.12); 2];
        let r = differential_evolution(
            &mut |x| rastrigin(x),
            &b,
            None,
            &DeConfig {
                max_evals: 3000,
                tol: 1e-10,
                ..DeConfig::default()
            },
        )
        .expect("de");
        assert!(r.f < 1e-3, "rastrigin {} at {:?}", r.f, r.x);
        let b = vec![(-2.0, 2.0); 2];
        let r = differential_evolution(
            &mut |x| rosenbrock(x),
            &b,
            None,
            &DeConfig {
                max_evals: 6000,
                tol: 1e-12,
                polish_evals: 400,
                ..DeConfig::default()
            },
        )
        .expect("de");
        assert!(
            r.f < 1e-6 && (r.x[0] - 1.0).abs() < 1e-2,
            "rosenbrock {} at {:?}",
            r.f,
            r.x
        );
    }

    #[test]
    fn repeats_its_trace_for_a_seed() {
        let b = vec![(-5.12, 5.12); 3];
        let cfg = DeConfig {
            max_evals: 900,
            seed: 42,
            ..DeConfig::default()
        };
        let traced = || {
            let mut trace = Vec::new();
            let r = differential_evolution(
                &mut |x| {
                    trace.push(x.to_vec());
                    rastrigin(x)
                },
                &b,
                None,
                &cfg,
            )
            .expect("de");
            (trace, r)
        };
        let (trace_a, a) = traced();
        let (trace_b, bb) = traced();
        assert_eq!(trace_a, trace_b);
        assert_eq!(a, bb);
        let c = differential_evolution(
            &mut |x| rastrigin(x),
            &b,
            None,
            &DeConfig { seed: 43, ..cfg },
        )
        .expect("de");
        assert_ne!(a.generation_best, c.generation_best);
    }

    #[test]
    fn x0_is_in_the_initial_population_and_budget_is_respected() {
        let b = vec![(-1.0, 1.0); 2];
        let mut first = None;
        let r = differential_evolution(
            &mut |x| {
                if first.is_none() {
                    first = Some(x.to_vec());
                }
                sphere(x)
            },
            &b,
            Some(&[0.3, 0.3]),
            &DeConfig {
                max_evals: 7,
                ..DeConfig::default()
            },
        )
        .expect("de");
        let first = first.expect("evaluated");
        assert!(
            (first[0] - 0.3).abs() < 1e-12 && (first[1] - 0.3).abs() < 1e-12,
            "{first:?}"
        );
        assert_eq!(r.nfev, 7);
        assert!(r.f < 1e-12);
        let fixed = differential_evolution(
            &mut |x| sphere(x),
            &[(1.0, 1.0)],
            None,
            &DeConfig::default(),
        )
        .expect("de");
        assert_eq!(fixed.termination, Termination::FixedBounds);
        assert!(differential_evolution(
            &mut |x| sphere(x),
            &[(1.0, 0.0)],
            None,
            &DeConfig::default()
        )
        .is_err());
    }

    #[test]
    fn a_flat_initial_population_still_searches_for_min_generations() {
        // A plateau at 1.0 with a narrow well at 0.8: every member of the initial population
        // lands on the plateau, so SciPy's test (std 0 ≤ tol·|mean|) stops at once.
        let well = |x: &[f64]| {
            let d2: f64 = x.iter().map(|v| (v - 0.8) * (v - 0.8)).sum();
            if d2 < 0.04 {
                d2 - 0.04
            } else {
                0.0
            }
        };
        let b = vec![(-1.0, 1.0); 2];
        let scipy = differential_evolution(
            &mut |x| well(x),
            &b,
            Some(&[0.0, 0.0]),
            &DeConfig {
                popsize: 2,
                max_evals: 2000,
                ..DeConfig::default()
            },
        )
        .expect("de");
        let searching = differential_evolution(
            &mut |x| well(x),
            &b,
            Some(&[0.0, 0.0]),
            &DeConfig {
                popsize: 2,
                max_evals: 2000,
                min_generations: 60,
                ..DeConfig::default()
            },
        )
        .expect("de");
        assert!(
            searching.generations >= 60,
            "{} generations",
            searching.generations
        );
        assert_eq!(
            (scipy.generations, scipy.f),
            (0, 0.0),
            "SciPy's rule stops flat"
        );
        assert!(searching.nfev > scipy.nfev);
        assert!(
            searching.f < -0.02,
            "the well was not found: f {} at {:?}",
            searching.f,
            searching.x
        );
    }
}

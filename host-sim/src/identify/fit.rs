//! Fitting a contact law to drop tests (thesis §3.3.2, Figs. 3.8–3.10): Nelder–Mead (argmin)
//! on the error of [`super::cost`], as the thesis did with MATLAB's `fminsearch`; several laws
//! compared by Akaike's criterion; the fit's uncertainty from [`super::uncertainty`].

use anyhow::{Context, Result, bail};
use argmin::core::{CostFunction, Executor, State};
use argmin::solver::neldermead::NelderMead;
use rayon::prelude::*;
use shared::model::{ContactLaw, ContactLawKind};

use super::cost::{DropSetup, DropTest, Problem, Residual, SimDrop, Weights};
use super::data::DropData;
use super::uncertainty::Uncertainty;

/// Gauss–Newton iterations after Nelder–Mead ([`fit_law_joint`]).
const GAUSS_NEWTON_POLISH: usize = 4;

/// A fitted law.
#[derive(Debug, Clone)]
pub struct Fit {
    /// The law with its fitted parameters.
    pub law: ContactLaw,
    /// The error at the fit (all traces together: `J` is the sum of the traces' errors, the
    /// RMS values are over all their impacts and samples).
    pub residual: Residual,
    /// Cost evaluations (each one drop simulation per trace) spent.
    pub evaluations: u64,
    /// Per trace, in the order given: its own error and the simulated drop at the fit (all
    /// samples kept, for plots).
    pub traces: Vec<TraceFit>,
    /// The parameters' uncertainty at the fit, or why it could not be estimated.
    pub uncertainty: Result<Uncertainty, String>,
    /// Terms of the error (`J = Σ r̃²`): peaks, times and profile samples of all traces.
    pub terms: usize,
}

impl Fit {
    /// Parameters of the law.
    pub fn parameters(&self) -> usize {
        crate::config::coordinate_names(self.law.kind()).len()
    }

    /// Akaike's information criterion on the error's terms, `n ln(J/n) + 2p` (`n` terms, `p`
    /// parameters): the same terms for every law of one identification, so laws with more
    /// parameters pay for them.
    pub fn aic(&self) -> f64 {
        let n = self.terms.max(1) as f64;
        let p = self.parameters() as f64;
        n * (self.residual.cost / n).max(1e-300).ln() + 2.0 * p
    }

    /// The AIC with the small-sample correction (Hurvich and Tsai 1989),
    /// `AIC + 2p(p + 1)/(n − p − 1)`: the laws are ranked by it (differences below 2 do not
    /// tell two laws apart). `+∞` when `n ≤ p + 1` (too few terms to rank).
    pub fn aicc(&self) -> f64 {
        let (n, p) = (self.terms as f64, self.parameters() as f64);
        if n <= p + 1.0 {
            return f64::INFINITY;
        }
        self.aic() + 2.0 * p * (p + 1.0) / (n - p - 1.0)
    }
}

/// One trace's part of a [`Fit`].
#[derive(Debug, Clone)]
pub struct TraceFit {
    /// This trace's error at the fit.
    pub residual: Residual,
    /// The simulated drop of this trace's setup at the fit (all samples kept).
    pub sim: SimDrop,
}

fn start_point(law: ContactLawKind, data: &DropData) -> Vec<f64> {
    let e = data
        .impacts
        .get(1)
        .map_or(0.5, |i1| {
            (i1.peak_n / data.impacts[0].peak_n).powf(2.5 / 3.0)
        })
        .clamp(0.05, 0.95);
    match law {
        ContactLawKind::SpringDashpot => vec![0.0, 0.0],
        ContactLawKind::Hertz => vec![0.0, 1.5],
        ContactLawKind::HuntCrossley => vec![0.0, 1.5, 0.0],
        ContactLawKind::LankaraniNikravesh => vec![0.0, 1.5, e],
    }
}

fn simplex(law: ContactLawKind, x0: &[f64]) -> Vec<Vec<f64>> {
    let steps: &[f64] = match law {
        ContactLawKind::SpringDashpot => &[0.4, 0.4],
        ContactLawKind::Hertz => &[0.3, 0.2],
        ContactLawKind::HuntCrossley => &[0.3, 0.2, 0.5],
        ContactLawKind::LankaraniNikravesh => &[0.3, 0.2, 0.1],
    };
    let mut s = vec![x0.to_vec()];
    for (i, &h) in steps.iter().enumerate() {
        let mut p = x0.to_vec();
        // Step inward for a bounded coordinate near its upper bound.
        p[i] += if law == ContactLawKind::LankaraniNikravesh && i == 2 && x0[2] + h > 1.0 {
            -h
        } else {
            h
        };
        s.push(p);
    }
    s
}

/// Fits `law` to the measured drop `data` with Nelder–Mead (argmin), restarting from the best
/// point with a fresh simplex until a restart improves the error by less than 0.1 % (at most 4
/// runs of at most `max_iters` iterations). One trace of [`fit_law_joint`].
///
/// # Errors
/// Invalid rig parameters or drop setup (checked with the preset law before fitting), or an
/// optimiser failure.
pub fn fit_law(
    setup: &DropSetup,
    data: &DropData,
    law: ContactLawKind,
    weights: Weights,
    max_iters: u64,
) -> Result<Fit> {
    let tests = [DropTest {
        setup: *setup,
        data: data.clone(),
    }];
    fit_law_joint(&tests, law, weights, max_iters)
}

/// Fits every law of `laws` to the drop tests `tests` jointly (one parameter set per law, the
/// error summed over the tests; at most `max_iters` Nelder–Mead iterations), the laws in
/// parallel; results in the order of `laws`.
///
/// # Errors
/// The first law whose fit fails (named).
pub fn fit_laws(
    tests: &[DropTest],
    laws: &[ContactLawKind],
    weights: Weights,
    max_iters: u64,
) -> Result<Vec<(ContactLawKind, Fit)>> {
    laws.par_iter()
        .map(|&k| {
            fit_law_joint(tests, k, weights, max_iters)
                .with_context(|| format!("fitting the {k} law"))
                .map(|f| (k, f))
        })
        .collect()
}

/// The law of `fits` with the lowest AICc ([`Fit::aicc`]: the same error terms for every law);
/// among laws with too few terms to rank (`+∞`), the lowest error `J`; `None` if `fits` is
/// empty.
pub fn best_by_aicc(fits: &[(ContactLawKind, Fit)]) -> Option<ContactLawKind> {
    fits.iter().min_by(|x, y| by_aicc(&x.1, &y.1)).map(|f| f.0)
}

/// The order of [`best_by_aicc`]: AICc, then the error `J`.
pub fn by_aicc(x: &Fit, y: &Fit) -> std::cmp::Ordering {
    x.aicc()
        .total_cmp(&y.aicc())
        .then(x.residual.cost.total_cmp(&y.residual.cost))
}

/// Fits one parameter set of `law` to several drop tests at once (e.g. two release heights):
/// the error is the sum of the traces' errors (module docs). Nelder–Mead as in [`fit_law`],
/// started from the first trace's data-based guess.
///
/// # Errors
/// No test, a test without impacts, invalid rig parameters or drop setup of any test (checked
/// with the preset law before fitting, named with the test's number), or an optimiser failure.
pub fn fit_law_joint(
    tests: &[DropTest],
    law: ContactLawKind,
    weights: Weights,
    max_iters: u64,
) -> Result<Fit> {
    let problem = Problem::new(tests, law, weights)?;
    let mut x = start_point(law, &tests[0].data);
    let mut best = problem.cost(&x).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut evaluations = 1u64;
    for _ in 0..4 {
        let solver = NelderMead::new(simplex(law, &x))
            .with_sd_tolerance(1e-12)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let res = Executor::new(problem.clone(), solver)
            .configure(|s| s.max_iters(max_iters).counting(true))
            .run()
            .map_err(|e| anyhow::anyhow!("Nelder–Mead: {e}"))?;
        evaluations += res
            .state()
            .get_func_counts()
            .get("cost_count")
            .copied()
            .unwrap_or(0);
        let cost = res.state().get_best_cost();
        let Some(p) = res.state().get_best_param().cloned() else {
            break;
        };
        let improved = cost < best * (1.0 - 1e-3);
        if cost < best {
            best = cost;
            x = p;
        }
        if !improved {
            break;
        }
    }
    // Gauss–Newton from Nelder–Mead's point: NM's stop (a restart gaining < 0.1 %) leaves
    // it up to about one standard deviation from the minimum along a flat valley.
    for _ in 0..GAUSS_NEWTON_POLISH {
        let Ok(law) = problem.law_at(&x) else { break };
        let Some(step) = problem
            .around(&x, &law)
            .ok()
            .and_then(|a| problem.gauss_newton(&a))
        else {
            break;
        };
        let next: Vec<f64> = x.iter().zip(&step).map(|(a, d)| a + d).collect();
        let cost = problem.cost(&next).map_err(|e| anyhow::anyhow!("{e}"))?;
        evaluations += 1 + 2 * x.len() as u64;
        if cost >= best {
            break;
        }
        let gain = best - cost;
        best = cost;
        x = next;
        if gain < 1e-6 * best {
            break;
        }
    }
    let Ok(law_fit) = problem.law_at(&x) else {
        bail!("the fit left the parameter bounds");
    };
    let (residual, each) = problem.residual(&law_fit)?;
    let mut traces = Vec::with_capacity(each.len());
    for (sim, r) in problem.simulate_whole(&law_fit)?.into_iter().zip(each) {
        traces.push(TraceFit { residual: r, sim });
    }
    let uncertainty = super::uncertainty::estimate(&problem, &x);
    let terms = problem.cost_term_count();
    Ok(Fit {
        terms,
        law: law_fit,
        residual,
        evaluations,
        traces,
        uncertainty,
    })
}

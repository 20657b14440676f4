//! The fitted contact law's uncertainty: 95 % intervals, correlations, and what the data leave
//! undetermined, said in words.
//!
//! ## Method (parametric bootstrap, linearised in the parameters)
//! The fit minimises `J(x) = Σ r̃_i(x, F)²` over the search coordinates `x` (module
//! [`super::contact`]), where the terms `r̃` depend on the measured samples `F` through the
//! preprocessing: thresholds, impact windows, peak estimates and centroids. Those are not
//! smooth in `F` (a noisy sample crosses the threshold, the largest sample of a flat top
//! changes), so the noise is propagated by simulation rather than by derivatives:
//! - the drop at the fit is simulated and sampled at each trace's sample times; [`REDRAWS`]
//!   times, white noise of the trace's own `σ` is added (ChaCha8, seeded: the same result on
//!   every machine) and the redrawn trace is preprocessed like the measurement;
//! - for each redraw `b`, one Gauss–Newton step from the fit gives where a fit of that trace
//!   would land: `δx_b = −R_b⁺ r̃_b`, with `r̃_b` the terms of the redrawn trace against the
//!   fitted drop and `R_b = ∂r̃_b/∂x` (central differences, step 1e-3, on drops simulated
//!   once for all redraws; `R⁺` from nalgebra's SVD);
//! - `Cov(x)` is the covariance of the `δx_b`.
//!
//! Redraws whose trace does not show the measured number of impacts are dropped (counted in
//! the method); fewer than half usable is an error.
//!
//! The reported coordinates are linear in `x`: `ln k_i` (the stiffness), `n`, `ln c_i`,
//! `ln λ_i`, `e`. Scale parameters (`k_i`, `c_i`, `λ_i`) get log-normal intervals
//! `[v e^{−1.96 s}, v e^{1.96 s}]`, the others `v ± 1.96 s`. Where the linearisation does not
//! hold (a parameter the data barely fix), the interval says so by its width; a direction
//! along which the error does not change at all (singular `R`) is reported as not identifiable.
//! Coverage on synthetic drop tests with known truth: `host-sim/tests/uncertainty.rs`.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::Serialize;
use shared::model::{ContactLaw, ContactLawKind};

use super::contact::{Problem, SimDrop};

/// The normal quantile of a two-sided 95 % interval.
pub const Z95: f64 = 1.959_963_984_540_054;
/// An interval wider than this (relative half-width) is reported as poorly fixed.
pub const WIDE_REL: f64 = 0.10;
/// A correlation beyond this is reported as a trade-off.
pub const STRONG_CORRELATION: f64 = 0.95;
/// Noise redraws of the parametric bootstrap.
pub const REDRAWS: usize = 100;
/// The step of the central differences in the search coordinates.
const JACOBIAN_STEP: f64 = 1e-3;
/// A singular value below this fraction of the largest marks a direction the data do not fix.
const SINGULAR: f64 = 1e-9;

/// One fitted parameter with its 95 % interval.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamEstimate {
    /// Symbol (`k_i`, `c_i`, `n`, `λ_i`, `e`).
    pub name: &'static str,
    /// Its key in the config file (`stiffness_n_m`, `damping_n_s_m`, `stiffness`, `exponent`,
    /// `lambda_s_m`, `restitution`).
    pub key: &'static str,
    /// Unit.
    pub unit: String,
    /// Fitted value.
    pub value: f64,
    /// 95 % interval (`±∞` where the data do not fix it).
    pub ci95: [f64; 2],
    /// Standard deviation of the reported coordinate (of `ln v` for a scale parameter).
    pub sd: f64,
    /// A scale parameter (log-normal interval).
    pub log: bool,
}

impl ParamEstimate {
    /// The interval's larger half-width relative to the value (∞ when unbounded).
    pub fn rel_half_width(&self) -> f64 {
        if self.log {
            (Z95 * self.sd).exp() - 1.0
        } else {
            Z95 * self.sd / self.value.abs().max(1e-300)
        }
    }
}

/// The uncertainty of a fitted law.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Uncertainty {
    /// How it was estimated.
    pub method: String,
    /// The law.
    pub law: ContactLawKind,
    /// The reported coordinates (`ln_stiffness`, `exponent`, `ln_damping_n_s_m`, …): what
    /// `select --uncertainty` draws in.
    pub coordinates: Vec<&'static str>,
    /// Their values at the fit.
    pub mean: Vec<f64>,
    /// Their covariance.
    pub covariance: Vec<Vec<f64>>,
    /// The parameters, in the law's order.
    pub params: Vec<ParamEstimate>,
    /// Correlations of the coordinates.
    pub correlation: Vec<Vec<f64>>,
    /// Whether every direction is fixed by the data.
    pub identifiable: bool,
    /// What the data leave undetermined, why, and what fixes it (empty when all is fixed).
    pub notes: Vec<String>,
    /// Sensor noise of each trace, N.
    pub noise_n: Vec<f64>,
    /// Samples per contact of the least resolved trace (width at half maximum over the sampling
    /// step).
    pub samples_per_contact: f64,
}

impl Uncertainty {
    /// The `[uncertainty]` table of a fit's config file: the coordinates `select --uncertainty`
    /// draws in, their mean and covariance, the 95 % intervals and the notes.
    ///
    /// # Errors
    /// Serialisation failure.
    pub fn toml_table(&self) -> anyhow::Result<String> {
        let u = self;
        let mut t = toml::Table::new();
        t.insert("method".into(), u.method.clone().into());
        t.insert("law".into(), u.law.to_string().into());
        t.insert(
            "coordinates".into(),
            toml::Value::Array(u.coordinates.iter().map(|c| (*c).into()).collect()),
        );
        t.insert(
            "mean".into(),
            toml::Value::Array(u.mean.iter().map(|&v| v.into()).collect()),
        );
        t.insert(
            "covariance".into(),
            toml::Value::Array(
                u.covariance
                    .iter()
                    .map(|row| toml::Value::Array(row.iter().map(|&v| v.into()).collect()))
                    .collect(),
            ),
        );
        let mut ci = toml::Table::new();
        for p in &u.params {
            ci.insert(
                p.key.into(),
                toml::Value::Array(vec![p.ci95[0].into(), p.ci95[1].into()]),
            );
        }
        t.insert("ci95".into(), toml::Value::Table(ci));
        t.insert(
            "noise_n".into(),
            toml::Value::Array(u.noise_n.iter().map(|&v| v.into()).collect()),
        );
        t.insert(
            "notes".into(),
            toml::Value::Array(u.notes.iter().map(|n| n.clone().into()).collect()),
        );
        let mut root = toml::Table::new();
        root.insert("uncertainty".into(), toml::Value::Table(t));
        anyhow::Context::context(toml::to_string(&root), "writing the [uncertainty] table")
    }
}

struct Coord {
    name: &'static str,
    key: &'static str,
    symbol: &'static str,
    log: bool,
    /// The fit's bounds on a coordinate that has them (module [`super::contact`]).
    bounds: Option<(f64, f64)>,
}

fn coords(law: ContactLawKind) -> Vec<Coord> {
    let c = |name, key, symbol, log| Coord {
        name,
        key,
        symbol,
        log,
        bounds: match key {
            "exponent" => Some((1.0, 3.0)),
            "restitution" => Some((0.01, 1.0)),
            _ => None,
        },
    };
    match law {
        ContactLawKind::SpringDashpot => vec![
            c("ln_stiffness_n_m", "stiffness_n_m", "k_i", true),
            c("ln_damping_n_s_m", "damping_n_s_m", "c_i", true),
        ],
        ContactLawKind::Hertz => vec![
            c("ln_stiffness", "stiffness", "k_i", true),
            c("exponent", "exponent", "n", false),
        ],
        ContactLawKind::HuntCrossley => vec![
            c("ln_stiffness", "stiffness", "k_i", true),
            c("exponent", "exponent", "n", false),
            c("ln_lambda_s_m", "lambda_s_m", "λ_i", true),
        ],
        ContactLawKind::LankaraniNikravesh => vec![
            c("ln_stiffness", "stiffness", "k_i", true),
            c("exponent", "exponent", "n", false),
            c("restitution", "restitution", "e", false),
        ],
    }
}

/// The names of the law's reported coordinates (the `[uncertainty]` table's `coordinates`).
pub fn coordinate_names(law: ContactLawKind) -> Vec<&'static str> {
    coords(law).iter().map(|c| c.name).collect()
}

/// The reported coordinates as a linear map of the search coordinates: `rep = G x + b`.
fn linear_map(problem: &Problem<'_>) -> (DMatrix<f64>, DVector<f64>) {
    let s = problem.x0_scale;
    let ln_d = problem.delta_ref.ln();
    match problem.law {
        ContactLawKind::SpringDashpot => (
            DMatrix::identity(2, 2),
            DVector::from_vec(vec![s[0].ln(), s[1].ln()]),
        ),
        ContactLawKind::Hertz => (
            DMatrix::from_row_slice(2, 2, &[1.0, -ln_d, 0.0, 1.0]),
            DVector::from_vec(vec![s[0].ln(), 0.0]),
        ),
        ContactLawKind::HuntCrossley => (
            DMatrix::from_row_slice(3, 3, &[1.0, -ln_d, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
            DVector::from_vec(vec![s[0].ln(), 0.0, s[2].ln()]),
        ),
        ContactLawKind::LankaraniNikravesh => (
            DMatrix::from_row_slice(3, 3, &[1.0, -ln_d, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
            DVector::from_vec(vec![s[0].ln(), 0.0, 0.0]),
        ),
    }
}

/// The law at reported coordinates `rep` (e.g. a draw of `select --uncertainty`).
pub fn law_from_coordinates(law: ContactLawKind, rep: &[f64]) -> Option<ContactLaw> {
    let get = |i: usize| rep.get(i).copied();
    let l = match law {
        ContactLawKind::SpringDashpot => ContactLaw::SpringDashpot {
            stiffness_n_m: get(0)?.exp(),
            damping_n_s_m: get(1)?.exp(),
        },
        ContactLawKind::Hertz => ContactLaw::Hertz {
            stiffness: get(0)?.exp(),
            exponent: get(1)?,
        },
        ContactLawKind::HuntCrossley => ContactLaw::HuntCrossley {
            stiffness: get(0)?.exp(),
            exponent: get(1)?,
            lambda_s_m: get(2)?.exp(),
        },
        ContactLawKind::LankaraniNikravesh => ContactLaw::LankaraniNikravesh {
            stiffness: get(0)?.exp(),
            exponent: get(1)?,
            restitution: get(2)?,
        },
    };
    l.validate().is_ok().then_some(l)
}

/// The uncertainty of the fit at search coordinates `x` of `problem` (module docs); `Err`
/// with the reason when it cannot be estimated (e.g. the law at `x` is invalid or a drop
/// simulation fails).
pub(crate) fn estimate(problem: &Problem<'_>, x: &[f64]) -> Result<Uncertainty, String> {
    let law = problem
        .law_at(x)
        .map_err(|_| "the fit is outside the parameter bounds".to_string())?;
    let p = x.len();
    let center = problem.simulate(&law, true).map_err(|e| format!("{e:#}"))?;
    // The drops one step up and down each coordinate (None beyond a bound).
    let around: Vec<[Option<Vec<SimDrop>>; 2]> = (0..p)
        .map(|j| {
            [1.0, -1.0].map(|sign| {
                let mut xs = x.to_vec();
                xs[j] += sign * JACOBIAN_STEP;
                problem.simulate(&problem.law_at(&xs).ok()?, false).ok()
            })
        })
        .collect();
    // The terms at the fit and their Jacobian for one data set (the measured or a redrawn one).
    let linear = |pr: &Problem<'_>| -> Option<(DVector<f64>, DMatrix<f64>)> {
        let r0 = pr.terms(&center);
        let n = r0.len();
        let mut jac = DMatrix::<f64>::zeros(n, p);
        for (j, [up, down]) in around.iter().enumerate() {
            let at =
                |s: &Option<Vec<SimDrop>>| s.as_ref().map(|s| pr.terms(s)).filter(|t| t.len() == n);
            let (col, span): (Vec<f64>, f64) = match (at(up), at(down)) {
                (Some(u), Some(d)) => (u.iter().zip(&d).map(|(u, d)| u - d).collect(), 2.0),
                (Some(u), None) => (u.iter().zip(&r0).map(|(u, c)| u - c).collect(), 1.0),
                (None, Some(d)) => (r0.iter().zip(&d).map(|(c, d)| c - d).collect(), 1.0),
                (None, None) => return None,
            };
            for (i, v) in col.iter().enumerate() {
                jac[(i, j)] = v / (span * JACOBIAN_STEP);
            }
        }
        Some((DVector::from_vec(r0), jac))
    };
    let (_, jac) = linear(problem)
        .ok_or_else(|| "the error cannot be evaluated around the fit".to_string())?;
    let svd = jac.svd(true, true);
    let s_max = svd.singular_values.max();
    let s_min = svd.singular_values.min();
    let identifiable = s_max > 0.0 && s_min > SINGULAR * s_max;
    // The redraws, each one Gauss–Newton step from the fit.
    let steps: Vec<DVector<f64>> = (0..REDRAWS as u64)
        .into_par_iter()
        .filter_map(|b| {
            let data = problem.synthetic_data(&center, b)?;
            let (r, jac) = linear(&problem.with_data(&data))?;
            let svd = jac.svd(true, true);
            let tol = SINGULAR * svd.singular_values.max().max(1e-300);
            Some(-(svd.pseudo_inverse(tol).ok()? * r))
        })
        .collect();
    let used = steps.len();
    if 2 * used < REDRAWS {
        return Err(format!(
            "only {used} of {REDRAWS} noise redraws of the fitted drop show the measured impacts"
        ));
    }
    let mean_x = steps.iter().fold(DVector::zeros(p), |acc, d| acc + d) / used as f64;
    let cov_x = steps.iter().fold(DMatrix::zeros(p, p), |acc, d| {
        let c = d - &mean_x;
        acc + &c * c.transpose()
    }) / (used - 1) as f64;
    let noise = problem.noise_n();
    let (g, b) = linear_map(problem);
    let xv = DVector::from_column_slice(x);
    let mean = &g * xv + b;
    let mut cov = &g * cov_x * g.transpose();
    // Directions the data do not fix: unbounded along the right singular vectors of the
    // vanishing singular values (mapped to the reported coordinates).
    let mut free = vec![false; p];
    if !identifiable {
        for (k, &sv) in svd.singular_values.iter().enumerate() {
            if sv <= SINGULAR * s_max
                && let Some(vt) = &svd.v_t
            {
                let dir = &g * vt.row(k).transpose();
                let norm = dir.norm().max(1e-300);
                for i in 0..p {
                    if (dir[i] / norm).abs() > 0.1 {
                        free[i] = true;
                    }
                }
            }
        }
        for i in 0..p {
            if free[i] {
                cov[(i, i)] = f64::INFINITY;
            }
        }
    }
    let cs = coords(problem.law);
    let unit = |c: &Coord| -> String {
        match (problem.law, c.key) {
            (ContactLawKind::SpringDashpot, "stiffness_n_m") => "N/m".into(),
            (ContactLawKind::SpringDashpot, _) => "N s/m".into(),
            (_, "stiffness") => format!("N/m^{:.3}", mean[1]),
            (_, "lambda_s_m") => "s/m".into(),
            _ => String::new(),
        }
    };
    let mut params = Vec::with_capacity(p);
    for (i, c) in cs.iter().enumerate() {
        let sd = cov[(i, i)].sqrt();
        let (value, ci95) = if c.log {
            let v = mean[i].exp();
            (v, [(mean[i] - Z95 * sd).exp(), (mean[i] + Z95 * sd).exp()])
        } else {
            let (lo, hi) = c.bounds.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
            (
                mean[i],
                [(mean[i] - Z95 * sd).max(lo), (mean[i] + Z95 * sd).min(hi)],
            )
        };
        params.push(ParamEstimate {
            name: c.symbol,
            key: c.key,
            unit: unit(c),
            value,
            ci95,
            sd,
            log: c.log,
        });
    }
    let mut correlation = vec![vec![0.0; p]; p];
    for i in 0..p {
        for j in 0..p {
            correlation[i][j] = if i == j {
                1.0
            } else if free[i] || free[j] {
                f64::NAN
            } else {
                cov[(i, j)] / (cov[(i, i)] * cov[(j, j)]).sqrt()
            };
        }
    }
    let mut u = Uncertainty {
        method: format!(
            "parametric bootstrap: {used} of {REDRAWS} noise redraws, one Gauss–Newton step each"
        ),
        law: problem.law,
        coordinates: cs.iter().map(|c| c.name).collect(),
        mean: mean.iter().copied().collect(),
        covariance: (0..p)
            .map(|i| (0..p).map(|j| cov[(i, j)]).collect())
            .collect(),
        params,
        correlation,
        identifiable,
        notes: Vec::new(),
        noise_n: noise,
        samples_per_contact: problem.samples_per_contact(),
    };
    u.notes = notes(&u, &cs, problem);
    Ok(u)
}

/// How a change of coordinate `c` reads (`Δk_i/k_i` for a scale parameter, `Δn` otherwise).
fn delta(c: &Coord) -> String {
    if c.log {
        format!("Δ{0}/{0}", c.symbol)
    } else {
        format!("Δ{}", c.symbol)
    }
}

/// The identifiability notes: each poorly fixed parameter and each strong trade-off, why, and
/// what fixes it.
fn notes(u: &Uncertainty, cs: &[Coord], problem: &Problem<'_>) -> Vec<String> {
    let mut out = Vec::new();
    for (c, par) in cs.iter().zip(&u.params) {
        if let Some((lo, hi)) = c.bounds
            && (par.value <= lo + 1e-3 * (hi - lo) || par.value >= hi - 1e-3 * (hi - lo))
        {
            out.push(format!(
                "{} = {:.4} sits on the fit's bound ({lo} ≤ {} ≤ {hi}): the {} law does not \
                 describe these data (its interval is cut at the bound)",
                par.name, par.value, par.name, u.law
            ));
        }
    }
    let p = cs.len();
    let mut pairs = Vec::new();
    for i in 0..p {
        for j in i + 1..p {
            let rho = u.correlation[i][j];
            if rho.abs() > STRONG_CORRELATION {
                // Along the trade-off: Δa ≈ (cov_ab / var_b) Δb.
                let slope = u.covariance[i][j] / u.covariance[j][j];
                pairs.push((i, j));
                out.push(format!(
                    "{} and {} trade off (correlation {:+.3}): {} ≈ {:.3} {} leaves the error nearly unchanged",
                    cs[i].symbol,
                    cs[j].symbol,
                    rho,
                    delta(&cs[i]),
                    slope,
                    delta(&cs[j])
                ));
            }
        }
    }
    for (i, par) in u.params.iter().enumerate() {
        if !par.sd.is_finite() {
            out.push(format!(
                "{} is not identifiable from these data: the error does not change along a \
                 direction that moves it",
                par.name
            ));
        } else if par.rel_half_width() > WIDE_REL {
            let partner = pairs
                .iter()
                .find(|(a, b)| *a == i || *b == i)
                .map(|(a, b)| {
                    if *a == i {
                        cs[*b].symbol
                    } else {
                        cs[*a].symbol
                    }
                });
            out.push(format!(
                "{} is fixed to ±{:.0} % only (95 %){}",
                par.name,
                100.0 * par.rel_half_width(),
                partner.map_or(String::new(), |q| format!(
                    ", through its trade-off with {q}"
                ))
            ));
        }
    }
    if !out.is_empty() {
        let mut fixes = Vec::new();
        let spc = u.samples_per_contact;
        if problem.weights.profile == 0.0 {
            if spc >= super::contact::PROFILE_MIN_SAMPLES {
                fixes.push(format!(
                    "the profile error (--error profile): the trace resolves the contact \
                     ({spc:.0} samples per contact)"
                ));
            } else {
                fixes.push(format!(
                    "a faster capture (≥ {:.0} samples per contact, this trace {spc:.1}; \
                     `rig capture` records at 100 kHz), then the profile error",
                    super::contact::PROFILE_MIN_SAMPLES
                ));
            }
        }
        if problem.trace_count() == 1 && problem.law != ContactLawKind::SpringDashpot {
            fixes.push(
                "a second drop test from another height (--trace … --release-mm …, fitted \
                 jointly): impact speeds a factor ~10 apart separate k_i from n"
                    .into(),
            );
        }
        if fixes.is_empty() {
            fixes.push("more impacts or less noise (a larger release, more drop tests)".into());
        }
        out.push(format!("what fixes it: {}", fixes.join("; or ")));
    }
    out
}

//! What an identified contact law's uncertainty does to the main job (`select --uncertainty`):
//! parameter sets drawn from the fit's normal distribution (the `[uncertainty]` table of
//! `identify contact --out`, in its coordinates: `ln` of the scale parameters), the whole
//! selection run for each (responses at the nominal and perturbed gaps), and the spread of the
//! answers:
//! - the operating frequency and its `F_i/mg` as median and 95 % range over the draws;
//! - the share of draws in which the nominal answer's frequency is still `z = 1/1`;
//! - a robust recommendation: of the sweep's frequencies that are `1/1` in every draw, the one
//!   with the best worst-case `F_i/mg`;
//! - per frequency, the median and 95 % range of `F_i/mg` (the figure's band).
//!
//! Draws whose law is invalid (e.g. a negative damping) are redrawn and counted. The draws are
//! seeded (ChaCha8: the same on every machine) and run in parallel.

use anyhow::{Context, Result, bail, ensure};
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::Serialize;
use shared::analysis::SelectionError;
use shared::model::ContactLawKind;

use crate::config::{Setup, UncertaintyTable, law_from_coordinates};
use crate::selection::{SelectReport, compute_parts};

/// Median and 95 % range.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// 2.5 % quantile.
    pub lo95: f64,
    /// 97.5 % quantile.
    pub hi95: f64,
}

impl Spread {
    /// Of `values` (at least one).
    pub fn of(values: &[f64]) -> Spread {
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let q = |p: f64| {
            let x = p * (v.len() - 1) as f64;
            let (i, f) = (x.floor() as usize, x - x.floor());
            v[i] + (v[(i + 1).min(v.len() - 1)] - v[i]) * f
        };
        Spread {
            median: q(0.5),
            lo95: q(0.025),
            hi95: q(0.975),
        }
    }
}

/// One frequency of the sweep over the draws.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BandPoint {
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Hz.
    pub freq_hz: f64,
    /// `F_i/mg` over the draws.
    pub impact_force_mg: Spread,
    /// Share of draws that are `z = 1/1` here.
    pub one_one_share: f64,
}

/// The robust recommendation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RobustPoint {
    /// Hz.
    pub freq_hz: f64,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// The smallest `F_i/mg` over the draws there.
    pub worst_impact_force_mg: f64,
    /// The median.
    pub median_impact_force_mg: f64,
}

/// What the draws say (the JSON `uncertainty` of `select --json --uncertainty`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Propagation {
    /// Draws run.
    pub draws: usize,
    /// Draws rejected (invalid law) and redrawn.
    pub redrawn: usize,
    /// Seed.
    pub seed: u64,
    /// Draws in which no robust `1/1` point was found.
    pub no_selection: usize,
    /// The operating frequency over the draws that found one, Hz.
    pub freq_hz: Spread,
    /// Its `F_i/mg`.
    pub impact_force_mg: Spread,
    /// Share of draws in which the nominal operating frequency is still `z = 1/1`.
    pub nominal_one_one_share: f64,
    /// The frequency that stays `1/1` in every draw with the best worst-case `F_i/mg`.
    pub robust: Option<RobustPoint>,
    /// Per sweep frequency at the nominal gap.
    pub band: Vec<BandPoint>,
}

/// Normal draws in the table's coordinates: `mean + L z` with `L` a Cholesky factor of the
/// covariance (eigen-decomposition, negative eigenvalues clamped, when it is only
/// semi-definite).
fn factor(cov: &[Vec<f64>]) -> DMatrix<f64> {
    let p = cov.len();
    let c = DMatrix::from_fn(p, p, |i, j| cov[i][j]);
    if let Some(l) = c.clone().cholesky() {
        return l.l();
    }
    let e = c.symmetric_eigen();
    let mut l = e.eigenvectors.clone();
    for (j, &ev) in e.eigenvalues.iter().enumerate() {
        let s = ev.max(0.0).sqrt();
        for i in 0..p {
            l[(i, j)] *= s;
        }
    }
    l
}

/// Runs the selection for `draws` parameter sets drawn from `table` (seeded with `seed`),
/// with a progress bar over the draws on a terminal. `nominal` is the selection at the fit.
///
/// # Errors
/// An unbounded table, too many invalid draws, or a failed response computation.
pub fn propagate(
    setup: &Setup,
    gap_mm: f64,
    table: &UncertaintyTable,
    nominal: &SelectReport,
    draws: usize,
    seed: u64,
) -> Result<Propagation> {
    table.check_bounded()?;
    ensure!(
        (8..=100_000).contains(&draws),
        "--draws = {draws} is out of range: allowed 8 ..= 100000"
    );
    let kind: ContactLawKind = table.law;
    let l = factor(&table.covariance);
    let mean = DVector::from_column_slice(&table.mean);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut laws = Vec::with_capacity(draws);
    let mut redrawn = 0;
    while laws.len() < draws {
        let z = DVector::from_fn(mean.len(), |_, _| {
            <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng)
        });
        let x = &mean + &l * z;
        match law_from_coordinates(kind, x.as_slice()) {
            Some(law) => laws.push(law),
            None => {
                redrawn += 1;
                if redrawn > 10 * draws {
                    bail!(
                        "the [uncertainty] distribution gives mostly invalid laws ({redrawn} \
                         redrawn): it is too wide to draw from"
                    );
                }
            }
        }
    }
    let bar = crate::progress::progress_of(draws, "uncertainty", "draws");
    let results: Vec<Result<(Option<SelectReport>, Vec<shared::observe::PointResult>)>> = laws
        .par_iter()
        .map(|law| {
            let mut s = setup.clone();
            s.params.contact = *law;
            // A draw without a robust 1/1 point still counts by its nominal response.
            let r = compute_parts(&s, gap_mm, "").and_then(|(rep, mut resp)| match rep {
                Ok(rep) => Ok((Some(rep), resp.swap_remove(0))),
                Err(SelectionError::NoOneToOneBand | SelectionError::NoRobustPoint { .. }) => {
                    Ok((None, resp.swap_remove(0)))
                }
                Err(e) => Err(anyhow::anyhow!("{e}")),
            });
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    let results = results
        .into_iter()
        .collect::<Result<Vec<_>>>()
        .context("a draw's response")?;
    let chosen: Vec<&SelectReport> = results.iter().filter_map(|r| r.0.as_ref()).collect();
    ensure!(
        !chosen.is_empty(),
        "no draw has a robust 1/1 operating point"
    );
    let sweep = setup.selection.omega_ratio;
    let ratios: Vec<f64> = (0..sweep.len()).map(|i| sweep.value(i)).collect();
    let natural = setup.params.natural_freq_hz();
    let nominal_index = ratios
        .iter()
        .position(|r| (r - nominal.omega_ratio).abs() < 1e-9)
        .context("internal: the nominal point is not on the sweep")?;
    let one_one = |r: &shared::observe::PointResult| r.regime == shared::observe::Regime::ONE_ONE;
    let nominal_one_one_share = results
        .iter()
        .filter(|r| r.1.get(nominal_index).is_some_and(one_one))
        .count() as f64
        / results.len() as f64;
    let mut band = Vec::with_capacity(ratios.len());
    let mut robust: Option<RobustPoint> = None;
    for (i, &ratio) in ratios.iter().enumerate() {
        let mg: Vec<f64> = results.iter().map(|r| r.1[i].impact_force_mg).collect();
        let ones = results.iter().filter(|r| one_one(&r.1[i])).count();
        let spread = Spread::of(&mg);
        band.push(BandPoint {
            omega_ratio: ratio,
            freq_hz: ratio * natural,
            impact_force_mg: spread,
            one_one_share: ones as f64 / results.len() as f64,
        });
        if ones == results.len() {
            let worst = mg.iter().copied().fold(f64::INFINITY, f64::min);
            if robust.is_none_or(|b| worst > b.worst_impact_force_mg) {
                robust = Some(RobustPoint {
                    freq_hz: ratio * natural,
                    omega_ratio: ratio,
                    worst_impact_force_mg: worst,
                    median_impact_force_mg: spread.median,
                });
            }
        }
    }
    let freqs: Vec<f64> = chosen.iter().map(|c| c.freq_hz).collect();
    let forces: Vec<f64> = chosen.iter().map(|c| c.impact_force_mg).collect();
    Ok(Propagation {
        draws,
        redrawn,
        seed,
        no_selection: results.len() - chosen.len(),
        freq_hz: Spread::of(&freqs),
        impact_force_mg: Spread::of(&forces),
        nominal_one_one_share,
        robust,
        band,
    })
}

//! Frequency responses: the canonical protocol from rest at every `Ω/ω` of a sweep, at one or
//! several gaps, all points in one parallel batch, and the CSV rows of one response.

use anyhow::Result;
use serde::Serialize;
use shared::analysis::Sweep;
use shared::observe::PointResult;
use shared::orbit::{Label, LabelSettings};

use crate::config::Setup;
use crate::runner::{OperatingPoint, evaluate_all, evaluate_all_labelled};

/// One CSV row of a frequency response.
#[derive(Debug, Clone, Serialize)]
pub struct ResponseRow {
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Excitation frequency, Hz.
    pub freq_hz: f64,
    /// Max impact force over the observation window, `F_i/mg`.
    pub impact_force_mg: f64,
    /// Regime `p/q`, `no impact`, `irregular` or `chaotic`.
    pub regime: String,
    /// Impacts in the observation window.
    pub impacts: u32,
    /// Transient periods before the window.
    pub transient_periods: u32,
    /// Whether a steady state was detected.
    pub settled: bool,
    /// Largest Lyapunov exponent per excitation period over a window after the protocol
    /// (empty with `--no-lyapunov`).
    pub lyapunov_per_period: Option<f64>,
    /// Its uncertainty: half the difference of the window's halves.
    pub lyapunov_uncertainty: Option<f64>,
    /// The protocol window's own regime where the exponent refined it (`irregular` that
    /// became `chaotic` or a period found by the extended run); empty otherwise.
    pub window_regime: Option<String>,
    /// Periods the extended run took to find the period (0: not needed).
    pub extra_periods: Option<u32>,
}

/// Every `(gap, Ω/ω)` of `gaps_m` (m) × `sweep`, gap outer.
fn grid_points(gaps_m: &[f64], sweep: &Sweep) -> Vec<OperatingPoint> {
    let n = sweep.len();
    gaps_m
        .iter()
        .flat_map(|&g| {
            (0..n).map(move |i| OperatingPoint {
                gap_m: g,
                omega_ratio: sweep.value(i),
            })
        })
        .collect()
}

/// The responses at each gap of `gaps_m` (m) over `sweep`, all points in one parallel batch
/// (progress bar labelled `what`, none if empty): one `Vec` of `sweep.len()` results per gap.
///
/// # Errors
/// The first invalid point.
pub fn compute(
    setup: &Setup,
    gaps_m: &[f64],
    sweep: &Sweep,
    what: &str,
) -> Result<Vec<Vec<PointResult>>> {
    let n = sweep.len();
    let points = grid_points(gaps_m, sweep);
    let all = evaluate_all(setup, &points, what)?;
    Ok(all.chunks(n).map(<[PointResult]>::to_vec).collect())
}

/// The responses at each gap of `gaps_m` (m) over `sweep` with their labels refined by the
/// largest Lyapunov exponent (`shared::orbit::label`): per gap, the results (their `regime`
/// the refined label) and the labels.
///
/// # Errors
/// The first invalid point.
pub fn compute_labelled(
    setup: &Setup,
    gaps_m: &[f64],
    sweep: &Sweep,
    what: &str,
    settings: &LabelSettings,
) -> Result<Vec<(Vec<PointResult>, Vec<Label>)>> {
    let n = sweep.len();
    let points = grid_points(gaps_m, sweep);
    let all = evaluate_all_labelled(setup, &points, what, settings)?;
    Ok(all
        .chunks(n)
        .map(|c| {
            c.iter()
                .map(|(r, l)| {
                    (
                        PointResult {
                            regime: l.regime,
                            ..*r
                        },
                        *l,
                    )
                })
                .unzip()
        })
        .collect())
}

/// CSV rows of one response (`results[i]` at `sweep.value(i)`), with the exponent's columns
/// from `labels` if given (`results` then carry the refined regimes).
pub fn rows(
    setup: &Setup,
    sweep: &Sweep,
    results: &[PointResult],
    labels: Option<&[Label]>,
) -> Vec<ResponseRow> {
    results
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let ratio = sweep.value(i);
            let LabelCells {
                lyapunov_per_period,
                lyapunov_uncertainty,
                window_regime,
                extra_periods,
            } = LabelCells::of(labels.and_then(|l| l.get(i)));
            ResponseRow {
                omega_ratio: ratio,
                freq_hz: setup.params.freq_hz_from_ratio(ratio),
                impact_force_mg: r.impact_force_mg,
                regime: r.regime.to_string(),
                impacts: r.impacts,
                transient_periods: r.transient_periods,
                settled: r.settled,
                lyapunov_per_period,
                lyapunov_uncertainty,
                window_regime,
                extra_periods,
            }
        })
        .collect()
}

/// The CSV cells of a Lyapunov label (`response`, `points --lyapunov`), all empty without one:
/// the exponent per period and its uncertainty, the protocol window's regime where the label
/// changed it, and the periods run after the window.
#[derive(Debug, Clone, Default)]
pub struct LabelCells {
    /// Largest Lyapunov exponent, per period.
    pub lyapunov_per_period: Option<f64>,
    /// Its uncertainty, per period.
    pub lyapunov_uncertainty: Option<f64>,
    /// The window's regime, where the exponent changed the label.
    pub window_regime: Option<String>,
    /// Periods run after the window to find a period.
    pub extra_periods: Option<u32>,
}

impl LabelCells {
    /// The cells of `label` (empty for `None`).
    pub fn of(label: Option<&Label>) -> Self {
        label.map_or_else(Self::default, |l| LabelCells {
            lyapunov_per_period: Some(l.exponent.per_period),
            lyapunov_uncertainty: Some(l.exponent.uncertainty()),
            window_regime: (l.window_regime != l.regime).then(|| l.window_regime.to_string()),
            extra_periods: Some(l.extra_periods),
        })
    }
}

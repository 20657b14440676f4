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
    /// Largest Lyapunov exponent per excitation period after the protocol (empty with
    /// `--no-lyapunov`): of the orbit the protocol or the confirmation run settled on, over the
    /// confirmation run's windows (`chaotic`, `irregular` after it), or over the first 64
    /// periods where that was negative.
    pub lyapunov_per_period: Option<f64>,
    /// Its uncertainty: the confirmation windows' standard error, or half the difference of
    /// one window's halves.
    pub lyapunov_uncertainty: Option<f64>,
    /// The protocol window's own regime where the exponent refined it (`irregular` that
    /// became `chaotic` or a period found by the extended or confirmation run); empty otherwise.
    pub window_regime: Option<String>,
    /// Periods run after the exponent's first window: the extended run's or the confirmation
    /// run's (0: neither ran).
    pub extra_periods: Option<u32>,
    /// Where the first window's exponent was positive and the motion then settled: the chaotic
    /// transient's length after the protocol, periods (an upper bound within 16); empty
    /// otherwise.
    pub chaotic_transient_periods: Option<u32>,
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
                chaotic_transient_periods,
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
                chaotic_transient_periods,
            }
        })
        .collect()
}

/// The CSV cells of a Lyapunov label (`response`, `points --lyapunov`), all empty without one:
/// the exponent per period and its uncertainty, the protocol window's regime where the label
/// changed it, the periods run after the window, and the chaotic transient's length.
#[derive(Debug, Clone, Default)]
pub struct LabelCells {
    /// Largest Lyapunov exponent, per period.
    pub lyapunov_per_period: Option<f64>,
    /// Its uncertainty, per period.
    pub lyapunov_uncertainty: Option<f64>,
    /// The window's regime, where the exponent changed the label.
    pub window_regime: Option<String>,
    /// Periods run after the window (extended or confirmation run).
    pub extra_periods: Option<u32>,
    /// The chaotic transient's length after the protocol, periods, where the motion settled
    /// after a positive first window.
    pub chaotic_transient_periods: Option<u32>,
}

impl LabelCells {
    /// The cells of `label` (empty for `None`).
    pub fn of(label: Option<&Label>) -> Self {
        label.map_or_else(Self::default, |l| LabelCells {
            lyapunov_per_period: Some(l.exponent.per_period),
            lyapunov_uncertainty: Some(l.exponent.uncertainty()),
            window_regime: (l.window_regime != l.regime).then(|| l.window_regime.to_string()),
            extra_periods: Some(l.extra_periods),
            chaotic_transient_periods: l.chaotic_transient_periods,
        })
    }
}

/// One line on what the exponent's labels found over a response (`labels[i]` at
/// `sweep.value(i)`): the chaotic and irregular points, and those that settled after a chaotic
/// transient (the first five named: `Ω/ω: regime after N periods`, or the non-impacting motion
/// they escaped to); `None` where there are none of the three.
pub fn label_summary(sweep: &Sweep, labels: &[Label]) -> Option<String> {
    let count = |r: shared::observe::Regime| labels.iter().filter(|l| l.regime == r).count();
    let chaotic = count(shared::observe::Regime::Chaotic);
    let irregular = count(shared::observe::Regime::Irregular);
    let after: Vec<String> = labels
        .iter()
        .enumerate()
        .filter_map(|(i, l)| {
            l.chaotic_transient_periods.map(|n| {
                let what = match l.regime {
                    shared::observe::Regime::NoImpact => "escapes to no impact".to_string(),
                    r => r.to_string(),
                };
                format!("Ω/ω {:.4}: {what} after {n} periods", sweep.value(i))
            })
        })
        .collect();
    if chaotic + irregular + after.len() == 0 {
        return None;
    }
    let mut line = format!(
        "labels: {chaotic} chaotic (a positive exponent over the confirmation run), {irregular} \
         irregular, {} settled after a chaotic transient",
        after.len()
    );
    if !after.is_empty() {
        let shown = after.len().min(5);
        line.push_str(&format!(
            " ({}{})",
            after[..shown].join(", "),
            if after.len() > shown { ", …" } else { "" }
        ));
    }
    Some(line)
}

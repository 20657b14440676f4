//! Frequency responses: the canonical protocol from rest at every `Ω/ω` of a sweep, at one or
//! several gaps, all points in one parallel batch, and the CSV rows of one response.

use anyhow::Result;
use serde::Serialize;
use shared::analysis::Sweep;
use shared::observe::PointResult;

use crate::config::Setup;
use crate::runner::{OperatingPoint, evaluate_all};

/// One CSV row of a frequency response.
#[derive(Debug, Clone, Serialize)]
pub struct ResponseRow {
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Excitation frequency, Hz.
    pub freq_hz: f64,
    /// Max impact force over the observation window, `F_i/mg`.
    pub impact_force_mg: f64,
    /// Regime `p/q`, `no impact` or `irregular`.
    pub regime: String,
    /// Impacts in the observation window.
    pub impacts: u32,
    /// Transient periods before the window.
    pub transient_periods: u32,
    /// Whether a steady state was detected.
    pub settled: bool,
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
    let points: Vec<OperatingPoint> = gaps_m
        .iter()
        .flat_map(|&g| {
            (0..n).map(move |i| OperatingPoint {
                gap_m: g,
                omega_ratio: sweep.value(i),
            })
        })
        .collect();
    let all = evaluate_all(setup, &points, what)?;
    Ok(all.chunks(n).map(<[PointResult]>::to_vec).collect())
}

/// CSV rows of one response (`results[i]` at `sweep.value(i)`).
pub fn rows(setup: &Setup, sweep: &Sweep, results: &[PointResult]) -> Vec<ResponseRow> {
    results
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let ratio = sweep.value(i);
            ResponseRow {
                omega_ratio: ratio,
                freq_hz: setup.params.freq_hz_from_ratio(ratio),
                impact_force_mg: r.impact_force_mg,
                regime: r.regime.to_string(),
                impacts: r.impacts,
                transient_periods: r.transient_periods,
                settled: r.settled,
            }
        })
        .collect()
}

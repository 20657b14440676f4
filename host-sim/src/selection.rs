//! The operating-frequency selection on the desktop (the main job): the responses at the
//! nominal and perturbed gaps in parallel, then `shared::analysis::select`, as a report.

use anyhow::{Result, anyhow};
use serde::Serialize;
use shared::analysis::{ResponseSample, Selection, SelectionError, perturbed_gaps, select};

use crate::config::{Setup, gap_m_from_mm};
use crate::precision::Precision;
use crate::response;

/// The JSON report.
#[derive(Debug, Serialize)]
pub struct SelectReport {
    /// Rig name.
    pub rig: String,
    /// Contact law.
    pub law: String,
    /// Float type.
    pub precision: Precision,
    /// Gap, mm.
    pub gap_mm: f64,
    /// Natural frequency `ω/2π`, Hz.
    pub natural_freq_hz: f64,
    /// Chosen excitation frequency, Hz.
    pub freq_hz: f64,
    /// Chosen `Ω/ω`.
    pub omega_ratio: f64,
    /// Regime at the chosen point (`1/1`).
    pub regime: String,
    /// Predicted max impact force, `F_i/mg`.
    pub impact_force_mg: f64,
    /// Edges of its `1/1` band, Hz.
    pub band_hz: [f64; 2],
    /// The same in `Ω/ω`.
    pub band_omega_ratio: [f64; 2],
    /// Distance to the nearer band edge, % of the chosen frequency.
    pub margin_freq_pct: f64,
    /// Frequency robustness required and verified, ± %.
    pub required_margin_freq_pct: f64,
    /// Gap robustness verified, ± mm.
    pub margin_gap_mm: f64,
    /// Gaps at which the response was checked, mm.
    pub gaps_checked_mm: Vec<f64>,
    /// Lowest `F_i/mg` over the robustness box.
    pub worst_impact_force_mg: f64,
    /// Sweep points that passed the robustness check.
    pub robust_points: usize,
    /// Every `1/1` band at the nominal gap, `Ω/ω`.
    pub bands_omega_ratio: Vec<[f64; 2]>,
    /// Strongest point of another periodic regime, for information.
    pub other_best: Option<OtherBest>,
}

/// The strongest non-`1/1` periodic point.
#[derive(Debug, Serialize)]
pub struct OtherBest {
    /// Its regime.
    pub regime: String,
    /// Hz.
    pub freq_hz: f64,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// `F_i/mg`.
    pub impact_force_mg: f64,
}

/// The report of selection `sel` at `gap_mm` (responses checked at `gaps_mm`).
fn report(setup: &Setup, gap_mm: f64, gaps_mm: Vec<f64>, sel: &Selection) -> SelectReport {
    SelectReport {
        rig: setup.rig.to_string(),
        law: setup.params.contact.kind().to_string(),
        precision: setup.precision,
        gap_mm,
        natural_freq_hz: setup.params.natural_freq_hz(),
        freq_hz: sel.best.freq_hz,
        omega_ratio: sel.best.omega_ratio,
        regime: sel.best.regime.to_string(),
        impact_force_mg: sel.best.impact_force_mg,
        band_hz: sel.band_hz,
        band_omega_ratio: sel.band_ratio,
        margin_freq_pct: sel.margin_freq_pct,
        required_margin_freq_pct: setup.selection.freq_margin_pct,
        margin_gap_mm: sel.margin_gap_mm,
        gaps_checked_mm: gaps_mm,
        worst_impact_force_mg: sel.worst_impact_force_mg,
        robust_points: sel.robust_points,
        bands_omega_ratio: sel.bands_ratio.iter().copied().collect(),
        other_best: sel.other_best.map(|c| OtherBest {
            regime: c.regime.to_string(),
            freq_hz: c.freq_hz,
            omega_ratio: c.omega_ratio,
            impact_force_mg: c.impact_force_mg,
        }),
    }
}

/// Computes the selection (responses at the nominal and perturbed gaps, in parallel).
///
/// # Errors
/// Bad input, or no robust `1/1` point.
pub fn compute(
    setup: &Setup,
    gap_mm: f64,
) -> Result<(SelectReport, Vec<shared::observe::PointResult>)> {
    compute_with(setup, gap_mm, "select")
}

/// [`compute`] with the progress bar's label (`""`: no bar, e.g. for one draw of many).
///
/// # Errors
/// As [`compute`].
pub fn compute_with(
    setup: &Setup,
    gap_mm: f64,
    what: &str,
) -> Result<(SelectReport, Vec<shared::observe::PointResult>)> {
    let (selection, nominal) = compute_parts(setup, gap_mm, what)?;
    let spec = setup.selection;
    let report = selection.map_err(|e| {
        anyhow!(
            "{} rig at {gap_mm} mm gap (±{} % frequency, ±{} mm gap): {e}",
            setup.rig,
            spec.freq_margin_pct,
            spec.gap_margin_mm
        )
    })?;
    Ok((report, nominal))
}

/// The selection's two results apart: the report, or why the responses hold no robust `1/1`
/// point ([`SelectionError`]); and the nominal-gap response, which exists either way.
///
/// # Errors
/// Bad input or a failed response computation.
pub fn compute_parts(
    setup: &Setup,
    gap_mm: f64,
    what: &str,
) -> Result<(
    Result<SelectReport, SelectionError>,
    Vec<shared::observe::PointResult>,
)> {
    let gap_m = gap_m_from_mm("--gap-mm", gap_mm)?;
    let spec = setup.selection;
    let sweep = spec.omega_ratio;
    let mut gaps = vec![gap_m];
    gaps.extend(perturbed_gaps(gap_m, spec.gap_margin_mm));
    let mut responses = response::compute(setup, &gaps, &sweep, what)?;
    let samples: Vec<Vec<ResponseSample>> = responses
        .iter()
        .map(|r| r.iter().map(ResponseSample::from).collect())
        .collect();
    let perturbed: Vec<&[ResponseSample]> = samples[1..].iter().map(Vec::as_slice).collect();
    let gaps_mm = gaps.iter().map(|g| g * 1e3).collect();
    let report = select(&setup.params, &spec, &samples[0], &perturbed)
        .map(|sel| report(setup, gap_mm, gaps_mm, &sel));
    Ok((report, responses.swap_remove(0)))
}

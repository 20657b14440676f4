//! `host-sim select`: the operating frequency for a rig and gap (the main job).

use std::path::PathBuf;

use anyhow::{Result, anyhow};
use clap::Args;
use serde::Serialize;
use shared::analysis::{ResponseSample, Selection, perturbed_gaps, select};

use super::response::{self, omega_sweep};
use crate::cli::{Precision, RigOpts};
use crate::config::{Setup, gap_m_from_mm};
use crate::output::Outputs;
use crate::plot::Highlight;

/// Arguments of `select`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct SelectArgs {
    /// Rig and numerics.
    #[command(flatten)]
    pub rig: RigOpts,
    /// Gap between the hammer at rest and the impact surface, mm (≥ 0; field use: 0).
    #[arg(long, default_value_t = 0.0)]
    pub gap_mm: f64,
    /// Frequency-ratio sweep searched, START:END:STEP (default from [selection] or 0.5:5.0:0.01).
    #[arg(long)]
    pub omega_ratio: Option<String>,
    /// Required robustness in frequency, ± % (default 5).
    #[arg(long)]
    pub freq_margin_pct: Option<f64>,
    /// Required robustness in gap, ± mm (default 0.1; the lower side is clipped at 0).
    #[arg(long)]
    pub gap_margin_mm: Option<f64>,
    /// Print one JSON object instead of the report.
    #[arg(long)]
    pub json: bool,
    /// CSV of the nominal-gap response (columns as `response`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// PNG of the nominal-gap response with the band, window and chosen point.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

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
    let gap_m = gap_m_from_mm("--gap-mm", gap_mm)?;
    let spec = setup.selection;
    let sweep = spec.omega_ratio;
    let mut gaps = vec![gap_m];
    gaps.extend(perturbed_gaps(gap_m, spec.gap_margin_mm));
    let responses = response::compute(setup, &gaps, &sweep, "select")?;
    let samples: Vec<Vec<ResponseSample>> = responses
        .iter()
        .map(|r| r.iter().map(ResponseSample::from).collect())
        .collect();
    let perturbed: Vec<&[ResponseSample]> = samples[1..].iter().map(Vec::as_slice).collect();
    let sel = select(&setup.params, &spec, &samples[0], &perturbed).map_err(|e| {
        anyhow!(
            "{} rig at {gap_mm} mm gap (±{} % frequency, ±{} mm gap): {e}",
            setup.rig,
            spec.freq_margin_pct,
            spec.gap_margin_mm
        )
    })?;
    let gaps_mm = gaps.iter().map(|g| g * 1e3).collect();
    let mut responses = responses;
    Ok((
        report(setup, gap_mm, gaps_mm, &sel),
        responses.swap_remove(0),
    ))
}

/// Runs `select`.
///
/// # Errors
/// Bad input, no robust point, or I/O failure.
pub fn run(a: &SelectArgs) -> Result<()> {
    let mut setup = Setup::from_opts(&a.rig)?;
    if let Some(s) = &a.omega_ratio {
        setup.selection.omega_ratio = omega_sweep(s)?;
    }
    if let Some(p) = a.freq_margin_pct {
        setup.selection.freq_margin_pct = p;
    }
    if let Some(g) = a.gap_margin_mm {
        setup.selection.gap_margin_mm = g;
    }
    setup
        .selection
        .validate()
        .map_err(|e| anyhow!("{e} (--freq-margin-pct / --gap-margin-mm)"))?;
    let (rep, nominal) = compute(&setup, a.gap_mm)?;
    let sweep = setup.selection.omega_ratio;
    let mut outputs = Outputs::new();
    if a.out.is_some() || a.plot.is_some() {
        let rows = response::rows(&setup, &sweep, &nominal);
        let p = setup.selection.freq_margin_pct / 100.0;
        let highlight = Highlight {
            chosen: (rep.omega_ratio, rep.impact_force_mg),
            band: rep.band_omega_ratio,
            window: [rep.omega_ratio * (1.0 - p), rep.omega_ratio * (1.0 + p)],
        };
        let title = format!(
            "{} rig, gap {:.2} mm: operating point {:.2} Hz (Ω/ω = {:.2})",
            setup.rig, a.gap_mm, rep.freq_hz, rep.omega_ratio
        );
        response::write(
            &mut outputs,
            a.out.as_ref(),
            a.plot.as_ref(),
            &title,
            &rows,
            &nominal,
            Some(highlight),
        )?;
    }
    outputs.commit()?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
    } else {
        print_report(&rep);
    }
    Ok(())
}

fn print_report(r: &SelectReport) {
    println!(
        "Operating frequency for the {} rig at {:.2} mm gap ({} law, {:?}):",
        r.rig, r.gap_mm, r.law, r.precision
    );
    println!(
        "  run the shaker at {:.3} Hz  (Ω/ω = {:.3}, ω/2π = {:.3} Hz)",
        r.freq_hz, r.omega_ratio, r.natural_freq_hz
    );
    println!(
        "  regime z = {}, predicted impact force F_i/mg = {:.2}",
        r.regime, r.impact_force_mg
    );
    println!(
        "  z = 1/1 band {:.3} – {:.3} Hz (Ω/ω {:.2} – {:.2})",
        r.band_hz[0], r.band_hz[1], r.band_omega_ratio[0], r.band_omega_ratio[1]
    );
    println!(
        "  margins: {:.1} % to the nearer band edge (required ±{} %); gap checked at {:?} mm (±{} mm)",
        r.margin_freq_pct,
        r.required_margin_freq_pct,
        r.gaps_checked_mm
            .iter()
            .map(|g| (g * 1e3).round() / 1e3)
            .collect::<Vec<_>>(),
        r.margin_gap_mm
    );
    println!(
        "  worst F_i/mg inside the robustness box: {:.2} ({} robust points)",
        r.worst_impact_force_mg, r.robust_points
    );
    if let Some(o) = &r.other_best {
        println!(
            "  for information, strongest other regime: z = {} at {:.3} Hz (Ω/ω = {:.2}), F_i/mg = {:.2}",
            o.regime, o.freq_hz, o.omega_ratio, o.impact_force_mg
        );
    }
}

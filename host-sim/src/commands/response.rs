//! `host-sim response`: max `F_i/mg` and the regime per frequency (canonical protocol from rest).

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use serde::Serialize;
use shared::analysis::Sweep;
use shared::analysis::response::OMEGA_RATIO_RANGE;
use shared::observe::PointResult;

use crate::cli::RigOpts;
use crate::config::{Setup, gap_m_from_mm, parse_sweep};
use crate::output::{Outputs, write_csv};
use crate::plot::{self, Highlight, ResponsePoint};
use crate::runner::{OperatingPoint, evaluate_all};

/// Arguments of `response`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct ResponseArgs {
    /// Rig and numerics.
    #[command(flatten)]
    pub rig: RigOpts,
    /// Gap between the hammer at rest and the impact surface, mm (≥ 0).
    #[arg(long)]
    pub gap_mm: f64,
    /// Frequency-ratio sweep Ω/ω as START:END:STEP.
    #[arg(long, default_value = "0.5:5.0:0.02")]
    pub omega_ratio: String,
    /// CSV output: omega_ratio, freq_hz, impact_force_mg, regime, impacts, transient_periods, settled.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// PNG plot of F_i/mg vs Ω/ω coloured by regime.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

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

/// Parses `--omega-ratio` for the response commands.
///
/// # Errors
/// Malformed or out-of-range sweep.
pub fn omega_sweep(text: &str) -> Result<Sweep> {
    parse_sweep(
        "--omega-ratio",
        text,
        OMEGA_RATIO_RANGE.0,
        OMEGA_RATIO_RANGE.1,
    )
}

/// Computes the response at each gap over `sweep`, all points in one parallel batch.
/// Returns one `Vec<PointResult>` per gap.
///
/// # Errors
/// An invalid point.
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

/// CSV rows of one response.
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

/// Writes the CSV and/or the plot of one response (reserved in `outputs`).
///
/// # Errors
/// File or drawing errors.
pub fn write(
    outputs: &mut Outputs,
    out: Option<&PathBuf>,
    plot_path: Option<&PathBuf>,
    title: &str,
    rows: &[ResponseRow],
    results: &[PointResult],
    highlight: Option<Highlight>,
) -> Result<()> {
    if let Some(p) = out {
        let tmp = outputs.reserve(p)?;
        write_csv(&tmp, rows)?;
    }
    if let Some(p) = plot_path {
        let tmp = outputs.reserve(p)?;
        let pts: Vec<ResponsePoint> = rows
            .iter()
            .zip(results)
            .map(|(row, r)| ResponsePoint {
                omega_ratio: row.omega_ratio,
                impact_force_mg: r.impact_force_mg,
                regime: r.regime,
            })
            .collect();
        plot::response(&tmp, title, &pts, highlight)?;
    }
    Ok(())
}

/// Title line of a figure.
pub fn title(setup: &Setup, gap_mm: f64) -> String {
    format!(
        "{} rig, gap {:.2} mm, {} law, {} — frequency response",
        setup.rig,
        gap_mm,
        setup.params.contact.kind(),
        match setup.precision {
            crate::cli::Precision::F32 => "f32",
            crate::cli::Precision::F64 => "f64",
        }
    )
}

/// Runs `response`.
///
/// # Errors
/// Bad input or I/O failure; no output file is left half-written.
pub fn run(a: &ResponseArgs) -> Result<()> {
    let setup = Setup::from_opts(&a.rig)?;
    let gap_m = gap_m_from_mm("--gap-mm", a.gap_mm)?;
    let sweep = omega_sweep(&a.omega_ratio)?;
    let results = compute(&setup, &[gap_m], &sweep, "response")?.remove(0);
    let rows = rows(&setup, &sweep, &results);
    let mut outputs = Outputs::new();
    write(
        &mut outputs,
        a.out.as_ref(),
        a.plot.as_ref(),
        &title(&setup, a.gap_mm),
        &rows,
        &results,
        None,
    )?;
    outputs.commit()?;
    if a.out.is_none() {
        let mut w = csv::Writer::from_writer(std::io::stdout());
        for r in &rows {
            w.serialize(r)?;
        }
        w.flush()?;
    }
    Ok(())
}

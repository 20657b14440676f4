//! `host-sim response`: max `F_i/mg` and the regime per frequency (canonical protocol from rest).

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use shared::orbit::LabelSettings;

use super::{omega_sweep, write_response};
use crate::config::{RigOpts, Setup};
use crate::figures::response::{points, title};
use crate::output::Outputs;
use crate::response;

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
    /// CSV output: omega_ratio, freq_hz, impact_force_mg, regime, impacts, transient_periods,
    /// settled, lyapunov_per_period, lyapunov_uncertainty, window_regime, extra_periods,
    /// chaotic_transient_periods.
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: Option<PathBuf>,
    /// The protocol's labels alone: no Lyapunov exponent (its columns empty), `irregular`
    /// where no period `q ≤ 16` showed in the window. By default the largest exponent over 64
    /// periods after the protocol refines them: where it is negative, the run goes on (up to
    /// 2,000 periods) until a period `q ≤ 64` shows; otherwise a confirmation run of up to
    /// 2,048 periods labels the point by what it settles on (the chaotic transient's length in
    /// `chaotic_transient_periods`), or `chaotic` where the exponent stays positive beyond 3
    /// standard errors over its 32 windows of 64 periods, else `irregular`.
    #[arg(long)]
    pub no_lyapunov: bool,
    /// PNG or SVG plot of F_i/mg vs Ω/ω coloured by regime.
    #[arg(long, value_parser = crate::output::figure_target)]
    pub plot: Option<PathBuf>,
}

/// Runs `response`.
///
/// # Errors
/// Bad input or I/O failure; no output file is left half-written.
pub fn run(a: &ResponseArgs) -> Result<()> {
    a.rig
        .check_outputs(&[("--out", a.out.as_deref()), ("--plot", a.plot.as_deref())])?;
    let setup = Setup::from_opts(&a.rig)?;
    let gap_m = setup.gap_m("--gap-mm", a.gap_mm)?;
    let sweep = omega_sweep(&a.omega_ratio)?;
    super::warn_coarse_steps(&setup, sweep.lo);
    let (results, labels) = if a.no_lyapunov {
        (
            response::compute(&setup, &[gap_m], &sweep, "response")?.remove(0),
            None,
        )
    } else {
        let (r, l) = response::compute_labelled(
            &setup,
            &[gap_m],
            &sweep,
            "response",
            &LabelSettings::default(),
        )?
        .remove(0);
        (r, Some(l))
    };
    let rows = response::rows(&setup, &sweep, &results, labels.as_deref());
    let mut outputs = Outputs::new();
    write_response(
        &mut outputs,
        a.out.as_deref(),
        a.plot.as_deref(),
        &title(&setup, a.gap_mm),
        &rows,
        &points(&sweep, &results),
        None,
    )?;
    outputs.commit()?;
    if let Some(out) = &a.out {
        let n = crate::output::count(rows.len() as u64, "point");
        eprintln!("response: {n} → {}", out.display());
    } else {
        let mut w = csv::Writer::from_writer(std::io::stdout());
        for r in &rows {
            w.serialize(r)?;
        }
        w.flush()?;
    }
    if let Some(line) = labels
        .as_deref()
        .and_then(|l| response::label_summary(&sweep, l))
    {
        eprintln!("{line}");
    }
    Ok(())
}

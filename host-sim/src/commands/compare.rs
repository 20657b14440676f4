//! `host-sim compare`: a measured record against the simulation (thesis §3.3.4, §3.4.2; the
//! computation: [`crate::comparison`]).
//!
//! Two kinds of record, told apart by their header:
//! - **frequency response** (a `freq_hz` or `omega_ratio` column, and `impact_force_mg` or
//!   `impact_force_n`): the measured max `F_i/mg` per frequency over the simulated response
//!   (canonical protocol from rest at each frequency, as `response` does; Figs. 3.12–3.14).
//!   Error summary at the measured frequencies: bias, RMS and largest difference of `F_i/mg`.
//! - **time series** at one frequency (`--freq-hz`; a time column and the absolute hammer
//!   displacement `x`, Eq. 3-18, e.g. `x_mm`): the measured displacement, phase plane
//!   `(x, ẋ)` (`ẋ` by central differences) and Poincaré points (`t = kT`) over the simulated
//!   steady state (after `--transient-periods` from rest). The record's phase relative to the
//!   shaker is unknown, so the simulation is shifted by the `τ ∈ [0, T)` (256 trials) that
//!   minimises the RMS displacement difference; the error summary gives that RMS.

use std::path::PathBuf;

use anyhow::{Context, Result, bail, ensure};
use clap::Args;
use shared::analysis::response::OMEGA_RATIO_RANGE;
use shared::error::{check_count, check_range};

use super::TimeOpts;
use crate::comparison;
use crate::config::{RigOpts, Setup};
use crate::output::write_whole;
use crate::trace::{LabTable, MotionUnit, trace_from_table};

/// Arguments of `compare`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct CompareArgs {
    /// Rig and numerics (use --config with the identified parameters).
    #[command(flatten)]
    pub rig: RigOpts,
    /// Measured record (CSV): a frequency response or a time series, see `--help`.
    #[arg(long, value_name = "FILE.csv")]
    pub experiment: PathBuf,
    /// Gap of the experiment, mm.
    #[arg(long)]
    pub gap_mm: f64,
    /// Excitation frequency of a time-series record, Hz.
    #[arg(long)]
    pub freq_hz: Option<f64>,
    /// Time-series record: time column, unit or sample rate.
    #[command(flatten)]
    pub time: TimeOpts,
    /// Time-series record: absolute displacement column (name or 1-based number).
    #[arg(long, default_value = "x_mm")]
    pub disp_col: String,
    /// Time-series record: unit of the displacement column.
    #[arg(long, value_enum, default_value = "mm")]
    pub disp_unit: MotionUnit,
    /// Time series: periods simulated from rest before the comparison window (1..=10000).
    #[arg(long, default_value_t = 200)]
    pub transient_periods: u32,
    /// PNG or SVG with the overlay.
    #[arg(value_parser = crate::output::figure_target, long, value_name = "FILE.png|svg")]
    pub out: PathBuf,
}

/// Runs `compare`.
///
/// # Errors
/// Bad input or I/O failure; nothing is written then.
pub fn run(a: &CompareArgs) -> Result<()> {
    let setup = Setup::from_opts(&a.rig)?;
    let gap_m = setup.gap_m("--gap-mm", a.gap_mm)?;
    let table = LabTable::read(&a.experiment).context("--experiment")?;
    let summary = if comparison::is_response(&table) {
        let meas = comparison::measured_response(&table, &setup)
            .with_context(|| format!("--experiment {}", a.experiment.display()))?;
        let (overlay, summary) = comparison::response(&setup, gap_m, &meas)?;
        let title = format!(
            "{} rig, gap {:.2} mm, {} law: measured vs simulated frequency response",
            setup.rig,
            a.gap_mm,
            setup.params.contact.kind()
        );
        write_whole(&a.out, |tmp| {
            crate::figures::identify::response_compare(tmp, &title, &summary, &overlay)
        })?;
        summary
    } else {
        let Some(freq_hz) = a.freq_hz else {
            bail!(
                "--experiment {} is a time series (no freq_hz/omega_ratio column): give its \
                 excitation frequency with --freq-hz",
                a.experiment.display()
            );
        };
        ensure!(
            !a.disp_unit.is_acceleration(),
            "--disp-unit must be a displacement unit (m, mm, um)"
        );
        let fn_hz = setup.params.natural_freq_hz();
        check_range(
            "freq_hz",
            freq_hz,
            OMEGA_RATIO_RANGE.0 * fn_hz,
            OMEGA_RATIO_RANGE.1 * fn_hz,
        )
        .context("--freq-hz")?;
        check_count("transient_periods", a.transient_periods, 1, 10_000)
            .context("--transient-periods")?;
        let format = a.time.format(Some(&a.disp_col), a.disp_unit.to_si());
        let trace = trace_from_table(&table, &format, "displacement")
            .with_context(|| format!("trace {}", a.experiment.display()))?;
        let (overlay, summary, warning) =
            comparison::time_series(&setup, gap_m, freq_hz, a.transient_periods, &trace)?;
        if let Some(w) = warning {
            eprintln!("! warning: {w}");
        }
        let title = format!(
            "{} rig, gap {:.2} mm, {:.3} Hz, {} law: measured vs simulated",
            setup.rig,
            a.gap_mm,
            freq_hz,
            setup.params.contact.kind()
        );
        write_whole(&a.out, |tmp| {
            crate::figures::identify::time_series_compare(tmp, &title, &summary, &overlay)
        })?;
        summary
    };
    println!("{}: {summary}", a.experiment.display());
    Ok(())
}

//! `host-sim simulate`: the time series of one operating point.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use shared::error::check_count;

use super::{ExcitationOpts, StartOpts};
use crate::config::{RigOpts, Setup};
use crate::figures::response::{TsPoint, time_series};
use crate::output::{Outputs, write_csv};
use crate::series::{self, SeriesSpec, TsRow};

/// Arguments of `simulate`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct SimulateArgs {
    /// Rig and numerics.
    #[command(flatten)]
    pub rig: RigOpts,
    /// Gap, mm (≥ 0).
    #[arg(long)]
    pub gap_mm: f64,
    #[command(flatten)]
    pub excitation: ExcitationOpts,
    /// Excitation periods to simulate (1..=100000).
    #[arg(long, default_value_t = 20)]
    pub periods: u32,
    #[command(flatten)]
    pub start: StartOpts,
    /// CSV: t_s, u_mm, du_mm_s, x_mm, impact_force_n, impact_force_mg, region, poincare,
    /// lyapunov_per_period (at Poincaré rows: the running estimate of the largest Lyapunov
    /// exponent over the periods so far).
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: Option<PathBuf>,
    /// PNG or SVG: displacement, impact force and phase plane with the Poincaré points.
    #[arg(long, value_parser = crate::output::figure_target)]
    pub plot: Option<PathBuf>,
}

/// Writes a time series' rows as CSV to `out` and its figure (displacement, impact force and
/// phase plane with the Poincaré points, titled `title`, the surface at `gap_mm`) to `plot`,
/// either if given, both or neither.
///
/// # Errors
/// File or drawing errors (nothing is written then).
pub(crate) fn write_series(
    rows: &[TsRow],
    out: Option<&Path>,
    plot: Option<&Path>,
    title: &str,
    gap_mm: f64,
) -> Result<()> {
    let mut outputs = Outputs::new();
    if let Some(p) = out {
        let tmp = outputs.reserve(p)?;
        write_csv(&tmp, rows)?;
    }
    if let Some(p) = plot {
        let tmp = outputs.reserve(p)?;
        let ts: Vec<TsPoint> = rows
            .iter()
            .map(|r| TsPoint {
                t_s: r.t_s,
                u_mm: r.u_mm,
                du_mm_s: r.du_mm_s,
                x_mm: r.x_mm,
                force_mg: r.impact_force_mg,
            })
            .collect();
        let strobes: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.poincare)
            .map(|r| (r.u_mm, r.du_mm_s))
            .collect();
        time_series(&tmp, title, &ts, &strobes, gap_mm)?;
    }
    outputs.commit()
}

/// Runs `simulate`.
///
/// # Errors
/// Bad input or I/O failure.
pub fn run(a: &SimulateArgs) -> Result<()> {
    a.rig
        .check_outputs(&[("--out", a.out.as_deref()), ("--plot", a.plot.as_deref())])?;
    let setup = Setup::from_opts(&a.rig)?;
    let gap_m = setup.gap_m("--gap-mm", a.gap_mm)?;
    let fn_hz = setup.params.natural_freq_hz();
    let ratio = a.excitation.ratio(&setup)?;
    check_count("periods", a.periods, 1, 100_000).context("--periods")?;
    let (u0_m, v0_m_s) = a.start.start_m(a.gap_mm)?;
    let omega_exc = ratio * setup.params.omega_n();
    let (rows, summary) = series::simulate(
        &setup,
        &SeriesSpec {
            gap_m,
            omega_exc,
            periods: a.periods,
            u0_m,
            v0_m_s,
        },
    )?;
    let title = format!(
        "{} rig, gap {:.2} mm, Ω/ω = {:.3} ({:.3} Hz), {}",
        setup.rig,
        a.gap_mm,
        ratio,
        ratio * fn_hz,
        crate::output::count(u64::from(a.periods), "period")
    );
    write_series(&rows, a.out.as_deref(), a.plot.as_deref(), &title, a.gap_mm)?;
    println!(
        "{} at Ω/ω = {:.4} ({:.4} Hz): {}, max F_i/mg = {:.3}, {} samples{}",
        crate::output::count(u64::from(a.periods), "period"),
        ratio,
        ratio * fn_hz,
        crate::output::count(u64::from(summary.impacts), "impact"),
        summary.max_force_mg,
        rows.len(),
        match summary.lyapunov {
            Some((l, u)) => format!(
                ", largest Lyapunov exponent {l:.4} ± {u:.4} per period{}",
                if u.is_finite() && u < l.abs() {
                    ""
                } else {
                    " (its sign undecided over this run: more --periods narrow it)"
                }
            ),
            None => String::new(),
        }
    );
    if let Some(stop) = summary.impacts_stopped {
        let (l, u) = stop.lyapunov;
        println!(
            "the impacts stopped after period {}: over the {} after it (the motion the run ends \
             on) the exponent is {l:.4} ± {u:.4} per period; the run's figure above averages \
             over both motions",
            stop.last_impact_period,
            crate::output::count(u64::from(stop.impact_free_periods), "impact-free period"),
        );
    }
    Ok(())
}

//! One module per command: each parses its arguments, calls the library, writes its outputs
//! and prints.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use shared::analysis::Sweep;
use shared::analysis::response::OMEGA_RATIO_RANGE;
use shared::error::check_range;
use shared::observe::RecurrenceSettings;

use crate::attractors::{
    ATTRACTOR_STEADY_TOL, ATTRACTOR_TOL, MAX_TRANSIENT_PERIODS, transient_periods,
};
use crate::config::{Setup, parse_sweep};
use crate::figures::{
    self,
    response::{Highlight, ResponsePoint},
};
use crate::grid::{Destination, Figures};
use crate::output::{Outputs, write_csv};
use crate::response::ResponseRow;
use crate::shard::ShardArg;
use crate::trace::{TimeUnit, TraceFormat};

pub mod basins;
pub mod bifurcation;
pub mod compare;
pub mod continuation;
pub mod drop;
pub mod fractions;
pub mod hil;
pub mod identify;
pub mod merge;
pub mod orbit;
pub mod peterka;
pub mod points;
pub mod response;
pub mod rig;
pub mod select;
pub mod simulate;

/// Parses `--omega-ratio START:END:STEP` within the analyses' `Ω/ω` range.
///
/// # Errors
/// Malformed or out-of-range sweep (the flag and the range named).
pub fn omega_sweep(text: &str) -> Result<Sweep> {
    parse_sweep(
        "--omega-ratio",
        text,
        OMEGA_RATIO_RANGE.0,
        OMEGA_RATIO_RANGE.1,
    )
}

/// Fewest RK4 steps per natural period of the suspension that resolve its free oscillation
/// ([`warn_coarse_steps`]).
pub const STEPS_PER_NATURAL_PERIOD: f64 = 16.0;

/// A warning (on stderr) where the lowest `Ω/ω` of a run, `omega_ratio_min`, leaves fewer than
/// [`STEPS_PER_NATURAL_PERIOD`] RK4 steps per natural period of the suspension: `N` steps per
/// excitation period are `N Ω/ω` per natural period, and RK4 damps the free oscillation
/// (`|R(i h ω)| < 1`), which biases its decay, the forces and the exponents there (the 170 mm
/// beam far from the surface at Ω/ω 0.05, `N = 64`: an exponent of −17.7 per period against
/// the model's −0.50; at 0.2, −0.131 against −0.126).
pub fn warn_coarse_steps(setup: &Setup, omega_ratio_min: f64) {
    let n = f64::from(setup.settings.steps.steps_per_period);
    let per_natural = n * omega_ratio_min;
    if per_natural < STEPS_PER_NATURAL_PERIOD {
        eprintln!(
            "! warning: at Ω/ω {omega_ratio_min:.3} the suspension's natural period has {per_natural:.1} \
             RK4 steps ({n} per excitation period), fewer than {STEPS_PER_NATURAL_PERIOD}: the \
             integrator damps its free oscillation, so forces, regimes and exponents below Ω/ω \
             {:.3} are approximate (steps_per_period up to 512 in [settings.steps] of a --config \
             file resolves it down to Ω/ω {:.3})",
            STEPS_PER_NATURAL_PERIOD / n,
            STEPS_PER_NATURAL_PERIOD / 512.0
        );
    }
}

/// The excitation frequency of one operating point, as `Ω/ω` or in Hz (`simulate`, `orbit`).
#[derive(Debug, Clone, Args)]
pub struct ExcitationOpts {
    /// Excitation frequency as Ω/ω (give this or --freq-hz).
    #[arg(long, conflicts_with = "freq_hz")]
    pub omega_ratio: Option<f64>,
    /// Excitation frequency, Hz.
    #[arg(long)]
    pub freq_hz: Option<f64>,
}

impl ExcitationOpts {
    /// `Ω/ω` ([`excitation_ratio`]).
    ///
    /// # Errors
    /// Neither or both given, or out of range (the flag and the range named).
    pub fn ratio(&self, setup: &Setup) -> Result<f64> {
        excitation_ratio(setup, self.omega_ratio, self.freq_hz)
    }
}

/// Where a run starts, relative to the cart (`simulate`, `orbit`).
#[derive(Debug, Clone, Args)]
pub struct StartOpts {
    /// Initial relative displacement u0, mm (default: at rest, 0).
    #[arg(long, default_value_t = 0.0)]
    pub u0_mm: f64,
    /// Initial relative velocity u̇0, mm/s.
    #[arg(long, default_value_t = 0.0)]
    pub v0_mm_s: f64,
}

impl StartOpts {
    /// The start `(u0, u̇0)` in m and m/s, checked: `u0` within ±20 mm and not beyond the
    /// surface at `gap_mm`, `u̇0` within ±10 m/s.
    ///
    /// # Errors
    /// Out of range (the flag and the range named).
    pub fn start_m(&self, gap_mm: f64) -> Result<(f64, f64)> {
        check_range("u0_mm", self.u0_mm, -20.0, 20.0).context("--u0-mm")?;
        check_start_off_surface(&format!("--u0-mm {}", self.u0_mm), self.u0_mm, gap_mm)?;
        check_range("v0_mm_s", self.v0_mm_s, -1e4, 1e4).context("--v0-mm-s")?;
        Ok((self.u0_mm * 1e-3, self.v0_mm_s * 1e-3))
    }
}

/// The excitation as `Ω/ω` from `--omega-ratio` or `--freq-hz` (exactly one given), within
/// the analyses' range.
///
/// # Errors
/// Neither or both given, or out of range (the flag and the range named).
pub fn excitation_ratio(
    setup: &Setup,
    omega_ratio: Option<f64>,
    freq_hz: Option<f64>,
) -> Result<f64> {
    let fn_hz = setup.params.natural_freq_hz();
    let ratio = match (omega_ratio, freq_hz) {
        (Some(r), None) => r,
        (None, Some(f)) => {
            check_range(
                "freq_hz",
                f,
                OMEGA_RATIO_RANGE.0 * fn_hz,
                OMEGA_RATIO_RANGE.1 * fn_hz,
            )
            .context("--freq-hz")?;
            f / fn_hz
        }
        _ => bail!("give the excitation frequency with --omega-ratio or --freq-hz"),
    };
    check_range(
        "omega_ratio",
        ratio,
        OMEGA_RATIO_RANGE.0,
        OMEGA_RATIO_RANGE.1,
    )
    .context("--omega-ratio")?;
    warn_coarse_steps(setup, ratio);
    Ok(ratio)
}

/// The outputs of a grid command (`peterka`, `basins`, `bifurcation`).
#[derive(Debug, Args)]
pub struct GridOutArgs {
    /// CSV output, its rows and columns as listed in `--help`. With a shard: the shard's
    /// rows, line 1 `# host-sim-shard {metadata}`, for `merge`.
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: PathBuf,
    /// PNG or SVG (by the name): the command's figure (described in `--help`); not with a shard
    /// (`merge` draws it).
    #[arg(long, value_parser = crate::output::figure_target)]
    pub plot: Option<PathBuf>,
    /// Shard of the grid to compute.
    #[command(flatten)]
    pub shard: ShardArg,
}

impl GridOutArgs {
    /// Where the command writes, with `force_plot` (peterka's second figure) and `boundaries`
    /// (peterka's boundary curves CSV) if asked.
    ///
    /// # Errors
    /// A malformed `--shard` or SLURM array variables.
    pub fn destination<'a>(
        &'a self,
        force_plot: Option<&'a Path>,
        boundaries: Option<&'a Path>,
    ) -> Result<Destination<'a>> {
        Ok(Destination {
            out: &self.out,
            figures: Figures {
                plot: self.plot.as_deref(),
                force_plot,
                boundaries,
                attractors: None,
            },
            shard: self.shard.resolve()?,
        })
    }
}

/// How `basins` and `fractions` find attractors.
#[derive(Debug, Clone, Args)]
pub struct AttractorOpts {
    /// Tolerance for "same attractor" on the scaled Poincaré distance
    /// max(|Δu|/A0, |Δu̇|/(A0 Ω)) (1e-6 ..= 1).
    #[arg(long, default_value_t = ATTRACTOR_TOL)]
    pub attractor_tol: f64,
    /// A trajectory whose Poincaré points stay within this scaled distance of a catalogued
    /// attractor's for --confirm periods in a row is assigned to it and stops (1e-9 ..= 1).
    #[arg(long, default_value_t = RecurrenceSettings::default().tol)]
    pub recurrence_tol: f64,
    /// Periods in a row on a catalogued attractor that assign a trajectory to it (1 ..= 10000).
    #[arg(long, default_value_t = RecurrenceSettings::default().confirm)]
    pub confirm: u32,
    /// Longest transient, periods (1 ..= 1000000): a trajectory that has not recurred by then
    /// and whose window does not repeat counts as never recurrent. Default: the protocol's
    /// max_transient_periods (200), or, on a damped suspension, the periods its free
    /// oscillation takes to shrink by --steady-tol at the run's largest Ω/ω if more (at most
    /// 10000; the beam rig at Ω/ω 1.6: 880).
    #[arg(long)]
    pub max_periods: Option<u32>,
    /// Steady-state tolerance that ends a transient, scaled (1e-9 ..= 1; the other commands'
    /// protocol uses 1e-4). An attractor's points must lie within half --attractor-tol of its
    /// limit: a slowly contracting state (light damping, near a fold) that still lies farther
    /// founds no attractor (it joins one found by an earlier start within the tolerance, else
    /// counts as no attractor); lower this and raise --max-periods.
    #[arg(long, default_value_t = ATTRACTOR_STEADY_TOL)]
    pub steady_tol: f64,
}

impl AttractorOpts {
    /// Checks the options, applies --max-periods (or the default for a run whose largest Ω/ω
    /// is `omega_ratio_max`, [`crate::attractors::transient_periods`], said on stderr where it
    /// exceeds the protocol's) and --steady-tol to `setup`, and returns the attractor
    /// tolerance and the recurrence settings.
    ///
    /// # Errors
    /// A value out of range, naming the flag and the range.
    pub fn apply(
        &self,
        setup: &mut Setup,
        omega_ratio_max: f64,
    ) -> Result<(f64, RecurrenceSettings)> {
        check_range("attractor_tol", self.attractor_tol, 1e-6, 1.0).context("--attractor-tol")?;
        let rec = RecurrenceSettings {
            tol: self.recurrence_tol,
            confirm: self.confirm,
        };
        rec.validate().map_err(|e| {
            let flag = if e.field() == "tol" {
                "--recurrence-tol"
            } else {
                "--confirm"
            };
            anyhow::Error::from(e).context(flag)
        })?;
        if let Some(n) = self.max_periods {
            anyhow::ensure!(
                (1..=1_000_000).contains(&n),
                "--max-periods {n}: out of range: allowed 1 ..= 1000000 (a start must have \
                 periods to reach an attractor)"
            );
            setup.settings.protocol.max_transient_periods = n;
            setup
                .settings
                .protocol
                .validate()
                .context("--max-periods")?;
        }
        setup.settings.protocol.steady_tol = self.steady_tol;
        setup.settings.protocol.validate().context("--steady-tol")?;
        if self.max_periods.is_none() {
            let protocol = &mut setup.settings.protocol;
            let n = transient_periods(
                &setup.params,
                protocol.max_transient_periods,
                omega_ratio_max,
                self.steady_tol,
            );
            if n > protocol.max_transient_periods {
                let cap = if n == MAX_TRANSIENT_PERIODS {
                    " (the default's cap)"
                } else {
                    ""
                };
                eprintln!(
                    "transient up to {n} periods{cap}: the suspension's free oscillation \
                     (ζ = {}) shrinks by --steady-tol {:e} in {} periods at Ω/ω \
                     {omega_ratio_max} (--max-periods to set it)",
                    setup.params.damping_ratio(),
                    self.steady_tol,
                    setup
                        .params
                        .free_decay_periods(omega_ratio_max, self.steady_tol)
                        .unwrap_or(f64::INFINITY)
                        .ceil()
                );
                protocol.max_transient_periods = n;
            }
        }
        Ok((self.attractor_tol, rec))
    }
}

/// A start off the impact surface: `u0 ≤ gap` (mm), which every command that takes `--u0-mm`
/// requires; `given` names the flag and its value as the message should quote them.
///
/// # Errors
/// `u0` beyond the surface, naming `given`.
pub fn check_start_off_surface(given: &str, u0_mm: f64, gap_mm: f64) -> Result<()> {
    if u0_mm > gap_mm {
        bail!(
            "{given} lies beyond the impact surface (gap {gap_mm} mm): allowed u0 ≤ gap \
             (the hammer cannot start pressed into the surface)"
        );
    }
    Ok(())
}

/// Where a lab file's time comes from and its unit (`identify`, `compare`).
#[derive(Debug, Clone, Args)]
pub struct TimeOpts {
    /// Time column: header name or 1-based number (ignored with --sample-rate-hz).
    #[arg(long, default_value = "t_s")]
    pub time_col: String,
    /// Unit of the time column.
    #[arg(long, value_enum, default_value = "s")]
    pub time_unit: TimeUnit,
    /// Fixed sample rate, Hz, for files without a time column (overrides the time column).
    #[arg(long)]
    pub sample_rate_hz: Option<f64>,
}

impl TimeOpts {
    /// How to read a trace whose values are in column `value_col` (name or 1-based number;
    /// `None`: [`TraceFormat::value_col`]'s default), `value_to_si` converting them to SI.
    pub fn format(&self, value_col: Option<&str>, value_to_si: f64) -> TraceFormat {
        TraceFormat {
            time_col: self.time_col.clone(),
            value_col: value_col.map(str::to_string),
            time_to_s: self.time_unit.to_s(),
            value_to_si,
            sample_rate_hz: self.sample_rate_hz,
        }
    }
}

/// Reserves and writes the CSV (`out`: `rows`) and/or the figure (`plot_path`: `points`) of
/// one response in `outputs` (`response` and `select`).
///
/// # Errors
/// File or drawing errors.
pub fn write_response(
    outputs: &mut Outputs,
    out: Option<&Path>,
    plot_path: Option<&Path>,
    title: &str,
    rows: &[ResponseRow],
    points: &[ResponsePoint],
    highlight: Option<Highlight>,
) -> Result<()> {
    if let Some(p) = out {
        let tmp = outputs.reserve(p)?;
        write_csv(&tmp, rows)?;
    }
    if let Some(p) = plot_path {
        let tmp = outputs.reserve(p)?;
        figures::response::response(&tmp, title, points, highlight, figures::response::MAX_FORCE)?;
    }
    Ok(())
}

//! `host-sim peterka`: the impact regime `z = p/q` over a gap × frequency grid (thesis
//! Fig. 3.24) and the `z = 1/1` region coloured by `F_i/mg` (Fig. 3.26), from rest at every
//! point (canonical protocol). Streams rows in chunks (flat memory), can run as a shard.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::{ArgGroup, Args};
use shared::analysis::response::OMEGA_RATIO_RANGE;

use super::{GridOutArgs, omega_sweep};
use crate::config::{RigOpts, Setup, parse_sweep};
use crate::grid;
use crate::grid::peterka::{self, Axis, AxisUnit, MAX_POINTS, Peterka, PeterkaGrid};

/// Arguments of `peterka`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
#[command(group(ArgGroup::new("gap").required(true).args(["gap_mm", "gap_ratio"])))]
#[command(group(ArgGroup::new("frequency").required(true).args(["freq_hz", "omega_ratio"])))]
pub struct PeterkaArgs {
    /// Rig and numerics.
    #[command(flatten)]
    pub rig: RigOpts,
    /// Gap sweep in mm, START:END:STEP (thesis: 0:3.42:0.01). Give this or --gap-ratio.
    #[arg(long, allow_hyphen_values = true)]
    pub gap_mm: Option<String>,
    /// Gap sweep as gap/A0, START:END:STEP (A0: the rig's cart amplitude).
    #[arg(long, allow_hyphen_values = true)]
    pub gap_ratio: Option<String>,
    /// Excitation-frequency sweep in Hz, START:END:STEP (thesis: 1:7.11:0.01). Give this or
    /// --omega-ratio.
    #[arg(long, allow_hyphen_values = true)]
    pub freq_hz: Option<String>,
    /// Frequency-ratio sweep Ω/ω, START:END:STEP.
    #[arg(long, allow_hyphen_values = true)]
    pub omega_ratio: Option<String>,
    /// CSV and regime map.
    #[command(flatten)]
    pub output: GridOutArgs,
    /// PNG or SVG: the z = 1/1 region coloured by F_i/mg, with a colour bar (Fig. 3.26).
    #[arg(long, value_parser = crate::output::figure_target)]
    pub force_plot: Option<PathBuf>,
    /// Refine each point's label by its largest Lyapunov exponent (column
    /// lyapunov_per_period): `chaotic` where positive beyond its uncertainty; where negative
    /// but no period showed, the run goes on (up to 2,000 periods) until a period q ≤ 64
    /// shows. Costs about 0.7× more (docs/performance.md).
    #[arg(long)]
    pub lyapunov: bool,
    /// Compute the curves that bound the z = 1/1 region (periodic orbits' bifurcations
    /// continued in the gap × Ω/ω plane, seeded from the grid's 1/1 points) and draw them on
    /// the --plot map.
    #[arg(long)]
    pub boundaries: bool,
    /// The boundary curves' CSV (curve, kind, regime, omega_ratio, gap_mm); implies --boundaries.
    #[arg(long, value_parser = crate::output::out_target)]
    pub boundaries_out: Option<PathBuf>,
}

fn parse_axes(a: &PeterkaArgs, setup: &Setup) -> Result<PeterkaGrid> {
    let a0_mm = setup.params.amplitude_m * 1e3;
    let fn_hz = setup.params.natural_freq_hz();
    let gap = match (&a.gap_mm, &a.gap_ratio) {
        (Some(t), None) => Axis {
            unit: AxisUnit::GapMm,
            sweep: parse_sweep("--gap-mm", t, 0.0, setup.max_gap_mm())?,
        },
        (None, Some(t)) => Axis {
            unit: AxisUnit::GapRatio,
            sweep: parse_sweep("--gap-ratio", t, 0.0, setup.max_gap_mm() / a0_mm)?,
        },
        _ => bail!("give exactly one of --gap-mm and --gap-ratio"),
    };
    let freq = match (&a.freq_hz, &a.omega_ratio) {
        (Some(t), None) => Axis {
            unit: AxisUnit::FreqHz,
            sweep: parse_sweep(
                "--freq-hz",
                t,
                OMEGA_RATIO_RANGE.0 * fn_hz,
                OMEGA_RATIO_RANGE.1 * fn_hz,
            )?,
        },
        (None, Some(t)) => Axis {
            unit: AxisUnit::OmegaRatio,
            sweep: omega_sweep(t)?,
        },
        _ => bail!("give exactly one of --freq-hz and --omega-ratio"),
    };
    super::warn_coarse_steps(
        setup,
        match freq.unit {
            AxisUnit::OmegaRatio => freq.sweep.lo,
            _ => freq.sweep.lo / fn_hz,
        },
    );
    let grid = PeterkaGrid {
        gap,
        freq,
        lyapunov: a.lyapunov,
        boundaries: a.boundaries || a.boundaries_out.is_some(),
    };
    if grid.points() > MAX_POINTS {
        bail!(
            "--gap-mm/--gap-ratio × --freq-hz/--omega-ratio: {} × {} = {} points is out of range: allowed at most {MAX_POINTS}",
            gap.sweep.len(),
            freq.sweep.len(),
            grid.points()
        );
    }
    Ok(grid)
}

/// Runs `peterka`.
///
/// # Errors
/// Bad input, I/O failure or Ctrl-C; no output file is left half-written.
pub fn run(a: &PeterkaArgs) -> Result<()> {
    let setup = Setup::from_opts(&a.rig)?;
    let grid = parse_axes(a, &setup)?;
    let dest = a
        .output
        .destination(a.force_plot.as_deref(), a.boundaries_out.as_deref())?;
    grid::from_rest::<Peterka, _>(
        &setup,
        &grid,
        grid.points(),
        dest,
        grid::streamed(|source, emit| peterka::rows(&setup, &grid, source, emit)),
    )
}

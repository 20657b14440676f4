//! `host-sim basins`: basins of attraction over a grid of initial conditions `(u0, u̇0)` at
//! phase 0 (thesis Figs. 3.36–3.38). Each point runs the canonical protocol from its initial
//! condition; its steady state is reduced to a regime and a canonical Poincaré point (for a
//! periodic regime of period `q`, the point of the last `q` window strobes with the smallest
//! `u`, so one attractor gives one point whatever its phase). Points are then grouped into
//! attractors: same regime and canonical points within `--attractor-tol` in the scaled
//! distance `max(|Δu|/A0, |Δu̇|/(A0 Ω))` of the first point of the group (in index order);
//! all `no impact` points form one group, as do all `irregular` points. Groups get letters
//! `A, B, …` sorted by regime (no impact, p/q ascending, irregular) then `u`, then `u̇`.
//!
//! A shard stores the ungrouped rows (with each attractor's `points`); grouping needs the
//! whole grid and happens in the one-run command and in `merge`, through the same code.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use shared::analysis::response::OMEGA_RATIO_RANGE;
use shared::error::check_range;

use super::{AttractorOpts, GridOutArgs};
use crate::attractors::Catalogue;
use crate::config::{RigOpts, Setup};
use crate::grid::basins::{self, Attractors, Basins, BasinsGrid, ColorBy, MAX_U0_MM, MAX_V0_MM_S};
use crate::grid::{self, CountSweep};

/// Arguments of `basins`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct BasinsArgs {
    /// Rig and numerics.
    #[command(flatten)]
    pub rig: RigOpts,
    /// Gap, mm (≥ 0).
    #[arg(long)]
    pub gap_mm: f64,
    /// Excitation frequency as Ω/ω.
    #[arg(long)]
    pub omega_ratio: f64,
    /// Initial displacements u0 in mm as START:END:COUNT (COUNT points, both ends included;
    /// -20 mm ≤ u0 ≤ gap).
    #[arg(long, allow_hyphen_values = true)]
    pub u0_mm: String,
    /// Initial velocities u̇0 in mm/s as START:END:COUNT (|u̇0| ≤ 10000 mm/s).
    #[arg(long, allow_hyphen_values = true)]
    pub v0_mm_s: String,
    /// How attractors are found.
    #[command(flatten)]
    pub attractors: AttractorOpts,
    /// What the figure colours: each attractor, each regime, or impacting / not (the thesis'
    /// view).
    #[arg(long, value_enum, default_value_t = ColorBy::Attractor)]
    pub color_by: ColorBy,
    /// CSV: the attractor catalogue (attractor, regime, count, fraction, ci95_lo, ci95_hi,
    /// impact_force_mg, and one row per Poincaré point k, u_mm, v_mm_s).
    #[arg(long, value_parser = crate::output::out_target)]
    pub attractors_out: Option<PathBuf>,
    /// CSV and figure.
    #[command(flatten)]
    pub output: GridOutArgs,
}

/// Runs `basins`.
///
/// # Errors
/// Bad input, I/O failure or Ctrl-C; no output file is left half-written.
pub fn run(a: &BasinsArgs) -> Result<()> {
    let mut setup = Setup::from_opts(&a.rig)?;
    setup.gap_m("--gap-mm", a.gap_mm)?;
    check_range(
        "omega_ratio",
        a.omega_ratio,
        OMEGA_RATIO_RANGE.0,
        OMEGA_RATIO_RANGE.1,
    )
    .context("--omega-ratio")?;
    super::warn_coarse_steps(&setup, a.omega_ratio);
    let u0_mm = CountSweep::parse("--u0-mm", &a.u0_mm, -MAX_U0_MM, MAX_U0_MM)?;
    let v0_mm_s = CountSweep::parse("--v0-mm-s", &a.v0_mm_s, -MAX_V0_MM_S, MAX_V0_MM_S)?;
    super::check_start_off_surface(
        &format!("--u0-mm {}: END = {} mm", a.u0_mm, u0_mm.end),
        u0_mm.end,
        a.gap_mm,
    )?;
    // After the input's checks: it says the transient it sets.
    let (attractor_tol, recurrence) = a.attractors.apply(&mut setup, a.omega_ratio)?;
    let grid = BasinsGrid {
        gap_mm: a.gap_mm,
        omega_ratio: a.omega_ratio,
        u0_mm,
        v0_mm_s,
        attractor_tol,
        recurrence,
        color_by: a.color_by,
    };
    let mut dest = a.output.destination(None, None)?;
    dest.figures.attractors = a.attractors_out.as_deref();
    let catalogue = Catalogue::new(
        Attractors::scales(&setup.params, grid.omega_ratio),
        attractor_tol,
    );
    grid::from_rest::<Basins, _>(
        &setup,
        &grid,
        grid.points(),
        dest,
        grid::batches(|b| basins::rows(&setup, &grid, &catalogue, b)),
    )
}

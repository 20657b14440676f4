//! `host-sim fractions`: basin fractions of the attractors from random initial conditions in a
//! box, with Wilson 95 % intervals, at one operating point or continued over `Ω/ω` or the gap
//! (`crate::grid::fractions`).

use anyhow::{Context, Result, bail};
use clap::Args;
use shared::analysis::response::OMEGA_RATIO_RANGE;
use shared::error::check_range;

use super::{AttractorOpts, GridOutArgs};
use crate::config::{RigOpts, Setup, parse_sweep};
use crate::grid::basins::{MAX_U0_MM, MAX_V0_MM_S};
use crate::grid::fractions::{
    Fractions, FractionsGrid, MAX_SAMPLES, Parameter, StartBox, check_width, run_adaptive,
};
use crate::grid::{self, complete};
use crate::shard::create_csv;

/// Arguments of `fractions`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct FractionsArgs {
    /// Rig and numerics.
    #[command(flatten)]
    pub rig: RigOpts,
    /// Gap, mm: a value, or START:END:STEP to continue the fractions over the gap.
    #[arg(long, allow_hyphen_values = true)]
    pub gap_mm: String,
    /// Ω/ω: a value, or START:END:STEP to continue the fractions over the frequency.
    #[arg(long, allow_hyphen_values = true)]
    pub omega_ratio: String,
    /// Initial displacements u0, mm, as LO:HI (uniform; u0 ≤ gap, |u0| ≤ 20). Without
    /// --u0-mm/--v0-mm-s: the start-up box, u0 from −max(gap, A0) to gap and u̇0 within ±A0 Ω.
    #[arg(long, allow_hyphen_values = true, requires = "v0_mm_s")]
    pub u0_mm: Option<String>,
    /// Initial velocities u̇0, mm/s, as LO:HI (uniform; |u̇0| ≤ 10000).
    #[arg(long, allow_hyphen_values = true, requires = "u0_mm")]
    pub v0_mm_s: Option<String>,
    /// Seed of the initial conditions.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Initial conditions per operating point (with --width: the most that may be drawn;
    /// 1 ..= 1000000).
    #[arg(long, default_value_t = 2000)]
    pub samples: u32,
    /// Draw rounds of 256 initial conditions until every attractor's 95 % interval is narrower
    /// than this (0 < width < 1; must be reachable within --samples); not with a shard.
    #[arg(long)]
    pub width: Option<f64>,
    /// Largest scaled distance between the canonical Poincaré points of one attractor at
    /// consecutive operating points (0 < tol ≤ 10).
    #[arg(long, default_value_t = crate::attractors::MATCH_TOL)]
    pub match_tol: f64,
    /// How attractors are found.
    #[command(flatten)]
    pub attractors: AttractorOpts,
    /// CSV (one row per operating point and attractor: gap_mm, omega_ratio, freq_hz, attractor,
    /// regime, u_mm, v_mm_s, impact_force_mg, count, samples, fraction, ci95_lo, ci95_hi) and
    /// the stacked figure of the fractions against the parameter.
    #[command(flatten)]
    pub output: GridOutArgs,
}

/// A value or a `START:END:STEP` sweep given to `flag`, within `[min, max]`.
fn values(flag: &'static str, text: &str, min: f64, max: f64) -> Result<Vec<f64>> {
    if text.contains(':') {
        let s = parse_sweep(flag, text, min, max)?;
        return Ok((0..s.len()).map(|i| s.value(i)).collect());
    }
    let v: f64 = text
        .trim()
        .parse()
        .with_context(|| format!("{flag} {text}: not a number"))?;
    check_range(flag, v, min, max)?;
    Ok(vec![v])
}

/// A `LO:HI` range given to `flag`, within `[min, max]`.
fn range(flag: &str, text: &str, min: f64, max: f64) -> Result<(f64, f64)> {
    let (a, b) = text
        .split_once(':')
        .with_context(|| format!("{flag} {text}: expected LO:HI, e.g. -1:0"))?;
    let num = |p: &str| -> Result<f64> {
        p.trim()
            .parse::<f64>()
            .with_context(|| format!("{flag} {text}: `{p}` is not a number"))
    };
    let (lo, hi) = (num(a)?, num(b)?);
    for v in [lo, hi] {
        if !v.is_finite() || v < min || v > max {
            bail!("{flag} {text}: {v} is out of range: allowed {min} ..= {max}");
        }
    }
    if lo > hi {
        bail!("{flag} {text}: LO must be ≤ HI");
    }
    Ok((lo, hi))
}

/// Runs `fractions`.
///
/// # Errors
/// Bad input, I/O failure or Ctrl-C; no output file is left half-written.
pub fn run(a: &FractionsArgs) -> Result<()> {
    let mut setup = Setup::from_opts(&a.rig)?;
    let gaps = values("--gap-mm", &a.gap_mm, 0.0, setup.max_gap_mm())?;
    let ratios = values(
        "--omega-ratio",
        &a.omega_ratio,
        OMEGA_RATIO_RANGE.0,
        OMEGA_RATIO_RANGE.1,
    )?;
    super::warn_coarse_steps(&setup, ratios.iter().copied().fold(f64::INFINITY, f64::min));
    let (parameter, points): (Parameter, Vec<(f64, f64)>) = match (gaps.len(), ratios.len()) {
        (1, _) => (
            Parameter::OmegaRatio,
            ratios.iter().map(|&r| (gaps[0], r)).collect(),
        ),
        (_, 1) => (
            Parameter::GapMm,
            gaps.iter().map(|&g| (g, ratios[0])).collect(),
        ),
        _ => {
            bail!("--gap-mm and --omega-ratio: continue over one of them only (the other a value)")
        }
    };
    for &(g, _) in &points {
        setup.gap_m("--gap-mm", g)?;
    }
    let ratio_max = points.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    if !(1..=MAX_SAMPLES).contains(&a.samples) {
        bail!(
            "--samples {}: out of range: allowed 1 ..= {MAX_SAMPLES}",
            a.samples
        );
    }
    if !(a.match_tol.is_finite() && a.match_tol > 0.0 && a.match_tol <= 10.0) {
        bail!(
            "--match-tol {}: out of range: allowed 0 < tol ≤ 10",
            a.match_tol
        );
    }
    let start = match (&a.u0_mm, &a.v0_mm_s) {
        (Some(u), Some(v)) => {
            let u0_mm = range("--u0-mm", u, -MAX_U0_MM, MAX_U0_MM)?;
            let v0_mm_s = range("--v0-mm-s", v, -MAX_V0_MM_S, MAX_V0_MM_S)?;
            let least_gap = points.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
            super::check_start_off_surface(
                &format!("--u0-mm {u}: HI = {} mm", u0_mm.1),
                u0_mm.1,
                least_gap,
            )?;
            StartBox::Explicit { u0_mm, v0_mm_s }
        }
        _ => StartBox::Startup,
    };
    let shard = a.output.shard.resolve()?;
    if let Some(w) = a.width {
        if shard.is_some() {
            bail!(
                "--width: the adaptive mode runs whole; with a shard give a fixed --samples \
                 (and no --width)"
            );
        }
        check_width(w, a.samples)?;
    }
    // After the input's checks: it says the transient it sets.
    let (attractor_tol, recurrence) = a.attractors.apply(&mut setup, ratio_max)?;
    let grid = FractionsGrid {
        points,
        parameter,
        start,
        seed: a.seed,
        samples: a.samples,
        width: a.width,
        attractor_tol,
        match_tol: a.match_tol,
        recurrence,
    };
    let total = grid.points.len() as u64 * u64::from(grid.samples);
    let dest = a.output.destination(None, None)?;
    if grid.width.is_some() {
        return grid::command::<Fractions>(
            &setup,
            &grid,
            total,
            dest,
            |outputs, meta, out, figures| {
                complete::<Fractions>(outputs, meta, out, figures, |path| {
                    let mut w = create_csv::<crate::grid::basins::BasinRaw>(path, None)?;
                    run_adaptive(&setup, meta, &grid, |row| Ok(w.serialize(row)?))?;
                    w.flush()?;
                    Ok(())
                })
            },
        );
    }
    let catalogues = grid.catalogues(&setup);
    grid::from_rest::<Fractions, _>(
        &setup,
        &grid,
        total,
        dest,
        grid::batches(|b| grid.rows(&setup, &catalogues, b)),
    )
}

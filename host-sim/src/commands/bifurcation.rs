//! `host-sim bifurcation`: the bifurcation diagram over an `Ω/ω` sweep at one gap, from rest
//! at each frequency (parallel, shardable) or by continuation up, down or both (the
//! computation: [`crate::grid::bifurcation`]).
use anyhow::{Result, bail};
use clap::Args;

use super::GridOutArgs;
use super::omega_sweep;
use crate::config::{RigOpts, Setup};
use crate::grid::bifurcation::{self, BifGrid, Bifurcation, Continuation};
use crate::grid::{self, per_point};

/// Arguments of `bifurcation`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct BifurcationArgs {
    /// Rig and numerics.
    #[command(flatten)]
    pub rig: RigOpts,
    /// Gap, mm (≥ 0).
    #[arg(long)]
    pub gap_mm: f64,
    /// Frequency-ratio sweep Ω/ω as START:END:STEP.
    #[arg(long, allow_hyphen_values = true)]
    pub omega_ratio: String,
    /// Start each frequency from the previous one's final state, sweeping up, down or both
    /// (default: from rest at each frequency).
    #[arg(long, value_enum)]
    pub continuation: Option<Continuation>,
    /// The protocol's labels alone, no Lyapunov exponent (its column empty). By default each
    /// frequency's largest exponent (its orbit's `ln max|μ|/q` where periodic, else over 64
    /// periods) refines the label: `chaotic`, or the period an extended run finds.
    #[arg(long)]
    pub no_lyapunov: bool,
    /// CSV and diagram.
    #[command(flatten)]
    pub output: GridOutArgs,
}

/// Runs `bifurcation`.
///
/// # Errors
/// Bad input, I/O failure or Ctrl-C; no output file is left half-written.
pub fn run(a: &BifurcationArgs) -> Result<()> {
    let setup = Setup::from_opts(&a.rig)?;
    let gap_m = setup.gap_m("--gap-mm", a.gap_mm)?;
    let sweep = omega_sweep(&a.omega_ratio)?;
    super::warn_coarse_steps(&setup, sweep.lo);
    let dest = a.output.destination(None, None)?;
    if a.continuation.is_some() && dest.shard.is_some() {
        bail!(
            "--shard: a continuation is sequential along the sweep and cannot be sharded \
             (drop --shard, and unset {}/{} if they are set; or run from rest)",
            crate::shard::SLURM_VARS.0,
            crate::shard::SLURM_VARS.1
        );
    }
    let grid = BifGrid {
        gap_mm: a.gap_mm,
        omega_ratio: sweep,
        continuation: a.continuation,
        lyapunov: !a.no_lyapunov,
    };
    let points = sweep.len() as u64;
    grid::command::<Bifurcation>(&setup, &grid, points, dest, |o, meta, out, f| {
        match a.continuation {
            Some(mode) => grid::complete::<Bifurcation>(o, meta, out, f, |path| {
                bifurcation::continuation(&setup, gap_m, &sweep, mode, !a.no_lyapunov, path)
            }),
            None => grid::run::<Bifurcation, _>(
                o,
                meta,
                out,
                f,
                grid::batches(per_point(|i| {
                    bifurcation::from_rest(&setup, gap_m, &sweep, i, !a.no_lyapunov)
                })),
            ),
        }
    })
}

//! `host-sim merge`: joins the shard CSVs of one `peterka`, `basins`, `fractions` or
//! `bifurcation` run
//! (`--shard I/N`) into the CSV and figures a single run would have written, byte for byte:
//! the rows go, in point-index order, through the same writer and figure code as the one-run
//! command. Checks that every shard has the same metadata (kind, tool version, rig, settings,
//! precision, grid) and that every point index appears exactly once. Memory stays flat: the
//! shards are read in step (a k-way merge by index).

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use clap::Args;

use crate::grid::basins::Basins;
use crate::grid::bifurcation::Bifurcation;
use crate::grid::fractions::Fractions;
use crate::grid::peterka::Peterka;
use crate::grid::{Figures, merge};
use crate::output::Outputs;
use crate::shard::{Kind, open_all};

/// Arguments of `merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Expected kind (default: read from the shards' metadata).
    #[arg(long, value_enum)]
    pub kind: Option<Kind>,
    /// Merged CSV (the columns of the one-run command).
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: PathBuf,
    /// PNG or SVG: the command's figure (Peterka regime map, basins map or bifurcation diagram).
    #[arg(long, value_parser = crate::output::figure_target)]
    pub plot: Option<PathBuf>,
    /// PNG (peterka only): the z = 1/1 region coloured by F_i/mg.
    #[arg(long, value_parser = crate::output::figure_target)]
    pub force_plot: Option<PathBuf>,
    /// CSV (peterka shards run with --boundaries): the curves bounding the z = 1/1 region.
    #[arg(long, value_parser = crate::output::out_target)]
    pub boundaries_out: Option<PathBuf>,
    /// CSV (basins shards): the attractor catalogue (id, regime, fraction with its 95 %
    /// interval, F_i/mg, Poincaré points).
    #[arg(long, value_parser = crate::output::out_target)]
    pub attractors_out: Option<PathBuf>,
    /// Shard CSVs, in any order.
    #[arg(required = true, value_name = "SHARD.csv")]
    pub shards: Vec<PathBuf>,
}

/// Runs `merge`.
///
/// # Errors
/// Malformed or mismatched shards, a missing or repeated point, I/O failure or Ctrl-C; no
/// output file is left half-written.
pub fn run(a: &MergeArgs) -> Result<()> {
    let (meta, files) = open_all(&a.shards, a.kind)?;
    if a.force_plot.is_some() && meta.kind != Kind::Peterka {
        bail!(
            "--force-plot: only for peterka shards (these are {})",
            meta.kind
        );
    }
    if a.boundaries_out.is_some() {
        let with = meta.kind == Kind::Peterka
            && meta.grid::<crate::grid::peterka::PeterkaGrid>()?.boundaries;
        if !with {
            bail!("--boundaries-out: only for peterka shards run with --boundaries");
        }
    }
    let figures = Figures {
        plot: a.plot.as_deref(),
        force_plot: a.force_plot.as_deref(),
        boundaries: a.boundaries_out.as_deref(),
        attractors: a.attractors_out.as_deref(),
    };
    let inputs: Vec<(&str, &Path)> = a.shards.iter().map(|p| ("a shard", p.as_path())).collect();
    figures.check_distinct(&a.out, &inputs)?;
    let n_files = files.len();
    let mut outputs = Outputs::new();
    let out = outputs.reserve(&a.out)?;
    if a.attractors_out.is_some() && !matches!(meta.kind, Kind::Basins | Kind::Fractions) {
        bail!(
            "--attractors-out: only for basins or fractions shards (these are {})",
            meta.kind
        );
    }
    match meta.kind {
        Kind::Peterka => merge::<Peterka>(&mut outputs, &meta, files, &out, figures)?,
        Kind::Basins => merge::<Basins>(&mut outputs, &meta, files, &out, figures)?,
        Kind::Fractions => merge::<Fractions>(&mut outputs, &meta, files, &out, figures)?,
        Kind::Bifurcation => merge::<Bifurcation>(&mut outputs, &meta, files, &out, figures)?,
    }
    outputs.commit()?;
    eprintln!(
        "merged {}: {}, {} → {}",
        crate::output::count(n_files as u64, "shard"),
        meta.kind,
        meta.kind.counted(meta.points),
        a.out.display()
    );
    Ok(())
}

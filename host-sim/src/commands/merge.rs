//! `host-sim merge`: joins the shard CSVs of one `peterka`, `basins` or `bifurcation` run
//! (`--shard I/N`) into the CSV and figures a single run would have written, byte for byte:
//! the rows go, in point-index order, through the same writer and figure code as the one-run
//! command. Checks that every shard has the same metadata (kind, tool version, rig, settings,
//! precision, grid) and that every point index appears exactly once. Memory stays flat: the
//! shards are read in step (a k-way merge by index).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;

use super::{basins, bifurcation, peterka};
use crate::output::Outputs;
use crate::shard::{Kind, create_csv, merge_rows, open_all};

/// Arguments of `merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Expected kind (default: read from the shards' metadata).
    #[arg(long, value_enum)]
    pub kind: Option<Kind>,
    /// Merged CSV (the columns of the one-run command).
    #[arg(long)]
    pub out: PathBuf,
    /// PNG: the command's figure (Peterka regime map, basins map or bifurcation diagram).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// PNG (peterka only): the z = 1/1 region coloured by F_i/mg.
    #[arg(long)]
    pub force_plot: Option<PathBuf>,
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
    let n_files = files.len();
    let mut outputs = Outputs::new();
    let out = outputs.reserve(&a.out)?;
    match meta.kind {
        Kind::Peterka => {
            let mut w = create_csv(&out, None, &peterka::HEADER)?;
            merge_rows::<peterka::PeterkaRow>(files, meta.points, &peterka::HEADER, false, |r| {
                Ok(w.serialize(r)?)
            })?;
            w.flush()?;
            peterka::figures(
                &mut outputs,
                &meta,
                &out,
                a.plot.as_deref(),
                a.force_plot.as_deref(),
            )?;
        }
        Kind::Bifurcation => {
            let mut w = create_csv(&out, None, &bifurcation::HEADER)?;
            merge_rows::<bifurcation::BifRow>(
                files,
                meta.points,
                &bifurcation::HEADER,
                true,
                |r| Ok(w.serialize(r)?),
            )?;
            w.flush()?;
            bifurcation::figure(&mut outputs, &meta, &out, a.plot.as_deref())?;
        }
        Kind::Basins => {
            let raw = tempfile::Builder::new()
                .prefix(".host-sim-")
                .suffix(".raw.csv")
                .tempfile_in(out.parent().unwrap_or(Path::new(".")))
                .context("cannot create a temporary file next to --out")?;
            let mut w = create_csv(raw.path(), None, &basins::RAW_HEADER)?;
            merge_rows::<basins::BasinRaw>(files, meta.points, &basins::RAW_HEADER, false, |r| {
                Ok(w.serialize(r)?)
            })?;
            w.flush()?;
            drop(w);
            basins::finish(&mut outputs, &meta, raw.path(), &out, a.plot.as_deref())?;
        }
    }
    outputs.commit()?;
    eprintln!(
        "merged {n_files} shards: {}, {} points → {}",
        meta.kind,
        meta.points,
        a.out.display()
    );
    Ok(())
}

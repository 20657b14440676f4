//! Long grid runs with flat memory: the points of a grid (or of one shard of it) are evaluated
//! in parallel (all cores or `RAYON_NUM_THREADS`) and their results are handed to a sink in
//! index order, so the sink can stream CSV rows to disk and nothing grows with the grid. Grids
//! whose points are independent (the Peterka map) stream them through every core's interleaved
//! lanes ([`run_streamed`]: at most [`stream::WINDOW`] points ahead of the rows written); the
//! others take them in chunks of [`CHUNK`] in ascending index order, each chunk in batches
//! ([`run_chunked`]). A progress bar with rate and ETA is drawn on a terminal (nothing when
//! stderr is not a terminal). Ctrl-C stops the run, after the runs in flight or the current
//! chunk, with [`Interrupted`](crate::interrupt::Interrupted).

use anyhow::{Context, Result, anyhow, bail};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use std::path::Path;

use crate::config::Setup;
use crate::interrupt;
use crate::output::{Outputs, scratch};
use crate::progress::progress;
use crate::runner::guided;
use crate::shard::{Indexed, Kind, Meta, Shard, ShardFile, create_csv, merge_rows};

pub mod basins;
pub mod bifurcation;
pub mod fractions;
pub mod peterka;
pub mod raster;
pub mod stream;

pub use stream::{Batches, GridCompute, Streamed, batches, run_streamed, streamed};

/// Points evaluated per parallel chunk.
pub const CHUNK: usize = 16384;

/// Evaluates `compute(batch)` (the results of the indices in `batch`, in order) over every index
/// of `indices` (ascending), `CHUNK` at a time with [`guided`] batches in parallel, and passes
/// each result to `sink` in index order. `len` is the number of indices (for the progress bar).
///
/// # Errors
/// The first failing point or sink call (in index order), or [`Interrupted`](crate::interrupt::Interrupted).
pub fn run_chunked<R: Send>(
    indices: impl Iterator<Item = usize>,
    len: usize,
    what: &str,
    compute: impl Fn(&[usize]) -> Vec<Result<R>> + Sync,
    mut sink: impl FnMut(usize, R) -> Result<()>,
) -> Result<()> {
    interrupt::install();
    let bar = progress(len, what);
    let mut indices = indices;
    let mut chunk: Vec<usize> = Vec::with_capacity(CHUNK);
    loop {
        chunk.clear();
        chunk.extend(indices.by_ref().take(CHUNK));
        if chunk.is_empty() {
            break;
        }
        let results: Vec<Option<Vec<Result<R>>>> = guided(&chunk, |batch| {
            if interrupt::requested() {
                return None;
            }
            let r = compute(batch);
            bar.inc(batch.len() as u64);
            Some(r)
        });
        if let Err(e) = interrupt::check() {
            bar.abandon();
            return Err(e.into());
        }
        let mut at = chunk.iter();
        for batch in results {
            let batch = batch.ok_or_else(|| anyhow!(interrupt::Interrupted))?;
            for r in batch {
                let &i = at
                    .next()
                    .ok_or_else(|| anyhow!("internal: batch longer than its chunk"))?;
                sink(i, r?)?;
            }
        }
    }
    bar.finish_and_clear();
    Ok(())
}

/// [`run_chunked`]'s `compute` for a per-point function.
pub fn per_point<R>(
    compute: impl Fn(usize) -> Result<R> + Sync,
) -> impl Fn(&[usize]) -> Vec<Result<R>> + Sync {
    move |batch| batch.iter().map(|&i| compute(i)).collect()
}

/// Writes the rows of a from-rest grid run to the CSV `path`: the points of `meta.shard` (or
/// all), `compute` giving the rows of each point ([`GridCompute`]: in batches or streamed), in
/// index order. A shard file starts with its metadata line; a whole-grid file is a plain CSV.
///
/// # Errors
/// As [`GridCompute::evaluate`], or I/O failure.
pub fn write_grid<I>(
    path: &Path,
    meta: &Meta,
    what: &str,
    compute: impl GridCompute<I>,
) -> Result<()>
where
    I: IntoIterator + Send,
    I::Item: Serialize + DeserializeOwned,
{
    let total = usize::try_from(meta.points).context("grid too large for this platform")?;
    let shard = meta.shard.unwrap_or(Shard::WHOLE);
    let mut w = create_csv::<I::Item>(path, meta.shard.is_some().then_some(meta))?;
    compute.evaluate(shard.indices(total), shard.len(total), what, |_, rows| {
        for r in rows {
            w.serialize(r)?;
        }
        Ok(())
    })?;
    w.flush()?;
    Ok(())
}

/// The figures asked of a grid command or of `merge` (each absent if not asked).
#[derive(Debug, Clone, Copy, Default)]
pub struct Figures<'a> {
    /// The kind's figure (Peterka regime map, basins map, bifurcation diagram).
    pub plot: Option<&'a Path>,
    /// Peterka only: the `z = 1/1` region coloured by `F_i/mg`.
    pub force_plot: Option<&'a Path>,
    /// Peterka only: the CSV of the curves bounding the `1/1` region (`--boundaries`).
    pub boundaries: Option<&'a Path>,
    /// Basins and fractions: the attractor catalogue CSV (`--attractors-out`).
    pub attractors: Option<&'a Path>,
}

impl Figures<'_> {
    /// Checks that the CSV `out` and these figures are distinct files, none of them one of
    /// `inputs` ([`crate::output::distinct_files`]).
    ///
    /// # Errors
    /// Two of them name the same file.
    pub fn check_distinct(&self, out: &Path, inputs: &[(&str, &Path)]) -> Result<()> {
        let outputs = crate::output::given(&[
            ("--out", Some(out)),
            ("--plot", self.plot),
            ("--force-plot", self.force_plot),
            ("--boundaries-out", self.boundaries),
            ("--attractors-out", self.attractors),
        ]);
        crate::output::distinct_files(inputs, &outputs)
    }
}

/// A gridded analysis that runs whole or in shards and whose shards merge into the one-run
/// outputs: its grid, its row type (the CSV header is derived from it) and its figures.
pub trait GridKind {
    /// The kind named in shard metadata.
    const KIND: Kind;
    /// Whether one point index may span several consecutive rows (bifurcation: the samples of
    /// one frequency).
    const GROUPED: bool = false;
    /// Whether the rows file is the command's CSV; otherwise [`GridKind::finish`] writes the
    /// CSV from it (basins: the attractors need the whole grid).
    const ROWS_ARE_OUTPUT: bool = true;
    /// The grid (metadata `grid`).
    type Grid: Serialize + DeserializeOwned;
    /// One row of a shard file, in point-index order.
    type Row: Serialize + DeserializeOwned + Indexed + Send;
    /// What the figures need besides the rows file (basins: the attractors and their raster).
    type Summary;

    /// Writes the CSV of a complete grid from its rows file (unless the rows are it) and
    /// returns what the figures need.
    ///
    /// # Errors
    /// Unreadable rows, file errors.
    fn finish(job: &mut Finish<'_>) -> Result<Self::Summary>;

    /// Checks a row read back from a shard against the grid it claims to belong to (its
    /// coordinates are those of its index; its values finite): `Err` says which field is off.
    /// The default checks nothing.
    ///
    /// # Errors
    /// A coordinate that is not its index's, or a value that cannot be the command's.
    fn check_row(_meta: &Meta, _grid: &Self::Grid, _row: &Self::Row) -> Result<(), String> {
        Ok(())
    }
}

/// `Err` naming `field` unless `value` is `expected` exactly (coordinates of a grid index are
/// computed, written and read back to the same bits).
pub fn same_coordinate(field: &str, value: f64, expected: f64) -> Result<(), String> {
    if value.to_bits() == expected.to_bits() {
        Ok(())
    } else {
        Err(format!(
            "{field} = {value} is not the grid's {expected} at this index (an edited row?)"
        ))
    }
}

/// `Err` naming `field` unless `value` is finite and not negative.
pub fn finite_non_negative(field: &str, value: f64) -> Result<(), String> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(format!("{field} = {value}: expected a finite value ≥ 0"))
    }
}

/// The figures of a grid kind, drawn from a complete grid (implemented where the figures are,
/// `crate::figures::maps`: the grid computations never import figure code).
pub trait GridFigures: GridKind {
    /// Draws the figures asked for in `job.figures`, reserved in `job.outputs`.
    ///
    /// # Errors
    /// Unreadable rows, drawing or file errors.
    fn draw(job: &mut Finish<'_>, summary: Self::Summary) -> Result<()>;
}

/// What [`GridKind::finish`] works on: a complete grid's rows file and where its outputs go.
pub struct Finish<'a> {
    /// Where the outputs are reserved (each written whole or not at all).
    pub outputs: &'a mut Outputs,
    /// The grid's metadata.
    pub meta: &'a Meta,
    /// The rows file: a plain CSV of [`GridKind::Row`] with header.
    pub rows: &'a Path,
    /// The command's CSV (the rows file itself where the rows are the output).
    pub out: &'a Path,
    /// The figures asked for.
    pub figures: Figures<'a>,
}

/// The metadata of a run of kind `K` over `grid` (`points` points, no shard yet).
///
/// # Errors
/// The grid does not serialise (internal).
pub fn meta<K: GridKind>(setup: &Setup, grid: &K::Grid, points: u64) -> Result<Meta> {
    Meta::new(K::KIND, setup, grid, points)
}

/// The outputs of a complete grid of kind `K`: `fill(path)` writes its rows file (a plain CSV
/// of `K::Row` with header) at `path`, which is `out` itself or a scratch file next to it; then
/// [`GridKind::finish`] and [`GridFigures::draw`]. The same function serves a one-run command
/// and `merge`, so their outputs are identical.
///
/// # Errors
/// As `fill`, [`GridKind::finish`] and [`GridFigures::draw`].
pub fn complete<K: GridFigures>(
    outputs: &mut Outputs,
    meta: &Meta,
    out: &Path,
    figures: Figures<'_>,
    fill: impl FnOnce(&Path) -> Result<()>,
) -> Result<()> {
    let scratch_rows = if K::ROWS_ARE_OUTPUT {
        None
    } else {
        Some(scratch(out, ".raw.csv")?)
    };
    let rows = scratch_rows.as_ref().map_or(out, |f| f.path());
    fill(rows)?;
    let mut job = Finish {
        outputs,
        meta,
        rows,
        out,
        figures,
    };
    let summary = K::finish(&mut job)?;
    K::draw(&mut job, summary)
}

/// A from-rest grid run of kind `K` into `out` (a reserved file): the shard file of
/// `meta.shard`, or the complete outputs ([`complete`]); `compute` gives the rows of each
/// point ([`write_grid`]).
///
/// # Errors
/// As [`write_grid`] and [`GridKind::finish`].
pub fn run<K: GridFigures, I>(
    outputs: &mut Outputs,
    meta: &Meta,
    out: &Path,
    figures: Figures<'_>,
    compute: impl GridCompute<I>,
) -> Result<()>
where
    I: IntoIterator<Item = K::Row> + Send,
{
    let what = K::KIND.to_string();
    if meta.shard.is_some() {
        write_grid(out, meta, &what, compute)
    } else {
        complete::<K>(outputs, meta, out, figures, |path| {
            write_grid(path, meta, &what, compute)
        })
    }
}

/// Where a grid command writes: its CSV, the figures asked for, and the shard it computes
/// (`None`: the whole grid).
#[derive(Debug, Clone, Copy)]
pub struct Destination<'a> {
    /// The CSV (a shard's rows file with a shard).
    pub out: &'a Path,
    /// The figures asked for (refused with a shard).
    pub figures: Figures<'a>,
    /// The shard computed.
    pub shard: Option<Shard>,
}

/// A grid command of kind `K` over `grid` (`points` points) into `dest`: refuses figures on a
/// shard, reserves the CSV, lets `write(outputs, meta, reserved out, figures)` fill it ([`run`]
/// or [`complete`]), commits the outputs and reports on stderr.
///
/// # Errors
/// A figure asked of a shard (named), and as `write`; nothing is left half-written.
pub fn command<K: GridKind>(
    setup: &Setup,
    grid: &K::Grid,
    points: u64,
    dest: Destination<'_>,
    write: impl FnOnce(&mut Outputs, &Meta, &Path, Figures<'_>) -> Result<()>,
) -> Result<()> {
    let Destination {
        out,
        figures,
        shard,
    } = dest;
    figures.check_distinct(out, &[])?;
    if shard.is_some() {
        let asked: Vec<&str> = [
            ("--plot", figures.plot),
            ("--force-plot", figures.force_plot),
            ("--boundaries-out", figures.boundaries),
            ("--attractors-out", figures.attractors),
        ]
        .iter()
        .filter_map(|(flag, p)| p.map(|_| *flag))
        .collect();
        if !asked.is_empty() {
            bail!(
                "{}: a shard (--shard, or {}/{} set) writes only its CSV; draw the figures \
                 with `host-sim merge`",
                asked.join(", "),
                crate::shard::SLURM_VARS.0,
                crate::shard::SLURM_VARS.1
            );
        }
    }
    let mut meta = meta::<K>(setup, grid, points)?;
    meta.shard = shard;
    let mut outputs = Outputs::new();
    let reserved = outputs.reserve(out)?;
    write(&mut outputs, &meta, &reserved, figures)?;
    outputs.commit()?;
    eprintln!("{} → {}", meta.describe(), out.display());
    Ok(())
}

/// A from-rest grid command ([`command`] with [`run`]): `compute` gives the rows of each
/// point ([`GridCompute`]).
///
/// # Errors
/// As [`command`] and [`run`].
pub fn from_rest<K: GridFigures, I>(
    setup: &Setup,
    grid: &K::Grid,
    points: u64,
    dest: Destination<'_>,
    compute: impl GridCompute<I>,
) -> Result<()>
where
    I: IntoIterator<Item = K::Row> + Send,
{
    command::<K>(setup, grid, points, dest, |outputs, meta, out, figures| {
        run::<K, I>(outputs, meta, out, figures, compute)
    })
}

/// Merges the shard `files` of one grid of kind `K` (their shared metadata `meta`) into the
/// outputs a single run writes ([`complete`]), streaming the rows in point-index order.
///
/// # Errors
/// Malformed shards, a missing or repeated point, I/O or drawing errors, Ctrl-C.
pub fn merge<K: GridFigures>(
    outputs: &mut Outputs,
    meta: &Meta,
    files: Vec<ShardFile>,
    out: &Path,
    figures: Figures<'_>,
) -> Result<()> {
    let grid: K::Grid = meta.grid()?;
    complete::<K>(outputs, meta, out, figures, |path| {
        let mut w = create_csv::<K::Row>(path, None)?;
        merge_rows::<K::Row>(
            files,
            meta.points,
            K::GROUPED,
            |r| K::check_row(meta, &grid, r),
            |r| Ok(w.serialize(r)?),
        )?;
        w.flush()?;
        Ok(())
    })
}

/// `count` evenly spaced values from `start` to `end`, both included (`START:END:COUNT`, used
/// for initial-condition grids).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CountSweep {
    /// First value.
    pub start: f64,
    /// Last value (equal to `start` when `count` is 1).
    pub end: f64,
    /// Number of values, ≥ 1.
    pub count: u32,
}

/// Largest `COUNT` of a [`CountSweep`].
pub const MAX_COUNT: u32 = 4096;

impl CountSweep {
    /// Parses `START:END:COUNT` given to `flag`, values within `[min, max]`.
    ///
    /// # Errors
    /// Not three fields, non-numbers, NaN, values outside `[min, max]`, `START > END`,
    /// `COUNT` outside `1 ..= 4096`, `COUNT = 1` with `START ≠ END`, or `COUNT > 1` with
    /// `START = END`.
    pub fn parse(flag: &str, text: &str, min: f64, max: f64) -> Result<Self> {
        let parts: Vec<&str> = text.split(':').collect();
        if parts.len() != 3 {
            bail!(
                "{flag} {text}: expected START:END:COUNT (COUNT points, both ends included), e.g. -1:1:41"
            );
        }
        let num = |p: &str| -> Result<f64> {
            p.trim()
                .parse::<f64>()
                .with_context(|| format!("{flag} {text}: `{p}` is not a number"))
        };
        let (start, end) = (num(parts[0])?, num(parts[1])?);
        let count: u32 = parts[2].trim().parse().map_err(|_| {
            anyhow!(
                "{flag} {text}: COUNT `{}` must be a whole number in 1 ..= {MAX_COUNT}",
                parts[2]
            )
        })?;
        for (name, v) in [("START", start), ("END", end)] {
            if !v.is_finite() || v < min || v > max {
                bail!("{flag} {text}: {name} = {v} is out of range: allowed {min} ..= {max}");
            }
        }
        if !(1..=MAX_COUNT).contains(&count) {
            bail!("{flag} {text}: COUNT = {count} is out of range: allowed 1 ..= {MAX_COUNT}");
        }
        if start > end {
            bail!("{flag} {text}: START must be ≤ END");
        }
        if count == 1 && start != end {
            bail!("{flag} {text}: with COUNT = 1, START must equal END");
        }
        if count > 1 && start == end {
            bail!(
                "{flag} {text}: START = END gives one value, COUNT times the same point: give \
                 COUNT = 1, or START < END"
            );
        }
        Ok(CountSweep { start, end, count })
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        self.count as usize
    }

    /// Never empty.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The `i`-th value (`start + (end − start)·i/(count − 1)`).
    pub fn value(&self, i: usize) -> f64 {
        if self.count <= 1 {
            self.start
        } else {
            self.start + (self.end - self.start) * i as f64 / f64::from(self.count - 1)
        }
    }

    /// Spacing between values (1 when there is a single value, for plotting a cell width).
    pub fn spacing(&self) -> f64 {
        if self.count <= 1 {
            1.0
        } else {
            (self.end - self.start) / f64::from(self.count - 1)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn count_sweeps() {
        let s = CountSweep::parse("--u0-mm", "-1:1:5", -20.0, 20.0).unwrap();
        assert_eq!(s.len(), 5);
        assert_eq!(s.value(0), -1.0);
        assert_eq!(s.value(4), 1.0);
        assert_eq!(s.value(2), 0.0);
        assert_eq!(
            CountSweep::parse("--u0-mm", "0.5:0.5:1", -20.0, 20.0)
                .unwrap()
                .value(0),
            0.5
        );
        for bad in [
            "-1:1:0", "-1:1", "1:-1:3", "-1:1:x", "NaN:1:3", "-30:1:3", "0:1:1", "0:1:2.5", "0:0:3",
        ] {
            assert!(
                CountSweep::parse("--u0-mm", bad, -20.0, 20.0).is_err(),
                "{bad}"
            );
        }
    }

    #[test]
    fn headers_are_the_row_fields_in_order() {
        use crate::shard::header;
        for (fields, expected) in [
            (
                header::<peterka::PeterkaRow>(),
                "index,gap_mm,gap_ratio,omega_ratio,freq_hz,regime,impacts,impact_force_mg,\
                 transient_periods,settled,lyapunov_per_period",
            ),
            (
                header::<basins::BasinRaw>(),
                "index,u0_mm,v0_mm_s,regime,impacts,impact_force_mg,settled,recurrence,points",
            ),
            (
                header::<basins::BasinRow>(),
                "index,u0_mm,v0_mm_s,impacting,regime,attractor,attractor_u_mm,attractor_v_mm_s,\
                 impacts,impact_force_mg,settled,recurrence",
            ),
            (
                header::<bifurcation::BifRow>(),
                "index,branch,omega_ratio,freq_hz,regime,kind,k,u_mm,du_mm_s,impact_force_mg,\
                 lyapunov_per_period",
            ),
        ] {
            assert_eq!(fields.join(","), expected);
        }
    }

    #[test]
    fn chunks_keep_index_order() {
        let mut seen = Vec::new();
        run_chunked(
            (0..10_000).step_by(3),
            3334,
            "test",
            per_point(|i| Ok(i * 2)),
            |i, r| {
                assert_eq!(r, i * 2);
                seen.push(i);
                Ok(())
            },
        )
        .unwrap();
        assert_eq!(seen, (0..10_000).step_by(3).collect::<Vec<_>>());
    }
}

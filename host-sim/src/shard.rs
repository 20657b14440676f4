//! Splitting a grid over cluster jobs and joining the pieces.
//!
//! A shard `I/N` (0-based `I < N`) computes the grid points whose index `i` satisfies
//! `i % N == I` (striped, so that costly regions of a map are spread over every shard).
//! Without `--shard`, `SLURM_ARRAY_TASK_ID` / `SLURM_ARRAY_TASK_COUNT` are used when both are set.
//!
//! A shard file is a CSV whose first line is `# host-sim-shard {JSON}`: the [`Meta`] data (kind,
//! tool version, rig parameters, numerical settings, precision, grid and shard), then the usual
//! header line and the rows in ascending point index. `merge` checks that every file carries the
//! same metadata apart from the shard, that each point index appears exactly once, and streams
//! the rows in index order through the same writer as a one-run command.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use clap::ValueEnum;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use shared::analysis::SimSettings;
use shared::model::RigParams;

use crate::config::Setup;
use crate::interrupt;
use crate::precision::Precision;

/// First characters of a shard file.
pub const MAGIC: &str = "# host-sim-shard ";

/// Environment variables read when `--shard` is not given.
pub const SLURM_VARS: (&str, &str) = ("SLURM_ARRAY_TASK_ID", "SLURM_ARRAY_TASK_COUNT");

/// One slice of a grid: the points whose index `i` has `i % count == index`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// 0-based shard index `I < count`.
    pub index: u32,
    /// Number of shards `N ≥ 1`.
    pub count: u32,
}

/// The `--shard I/N` option of the grid commands.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ShardArg {
    /// Compute only shard I of N (0-based; the points with index % N == I; bifurcation: from
    /// rest only); default from SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT. A shard writes only
    /// its CSV: join the shards with `merge`.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
}

impl ShardArg {
    /// The shard asked for, from the option or the SLURM array variables ([`Shard::resolve`]).
    ///
    /// # Errors
    /// As [`Shard::resolve`].
    pub fn resolve(&self) -> Result<Option<Shard>> {
        Shard::resolve(self.shard.as_deref())
    }
}

impl Shard {
    /// Parses `I/N` given to `what`.
    ///
    /// # Errors
    /// Not `I/N` with whole numbers, `N = 0`, or `I ≥ N`.
    pub fn parse(what: &str, text: &str) -> Result<Self> {
        let (i, n) = text.split_once('/').ok_or_else(|| {
            anyhow!("{what} {text}: expected I/N (0-based shard index I < shard count N), e.g. 0/8")
        })?;
        Self::from_parts(what, i, n)
    }

    fn from_parts(what: &str, i: &str, n: &str) -> Result<Self> {
        let num = |s: &str, name: &str| -> Result<u32> {
            s.trim().parse::<u32>().map_err(|_| {
                anyhow!("{what} {i}/{n}: {name} `{s}` is not a whole number (expected I/N, 0-based I < N)")
            })
        };
        let (index, count) = (num(i, "shard index I")?, num(n, "shard count N")?);
        if count == 0 {
            bail!("{what} {i}/{n}: shard count N = 0 is out of range: allowed N ≥ 1");
        }
        if index >= count {
            bail!(
                "{what} {i}/{n}: shard index I = {index} is out of range: allowed 0 ..= {} (I is 0-based, I < N)",
                count - 1
            );
        }
        Ok(Shard { index, count })
    }

    /// `--shard` if given, else the SLURM array variables if both are set, else no sharding.
    ///
    /// # Errors
    /// A malformed value, or only one of the two SLURM variables set.
    pub fn resolve(flag: Option<&str>) -> Result<Option<Shard>> {
        if let Some(s) = flag {
            return Self::parse("--shard", s).map(Some);
        }
        match (std::env::var(SLURM_VARS.0), std::env::var(SLURM_VARS.1)) {
            (Ok(i), Ok(n)) => {
                // Task ids are the shard indices only in an array 0-(N-1) with step 1: any
                // other fails in every task, not only in those whose id is out of range.
                let var = |name: &str| std::env::var(name).ok().map(|v| v.trim().to_string());
                let (min, step) = (var("SLURM_ARRAY_TASK_MIN"), var("SLURM_ARRAY_TASK_STEP"));
                if min.as_deref().is_some_and(|m| m != "0")
                    || step.as_deref().is_some_and(|s| s != "1")
                {
                    bail!(
                        "the SLURM array runs from {} in steps of {}: its task ids are not the \
                         shard indices; submit it as --array=0-{} (or pass --shard I/N)",
                        min.as_deref().unwrap_or("0"),
                        step.as_deref().unwrap_or("1"),
                        n.trim()
                            .parse::<u32>()
                            .map_or_else(|_| "(N-1)".into(), |n| n.saturating_sub(1).to_string())
                    );
                }
                Self::from_parts(
                    &format!("{}/{} (no --shard given)", SLURM_VARS.0, SLURM_VARS.1),
                    &i,
                    &n,
                )
                .map(Some)
            }
            (Err(_), Err(_)) => Ok(None),
            _ => bail!(
                "only one of {} and {} is set: set both, or pass --shard I/N",
                SLURM_VARS.0,
                SLURM_VARS.1
            ),
        }
    }

    /// This shard's point indices of a grid of `total` points, ascending.
    pub fn indices(&self, total: usize) -> std::iter::StepBy<std::ops::Range<usize>> {
        (self.index as usize..total.max(self.index as usize)).step_by(self.count as usize)
    }

    /// How many points of a grid of `total` this shard holds.
    pub fn len(&self, total: usize) -> usize {
        let i = self.index as usize;
        if i >= total {
            0
        } else {
            (total - i - 1) / self.count as usize + 1
        }
    }

    /// Whether this shard holds no point of a grid of `total`.
    pub fn is_empty(&self, total: usize) -> bool {
        self.len(total) == 0
    }

    /// The whole grid as one shard.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };
}

/// The kind of a gridded output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// `peterka`: regime over gap × frequency.
    Peterka,
    /// `basins`: attractor over initial conditions.
    Basins,
    /// `bifurcation`: strobe points and impact forces over frequency (from rest).
    Bifurcation,
    /// `fractions`: attractor of random initial conditions, over a parameter.
    Fractions,
}

impl std::fmt::Display for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Kind::Peterka => "peterka",
            Kind::Basins => "basins",
            Kind::Bifurcation => "bifurcation",
            Kind::Fractions => "fractions",
        })
    }
}

impl Kind {
    /// `n` of the grid's points in words: Peterka points, initial conditions (basins, and
    /// fractions' points × samples) or frequencies (bifurcation).
    pub fn counted(self, n: u64) -> String {
        match self {
            Kind::Peterka => crate::output::count(n, "point"),
            Kind::Basins | Kind::Fractions => crate::output::count(n, "initial condition"),
            Kind::Bifurcation => crate::output::count_as(n, "frequency", "frequencies"),
        }
    }
}

/// Everything that must agree between shards of one grid (and the shard itself).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Meta {
    /// `host-sim <version>` that wrote the file.
    pub tool: String,
    /// Which command.
    pub kind: Kind,
    /// Rig preset name.
    pub rig: String,
    /// Float type.
    pub precision: Precision,
    /// Rig parameters after `--law` and `--config` (SI units).
    pub params: RigParams,
    /// Numerical settings after `--config`.
    pub settings: SimSettings,
    /// The command's grid (kind-specific JSON object).
    pub grid: serde_json::Value,
    /// Points in the whole grid.
    pub points: u64,
    /// The slice in this file (absent in a whole-grid run).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<Shard>,
}

impl Meta {
    /// Metadata of a run of `kind` over `grid` (serialised) with `points` points.
    ///
    /// # Errors
    /// The grid does not serialise (internal).
    pub fn new<G: Serialize>(kind: Kind, setup: &Setup, grid: &G, points: u64) -> Result<Self> {
        Ok(Meta {
            tool: format!("host-sim {}", env!("CARGO_PKG_VERSION")),
            kind,
            rig: setup.rig.to_string(),
            precision: setup.precision,
            params: setup.params,
            settings: setup.settings,
            grid: serde_json::to_value(grid).context("internal: serialising the grid")?,
            points,
            shard: None,
        })
    }

    /// The grid, typed.
    ///
    /// # Errors
    /// The grid does not match the kind's grid type.
    pub fn grid<G: DeserializeOwned>(&self) -> Result<G> {
        serde_json::from_value(self.grid.clone())
            .with_context(|| format!("{} metadata: malformed grid", self.kind))
    }

    /// One line describing the run (kind, shard, points).
    pub fn describe(&self) -> String {
        match self.shard {
            Some(s) => format!(
                "{} shard {}/{}: {} of {}",
                self.kind,
                s.index,
                s.count,
                s.len(usize::try_from(self.points).unwrap_or(usize::MAX)),
                self.kind.counted(self.points)
            ),
            None => format!("{}: {}", self.kind, self.kind.counted(self.points)),
        }
    }

    /// Writes the first line of a shard file.
    ///
    /// # Errors
    /// I/O failure.
    pub fn write_line(&self, w: &mut impl Write) -> Result<()> {
        writeln!(w, "{MAGIC}{}", serde_json::to_string(self)?)?;
        Ok(())
    }

    /// The top-level fields in which two metadata differ, ignoring the shard.
    pub fn differences(&self, other: &Meta) -> Vec<String> {
        let (Ok(serde_json::Value::Object(a)), Ok(serde_json::Value::Object(b))) =
            (serde_json::to_value(self), serde_json::to_value(other))
        else {
            return vec!["(unreadable)".into()];
        };
        let mut keys: Vec<&String> = a.keys().chain(b.keys()).filter(|k| *k != "shard").collect();
        keys.sort();
        keys.dedup();
        keys.into_iter()
            .filter(|k| a.get(*k) != b.get(*k))
            .map(|k| k.to_string())
            .collect()
    }
}

/// A row with a grid-point index.
pub trait Indexed {
    /// The grid-point index.
    fn index(&self) -> u64;
}

/// An open shard file positioned at its first row.
pub struct ShardFile {
    /// Its path.
    pub path: PathBuf,
    /// Its metadata.
    pub meta: Meta,
    reader: csv::Reader<BufReader<File>>,
}

impl ShardFile {
    /// Opens a shard file and reads its metadata line.
    ///
    /// # Errors
    /// Unreadable file, or a first line that is not `# host-sim-shard {JSON}` metadata.
    pub fn open(path: &Path) -> Result<Self> {
        let mut file = File::open(path).map_err(|e| {
            // EMFILE: every shard stays open while they are merged.
            let hint = if e.raw_os_error() == Some(24) {
                " (every shard is open while they merge, and merge raised its limit of open \
                 files as far as the hard limit allows: raise that above the number of shards, \
                 e.g. `ulimit -Hn 8192` where permitted, or ask for it on the cluster)"
            } else {
                ""
            };
            anyhow!("cannot read shard {}: {e}{hint}", path.display())
        })?;
        // A shard is complete only with its last line's end: one cut short (a task killed as it
        // wrote, a copy interrupted) would end in a truncated value that still reads.
        let len = file
            .metadata()
            .with_context(|| format!("cannot read shard {}", path.display()))?
            .len();
        if len > 0 {
            let mut last = [0u8; 1];
            file.seek(SeekFrom::End(-1))
                .and_then(|_| file.read_exact(&mut last))
                .and_then(|()| file.seek(SeekFrom::Start(0)).map(drop))
                .with_context(|| format!("cannot read shard {}", path.display()))?;
            if last[0] != b'\n' {
                bail!(
                    "{}: the last line has no line end: the file was cut short (a task killed \
                     while writing, an interrupted copy); run that shard again",
                    path.display()
                );
            }
        }
        let mut buf = BufReader::new(file);
        let mut first = String::new();
        buf.read_line(&mut first)
            .with_context(|| format!("cannot read shard {}", path.display()))?;
        let json = first.strip_prefix(MAGIC).ok_or_else(|| {
            anyhow!(
                "{}: not a host-sim shard file (line 1 must be `{MAGIC}{{…}}` metadata, as written by a command run with --shard I/N)",
                path.display()
            )
        })?;
        let meta: Meta = serde_json::from_str(json.trim_end())
            .with_context(|| format!("{}: malformed shard metadata on line 1", path.display()))?;
        Ok(ShardFile {
            path: path.to_path_buf(),
            meta,
            reader: csv::Reader::from_reader(buf),
        })
    }
}

/// Files a merge may hold open besides its shards (standard streams, the outputs, the
/// figures' fonts).
const SPARE_FILES: u64 = 64;

/// Raises this process's soft limit of open files towards `needed` (as far as the hard limit
/// allows; a limit it cannot read or raise stays, and opening the shards says so): a SLURM
/// array of 1,000 tasks makes 1,000 shards, which a merge holds open together, where the
/// usual soft limit is 1,024.
fn allow_open_files(needed: u64) {
    use nix::sys::resource::{Resource, getrlimit, setrlimit};
    if let Ok((soft, hard)) = getrlimit(Resource::RLIMIT_NOFILE)
        && soft < needed
    {
        let _ = setrlimit(Resource::RLIMIT_NOFILE, needed.min(hard), hard);
    }
}

/// Opens every shard, checks that they are of one kind (`kind` if given) with identical
/// metadata apart from the shard, and returns them with the shared metadata (shard removed).
///
/// # Errors
/// No files, unreadable or malformed files, or mismatched metadata (fields named).
pub fn open_all(paths: &[PathBuf], kind: Option<Kind>) -> Result<(Meta, Vec<ShardFile>)> {
    if paths.is_empty() {
        bail!("merge: give at least one shard CSV");
    }
    allow_open_files(paths.len() as u64 + SPARE_FILES);
    let files: Vec<ShardFile> = paths
        .iter()
        .map(|p| ShardFile::open(p))
        .collect::<Result<_>>()?;
    let first = &files[0];
    if let Some(k) = kind
        && first.meta.kind != k
    {
        bail!(
            "--kind {k}: {} holds a {} grid",
            first.path.display(),
            first.meta.kind
        );
    }
    for f in &files[1..] {
        let d = first.meta.differences(&f.meta);
        if !d.is_empty() {
            bail!(
                "shards do not belong to the same run: {} and {} differ in {}",
                first.path.display(),
                f.path.display(),
                d.join(", ")
            );
        }
    }
    let mut meta = first.meta.clone();
    meta.shard = None;
    Ok((meta, files))
}

struct Input<R> {
    path: PathBuf,
    rows: csv::DeserializeRecordsIntoIter<BufReader<File>, R>,
    next: Option<R>,
    line: u64,
}

impl<R: DeserializeOwned + Indexed> Input<R> {
    fn advance(&mut self) -> Result<()> {
        self.next = match self.rows.next() {
            None => None,
            Some(r) => {
                self.line += 1;
                Some(r.map_err(|e| {
                    let why = match e.kind() {
                        csv::ErrorKind::Deserialize { err, .. } => err.to_string(),
                        _ => e.to_string(),
                    };
                    anyhow!(
                        "{} line {}: malformed row: {why}",
                        self.path.display(),
                        self.line
                    )
                })?)
            }
        };
        Ok(())
    }
}

/// Streams the rows of `files` to `sink` in ascending point index, checking the CSV header
/// against `R`'s ([`header`]), that every index `0 .. total` appears in exactly one file, that each
/// file is in ascending index order, and each row with `check`. With `grouped`, one index may span several consecutive
/// rows of one file (bifurcation: the samples of one frequency).
///
/// # Errors
/// Header mismatch, malformed rows, a missing, repeated or out-of-grid index, Ctrl-C.
pub fn merge_rows<R: DeserializeOwned + Indexed>(
    files: Vec<ShardFile>,
    total: u64,
    grouped: bool,
    check: impl Fn(&R) -> Result<(), String>,
    mut sink: impl FnMut(R) -> Result<()>,
) -> Result<()> {
    interrupt::install();
    let header = header::<R>();
    let mut inputs: Vec<Input<R>> = Vec::with_capacity(files.len());
    for mut f in files {
        let h = f
            .reader
            .headers()
            .with_context(|| format!("{}: cannot read the CSV header (line 2)", f.path.display()))?
            .clone();
        if h.iter().ne(header.iter().copied()) {
            bail!(
                "{}: CSV header on line 2 is `{}`, expected `{}`",
                f.path.display(),
                h.iter().collect::<Vec<_>>().join(","),
                header.join(",")
            );
        }
        let mut input = Input {
            path: f.path,
            rows: f.reader.into_deserialize(),
            next: None,
            line: 2,
        };
        input.advance()?;
        inputs.push(input);
    }
    for e in 0..total {
        if e % 4096 == 0 {
            interrupt::check()?;
        }
        let mut owner: Option<usize> = None;
        for (k, inp) in inputs.iter().enumerate() {
            let Some(r) = &inp.next else { continue };
            let i = r.index();
            if i < e {
                bail!(
                    "{} line {}: point index {i} is repeated or out of order",
                    inp.path.display(),
                    inp.line
                );
            }
            if i == e {
                if let Some(o) = owner {
                    bail!(
                        "point index {e} appears twice: in {} and in {} (the same shard given twice?)",
                        inputs[o].path.display(),
                        inp.path.display()
                    );
                }
                owner = Some(k);
            }
        }
        let k = owner.ok_or_else(|| {
            anyhow!(
                "point index {e} is missing: no shard holds it where it belongs (the grid has \
                 indices 0 ..= {}; is a shard file missing or truncated, or are a file's rows out \
                 of order? the next rows are at indices {})",
                total - 1,
                inputs
                    .iter()
                    .filter_map(|i| i.next.as_ref().map(|r| format!(
                        "{} in {} line {}",
                        r.index(),
                        i.path.display(),
                        i.line
                    )))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })?;
        let inp = &mut inputs[k];
        loop {
            let r = inp.next.take().expect("owner has a row");
            check(&r).map_err(|why| anyhow!("{} line {}: {why}", inp.path.display(), inp.line))?;
            sink(r)?;
            inp.advance()?;
            match &inp.next {
                Some(r) if grouped && r.index() == e => {}
                Some(r) if r.index() <= e => bail!(
                    "{} line {}: point index {} is repeated or out of order",
                    inp.path.display(),
                    inp.line,
                    r.index()
                ),
                _ => break,
            }
        }
    }
    for inp in &inputs {
        if let Some(r) = &inp.next {
            bail!(
                "{} line {}: point index {} is outside the grid (0 ..= {})",
                inp.path.display(),
                inp.line,
                r.index(),
                total.saturating_sub(1)
            );
        }
    }
    Ok(())
}

/// The CSV header of rows of type `R`: its field names, in order (a header line is written
/// even when no row follows).
pub fn header<R: DeserializeOwned>() -> &'static [&'static str] {
    serde_aux::serde_introspection::serde_introspect::<R>()
}

/// Creates a CSV file of `R` rows at `path` (normally a reserved temporary file): the metadata
/// line if `meta` is given (a shard), then `R`'s [`header`]; rows are written with
/// `serialize`.
///
/// # Errors
/// I/O failure.
pub fn create_csv<R: DeserializeOwned>(
    path: &Path,
    meta: Option<&Meta>,
) -> Result<csv::Writer<std::io::BufWriter<File>>> {
    let file = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut buf = std::io::BufWriter::new(file);
    if let Some(m) = meta {
        m.write_line(&mut buf)?;
    }
    let mut w = csv::WriterBuilder::new()
        .has_headers(false)
        .from_writer(buf);
    w.write_record(header::<R>())?;
    Ok(w)
}

/// Opens a plain CSV of `R` rows written by [`create_csv`] without metadata and checks its
/// header.
///
/// # Errors
/// Unreadable file or another header.
pub fn open_csv<R: DeserializeOwned>(path: &Path) -> Result<csv::Reader<BufReader<File>>> {
    let file = File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut r = csv::Reader::from_reader(BufReader::new(file));
    let h = r.headers()?.clone();
    if h.iter().ne(header::<R>().iter().copied()) {
        bail!("{}: unexpected CSV header", path.display());
    }
    Ok(r)
}

/// Title prefix of a figure: rig, law and precision.
pub fn title_prefix(meta: &Meta) -> String {
    format!(
        "{} rig, {} law, {}",
        meta.rig,
        meta.params.contact.kind(),
        meta.precision.name()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_counts_its_points_in_its_words() {
        assert_eq!(Kind::Peterka.counted(1), "1 point");
        assert_eq!(Kind::Peterka.counted(15), "15 points");
        assert_eq!(Kind::Basins.counted(20), "20 initial conditions");
        assert_eq!(Kind::Fractions.counted(1), "1 initial condition");
        assert_eq!(Kind::Bifurcation.counted(51), "51 frequencies");
        assert_eq!(Kind::Bifurcation.counted(1), "1 frequency");
    }

    #[test]
    fn shards_parse_and_partition() {
        assert_eq!(
            Shard::parse("--shard", "2/3").unwrap(),
            Shard { index: 2, count: 3 }
        );
        for bad in ["3/3", "0/0", "x", "1", "-1/3", "a/b", "1/2/3"] {
            assert!(Shard::parse("--shard", bad).is_err(), "{bad}");
        }
        let e = Shard::parse("--shard", "3/3").unwrap_err().to_string();
        assert!(e.contains("0 ..= 2"), "{e}");
        let total = 20;
        let mut all: Vec<usize> = (0..3)
            .flat_map(|i| {
                Shard { index: i, count: 3 }
                    .indices(total)
                    .collect::<Vec<_>>()
            })
            .collect();
        all.sort_unstable();
        assert_eq!(all, (0..total).collect::<Vec<_>>());
        for i in 0..3 {
            let s = Shard { index: i, count: 3 };
            assert_eq!(s.len(total), s.indices(total).count());
        }
        assert_eq!(Shard { index: 5, count: 8 }.len(3), 0);
        assert_eq!(Shard { index: 5, count: 8 }.indices(3).count(), 0);
    }
}

//! `host-sim peterka`: the impact regime `z = p/q` over a gap × frequency grid (thesis
//! Fig. 3.24) and the `z = 1/1` region coloured by `F_i/mg` (Fig. 3.26), from rest at every
//! point (canonical protocol). Streams rows in chunks (flat memory), can run as a shard.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{ArgGroup, Args};
use serde::{Deserialize, Serialize};
use shared::analysis::Sweep;
use shared::analysis::response::OMEGA_RATIO_RANGE;
use shared::observe::Regime;

use crate::config::RigOpts;
use crate::config::{MAX_GAP_MM, Setup, parse_sweep};
use crate::grid::write_grid;
use crate::maps::{self, Cell, MapAxis, Raster};
use crate::output::Outputs;
use crate::runner::{OperatingPoint, evaluate_batch};
use crate::shard::{Indexed, Kind, Meta, Shard, open_csv, title_prefix};

/// Largest Peterka grid, points.
pub const MAX_POINTS: u64 = 100_000_000;

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
    /// CSV output, one row per grid point (gap outer, frequency inner): index, gap_mm,
    /// gap_ratio, omega_ratio, freq_hz, regime, impacts, impact_force_mg, transient_periods,
    /// settled. With a shard: line 1 is `# host-sim-shard {metadata}`.
    #[arg(long)]
    pub out: PathBuf,
    /// PNG: regime over Ω/ω (x) and gap/A0 (y), one colour per regime (Fig. 3.24).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// PNG: the z = 1/1 region coloured by F_i/mg, with a colour bar (Fig. 3.26).
    #[arg(long)]
    pub force_plot: Option<PathBuf>,
    /// Compute only shard I of N (0-based; points with index % N == I); default from
    /// SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT. Shards write only the CSV: join with `merge`.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
}

/// How a grid axis was given.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisUnit {
    /// Gap in mm.
    GapMm,
    /// Gap over the cart amplitude, gap/A0.
    GapRatio,
    /// Frequency in Hz.
    FreqHz,
    /// Frequency ratio Ω/ω.
    OmegaRatio,
}

/// One axis of the grid: a sweep and its unit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Axis {
    /// Unit of the sweep values.
    pub unit: AxisUnit,
    /// The sweep.
    pub sweep: Sweep,
}

/// The grid of a Peterka map (metadata `grid`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PeterkaGrid {
    /// Gap axis (rows, outer).
    pub gap: Axis,
    /// Frequency axis (columns, inner).
    pub freq: Axis,
}

impl PeterkaGrid {
    /// Number of points.
    pub fn points(&self) -> u64 {
        self.gap.sweep.len() as u64 * self.freq.sweep.len() as u64
    }

    /// `(gap index, frequency index)` of point `i`.
    pub fn split(&self, i: usize) -> (usize, usize) {
        let nf = self.freq.sweep.len();
        (i / nf, i % nf)
    }

    /// `(gap mm, gap/A0)` of gap index `ig`; `a0_mm` the cart amplitude in mm.
    pub fn gap(&self, ig: usize, a0_mm: f64) -> (f64, f64) {
        let v = self.gap.sweep.value(ig);
        match self.gap.unit {
            AxisUnit::GapRatio => (v * a0_mm, v),
            _ => (v, v / a0_mm),
        }
    }

    /// `(Ω/ω, Hz)` of frequency index `jf`; `fn_hz` the natural frequency.
    pub fn freq(&self, jf: usize, fn_hz: f64) -> (f64, f64) {
        let v = self.freq.sweep.value(jf);
        match self.freq.unit {
            AxisUnit::FreqHz => (v / fn_hz, v),
            _ => (v, v * fn_hz),
        }
    }
}

/// One CSV row of a Peterka map.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PeterkaRow {
    /// Grid-point index, `gap index × frequency count + frequency index`.
    pub index: u64,
    /// Gap, mm.
    pub gap_mm: f64,
    /// gap/A0.
    pub gap_ratio: f64,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Excitation frequency, Hz.
    pub freq_hz: f64,
    /// Regime `p/q`, `no impact` or `irregular`.
    pub regime: Regime,
    /// Impacts in the observation window.
    pub impacts: u32,
    /// Max impact force over the window, `F_i/mg`.
    pub impact_force_mg: f64,
    /// Transient periods before the window.
    pub transient_periods: u32,
    /// Whether a steady state was detected.
    pub settled: bool,
}

/// CSV header of [`PeterkaRow`].
pub const HEADER: [&str; 10] = [
    "index",
    "gap_mm",
    "gap_ratio",
    "omega_ratio",
    "freq_hz",
    "regime",
    "impacts",
    "impact_force_mg",
    "transient_periods",
    "settled",
];

impl Indexed for PeterkaRow {
    fn index(&self) -> u64 {
        self.index
    }
}

fn parse_axes(a: &PeterkaArgs, setup: &Setup) -> Result<PeterkaGrid> {
    let a0_mm = setup.params.amplitude_m * 1e3;
    let fn_hz = setup.params.natural_freq_hz();
    let gap = match (&a.gap_mm, &a.gap_ratio) {
        (Some(t), None) => Axis {
            unit: AxisUnit::GapMm,
            sweep: parse_sweep("--gap-mm", t, 0.0, MAX_GAP_MM)?,
        },
        (None, Some(t)) => Axis {
            unit: AxisUnit::GapRatio,
            sweep: parse_sweep("--gap-ratio", t, 0.0, MAX_GAP_MM / a0_mm)?,
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
            sweep: parse_sweep("--omega-ratio", t, OMEGA_RATIO_RANGE.0, OMEGA_RATIO_RANGE.1)?,
        },
        _ => bail!("give exactly one of --freq-hz and --omega-ratio"),
    };
    let grid = PeterkaGrid { gap, freq };
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
    let shard = Shard::resolve(a.shard.as_deref())?;
    if shard.is_some() && (a.plot.is_some() || a.force_plot.is_some()) {
        bail!(
            "--plot/--force-plot: a shard writes only its CSV; draw the figures with `host-sim merge`"
        );
    }
    let total = grid.points();
    let mut meta = Meta::new(Kind::Peterka, &setup, &grid, total)?;
    meta.shard = shard;
    let a0_mm = setup.params.amplitude_m * 1e3;
    let fn_hz = setup.params.natural_freq_hz();
    let mut outputs = Outputs::new();
    let out = outputs.reserve(&a.out)?;
    let at = |i: usize| {
        let (ig, jf) = grid.split(i);
        (grid.gap(ig, a0_mm), grid.freq(jf, fn_hz))
    };
    write_grid(&out, &meta, &HEADER, "peterka", |batch: &[usize]| {
        let points: Vec<OperatingPoint> = batch
            .iter()
            .map(|&i| {
                let ((gap_mm, _), (omega_ratio, _)) = at(i);
                OperatingPoint {
                    gap_m: gap_mm * 1e-3,
                    omega_ratio,
                }
            })
            .collect();
        batch
            .iter()
            .zip(evaluate_batch(&setup, &points))
            .map(|(&i, r)| {
                let r = r?;
                let ((gap_mm, gap_ratio), (omega_ratio, freq_hz)) = at(i);
                Ok([PeterkaRow {
                    index: i as u64,
                    gap_mm,
                    gap_ratio,
                    omega_ratio,
                    freq_hz,
                    regime: r.regime,
                    impacts: r.impacts,
                    impact_force_mg: r.impact_force_mg,
                    transient_periods: r.transient_periods,
                    settled: r.settled,
                }])
            })
            .collect()
    })?;
    if shard.is_none() {
        figures(
            &mut outputs,
            &meta,
            &out,
            a.plot.as_deref(),
            a.force_plot.as_deref(),
        )?;
    }
    outputs.commit()?;
    eprintln!("{} → {}", meta.describe(), a.out.display());
    Ok(())
}

/// Draws the figures of a complete Peterka CSV `csv` (one run or merged) into reserved files.
/// The same function serves `peterka` and `merge`, so their figures are identical.
///
/// # Errors
/// Unreadable CSV, drawing or file errors.
pub fn figures(
    outputs: &mut Outputs,
    meta: &Meta,
    csv: &Path,
    plot: Option<&Path>,
    force_plot: Option<&Path>,
) -> Result<()> {
    if plot.is_none() && force_plot.is_none() {
        return Ok(());
    }
    let grid: PeterkaGrid = meta.grid()?;
    let a0_mm = meta.params.amplitude_m * 1e3;
    let fn_hz = meta.params.natural_freq_hz();
    let (nf, ng) = (grid.freq.sweep.len(), grid.gap.sweep.len());
    let mut cells = Raster::new(nf, ng, Cell::Empty);
    let mut force: Option<(f64, f64)> = None;
    let mut rdr = open_csv(csv, &HEADER)?;
    for row in rdr.deserialize::<PeterkaRow>() {
        let row = row.with_context(|| format!("{}: malformed row", csv.display()))?;
        let (ig, jf) = grid.split(row.index as usize);
        cells.set(jf, ig, Cell::Regime(row.regime, row.impact_force_mg as f32));
        if row.regime == Regime::ONE_ONE {
            let f = row.impact_force_mg;
            force = Some(force.map_or((f, f), |(lo, hi)| (lo.min(f), hi.max(f))));
        }
    }
    let (x0, _) = grid.freq(0, fn_hz);
    let (x1, _) = grid.freq(1, fn_hz);
    let x = MapAxis {
        lo: x0,
        step: if nf > 1 { x1 - x0 } else { 0.02 },
        n: nf,
        label: format!("Ω/ω (excitation / natural frequency; f = Ω/ω × {fn_hz:.4} Hz)"),
    };
    let y = MapAxis {
        lo: grid.gap(0, a0_mm).1,
        step: if ng > 1 {
            grid.gap(1, a0_mm).1 - grid.gap(0, a0_mm).1
        } else {
            0.02
        },
        n: ng,
        label: format!("gap/A0 (A0 = {a0_mm:.3} mm)"),
    };
    if let Some(p) = plot {
        let tmp = outputs.reserve(p)?;
        let title = format!(
            "{} — impact regime z = p/q (Peterka map)",
            title_prefix(meta)
        );
        maps::regime_map(&tmp, &title, &x, &y, &cells)?;
    }
    if let Some(p) = force_plot {
        let tmp = outputs.reserve(p)?;
        let title = format!(
            "{} — max impact force F_i/mg in the z = 1/1 region",
            title_prefix(meta)
        );
        maps::force_map(&tmp, &title, &x, &y, &cells, force)?;
    }
    Ok(())
}

//! Peterka maps (thesis Figs. 3.24, 3.26): the impact regime `z = p/q` over a gap ×
//! frequency grid, from rest at every point (canonical protocol), and the `z = 1/1` region
//! coloured by `F_i/mg`.

use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use shared::analysis::Sweep;
use shared::observe::{PointResult, Regime};
use shared::orbit::{LabelSettings, MapPoint};

use super::{Finish, GridKind};
use crate::config::Setup;
use crate::orbits::{CurveOut, boundary_curves, curve_rows};
use crate::output::write_csv;
use crate::runner::{OperatingPoint, evaluate_keyed, evaluate_keyed_labelled};
use crate::shard::{Indexed, Kind, Meta, open_csv};

/// Largest Peterka grid, points.
pub const MAX_POINTS: u64 = 100_000_000;

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
    /// Whether each point's label is refined by the largest Lyapunov exponent (column
    /// `lyapunov_per_period`; `--lyapunov`).
    #[serde(default)]
    pub lyapunov: bool,
    /// Whether the curves that bound the `1/1` region are computed (`--boundaries`).
    #[serde(default)]
    pub boundaries: bool,
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
    /// Regime `p/q`, `no impact`, `irregular` or (with `--lyapunov`) `chaotic`.
    pub regime: Regime,
    /// Impacts in the observation window.
    pub impacts: u32,
    /// Max impact force over the window, `F_i/mg`.
    pub impact_force_mg: f64,
    /// Transient periods before the window.
    pub transient_periods: u32,
    /// Whether a steady state was detected.
    pub settled: bool,
    /// Largest Lyapunov exponent per excitation period (with `--lyapunov`; else empty).
    pub lyapunov_per_period: Option<f64>,
}

impl Indexed for PeterkaRow {
    fn index(&self) -> u64 {
        self.index
    }
}

/// The rows of the points `source` gives (indices of `grid`), evaluated on the calling thread
/// as its lanes free up ([`super::streamed`]): `emit(index, row)` as each is done.
pub fn rows(
    setup: &Setup,
    grid: &PeterkaGrid,
    source: &mut dyn Iterator<Item = usize>,
    emit: &mut dyn FnMut(usize, Result<[PeterkaRow; 1]>),
) {
    let a0_mm = setup.params.amplitude_m * 1e3;
    let fn_hz = setup.params.natural_freq_hz();
    let at = |i: usize| {
        let (ig, jf) = grid.split(i);
        (grid.gap(ig, a0_mm), grid.freq(jf, fn_hz))
    };
    let points = source.map(|i| {
        let ((gap_mm, _), (omega_ratio, _)) = at(i);
        let p = OperatingPoint {
            gap_m: gap_mm * 1e-3,
            omega_ratio,
        };
        (i, p)
    });
    let mut row = |i: usize, r: Result<(PointResult, Option<f64>)>| {
        let row = r.map(|(r, lyapunov)| {
            let ((gap_mm, gap_ratio), (omega_ratio, freq_hz)) = at(i);
            [PeterkaRow {
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
                lyapunov_per_period: lyapunov,
            }]
        });
        emit(i, row);
    };
    if grid.lyapunov {
        evaluate_keyed_labelled(setup, points, &LabelSettings::default(), &mut |i, r| {
            let r = r.map(|(p, l)| {
                (
                    PointResult {
                        regime: l.regime,
                        ..p
                    },
                    Some(l.exponent.per_period),
                )
            });
            row(i, r);
        });
    } else {
        evaluate_keyed(setup, points, &mut |i, r| row(i, r.map(|p| (p, None))));
    }
}

/// The Peterka map as a [`GridKind`]: its rows are the CSV (the figures are drawn from them).
pub struct Peterka;

impl GridKind for Peterka {
    const KIND: Kind = Kind::Peterka;
    type Grid = PeterkaGrid;
    type Row = PeterkaRow;

    /// The boundary curves of the `1/1` region (empty unless asked for).
    type Summary = Vec<CurveOut>;

    fn check_row(meta: &Meta, grid: &PeterkaGrid, row: &PeterkaRow) -> Result<(), String> {
        let i = usize::try_from(row.index).map_err(|_| "index beyond the grid".to_string())?;
        let (ig, jf) = grid.split(i);
        let (gap_mm, gap_ratio) = grid.gap(ig, meta.params.amplitude_m * 1e3);
        let (omega_ratio, freq_hz) = grid.freq(jf, meta.params.natural_freq_hz());
        super::same_coordinate("gap_mm", row.gap_mm, gap_mm)?;
        super::same_coordinate("gap_ratio", row.gap_ratio, gap_ratio)?;
        super::same_coordinate("omega_ratio", row.omega_ratio, omega_ratio)?;
        super::same_coordinate("freq_hz", row.freq_hz, freq_hz)?;
        super::finite_non_negative("impact_force_mg", row.impact_force_mg)?;
        match row.lyapunov_per_period {
            Some(l) if !l.is_finite() => Err(format!("lyapunov_per_period = {l}: not finite")),
            _ => Ok(()),
        }
    }

    fn finish(job: &mut Finish<'_>) -> Result<Vec<CurveOut>> {
        let grid = job.meta.grid::<PeterkaGrid>()?;
        if !grid.boundaries {
            return Ok(Vec::new());
        }
        let curves = boundaries(job.meta, &grid, job.rows)?;
        if let Some(p) = job.figures.boundaries {
            let tmp = job.outputs.reserve(p)?;
            write_csv(&tmp, curve_rows(&curves))?;
        }
        Ok(curves)
    }
}

/// Gap rows seeded for the boundary curves, at most.
const BOUNDARY_SEEDS: usize = 8;

/// The curves bounding the `1/1` region of the complete grid in `rows`: seeded at up to
/// `BOUNDARY_SEEDS` (8) gap rows evenly spread among those with `1/1` points (at each, its
/// strongest `1/1` point), then continued in the (`Ω/ω`, gap) plane over the grid's box
/// ([`crate::orbits::boundary_curves`]).
///
/// # Errors
/// Unreadable rows, Ctrl-C.
pub fn boundaries(meta: &Meta, grid: &PeterkaGrid, rows: &Path) -> Result<Vec<CurveOut>> {
    let a0_mm = meta.params.amplitude_m * 1e3;
    let fn_hz = meta.params.natural_freq_hz();
    let ng = grid.gap.sweep.len();
    // The strongest 1/1 point of each gap row.
    let mut best: Vec<Option<(f64, f64)>> = vec![None; ng];
    let mut force = vec![f64::NEG_INFINITY; ng];
    for row in open_csv::<PeterkaRow>(rows)?.deserialize::<PeterkaRow>() {
        let row = row.with_context(|| format!("{}: malformed row", rows.display()))?;
        let (ig, _) = grid.split(row.index as usize);
        if row.regime == Regime::ONE_ONE && row.impact_force_mg > force[ig] {
            force[ig] = row.impact_force_mg;
            best[ig] = Some((row.gap_mm * 1e-3, row.omega_ratio));
        }
    }
    let with: Vec<(f64, f64)> = best.into_iter().flatten().collect();
    let n = with.len().min(BOUNDARY_SEEDS);
    let seeds: Vec<(f64, f64)> = (0..n)
        .map(|k| {
            with[if n > 1 {
                k * (with.len() - 1) / (n - 1)
            } else {
                0
            }]
        })
        .collect();
    let (r0, _) = grid.freq(0, fn_hz);
    let (r1, _) = grid.freq(grid.freq.sweep.len() - 1, fn_hz);
    let (g0, _) = grid.gap(0, a0_mm);
    let (g1, _) = grid.gap(ng - 1, a0_mm);
    let base = MapPoint {
        params: meta.params,
        settings: meta.settings,
        gap_m: g0 * 1e-3,
        omega_ratio: r0,
    };
    crate::with_precision!(meta.precision, T => {
        boundary_curves::<T>(&base, &seeds, [r0, r1], [g0 * 1e-3, g1 * 1e-3])
    })
}

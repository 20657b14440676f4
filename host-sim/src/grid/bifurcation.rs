//! Bifurcation diagrams (thesis Figs. 3.27–3.35, 3.43–3.45): per excitation frequency, the
//! Poincaré `u` at every section instant of the observation window and the peak force of every
//! impact ending in the window. From rest at each frequency (a grid, shardable), or by
//! continuation: each frequency starts from the previous one's final state, sweeping up, down
//! or both, so that jumps and hysteresis show.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::{Context, Result};
use clap::ValueEnum;
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};
use shared::Real;
use shared::analysis::Sweep;
use shared::analysis::simulator_at;
use shared::integrate::{PhaseTable, Simulator};
use shared::observe::{PointResult, Regime, run_protocol};
use shared::orbit::{LabelSettings, MapPoint, label};

use super::{Finish, GridKind};
use crate::config::Setup;
use crate::interrupt;
use crate::output::scratch;
use crate::progress::progress;
use crate::runner::WindowSamples;
use crate::shard::{Indexed, Kind, create_csv};

/// How the frequencies are visited.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Continuation {
    /// Increasing Ω.
    Up,
    /// Decreasing Ω.
    Down,
    /// Up, then (an independent branch from rest at the top) down.
    Both,
}

/// The grid of a bifurcation run (metadata `grid`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BifGrid {
    /// Gap, mm.
    pub gap_mm: f64,
    /// `Ω/ω` sweep; the point index is the sweep index.
    pub omega_ratio: Sweep,
    /// Continuation, or `None` from rest.
    pub continuation: Option<Continuation>,
    /// Whether each frequency's label is refined by the largest Lyapunov exponent (column
    /// `lyapunov_per_period`).
    #[serde(default)]
    pub lyapunov: bool,
}

/// One CSV row: a Poincaré point or an impact of the observation window.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BifRow {
    /// Frequency index in the sweep.
    pub index: u64,
    /// `rest` (from rest), `up` or `down` (continuation).
    pub branch: String,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Excitation frequency, Hz.
    pub freq_hz: f64,
    /// Regime of the window at this frequency.
    pub regime: Regime,
    /// `strobe` (Poincaré point at the end of period `k`) or `impact` (ending in period `k`).
    pub kind: String,
    /// Period of the observation window, 0-based.
    pub k: u32,
    /// Poincaré `u`, mm (strobes).
    pub u_mm: Option<f64>,
    /// Poincaré `u̇`, mm/s (strobes).
    pub du_mm_s: Option<f64>,
    /// Peak impact force `F_i/mg` (impacts).
    pub impact_force_mg: Option<f64>,
    /// Largest Lyapunov exponent at this frequency, per excitation period (empty with
    /// `--no-lyapunov`).
    pub lyapunov_per_period: Option<f64>,
}

impl Indexed for BifRow {
    fn index(&self) -> u64 {
        self.index
    }
}

/// The label of the protocol's `result` at `gap_m`, `omega_ratio` that ended on `x_end`,
/// refined by the largest Lyapunov exponent if `lyapunov` (`shared::orbit::label`).
fn refine<T: Real>(
    setup: &Setup,
    gap_m: f64,
    omega_ratio: f64,
    result: &mut PointResult,
    x_end: Vector2<T>,
    lyapunov: bool,
) -> Result<Option<f64>> {
    if !lyapunov {
        return Ok(None);
    }
    let at = MapPoint {
        params: setup.params,
        settings: setup.settings,
        gap_m,
        omega_ratio,
    };
    let l = label::<T>(&at, result, x_end, &LabelSettings::default())?;
    result.regime = l.regime;
    Ok(Some(l.exponent.per_period))
}

fn rows(
    setup: &Setup,
    index: usize,
    omega_ratio: f64,
    branch: &str,
    r: &PointResult,
    s: &WindowSamples,
    lyapunov: Option<f64>,
) -> Vec<BifRow> {
    let freq_hz = setup.params.freq_hz_from_ratio(omega_ratio);
    let mg = setup.params.weight_n();
    let base = |kind: &str, k: u32| BifRow {
        index: index as u64,
        branch: branch.to_string(),
        omega_ratio,
        freq_hz,
        regime: r.regime,
        kind: kind.to_string(),
        k,
        u_mm: None,
        du_mm_s: None,
        impact_force_mg: None,
        lyapunov_per_period: lyapunov,
    };
    let mut out = Vec::with_capacity(s.strobes.len() + s.impacts.len());
    for (k, &(u, du)) in s.strobes.iter().enumerate() {
        out.push(BifRow {
            u_mm: Some(u * 1e3),
            du_mm_s: Some(du * 1e3),
            ..base("strobe", k as u32)
        });
    }
    for &(k, peak) in &s.impacts {
        out.push(BifRow {
            impact_force_mg: Some(peak / mg),
            ..base("impact", k)
        });
    }
    out
}

/// Runs the protocol on `sim` (at gap `gap_m`, m, and `Ω/ω = ratio`) and refines its label
/// (with `lyapunov`, by the largest Lyapunov exponent): the result, the window's samples and
/// the exponent per period.
fn observe<T: Real>(
    setup: &Setup,
    gap_m: f64,
    ratio: f64,
    sim: &mut Simulator<T>,
    lyapunov: bool,
) -> Result<(PointResult, WindowSamples, Option<f64>)> {
    let mut s = WindowSamples::default();
    let mut r = run_protocol(
        sim,
        &setup.settings.protocol,
        setup.params.weight_n(),
        &mut s,
    )?;
    let l = refine(setup, gap_m, ratio, &mut r, sim.state(), lyapunov)?;
    Ok((r, s, l))
}

/// The rows of frequency index `i` of `sweep` at gap `gap_m` (m), from rest.
///
/// # Errors
/// An invalid point.
pub fn from_rest(
    setup: &Setup,
    gap_m: f64,
    sweep: &Sweep,
    i: usize,
    lyapunov: bool,
) -> Result<Vec<BifRow>> {
    fn go<T: Real>(
        setup: &Setup,
        gap_m: f64,
        ratio: f64,
        lyapunov: bool,
    ) -> Result<(PointResult, WindowSamples, Option<f64>)> {
        let phases = PhaseTable::<T>::new(setup.settings.steps.steps_per_period)?;
        let mut sim = simulator_at(&setup.params, gap_m, ratio, &setup.settings, &phases)?;
        observe(setup, gap_m, ratio, &mut sim, lyapunov)
    }
    let ratio = sweep.value(i);
    let (r, s, l) = crate::with_precision!(setup.precision, T => {
        go::<T>(setup, gap_m, ratio, lyapunov)
    })
    .with_context(|| format!("Ω/ω {ratio}"))?;
    Ok(rows(setup, i, ratio, "rest", &r, &s, l))
}

/// Runs one continuation branch `(name, order)` (`order`: sweep indices), writing rows without
/// header.
fn branch<T: Real>(
    setup: &Setup,
    gap_m: f64,
    sweep: &Sweep,
    (name, order): (&str, &[usize]),
    lyapunov: bool,
    w: &mut csv::Writer<BufWriter<File>>,
    bar: &indicatif::ProgressBar,
) -> Result<()> {
    let mut prev = None;
    let phases = PhaseTable::new(setup.settings.steps.steps_per_period)?;
    for &i in order {
        interrupt::check()?;
        let ratio = sweep.value(i);
        let mut sim = Simulator::<T>::new(
            &setup.params,
            gap_m,
            ratio * setup.params.omega_n(),
            &setup.settings.bands,
            &setup.settings.steps,
            &phases,
        )
        .with_context(|| format!("Ω/ω {ratio}"))?;
        if let Some(x) = prev {
            sim.reset_state(x);
        }
        let (r, s, l) = observe(setup, gap_m, ratio, &mut sim, lyapunov)
            .with_context(|| format!("Ω/ω {ratio}"))?;
        prev = Some(sim.state());
        for row in rows(setup, i, ratio, name, &r, &s, l) {
            w.serialize(row)?;
        }
        bar.inc(1);
    }
    w.flush()?;
    Ok(())
}

/// Writes the rows of a continuation over `sweep` at gap `gap_m` (m) to the CSV `out` (with
/// header): each branch of `mode` from rest at its first frequency, then from the previous
/// frequency's final state; the two branches of `both` in parallel, `up` first in the file.
///
/// # Errors
/// An invalid point, I/O failure or Ctrl-C.
pub fn continuation(
    setup: &Setup,
    gap_m: f64,
    sweep: &Sweep,
    mode: Continuation,
    lyapunov: bool,
    out: &Path,
) -> Result<()> {
    interrupt::install();
    let n = sweep.len();
    let up: Vec<usize> = (0..n).collect();
    let down: Vec<usize> = (0..n).rev().collect();
    let branches: Vec<(&str, &[usize])> = match mode {
        Continuation::Up => vec![("up", &up)],
        Continuation::Down => vec![("down", &down)],
        Continuation::Both => vec![("up", &up), ("down", &down)],
    };
    let bar = progress(n * branches.len(), "bifurcation (continuation)");
    let run_one = |which: (&str, &[usize])| -> Result<tempfile::NamedTempFile> {
        let tmp = scratch(out, ".branch.csv")?;
        let mut w = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(BufWriter::new(tmp.reopen()?));
        crate::with_precision!(setup.precision, T => {
            branch::<T>(setup, gap_m, sweep, which, lyapunov, &mut w, &bar)
        })?;
        Ok(tmp)
    };
    let parts: Vec<tempfile::NamedTempFile> = if branches.len() == 2 {
        let (a, b) = rayon::join(|| run_one(branches[0]), || run_one(branches[1]));
        vec![a?, b?]
    } else {
        vec![run_one(branches[0])?]
    };
    bar.finish_and_clear();
    let mut w = create_csv::<BifRow>(out, None)?;
    w.flush()?;
    let mut file = w.into_inner().map_err(|e| anyhow::anyhow!("{e}"))?;
    for p in &parts {
        std::io::copy(&mut File::open(p.path())?, &mut file)?;
    }
    file.flush()?;
    Ok(())
}

/// The bifurcation diagram as a [`GridKind`]: one point index per frequency, several rows
/// each; its rows are the CSV.
pub struct Bifurcation;

impl GridKind for Bifurcation {
    const KIND: Kind = Kind::Bifurcation;
    const GROUPED: bool = true;
    type Grid = BifGrid;
    type Row = BifRow;

    type Summary = ();

    fn finish(_job: &mut Finish<'_>) -> Result<()> {
        Ok(())
    }
}

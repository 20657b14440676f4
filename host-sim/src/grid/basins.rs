//! Basins of attraction over a grid of initial conditions `(u0, u̇0)` at
//! phase 0 (thesis Figs. 3.36–3.38), coloured by attractor ([`crate::attractors`]). Each point
//! runs the canonical protocol from its initial condition, watched for recurrence on the
//! catalogue of attractors found so far (shared by the threads): a trajectory that stays within
//! `tol` of a known attractor's Poincaré points for `confirm` periods is assigned to it and
//! stops; otherwise its observation window is reduced to its recurrent set (a periodic orbit:
//! its regime and its `q` Poincaré points, the canonical one with the smallest `u` first, and
//! the orbit joins the catalogue; an irregular set whose points keep returning), or it never
//! recurred. Rows are then grouped into attractors: same regime and canonical points within
//! `--attractor-tol` in the scaled distance `max(|Δu|/A0, |Δu̇|/(A0 Ω))` of the first point of
//! the group (in index order); all recurrent irregular points form one group per regime, the
//! never-recurrent ones another. Groups get letters `A, B, …` sorted by regime (no impact,
//! p/q ascending, irregular) then `u`, then `u̇`; the group without an attractor (never recurred, or
//! conservative: no impact on an undamped suspension) comes last, `-`.
//!
//! A shard stores the ungrouped rows (with the attractor's `points`); grouping
//! needs the whole grid and happens in [`GridKind::finish`], for a one-run command and `merge`
//! alike. The catalogue only saves time: a trajectory assigned early reaches the attractor it
//! would have settled on (to the `tol`/`confirm` criterion).

use std::collections::VecDeque;
use std::io::Write as _;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use shared::Real;
use shared::analysis::{run_interleaved_native, simulator_at};
use shared::integrate::PhaseTable;
use shared::model::RigParams;
use shared::observe::{
    Observer, Protocol, ProtocolRun, RecurrenceSettings, RecurrenceWatch, Regime, StroboPoint,
};

use super::raster::Raster;
use super::{CountSweep, Finish, GridKind};
use crate::attractors::{
    Before, Catalogue, Ending, Known, Recurrence, Scales, converging, cycle, minimal_cycle,
    residual, returns, window_period,
};
use crate::config::Setup;
use crate::runner::in_order;
use crate::shard::{Indexed, Kind, create_csv, open_csv};
use crate::stats::wilson;

/// Largest `|u0|` accepted, mm.
pub const MAX_U0_MM: f64 = 20.0;
/// Largest `|u̇0|` accepted, mm/s.
pub const MAX_V0_MM_S: f64 = 1e4;

/// What the basins figure colours.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum ColorBy {
    /// Each attractor its colour (two orbits of one regime are two colours).
    #[default]
    Attractor,
    /// Each regime its colour.
    Regime,
    /// Whether each run impacts in its observed window (the thesis' Figs. 3.36–3.38), on an
    /// attractor or not.
    Impact,
}

/// The grid of a basins run (metadata `grid`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BasinsGrid {
    /// Gap, mm.
    pub gap_mm: f64,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Initial displacements, mm (x, fastest).
    pub u0_mm: CountSweep,
    /// Initial velocities, mm/s (y).
    pub v0_mm_s: CountSweep,
    /// Attractor tolerance (scaled).
    pub attractor_tol: f64,
    /// Recurrence on the catalogue of known attractors.
    pub recurrence: RecurrenceSettings,
    /// What the figure colours.
    pub color_by: ColorBy,
}

impl BasinsGrid {
    /// Number of points.
    pub fn points(&self) -> u64 {
        self.u0_mm.len() as u64 * self.v0_mm_s.len() as u64
    }
    /// `(u index, v index)` of point `i`.
    pub fn split(&self, i: usize) -> (usize, usize) {
        (i % self.u0_mm.len(), i / self.u0_mm.len())
    }
    /// The initial condition of point `i`, `(u0 mm, u̇0 mm/s)`.
    pub fn initial(&self, i: usize) -> (f64, f64) {
        let (iu, iv) = self.split(i);
        (self.u0_mm.value(iu), self.v0_mm_s.value(iv))
    }
}

/// One ungrouped row (what a shard stores).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BasinRaw {
    /// Point index (basins: `v index × u count + u index`).
    pub index: u64,
    /// Initial `u0`, mm.
    pub u0_mm: f64,
    /// Initial `u̇0`, mm/s.
    pub v0_mm_s: f64,
    /// Steady-state regime (of the attractor reached, for a trajectory assigned early).
    pub regime: Regime,
    /// Impacts in the observation window (the attractor's, if assigned early).
    pub impacts: u32,
    /// Max `F_i/mg` over the window (the attractor's, if assigned early).
    pub impact_force_mg: f64,
    /// Whether the protocol's steady-state test ended the transient.
    pub settled: bool,
    /// How the trajectory ended.
    pub recurrence: Recurrence,
    /// The attractor's Poincaré points (periodic attractors only; empty otherwise).
    pub points: Points,
}

/// Poincaré points `(u mm, u̇ mm/s)`, canonical first, written `u:u̇` separated by `;` (empty:
/// none); a malformed text is an error where it is read.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Points(pub Vec<(f64, f64)>);

impl Points {
    /// The canonical point, if any.
    pub fn canonical(&self) -> Option<(f64, f64)> {
        self.0.first().copied()
    }
}

impl Serialize for Points {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        let text: Vec<String> = self.0.iter().map(|(u, v)| format!("{u}:{v}")).collect();
        s.serialize_str(&text.join(";"))
    }
}

impl<'de> Deserialize<'de> for Points {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        text.split(';')
            .filter(|p| !p.trim().is_empty())
            .map(|p| {
                let (u, v) = p.split_once(':')?;
                Some((u.trim().parse().ok()?, v.trim().parse().ok()?))
            })
            .collect::<Option<Vec<_>>>()
            .map(Points)
            .ok_or_else(|| {
                serde::de::Error::custom(format!(
                    "points {text:?}: expected u:u̇ pairs (mm, mm/s) separated by ;"
                ))
            })
    }
}

impl BasinRaw {
    /// `Err` naming the field unless the values are finite (`F_i/mg` also ≥ 0).
    pub(crate) fn check_values(&self) -> Result<(), String> {
        super::finite_non_negative("impact_force_mg", self.impact_force_mg)?;
        if let Some((u, v)) = self
            .points
            .0
            .iter()
            .find(|(u, v)| !(u.is_finite() && v.is_finite()))
        {
            return Err(format!("points: {u}:{v} is not finite"));
        }
        if !(self.u0_mm.is_finite() && self.v0_mm_s.is_finite()) {
            return Err("u0_mm, v0_mm_s: not finite".into());
        }
        Ok(())
    }
}

impl Indexed for BasinRaw {
    fn index(&self) -> u64 {
        self.index
    }
}

/// One row of the final basins CSV.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BasinRow {
    /// Grid-point index.
    pub index: u64,
    /// Initial `u0`, mm.
    pub u0_mm: f64,
    /// Initial `u̇0`, mm/s.
    pub v0_mm_s: f64,
    /// Whether the steady state impacts.
    pub impacting: bool,
    /// Steady-state regime.
    pub regime: Regime,
    /// Attractor id (`A`, `B`, …; sorted by regime, then `u`, then `u̇`; `-`: no attractor).
    pub attractor: String,
    /// The attractor's canonical Poincaré `u`, mm (periodic attractors only).
    pub attractor_u_mm: Option<f64>,
    /// The attractor's canonical Poincaré `u̇`, mm/s.
    pub attractor_v_mm_s: Option<f64>,
    /// Impacts in the observation window.
    pub impacts: u32,
    /// Max `F_i/mg` over the window.
    pub impact_force_mg: f64,
    /// Whether a steady state was detected.
    pub settled: bool,
    /// How the trajectory ended (`attractor`, `none`, `neutral`).
    pub recurrence: Ending,
}

/// Watches a run: the catalogue's recurrence test on every Poincaré point, and the points of
/// the observation window (mm, mm/s).
struct Watch<'c> {
    keep: usize,
    window: VecDeque<(f64, f64)>,
    recurrence: RecurrenceWatch<Before<'c>>,
}

impl<T: Real> Observer<T> for Watch<'_> {
    const SAMPLES: bool = false;
    fn strobe(&mut self, p: &StroboPoint<T>, window: bool) {
        if window {
            if self.window.len() == self.keep {
                self.window.pop_front();
            }
            self.window
                .push_back((p.u.to_f64() * 1e3, p.du.to_f64() * 1e3));
        }
        Observer::<T>::strobe(&mut self.recurrence, p, window);
    }
    fn stop(&self) -> bool {
        Observer::<T>::stop(&self.recurrence)
    }
}

/// One operating point whose initial conditions are evaluated against a shared catalogue.
#[derive(Debug, Clone, Copy)]
pub struct Attractors<'a> {
    /// Rig, numerics, precision.
    pub setup: &'a Setup,
    /// Gap, mm.
    pub gap_mm: f64,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Recurrence settings (validated).
    pub recurrence: RecurrenceSettings,
    /// The catalogue shared by the run's threads.
    pub catalogue: &'a Catalogue,
}

impl Attractors<'_> {
    /// The scales of the scaled Poincaré distance at this point.
    pub fn scales(params: &RigParams, omega_ratio: f64) -> Scales {
        let a0_mm = params.amplitude_m * 1e3;
        Scales {
            u_mm: a0_mm,
            v_mm_s: a0_mm * omega_ratio * params.omega_n(),
        }
    }

    /// The rows of the initial conditions `ics` (`(index, u0 mm, u̇0 mm/s)`) on the calling
    /// thread, [`shared::analysis::lanes_per_core`] interleaved, in the setup's precision.
    pub fn rows(&self, ics: &[(u64, f64, f64)]) -> Vec<Result<BasinRaw>> {
        crate::with_precision!(self.setup.precision, T => self.points::<T>(ics))
    }

    fn points<T: Real>(&self, ics: &[(u64, f64, f64)]) -> Vec<Result<BasinRaw>> {
        let setup = self.setup;
        let phases = match PhaseTable::new(setup.settings.steps.steps_per_period) {
            Ok(p) => p,
            Err(e) => return ics.iter().map(|_| Err(e.into())).collect(),
        };
        let protocol = &setup.settings.protocol;
        let scales = Self::scales(&setup.params, self.omega_ratio);
        let grid_tol = self.catalogue.attractor_tol();
        // Without damping a non-impacting motion is conservative and attracts nothing.
        let conservative = setup.params.free_flight_conservative();
        in_order(ics.len(), |emit| {
            run_interleaved_native::<T, Watch<'_>, _, _, _>(
                ics.iter().copied(),
                |(index, u0_mm, v0_mm_s)| {
                    let mut sim = simulator_at::<T>(
                        &setup.params,
                        self.gap_mm * 1e-3,
                        self.omega_ratio,
                        &setup.settings,
                        &phases,
                    )?;
                    sim.reset_relative(u0_mm * 1e-3, v0_mm_s * 1e-3)?;
                    let run = ProtocolRun::new(&sim, protocol, setup.params.weight_n())?;
                    let obs = Watch {
                        keep: protocol.observe_periods as usize,
                        window: VecDeque::new(),
                        recurrence: RecurrenceWatch::new(
                            self.catalogue.before(index),
                            self.recurrence,
                        ),
                    };
                    Ok((sim, run, obs))
                },
                |k, r| {
                    let (index, u0_mm, v0_mm_s) = ics[k];
                    let row = r
                        .map(|(r, obs, _)| {
                            let mut row = BasinRaw {
                                index,
                                u0_mm,
                                v0_mm_s,
                                regime: r.regime,
                                impacts: r.impacts,
                                impact_force_mg: r.impact_force_mg,
                                settled: r.settled,
                                recurrence: Recurrence::None,
                                points: Points::default(),
                            };
                            let known = match obs.recurrence.assigned() {
                                Some(id) => self.catalogue.get(id),
                                None => None,
                            };
                            let set = known.or_else(|| {
                                if conservative && !r.regime.impacts() {
                                    row.recurrence = Recurrence::Neutral;
                                    return None;
                                }
                                let q = match r.regime {
                                    Regime::Periodic { q, .. } => Some(usize::from(q)),
                                    Regime::NoImpact => window_period(
                                        &obs.window,
                                        protocol.max_q as usize,
                                        protocol.classify_tol,
                                        scales,
                                    ),
                                    Regime::Irregular | Regime::Chaotic => None,
                                }?;
                                let mut points = cycle(&obs.window, q)?;
                                if r.regime == Regime::NoImpact {
                                    points = minimal_cycle(points, grid_tol, scales);
                                }
                                let set = Known {
                                    regime: r.regime,
                                    points,
                                    impact_force_mg: r.impact_force_mg,
                                    impacts: r.impacts,
                                };
                                if residual(&obs.window, q, scales) > 0.5 * grid_tol {
                                    // Still far from its limit: not a new attractor, but its
                                    // points may join one found by a lower index.
                                    row.recurrence = Recurrence::Unsettled;
                                } else {
                                    self.catalogue.register(set.clone(), index);
                                    row.recurrence = Recurrence::Found;
                                }
                                Some(set)
                            });
                            match set {
                                Some(set) => {
                                    if obs.recurrence.assigned().is_some() {
                                        row.recurrence = Recurrence::Known;
                                        row.settled = true;
                                        row.regime = set.regime;
                                        row.impacts = set.impacts;
                                        row.impact_force_mg = set.impact_force_mg;
                                    }
                                    row.points = Points(set.points);
                                }
                                None if r.regime.impacts()
                                    && row.recurrence == Recurrence::None
                                    && !converging(
                                        &obs.window,
                                        protocol.max_q as usize,
                                        scales,
                                    )
                                    && returns(&obs.window, scales) =>
                                {
                                    row.recurrence = Recurrence::Found;
                                }
                                None => {}
                            }
                            row
                        })
                        .map_err(|e| {
                            anyhow::anyhow!(
                                "initial condition u0 {u0_mm} mm, u̇0 {v0_mm_s} mm/s: {e}"
                            )
                        });
                    emit(k, row);
                },
            );
        })
    }
}

/// The ungrouped rows of the grid points `batch` on the calling thread (see [`Attractors::rows`]).
pub fn rows(
    setup: &Setup,
    grid: &BasinsGrid,
    catalogue: &Catalogue,
    batch: &[usize],
) -> Vec<Result<[BasinRaw; 1]>> {
    let ics: Vec<(u64, f64, f64)> = batch
        .iter()
        .map(|&i| {
            let (u, v) = grid.initial(i);
            (i as u64, u, v)
        })
        .collect();
    Attractors {
        setup,
        gap_mm: grid.gap_mm,
        omega_ratio: grid.omega_ratio,
        recurrence: grid.recurrence,
        catalogue,
    }
    .rows(&ics)
    .into_iter()
    .map(|r| r.map(|r| [r]))
    .collect()
}

/// The group key of a row: whether it recurred, its regime, its canonical point.
fn key(r: &BasinRaw) -> (bool, Regime, Option<(f64, f64)>) {
    let recurrent = r.recurrence.attracted();
    let point = match r.regime {
        _ if !recurrent => None,
        Regime::Periodic { .. } | Regime::NoImpact => r.points.canonical(),
        _ => None,
    };
    (
        recurrent,
        if recurrent {
            r.regime
        } else {
            Regime::NoImpact
        },
        point,
    )
}

/// A group of rows: the attractor's values are its first row's (in index order, the
/// trajectory that found it: [`Catalogue`]); an irregular set's force is the peak over its rows.
#[derive(Debug, Clone)]
struct Group {
    recurrent: bool,
    regime: Regime,
    point: Option<(f64, f64)>,
    points: Vec<(f64, f64)>,
    force_mg: f64,
    impacts: u32,
    settled: bool,
    cells: u64,
}

/// Greedy grouping in index order (deterministic): a row joins the first group (in creation
/// order) of its regime whose first point lies within the tolerance.
#[derive(Debug, Clone)]
pub struct Grouping {
    scales: Scales,
    tol: f64,
    groups: Vec<Group>,
}

impl Grouping {
    /// An empty grouping with the scaled tolerance `tol` in `scales`.
    pub fn new(scales: Scales, tol: f64) -> Self {
        Grouping {
            scales,
            tol,
            groups: Vec::new(),
        }
    }

    fn find(&self, r: &BasinRaw) -> Option<usize> {
        let group_of = |(recurrent, regime, point): (bool, Regime, Option<(f64, f64)>)| {
            self.groups.iter().position(|g| {
                g.recurrent == recurrent
                    && g.regime == regime
                    && match (g.point, point) {
                        (Some(a), Some(b)) => self.scales.distance(a, b) <= self.tol,
                        (None, None) => true,
                        _ => false,
                    }
            })
        };
        // An unsettled row joins the periodic attractor its point lies on, if one is grouped.
        if r.recurrence == Recurrence::Unsettled
            && let Some(p) = r.points.canonical()
            && let Some(k) = group_of((true, r.regime, Some(p)))
        {
            return Some(k);
        }
        group_of(key(r))
    }

    /// Adds one row.
    pub fn add(&mut self, r: &BasinRaw) {
        match self.find(r) {
            Some(k) => {
                let g = &mut self.groups[k];
                g.cells += 1;
                if g.recurrent && g.point.is_none() {
                    g.force_mg = g.force_mg.max(r.impact_force_mg);
                }
            }
            None => {
                let (recurrent, regime, point) = key(r);
                self.groups.push(Group {
                    recurrent,
                    regime,
                    point,
                    points: if point.is_some() {
                        r.points.0.clone()
                    } else {
                        Vec::new()
                    },
                    force_mg: if recurrent { r.impact_force_mg } else { 0.0 },
                    impacts: r.impacts,
                    settled: r.settled,
                    cells: 1,
                })
            }
        }
    }

    /// The attractors, sorted (recurrent first; regime; canonical `u`, `u̇`), and for each
    /// group (in creation order) its sorted id.
    pub fn attractors(&self) -> (Vec<Attractor>, Vec<u32>) {
        let mut order: Vec<usize> = (0..self.groups.len()).collect();
        order.sort_by(|&a, &b| {
            let (ga, gb) = (&self.groups[a], &self.groups[b]);
            let pa = ga.point.unwrap_or((0.0, 0.0));
            let pb = gb.point.unwrap_or((0.0, 0.0));
            gb.recurrent
                .cmp(&ga.recurrent)
                .then(ga.regime.cmp(&gb.regime))
                .then(pa.0.total_cmp(&pb.0))
                .then(pa.1.total_cmp(&pb.1))
        });
        let mut id_of = vec![0u32; order.len()];
        for (id, &k) in order.iter().enumerate() {
            id_of[k] = id as u32;
        }
        let total: u64 = self.groups.iter().map(|g| g.cells).sum();
        let list = order
            .iter()
            .enumerate()
            .map(|(id, &k)| {
                let g = &self.groups[k];
                let (lo, hi) = wilson(g.cells, total);
                Attractor {
                    id: if g.recurrent { label(id) } else { "-".into() },
                    label: if g.recurrent {
                        format!("{} {}", g.regime, label(id))
                    } else {
                        "no attractor".into()
                    },
                    recurrent: g.recurrent,
                    regime: g.regime,
                    point: g.point,
                    points: g.points.clone(),
                    impact_force_mg: g.force_mg,
                    cells: g.cells,
                    fraction: g.cells as f64 / total.max(1) as f64,
                    ci95: (lo, hi),
                }
            })
            .collect();
        (list, id_of)
    }

    /// The sorted id of a row's group (after [`Grouping::attractors`]'s `ids`).
    pub fn id(&self, r: &BasinRaw, ids: &[u32]) -> Option<u32> {
        self.find(r).map(|k| ids[k])
    }

    /// How a row ended, as the final CSV says it: on an attractor when its group is one (an
    /// [`Recurrence::Unsettled`] row that joined an attractor found by a lower index too).
    pub fn ending(&self, r: &BasinRaw) -> Ending {
        match self.find(r).map(|k| &self.groups[k]) {
            Some(g) if g.recurrent => Ending::Attractor,
            _ if r.recurrence == Recurrence::Neutral => Ending::Neutral,
            _ => Ending::None,
        }
    }

    /// What a row reports: for a row on a periodic attractor, the attractor's regime, impacts
    /// in the window, `F_i/mg` and settledness (its first row's: the same in any thread order
    /// and in merged shards, where a row may have stopped early on the catalogue); for the
    /// others (irregular sets, no attractor: they always run to their end), the row's own.
    fn reported(&self, r: &BasinRaw) -> (Regime, u32, f64, bool) {
        match self.find(r).map(|k| &self.groups[k]) {
            Some(g) if g.recurrent && g.point.is_some() => {
                (g.regime, g.impacts, g.force_mg, g.settled)
            }
            _ => (r.regime, r.impacts, r.impact_force_mg, r.settled),
        }
    }
}

/// What the initial conditions without an attractor mean, with their count (`cells` of
/// `total`) and the limit they ran to.
pub fn no_attractor_note(cells: u64, total: u64, protocol: &Protocol) -> String {
    format!(
        "  no attractor: {cells} initial conditions of {total} either never recurred within {} \
         transient + {} window periods (raise --max-periods, and lower --steady-tol, if the \
         damping is light, or near a fold or period doubling where the approach is slow) or move \
         without impacts on an undamped suspension (conservative: no attractor to reach)",
        protocol.max_transient_periods, protocol.observe_periods
    )
}

/// Letters of attractor `k`: A … Z, AA, AB, …
pub fn label(mut k: usize) -> String {
    let mut s = Vec::new();
    loop {
        s.push(b'A' + (k % 26) as u8);
        if k < 26 {
            break;
        }
        k = k / 26 - 1;
    }
    s.reverse();
    String::from_utf8(s).unwrap_or_default()
}

/// An attractor of a set of initial conditions: the steady states its cells reach, grouped.
#[derive(Debug, Clone, PartialEq)]
pub struct Attractor {
    /// Id: letters (`A`), or `-` for the trajectories that reached none.
    pub id: String,
    /// Label: regime and letter (`1/1 A`), or `no attractor`.
    pub label: String,
    /// Whether it is an attractor (not the group without one).
    pub recurrent: bool,
    /// Regime.
    pub regime: Regime,
    /// Canonical Poincaré point `(u mm, u̇ mm/s)`, if periodic.
    pub point: Option<(f64, f64)>,
    /// All its Poincaré points, canonical first (periodic only).
    pub points: Vec<(f64, f64)>,
    /// Peak `F_i/mg` on it.
    pub impact_force_mg: f64,
    /// Initial conditions in its basin.
    pub cells: u64,
    /// Its basin fraction, `cells / total`.
    pub fraction: f64,
    /// Wilson 95 % interval of the fraction (meaningful for random initial conditions).
    pub ci95: (f64, f64),
}

impl Attractor {
    /// The regime as the CSVs write it: `-` for the group without an attractor.
    pub fn regime_text(&self) -> String {
        if self.recurrent {
            self.regime.to_string()
        } else {
            "-".into()
        }
    }
}

/// One row of an attractor catalogue CSV (one per Poincaré point; one with empty point fields
/// for an attractor without points).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CatalogueRow {
    /// Attractor id.
    pub attractor: String,
    /// Regime.
    pub regime: String,
    /// Initial conditions in its basin.
    pub count: u64,
    /// Basin fraction.
    pub fraction: f64,
    /// Wilson 95 % interval, low end.
    pub ci95_lo: f64,
    /// Wilson 95 % interval, high end.
    pub ci95_hi: f64,
    /// Peak `F_i/mg`.
    pub impact_force_mg: f64,
    /// Poincaré point number (0 = canonical).
    pub k: Option<usize>,
    /// Poincaré `u`, mm.
    pub u_mm: Option<f64>,
    /// Poincaré `u̇`, mm/s.
    pub v_mm_s: Option<f64>,
}

/// Writes the attractor catalogue CSV.
///
/// # Errors
/// I/O failure.
pub fn write_catalogue(path: &std::path::Path, attractors: &[Attractor]) -> Result<()> {
    let mut w = create_csv::<CatalogueRow>(path, None)?;
    for a in attractors {
        let row = |k: Option<usize>, p: Option<(f64, f64)>| CatalogueRow {
            attractor: a.id.clone(),
            regime: a.regime_text(),
            count: a.cells,
            fraction: a.fraction,
            ci95_lo: a.ci95.0,
            ci95_hi: a.ci95.1,
            impact_force_mg: a.impact_force_mg,
            k,
            u_mm: p.map(|p| p.0),
            v_mm_s: p.map(|p| p.1),
        };
        if a.points.is_empty() {
            w.serialize(row(None, None))?;
        }
        for (k, p) in a.points.iter().enumerate() {
            w.serialize(row(Some(k), Some(*p)))?;
        }
    }
    w.flush()?;
    Ok(())
}

/// What the basins figure needs: each cell's attractor id (`u32::MAX` for none) and the
/// attractors, sorted (regime, then Poincaré point).
#[derive(Debug, Clone)]
pub struct BasinsSummary {
    /// Attractor id per cell.
    pub cells: Raster<u32>,
    /// The attractors, by id.
    pub attractors: Vec<Attractor>,
    /// Whether each cell's run impacts in its observed window (the `impacting` column).
    pub impacting: Raster<bool>,
    /// How many runs impact in their window (of all the attractors' `cells`; the raster may be
    /// down-sampled, so it is counted while the rows are read).
    pub impacting_count: u64,
}

/// The basins map as a [`GridKind`]: shards hold ungrouped rows; the CSV with the attractors
/// is written from the complete grid.
pub struct Basins;

impl GridKind for Basins {
    const KIND: Kind = Kind::Basins;
    const ROWS_ARE_OUTPUT: bool = false;
    type Grid = BasinsGrid;
    type Row = BasinRaw;

    /// Groups the ungrouped rows of a complete grid (`raw`) into attractors and writes the
    /// final CSV to `out` and the figure.
    type Summary = BasinsSummary;

    fn check_row(
        _meta: &crate::shard::Meta,
        grid: &BasinsGrid,
        row: &BasinRaw,
    ) -> Result<(), String> {
        let i = usize::try_from(row.index).map_err(|_| "index beyond the grid".to_string())?;
        let (u0_mm, v0_mm_s) = grid.initial(i);
        super::same_coordinate("u0_mm", row.u0_mm, u0_mm)?;
        super::same_coordinate("v0_mm_s", row.v0_mm_s, v0_mm_s)?;
        row.check_values()
    }

    fn finish(job: &mut Finish<'_>) -> Result<BasinsSummary> {
        let (meta, raw, out) = (job.meta, job.rows, job.out);
        let grid = meta.grid::<Self::Grid>()?;
        // Pass 1: groups.
        let mut grouping = Grouping::new(
            Attractors::scales(&meta.params, grid.omega_ratio),
            grid.attractor_tol,
        );
        for r in open_csv::<BasinRaw>(raw)?.deserialize::<BasinRaw>() {
            let r = r.with_context(|| format!("{}: malformed row", raw.display()))?;
            grouping.add(&r);
        }
        let (keys, ids) = grouping.attractors();
        // Pass 2: rows and raster.
        let (nu, nv) = (grid.u0_mm.len(), grid.v0_mm_s.len());
        let mut cells = Raster::new(nu, nv, u32::MAX);
        let mut impacting = Raster::new(nu, nv, false);
        let (mut impacting_count, mut total) = (0u64, 0u64);
        let mut w = create_csv::<BasinRow>(out, None)?;
        for r in open_csv::<BasinRaw>(raw)?.deserialize::<BasinRaw>() {
            let r = r.with_context(|| format!("{}: malformed row", raw.display()))?;
            let id = grouping
                .id(&r, &ids)
                .context("internal: row without a group")?;
            let a = &keys[id as usize];
            let (iu, iv) = grid.split(r.index as usize);
            cells.set(iu, iv, id);
            let (regime, impacts, impact_force_mg, settled) = grouping.reported(&r);
            impacting.set(iu, iv, regime.impacts());
            impacting_count += u64::from(regime.impacts());
            total += 1;
            w.serialize(BasinRow {
                index: r.index,
                u0_mm: r.u0_mm,
                v0_mm_s: r.v0_mm_s,
                impacting: regime.impacts(),
                regime,
                attractor: a.id.clone(),
                attractor_u_mm: a.point.map(|p| p.0),
                attractor_v_mm_s: a.point.map(|p| p.1),
                impacts,
                impact_force_mg,
                settled,
                recurrence: grouping.ending(&r),
            })?;
        }
        w.flush()?;
        if let Some(path) = job.figures.attractors {
            let tmp = job.outputs.reserve(path)?;
            write_catalogue(&tmp, &keys)?;
        }
        let mut summary = String::new();
        for a in &keys {
            summary.push_str(&format!(
                "  {:<16} {:>6.2} %  F_i/mg {:.2}\n",
                a.label,
                100.0 * a.fraction,
                a.impact_force_mg
            ));
        }
        summary.push_str(&format!(
            "  impacting in the last window: {:.2} % of starts (--color-by impact)\n",
            100.0 * impacting_count as f64 / total.max(1) as f64
        ));
        if let Some(never) = keys.iter().find(|a| !a.recurrent) {
            summary.push_str(&no_attractor_note(
                never.cells,
                keys.iter().map(|a| a.cells).sum(),
                &meta.settings.protocol,
            ));
            summary.push('\n');
        }
        let _ = std::io::stderr().write_all(summary.as_bytes());
        Ok(BasinsSummary {
            cells,
            attractors: keys,
            impacting,
            impacting_count,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels() {
        assert_eq!(label(0), "A");
        assert_eq!(label(25), "Z");
        assert_eq!(label(26), "AA");
        assert_eq!(label(27), "AB");
        assert_eq!(label(26 + 26 * 26), "AAA");
    }

    #[test]
    fn points_round_trip_through_text() {
        #[derive(Serialize, Deserialize)]
        struct Row {
            points: Points,
        }
        let text = |p: Points| {
            let mut w = csv::Writer::from_writer(Vec::new());
            w.serialize(Row { points: p }).unwrap();
            String::from_utf8(w.into_inner().unwrap()).unwrap()
        };
        let parse = |t: &str| {
            csv::Reader::from_reader(t.as_bytes())
                .deserialize::<Row>()
                .next()
                .unwrap()
                .map(|r| r.points)
        };
        let p = Points(vec![(-0.125, 3.5), (1e-3, -250.0)]);
        assert_eq!(parse(&text(p.clone())).unwrap(), p);
        assert_eq!(parse(&text(Points::default())).unwrap(), Points::default());
        // A malformed pair is an error naming the text, not a point silently dropped.
        let e = parse("points\n1:2;x:3\n").unwrap_err().to_string();
        assert!(e.contains("x:3") && e.contains("u:u̇ pairs"), "{e}");
    }
}

//! Basins of attraction over a grid of initial conditions `(u0, u̇0)` at
//! phase 0 (thesis Figs. 3.36–3.38). Each point runs the canonical protocol from its initial
//! condition; its steady state is reduced to a regime and a canonical Poincaré point (for a
//! periodic regime of period `q`, the point of the last `q` window strobes with the smallest
//! `u`, so one attractor gives one point whatever its phase). Points are then grouped into
//! attractors: same regime and canonical points within `--attractor-tol` in the scaled
//! distance `max(|Δu|/A0, |Δu̇|/(A0 Ω))` of the first point of the group (in index order);
//! all `no impact` points form one group, as do all `irregular` points. Groups get letters
//! `A, B, …` sorted by regime (no impact, p/q ascending, irregular) then `u`, then `u̇`.
//!
//! A shard stores the ungrouped rows (`strobe_u_mm`, `strobe_v_mm_s`); grouping needs the
//! whole grid and happens in [`GridKind::finish`], for a one-run command and `merge` alike.

use std::collections::VecDeque;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use shared::Real;
use shared::analysis::{DEFAULT_LANES, run_interleaved, simulator_at};
use shared::integrate::PhaseTable;
use shared::observe::{Observer, ProtocolRun, Regime, StroboPoint};

use super::raster::Raster;
use super::{CountSweep, Finish, GridKind};
use crate::config::Setup;
use crate::runner::in_order;
use crate::shard::{Indexed, Kind, Meta, create_csv, open_csv};

/// Largest `|u0|` accepted, mm.
pub const MAX_U0_MM: f64 = 20.0;
/// Largest `|u̇0|` accepted, mm/s.
pub const MAX_V0_MM_S: f64 = 1e4;

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
}

/// One ungrouped row (what a shard stores).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BasinRaw {
    /// Grid-point index, `v index × u count + u index`.
    pub index: u64,
    /// Initial `u0`, mm.
    pub u0_mm: f64,
    /// Initial `u̇0`, mm/s.
    pub v0_mm_s: f64,
    /// Steady-state regime.
    pub regime: Regime,
    /// Impacts in the observation window.
    pub impacts: u32,
    /// Max `F_i/mg` over the window.
    pub impact_force_mg: f64,
    /// Whether a steady state was detected.
    pub settled: bool,
    /// Canonical Poincaré `u` of the steady cycle, mm (periodic regimes only).
    pub strobe_u_mm: Option<f64>,
    /// Canonical Poincaré `u̇`, mm/s (periodic regimes only).
    pub strobe_v_mm_s: Option<f64>,
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
    /// Attractor id (`A`, `B`, …; sorted by regime, then `u`, then `u̇`).
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
}

/// Keeps the last `max_q` Poincaré points of the observation window.
#[derive(Debug, Default)]
struct LastStrobes {
    keep: usize,
    pts: VecDeque<(f64, f64)>,
}

impl<T: Real> Observer<T> for LastStrobes {
    const SAMPLES: bool = false;
    fn strobe(&mut self, p: &StroboPoint<T>, window: bool) {
        if window {
            if self.pts.len() == self.keep {
                self.pts.pop_front();
            }
            self.pts.push_back((p.u.to_f64(), p.du.to_f64()));
        }
    }
}

/// The canonical point of a cycle of period `q` (m, m/s): the smallest `u` (then `u̇`) of the
/// last `q` points.
fn canonical(pts: &VecDeque<(f64, f64)>, q: usize) -> Option<(f64, f64)> {
    let n = pts.len();
    if q == 0 || q > n {
        return None;
    }
    pts.range(n - q..)
        .copied()
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)))
}

/// The ungrouped rows of the points `batch` on the calling thread, [`DEFAULT_LANES`]
/// interleaved, in the setup's precision.
pub fn rows(setup: &Setup, grid: &BasinsGrid, batch: &[usize]) -> Vec<Result<[BasinRaw; 1]>> {
    crate::with_precision!(setup.precision, T => points::<T>(setup, grid, batch))
        .into_iter()
        .map(|r| r.map(|r| [r]))
        .collect()
}

/// The points of `batch` on the calling thread, [`DEFAULT_LANES`] interleaved.
fn points<T: Real>(setup: &Setup, grid: &BasinsGrid, batch: &[usize]) -> Vec<Result<BasinRaw>> {
    let initial = |i: usize| {
        let (iu, iv) = grid.split(i);
        (grid.u0_mm.value(iu), grid.v0_mm_s.value(iv))
    };
    let phases = match PhaseTable::new(setup.settings.steps.steps_per_period) {
        Ok(p) => p,
        Err(e) => return batch.iter().map(|_| Err(e.into())).collect(),
    };
    in_order(batch.len(), |emit| {
        run_interleaved::<T, LastStrobes, DEFAULT_LANES, _, _, _>(
            batch.iter().copied(),
            |i| {
                let (u0_mm, v0_mm_s) = initial(i);
                let mut sim = simulator_at::<T>(
                    &setup.params,
                    grid.gap_mm * 1e-3,
                    grid.omega_ratio,
                    &setup.settings,
                    &phases,
                )?;
                sim.reset_relative(u0_mm * 1e-3, v0_mm_s * 1e-3)?;
                let run =
                    ProtocolRun::new(&sim, &setup.settings.protocol, setup.params.weight_n())?;
                let obs = LastStrobes {
                    keep: setup.settings.protocol.max_q as usize,
                    pts: VecDeque::new(),
                };
                Ok((sim, run, obs))
            },
            |k, r| {
                let i = batch[k];
                let (u0_mm, v0_mm_s) = initial(i);
                let row = r
                    .map(|(r, obs, _)| {
                        let c = match r.regime {
                            Regime::Periodic { q, .. } => canonical(&obs.pts, usize::from(q)),
                            _ => None,
                        };
                        BasinRaw {
                            index: i as u64,
                            u0_mm,
                            v0_mm_s,
                            regime: r.regime,
                            impacts: r.impacts,
                            impact_force_mg: r.impact_force_mg,
                            settled: r.settled,
                            strobe_u_mm: c.map(|c| c.0 * 1e3),
                            strobe_v_mm_s: c.map(|c| c.1 * 1e3),
                        }
                    })
                    .map_err(|e| {
                        anyhow::anyhow!("initial condition u0 {u0_mm} mm, u̇0 {v0_mm_s} mm/s: {e}")
                    });
                emit(k, row);
            },
        );
    })
}

struct Group {
    regime: Regime,
    point: Option<(f64, f64)>,
    cells: u64,
}

/// Greedy grouping in index order (deterministic): a row joins the first group (in creation
/// order) of its regime whose first point lies within the tolerance.
struct Grouping {
    u_scale: f64,
    v_scale: f64,
    tol: f64,
    groups: Vec<Group>,
}

impl Grouping {
    fn new(meta: &Meta, grid: &BasinsGrid) -> Self {
        let a0_mm = meta.params.amplitude_m * 1e3;
        let omega = grid.omega_ratio * meta.params.omega_n();
        Grouping {
            u_scale: a0_mm,
            v_scale: a0_mm * omega,
            tol: grid.attractor_tol,
            groups: Vec::new(),
        }
    }

    fn find(&self, regime: Regime, point: Option<(f64, f64)>) -> Option<usize> {
        self.groups.iter().position(|g| {
            g.regime == regime
                && match (g.point, point) {
                    (Some(a), Some(b)) => {
                        ((a.0 - b.0).abs() / self.u_scale).max((a.1 - b.1).abs() / self.v_scale)
                            <= self.tol
                    }
                    (None, None) => true,
                    _ => false,
                }
        })
    }

    fn add(&mut self, regime: Regime, point: Option<(f64, f64)>) {
        match self.find(regime, point) {
            Some(k) => self.groups[k].cells += 1,
            None => self.groups.push(Group {
                regime,
                point,
                cells: 1,
            }),
        }
    }
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

fn raw_point(r: &BasinRaw) -> Option<(f64, f64)> {
    match r.regime {
        Regime::Periodic { .. } => r.strobe_u_mm.zip(r.strobe_v_mm_s),
        _ => None,
    }
}

/// An attractor of a basins grid: the steady states its cells reach, grouped.
#[derive(Debug, Clone)]
pub struct Attractor {
    /// Label: regime and letter (`1/1 A`).
    pub label: String,
    /// Regime.
    pub regime: Regime,
    /// Canonical Poincaré point `(u mm, u̇ mm/s)`, if periodic.
    pub point: Option<(f64, f64)>,
    /// Cells in its basin.
    pub cells: u64,
}

/// What the basins figure needs: each cell's attractor id (`u32::MAX` for none) and the
/// attractors, sorted (regime, then Poincaré point).
#[derive(Debug, Clone)]
pub struct BasinsSummary {
    /// Attractor id per cell.
    pub cells: Raster<u32>,
    /// The attractors, by id.
    pub attractors: Vec<Attractor>,
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

    fn finish(job: &mut Finish<'_>) -> Result<BasinsSummary> {
        let (meta, raw, out) = (job.meta, job.rows, job.out);
        let grid = meta.grid::<Self::Grid>()?;
        // Pass 1: groups.
        let mut grouping = Grouping::new(meta, &grid);
        for r in open_csv::<BasinRaw>(raw)?.deserialize::<BasinRaw>() {
            let r = r.with_context(|| format!("{}: malformed row", raw.display()))?;
            grouping.add(r.regime, raw_point(&r));
        }
        let mut order: Vec<usize> = (0..grouping.groups.len()).collect();
        order.sort_by(|&a, &b| {
            let (ga, gb) = (&grouping.groups[a], &grouping.groups[b]);
            let pa = ga.point.unwrap_or((0.0, 0.0));
            let pb = gb.point.unwrap_or((0.0, 0.0));
            ga.regime
                .cmp(&gb.regime)
                .then(pa.0.total_cmp(&pb.0))
                .then(pa.1.total_cmp(&pb.1))
        });
        let mut id_of = vec![0u32; order.len()];
        for (id, &k) in order.iter().enumerate() {
            id_of[k] = id as u32;
        }
        let keys: Vec<Attractor> = order
            .iter()
            .enumerate()
            .map(|(id, &k)| {
                let g = &grouping.groups[k];
                Attractor {
                    label: format!("{} {}", g.regime, label(id)),
                    regime: g.regime,
                    point: g.point,
                    cells: g.cells,
                }
            })
            .collect();
        // Pass 2: rows and raster.
        let (nu, nv) = (grid.u0_mm.len(), grid.v0_mm_s.len());
        let mut cells = Raster::new(nu, nv, u32::MAX);
        let mut w = create_csv::<BasinRow>(out, None)?;
        for r in open_csv::<BasinRaw>(raw)?.deserialize::<BasinRaw>() {
            let r = r.with_context(|| format!("{}: malformed row", raw.display()))?;
            let k = grouping
                .find(r.regime, raw_point(&r))
                .context("internal: row without a group")?;
            let id = id_of[k];
            let g = &grouping.groups[k];
            let (iu, iv) = grid.split(r.index as usize);
            cells.set(iu, iv, id);
            w.serialize(BasinRow {
                index: r.index,
                u0_mm: r.u0_mm,
                v0_mm_s: r.v0_mm_s,
                impacting: r.regime.impacts(),
                regime: r.regime,
                attractor: label(id as usize),
                attractor_u_mm: g.point.map(|p| p.0),
                attractor_v_mm_s: g.point.map(|p| p.1),
                impacts: r.impacts,
                impact_force_mg: r.impact_force_mg,
                settled: r.settled,
            })?;
        }
        w.flush()?;
        Ok(BasinsSummary {
            cells,
            attractors: keys,
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
    fn canonical_point_is_phase_independent() {
        let a: VecDeque<(f64, f64)> = [(3.0, 0.0), (1.0, 2.0), (2.0, 1.0)].into();
        let b: VecDeque<(f64, f64)> = [(2.0, 1.0), (3.0, 0.0), (1.0, 2.0)].into();
        assert_eq!(canonical(&a, 3), Some((1.0, 2.0)));
        assert_eq!(canonical(&a, 3), canonical(&b, 3));
        assert_eq!(canonical(&a, 1), Some((2.0, 1.0)));
        assert_eq!(canonical(&a, 4), None);
    }
}

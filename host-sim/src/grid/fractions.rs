//! Basin fractions: the share of random initial conditions in a box that end on each attractor
//! ([`crate::attractors`]), with Wilson 95 % intervals, at one operating point or continued
//! over `Ω/ω` or the gap. Initial conditions are uniform in the box, drawn from ChaCha8 with the
//! run's seed, stream = the operating point's number and the position given by the sample's
//! number, so a sample is the same whatever the shard or the round that computes it.
//!
//! Two modes: a fixed number of samples per operating point (a [`GridKind`]: shards and
//! `merge` like the other grids), or rounds of [`ROUND`] samples until every attractor's
//! interval is narrower than a stated width (at most the stated samples). At each operating
//! point the rows are grouped into attractors as in `basins`; attractors are then matched from
//! one operating point to the next (same regime, same number of Poincaré points, canonical
//! points within `match_tol` scaled of where the attractor's last two occurrences extrapolate,
//! nearest first; an attractor missing at up to
//! [`MATCH_BACK`] − 1 points in between, its basin too small for the sample, is still matched) and keep their letter along the parameter.

use anyhow::{Context, Result, bail};
use rand::SeedableRng;
use rand::distr::{Distribution, StandardUniform};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use shared::model::RigParams;
use shared::observe::{RecurrenceSettings, Regime};

use super::basins::{Attractor, Attractors, BasinRaw, Grouping, label, no_attractor_note};
use super::{Finish, GridKind, run_chunked};
use crate::attractors::Catalogue;
use crate::config::Setup;
use crate::shard::{Kind, Meta, create_csv, open_csv};
use crate::stats::{Z95, widest_interval};

/// Samples per round of the adaptive mode.
pub const ROUND: u32 = 256;
/// Operating points back over which an attractor missing from a sample can still be matched.
pub const MATCH_BACK: usize = 3;

/// Where an attractor id was last seen: the operating point's index, the attractor there, and
/// the operating point and canonical point of the occurrence before (for extrapolation).
type LastSeen = (usize, Attractor, Option<(usize, (f64, f64))>);
/// Largest number of samples per operating point.
pub const MAX_SAMPLES: u32 = 1_000_000;

/// Which parameter the operating points follow.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Parameter {
    /// `Ω/ω`.
    OmegaRatio,
    /// The gap, mm.
    GapMm,
}

/// The box of initial conditions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StartBox {
    /// `u0` in `[lo, hi]` mm, `u̇0` in `[lo, hi]` mm/s.
    Explicit {
        /// `u0` range, mm.
        u0_mm: (f64, f64),
        /// `u̇0` range, mm/s.
        v0_mm_s: (f64, f64),
    },
    /// The start-up box at each operating point: `u0` from `−max(gap, A0)` to the surface
    /// (`gap`), `u̇0` within the cart's velocity amplitude `±A0 Ω` (rest is inside).
    Startup,
}

impl StartBox {
    /// `((u0 lo, hi) mm, (u̇0 lo, hi) mm/s)` at gap `gap_mm` and `Ω/ω`.
    pub fn bounds(
        &self,
        params: &RigParams,
        gap_mm: f64,
        omega_ratio: f64,
    ) -> ((f64, f64), (f64, f64)) {
        match *self {
            StartBox::Explicit { u0_mm, v0_mm_s } => (u0_mm, v0_mm_s),
            StartBox::Startup => {
                let a0_mm = params.amplitude_m * 1e3;
                let v = a0_mm * omega_ratio * params.omega_n();
                ((-gap_mm.max(a0_mm), gap_mm), (-v, v))
            }
        }
    }
}

/// The grid of a fractions run (metadata `grid`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FractionsGrid {
    /// Operating points `(gap mm, Ω/ω)`, in parameter order.
    pub points: Vec<(f64, f64)>,
    /// The parameter the points follow (the figure's axis).
    pub parameter: Parameter,
    /// Initial conditions.
    pub start: StartBox,
    /// Seed of the initial conditions.
    pub seed: u64,
    /// Samples per operating point (the cap in the adaptive mode).
    pub samples: u32,
    /// Adaptive mode: stop when every interval is narrower than this.
    pub width: Option<f64>,
    /// Attractor tolerance (scaled), as in `basins`.
    pub attractor_tol: f64,
    /// Matching tolerance between consecutive operating points (scaled).
    pub match_tol: f64,
    /// Recurrence on the catalogue.
    pub recurrence: RecurrenceSettings,
}

impl FractionsGrid {
    /// `(operating point, sample)` of index `i`.
    pub fn split(&self, i: u64) -> (usize, u32) {
        let n = u64::from(self.samples.max(1));
        ((i / n) as usize, (i % n) as u32)
    }

    /// The index of sample `s` at operating point `k`.
    pub fn index(&self, k: usize, s: u32) -> u64 {
        k as u64 * u64::from(self.samples) + u64::from(s)
    }

    /// The parameter value of operating point `k`.
    pub fn value(&self, k: usize) -> f64 {
        let (g, r) = self.points[k];
        match self.parameter {
            Parameter::OmegaRatio => r,
            Parameter::GapMm => g,
        }
    }

    /// The initial condition `(u0 mm, u̇0 mm/s)` of index `i`.
    pub fn initial(&self, setup: &Setup, i: u64) -> (f64, f64) {
        let (k, s) = self.split(i);
        let (g, r) = self.points[k];
        let ((u_lo, u_hi), (v_lo, v_hi)) = self.start.bounds(&setup.params, g, r);
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(k as u64);
        // Two f64 per sample, 64 bits each: four 32-bit words.
        rng.set_word_pos(u128::from(s) * 4);
        let a: f64 = StandardUniform.sample(&mut rng);
        let b: f64 = StandardUniform.sample(&mut rng);
        (u_lo + (u_hi - u_lo) * a, v_lo + (v_hi - v_lo) * b)
    }

    /// One catalogue per operating point.
    pub fn catalogues(&self, setup: &Setup) -> Vec<Catalogue> {
        self.points
            .iter()
            .map(|&(_, r)| Catalogue::new(Attractors::scales(&setup.params, r), self.attractor_tol))
            .collect()
    }

    /// The rows of the indices `batch` (ascending) on the calling thread.
    pub fn rows(
        &self,
        setup: &Setup,
        catalogues: &[Catalogue],
        batch: &[usize],
    ) -> Vec<Result<[BasinRaw; 1]>> {
        let mut out = Vec::with_capacity(batch.len());
        let mut at = 0;
        while at < batch.len() {
            let k = self.split(batch[at] as u64).0;
            let end = batch[at..]
                .iter()
                .position(|&i| self.split(i as u64).0 != k)
                .map_or(batch.len(), |n| at + n);
            let ics: Vec<(u64, f64, f64)> = batch[at..end]
                .iter()
                .map(|&i| {
                    let (u, v) = self.initial(setup, i as u64);
                    (i as u64, u, v)
                })
                .collect();
            let (gap_mm, omega_ratio) = self.points[k];
            let run = Attractors {
                setup,
                gap_mm,
                omega_ratio,
                recurrence: self.recurrence,
                catalogue: &catalogues[k],
            };
            out.extend(run.rows(&ics).into_iter().map(|r| r.map(|r| [r])));
            at = end;
        }
        out
    }
}

/// Checks that `width` can be met with `samples` samples.
///
/// # Errors
/// `width` outside `(0, 1)`, or narrower than the widest 95 % interval at `samples` samples.
pub fn check_width(width: f64, samples: u32) -> Result<()> {
    if !(width.is_finite() && width > 0.0 && width < 1.0) {
        bail!("--width {width}: the interval width must lie in (0, 1)");
    }
    let worst = widest_interval(u64::from(samples));
    if width < worst {
        // The widest interval at n samples is Z95/√(n + Z95²) (k = n/2).
        let need = (Z95 * Z95 / (width * width) - Z95 * Z95).ceil();
        bail!(
            "--width {width} cannot be met with --samples {samples}: a fraction near 1/2 has a 95 % \
             interval {worst:.4} wide at {samples} samples; allowed --width ≥ {worst:.4}, or \
             --samples ≥ {need:.0}"
        );
    }
    Ok(())
}

/// Runs the adaptive mode: at each operating point, rounds of [`ROUND`] samples until every
/// attractor's interval is narrower than `grid.width` (or `grid.samples` are done), writing the
/// rows in index order with `sink`. Returns the samples taken per operating point.
///
/// # Errors
/// A failing point, `sink`, or Ctrl-C.
pub fn run_adaptive(
    setup: &Setup,
    meta: &Meta,
    grid: &FractionsGrid,
    mut sink: impl FnMut(BasinRaw) -> Result<()>,
) -> Result<Vec<u32>> {
    let width = grid
        .width
        .context("internal: adaptive mode without a width")?;
    let catalogues = grid.catalogues(setup);
    let mut taken = Vec::with_capacity(grid.points.len());
    for (k, &(_, omega_ratio)) in grid.points.iter().enumerate() {
        let mut grouping = Grouping::new(
            Attractors::scales(&meta.params, omega_ratio),
            grid.attractor_tol,
        );
        let mut n = 0u32;
        while n < grid.samples {
            let round = ROUND.min(grid.samples - n);
            let first = grid.index(k, n);
            let idx = (first..first + u64::from(round)).map(|i| i as usize);
            run_chunked(
                idx,
                round as usize,
                "",
                |b| grid.rows(setup, &catalogues, b),
                |_, [row]| {
                    grouping.add(&row);
                    sink(row)
                },
            )?;
            n += round;
            let (list, _) = grouping.attractors();
            if list.iter().all(|a| a.ci95.1 - a.ci95.0 < width) {
                break;
            }
        }
        taken.push(n);
    }
    Ok(taken)
}

/// One row of the fractions CSV: one attractor at one operating point.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FractionRow {
    /// Gap, mm.
    pub gap_mm: f64,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Excitation frequency, Hz.
    pub freq_hz: f64,
    /// Attractor id, kept along the parameter (`-`: no attractor).
    pub attractor: String,
    /// Regime (`-` for the initial conditions without an attractor).
    pub regime: String,
    /// Canonical Poincaré `u`, mm (periodic attractors).
    pub u_mm: Option<f64>,
    /// Canonical Poincaré `u̇`, mm/s.
    pub v_mm_s: Option<f64>,
    /// Peak `F_i/mg` on the attractor.
    pub impact_force_mg: f64,
    /// Initial conditions that end on it.
    pub count: u64,
    /// Samples at this operating point.
    pub samples: u64,
    /// Basin fraction.
    pub fraction: f64,
    /// Wilson 95 % interval, low end.
    pub ci95_lo: f64,
    /// Wilson 95 % interval, high end.
    pub ci95_hi: f64,
}

/// The attractors of one operating point with their ids along the parameter.
#[derive(Debug, Clone)]
pub struct PointFractions {
    /// Parameter value.
    pub value: f64,
    /// `(gap mm, Ω/ω)`.
    pub point: (f64, f64),
    /// Samples.
    pub samples: u64,
    /// Attractors with their id along the parameter (index into [`FractionsSummary::ids`]).
    pub attractors: Vec<(usize, Attractor)>,
}

/// What the fractions figure needs.
#[derive(Debug, Clone)]
pub struct FractionsSummary {
    /// The operating points in parameter order.
    pub points: Vec<PointFractions>,
    /// Ids along the parameter: letter and the regime it was first found with.
    pub ids: Vec<(String, Regime, bool)>,
}

/// Matches the attractors of one operating point to those of the previous one: returns for
/// each of `next` the index into `prev` it continues, if any. Two attractors can match when
/// they share recurrence, regime and number of Poincaré points; pairs whose canonical points lie
/// within `tol` in the scaled distance `scale` are matched first, nearest first; then a pair
/// left unmatched within [`FOLD_REACH`]` · tol` is matched when each is the other's only
/// candidate of its kind (near a fold an orbit moves like the square root of the distance to
/// it, faster than any fixed tolerance at a fixed step).
pub fn match_attractors(
    prev: &[Attractor],
    next: &[Attractor],
    tol: f64,
    scale: impl Fn((f64, f64), (f64, f64)) -> f64,
) -> Vec<Option<usize>> {
    let kin = |a: &Attractor, b: &Attractor| {
        a.recurrent == b.recurrent && a.regime == b.regime && a.points.len() == b.points.len()
    };
    let dist = |a: &Attractor, b: &Attractor| match (a.point, b.point) {
        (Some(p), Some(q)) => Some(scale(p, q)),
        (None, None) => Some(0.0),
        _ => None,
    };
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (j, b) in next.iter().enumerate() {
        for (i, a) in prev.iter().enumerate() {
            if let Some(d) = dist(a, b).filter(|&d| kin(a, b) && d <= tol) {
                pairs.push((d, i, j));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut out = vec![None; next.len()];
    let mut used = vec![false; prev.len()];
    for (_, i, j) in pairs {
        if out[j].is_none() && !used[i] {
            out[j] = Some(i);
            used[i] = true;
        }
    }
    // The only unmatched candidates of their kind on both sides, within the fold's reach.
    for j in 0..next.len() {
        if out[j].is_some() {
            continue;
        }
        let b = &next[j];
        let cands: Vec<usize> = (0..prev.len())
            .filter(|&i| !used[i] && kin(&prev[i], b))
            .collect();
        let [i] = cands[..] else { continue };
        let rivals = (0..next.len())
            .filter(|&k| k != j && out[k].is_none() && kin(&prev[i], &next[k]))
            .count();
        if rivals == 0 && dist(&prev[i], b).is_some_and(|d| d <= FOLD_REACH * tol) {
            out[j] = Some(i);
            used[i] = true;
        }
    }
    out
}

/// How much farther than the matching tolerance an attractor may have moved between two
/// operating points when it is the only one of its kind on both sides.
pub const FOLD_REACH: f64 = 4.0;

/// Basin fractions as a [`GridKind`].
pub struct Fractions;

impl GridKind for Fractions {
    const KIND: Kind = Kind::Fractions;
    const ROWS_ARE_OUTPUT: bool = false;
    type Grid = FractionsGrid;
    type Row = BasinRaw;
    type Summary = FractionsSummary;

    fn check_row(_meta: &Meta, _grid: &FractionsGrid, row: &BasinRaw) -> Result<(), String> {
        row.check_values()
    }

    fn finish(job: &mut Finish<'_>) -> Result<FractionsSummary> {
        let (meta, raw, out) = (job.meta, job.rows, job.out);
        let grid = meta.grid::<FractionsGrid>()?;
        if job.figures.attractors.is_some() {
            bail!("--attractors-out: only for basins (the fractions CSV lists each attractor)");
        }
        let mut groupings: Vec<Grouping> = grid
            .points
            .iter()
            .map(|&(_, r)| Grouping::new(Attractors::scales(&meta.params, r), grid.attractor_tol))
            .collect();
        for r in open_csv::<BasinRaw>(raw)?.deserialize::<BasinRaw>() {
            let r = r.with_context(|| format!("{}: malformed row", raw.display()))?;
            let (k, _) = grid.split(r.index);
            groupings
                .get_mut(k)
                .with_context(|| {
                    format!("{}: row index {} beyond the grid", raw.display(), r.index)
                })?
                .add(&r);
        }
        let mut ids: Vec<(String, Regime, bool)> = Vec::new();
        // The last operating point at which each id was seen, its attractor there, and the
        // operating point and canonical point of the occurrence before.
        let mut last: Vec<LastSeen> = Vec::new();
        let mut points: Vec<PointFractions> = Vec::new();
        let mut w = create_csv::<FractionRow>(out, None)?;
        for (k, g) in groupings.iter().enumerate() {
            let (list, _) = g.attractors();
            let samples: u64 = list.iter().map(|a| a.cells).sum();
            let (gap_mm, omega_ratio) = grid.points[k];
            let scales = Attractors::scales(&meta.params, omega_ratio);
            // Candidates: the ids seen within the last MATCH_BACK operating points.
            let candidates: Vec<usize> = (0..last.len())
                .filter(|&id| last[id].0 + MATCH_BACK >= k && last[id].0 < k)
                .collect();
            // Each candidate's canonical point extrapolated linearly from its last two
            // occurrences (a branch moves fast near a fold).
            let prev_list: Vec<Attractor> = candidates
                .iter()
                .map(|&id| {
                    let (at, mut a, before) = last[id].clone();
                    if let (Some(p), Some((k0, p0))) = (a.point, before) {
                        let f = (k - at) as f64 / (at - k0) as f64;
                        a.point = Some((p.0 + f * (p.0 - p0.0), p.1 + f * (p.1 - p0.1)));
                    }
                    a
                })
                .collect();
            let matched: Vec<Option<usize>> =
                match_attractors(&prev_list, &list, grid.match_tol, |a, b| {
                    scales.distance(a, b)
                })
                .into_iter()
                .map(|m| m.map(|i| candidates[i]))
                .collect();
            let mut here = Vec::new();
            for (a, m) in list.into_iter().zip(matched) {
                // "No attractor" is one id over the whole continuation.
                let m = if a.recurrent {
                    m
                } else {
                    ids.iter().position(|i| !i.2)
                };
                let id = m.unwrap_or_else(|| {
                    let n_rec = ids.iter().filter(|i| i.2).count();
                    ids.push((
                        if a.recurrent {
                            label(n_rec)
                        } else {
                            "-".into()
                        },
                        a.regime,
                        a.recurrent,
                    ));
                    last.push((k, a.clone(), None));
                    ids.len() - 1
                });
                let before = match (last[id].0 < k, last[id].1.point) {
                    (true, Some(p)) => Some((last[id].0, p)),
                    _ => None,
                };
                last[id] = (k, a.clone(), before);
                w.serialize(FractionRow {
                    gap_mm,
                    omega_ratio,
                    freq_hz: meta.params.freq_hz_from_ratio(omega_ratio),
                    attractor: ids[id].0.clone(),
                    regime: a.regime_text(),
                    u_mm: a.point.map(|p| p.0),
                    v_mm_s: a.point.map(|p| p.1),
                    impact_force_mg: a.impact_force_mg,
                    count: a.cells,
                    samples,
                    fraction: a.fraction,
                    ci95_lo: a.ci95.0,
                    ci95_hi: a.ci95.1,
                })?;
                here.push((id, a));
            }
            let mut line = format!("  {:.4}:", grid.value(k));
            for (id, a) in &here {
                line.push_str(&format!(
                    " {} {} {:.1} % [{:.1}, {:.1}]",
                    ids[*id].0,
                    if a.recurrent {
                        a.regime.to_string()
                    } else {
                        "no attractor".into()
                    },
                    100.0 * a.fraction,
                    100.0 * a.ci95.0,
                    100.0 * a.ci95.1
                ));
            }
            eprintln!("{line} (n = {samples})");
            points.push(PointFractions {
                value: grid.value(k),
                point: (gap_mm, omega_ratio),
                samples,
                attractors: here,
            });
        }
        w.flush()?;
        let never: u64 = points
            .iter()
            .flat_map(|p| &p.attractors)
            .filter(|(_, a)| !a.recurrent)
            .map(|(_, a)| a.cells)
            .sum();
        if never > 0 {
            let total: u64 = points.iter().map(|p| p.samples).sum();
            eprintln!(
                "{}",
                no_attractor_note(never, total, &meta.settings.protocol)
            );
        }
        Ok(FractionsSummary { points, ids })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn attractor(regime: Regime, point: Option<(f64, f64)>, n: usize) -> Attractor {
        Attractor {
            id: String::new(),
            label: String::new(),
            recurrent: true,
            regime,
            point,
            points: point.map(|p| vec![p; n]).unwrap_or_default(),
            impact_force_mg: 0.0,
            cells: 1,
            fraction: 0.5,
            ci95: (0.0, 1.0),
        }
    }

    #[test]
    fn matching_pairs_nearest_of_the_same_kind() {
        let one = Regime::ONE_ONE;
        let prev = [
            attractor(one, Some((0.0, 0.0)), 1),
            attractor(one, Some((1.0, 0.0)), 1),
            attractor(Regime::Irregular, None, 0),
        ];
        let next = [
            attractor(one, Some((0.95, 0.0)), 1),
            attractor(one, Some((0.1, 0.0)), 1),
            attractor(Regime::Periodic { p: 2, q: 2 }, Some((0.0, 0.0)), 2),
            attractor(Regime::Irregular, None, 0),
            attractor(one, Some((5.0, 0.0)), 1),
        ];
        let d = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs().max((a.1 - b.1).abs());
        assert_eq!(
            match_attractors(&prev, &next, 0.25, d),
            vec![Some(1), Some(0), None, Some(2), None]
        );
    }

    #[test]
    fn a_lone_attractor_near_a_fold_is_followed_farther() {
        let one = Regime::ONE_ONE;
        let d = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs().max((a.1 - b.1).abs());
        let prev = [
            attractor(one, Some((0.0, 0.0)), 1),
            attractor(Regime::NoImpact, Some((3.0, 0.0)), 1),
        ];
        // The only 1/1 on both sides, 0.6 away (beyond 0.25, within 4 · 0.25): followed.
        let next = [
            attractor(one, Some((0.6, 0.0)), 1),
            attractor(Regime::NoImpact, Some((3.0, 0.0)), 1),
        ];
        assert_eq!(
            match_attractors(&prev, &next, 0.25, d),
            vec![Some(0), Some(1)]
        );
        // Beyond the fold's reach: a new attractor.
        let far = [attractor(one, Some((1.2, 0.0)), 1)];
        assert_eq!(match_attractors(&prev, &far, 0.25, d), vec![None]);
        // Two unmatched 1/1 candidates: neither is taken for the other.
        let two = [
            attractor(one, Some((0.6, 0.0)), 1),
            attractor(one, Some((-0.6, 0.0)), 1),
        ];
        assert_eq!(match_attractors(&prev, &two, 0.25, d), vec![None, None]);
    }

    #[test]
    fn samples_do_not_depend_on_how_they_are_drawn() {
        let setup = Setup::preset(shared::model::RigId::Wires).unwrap();
        let grid = FractionsGrid {
            points: vec![(0.0, 2.0), (0.0, 2.1)],
            parameter: Parameter::OmegaRatio,
            start: StartBox::Explicit {
                u0_mm: (-1.0, 0.0),
                v0_mm_s: (-10.0, 10.0),
            },
            seed: 7,
            samples: 100,
            width: None,
            attractor_tol: 0.01,
            match_tol: 0.25,
            recurrence: RecurrenceSettings::default(),
        };
        let a = grid.initial(&setup, 150);
        assert_eq!(a, grid.initial(&setup, 150));
        assert_ne!(a, grid.initial(&setup, 151));
        assert_ne!(a, grid.initial(&setup, 50));
        // Uniform in the box: the mean of many samples is the box's centre.
        let n = 20_000u64;
        let mut grid = grid;
        grid.samples = n as u32;
        let (su, sv) = (0..n)
            .map(|i| grid.initial(&setup, i))
            .fold((0.0, 0.0), |s, p| (s.0 + p.0, s.1 + p.1));
        // Standard error of the mean: 1/sqrt(12 n) of the width.
        assert!(
            (su / n as f64 + 0.5).abs() < 4.0 / (12.0 * n as f64).sqrt(),
            "{su}"
        );
        assert!(
            (sv / n as f64).abs() < 4.0 * 20.0 / (12.0 * n as f64).sqrt(),
            "{sv}"
        );
    }

    #[test]
    fn widths_that_cannot_be_met_are_refused() {
        assert!(check_width(0.05, 2000).is_ok());
        let e = check_width(0.01, 2000).unwrap_err().to_string();
        assert!(
            e.contains("cannot be met") && e.contains("--samples ≥ 38411"),
            "{e}"
        );
        // The count it names is the least that meets the width.
        assert!(check_width(0.01, 38411).is_ok());
        assert!(check_width(0.01, 38410).is_err());
        assert!(check_width(0.0, 2000).is_err());
        assert!(check_width(f64::NAN, 2000).is_err());
    }
}

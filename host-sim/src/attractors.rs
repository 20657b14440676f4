//! Attractors at one operating point, from many initial conditions: the catalogue a run shares
//! between its threads (trajectories that reach a catalogued attractor stop early,
//! [`shared::observe::RecurrenceWatch`]), the reduction of one trajectory's observation window
//! to its recurrent set, fractions with 95 % confidence intervals, and the matching of
//! attractors from one parameter value to the next.
//!
//! An attractor is what a trajectory recurs on: a periodic orbit (the protocol's steady state,
//! or a window that repeats with a period `q ≤ max_q` to `classify_tol`), identified by its
//! regime and its Poincaré points; or an irregular set (an impacting window without period
//! whose Poincaré points keep returning near each other). A trajectory whose window neither
//! repeats nor returns (a transient longer than the limit) never recurred and is counted as
//! such; a non-impacting motion of an undamped suspension recurs but is conservative (no
//! attractor) and is counted with them.

use std::collections::VecDeque;
use std::sync::RwLock;

use serde::{Deserialize, Serialize};
use shared::observe::{AttractorCatalogue, Regime};

/// Steady-state tolerance of the attractor runs (`basins`, `fractions`, `select`'s basin
/// check), scaled: a state is taken as settled when its lag-`q` step is below it, and lies
/// within `1e-6 · μ/(1 − μ)` of its limit (`μ` the contraction per `q` periods) — within half
/// the default attractor tolerance for `1 − μ > 2e-4`.
pub const ATTRACTOR_STEADY_TOL: f64 = 1e-6;

/// Most transient periods [`transient_periods`] gives (a start that never recurs runs them all).
pub const MAX_TRANSIENT_PERIODS: u32 = 10_000;

/// The transient limit of an attractor run whose longest is not given: at least `protocol`
/// (the protocol's `max_transient_periods`), and as many periods as the suspension's free
/// oscillation takes to shrink by `steady_tol` at the run's largest Ω/ω
/// ([`shared::model::RigParams::free_decay_periods`]: a start must forget itself to found
/// an attractor), rounded up, at most [`MAX_TRANSIENT_PERIODS`]. Undamped: `protocol`.
///
/// The beam rig (ζ = 0.004) at Ω/ω 1.6 with the default 1e-6: 880 periods, where the
/// protocol's 200 leave every start without an attractor.
pub fn transient_periods(
    params: &shared::model::RigParams,
    protocol: u32,
    omega_ratio_max: f64,
    steady_tol: f64,
) -> u32 {
    let decay = params
        .free_decay_periods(omega_ratio_max, steady_tol)
        .unwrap_or(0.0);
    // `as` saturates; the cap keeps the run bounded for a damping near zero.
    (decay.ceil() as u32).clamp(protocol, MAX_TRANSIENT_PERIODS.max(protocol))
}

/// Default tolerance for "same attractor" (scaled): two periodic sets of one regime whose
/// canonical points lie this close are one attractor.
pub const ATTRACTOR_TOL: f64 = 0.01;
/// Default largest scaled distance between an attractor's canonical points at consecutive
/// operating points of a continuation.
pub const MATCH_TOL: f64 = 0.5;

/// Scaled distance within which an irregular window's Poincaré point counts as a return to an
/// earlier point of the same window.
pub const RETURN_TOL: f64 = 0.05;
/// Share of an irregular window's points that must return for the set to count as recurrent.
pub const RETURN_SHARE: f64 = 0.5;

/// How a trajectory ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Recurrence {
    /// Its own window recurred: a new or already catalogued attractor.
    Found,
    /// It reached a catalogued attractor and stopped early.
    Known,
    /// It never recurred within the protocol's periods.
    None,
    /// Its window repeats with a period but still lies far from its limit (a multiplier near 1
    /// in modulus: light damping, a fold, a doubling; see [`residual`]): it joins an attractor
    /// found by a lower index within the tolerance (where it would have stopped early had that
    /// one been catalogued in time), and otherwise counts as "no attractor".
    Unsettled,
    /// It recurred without impacts on an undamped suspension: a conservative motion (the
    /// stroboscopic map of the undamped free flight preserves area, so it has no attractor),
    /// counted with the never-recurrent as "no attractor".
    Neutral,
}

impl Recurrence {
    /// Whether the trajectory ended on an attractor.
    pub fn attracted(self) -> bool {
        matches!(self, Recurrence::Found | Recurrence::Known)
    }
}

/// How a trajectory ended, as the final CSVs say it: whether it was found by its own window or
/// stopped early on the catalogue depends on the order the threads ran, so it is not written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Ending {
    /// On an attractor.
    Attractor,
    /// It never recurred within the protocol's periods.
    None,
    /// A conservative motion without impacts on an undamped suspension ([`Recurrence::Neutral`]).
    Neutral,
}

impl From<Recurrence> for Ending {
    fn from(r: Recurrence) -> Self {
        match r {
            Recurrence::Found | Recurrence::Known => Ending::Attractor,
            Recurrence::None | Recurrence::Unsettled => Ending::None,
            Recurrence::Neutral => Ending::Neutral,
        }
    }
}

/// Scales of the scaled Poincaré distance `max(|Δu|/A0, |Δu̇|/(A0 Ω))`, in mm and mm/s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scales {
    /// `A0`, mm.
    pub u_mm: f64,
    /// `A0 Ω`, mm/s.
    pub v_mm_s: f64,
}

impl Scales {
    /// The scaled distance between two points `(u mm, u̇ mm/s)`.
    pub fn distance(&self, a: (f64, f64), b: (f64, f64)) -> f64 {
        ((a.0 - b.0).abs() / self.u_mm).max((a.1 - b.1).abs() / self.v_mm_s)
    }
}

/// A catalogued periodic attractor.
#[derive(Debug, Clone, PartialEq)]
pub struct Known {
    /// Regime (`no impact` for a non-impacting periodic orbit).
    pub regime: Regime,
    /// Its `q` Poincaré points `(u mm, u̇ mm/s)`, the canonical one (smallest `u`) first.
    pub points: Vec<(f64, f64)>,
    /// Peak `F_i/mg` over the window that found it.
    pub impact_force_mg: f64,
    /// Impacts in that window.
    pub impacts: u32,
}

/// The periodic attractors found so far in a run, shared by its threads, each with the lowest
/// initial-condition index that found it.
///
/// A trajectory is only matched against the attractors found by initial conditions of lower
/// index ([`Catalogue::before`]): the lowest-index trajectory of every attractor then always
/// runs to its own end, whatever order the threads ran in or however the grid was sharded,
/// and the attractor's reported values (its Poincaré points, force, impacts) are that
/// trajectory's — the same bits in one run and in merged shards.
#[derive(Debug)]
pub struct Catalogue {
    scales: Scales,
    attractor_tol: f64,
    known: RwLock<Vec<(u64, Known)>>,
}

impl Catalogue {
    /// An empty catalogue; two periodic sets of the same regime whose canonical points lie
    /// within `attractor_tol` (scaled) are one attractor.
    pub fn new(scales: Scales, attractor_tol: f64) -> Self {
        Catalogue {
            scales,
            attractor_tol,
            known: RwLock::new(Vec::new()),
        }
    }

    /// Registers a periodic set (its canonical point first) found by initial condition
    /// `index`, unless it is already known (then the lower index is kept); returns its id.
    pub fn register(&self, set: Known, index: u64) -> u32 {
        let mut known = self.known.write().unwrap_or_else(|e| e.into_inner());
        if let Some(k) = known.iter().position(|(_, k)| {
            k.regime == set.regime
                && k.points.len() == set.points.len()
                && self.scales.distance(k.points[0], set.points[0]) <= self.attractor_tol
        }) {
            if index < known[k].0 {
                known[k] = (index, set);
            }
            return k as u32;
        }
        known.push((index, set));
        (known.len() - 1) as u32
    }

    /// Attractor `id`.
    pub fn get(&self, id: u32) -> Option<Known> {
        let known = self.known.read().unwrap_or_else(|e| e.into_inner());
        known.get(id as usize).map(|(_, k)| k.clone())
    }

    /// The view of the catalogue for initial condition `index`: the attractors found by lower
    /// indices.
    pub fn before(&self, index: u64) -> Before<'_> {
        Before {
            catalogue: self,
            index,
        }
    }

    /// The tolerance for "same attractor" (scaled).
    pub fn attractor_tol(&self) -> f64 {
        self.attractor_tol
    }

    fn lookup_below(&self, u_m: f64, du_m_s: f64, tol: f64, index: u64) -> Option<u32> {
        let p = (u_m * 1e3, du_m_s * 1e3);
        let known = self.known.read().unwrap_or_else(|e| e.into_inner());
        known
            .iter()
            .position(|(by, k)| {
                *by < index && k.points.iter().any(|&q| self.scales.distance(p, q) <= tol)
            })
            .map(|k| k as u32)
    }
}

/// The attractors of a [`Catalogue`] found by initial conditions of index below `index`.
#[derive(Debug, Clone, Copy)]
pub struct Before<'c> {
    catalogue: &'c Catalogue,
    index: u64,
}

impl AttractorCatalogue for Before<'_> {
    fn lookup(&self, u_m: f64, du_m_s: f64, tol: f64) -> Option<u32> {
        self.catalogue.lookup_below(u_m, du_m_s, tol, self.index)
    }
}

/// The smallest period `q ≤ max_q` with which the last points of `window` (mm, mm/s) repeat
/// to the scaled `tol` over the whole window.
pub fn window_period(
    window: &VecDeque<(f64, f64)>,
    max_q: usize,
    tol: f64,
    scales: Scales,
) -> Option<usize> {
    let n = window.len();
    (1..=max_q.min(n / 2))
        .find(|&q| (q..n).all(|j| scales.distance(window[j], window[j - q]) <= tol))
}

/// The last `q` points of `window`, rotated so that the canonical one (smallest `u`, then
/// `u̇`) comes first; `None` if the window is shorter than `q` or `q` is 0.
pub fn cycle(window: &VecDeque<(f64, f64)>, q: usize) -> Option<Vec<(f64, f64)>> {
    let n = window.len();
    if q == 0 || q > n {
        return None;
    }
    let mut pts: Vec<(f64, f64)> = window.range(n - q..).copied().collect();
    canonical_first(&mut pts);
    Some(pts)
}

/// Rotates a cycle's points so that the canonical one (smallest `u`, then `u̇`) comes first.
fn canonical_first(points: &mut [(f64, f64)]) {
    if let Some(first) = (0..points.len()).min_by(|&a, &b| {
        points[a]
            .0
            .total_cmp(&points[b].0)
            .then(points[a].1.total_cmp(&points[b].1))
    }) {
        points.rotate_left(first);
    }
}

/// A cycle reduced to its minimal period: the first `d` points, for the smallest divisor `d`
/// of its length such that every point lies within `tol` (scaled) of the point `d` before it
/// (a still-converging window can repeat better at twice its period than at its period).
pub fn minimal_cycle(points: Vec<(f64, f64)>, tol: f64, scales: Scales) -> Vec<(f64, f64)> {
    let q = points.len();
    for d in (1..q).filter(|d| q.is_multiple_of(*d)) {
        if (d..q).all(|j| scales.distance(points[j], points[j - d]) <= tol) {
            let mut head: Vec<(f64, f64)> = points[..d].to_vec();
            canonical_first(&mut head);
            return head;
        }
    }
    points
}

/// How far the last point of a window that repeats with period `q` may still lie from the
/// periodic orbit it converges to (scaled): the last lag-`q` step `d` over the geometric tail
/// `μ/(1 − μ)`, with the contraction per `q` periods `μ` measured between the window's first
/// and last `q` lag steps. Where the orbit's multiplier nears 1 in modulus (light damping: a
/// free oscillation commensurate with the excitation decays by `e^{−2πζ q ω/Ω}` per `q`
/// periods; near a fold or a doubling) the protocol's steady-state test, on the step `d`,
/// passes long before the state is near its limit, and two starts would otherwise be taken for
/// two attractors. A window that does not contract (an exactly repeating one) gives `d`.
pub fn residual(window: &VecDeque<(f64, f64)>, q: usize, scales: Scales) -> f64 {
    let n = window.len();
    if q == 0 || n < 3 * q {
        return f64::INFINITY;
    }
    let step = |k: usize| scales.distance(window[k], window[k - q]);
    let first = (q..2 * q).map(step).fold(0.0, f64::max);
    let last = (n - q..n).map(step).fold(0.0, f64::max);
    if first <= 0.0 || last <= 0.0 || last >= first {
        return last;
    }
    // Lags between the two blocks, in units of q periods.
    let lags = (n - 2 * q) as f64 / q as f64;
    let mu = (last / first).powf(1.0 / lags);
    last * mu / (1.0 - mu)
}

/// Whether an irregular window is still converging onto a periodic orbit: its points repeat
/// with a period `q ≤ max_q` to [`RETURN_TOL`] (scaled) over the whole window, though not to
/// the protocol's tolerance (near a fold or a period doubling, where a multiplier nears ±1,
/// the approach takes thousands of periods). Such a start has not settled: it is not an
/// attractor of its own.
pub fn converging(window: &VecDeque<(f64, f64)>, max_q: usize, scales: Scales) -> bool {
    window_period(window, max_q, RETURN_TOL, scales).is_some()
}

/// Whether an irregular window's points keep returning: at least [`RETURN_SHARE`] of them lie
/// within [`RETURN_TOL`] (scaled) of an earlier point of the window.
pub fn returns(window: &VecDeque<(f64, f64)>, scales: Scales) -> bool {
    let n = window.len();
    if n < 2 {
        return false;
    }
    let back = (1..n)
        .filter(|&j| (0..j).any(|i| scales.distance(window[i], window[j]) <= RETURN_TOL))
        .count();
    back as f64 >= RETURN_SHARE * (n - 1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: Scales = Scales {
        u_mm: 1.0,
        v_mm_s: 10.0,
    };

    #[test]
    fn periods_and_cycles_of_a_window() {
        let w: VecDeque<(f64, f64)> = (0..12)
            .map(|j| {
                if j % 3 == 0 {
                    (1.0, 0.0)
                } else if j % 3 == 1 {
                    (-1.0, 5.0)
                } else {
                    (0.5, -5.0)
                }
            })
            .collect();
        assert_eq!(window_period(&w, 16, 1e-3, S), Some(3));
        assert_eq!(window_period(&w, 2, 1e-3, S), None);
        assert_eq!(
            cycle(&w, 3),
            Some(vec![(-1.0, 5.0), (0.5, -5.0), (1.0, 0.0)])
        );
        // A rotation of the same cycle gives the same canonical first point.
        let mut r = w.clone();
        r.rotate_left(1);
        assert_eq!(cycle(&r, 3).unwrap()[0], (-1.0, 5.0));
    }

    #[test]
    fn a_cycle_reduces_to_its_minimal_period() {
        let c = vec![(0.0, 0.0), (0.001, 0.0), (0.0, 0.0005), (0.0005, 0.0)];
        assert_eq!(minimal_cycle(c.clone(), 1e-2, S), vec![(0.0, 0.0)]);
        let two = vec![(0.0, 0.0), (1.0, 0.0), (0.0, 0.0), (1.0, 0.0)];
        assert_eq!(minimal_cycle(two, 1e-2, S), vec![(0.0, 0.0), (1.0, 0.0)]);
        let three = vec![(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)];
        assert_eq!(minimal_cycle(three.clone(), 1e-2, S), three);
    }

    #[test]
    fn returns_tells_a_recurrent_cloud_from_a_drift() {
        // Points on a circle visited again and again return; a monotone drift does not.
        let circle: VecDeque<(f64, f64)> = (0..64)
            .map(|j| {
                let a = j as f64 * 0.7;
                (a.cos(), 10.0 * a.sin())
            })
            .collect();
        assert!(returns(&circle, S));
        let drift: VecDeque<(f64, f64)> = (0..64).map(|j| (j as f64 * 0.1, 0.0)).collect();
        assert!(!returns(&drift, S));
    }

    #[test]
    fn residual_is_the_geometric_tail_of_a_contracting_window() {
        // x_k = L + a μ1^k with μ1 = 0.99 per period: the last point lies a μ1^63 from L.
        let (l, a, mu1) = (0.3, 0.2, 0.99f64);
        let w: VecDeque<(f64, f64)> = (0..64).map(|k| (l + a * mu1.powi(k), 0.0)).collect();
        let exact = a * mu1.powi(63);
        let r = residual(&w, 1, S);
        assert!((r - exact).abs() < 1e-9 * exact.max(1.0), "{r} vs {exact}");
        // An exactly repeating window: its step (0).
        let still: VecDeque<(f64, f64)> = (0..64).map(|k| ((k % 2) as f64, 0.0)).collect();
        assert_eq!(residual(&still, 2, S), 0.0);
        // Too short for its period.
        assert_eq!(residual(&still, 32, S), f64::INFINITY);
    }

    #[test]
    fn a_slow_approach_to_a_cycle_is_converging_a_cloud_is_not() {
        // A 2-cycle approached at rate 0.999 per period (a multiplier near −1): the window's
        // points repeat with period 2 to 0.05 of the scales, not to the protocol's tolerance.
        let slow: VecDeque<(f64, f64)> = (0..64)
            .map(|j| {
                let sign = if j % 2 == 0 { 1.0 } else { -1.0 };
                let e = 0.02 * 0.999f64.powi(j);
                (sign * (0.5 + e), 0.0)
            })
            .collect();
        assert!(converging(&slow, 8, S));
        assert_eq!(window_period(&slow, 8, 1e-6, S), None);
        let cloud: VecDeque<(f64, f64)> = (0..64)
            .map(|j| {
                let a = j as f64 * 0.7;
                (a.cos(), 10.0 * a.sin())
            })
            .collect();
        assert!(!converging(&cloud, 8, S));
    }

    #[test]
    fn catalogue_registers_once_and_looks_up_by_any_point() {
        let c = Catalogue::new(S, 1e-2);
        let a = Known {
            regime: Regime::Periodic { p: 1, q: 2 },
            points: vec![(-1.0, 0.0), (1.0, 0.0)],
            impact_force_mg: 3.0,
            impacts: 32,
        };
        assert_eq!(c.register(a.clone(), 7), 0);
        let mut same = a.clone();
        same.points[0].0 += 1e-3;
        assert_eq!(c.register(same.clone(), 9), 0);
        assert_eq!(c.get(0), Some(a.clone()));
        let mut other = a.clone();
        other.points[0].0 += 0.5;
        other.points[1].0 += 0.5;
        assert_eq!(c.register(other, 3), 1);
        // Two attractors catalogued.
        assert!(c.get(1).is_some() && c.get(2).is_none());
        // Lookup in m and m/s (over the whole catalogue).
        let all = c.before(u64::MAX);
        assert_eq!(all.lookup(1.0e-3, 0.0, 1e-2), Some(0));
        assert_eq!(all.lookup(-0.5e-3, 0.0, 1e-2), Some(1));
        assert_eq!(all.lookup(1.5e-3, 0.0, 1e-2), Some(1));
        assert_eq!(all.lookup(0.0, 0.0, 1e-2), None);
        // Only the attractors found by lower indices: attractor 0 was found by 7.
        assert_eq!(c.before(7).lookup(1.0e-3, 0.0, 1e-2), None);
        assert_eq!(c.before(8).lookup(1.0e-3, 0.0, 1e-2), Some(0));
        assert_eq!(c.before(4).lookup(-0.5e-3, 0.0, 1e-2), Some(1));
        // A lower index finding it again takes it over (with its own values).
        assert_eq!(c.register(same.clone(), 2), 0);
        assert_eq!(c.get(0), Some(same));
        assert_eq!(c.before(3).lookup(1.0e-3, 0.0, 1e-2), Some(0));
    }
}

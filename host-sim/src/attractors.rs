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

/// The periodic attractors found so far in a run, shared by its threads.
#[derive(Debug)]
pub struct Catalogue {
    scales: Scales,
    attractor_tol: f64,
    known: RwLock<Vec<Known>>,
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

    /// Registers a periodic set (its canonical point first) unless it is already known;
    /// returns its id.
    pub fn register(&self, set: Known) -> u32 {
        let mut known = self.known.write().unwrap_or_else(|e| e.into_inner());
        if let Some(k) = known.iter().position(|k| {
            k.regime == set.regime
                && k.points.len() == set.points.len()
                && self.scales.distance(k.points[0], set.points[0]) <= self.attractor_tol
        }) {
            return k as u32;
        }
        known.push(set);
        (known.len() - 1) as u32
    }

    /// Attractor `id`.
    pub fn get(&self, id: u32) -> Option<Known> {
        let known = self.known.read().unwrap_or_else(|e| e.into_inner());
        known.get(id as usize).cloned()
    }

    /// The tolerance for "same attractor" (scaled).
    pub fn attractor_tol(&self) -> f64 {
        self.attractor_tol
    }

    /// Number of catalogued attractors.
    pub fn len(&self) -> usize {
        self.known.read().unwrap_or_else(|e| e.into_inner()).len()
    }

    /// Whether none is catalogued.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl AttractorCatalogue for Catalogue {
    fn lookup(&self, u_m: f64, du_m_s: f64, tol: f64) -> Option<u32> {
        let p = (u_m * 1e3, du_m_s * 1e3);
        let known = self.known.read().unwrap_or_else(|e| e.into_inner());
        known
            .iter()
            .position(|k| k.points.iter().any(|&q| self.scales.distance(p, q) <= tol))
            .map(|k| k as u32)
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
    let pts: Vec<(f64, f64)> = window.range(n - q..).copied().collect();
    let first = (0..q).min_by(|&a, &b| {
        pts[a]
            .0
            .total_cmp(&pts[b].0)
            .then(pts[a].1.total_cmp(&pts[b].1))
    })?;
    Some((0..q).map(|k| pts[(first + k) % q]).collect())
}

/// A cycle reduced to its minimal period: the first `d` points, for the smallest divisor `d`
/// of its length such that every point lies within `tol` (scaled) of the point `d` before it
/// (a still-converging window can repeat better at twice its period than at its period).
pub fn minimal_cycle(points: Vec<(f64, f64)>, tol: f64, scales: Scales) -> Vec<(f64, f64)> {
    let q = points.len();
    for d in (1..q).filter(|d| q.is_multiple_of(*d)) {
        if (d..q).all(|j| scales.distance(points[j], points[j - d]) <= tol) {
            let mut head: Vec<(f64, f64)> = points[..d].to_vec();
            // Canonical first again.
            if let Some(first) = (0..d).min_by(|&a, &b| {
                head[a]
                    .0
                    .total_cmp(&head[b].0)
                    .then(head[a].1.total_cmp(&head[b].1))
            }) {
                head.rotate_left(first);
            }
            return head;
        }
    }
    points
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

/// `z` of the two-sided 95 % normal interval.
pub const Z95: f64 = 1.959_963_984_540_054;

/// Wilson's 95 % score interval of a fraction `k/n` (E. B. Wilson, J. Am. Stat. Assoc. 22,
/// 209, 1927): `[lo, hi]` within `[0, 1]`; `[0, 1]` when `n = 0`.
pub fn wilson(k: u64, n: u64) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let (n, p, z2) = (n as f64, k as f64 / n as f64, Z95 * Z95);
    let centre = (p + z2 / (2.0 * n)) / (1.0 + z2 / n);
    let half = Z95 / (1.0 + z2 / n) * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt();
    ((centre - half).max(0.0), (centre + half).min(1.0))
}

/// The widest Wilson interval over all `k` at `n` samples (at `k = n/2`).
pub fn widest_interval(n: u64) -> f64 {
    let (lo, hi) = wilson(n / 2, n);
    hi - lo
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: Scales = Scales {
        u_mm: 1.0,
        v_mm_s: 10.0,
    };

    #[test]
    fn wilson_matches_the_closed_form() {
        // k = 0: [0, z²/(n + z²)].
        let (lo, hi) = wilson(0, 100);
        assert_eq!(lo, 0.0);
        assert!((hi - Z95 * Z95 / (100.0 + Z95 * Z95)).abs() < 1e-15);
        // Symmetric about 1/2 at k = n/2, and close to the normal interval at large n.
        let (lo, hi) = wilson(5000, 10_000);
        assert!((lo + hi - 1.0).abs() < 1e-12);
        assert!(((hi - lo) - 2.0 * Z95 * 0.005).abs() < 1e-6);
        // k = 8 of n = 10, by hand: centre 0.71674, half-width 0.22658.
        let (lo, hi) = wilson(8, 10);
        assert!(
            (lo - 0.4902).abs() < 1e-4 && (hi - 0.9433).abs() < 1e-4,
            "{lo} {hi}"
        );
        assert!((widest_interval(10_000) - 0.0196).abs() < 1e-4);
    }

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
    fn catalogue_registers_once_and_looks_up_by_any_point() {
        let c = Catalogue::new(S, 1e-2);
        let a = Known {
            regime: Regime::Periodic { p: 1, q: 2 },
            points: vec![(-1.0, 0.0), (1.0, 0.0)],
            impact_force_mg: 3.0,
            impacts: 32,
        };
        assert_eq!(c.register(a.clone()), 0);
        let mut same = a.clone();
        same.points[0].0 += 1e-3;
        assert_eq!(c.register(same), 0);
        let mut other = a.clone();
        other.points[0].0 += 0.5;
        assert_eq!(c.register(other), 1);
        assert_eq!(c.len(), 2);
        // Lookup in m and m/s.
        assert_eq!(c.lookup(1.0e-3, 0.0, 1e-2), Some(0));
        assert_eq!(c.lookup(-0.5e-3, 0.0, 1e-2), Some(1));
        assert_eq!(c.lookup(0.0, 0.0, 1e-2), None);
    }
}

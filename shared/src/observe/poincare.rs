//! The stroboscopic Poincaré section: the state sampled at `t = kT` (excitation phase 0).

use heapless::HistoryBuf;

use super::period::smallest_period;
use crate::real::Real;

/// One point of the Poincaré section: relative displacement and velocity.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StroboPoint<T> {
    /// `u`, m.
    pub u: T,
    /// `u̇`, m/s.
    pub du: T,
}

impl<T: Real> StroboPoint<T> {
    /// Scaled distance `max(|Δu|/u_scale, |Δu̇|/v_scale)` (the protocol uses `A0` and `A0 Ω`).
    #[inline(always)]
    pub fn distance(&self, other: &Self, u_scale: T, v_scale: T) -> T {
        ((self.u - other.u).abs() / u_scale).max_of((self.du - other.du).abs() / v_scale)
    }
}

/// Length of the section history kept for steady-state detection: `4 × 16` periods.
pub const HISTORY: usize = 64;

/// The last [`HISTORY`] Poincaré points.
#[derive(Debug, Clone)]
pub struct SectionHistory<T: Copy> {
    buf: HistoryBuf<StroboPoint<T>, HISTORY>,
}

impl<T: Real> Default for SectionHistory<T> {
    fn default() -> Self {
        SectionHistory {
            buf: HistoryBuf::new(),
        }
    }
}

impl<T: Real> SectionHistory<T> {
    /// Appends a point (dropping the oldest when full).
    pub fn push(&mut self, p: StroboPoint<T>) {
        self.buf.write(p);
    }

    /// Number of points held.
    pub fn len(&self) -> usize {
        self.buf.len()
    }

    /// Whether no point is held.
    pub fn is_empty(&self) -> bool {
        self.buf.is_empty()
    }

    /// The `j`-th most recent point (`j = 0` is the newest).
    pub fn back(&self, j: usize) -> Option<&StroboPoint<T>> {
        nth_back(self.buf.as_slice(), self.buf.recent_index()?, j)
    }

    /// The smallest period `q ≤ max_q` with which the last `cycles` cycles of `q` repeat the
    /// preceding ones: `dist(s_{k−j}, s_{k−j−q}) ≤ tol` for `j = 0 .. cycles·q`.
    pub fn repeating_period(
        &self,
        max_q: usize,
        cycles: usize,
        tol: T,
        u_scale: T,
        v_scale: T,
    ) -> Option<usize> {
        // `back` with the slice and the newest index looked up once.
        let (points, recent) = (self.buf.as_slice(), self.buf.recent_index()?);
        smallest_period(
            max_q,
            |q| Some((cycles + 1) * q).filter(|&need| need <= points.len()),
            |a, b| match (nth_back(points, recent, a), nth_back(points, recent, b)) {
                (Some(a), Some(b)) => a.distance(b, u_scale, v_scale) <= tol,
                _ => false,
            },
        )
    }
}

/// The point `j` sections back from the newest in a history buffer's storage `points` (the
/// filled part, the newest at `recent`); `None` beyond the oldest.
#[inline(always)]
fn nth_back<P>(points: &[P], recent: usize, j: usize) -> Option<&P> {
    if j >= points.len() {
        return None;
    }
    points.get((recent + HISTORY - j) % HISTORY)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_smallest_repeating_period() {
        let mut h = SectionHistory::<f64>::default();
        for k in 0..100 {
            let v = [1.0, 2.0, 3.0][k % 3];
            h.push(StroboPoint { u: v, du: 0.0 });
        }
        assert_eq!(h.back(0).unwrap().u, [1.0, 2.0, 3.0][99 % 3]);
        assert_eq!(h.repeating_period(16, 3, 1e-9, 1.0, 1.0), Some(3));
        h.push(StroboPoint { u: 7.0, du: 0.0 });
        assert_eq!(h.repeating_period(16, 3, 1e-9, 1.0, 1.0), None);
    }
}

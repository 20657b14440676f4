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
        let far = FarBound::new(tol, u_scale, v_scale);
        // Neither a period nor a cycle count beyond the history can repeat in it: clamped, no
        // q past it is tried and `(cycles + 1)·q` cannot overflow.
        let (max_q, cycles) = (max_q.min(HISTORY), cycles.min(HISTORY));
        smallest_period(
            max_q,
            |q| Some((cycles + 1) * q).filter(|&need| need <= points.len()),
            |a, b| match (nth_back(points, recent, a), nth_back(points, recent, b)) {
                (Some(a), Some(b)) => !far.beyond(a, b) && a.distance(b, u_scale, v_scale) <= tol,
                _ => false,
            },
        )
    }
}

/// A bound past which two points are certainly farther apart than `tol`
/// ([`StroboPoint::distance`]) without its divisions: most pairs the steady-state test
/// compares are, and a multiplication decides them; the others go through `distance` itself, so
/// every decision is `distance`'s, bit for bit. (Host only: without the `std` feature there is
/// no bound.)
#[derive(Clone, Copy)]
struct FarBound<T> {
    /// `|Δu|` and `|Δu̇|` above which the scaled distance exceeds `tol` (`None`: no bound, for
    /// scales that are not positive and finite).
    du_dv: Option<(T, T)>,
}

impl<T: Real> FarBound<T> {
    #[inline(always)]
    fn new(tol: T, u_scale: T, v_scale: T) -> Self {
        // `fl(tol·s)·(1 + 2⁻²⁰)` exceeds `tol·s·(1 + 13 ε)` in f32 (ε = 2⁻²⁴; more in f64), so a
        // difference above it gives `fl(Δ/s) ≥ (Δ/s)(1 − ε) > tol`.
        let margin = T::from_f64(1.0 + 1.0 / 1_048_576.0);
        let positive = |s: T| s > T::zero() && s.is_finite();
        // On the host only: the MCU keeps its flash (its section test runs once a period).
        let du_dv = (cfg!(feature = "std") && positive(u_scale) && positive(v_scale))
            .then(|| (tol * u_scale * margin, tol * v_scale * margin));
        FarBound { du_dv }
    }

    /// Whether `a` and `b` are certainly farther apart than `tol` (false: perhaps not; a NaN
    /// difference is never beyond).
    #[inline(always)]
    fn beyond(&self, a: &StroboPoint<T>, b: &StroboPoint<T>) -> bool {
        match self.du_dv {
            Some((bu, bv)) => ((a.u - b.u).abs() > bu) | ((a.du - b.du).abs() > bv),
            None => false,
        }
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

    /// Any cycle count and `max_q` are answered, without overflow or a long search: a period-2
    /// history repeats for the cycles it holds, and not for more.
    #[test]
    fn repeating_period_takes_any_counts() {
        let mut h = SectionHistory::<f64>::default();
        for j in 0..HISTORY {
            h.push(StroboPoint {
                u: (j % 2) as f64,
                du: 0.0,
            });
        }
        assert_eq!(h.repeating_period(usize::MAX, 3, 1e-9, 1.0, 1.0), Some(2));
        assert_eq!(h.repeating_period(8, usize::MAX, 1e-9, 1.0, 1.0), None);
        assert_eq!(
            h.repeating_period(usize::MAX, usize::MAX, 1e-9, 1.0, 1.0),
            None
        );
        assert_eq!(h.repeating_period(0, 3, 1e-9, 1.0, 1.0), None);
    }

    /// Differences ulp by ulp around `tol·scale` (where `distance` turns) and around the bound
    /// (where `beyond` turns), over tolerances and scales of several magnitudes: a pair the
    /// bound calls far is farther than `tol` by `distance` itself, and pairs farther by 1e-5
    /// relative are called far.
    #[cfg(feature = "std")]
    fn far_bound_agrees_with_distance<T: Real>(ulps: impl Fn(T, i64) -> T) {
        let zero = StroboPoint {
            u: T::zero(),
            du: T::zero(),
        };
        let mut far_seen = 0;
        for tol in [1e-4, 1e-3, 3.7e-2] {
            for (su, sv) in [(1.0e-3, 2.0e-2), (3.3e-3, 7.1e-1), (1.0, 1.0)] {
                let (tol, su, sv) = (T::from_f64(tol), T::from_f64(su), T::from_f64(sv));
                let far = FarBound::new(tol, su, sv);
                let Some((bu, bv)) = far.du_dv else {
                    panic!("positive scales have a bound");
                };
                for (scale, bound, on_u) in [(su, bu, true), (sv, bv, false)] {
                    for centre in [tol * scale, bound] {
                        for k in -300..=300 {
                            let d = ulps(centre, k);
                            let b = if on_u {
                                StroboPoint {
                                    u: d,
                                    du: T::zero(),
                                }
                            } else {
                                StroboPoint {
                                    u: T::zero(),
                                    du: d,
                                }
                            };
                            // (What the steady-state test asks, negated: NaN is not within.)
                            let within = zero.distance(&b, su, sv) <= tol;
                            if far.beyond(&zero, &b) {
                                assert!(!within, "tol {tol:?} scale {scale:?} Δ {d:?}");
                                far_seen += 1;
                            }
                        }
                    }
                    let clearly = tol * scale * T::from_f64(1.0 + 1e-5);
                    assert!(far.beyond(
                        &zero,
                        &StroboPoint {
                            u: clearly,
                            du: clearly
                        }
                    ));
                }
            }
        }
        assert!(far_seen > 0);
        // No bound for scales that are not positive: `distance` decides.
        let none = FarBound::new(T::from_f64(1e-3), T::zero(), T::from_f64(1.0));
        let p = StroboPoint {
            u: T::from_f64(1.0),
            du: T::from_f64(1.0),
        };
        assert!(!none.beyond(&p, &zero));
    }

    #[test]
    #[cfg(feature = "std")]
    fn the_far_bound_only_decides_what_distance_decides() {
        far_bound_agrees_with_distance::<f32>(|x, k| {
            f32::from_bits(x.to_bits().wrapping_add_signed(k as i32))
        });
        far_bound_agrees_with_distance::<f64>(|x, k| {
            f64::from_bits(x.to_bits().wrapping_add_signed(k))
        });
    }

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

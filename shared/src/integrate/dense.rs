//! Dense output of one RK4 step and what the stepper reads from it: the cubic Hermite
//! interpolant of the state ([`DenseStep`]), a rising zero of an event function on it
//! ([`root_in_unit`], switching events), and the smallest value of a scalar's interpolant
//! between two samples ([`hermite_min`], how far the hammer left the surface between them);
//! both searches are [`bracket_rising`].

use nalgebra::Vector2;

use super::bracket::{Rule, bracket_rising};
use crate::real::Real;

/// One RK4 step's cubic Hermite dense output: from `x0` with slope `f0` to `x1` with slope
/// `f1` over `h` seconds.
#[derive(Clone, Copy)]
pub(super) struct DenseStep<T: Real> {
    pub(super) x0: Vector2<T>,
    pub(super) f0: Vector2<T>,
    pub(super) x1: Vector2<T>,
    pub(super) f1: Vector2<T>,
    pub(super) h: T,
}

impl<T: Real> DenseStep<T> {
    /// The interpolated state at fraction `s ∈ [0, 1]` of the step.
    #[inline(always)]
    pub(super) fn at(&self, s: T) -> Vector2<T> {
        let (h00, h10, h01, h11) = hermite_weights(s, self.h);
        self.x0 * h00 + self.f0 * h10 + self.x1 * h01 + self.f1 * h11
    }

    /// The interpolated state at `t` s from the step's start and its rate there (per s): the
    /// interpolant's time derivative, not the field.
    #[inline(always)]
    pub(super) fn position_and_rate(&self, t: T) -> (Vector2<T>, Vector2<T>) {
        let s = t / self.h;
        let x = self.at(s);
        let (two, three, four, six) = (
            T::from_f64(2.0),
            T::from_f64(3.0),
            T::from_f64(4.0),
            T::from_f64(6.0),
        );
        let s2 = s * s;
        // d/ds of the Hermite weights, over h for d/dt; the slope weights carry an h.
        let d00 = (six * s2 - six * s) / self.h;
        let d10 = three * s2 - four * s + T::from_f64(1.0);
        let d11 = three * s2 - two * s;
        let rate = self.x0 * d00 + self.f0 * d10 - self.x1 * d00 + self.f1 * d11;
        (x, rate)
    }
}

/// The cubic Hermite weights at fraction `s` of a step of `h` seconds: of the start, its slope,
/// the end and its slope ([`DenseStep::at`]).
#[inline(always)]
pub(super) fn hermite_weights<T: Real>(s: T, h: T) -> (T, T, T, T) {
    let one = T::from_f64(1.0);
    let two = T::from_f64(2.0);
    let three = T::from_f64(3.0);
    let s2 = s * s;
    let s3 = s2 * s;
    (
        two * s3 - three * s2 + one,
        (s3 - two * s2 + s) * h,
        three * s2 - two * s3,
        (s3 - s2) * h,
    )
}

/// The event tolerance of the production runs: a bracket `2^-14` of the sub-step wide (3 ns of
/// a 45 µs sub-step, a 0.2 nm change of `δ` at 0.06 m/s).
pub(crate) const EVENT_TOL: f64 = 1.0 / 16384.0;

/// Evaluations of an event function at most in one search.
pub(super) const MAX_EVENT_EVALS: u32 = 40;

/// The upper end of a bracket in `[0, 1]` (below `tol` wide, or after 40 evaluations) of a
/// rising zero of `g` with `g(0) ≤ 0 < g(1)` (if that premise fails, an end of the interval):
/// [`Rule::Illinois`], given `ends` = `(g(0), g(1))` bit for bit.
#[inline]
pub(super) fn root_in_unit<T: Real, G: Fn(T) -> T>(tol: T, ends: (T, T), g: G) -> T {
    let rule = Rule::Illinois {
        tol,
        max_evals: MAX_EVENT_EVALS,
        ends,
    };
    bracket_rising(T::zero(), T::from_f64(1.0), rule, g).1
}

/// The smallest value over a segment of `len` seconds of the cubic Hermite interpolant from
/// `y0` (slope `dy0`, per s) to `y1` (slope `dy1`): the smaller end value, or, where the slope
/// turns from falling (`dy0 < 0`) to rising (`dy1 > 0`), the interior minimum (the
/// interpolant's slope is then a quadratic with one sign change in the segment, located by 20
/// bisections: to 1e-6 of the segment, a value error of second order in that).
///
/// Used on the penetration `δ` between two samples: whether the hammer left the surface by the
/// separation of an impact episode (`crate::observe::impact`) between samples, which the
/// samples themselves (step ends, up to `T/N` apart) do not show.
// Inlined into the host's hot loop (measured: a few per mille of the grid's instructions); on the
// MCU left to the size heuristics.
#[cfg_attr(feature = "std", inline(always))]
#[cfg_attr(not(feature = "std"), inline)]
pub(crate) fn hermite_min<T: Real>(y0: T, dy0: T, y1: T, dy1: T, len: T) -> T {
    let ends = y0.min_of(y1);
    if !(dy0 < T::zero() && dy1 > T::zero()) {
        return ends;
    }
    let two = T::from_f64(2.0);
    let three = T::from_f64(3.0);
    let d = y1 - y0;
    // p(s) = y0 + a s + b s² + c s³ on s ∈ [0, 1]; p'(0) = a < 0 < p'(1) = len·dy1.
    let a = dy0 * len;
    let b = three * d - len * (two * dy0 + dy1);
    let c = len * (dy0 + dy1) - two * d;
    let slope = |s: T| a + (two * b + three * c * s) * s;
    let (lo, hi) = bracket_rising(T::zero(), T::from_f64(1.0), Rule::Bisect(20), slope);
    let s = (lo + hi) * T::from_f64(0.5);
    ends.min_of(y0 + (a + (b + c * s) * s) * s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hermite_min_is_exact_on_a_parabola_and_the_end_value_without_a_turn() {
        // y(t) = (t − 0.3)² − 0.05 on [0, 1]: a cubic Hermite interpolant reproduces it, so the
        // minimum is −0.05 at t = 0.3.
        let y = |t: f64| (t - 0.3) * (t - 0.3) - 0.05;
        let dy = |t: f64| 2.0 * (t - 0.3);
        let m = hermite_min(y(0.0), dy(0.0), y(1.0), dy(1.0), 1.0);
        assert!((m + 0.05).abs() < 1e-12, "{m}");
        // Over 2 s (scaled time): y(t) = (t − 1.5)² on [0, 2], minimum 0 at t = 1.5.
        let m2 = hermite_min(2.25, -3.0, 0.25, 1.0, 2.0);
        assert!(m2.abs() < 1e-12, "{m2}");
        // Falling throughout: the end value.
        assert_eq!(hermite_min(1.0, -1.0, 0.2, -0.1, 1.0), 0.2);
        // Rising then falling (a maximum inside): the smaller end.
        assert_eq!(hermite_min(0.1, 1.0, 0.3, -1.0, 1.0), 0.1);
    }

    #[test]
    fn hermite_min_of_a_bounce_matches_the_free_flight_apex() {
        // A hammer leaving the surface at 2 mm/s against a constant 1.7 m/s² pull back, sampled
        // 2.2 ms apart: δ(t) = −v t + a t²/2 (a parabola, reproduced exactly): apex −v²/(2a).
        let (v, acc, len) = (2e-3f32, 1.7f32, 2.2e-3f32);
        let d1 = -v * len + 0.5 * acc * len * len;
        let m = hermite_min(0.0, -v, d1, -v + acc * len, len);
        let apex = -v * v / (2.0 * acc);
        assert!((m - apex).abs() < 1e-6 * apex.abs(), "{m} vs {apex}");
        // Both samples are within 1 µm of the surface, the apex is not.
        assert!(d1 > -1e-6 && apex < -1e-6);
    }
}

//! The integrator's one bracketing root finder: shrinks `[lo, hi]` around a rising sign change
//! of `g` (`g(lo) ≤ 0 < g(hi)`), by plain bisection or by Illinois regula falsi.

use crate::real::Real;

/// How [`bracket_rising`] picks the next point.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Rule<T> {
    /// This many halvings (`g` is evaluated at the midpoints only; its ends are not needed).
    Bisect(u32),
    /// Illinois regula falsi (superlinear on smooth `g`, each iteration shrinks the bracket;
    /// a bisection step whenever the secant point falls within 1e-3 of an end) until the
    /// bracket is `tol` wide or `g` has been evaluated `max_evals` times.
    Illinois {
        /// Width at which to stop.
        tol: T,
        /// Evaluations of `g` at most (besides its ends).
        max_evals: u32,
        /// `(g(lo), g(hi))`, bit for bit what `g` gives there (the caller has them).
        ends: (T, T),
    },
}

/// The bracket `(lo, hi)` of a rising zero of `g` in `[lo, hi]` after `rule`: at a point `m`,
/// `g(m) > 0` moves `hi` to `m`, otherwise `lo`. With [`Rule::Illinois`], if the ends do not
/// bracket a rising zero the result is `(lo, lo)` when `g(lo) > 0`, else `(hi, hi)`. (The rule
/// is a constant at each caller, so only its branch is compiled there.)
#[inline(always)]
pub(crate) fn bracket_rising<T: Real, G: Fn(T) -> T>(lo: T, hi: T, rule: Rule<T>, g: G) -> (T, T) {
    match rule {
        Rule::Bisect(halvings) => bisect(lo, hi, halvings, g),
        Rule::Illinois {
            tol,
            max_evals,
            ends,
        } => illinois(lo, hi, tol, max_evals, ends, g),
    }
}

/// [`Rule::Bisect`] on the host: two halvings at a time, the second's two possible midpoints
/// evaluated together with the first's. The same points and the same decisions as one halving
/// after the other ([`bisect_one_at_a_time`], so the same bracket, bit for bit), but the three
/// evaluations of `g` are independent: an out-of-order processor overlaps them where two in
/// sequence would wait on each other (`g` is a chain of dependent operations: a dense-output
/// point and its penetration with a sine). An in-order MCU would only evaluate `g` more often.
#[cfg(feature = "std")]
#[inline]
fn bisect<T: Real, G: Fn(T) -> T>(mut lo: T, mut hi: T, halvings: u32, g: G) -> (T, T) {
    let half = T::from_f64(0.5);
    let zero = T::zero();
    let mut left = halvings;
    while left >= 2 {
        let mid = (lo + hi) * half;
        let (below, above) = ((lo + mid) * half, (mid + hi) * half);
        let (g_mid, g_below, g_above) = (g(mid), g(below), g(above));
        let (next, g_next) = if g_mid > zero {
            hi = mid;
            (below, g_below)
        } else {
            lo = mid;
            (above, g_above)
        };
        if g_next > zero {
            hi = next;
        } else {
            lo = next;
        }
        left -= 2;
    }
    if left == 1 {
        let mid = (lo + hi) * half;
        if g(mid) > zero {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    (lo, hi)
}

/// [`Rule::Illinois`].
#[inline]
fn illinois<T: Real, G: Fn(T) -> T>(
    mut lo: T,
    mut hi: T,
    tol: T,
    max_evals: u32,
    (mut g_lo, mut g_hi): (T, T),
    g: G,
) -> (T, T) {
    if !(g_lo <= T::zero() && g_hi > T::zero()) {
        let end = if g_lo > T::zero() { lo } else { hi };
        return (end, end);
    }
    let mut side = 0u32;
    for _ in 0..max_evals {
        if hi - lo <= tol {
            break;
        }
        let mid = illinois_step(lo, hi, g_lo, g_hi);
        let g_mid = g(mid);
        #[cfg(feature = "std")]
        illinois_update(
            true,
            (mid, g_mid),
            (&mut lo, &mut hi),
            (&mut g_lo, &mut g_hi),
            &mut side,
        );
        #[cfg(not(feature = "std"))]
        illinois_update_alone(
            (mid, g_mid),
            (&mut lo, &mut hi),
            (&mut g_lo, &mut g_hi),
            &mut side,
        );
    }
    (lo, hi)
}

/// The next point of an Illinois search of `[lo, hi]` with `g(lo) = g_lo ≤ 0 < g_hi = g(hi)`:
/// the secant's zero, or the midpoint where that falls within 1e-3 of the bracket of an end.
#[inline(always)]
pub(super) fn illinois_step<T: Real>(lo: T, hi: T, g_lo: T, g_hi: T) -> T {
    let secant = (lo * g_hi - hi * g_lo) / (g_hi - g_lo);
    let width = hi - lo;
    let inside =
        (secant > lo + width * T::from_f64(1e-3)) & (secant < hi - width * T::from_f64(1e-3));
    if inside {
        secant
    } else {
        (lo + hi) * T::from_f64(0.5)
    }
}

/// The bracket of an Illinois search after its point `mid` with `g(mid) = g_mid` (if `on`;
/// else all left as they are): `g_mid > 0` moves `hi` there, otherwise `lo`, and the end that
/// stays for the second time in a row has its `g` halved (the Illinois modification). `side`:
/// where the last point fell, 1 above the zero, 2 below, 0 none yet.
///
/// Written as one select per value, each on conditions of its own (no `else if` chain), so
/// that the switching-event lanes (`super::switch_lanes`) vectorise it: an `else if` chain
/// compiles, lane by lane, to branches, and the searches then run one lane at a time (a round
/// of 8 lanes on AVX2, release build: 577 instructions with 64 branches, against 144 with 2).
#[inline(always)]
pub(super) fn illinois_update<T: Real>(
    on: bool,
    (mid, g_mid): (T, T),
    (lo, hi): (&mut T, &mut T),
    (g_lo, g_hi): (&mut T, &mut T),
    side: &mut u32,
) {
    let half = T::from_f64(0.5);
    let above = g_mid > T::zero();
    let (up, down) = (on & above, on & !above);
    // The end that stays, halved if it stayed last time too.
    let g_lo_kept = if up & (*side == 1) {
        *g_lo * half
    } else {
        *g_lo
    };
    let g_hi_kept = if down & (*side == 2) {
        *g_hi * half
    } else {
        *g_hi
    };
    *hi = if up { mid } else { *hi };
    *lo = if down { mid } else { *lo };
    *g_lo = if down { g_mid } else { g_lo_kept };
    *g_hi = if up { g_mid } else { g_hi_kept };
    *side = if on { 2 - u32::from(above) } else { *side };
}

/// [`illinois_update`] of a search alone (`on` true) as branches, on the MCU: an in-order core
/// then computes only the side the point fell on (the selects cost it 0.8 % more instructions
/// in the target-frequency computation). The same values, bit for bit (tested).
#[cfg_attr(feature = "std", allow(dead_code))]
#[inline(always)]
fn illinois_update_alone<T: Real>(
    (mid, g_mid): (T, T),
    (lo, hi): (&mut T, &mut T),
    (g_lo, g_hi): (&mut T, &mut T),
    side: &mut u32,
) {
    let half = T::from_f64(0.5);
    if g_mid > T::zero() {
        *hi = mid;
        *g_hi = g_mid;
        if *side == 1 {
            *g_lo *= half;
        }
        *side = 1;
    } else {
        *lo = mid;
        *g_lo = g_mid;
        if *side == 2 {
            *g_hi *= half;
        }
        *side = 2;
    }
}

/// [`Rule::Bisect`] on the MCU: one halving after the other.
#[cfg(not(feature = "std"))]
#[inline]
fn bisect<T: Real, G: Fn(T) -> T>(lo: T, hi: T, halvings: u32, g: G) -> (T, T) {
    bisect_one_at_a_time(lo, hi, halvings, g)
}

/// [`Rule::Bisect`] as it reads: one halving after the other.
#[cfg_attr(feature = "std", allow(dead_code))]
#[inline]
fn bisect_one_at_a_time<T: Real, G: Fn(T) -> T>(
    mut lo: T,
    mut hi: T,
    halvings: u32,
    g: G,
) -> (T, T) {
    let half = T::from_f64(0.5);
    for _ in 0..halvings {
        let mid = (lo + hi) * half;
        if g(mid) > T::zero() {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bisection_two_halvings_at_a_time_is_one_at_a_time_bit_for_bit() {
        // Roots at many places (on the midpoints too, where `g = 0` moves `lo`), odd and even
        // numbers of halvings, and a `g` that is NaN on part of the interval (NaN moves `lo`).
        for k in 0..=64u32 {
            let root = k as f32 / 64.0 * 0.37 + 0.1;
            let g = |x: f32| x - root;
            let nan_above = |x: f32| if x > 0.4 { f32::NAN } else { x - root };
            for halvings in 0..=21 {
                for (lo, hi) in [(0.1f32, 0.47f32), (-1e-3, 2.0)] {
                    assert_eq!(
                        bisect(lo, hi, halvings, g),
                        bisect_one_at_a_time(lo, hi, halvings, g),
                        "root {root} halvings {halvings}"
                    );
                    assert_eq!(
                        bisect(lo, hi, halvings, nan_above),
                        bisect_one_at_a_time(lo, hi, halvings, nan_above)
                    );
                }
            }
        }
    }

    #[test]
    fn the_update_alone_is_the_selects_bit_for_bit() {
        // Every side (none yet, above, below), points above, below and at the zero (`g = 0`
        // moves `lo`), and a NaN (moves `lo` too), from brackets with and without halved ends.
        let gs = [0.75f32, -0.3, 0.0, -0.0, f32::NAN, 1e-30, -1e-30];
        for side0 in 0..=2u32 {
            for &g_mid in &gs {
                for (mid, lo0, hi0, g_lo0, g_hi0) in
                    [(0.4f32, 0.1, 0.9, -2.0, 3.0), (0.25, 0.2, 0.3, -1e-3, 5e-4)]
                {
                    let mut a = (lo0, hi0, g_lo0, g_hi0, side0);
                    let mut b = a;
                    illinois_update(
                        true,
                        (mid, g_mid),
                        (&mut a.0, &mut a.1),
                        (&mut a.2, &mut a.3),
                        &mut a.4,
                    );
                    illinois_update_alone(
                        (mid, g_mid),
                        (&mut b.0, &mut b.1),
                        (&mut b.2, &mut b.3),
                        &mut b.4,
                    );
                    let bits = |t: (f32, f32, f32, f32, u32)| {
                        (
                            t.0.to_bits(),
                            t.1.to_bits(),
                            t.2.to_bits(),
                            t.3.to_bits(),
                            t.4,
                        )
                    };
                    assert_eq!(bits(a), bits(b), "side {side0} g_mid {g_mid}");
                }
            }
        }
    }

    #[test]
    fn both_rules_bracket_the_root_of_a_cubic() {
        // g(x) = x³ − 0.2 on [0, 1]: root 0.2^(1/3) = 0.584803547642573…
        let root = libm::cbrt(0.2f64);
        let g = |x: f64| x * x * x - 0.2;
        let (lo, hi) = bracket_rising(0.0, 1.0, Rule::Bisect(20), g);
        assert!(lo <= root && root <= hi && hi - lo <= 1.0 / f64::from(1u32 << 20));
        let (lo, hi) = bracket_rising(
            0.0,
            1.0,
            Rule::Illinois {
                tol: 1e-9,
                max_evals: 40,
                ends: (g(0.0), g(1.0)),
            },
            g,
        );
        assert!(lo <= root && root <= hi && hi - lo <= 1e-9, "{lo} {hi}");
        // No sign change: an end.
        let ill = |ends| Rule::Illinois {
            tol: 1e-9,
            max_evals: 40,
            ends,
        };
        let (above, below) = (|x: f64| x + 1.0, |x: f64| x - 2.0);
        assert_eq!(
            bracket_rising(0.0, 1.0, ill((above(0.0), above(1.0))), above),
            (0.0, 0.0)
        );
        assert_eq!(
            bracket_rising(0.0, 1.0, ill((below(0.0), below(1.0))), below),
            (1.0, 1.0)
        );
    }
}

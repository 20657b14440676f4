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

/// [`Rule::Bisect`].
#[inline]
fn bisect<T: Real, G: Fn(T) -> T>(mut lo: T, mut hi: T, halvings: u32, g: G) -> (T, T) {
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
    let half = T::from_f64(0.5);
    if !(g_lo <= T::zero() && g_hi > T::zero()) {
        let end = if g_lo > T::zero() { lo } else { hi };
        return (end, end);
    }
    let mut side = 0i8;
    for _ in 0..max_evals {
        if hi - lo <= tol {
            break;
        }
        let mut mid = (lo * g_hi - hi * g_lo) / (g_hi - g_lo);
        let width = hi - lo;
        if !(mid > lo + width * T::from_f64(1e-3) && mid < hi - width * T::from_f64(1e-3)) {
            mid = (lo + hi) * half;
        }
        let g_mid = g(mid);
        if g_mid > T::zero() {
            hi = mid;
            g_hi = g_mid;
            if side == 1 {
                g_lo *= half;
            }
            side = 1;
        } else {
            lo = mid;
            g_lo = g_mid;
            if side == -1 {
                g_hi *= half;
            }
            side = -1;
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

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

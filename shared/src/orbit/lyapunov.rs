//! The largest Lyapunov exponent of a trajectory of the stroboscopic map, per excitation
//! period, from the same tangent dynamics as the monodromy (Benettin et al., Meccanica 15
//! (1980) 9–20; through impacts: Müller, Chaos Solitons Fractals 5 (1995) 1671–1681):
//! a tangent vector `v` is carried through each period by `DP` (dual numbers through the
//! simulator) and renormalised, `λ = (1/n) Σ ln ‖DP(x_k) v_k‖` in the scaled norm of
//! [`MapPoint::scales`]. Its convergence is judged by the two halves of the window: on a
//! periodic orbit both give `ln max|μ| / q`, on a chaotic one they scatter around a positive
//! value. Where the period `q` is known, [`orbit_exponent`] takes it from the monodromy.

use nalgebra::Vector2;

use super::map::{MapPoint, Trace, run};
use crate::dual::Dual;
use crate::error::{ParamError, check_count};
use crate::integrate::PhaseTable;
use crate::real::Real;

/// An estimate of the largest Lyapunov exponent, per excitation period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exponent {
    /// Over the whole window.
    pub per_period: f64,
    /// Over its first half.
    pub first_half: f64,
    /// Over its second half.
    pub second_half: f64,
    /// Periods in the window.
    pub periods: u32,
    /// Where the estimate is the mean over independent windows (a confirmation run,
    /// [`super::label()`]): the standard error of that mean, per period; `None` for one window
    /// judged by its halves.
    pub window_spread: Option<f64>,
}

impl Exponent {
    /// Its uncertainty: the independent windows' standard error where there are several
    /// ([`Exponent::window_spread`]), else half the difference of the halves' estimates (NaN
    /// with one period counted); 0 where it is −∞ (the tangent vanished in the last period:
    /// certain).
    pub fn uncertainty(&self) -> f64 {
        if self.per_period == f64::NEG_INFINITY {
            return 0.0;
        }
        if let Some(spread) = self.window_spread {
            return spread;
        }
        0.5 * (self.first_half - self.second_half).abs()
    }

    /// Whether it is positive beyond `sigmas` uncertainties (and beyond 1e-3 per period).
    pub fn clearly_positive(&self, sigmas: f64) -> bool {
        self.per_period > (sigmas * self.uncertainty()).max(1e-3)
    }

    /// Whether it is negative beyond `sigmas` uncertainties (and beyond 1e-3 per period).
    pub fn clearly_negative(&self, sigmas: f64) -> bool {
        self.per_period < -(sigmas * self.uncertainty()).max(1e-3)
    }
}

/// One period at a time of the map at a point, with what each period did.
pub(crate) struct Periods<'t, U: Real> {
    sim: crate::integrate::Simulator<'t, U>,
    separation_m: f64,
}

impl<'t, U: Real> Periods<'t, U> {
    pub(crate) fn new(at: &MapPoint, table: &'t PhaseTable<U>) -> Result<Self, ParamError> {
        Ok(Periods {
            sim: at.simulator(table)?,
            separation_m: at.settings.protocol.separation_m,
        })
    }

    /// `(u, u̇)` of the current state, m and m/s.
    pub(crate) fn relative(&self) -> (U, U) {
        self.sim.relative()
    }

    /// One period from `x` (phase 0): the state after it and what it did.
    pub(crate) fn run(&mut self, x: Vector2<U>) -> (Vector2<U>, Trace) {
        run(&mut self.sim, x, 1, self.separation_m, |_| {})
    }
}

/// A tangent vector carried through one period at a time of the map (value and tangent in one
/// dual-number run) and renormalised, in the scaled norm of [`MapPoint::scales`]; it starts
/// along the diagonal.
pub(crate) struct Tangent<'t, T: Real> {
    run: Periods<'t, Dual<T, 1>>,
    scales: [f64; 2],
    v: [f64; 2],
}

impl<'t, T: Real> Tangent<'t, T> {
    pub(crate) fn new(
        at: &MapPoint,
        table: &'t PhaseTable<Dual<T, 1>>,
    ) -> Result<Self, ParamError> {
        Ok(Tangent {
            run: Periods::new(at, table)?,
            scales: at.scales(),
            v: [libm::sqrt(0.5), libm::sqrt(0.5)],
        })
    }

    /// One period from `x` (phase 0): the map's image, the log of the tangent's stretch over it
    /// (`None` where the tangent vanished: the vector is then kept as it was), and what the
    /// period did.
    ///
    /// # Errors
    /// The tangent overflowing.
    pub(crate) fn period(
        &mut self,
        x: Vector2<T>,
    ) -> Result<(Vector2<T>, Option<f64>, Trace), ParamError> {
        let (s, v) = (self.scales, self.v);
        let seeded = Vector2::new(
            Dual {
                v: x[0],
                d: [T::from_f64(v[0] * s[0])],
            },
            Dual {
                v: x[1],
                d: [T::from_f64(v[1] * s[1])],
            },
        );
        let (y, trace) = self.run.run(seeded);
        let image = Vector2::new(y[0].v, y[1].v);
        let d = [y[0].d[0].to_f64() / s[0], y[1].d[0].to_f64() / s[1]];
        let n = libm::hypot(d[0], d[1]);
        if !n.is_finite() {
            return Err(ParamError::NotFinite {
                field: "tangent vector",
            });
        }
        if n == 0.0 {
            return Ok((image, None, trace));
        }
        self.v = [d[0] / n, d[1] / n];
        Ok((image, Some(libm::log(n)), trace))
    }

    /// `(u, u̇)` of the current state, m and m/s.
    pub(crate) fn relative(&self) -> (T, T) {
        let (u, du) = self.run.relative();
        (u.v, du.v)
    }
}

/// The largest Lyapunov exponent over `periods` (2 ..= 100,000) iterations of the map from
/// `x0` (from the last period where the tangent vanished, if it did:
/// [`largest_exponent_with`]), and the state reached.
///
/// # Errors
/// [`ParamError`]: an invalid point, `periods` out of range.
pub fn largest_exponent<T: Real>(
    at: &MapPoint,
    x0: Vector2<T>,
    periods: u32,
) -> Result<(Exponent, Vector2<T>), ParamError> {
    largest_exponent_with(at, x0, periods, |_, _| {})
}

/// [`largest_exponent`], calling `each(k, estimate)` after period `k` (1-based) with the
/// running estimate over the periods counted so far.
///
/// A tangent that vanishes (the hammer pressed on the surface contracts it below the float
/// type's range: in f32 a rest from the start of a run does) has stretched by 0. The estimate then starts again
/// from the next period (a transient rest says nothing of the motion after it; `periods` of the
/// result counts the periods used), and is −∞ if the tangent vanished in the last period (a
/// resting orbit).
///
/// # Errors
/// As [`largest_exponent`]; the tangent overflowing.
pub fn largest_exponent_with<T: Real>(
    at: &MapPoint,
    x0: Vector2<T>,
    periods: u32,
    each: impl FnMut(u32, f64),
) -> Result<(Exponent, Vector2<T>), ParamError> {
    exponent_core(at, x0, periods, |_, image| image, each)
}

/// The largest Lyapunov exponent along a trajectory given by its points on the section,
/// `section[0..=n]` (states at phase 0, `n = section.len() − 1` periods, 2 ..= 100,000): the
/// tangent vector is carried through period `k` by the map's `DP` at `section[k]` (events
/// located to round-off, as in [`largest_exponent`]) and renormalised, while the states are the
/// given ones, not the map's images. For a trajectory computed otherwise (the production
/// stepper's fixed steps, whose Poincaré points `simulate` writes), this is the exponent of
/// that trajectory: where it leaves a chaotic set for a periodic orbit or the non-impacting
/// motion, the running estimate falls with it, where the map's own iterates would stay on the
/// chaotic set. On the map's own iterates it is [`largest_exponent_with`]'s, bit for bit.
/// `each(k, estimate)` and the vanishing tangent as there.
///
/// # Errors
/// [`ParamError`]: an invalid point, a section of fewer than 3 or more than 100,001 points, the
/// tangent overflowing.
pub fn exponent_along_with<T: Real>(
    at: &MapPoint,
    section: &[Vector2<T>],
    each: impl FnMut(u32, f64),
) -> Result<Exponent, ParamError> {
    let periods = u32::try_from(section.len().saturating_sub(1)).unwrap_or(u32::MAX);
    check_count("periods", periods, 2, 100_000)?;
    let (e, _) = exponent_core(
        at,
        section[0],
        periods,
        |k, image| section.get(k as usize + 1).copied().unwrap_or(image),
        each,
    )?;
    Ok(e)
}

/// [`largest_exponent_with`] with the state after period `k` (0-based) given by
/// `next(k, image)` from the map's image of the state before it.
fn exponent_core<T: Real>(
    at: &MapPoint,
    x0: Vector2<T>,
    periods: u32,
    mut next: impl FnMut(u32, Vector2<T>) -> Vector2<T>,
    mut each: impl FnMut(u32, f64),
) -> Result<(Exponent, Vector2<T>), ParamError> {
    check_count("periods", periods, 2, 100_000)?;
    let table = PhaseTable::<Dual<T, 1>>::new(at.settings.steps.steps_per_period)?;
    let mut tangent = Tangent::new(at, &table)?;
    let mut x = x0;
    // The counted periods: from `start` on, `half` of them in the first half.
    let (mut start, mut half) = (0, periods / 2);
    let (mut sum1, mut sum2) = (0.0, 0.0);
    for k in 0..periods {
        let (image, stretch, _) = tangent.period(x)?;
        x = next(k, image);
        let Some(ln) = stretch else {
            (start, sum1, sum2) = (k + 1, 0.0, 0.0);
            half = (periods - start) / 2;
            each(k + 1, f64::NEG_INFINITY);
            continue;
        };
        if k - start < half {
            sum1 += ln;
        } else {
            sum2 += ln;
        }
        each(k + 1, (sum1 + sum2) / f64::from(k + 1 - start));
    }
    let counted = periods - start;
    if counted == 0 {
        return Ok((
            Exponent {
                per_period: f64::NEG_INFINITY,
                first_half: f64::NEG_INFINITY,
                second_half: f64::NEG_INFINITY,
                periods: 0,
                window_spread: None,
            },
            x,
        ));
    }
    let second = counted - half;
    Ok((
        Exponent {
            per_period: (sum1 + sum2) / f64::from(counted),
            // One period counted: no halves to compare, no uncertainty.
            first_half: if half > 0 {
                sum1 / f64::from(half)
            } else {
                f64::NAN
            },
            second_half: sum2 / f64::from(second),
            periods: counted,
            window_spread: None,
        },
        x,
    ))
}

/// The largest Lyapunov exponent of the periodic orbit of period `q` near `x0` (a state the
/// protocol settled on): `ln max|μ| / q` from the monodromy `DP^q` at `x0`, and again at
/// `P^q(x0)` (the two are the "halves": their difference is the uncertainty). Much cheaper than
/// [`largest_exponent`]'s window where the period is known; the same value on a periodic orbit.
///
/// # Errors
/// [`ParamError`]: an invalid point, `q` out of range.
pub fn orbit_exponent<T: Real>(
    at: &MapPoint,
    x0: Vector2<T>,
    q: u32,
) -> Result<(Exponent, Vector2<T>), ParamError> {
    let (a, ma) = super::map::tangent(at, q, x0)?;
    let (b, mb) = super::map::tangent(at, q, a.x)?;
    let rate =
        |m: &[[f64; 2]; 2]| libm::log(super::floquet::Floquet::of(m).max_abs()) / f64::from(q);
    let (first, second) = (rate(&ma), rate(&mb));
    Ok((
        Exponent {
            per_period: 0.5 * (first + second),
            first_half: first,
            second_half: second,
            periods: 2 * q,
            window_spread: None,
        },
        b.x,
    ))
}

//! What the Lyapunov exponent adds to a protocol's regime label. The canonical protocol calls a
//! point `irregular` when no period `q ≤ 16` showed within its window: that may be chaos, a
//! quasi-periodic motion, or a long transient onto a periodic orbit. With the exponent:
//!
//! - positive beyond its uncertainty ([`Exponent::clearly_positive`]): `chaotic`;
//! - negative beyond it: the run goes on (from where the protocol stopped, up to
//!   [`LabelSettings::max_periods`]) until a period `q ≤` [`LabelSettings::max_q`] repeats over
//!   three cycles, which becomes the label (`p/q`); if none shows, it stays `irregular`;
//! - otherwise (within its uncertainty of 0: quasi-periodic, or not converged): `irregular`.
//!
//! A periodic or no-impact label is kept; the exponent is reported beside it (the orbit's,
//! `ln max|μ| / q`, [`super::lyapunov::orbit_exponent`]).

use heapless::Vec;
use nalgebra::Vector2;

use super::lyapunov::{Exponent, Periods, largest_exponent, orbit_exponent};
use super::map::MapPoint;
use crate::error::{ParamError, check_count};
use crate::integrate::PhaseTable;
use crate::observe::poincare::StroboPoint;
use crate::observe::regime::classify;
use crate::observe::{PointResult, Regime};
use crate::real::Real;

/// Largest period the extended run recognises.
pub const MAX_EXTENDED_Q: u32 = 64;
/// Periods the extended run classifies over: three cycles of the largest period.
const SPAN: usize = 3 * MAX_EXTENDED_Q as usize;

/// How the exponent refines a label.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelSettings {
    /// Periods of the exponent's window (64).
    pub window: u32,
    /// Uncertainties beyond which the exponent's sign counts (3).
    pub sigmas: f64,
    /// Longest run after the protocol, periods, to find the period of an orbit with a negative
    /// exponent (2,000).
    pub max_periods: u32,
    /// Largest period recognised then (64, at most [`MAX_EXTENDED_Q`]).
    pub max_q: u32,
    /// Tolerance of the scaled Poincaré distance for a repeat (the protocol's `classify_tol`).
    pub classify_tol: f64,
}

impl Default for LabelSettings {
    fn default() -> Self {
        LabelSettings {
            window: 64,
            sigmas: 3.0,
            max_periods: 2000,
            max_q: MAX_EXTENDED_Q,
            classify_tol: 1e-3,
        }
    }
}

/// A refined label.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Label {
    /// The regime: the protocol's, or `chaotic`, or the period found by the extended run.
    pub regime: Regime,
    /// The protocol window's regime.
    pub window_regime: Regime,
    /// The largest Lyapunov exponent, per period, over the window after the protocol.
    pub exponent: Exponent,
    /// Periods run beyond the protocol and the exponent's window to find a period (0 if not
    /// needed).
    pub extra_periods: u32,
}

/// Refines `result` (the protocol's, at `at`, ending at state `x_end` on the section).
///
/// # Errors
/// [`ParamError`]: an invalid point or settings.
pub fn label<T: Real>(
    at: &MapPoint,
    result: &PointResult,
    x_end: Vector2<T>,
    s: &LabelSettings,
) -> Result<Label, ParamError> {
    check_count("max_q", s.max_q, 1, MAX_EXTENDED_Q)?;
    let (exponent, x) = match result.regime {
        // On the orbit the protocol settled on: its multipliers.
        Regime::Periodic { q, .. } => orbit_exponent(at, x_end, u32::from(q))?,
        Regime::NoImpact if result.settled => orbit_exponent(at, x_end, 1)?,
        _ => largest_exponent(at, x_end, s.window)?,
    };
    let mut out = Label {
        regime: result.regime,
        window_regime: result.regime,
        exponent,
        extra_periods: 0,
    };
    if result.regime != Regime::Irregular {
        return Ok(out);
    }
    if exponent.clearly_positive(s.sigmas) {
        out.regime = Regime::Chaotic;
    } else if exponent.clearly_negative(s.sigmas) {
        let (regime, periods) = extended_period(at, x, s)?;
        out.regime = regime;
        out.extra_periods = periods;
    }
    Ok(out)
}

/// Runs the map from `x` until a period `q ≤ s.max_q` repeats over the last three of its
/// cycles (checked every 16 periods) or `s.max_periods` have passed: the regime found
/// (`irregular` if none) and the periods run.
fn extended_period<T: Real>(
    at: &MapPoint,
    x: Vector2<T>,
    s: &LabelSettings,
) -> Result<(Regime, u32), ParamError> {
    let table = PhaseTable::<T>::new(at.settings.steps.steps_per_period)?;
    let mut run = Periods::new(at, &table)?;
    let u_scale = T::from_f64(at.params.amplitude_m);
    let v_scale = T::from_f64(at.params.amplitude_m * at.omega_ratio * at.params.omega_n());
    let tol = T::from_f64(s.classify_tol);
    let span = (3 * s.max_q as usize).min(SPAN);
    let mut section: Vec<StroboPoint<T>, SPAN> = Vec::new();
    let mut impacts: Vec<u16, SPAN> = Vec::new();
    let mut x = x;
    for k in 1..=s.max_periods {
        let (y, trace) = run.run(x);
        x = y;
        if section.len() == span {
            section.remove(0);
            impacts.remove(0);
        }
        let (u, du) = run.relative();
        let _ = section.push(StroboPoint { u, du });
        let _ = impacts.push(u16::try_from(trace.impacts).unwrap_or(u16::MAX));
        if section.len() == span && k % 16 == 0 {
            let r = classify(&section, &impacts, s.max_q as usize, tol, u_scale, v_scale);
            if r != Regime::Irregular {
                return Ok((r, k));
            }
        }
    }
    Ok((Regime::Irregular, s.max_periods))
}

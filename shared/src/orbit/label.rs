//! What the Lyapunov exponent adds to a protocol's regime label. The canonical protocol calls a
//! point `irregular` when no period `q ≤ 16` showed within its window: that may be chaos, a
//! quasi-periodic motion, or a long transient onto a periodic orbit (or onto the non-impacting
//! motion). The exponent over a first window of [`LabelSettings::window`] periods after the
//! protocol sorts them:
//!
//! - negative beyond its uncertainty ([`Exponent::clearly_negative`]): the run goes on (from
//!   where the window stopped, up to [`LabelSettings::max_periods`]) until a period
//!   `q ≤` [`LabelSettings::max_q`] repeats over three cycles, which becomes the label (`p/q`);
//!   if none shows, it stays `irregular`;
//! - otherwise (positive, or within its uncertainty of 0) a **confirmation run** follows: up to
//!   [`LabelSettings::confirm_periods`] more periods, the tangent carried all along and the
//!   exponent measured over independent windows of `window` periods. A motion that settles
//!   within it (a period `q ≤ max_q` repeating over three cycles, or no impact over as many
//!   periods) is labelled by what it settles on, its exponent that attractor's, and where the
//!   first window's exponent was positive the chaotic transient's length is kept
//!   ([`Label::chaotic_transient_periods`]). A motion that does not settle is `chaotic` where the
//!   windows' mean is positive beyond `sigmas` standard errors ([`Exponent::window_spread`]),
//!   else `irregular` (the exponent and its spread reported): never `chaotic` on the first
//!   window alone.
//!
//! A periodic or no-impact label is kept; the exponent is reported beside it (the orbit's,
//! `ln max|μ| / q`, [`super::lyapunov::orbit_exponent`]).

use heapless::Vec;
use nalgebra::Vector2;

use super::lyapunov::{Exponent, Periods, Tangent, largest_exponent, orbit_exponent};
use super::map::MapPoint;
use crate::dual::Dual;
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
/// Most windows a confirmation run measures.
pub const MAX_CONFIRM_WINDOWS: usize = 256;

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
    /// Longest confirmation run of a window whose exponent is not clearly negative, periods
    /// (2,048: 32 windows of 64); whole windows of `window` periods are run, 2 ..=
    /// [`MAX_CONFIRM_WINDOWS`] of them.
    pub confirm_periods: u32,
}

impl Default for LabelSettings {
    fn default() -> Self {
        LabelSettings {
            window: 64,
            sigmas: 3.0,
            max_periods: 2000,
            max_q: MAX_EXTENDED_Q,
            classify_tol: 1e-3,
            confirm_periods: 2048,
        }
    }
}

/// A refined label.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Label {
    /// The regime: the protocol's, or what the extended or confirmation run found (a period,
    /// no impact, `chaotic`, or still `irregular`).
    pub regime: Regime,
    /// The protocol window's regime.
    pub window_regime: Regime,
    /// The largest Lyapunov exponent, per period: of the orbit the protocol or the
    /// confirmation run settled on (its multipliers'), or over the first window after the
    /// protocol (a negative one, whatever its extended run found), or over the confirmation
    /// run's windows (`chaotic`, or `irregular` after it).
    pub exponent: Exponent,
    /// Periods run beyond the protocol and the exponent's first window: by the extended run
    /// to find a period, or by the confirmation run (0 if neither ran).
    pub extra_periods: u32,
    /// Where the first window's exponent was clearly positive and the motion then settled (on a
    /// periodic orbit, or the non-impacting motion): the periods after the protocol before the
    /// span over which it repeats, an upper bound on the chaotic transient's length after the
    /// protocol (within 16 periods). `None` otherwise.
    pub chaotic_transient_periods: Option<u32>,
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
        chaotic_transient_periods: None,
    };
    if result.regime != Regime::Irregular {
        return Ok(out);
    }
    if exponent.clearly_negative(s.sigmas) {
        let (regime, periods) = extended_period(at, x, s)?;
        out.regime = regime;
        out.extra_periods = periods;
        return Ok(out);
    }
    match confirm(at, x, s)? {
        Confirmed::Settled {
            regime,
            x_end,
            periods,
            repeats_from,
        } => {
            out.regime = regime;
            out.extra_periods = periods;
            out.exponent = match regime {
                Regime::Periodic { q, .. } => orbit_exponent(at, x_end, u32::from(q))?.0,
                _ => largest_exponent(at, x_end, s.window)?.0,
            };
            if exponent.clearly_positive(s.sigmas) {
                out.chaotic_transient_periods = Some(s.window + repeats_from);
            }
        }
        Confirmed::Unsettled { exponent, periods } => {
            out.extra_periods = periods;
            out.exponent = exponent;
            if exponent.clearly_positive(s.sigmas) {
                out.regime = Regime::Chaotic;
            }
        }
    }
    Ok(out)
}

/// The Poincaré points and impact counts of the last `3 max_q` periods of a run, classified as
/// the protocol classifies its window.
struct Recogniser<T: Real> {
    section: Vec<StroboPoint<T>, SPAN>,
    impacts: Vec<u16, SPAN>,
    span: usize,
    max_q: usize,
    tol: T,
    u_scale: T,
    v_scale: T,
}

impl<T: Real> Recogniser<T> {
    fn new(at: &MapPoint, s: &LabelSettings) -> Self {
        Recogniser {
            section: Vec::new(),
            impacts: Vec::new(),
            span: (3 * s.max_q as usize).min(SPAN),
            max_q: s.max_q as usize,
            tol: T::from_f64(s.classify_tol),
            u_scale: T::from_f64(at.params.amplitude_m),
            v_scale: T::from_f64(at.params.amplitude_m * at.omega_ratio * at.params.omega_n()),
        }
    }

    /// Adds period `k`'s point `(u, u̇)` and impacts; every 16 periods once the span is full,
    /// the regime it shows (`None` while `irregular`).
    fn push(&mut self, k: u32, (u, du): (T, T), impacts: u32) -> Option<Regime> {
        if self.section.len() == self.span {
            self.section.remove(0);
            self.impacts.remove(0);
        }
        let _ = self.section.push(StroboPoint { u, du });
        let _ = self
            .impacts
            .push(u16::try_from(impacts).unwrap_or(u16::MAX));
        if self.section.len() < self.span || !k.is_multiple_of(16) {
            return None;
        }
        let r = classify(
            &self.section,
            &self.impacts,
            self.max_q,
            self.tol,
            self.u_scale,
            self.v_scale,
        );
        (r != Regime::Irregular).then_some(r)
    }
}

/// What a confirmation run found.
enum Confirmed<T: Real> {
    /// It settled on `regime`, ending in `x_end` after `periods`, the regime repeating over
    /// the periods after `repeats_from` (of the run).
    Settled {
        regime: Regime,
        x_end: Vector2<T>,
        periods: u32,
        repeats_from: u32,
    },
    /// No regime showed over its `periods`: the exponent over its whole windows since the
    /// tangent last vanished (the mean, its halves, and the windows' standard error).
    Unsettled { exponent: Exponent, periods: u32 },
}

/// Runs the map from `x` with its tangent for up to `s.confirm_periods` (whole windows of
/// `s.window`), looking for a period as [`extended_period`] does, and measures the exponent
/// over each window: their mean and its standard error. A vanishing tangent (a rest on the
/// surface) discards the windows before it, as [`largest_exponent`] does.
fn confirm<T: Real>(
    at: &MapPoint,
    x: Vector2<T>,
    s: &LabelSettings,
) -> Result<Confirmed<T>, ParamError> {
    check_count("window", s.window, 2, 100_000)?;
    let total_windows = s.confirm_periods / s.window;
    check_count(
        "confirm_periods / window",
        total_windows,
        2,
        MAX_CONFIRM_WINDOWS as u32,
    )?;
    let table = PhaseTable::<Dual<T, 1>>::new(at.settings.steps.steps_per_period)?;
    let mut tangent = Tangent::new(at, &table)?;
    let mut seen = Recogniser::<T>::new(at, s);
    // Per window: the sum of the logs of the stretches; the windows completed.
    let (mut sum, mut in_window) = (0.0, 0);
    let mut windows: Vec<f64, MAX_CONFIRM_WINDOWS> = Vec::new();
    let mut x = x;
    let total = total_windows * s.window;
    for k in 1..=total {
        let (image, stretch, trace) = tangent.period(x)?;
        x = image;
        if let Some(regime) = seen.push(k, tangent.relative(), trace.impacts) {
            return Ok(Confirmed::Settled {
                regime,
                x_end: x,
                periods: k,
                repeats_from: k.saturating_sub(seen.span as u32),
            });
        }
        match stretch {
            Some(ln) => {
                sum += ln;
                in_window += 1;
                if in_window == s.window {
                    let _ = windows.push(sum / f64::from(s.window));
                    (sum, in_window) = (0.0, 0);
                }
            }
            None => {
                windows.clear();
                (sum, in_window) = (0.0, 0);
            }
        }
    }
    Ok(Confirmed::Unsettled {
        exponent: window_mean(&windows, s.window),
        periods: total,
    })
}

/// The exponent of `windows` (each the mean stretch over `window` periods): their mean, the
/// means of their halves, and the standard error of the mean (∞ with one window: undecided;
/// −∞ with none: the tangent vanished in the last window).
fn window_mean(windows: &[f64], window: u32) -> Exponent {
    let n = windows.len();
    let mean = |w: &[f64]| {
        if w.is_empty() {
            f64::NAN
        } else {
            w.iter().sum::<f64>() / w.len() as f64
        }
    };
    if n == 0 {
        return Exponent {
            per_period: f64::NEG_INFINITY,
            first_half: f64::NEG_INFINITY,
            second_half: f64::NEG_INFINITY,
            periods: 0,
            window_spread: None,
        };
    }
    let m = mean(windows);
    // One window has no spread to judge it by: never clearly signed.
    let spread = if n < 2 {
        f64::INFINITY
    } else {
        let var = windows.iter().map(|w| (w - m) * (w - m)).sum::<f64>() / (n - 1) as f64;
        libm::sqrt(var / n as f64)
    };
    Exponent {
        per_period: m,
        first_half: mean(&windows[..n / 2]),
        second_half: mean(&windows[n / 2..]),
        periods: u32::try_from(n).unwrap_or(u32::MAX) * window,
        window_spread: Some(spread),
    }
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
    let mut seen = Recogniser::<T>::new(at, s);
    let mut x = x;
    for k in 1..=s.max_periods {
        let (y, trace) = run.run(x);
        x = y;
        if let Some(r) = seen.push(k, run.relative(), trace.impacts) {
            return Ok((r, k));
        }
    }
    Ok((Regime::Irregular, s.max_periods))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_give_their_mean_and_its_standard_error() {
        // Four windows: mean 0.25, sample variance ((−0.15)² + (−0.05)² + 0.05² + 0.15²)/3 =
        // 0.05/3, standard error √(0.05/3/4) = 0.0645497.
        let e = window_mean(&[0.1, 0.2, 0.3, 0.4], 64);
        assert!((e.per_period - 0.25).abs() < 1e-15);
        assert!((e.uncertainty() - (0.05f64 / 12.0).sqrt()).abs() < 1e-15);
        assert!((e.first_half - 0.15).abs() < 1e-15 && (e.second_half - 0.35).abs() < 1e-15);
        assert_eq!(e.periods, 256);
        assert!(e.clearly_positive(3.0));
        // Positive, but within three standard errors of 0: undecided.
        let e = window_mean(&[0.3, -0.1, 0.25, -0.05], 64);
        assert!(!e.clearly_positive(3.0) && !e.clearly_negative(3.0));
        // One window: no spread, never signed; none: the tangent vanished last.
        let one = window_mean(&[0.5], 64);
        assert!(!one.clearly_positive(3.0) && !one.clearly_negative(3.0));
        let none = window_mean(&[], 64);
        assert_eq!(none.per_period, f64::NEG_INFINITY);
        assert!(!none.clearly_positive(3.0));
    }
}

//! Two-parameter continuation of a codimension-one bifurcation in the (`Ω/ω`, gap) plane: the
//! curves that bound a regime's region in the Peterka map, computed rather than sampled
//! (Kuznetsov, *Elements of Applied Bifurcation Theory*, 2004, ch. 10; Dankowicz & Schilder,
//! *Recipes for Continuation*, 2013, ch. 10).
//!
//! The curve is the zero set of the event's test function `g` over the plane
//! `p = (Ω/ω, gap/A0)`, the orbit at each `p` found by Newton's method (shooting): `det(M − I)`
//! (fold), `det(M + I)` (period doubling), `det M − 1` (Neimark–Sacker), the free flight's
//! closest approach `δ_max/A0` (grazing, an impact appears) or `−(v/(A0 Ω))²` (grazing, one
//! vanishes). The monodromy `M` of the fixed-step map is piecewise smooth in the parameters (a
//! sub-step boundary crossing an event changes it by about 1e-4), so `g` is located by
//! bracketing rather than by Newton's method on `g`: each step predicts along the tangent and
//! finds `g`'s zero on the line across it. The curve ends where it leaves the parameter box,
//! where the orbit's impact count changes (a codimension-two point: the curve meets a grazing),
//! or where the step falls below its minimum.

use core::fmt;
use core::ops::ControlFlow;

use nalgebra::Vector2;

use super::continuation::{BifEvent, ContinuationSettings, EventKind, StepSizes, continue_branch};
use super::floquet::Floquet;
use super::map::{MapPoint, Param, Trace};
use super::shooting::{Orbit, ShootSettings, shoot};
use crate::real::Real;

/// How a curve is continued.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurveSettings {
    /// The `Ω/ω` range; the curve ends where it leaves it.
    pub omega_ratio: [f64; 2],
    /// The gap range, m.
    pub gap_m: [f64; 2],
    /// Step sizes in the scaled unknowns; below the smallest the curve ends.
    pub steps: StepSizes,
    /// Points at most (2,000).
    pub max_points: u32,
    /// Newton's tolerance and iterations (the test function's residual is held to the same
    /// tolerance).
    pub newton: ShootSettings,
}

impl CurveSettings {
    /// The defaults in the float type `T` over the box `omega_ratio` × `gap_m` (m).
    pub fn new<T: Real>(omega_ratio: [f64; 2], gap_m: [f64; 2]) -> Self {
        CurveSettings {
            omega_ratio,
            gap_m,
            steps: StepSizes::for_type::<T>(),
            max_points: 2000,
            newton: ShootSettings::for_type::<T>(),
        }
    }

    /// Whether `(omega_ratio, gap_m)` lies in the box.
    pub fn contains(&self, omega_ratio: f64, gap_m: f64) -> bool {
        (self.omega_ratio[0]..=self.omega_ratio[1]).contains(&omega_ratio)
            && (self.gap_m[0]..=self.gap_m[1]).contains(&gap_m)
    }
}

/// A point of a curve: the orbit at the bifurcation there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurvePoint<T> {
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Gap, m.
    pub gap_m: f64,
    /// The orbit.
    pub orbit: Orbit<T>,
}

/// Why a curve ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CurveEnd {
    /// It left the box (at the last point inside: `Ω/ω`, gap m).
    Box(f64, f64),
    /// The orbit's impact count changed beyond the last point (a codimension-two point).
    ImpactsChanged(f64, f64),
    /// The step fell below the minimum.
    StepTooSmall(f64, f64),
    /// The point budget was spent.
    MaxPoints(f64, f64),
    /// The caller stopped it.
    Stopped(f64, f64),
    /// The event has no test function to continue (none here) or the start did not converge.
    NoStart,
}

impl fmt::Display for CurveEnd {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let at = |f: &mut fmt::Formatter<'_>, what: &str, r: f64, g: f64| {
            write!(f, "{what} at Ω/ω {r:.6}, gap {:.4} mm", g * 1e3)
        };
        match *self {
            CurveEnd::Box(r, g) => at(f, "the edge of the box", r, g),
            CurveEnd::ImpactsChanged(r, g) => at(f, "a change of the impact count", r, g),
            CurveEnd::StepTooSmall(r, g) => at(f, "a step below the minimum", r, g),
            CurveEnd::MaxPoints(r, g) => at(f, "the point budget", r, g),
            CurveEnd::Stopped(r, g) => at(f, "the caller's stop", r, g),
            CurveEnd::NoStart => {
                f.write_str("no start (the event did not converge as a curve point)")
            }
        }
    }
}

/// The test function of `kind` at an orbit (its trace and monodromy); `appears` selects the
/// grazing monitor.
fn test_value(kind: EventKind, appears: bool, at: &MapPoint, trace: &Trace, f: &Floquet) -> f64 {
    match kind {
        EventKind::Fold => f.fold_test(),
        EventKind::PeriodDoubling => f.doubling_test(),
        EventKind::NeimarkSacker => f.torus_test(),
        EventKind::Grazing => {
            let a0 = at.params.amplitude_m;
            if appears {
                trace.closest_free_m / a0
            } else {
                let v = trace.slowest_arrival_m_s / (a0 * at.omega_ratio * at.params.omega_n());
                -v * v
            }
        }
    }
}

/// The curve's frame: the orbit family, its test function and the scaled parameter plane
/// `p = (Ω/ω, gap/A0)`.
struct Frame {
    base: MapPoint,
    q: u32,
    a0: f64,
    kind: EventKind,
    appears: bool,
    /// The orbit family's impacts per period `q`.
    impacts: u32,
    newton: ShootSettings,
}

impl Frame {
    fn point(&self, p: [f64; 2]) -> MapPoint {
        let mut m = self.base;
        m.omega_ratio = p[0];
        m.gap_m = p[1] * self.a0;
        m
    }

    /// The orbit at `p` (Newton from `x`) and its test function there. For a grazing, where
    /// the family's orbit does not exist (Newton fails, or finds one with another impact
    /// count) the test function's sign is all that is known: `+1` and no orbit.
    fn orbit<T: Real>(&self, p: [f64; 2], x: Vector2<T>) -> Option<(Option<Orbit<T>>, f64)> {
        if p[1].is_nan() || p[1] < 0.0 {
            return None;
        }
        let at = self.point(p);
        let grazing = self.kind == EventKind::Grazing;
        match shoot(&at, self.q, x, &self.newton) {
            Ok(o) if grazing && o.trace.impacts != self.impacts => Some((None, 1.0)),
            Ok(o) => {
                let g = test_value(self.kind, self.appears, &at, &o.trace, &o.floquet);
                g.is_finite().then_some((Some(o), g))
            }
            Err(_) if grazing => Some((None, 1.0)),
            Err(_) => None,
        }
    }
}

/// The zero of `g` along `p + s n`, `|s| ≤ reach`, nearest `s = 0`: a bracket grown from
/// `±reach/8`, then Illinois steps to `tol` (each evaluation an orbit found by Newton, so the
/// test function's discretisation kinks, about 1e-4, cannot stall it).
fn zero_along<T: Real>(
    fr: &Frame,
    p: [f64; 2],
    n: [f64; 2],
    reach: f64,
    tol: f64,
    x: Vector2<T>,
) -> Option<([f64; 2], Orbit<T>)> {
    let at = |s: f64| [p[0] + s * n[0], p[1] + s * n[1]];
    let (o0, g0) = fr.orbit::<T>(p, x)?;
    let x0 = o0.as_ref().map_or(x, |o| o.x);
    if g0 == 0.0 {
        return o0.map(|o| (p, o));
    }
    // Grow a bracket on both sides.
    let mut lo = (0.0, g0, o0);
    let mut hi = None;
    let mut d = reach / 8.0;
    while d <= reach * 1.0001 && hi.is_none() {
        for s in [d, -d] {
            if let Some((o, g)) = fr.orbit::<T>(at(s), x0)
                && (g > 0.0) != (g0 > 0.0)
            {
                hi = Some((s, g, o));
                break;
            }
        }
        d *= 2.0;
    }
    let mut hi = hi?;
    let mut side = 0i8;
    for _ in 0..60 {
        if (hi.0 - lo.0).abs() <= tol {
            break;
        }
        let mut s = (lo.0 * hi.1 - hi.0 * lo.1) / (hi.1 - lo.1);
        let w = (hi.0 - lo.0).abs();
        if !(s.is_finite() && (s - lo.0).abs() > 1e-3 * w && (s - hi.0).abs() > 1e-3 * w) {
            s = 0.5 * (lo.0 + hi.0);
        }
        let start = lo.2.as_ref().or(hi.2.as_ref()).map_or(x0, |o| o.x);
        let (o, g) = fr.orbit::<T>(at(s), start)?;
        if (g > 0.0) == (lo.1 > 0.0) {
            lo = (s, g, o);
            if side == -1 {
                hi.1 *= 0.5;
            }
            side = -1;
        } else {
            hi = (s, g, o);
            if side == 1 {
                lo.1 *= 0.5;
            }
            side = 1;
        }
    }
    // The end nearer the zero among those with the family's orbit.
    let best = match (&lo.2, &hi.2) {
        (Some(_), None) => lo,
        (None, Some(_)) => hi,
        _ if lo.1.abs() <= hi.1.abs() => lo,
        _ => hi,
    };
    best.2.map(|o| (at(best.0), o))
}

/// Continues the bifurcation `event` (located along a branch in `param`) as a curve in the
/// (`Ω/ω`, gap) plane, towards increasing gap if `direction > 0` (else decreasing). Each point
/// goes to `on_point` (the start first); [`ControlFlow::Break`] ends the curve there.
///
/// Each step predicts along the curve's tangent in the plane `(Ω/ω, gap/A0)` and finds the test
/// function's zero across it (a bracketing search perpendicular to the tangent), the orbit at
/// every trial found by Newton's method: the curve is located to 1e-6 in the plane (f64; f32
/// 1e-4), across the test function's discretisation kinks. A fold, which no line across it
/// brackets, is marched in the other parameter and located on the branch at each step.
pub fn continue_curve<T: Real>(
    event: &BifEvent<T>,
    param: Param,
    settings: &CurveSettings,
    direction: f64,
    mut on_point: impl FnMut(&CurvePoint<T>) -> ControlFlow<()>,
) -> CurveEnd {
    if event.kind == EventKind::Fold {
        return fold_curve(event, param, settings, direction, on_point);
    }
    let o = &event.orbit;
    let mut base = o.at;
    match param {
        Param::OmegaRatio => base.omega_ratio = event.value,
        Param::GapM => base.gap_m = event.value,
    }
    let a0 = base.params.amplitude_m;
    let fr = Frame {
        base,
        q: o.q,
        a0,
        kind: event.kind,
        appears: event.impacts_beyond > o.trace.impacts,
        impacts: o.trace.impacts,
        newton: settings.newton,
    };
    let f64_like = T::EPSILON < 1e-10;
    let tol = if f64_like { 1e-7 } else { 1e-5 };
    // From the orbit itself (a grazing's value lies just beyond it, where the family's orbit
    // may not exist).
    let p0 = [o.at.omega_ratio, o.at.gap_m / a0];
    // The start, on the zero across the branch's parameter.
    let across = match param {
        Param::OmegaRatio => [1.0, 0.0],
        Param::GapM => [0.0, 1.0],
    };
    let Some((mut p, mut orbit)) = zero_along::<T>(&fr, p0, across, 1e-3, tol, o.x) else {
        return CurveEnd::NoStart;
    };
    let impacts = orbit.trace.impacts;
    // The tangent ⟂ the test function's gradient in the plane (differences of 1e-3: wider than
    // its kinks); one-sided at the gap's lower bound.
    let eps = 1e-3;
    let grad = |k: usize, orbit: &Orbit<T>| -> Option<f64> {
        let mut up = p;
        let mut dn = p;
        up[k] += eps;
        dn[k] -= eps;
        // Central where both sides hold the family's orbit, else one-sided.
        let side = |q: [f64; 2]| match fr.orbit::<T>(q, orbit.x) {
            Some((Some(o), g)) if o.trace.impacts == fr.impacts => Some(g),
            _ => None,
        };
        let g0 = side(p)?;
        match (side(up), if dn[1] >= 0.0 { side(dn) } else { None }) {
            (Some(gu), Some(gd)) => Some((gu - gd) / (2.0 * eps)),
            (Some(gu), None) => Some((gu - g0) / eps),
            (None, Some(gd)) => Some((g0 - gd) / eps),
            (None, None) => None,
        }
    };
    let (Some(gr), Some(gg)) = (grad(0, &orbit), grad(1, &orbit)) else {
        return CurveEnd::NoStart;
    };
    let norm = libm::hypot(gr, gg);
    if norm.is_nan() || norm <= 0.0 {
        return CurveEnd::NoStart;
    }
    let mut t = [-gg / norm, gr / norm];
    if t[1] * direction < 0.0 || (t[1] == 0.0 && t[0] * direction < 0.0) {
        t = [-t[0], -t[1]];
    }
    let emit = |p: [f64; 2], orbit: &Orbit<T>| CurvePoint {
        omega_ratio: p[0],
        gap_m: p[1] * a0,
        orbit: *orbit,
    };
    if on_point(&emit(p, &orbit)).is_break() {
        return CurveEnd::Stopped(p[0], p[1] * a0);
    }
    let inside = |q: [f64; 2]| settings.contains(q[0], q[1] * a0);
    let mut h = settings.steps.first;
    for _ in 0..settings.max_points {
        let next = loop {
            if settings.steps.below_min(h) {
                return CurveEnd::StepTooSmall(p[0], p[1] * a0);
            }
            let pred = [p[0] + h * t[0], p[1] + h * t[1]];
            if !inside(pred) && pred[1] < 0.0 {
                // Below gap 0: the box's edge.
                return CurveEnd::Box(p[0], p[1] * a0);
            }
            match zero_along::<T>(&fr, pred, [-t[1], t[0]], h, tol, orbit.x) {
                Some((q, on)) => {
                    let d = [q[0] - p[0], q[1] - p[1]];
                    let len = libm::hypot(d[0], d[1]);
                    let tn = [d[0] / len, d[1] / len];
                    if len.is_nan() || len <= 0.0 || tn[0] * t[0] + tn[1] * t[1] < 0.8 {
                        h *= 0.5;
                        continue;
                    }
                    break (q, on, tn);
                }
                None => h *= 0.5,
            }
        };
        let (q, on, tn) = next;
        if !inside(q) {
            return CurveEnd::Box(p[0], p[1] * a0);
        }
        if on.trace.impacts != impacts {
            return CurveEnd::ImpactsChanged(p[0], p[1] * a0);
        }
        (p, orbit, t) = (q, on, tn);
        if on_point(&emit(p, &orbit)).is_break() {
            return CurveEnd::Stopped(p[0], p[1] * a0);
        }
        h = (h * 1.3).min(settings.steps.max);
    }
    CurveEnd::MaxPoints(p[0], p[1] * a0)
}

/// A fold's curve. Across a fold the family's orbit exists on one side only (two of them,
/// stable and unstable, whose test functions have opposite signs), so no bracket spans it:
/// the curve is marched in the other parameter instead, and at each of its values the fold is
/// located on the branch itself — continued from an orbit a little inside the fold
/// (Newton from the last fold's state) until its fold test changes sign.
fn fold_curve<T: Real>(
    event: &BifEvent<T>,
    param: Param,
    settings: &CurveSettings,
    direction: f64,
    mut on_point: impl FnMut(&CurvePoint<T>) -> ControlFlow<()>,
) -> CurveEnd {
    let o = &event.orbit;
    let a0 = o.at.params.amplitude_m;
    // (branch parameter, marched parameter) in the scaled plane (Ω/ω, gap/A0).
    let (mut lam, mut mu) = match param {
        Param::OmegaRatio => (event.value, o.at.gap_m / a0),
        Param::GapM => (event.value / a0, o.at.omega_ratio),
    };
    let point = |lam: f64, mu: f64| {
        let mut at = o.at;
        match param {
            Param::OmegaRatio => {
                at.omega_ratio = lam;
                at.gap_m = mu * a0;
            }
            Param::GapM => {
                at.gap_m = lam * a0;
                at.omega_ratio = mu;
            }
        }
        at
    };
    let plane = |lam: f64, mu: f64| match param {
        Param::OmegaRatio => (lam, mu * a0),
        Param::GapM => (mu, lam * a0),
    };
    let inside = |lam: f64, mu: f64| {
        let (r, g) = plane(lam, mu);
        settings.contains(r, g)
    };
    let emit = |lam: f64, mu: f64, orbit: &Orbit<T>| {
        let (omega_ratio, gap_m) = plane(lam, mu);
        CurvePoint {
            omega_ratio,
            gap_m,
            orbit: *orbit,
        }
    };
    // An orbit of the family (stable or unstable: both lead to the fold) near `x`.
    let family_at = |lam: f64, mu: f64, x: Vector2<T>| {
        shoot(&point(lam, mu), o.q, x, &settings.newton)
            .ok()
            .filter(|s| s.trace.impacts == o.trace.impacts)
    };
    // The side of the fold where the family's orbits lie.
    let Some(side) = [0.003, 0.01, 0.03].into_iter().find_map(|back| {
        [-1.0, 1.0]
            .into_iter()
            .find(|&sd| family_at(lam + sd * back, mu, o.x).is_some())
    }) else {
        return CurveEnd::NoStart;
    };
    let mut x = o.x;
    if on_point(&emit(lam, mu, o)).is_break() {
        let (r, g) = plane(lam, mu);
        return CurveEnd::Stopped(r, g);
    }
    let lam_range = match param {
        Param::OmegaRatio => settings.omega_ratio,
        Param::GapM => [settings.gap_m[0] / a0, settings.gap_m[1] / a0],
    };
    let mut h = settings.steps.first;
    for _ in 0..settings.max_points {
        let (r, g) = plane(lam, mu);
        if settings.steps.below_min(h) {
            return CurveEnd::StepTooSmall(r, g);
        }
        let mu_next = mu + direction * h;
        if !inside(lam, mu_next) {
            return CurveEnd::Box(r, g);
        }
        // The stable orbit inside the fold, then the branch towards it.
        let found = [0.01, 0.04, 0.16].into_iter().find_map(|back| {
            let start = family_at(lam + side * back, mu_next, x)?;
            let reach = 4.0 * back + 8.0 * h;
            let mut cs = ContinuationSettings::new::<T>(
                param,
                match param {
                    Param::OmegaRatio => [
                        (lam - reach).max(lam_range[0]),
                        (lam + reach).min(lam_range[1]),
                    ],
                    Param::GapM => [
                        (lam - reach).max(lam_range[0]) * a0,
                        (lam + reach).min(lam_range[1]) * a0,
                    ],
                },
            );
            cs.max_points = 400;
            cs.steps.first = cs.steps.first.min(back);
            let mut fold = None;
            continue_branch(
                &start,
                &cs,
                -side,
                None,
                |_| {},
                |ev| {
                    if ev.kind == EventKind::Fold {
                        fold = Some(*ev);
                        ControlFlow::Break(())
                    } else {
                        ControlFlow::Continue(())
                    }
                },
            );
            fold
        });
        let Some(fold) = found else {
            h *= 0.5;
            continue;
        };
        let lam_next = match param {
            Param::OmegaRatio => fold.value,
            Param::GapM => fold.value / a0,
        };
        if fold.orbit.trace.impacts != o.trace.impacts {
            return CurveEnd::ImpactsChanged(r, g);
        }
        (lam, mu, x) = (lam_next, mu_next, fold.orbit.x);
        if on_point(&emit(lam, mu, &fold.orbit)).is_break() {
            let (r, g) = plane(lam, mu);
            return CurveEnd::Stopped(r, g);
        }
        h = (h * 1.5).min(settings.steps.max);
    }
    let (r, g) = plane(lam, mu);
    CurveEnd::MaxPoints(r, g)
}

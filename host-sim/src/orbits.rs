//! Periodic orbits on the desktop: found from a protocol run, continued in `Ω/ω` or the gap
//! (both directions, branch switching at period doublings), as reports and CSV rows. The
//! computations are `shared::orbit`'s; this module picks the float type, collects the branches
//! and converts to the units of the reports (mm, Hz).

use std::ops::ControlFlow;

use anyhow::{Result, anyhow};
use clap::ValueEnum;
use serde::Serialize;
use shared::Real;
use shared::observe::Regime;
use shared::orbit::{
    BifEvent, BranchEnd, BranchPoint, ContinuationSettings, EventKind, MIN_TURN_COSINE, MapPoint,
    Multiplier, Orbit, OrbitError, Param, ShootSettings, Stability, continue_branch,
    doubling_start, iterate, orbit_from, relative, shoot, state_of,
};

use crate::config::Setup;
use crate::interrupt;
use crate::progress::progress;
use crate::runner::WindowSamples;

/// Where an orbit search starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Start {
    /// At rest at phase 0.
    Rest,
    /// From a relative displacement `u` (m) and velocity `u̇` (m/s) at phase 0.
    Relative {
        /// `u`, m.
        u_m: f64,
        /// `u̇`, m/s.
        du_m_s: f64,
    },
}

/// A periodic orbit as the host reports it (mm, mm/s, Hz).
#[derive(Debug, Clone, Serialize)]
pub struct OrbitReport {
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Excitation frequency, Hz.
    pub freq_hz: f64,
    /// Gap, mm.
    pub gap_mm: f64,
    /// `p/q`, or `no impact`.
    pub regime: String,
    /// Impacts per period `q`.
    pub p: u32,
    /// Period, excitation periods.
    pub q: u32,
    /// The orbit's `q` points on the Poincaré section, `(u mm, u̇ mm/s)`, from the state found.
    pub section: Vec<[f64; 2]>,
    /// Largest impact force, `F_i/mg`.
    pub impact_force_mg: f64,
    /// The Floquet multipliers `(re, im)`, the larger modulus first.
    pub multipliers: [[f64; 2]; 2],
    /// `max |μ|`.
    pub max_abs_multiplier: f64,
    /// Asymptotically stable: `max |μ| < 1`, and not a neutral orbit.
    pub stable: bool,
    /// `stable`, `neutral` (a conservative orbit's pair on the unit circle: no impact on an
    /// undamped suspension, [`Orbit::stability`]) or `unstable`.
    #[serde(serialize_with = "stability_name")]
    pub stability: Stability,
    /// Stability margin `1 − max |μ|`.
    pub margin: f64,
    /// Its largest Lyapunov exponent, per excitation period: `ln max|μ| / q`.
    pub lyapunov_per_period: f64,
    /// Newton's scaled residual at convergence (a fraction of the cart's amplitude).
    pub residual: f64,
    /// Newton iterations.
    pub iterations: u32,
}

impl OrbitReport {
    /// Its regime (`no impact` for `p = 0`).
    pub fn regime(&self) -> Regime {
        regime_of(self.p, self.q)
    }
}

/// The regime `p/q` (`no impact` for `p = 0`).
fn regime_of(p: u32, q: u32) -> Regime {
    if p == 0 {
        Regime::NoImpact
    } else {
        Regime::Periodic {
            p: u16::try_from(p).unwrap_or(u16::MAX),
            q: u16::try_from(q).unwrap_or(u16::MAX),
        }
    }
}

fn mu_pair(m: &[Multiplier; 2]) -> [[f64; 2]; 2] {
    [[m[0].re, m[0].im], [m[1].re, m[1].im]]
}

/// The `q` points of `o` on the section, `(u mm, u̇ mm/s)`.
fn section_points<T: Real>(o: &Orbit<T>) -> Result<Vec<[f64; 2]>> {
    let mut x = o.x;
    let mut out = Vec::with_capacity(o.q as usize);
    for k in 0..o.q {
        let (u, du) = relative(&o.at, &x)?;
        out.push([u * 1e3, du * 1e3]);
        if k + 1 < o.q {
            x = iterate(&o.at, 1, x)?.x;
        }
    }
    Ok(out)
}

/// The report of `o`.
///
/// # Errors
/// The map cannot be evaluated along it (not for a converged orbit).
pub fn report<T: Real>(o: &Orbit<T>) -> Result<OrbitReport> {
    let f = &o.floquet;
    let stability = o.stability();
    Ok(OrbitReport {
        omega_ratio: o.at.omega_ratio,
        freq_hz: o.at.params.freq_hz_from_ratio(o.at.omega_ratio),
        gap_mm: mm(o.at.gap_m),
        regime: regime_of(o.p(), o.q).to_string(),
        p: o.p(),
        q: o.q,
        section: section_points(o)?,
        impact_force_mg: o.impact_force_mg(),
        multipliers: mu_pair(&f.mu),
        max_abs_multiplier: f.max_abs(),
        // (`stable` kept in the JSON and CSV beside `stability` for readers of the bool.)
        stable: stability == Stability::Stable,
        stability,
        margin: f.margin(),
        lyapunov_per_period: f.max_abs().ln() / f64::from(o.q),
        residual: o.residual,
        iterations: o.iterations,
    })
}

/// Where the map is evaluated for `setup` at `gap_m` (m) and `omega_ratio`.
pub fn map_point(setup: &Setup, gap_m: f64, omega_ratio: f64) -> MapPoint {
    MapPoint {
        params: setup.params,
        settings: setup.settings,
        gap_m,
        omega_ratio,
    }
}

/// The protocol's regime from the start, and the orbit shooting found from where it stopped
/// (period `q` if given, else the protocol's).
///
/// # Errors
/// An invalid point or start, or no orbit (the reason, with the point).
pub fn find<T: Real>(
    at: &MapPoint,
    start: Start,
    q: Option<u32>,
) -> Result<(shared::observe::PointResult, Orbit<T>)> {
    let (u, du) = match start {
        Start::Rest => (0.0, 0.0),
        Start::Relative { u_m, du_m_s } => {
            // Checked here, where the state's range is known.
            state_of::<T>(at, u_m, du_m_s)?;
            (u_m, du_m_s)
        }
    };
    orbit_from::<T>(at, u, du, q, &ShootSettings::for_type::<T>()).map_err(|e| {
        // The commands that call this take the period as `--q`.
        let hint = if matches!(e, OrbitError::NoPeriod { .. }) {
            " (`--q Q`: Newton's method then seeks an orbit of Q periods from where the \
             protocol stopped)"
        } else {
            ""
        };
        anyhow!(
            "no periodic orbit at Ω/ω {}, gap {} mm: {e}{hint}",
            at.omega_ratio,
            mm(at.gap_m)
        )
    })
}

/// Above this [`Orbit::slope_mismatch`] (at ±1e-4 of the scales) the map's own slope is not
/// the monodromy's, and a report says so.
pub const SLOPE_MISMATCH_WARN: f64 = 0.05;

/// The orbit's [`Orbit::slope_mismatch`] over ±1e-4 of the state's scales, and a warning where
/// it is above [`SLOPE_MISMATCH_WARN`] (`None` where the monodromy is the map's slope): the
/// map is not smooth that close to the orbit, as within that of a grazing (an impact appears
/// or vanishes).
///
/// # Errors
/// A displaced state outside the rig's limits.
pub fn slope_check<T: Real>(o: &Orbit<T>) -> Result<(f64, Option<String>)> {
    let mismatch = o.slope_mismatch(1e-4)?;
    let warning = (mismatch > SLOPE_MISMATCH_WARN).then(|| {
        format!(
            "! warning: at this orbit the map's slope differs from its monodromy by {mismatch:.3} \
             (over ±1e-4 of the state's scales; {SLOPE_MISMATCH_WARN} at most where they agree): \
             the map is not smooth that close to the orbit (within that of a grazing, an impact \
             appears or vanishes), so its Floquet multipliers, stability, exponent and the \
             bifurcations located from them may describe one side only (docs/accuracy.md)"
        )
    });
    Ok((mismatch, warning))
}

/// Which ways a branch is followed from its start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Direction {
    /// Increasing parameter.
    Up,
    /// Decreasing parameter.
    Down,
    /// Both, as two branches.
    Both,
}

/// What to continue.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BranchSpec {
    /// The parameter.
    pub param: Param,
    /// Its range (`Ω/ω`, or the gap in m).
    pub range: [f64; 2],
    /// Directions from the start.
    pub direction: Direction,
    /// Period doublings to switch at, in cascade (0: none).
    pub follow_doublings: u32,
}

/// A point of a branch, as reported.
#[derive(Debug, Clone, Serialize)]
pub struct PointOut {
    /// The orbit.
    pub orbit: OrbitReport,
}

/// A located bifurcation, as reported.
#[derive(Debug, Clone, Serialize)]
pub struct EventOut {
    /// Its type.
    pub kind: String,
    /// The parameter's value there (`Ω/ω`, or the gap in mm).
    pub value: f64,
    /// The orbit there (for a grazing: the last orbit of the branch's `p`; where the branch
    /// stalled before the grazing, the last orbit it reached, from which `value` may be
    /// extrapolated: `extrapolated`).
    pub orbit: OrbitReport,
    /// The critical multiplier `(re, im)`.
    pub critical: [f64; 2],
    /// Impacts per period `q` beyond it (grazing).
    pub impacts_beyond: u32,
    /// Its test function along the branch round it (period doubling and Neimark–Sacker
    /// probed, a fold's changes of sign met by the continuation where there were several;
    /// [`crossings`]).
    pub crossings: Option<Crossings>,
    /// A period doubling across a jump of the discretised map ([`BifEvent::at_jump`]): its
    /// multiplier passes −1 by the jump, `critical` is the one located on the near side.
    pub at_jump: bool,
    /// A grazing extrapolated past the branch's last orbit ([`BifEvent::extrapolated`]):
    /// `orbit` and `critical` are that orbit's, at another value than `value`.
    pub extrapolated: bool,
    /// For an extrapolated grazing: how far it lies past the last orbit and the error it is
    /// given ([`Extrapolation`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub extrapolation: Option<Extrapolation>,
}

/// An extrapolated grazing's error is taken as this many times its extrapolation distance:
/// the 170 mm beam's at 3.0 mm lies in f32 0.0041 from f64's (1.19238) after an extrapolation
/// of 0.0016 (ratio 2.6); where the f64 branch reaches its grazing, the extrapolation is short.
pub const EXTRAPOLATION_ERROR_FACTOR: f64 = 4.0;

/// An event is placed when its error is at most this (of `Ω/ω`; of the gap, mm).
pub const PLACED_TO: f64 = 1e-3;

/// How far a grazing is extrapolated past the branch's last orbit, and the error it is given.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Extrapolation {
    /// `|value − the last orbit's value|` (of `Ω/ω`; of the gap, mm).
    pub distance: f64,
    /// [`EXTRAPOLATION_ERROR_FACTOR`] × `distance`.
    pub error_bound: f64,
    /// `error_bound` ≤ [`PLACED_TO`] (else `--precision f64` follows the branch closer).
    pub placed: bool,
}

impl Extrapolation {
    /// The extrapolation from the last orbit at `last` to `value`.
    pub fn new(value: f64, last: f64) -> Extrapolation {
        let distance = (value - last).abs();
        let error_bound = EXTRAPOLATION_ERROR_FACTOR * distance;
        Extrapolation {
            distance,
            error_bound,
            placed: error_bound <= PLACED_TO,
        }
    }
}

/// Spacing of the probes of [`crossings`], in the scaled parameter (`Ω/ω`, or gap/A0).
pub const PROBE_STEP: f64 = 5e-4;

/// Probes of [`crossings`] on each side of the event.
pub const PROBE_POINTS: u32 = 20;

/// How a located bifurcation stands on its branch: for a period doubling or Neimark–Sacker
/// bifurcation its test function (`det(M + I)`, or `det M − 1` while the pair is complex) at
/// [`PROBE_POINTS`] orbits each side, [`PROBE_STEP`] apart; for a fold the changes of sign of
/// `det(M − I)` the continuation met on its way round it ([`BifEvent::changes`]; a fold's
/// branch turns, so probes at fixed parameter values would see one side only). On a smooth
/// branch the test changes sign once, at the event. On the discretised map the monodromy also
/// moves in small jumps as the parameter moves the contact's sub-steps; where those are as
/// large as the multiplier's own motion, the test changes sign several times, and the
/// bifurcation lies somewhere in the span of those crossings rather than at the one located
/// (docs/accuracy.md; a fold is told where the branch turned farthest).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Crossings {
    /// Changes of sign among the probes (1 on a smooth branch; 0 where the located point is a
    /// kink at which the test only touches zero).
    pub count: u32,
    /// The probes that enclose the first and the last change (with no change, the outermost
    /// probes), in the report's units (`Ω/ω`, or the gap in mm).
    pub span: [f64; 2],
    /// The probes' spacing, in the report's units (`None` for a fold's changes, met along the
    /// branch by the continuation's own steps).
    pub step: Option<f64>,
}

impl Crossings {
    /// Whether the test function changes sign other than once among the probes: the
    /// bifurcation is not located at one point ([`Crossings::describe`]).
    pub fn smeared(&self) -> bool {
        self.count != 1
    }

    /// What the probes show, for a report (`what`: `Ω/ω` or `gap`, with `mm` for the gap).
    pub fn describe(&self, what: &str, mm: &str) -> String {
        let [lo, hi] = self.span;
        match self.step {
            Some(step) if self.count == 0 => format!(
                "its test function keeps its sign at every probe between {what} {lo:.4} and \
                 {hi:.4}{mm} (every {step:.4}{mm}): the located point is a kink of the \
                 discretised map where it touches zero, not a crossing"
            ),
            Some(step) => format!(
                "its test function changes sign {} times between {what} {lo:.4} and {hi:.4}{mm} \
                 (probed every {step:.4}{mm}): kinks of the discretised map, the bifurcation lies \
                 in that span, not at one point",
                self.count
            ),
            None => format!(
                "its test function changes sign at {} located folds between {what} {lo:.4} and \
                 {hi:.4}{mm} along the branch, which zig-zags there over kinks of the \
                 discretised map: told as one fold, where the branch turns farthest",
                self.count
            ),
        }
    }
}

/// [`Crossings`] of the event `e` on its branch in `param`: each side probed outward from the
/// event's orbit by Newton's method, a side ending early where Newton fails, the orbit's
/// impacts change (a grazing) or a probe's secant turns further than a continuation step may
/// ([`MIN_TURN_COSINE`]: it converged onto another orbit); `None` for the other events, or
/// where no probe converged on one side. [`Crossings::smeared`] says whether the event is not
/// the one crossing.
pub fn crossings<T: Real>(e: &BifEvent<T>, param: Param) -> Option<Crossings> {
    // A fold's branch turns there: probes at fixed parameter values see one side only; the
    // continuation's own changes of sign say it where there were several.
    if e.kind == EventKind::Fold {
        return e.changes.filter(|c| c.count > 1).map(|c| Crossings {
            count: c.count,
            span: c.span.map(|v| report_value(param, v)),
            step: None,
        });
    }
    if !matches!(e.kind, EventKind::PeriodDoubling | EventKind::NeimarkSacker) {
        return None;
    }
    let test = |o: &Orbit<T>| e.kind.multiplier_test(o);
    test(&e.orbit)?;
    let settings = ShootSettings::for_type::<T>();
    let (scale, scaled) = scaled_frame(&e.orbit, param);
    let mut probes: Vec<(f64, Option<f64>)> = Vec::new();
    let mut sides = 0;
    for dir in [-1.0, 1.0] {
        let mut x = e.orbit.x;
        let mut walk = Walk::from(scaled(&x, e.value));
        let mut any = false;
        for k in 1..=PROBE_POINTS {
            let value = e.value + dir * f64::from(k) * PROBE_STEP * scale;
            if param == Param::GapM && value < 0.0 {
                break;
            }
            match shoot(&e.orbit.at.with(param, value), e.orbit.q, x, &settings) {
                Ok(o)
                    if o.trace.impacts == e.orbit.trace.impacts
                        && walk.step_to(scaled(&o.x, value)) =>
                {
                    x = o.x;
                    any = true;
                    probes.push((value, test(&o)));
                }
                _ => break,
            }
        }
        sides += u32::from(any);
    }
    if sides < 2 {
        return None;
    }
    probes.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Consecutive probes with a test value (a Neimark–Sacker's pair may turn real on the way).
    let signed: Vec<(f64, bool)> = probes
        .iter()
        .filter_map(|&(v, t)| t.filter(|t| t.is_finite()).map(|t| (v, t > 0.0)))
        .collect();
    let changes: Vec<usize> = (1..signed.len())
        .filter(|&i| signed[i].1 != signed[i - 1].1)
        .collect();
    // No change among the probes: the span is theirs.
    let span = match (changes.first(), changes.last()) {
        (Some(&first), Some(&last)) => [signed[first - 1].0, signed[last].0],
        _ => [signed.first()?.0, signed.last()?.0],
    };
    Some(Crossings {
        count: changes.len() as u32,
        span: span.map(|v| report_value(param, v)),
        step: Some(report_value(param, PROBE_STEP * scale)),
    })
}

/// The scale of `param` (1 for `Ω/ω`, `A0` for the gap in m) and the map into the branch's
/// scaled frame as the continuation has it: `(x, value)` to the state over
/// [`MapPoint::scales`] at `o` and the value over that scale.
fn scaled_frame<T: Real>(
    o: &Orbit<T>,
    param: Param,
) -> (f64, impl Fn(&nalgebra::Vector2<T>, f64) -> [f64; 3]) {
    let scale = match param {
        Param::OmegaRatio => 1.0,
        Param::GapM => o.at.params.amplitude_m,
    };
    let s = o.at.scales();
    (scale, move |x: &nalgebra::Vector2<T>, value: f64| {
        [x[0].to_f64() / s[0], x[1].to_f64() / s[1], value / scale]
    })
}

/// Probes walked outward along a branch in its scaled frame: each secant must keep within
/// [`MIN_TURN_COSINE`] of the one before, as a continuation step must, else the probe has left
/// the branch (Newton converged onto another orbit with as many impacts).
#[derive(Clone)]
struct Walk {
    at: [f64; 3],
    heading: Option<[f64; 3]>,
}

impl Walk {
    fn from(at: [f64; 3]) -> Self {
        Walk { at, heading: None }
    }

    /// Whether `next` continues the walk (then it is the walk's new end); the first step is
    /// taken as it comes.
    fn step_to(&mut self, next: [f64; 3]) -> bool {
        let d = [0, 1, 2].map(|i| next[i] - self.at[i]);
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let heading = d.map(|c| c / n);
        // A NaN heading (no step) is not taken either.
        let turn = self.heading.map_or(1.0, |h| {
            h[0] * heading[0] + h[1] * heading[1] + h[2] * heading[2]
        });
        if turn.is_nan() || turn < MIN_TURN_COSINE {
            return false;
        }
        (self.at, self.heading) = (next, Some(heading));
        true
    }
}

/// Jumps of the discretised map a branch of [`branches`] may step over.
pub const MAX_BRIDGES: usize = 100;

/// Steps over a jump of the discretised map where the continuation of the branch `points`
/// stalled (its step below the minimum) while moving the way it set out (from its first point
/// to the first a probe's step away): the orbit at the first of up to four values
/// [`PROBE_STEP`] apart beyond the last point (scaled as [`crossings`] scales it) at which
/// Newton's method converges from the last point's state with as many impacts, the secant from
/// the branch's recent points turning no further than a continuation step may
/// ([`MIN_TURN_COSINE`]), and no test function (fold, period doubling; Neimark–Sacker while
/// both pairs are complex) changing sign between the two orbits; with that way (+1: up, −1:
/// down). `None` where none qualifies, or the branch had turned back: the stall stands (a
/// bifurcation, a turn, or Newton failing for another cause).
fn bridge<T: Real>(
    points: &[BranchPoint<T>],
    param: Param,
    settings: &ContinuationSettings,
) -> Option<(Orbit<T>, f64)> {
    let (first, last) = (points.first()?, points.last()?);
    let o = &last.orbit;
    let (scale, scaled) = scaled_frame(o, param);
    let away = |a: &BranchPoint<T>, b: &BranchPoint<T>| moved(a, b, PROBE_STEP * scale);
    let heading = points.iter().find_map(|p| away(p, first))?;
    // The last secant: from the latest point at least a probe's step behind.
    let (behind, sign) = points
        .iter()
        .rev()
        .find_map(|p| away(last, p).map(|sign| (p, sign)))?;
    if sign != heading {
        return None;
    }
    let mut walk = Walk::from(scaled(&behind.orbit.x, behind.value));
    walk.step_to(scaled(&o.x, last.value));
    let shoot_settings = ShootSettings::for_type::<T>();
    (1..=4).find_map(|k| {
        let value = last.value + sign * f64::from(k) * PROBE_STEP * scale;
        if value < settings.range[0] || value > settings.range[1] {
            return None;
        }
        let next = shoot(&o.at.with(param, value), o.q, o.x, &shoot_settings).ok()?;
        let same_side = |kind: EventKind| {
            match (kind.multiplier_test(o), kind.multiplier_test(&next)) {
                (Some(a), Some(b)) => (a > 0.0) == (b > 0.0),
                // Neimark–Sacker's test only while the pair is complex: a pair turning real
                // crosses neither +1 nor −1 unless the fold's or the doubling's test says so.
                _ => true,
            }
        };
        (next.trace.impacts == o.trace.impacts
            && EventKind::BY_MULTIPLIERS.into_iter().all(same_side)
            && walk.clone().step_to(scaled(&next.x, value)))
        .then_some((next, heading))
    })
}

/// A continued branch.
#[derive(Debug, Clone, Serialize)]
pub struct BranchOut {
    /// Its number (0, 1, …: the order computed).
    pub id: usize,
    /// The branch it switched from at a period doubling.
    pub parent: Option<usize>,
    /// `up`, `down`, or `doubled` (from a period doubling).
    pub direction: &'static str,
    /// Its period.
    pub q: u32,
    /// Its points, in the order followed.
    pub points: Vec<PointOut>,
    /// The bifurcations located on it, in order.
    pub events: Vec<EventOut>,
    /// Why it ended.
    pub end: String,
    /// The jumps of the discretised map stepped over where Newton could not follow the
    /// branch ([`branches`]): the last value before each and the first after, in the report's
    /// units (`Ω/ω`, or the gap in mm).
    pub bridges: Vec<[f64; 2]>,
    /// Where the branch, with no fold told, turned back in the parameter (a kink of the
    /// discretised map), in the report's units: its farthest value the way it set out, more
    /// than `kink_span` beyond where it ended; `None` otherwise.
    pub turned_back: Option<f64>,
}

/// The way from branch point `b` to `a` in the parameter (+1 or −1), if they lie at least
/// `min` apart.
fn moved<T: Real>(a: &BranchPoint<T>, b: &BranchPoint<T>, min: f64) -> Option<f64> {
    ((a.value - b.value).abs() >= min).then(|| (a.value - b.value).signum())
}

/// The farthest value of a branch's `points` the way it set out (its first move of at least
/// the span), where that lies more than `settings.kink_span` (scaled) beyond its last point
/// and no fold of `events` was told: the branch turned back there without a multiplier
/// through +1 (a kink of the discretised map) and ended on the way back. (A told fold is
/// located by Newton across the branch, 9e-5 of `Ω/ω` beyond its farthest point on the
/// wire rig's `3/1` branch: a branch with one is taken to have turned there.)
fn turned_back<T: Real>(
    points: &[BranchPoint<T>],
    events: &[BifEvent<T>],
    param: Param,
    settings: &ContinuationSettings,
) -> Option<f64> {
    if events.iter().any(|e| e.kind == EventKind::Fold) {
        return None;
    }
    let (first, last) = (points.first()?, points.last()?);
    let (scale, _) = scaled_frame(&first.orbit, param);
    let span = settings.kink_span * scale;
    let heading = points.iter().find_map(|p| moved(p, first, span))?;
    let farthest = points
        .iter()
        .map(|p| p.value * heading)
        .fold(f64::NEG_INFINITY, f64::max)
        * heading;
    ((farthest - last.value) * heading > span).then_some(farthest)
}

/// Continues the branch of `start` as `spec` says: the start's branch in the asked
/// directions, then (up to `spec.follow_doublings` deep) the doubled branch of every period
/// doubling found. Where a branch stalls (its step below the minimum) at a jump of the
/// discretised map while moving the way it set out, it steps over the jump and goes on
/// (at most [`MAX_BRIDGES`] times): from the orbit Newton's method finds at the first of up
/// to four values [`PROBE_STEP`] beyond, with as many impacts, a secant within
/// [`MIN_TURN_COSINE`] of the branch's, and no fold or doubling test changing sign across.
///
/// # Errors
/// Ctrl-C; a report that cannot be made (not for converged orbits).
pub fn branches<T: Real>(start: &Orbit<T>, spec: &BranchSpec) -> Result<Vec<BranchOut>> {
    let settings = ContinuationSettings::new::<T>(spec.param, spec.range);
    // (start, initial tangent, direction, parent branch, doublings deep)
    type Todo<T> = (Orbit<T>, Option<[f64; 3]>, f64, Option<usize>, u32);
    let mut todo: Vec<Todo<T>> = Vec::new();
    if matches!(spec.direction, Direction::Up | Direction::Both) {
        todo.push((*start, None, 1.0, None, 0));
    }
    if matches!(spec.direction, Direction::Down | Direction::Both) {
        todo.push((*start, None, -1.0, None, 0));
    }
    todo.reverse();
    let mut out = Vec::new();
    while let Some((orbit, tangent, dir, parent, depth)) = todo.pop() {
        interrupt::check()?;
        let mut points: Vec<BranchPoint<T>> = Vec::new();
        let mut events: Vec<BifEvent<T>> = Vec::new();
        let mut bridges: Vec<[f64; 2]> = Vec::new();
        let (mut from, mut along, mut toward) = (orbit, tangent, dir);
        let end = loop {
            let end = continue_branch(
                &from,
                &settings,
                toward,
                along,
                |p| points.push(*p),
                |e| {
                    events.push(*e);
                    ControlFlow::Continue(())
                },
            );
            // Where Newton could not follow the branch, a jump of the discretised map may
            // be what stopped it: stepped over, the branch goes on.
            let BranchEnd::StepTooSmall(at) = end else {
                break end;
            };
            if bridges.len() >= MAX_BRIDGES || points.len() >= settings.max_points as usize {
                break end;
            }
            interrupt::check()?;
            let Some((next, heading)) = bridge(&points, spec.param, &settings) else {
                break end;
            };
            bridges.push([at, next.at.get(spec.param)]);
            (from, along, toward) = (next, None, heading);
        };
        let id = out.len();
        if depth < spec.follow_doublings {
            for e in &events {
                if let Some((o, t)) = doubling_start(e) {
                    todo.insert(0, (o, Some(t), 1.0, Some(id), depth + 1));
                }
            }
        }
        out.push(BranchOut {
            id,
            parent,
            direction: match (tangent.is_some(), dir > 0.0) {
                (true, _) => "doubled",
                (false, true) => "up",
                (false, false) => "down",
            },
            q: orbit.q,
            points: points
                .iter()
                .map(|p| {
                    Ok(PointOut {
                        orbit: report(&p.orbit)?,
                    })
                })
                .collect::<Result<_>>()?,
            events: events
                .iter()
                .map(|e| {
                    let value = report_value(spec.param, e.value);
                    let orbit = report(&e.orbit)?;
                    let extrapolation = e
                        .extrapolated
                        .then(|| Extrapolation::new(value, param_value(spec.param, &orbit)));
                    Ok(EventOut {
                        kind: e.kind.name().to_string(),
                        value,
                        orbit,
                        critical: [e.critical.re, e.critical.im],
                        impacts_beyond: e.impacts_beyond,
                        crossings: crossings(e, spec.param),
                        at_jump: e.at_jump,
                        extrapolated: e.extrapolated,
                        extrapolation,
                    })
                })
                .collect::<Result<_>>()?,
            end: end_text(&end, spec.param),
            bridges: bridges
                .iter()
                .map(|b| b.map(|v| report_value(spec.param, v)))
                .collect(),
            turned_back: turned_back(&points, &events, spec.param, &settings)
                .map(|v| report_value(spec.param, v)),
        });
    }
    Ok(out)
}

/// Why a branch ended, with the value in the report's units (`Ω/ω`, or the gap in mm).
fn end_text(end: &BranchEnd, param: Param) -> String {
    let (what, v) = match *end {
        BranchEnd::RangeEnd(v) => ("the end of the range", v),
        BranchEnd::Grazing(v) => ("a grazing", v),
        BranchEnd::StepTooSmall(v) => ("a step below the minimum", v),
        BranchEnd::MaxPoints(v) => ("the point budget", v),
        BranchEnd::Stopped(v) => ("an event", v),
    };
    let v = report_value(param, v);
    match param {
        Param::OmegaRatio => format!("{what} at Ω/ω {v:.6}"),
        Param::GapM => format!("{what} at gap {v:.6} mm"),
    }
}

/// A value of `param` (`Ω/ω`, or the gap in m) in the report's units (`Ω/ω`, or the gap in
/// mm).
pub fn report_value(param: Param, v: f64) -> f64 {
    match param {
        Param::OmegaRatio => v,
        Param::GapM => mm(v),
    }
}

/// A stability as its name (`stable`, `neutral`, `unstable`) in JSON and CSV.
fn stability_name<S: serde::Serializer>(s: &Stability, to: S) -> Result<S::Ok, S::Error> {
    to.serialize_str(s.name())
}

/// A gap of `m` metres in mm as typed: the shortest decimal whose `× 1e-3` (as `--gap-mm` is
/// read, `Setup::gap_m`) is `m`, so that the 0.018 m of `--gap-mm 18` reads 18 and not
/// 18.000000000000004 (the product's rounding); `m × 1e3` where no decimal of up to 17
/// digits gives `m` back.
pub fn mm(m: f64) -> f64 {
    let v = m * 1e3;
    (0..17)
        .filter_map(|digits| format!("{v:.digits$e}").parse::<f64>().ok())
        .find(|&d| d * 1e-3 == m)
        .unwrap_or(v)
}

/// The value of `param` in a report (`Ω/ω`, or the gap in mm).
pub fn param_value(param: Param, o: &OrbitReport) -> f64 {
    match param {
        Param::OmegaRatio => o.omega_ratio,
        Param::GapM => o.gap_mm,
    }
}

/// One CSV row of `continue`: a point of a branch, or a located bifurcation (`event` set).
#[derive(Debug, Clone, Serialize)]
pub struct BranchRow {
    /// Branch number.
    pub branch: usize,
    /// The branch it switched from at a period doubling (empty: none).
    pub parent: Option<usize>,
    /// `up`, `down` or `doubled`.
    pub direction: &'static str,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Excitation frequency, Hz.
    pub freq_hz: f64,
    /// Gap, mm.
    pub gap_mm: f64,
    /// `u` on the section, mm (the orbit's first point).
    pub u_mm: f64,
    /// `u̇` on the section, mm/s.
    pub du_mm_s: f64,
    /// `p/q`.
    pub regime: String,
    /// Largest impact force, `F_i/mg`.
    pub impact_force_mg: f64,
    /// Multiplier 1 (the larger modulus), real part.
    pub mu1_re: f64,
    /// Multiplier 1, imaginary part.
    pub mu1_im: f64,
    /// Multiplier 2, real part.
    pub mu2_re: f64,
    /// Multiplier 2, imaginary part.
    pub mu2_im: f64,
    /// `max |μ|`.
    pub max_abs_mu: f64,
    /// Asymptotically stable: `max |μ| < 1`, and not neutral.
    pub stable: bool,
    /// `stable`, `neutral` (no impact on an undamped suspension: `|μ| = 1`) or `unstable`.
    #[serde(serialize_with = "stability_name")]
    pub stability: Stability,
    /// Empty for a point; `fold`, `period-doubling`, `neimark-sacker` or `grazing` for a
    /// located bifurcation.
    pub event: String,
}

fn row(b: &BranchOut, o: &OrbitReport, event: &str) -> BranchRow {
    let first = o.section.first().copied().unwrap_or([f64::NAN, f64::NAN]);
    BranchRow {
        branch: b.id,
        parent: b.parent,
        direction: b.direction,
        omega_ratio: o.omega_ratio,
        freq_hz: o.freq_hz,
        gap_mm: o.gap_mm,
        u_mm: first[0],
        du_mm_s: first[1],
        regime: o.regime.clone(),
        impact_force_mg: o.impact_force_mg,
        mu1_re: o.multipliers[0][0],
        mu1_im: o.multipliers[0][1],
        mu2_re: o.multipliers[1][0],
        mu2_im: o.multipliers[1][1],
        max_abs_mu: o.max_abs_multiplier,
        stable: o.stable,
        stability: o.stability,
        event: event.to_string(),
    }
}

/// The CSV rows of `branches` (continued in `param`): each branch's points in order, its
/// events after them (at their located value; the orbit's state and multipliers are those of
/// the last orbit before it).
pub fn rows(param: Param, branches: &[BranchOut]) -> Vec<BranchRow> {
    let mut out = Vec::new();
    for b in branches {
        out.extend(b.points.iter().map(|p| row(b, &p.orbit, "")));
        out.extend(b.events.iter().map(|e| {
            let mut r = row(b, &e.orbit, &e.kind);
            match param {
                Param::OmegaRatio => {
                    r.omega_ratio = e.value;
                    r.freq_hz = e.orbit.freq_hz * e.value / e.orbit.omega_ratio;
                }
                Param::GapM => r.gap_mm = e.value,
            }
            r
        }));
    }
    out
}

/// `true` if `kind` names a located bifurcation type.
pub fn is_event_kind(kind: &str) -> bool {
    [
        EventKind::Fold,
        EventKind::PeriodDoubling,
        EventKind::NeimarkSacker,
        EventKind::Grazing,
    ]
    .iter()
    .any(|k| k.name() == kind)
}

/// The brute-force diagram drawn behind a branch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Background {
    /// None.
    None,
    /// From rest at each value (in parallel).
    Rest,
    /// Two sweeps, up and down, each value starting from the previous one's final state (the
    /// jumps and hysteresis show).
    Sweeps,
}

/// One brute-force run behind a branch: the protocol's window at each value of the sweep.
#[derive(Debug, Clone)]
pub struct BackgroundRun {
    /// `rest`, `up` or `down`.
    pub branch: &'static str,
    /// Poincaré points `(parameter, u mm)` (parameter: `Ω/ω`, or the gap in mm).
    pub strobes: Vec<(f64, f64)>,
    /// Impact peaks `(parameter, F_i/mg)`.
    pub impacts: Vec<(f64, f64)>,
}

/// One protocol run at `at` (from `x` if given, else rest): its window's samples and the final
/// state.
fn window<T: Real>(
    at: &MapPoint,
    x: Option<nalgebra::Vector2<T>>,
) -> Result<(WindowSamples, nalgebra::Vector2<T>)> {
    let table = shared::integrate::PhaseTable::<T>::new(at.settings.steps.steps_per_period)?;
    let mut sim =
        shared::analysis::simulator_at(&at.params, at.gap_m, at.omega_ratio, &at.settings, &table)?;
    if let Some(x) = x {
        sim.reset_state(x);
    }
    let mut s = WindowSamples::default();
    shared::observe::run_protocol(
        &mut sim,
        &at.settings.protocol,
        at.params.weight_n(),
        &mut s,
    )?;
    Ok((s, sim.state()))
}

/// The brute-force diagram over `values` of `param` around `at` (gap values in m).
///
/// # Errors
/// An invalid point, or Ctrl-C.
pub fn background<T: Real>(
    at: &MapPoint,
    param: Param,
    values: &[f64],
    mode: Background,
) -> Result<Vec<BackgroundRun>> {
    use rayon::prelude::*;
    let mg = at.params.weight_n();
    let shown = |v: f64| report_value(param, v);
    let collect = |run: &mut BackgroundRun, v: f64, s: &WindowSamples| {
        let x = shown(v);
        run.strobes
            .extend(s.strobes.iter().map(|&(u, _)| (x, u * 1e3)));
        run.impacts
            .extend(s.impacts.iter().map(|&(_, f)| (x, f / mg)));
    };
    let bar = progress(
        values.len() * if mode == Background::Sweeps { 2 } else { 1 },
        "brute-force diagram",
    );
    let sweep = |branch: &'static str, order: Vec<f64>| -> Result<BackgroundRun> {
        let mut run = BackgroundRun {
            branch,
            strobes: Vec::new(),
            impacts: Vec::new(),
        };
        let mut x = None;
        for v in order {
            interrupt::check()?;
            let (s, end) = window::<T>(&at.with(param, v), x)?;
            x = Some(end);
            collect(&mut run, v, &s);
            bar.inc(1);
        }
        Ok(run)
    };
    let out = match mode {
        Background::None => Vec::new(),
        Background::Rest => {
            let windows: Vec<Result<(f64, WindowSamples)>> = values
                .par_iter()
                .map(|&v| {
                    interrupt::check()?;
                    let (s, _) = window::<T>(&at.with(param, v), None)?;
                    bar.inc(1);
                    Ok((v, s))
                })
                .collect();
            let mut run = BackgroundRun {
                branch: "rest",
                strobes: Vec::new(),
                impacts: Vec::new(),
            };
            for w in windows {
                let (v, s) = w?;
                collect(&mut run, v, &s);
            }
            vec![run]
        }
        Background::Sweeps => {
            let down: Vec<f64> = values.iter().rev().copied().collect();
            let (a, b) = rayon::join(|| sweep("up", values.to_vec()), || sweep("down", down));
            vec![a?, b?]
        }
    };
    bar.finish_and_clear();
    Ok(out)
}

/// A bifurcation curve in the (`Ω/ω`, gap) plane, as reported.
#[derive(Debug, Clone, Serialize)]
pub struct CurveOut {
    /// The bifurcation's type.
    pub kind: String,
    /// The regime of the orbit it bounds (`1/1`, …).
    pub regime: String,
    /// Its points `(Ω/ω, gap mm)`, in order along the curve.
    pub points: Vec<[f64; 2]>,
    /// How each end was reached (towards smaller gaps first).
    pub ends: [String; 2],
}

/// One CSV row of the boundary curves (`peterka --boundaries-out`).
#[derive(Debug, Clone, Serialize)]
pub struct CurveRow {
    /// Curve number.
    pub curve: usize,
    /// Bifurcation type.
    pub kind: String,
    /// Regime of the orbit it bounds.
    pub regime: String,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Gap, mm.
    pub gap_mm: f64,
}

/// The CSV rows of `curves`.
pub fn curve_rows(curves: &[CurveOut]) -> Vec<CurveRow> {
    curves
        .iter()
        .enumerate()
        .flat_map(|(i, c)| {
            c.points.iter().map(move |p| CurveRow {
                curve: i,
                kind: c.kind.clone(),
                regime: c.regime.clone(),
                omega_ratio: p[0],
                gap_mm: p[1],
            })
        })
        .collect()
}

/// Relative distance (fraction of the map's width and height) under which a seed's edge
/// is taken to lie on a curve already traced.
const KNOWN_CURVE_TOL: f64 = 5e-3;

/// Whether `p` lies within `tol` of the polyline `points`, both scaled by `scale`
/// (the map's width and height) so that the two axes weigh alike.
fn near_polyline(points: &[[f64; 2]], p: [f64; 2], scale: [f64; 2], tol: f64) -> bool {
    let n = |q: [f64; 2]| [q[0] / scale[0], q[1] / scale[1]];
    let p = n(p);
    let dist = |a: [f64; 2], b: [f64; 2]| {
        let (a, b) = (n(a), n(b));
        let d = [b[0] - a[0], b[1] - a[1]];
        let len2 = d[0] * d[0] + d[1] * d[1];
        let t = if len2 > 0.0 {
            (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (p[0] - a[0] - t * d[0]).hypot(p[1] - a[1] - t * d[1])
    };
    match points {
        [] => false,
        [a] => dist(*a, *a) < tol,
        _ => points.windows(2).any(|w| dist(w[0], w[1]) < tol),
    }
}

/// The curves that bound the band of the stable orbit found from rest at each seed
/// `(gap_m, Ω/ω)`: the band's two edges located on its branch in `Ω/ω`, each continued in
/// (`Ω/ω`, gap) over the box `omega_range` × `gap_range_m` both ways. A seed whose edge lies on
/// a curve already computed (within 0.5 % of the box's width and height) adds nothing.
///
/// # Errors
/// Ctrl-C.
pub fn boundary_curves<T: Real>(
    base: &MapPoint,
    seeds: &[(f64, f64)],
    omega_range: [f64; 2],
    gap_range_m: [f64; 2],
) -> Result<Vec<CurveOut>> {
    use shared::orbit::{CurveSettings, Edge, band_edges, continue_curve};
    let a0 = base.params.amplitude_m;
    let mut out: Vec<CurveOut> = Vec::new();
    let settings = CurveSettings::new::<T>(omega_range, gap_range_m);
    let scale = [
        (omega_range[1] - omega_range[0]).abs().max(1e-9),
        (gap_range_m[1] - gap_range_m[0]).abs().max(a0 * 1e-3) * 1e3,
    ];
    for &(gap_m, ratio) in seeds {
        interrupt::check()?;
        let mut at = *base;
        at.gap_m = gap_m;
        at.omega_ratio = ratio;
        let Ok((_, orbit)) = find::<T>(&at, Start::Rest, None) else {
            continue;
        };
        if orbit.stability() != Stability::Stable {
            continue;
        }
        let edges = band_edges(
            &orbit,
            &ContinuationSettings::new::<T>(Param::OmegaRatio, omega_range),
        );
        for edge in edges {
            let Edge::Event(event) = edge else {
                continue;
            };
            // A seed whose edge lies on a curve already traced (within half a percent of
            // the map's width and height, measured to the curve's segments) adds nothing.
            let here = [event.value, gap_m * 1e3];
            let known = out
                .iter()
                .any(|c| near_polyline(&c.points, here, scale, KNOWN_CURVE_TOL));
            if known {
                continue;
            }
            let mut halves: Vec<(Vec<[f64; 2]>, String)> = Vec::new();
            for direction in [-1.0, 1.0] {
                let mut pts = Vec::new();
                let end = continue_curve(&event, Param::OmegaRatio, &settings, direction, |p| {
                    pts.push([p.omega_ratio, p.gap_m * 1e3]);
                    if interrupt::check().is_err() {
                        ControlFlow::Break(())
                    } else {
                        ControlFlow::Continue(())
                    }
                });
                interrupt::check()?;
                halves.push((pts, end.to_string()));
            }
            let (mut down, down_end) = halves.remove(0);
            let (up, up_end) = halves.remove(0);
            down.reverse();
            // The start appears in both halves.
            down.extend(up.into_iter().skip(1));
            out.push(CurveOut {
                kind: event.kind.name().to_string(),
                regime: regime_of(orbit.p(), orbit.q).to_string(),
                points: down,
                ends: [down_end, up_end],
            });
        }
    }
    // A curve traced from an early seed may stop short of where a later seed's trace of the
    // same curve goes on: of two such, the longer stays.
    out.sort_by_key(|c| std::cmp::Reverse(c.points.len()));
    let mut kept: Vec<CurveOut> = Vec::new();
    for c in out {
        let on = c
            .points
            .iter()
            .filter(|&&p| {
                kept.iter().any(|k| {
                    k.kind == c.kind && near_polyline(&k.points, p, scale, KNOWN_CURVE_TOL)
                })
            })
            .count();
        if 2 * on <= c.points.len() {
            kept.push(c);
        }
    }
    Ok(kept)
}

#[cfg(test)]
mod tests {
    use super::{Crossings, Walk, mm};

    #[test]
    fn a_gap_reads_as_typed() {
        // Every gap typed to the micrometre over the wire rig's range reads back as typed,
        // although 2,591 of these 18,751 round trips `× 1e-3 × 1e3` do not (18 among them).
        let mut off = 0;
        for k in 0..=18_750u32 {
            let typed: f64 = format!("{}.{:03}", k / 1000, k % 1000).parse().unwrap();
            let m = typed * 1e-3;
            off += usize::from(m * 1e3 != typed);
            assert_eq!(mm(m), typed, "{typed}");
        }
        assert_eq!(off, 2591);
        let m = 18.0 * 1e-3;
        assert_eq!((m * 1e3, mm(m)), (18.000000000000004, 18.0));
        // A value no short decimal gives (a gap continuation's) is `m × 1e3` in full.
        for m in [1.0027946603013547e-3, 0.018, 2.0f64.sqrt() * 1e-3] {
            assert_eq!(mm(m), m * 1e3, "{m}");
        }
        assert_eq!(mm(1.0027946603013547e-3), 1.0027946603013547);
    }

    #[test]
    fn probes_that_turn_further_than_a_continuation_step_have_left_the_branch() {
        // Along a straight branch every probe is taken, the first one whatever its heading.
        let mut w = Walk::from([0.0, 0.0, 0.0]);
        assert!(w.step_to([3.0, 0.0, 1.0]));
        assert!(w.step_to([6.0, 0.0, 2.0]));
        // A gentle bend, the state's part of the secant turned by 0.2 rad (cos 0.982), is taken.
        let (c, s) = (0.2f64.cos(), 0.2f64.sin());
        assert!(w.step_to([6.0 + 3.0 * c, 3.0 * s, 3.0]));
        // A jump across to another orbit at the next parameter value: the secant turns by
        // 0.71 rad (cos 0.757), below MIN_TURN_COSINE = 0.9; the walk keeps its end.
        let end = w.at;
        let jump = [end[0] + 3.0, end[1] + 4.0, end[2] + 1.0];
        assert!(!w.step_to(jump));
        assert_eq!(w.at, end);
        // Back the way it came, and a probe at its own end (no direction), are not taken.
        assert!(!w.step_to([0.0, 0.0, 0.0]));
        assert!(!w.step_to(end));
    }

    #[test]
    fn an_event_is_smeared_unless_its_test_changes_sign_once() {
        let c = |count| Crossings {
            count,
            span: [2.6355, 2.6425],
            step: Some(5e-4),
        };
        assert!(!c(1).smeared());
        assert!(c(0).smeared() && c(5).smeared());
        let five = c(5).describe("Ω/ω", "");
        assert!(
            five.contains("changes sign 5 times between Ω/ω 2.6355 and 2.6425"),
            "{five}"
        );
        let none = c(0).describe("gap", " mm");
        assert!(
            none.contains("keeps its sign") && none.contains("2.6425 mm"),
            "{none}"
        );
        let fold = Crossings { step: None, ..c(7) }.describe("Ω/ω", "");
        assert!(
            fold.contains("changes sign at 7 located folds between Ω/ω 2.6355 and 2.6425 along"),
            "{fold}"
        );
    }
}

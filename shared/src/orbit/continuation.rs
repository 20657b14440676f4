//! Pseudo-arclength continuation of a branch of periodic orbits in one parameter (`Ω/ω` or the
//! gap), with step control, round folds and along unstable branches, locating the bifurcations
//! it passes (Dankowicz & Schilder, *Recipes for Continuation*, SIAM 2013, ch. 10; Kuznetsov,
//! *Elements of Applied Bifurcation Theory*, ch. 10).
//!
//! Unknowns `z = (x₀/s₀, x₁/s₁, λ/s_λ)`: the orbit's state on the section scaled by the cart's
//! motion (`s`: [`MapPoint::scales`] at the start) and the parameter (`s_λ` = 1 for `Ω/ω`, `A0`
//! for the gap). The branch solves `F(z) = (P^q_λ(x) − x)/s = 0`; its tangent `t` is the null
//! vector of `DF = [S⁻¹(M − I)S | ∂F/∂λ]` (the monodromy from dual numbers, `∂F/∂λ` by central
//! differences). Each step predicts `z + h t` and corrects by Newton's method on
//! `F(z) = 0, t·(z − z_pred) = 0`.
//!
//! Events between two accepted points, located by bisection on the step to `locate_tol` in the
//! parameter: a fold (`det(M − I)` changes sign), a period doubling (`det(M + I)`), a
//! Neimark–Sacker bifurcation (`det M − 1` while the multipliers are a complex pair), and a
//! grazing (the orbit's impact count changes: an impact appears or disappears; the map's
//! derivative is singular there, Nordmark 1991, so the branch ends at it).

use core::fmt;
use core::ops::ControlFlow;

use nalgebra::Vector2;

use super::floquet::{Floquet, Multiplier};
use super::map::{MapPoint, Param, iterate, tangent};
use super::shooting::{Orbit, ShootSettings, scaled_norm};
use crate::real::Real;

/// The least cosine between successive directions of a branch in its scaled frame (the
/// state over [`MapPoint::scales`], `Ω/ω` as it is, the gap over `A0`): a step whose
/// direction turns further has not stayed on the branch (the corrector converged onto another
/// orbit, or stepped across a fold) and is not taken.
pub const MIN_TURN_COSINE: f64 = 0.9;

/// How a branch is continued.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContinuationSettings {
    /// The parameter.
    pub param: Param,
    /// Its range (gap in m); the branch ends on its edge (its last step shortened to land
    /// there, within twice the smallest step).
    pub range: [f64; 2],
    /// Step sizes in the scaled unknowns; below the smallest the branch ends.
    pub steps: StepSizes,
    /// Points at most (10,000).
    pub max_points: u32,
    /// An event is located to this much in the parameter (1e-7).
    pub locate_tol: f64,
    /// Newton's tolerance and iterations for every corrector.
    pub newton: ShootSettings,
    /// Where Newton stalls, a grazing monitor within this much of 0 (in units of the cart's
    /// motion) says the branch ends at a grazing (1e-4; f32: 1e-2).
    pub grazing_near: f64,
    /// The width of a kink of the discretised map, in the scaled parameter (1e-5): the fold
    /// test's sign counts as settled once it has held over this much of the branch, and a
    /// fold within this of where the branch stalls is the kink that stalls it, not reported.
    pub kink_span: f64,
    /// How far, in the scaled parameter, the branch must move from the farthest of a cluster
    /// of located folds before the cluster is told (0.01): where kinks of the discretised map
    /// make the fold test change sign back and forth near a fold (the branch zig-zagging by up
    /// to 6e-3 of `Ω/ω` over 4.6e-3 with Hunt–Crossley on the 170 mm beam rig), the cluster is
    /// one fold, at its farthest value, if the test's sign ends changed, and none otherwise.
    pub fold_retreat: f64,
}

impl ContinuationSettings {
    /// The defaults for `param` over `range` in the float type `T`: steps 0.02 (1e-6 ..= 0.05)
    /// in the scaled unknowns, events located to 1e-7 in the parameter (f64; f32: 1e-5, its
    /// own resolution), Newton as [`ShootSettings::for_type`], grazing monitors near 0 within
    /// 1e-4 (f32: 1e-2), kinks 1e-5 wide, fold clusters told 0.01 past their farthest fold.
    pub fn new<T: Real>(param: Param, range: [f64; 2]) -> Self {
        let f64_like = T::EPSILON < 1e-10;
        ContinuationSettings {
            param,
            range,
            steps: StepSizes::for_type::<T>(),
            max_points: 10_000,
            locate_tol: if f64_like { 1e-7 } else { 1e-5 },
            newton: ShootSettings::for_type::<T>(),
            grazing_near: if f64_like { 1e-4 } else { 1e-2 },
            kink_span: 1e-5,
            fold_retreat: 1e-2,
        }
    }
}

/// The step-size control of a pseudo-arclength continuation (a branch, or a bifurcation
/// curve: [`super::curve::CurveSettings`]), in the scaled unknowns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepSizes {
    /// First step (0.02).
    pub first: f64,
    /// Smallest step: below it the continuation ends (1e-6; f32: 1e-4).
    pub min: f64,
    /// Largest step (0.05).
    pub max: f64,
}

impl StepSizes {
    /// Whether the step `h` has fallen below the smallest, which ends a continuation: also
    /// when `h` or the smallest step is NaN, and when `h` has reached 0 (a smallest step that
    /// is not positive), so that halving the step always ends.
    pub fn below_min(&self, h: f64) -> bool {
        !(h >= self.min && h > 0.0)
    }

    /// The defaults in the float type `T`: 0.02, within 1e-6 ..= 0.05 (f32: from 1e-4).
    pub fn for_type<T: Real>() -> Self {
        StepSizes {
            first: 0.02,
            min: if T::EPSILON < 1e-10 { 1e-6 } else { 1e-4 },
            max: 0.05,
        }
    }
}

/// A point of a branch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BranchPoint<T> {
    /// The parameter's value (gap in m).
    pub value: f64,
    /// The orbit there.
    pub orbit: Orbit<T>,
}

/// Kinds of bifurcation along a branch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EventKind {
    /// A real multiplier through +1: the branch turns (a jump of the response).
    Fold,
    /// A real multiplier through −1: the orbit of period `2q` branches off.
    PeriodDoubling,
    /// A complex pair through the unit circle: a torus (quasi-periodic motion) branches off.
    NeimarkSacker,
    /// An impact appears or disappears (zero arrival speed): the branch of this `p/q` ends.
    Grazing,
}

impl EventKind {
    /// Its name in reports and CSV.
    pub fn name(self) -> &'static str {
        match self {
            EventKind::Fold => "fold",
            EventKind::PeriodDoubling => "period-doubling",
            EventKind::NeimarkSacker => "neimark-sacker",
            EventKind::Grazing => "grazing",
        }
    }

    /// The events told by a test function on the multipliers ([`EventKind::multiplier_test`]).
    pub const BY_MULTIPLIERS: [EventKind; 3] = [
        EventKind::Fold,
        EventKind::PeriodDoubling,
        EventKind::NeimarkSacker,
    ];

    /// Its test function on the multipliers of orbit `o`, which changes sign at the event
    /// along a branch: `det(M − I)` for a fold, `det(M + I)` for a period doubling, `det M − 1`
    /// for a Neimark–Sacker while the pair is complex; `None` for a Neimark–Sacker with a real
    /// pair or on a conservative orbit ([`Orbit::conservative`]: `det M = 1` there, the test is
    /// zero and its computed sign the integrator's error), and for a grazing (told by the
    /// orbit's impacts, not its multipliers).
    pub fn multiplier_test<T: Real>(self, o: &Orbit<T>) -> Option<f64> {
        let f = &o.floquet;
        match self {
            EventKind::Fold => Some(f.fold_test()),
            EventKind::PeriodDoubling => Some(f.doubling_test()),
            EventKind::NeimarkSacker => (f.complex() && !o.conservative()).then(|| f.torus_test()),
            EventKind::Grazing => None,
        }
    }
}

impl fmt::Display for EventKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A located bifurcation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BifEvent<T> {
    /// What it is.
    pub kind: EventKind,
    /// The parameter's value there (gap in m).
    pub value: f64,
    /// The orbit at it (for a grazing: the last orbit of the branch's `p`, within
    /// `locate_tol` of the grazing where it is bracketed; where Newton stalled before it, the
    /// last orbit reached, from whose grazing monitors `value` may be extrapolated:
    /// [`BifEvent::extrapolated`]).
    pub orbit: Orbit<T>,
    /// The critical multiplier (nearest +1 for a fold, −1 for a doubling, the pair's upper
    /// member for a torus); for a grazing the larger one.
    pub critical: Multiplier,
    /// For a grazing: the impacts per `q` periods beyond it.
    pub impacts_beyond: u32,
    /// For a fold: the changes of sign of the fold test located as folds that it stands for
    /// along the branch (one where the branch turns cleanly; several where kinks of the
    /// discretised map make the test change sign back and forth round the fold), with the span
    /// of their values; for a period doubling across a jump ([`BifEvent::at_jump`]), the
    /// test's changes at jumps it stands for.
    pub changes: Option<SignChanges>,
    /// A period doubling across a jump of the discretised map: the doubling test changed sign
    /// where the monodromy jumps (the located multiplier, [`BifEvent::critical`], is not within
    /// [`CRITICAL_TOL`] of −1) and kept its new sign for
    /// [`ContinuationSettings::fold_retreat`]: the multiplier passes −1 by a jump, not
    /// smoothly. No branch is switched onto there ([`doubling_start`]).
    pub at_jump: bool,
    /// A grazing extrapolated past the branch's last orbit (Newton stalled before it):
    /// `value` is the zero of the grazing monitors extrapolated from the last orbits, and
    /// [`BifEvent::orbit`] and [`BifEvent::critical`] are the last orbit's, at another value.
    pub extrapolated: bool,
}

/// The changes of sign of a test function along a branch that one event stands for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignChanges {
    /// How many were located as events (changes located far from the critical value,
    /// [`CRITICAL_TOL`], are not counted).
    pub count: u32,
    /// The smallest and largest parameter values at which the test changed sign (gap in m).
    pub span: [f64; 2],
}

/// Why a branch ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BranchEnd {
    /// It reached the end of the parameter range (its last point's value: on the edge,
    /// within twice the smallest step).
    RangeEnd(f64),
    /// At a grazing (the value): the orbit's impact count changes beyond it.
    Grazing(f64),
    /// The step fell below the minimum (the last value): Newton could not follow the branch.
    StepTooSmall(f64),
    /// The point budget was spent (the last value).
    MaxPoints(f64),
    /// The caller stopped it at an event (its value).
    Stopped(f64),
}

impl fmt::Display for BranchEnd {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BranchEnd::RangeEnd(v) => write!(f, "the end of the range at {v}"),
            BranchEnd::Grazing(v) => write!(f, "a grazing at {v}"),
            BranchEnd::StepTooSmall(v) => write!(f, "a step below the minimum at {v}"),
            BranchEnd::MaxPoints(v) => write!(f, "the point budget at {v}"),
            BranchEnd::Stopped(v) => write!(f, "an event at {v}"),
        }
    }
}

/// The branch's scaled frame.
#[derive(Debug, Clone, Copy)]
struct Frame {
    at: MapPoint,
    param: Param,
    q: u32,
    s: [f64; 2],
    s_lambda: f64,
}

impl Frame {
    fn point(&self, z: &[f64; 3]) -> MapPoint {
        self.at.with(self.param, z[2] * self.s_lambda)
    }

    fn state<T: Real>(&self, z: &[f64; 3]) -> Vector2<T> {
        Vector2::new(T::from_f64(z[0] * self.s[0]), T::from_f64(z[1] * self.s[1]))
    }

    fn z_of<T: Real>(&self, x: &Vector2<T>, value: f64) -> [f64; 3] {
        [
            x[0].to_f64() / self.s[0],
            x[1].to_f64() / self.s[1],
            value / self.s_lambda,
        ]
    }
}

/// An evaluation of the branch's equations at `z`.
#[derive(Debug, Clone, Copy)]
struct Eval<T> {
    f: [f64; 2],
    jac: [[f64; 3]; 2],
    orbit: Orbit<T>,
}

/// `F(z)`, `DF(z)` and the orbit data at `z`; `None` where the map cannot be evaluated.
fn evaluate<T: Real>(fr: &Frame, z: &[f64; 3], fd_step: f64) -> Option<Eval<T>> {
    let at = fr.point(z);
    let x = fr.state::<T>(z);
    let (img, m) = tangent(&at, fr.q, x).ok()?;
    let f = [
        (img.x[0].to_f64() - x[0].to_f64()) / fr.s[0],
        (img.x[1].to_f64() - x[1].to_f64()) / fr.s[1],
    ];
    // ∂F/∂λ̂ by central differences of the plain map; one-sided at the edge of the
    // parameter's domain (a gap of 0, where `λ − d` is no gap).
    let lam = z[2] * fr.s_lambda;
    let d = fd_step * fr.s_lambda;
    let plus = iterate(&fr.at.with(fr.param, lam + d), fr.q, x).ok();
    let minus = iterate(&fr.at.with(fr.param, lam - d), fr.q, x).ok();
    let (hi, lo, width) = match (plus, minus) {
        (Some(p), Some(m)) => (p.x, m.x, 2.0 * fd_step),
        (Some(p), None) => (p.x, img.x, fd_step),
        (None, Some(m)) => (img.x, m.x, fd_step),
        (None, None) => return None,
    };
    let mut jac = [[0.0; 3]; 2];
    for i in 0..2 {
        for j in 0..2 {
            let ident = if i == j { 1.0 } else { 0.0 };
            jac[i][j] = (m[i][j] - ident) * fr.s[j] / fr.s[i];
        }
        jac[i][2] = (hi[i].to_f64() - lo[i].to_f64()) / width / fr.s[i];
    }
    if !(f.iter().chain(jac.iter().flatten()).all(|v| v.is_finite())) {
        return None;
    }
    let orbit = Orbit {
        at,
        q: fr.q,
        x,
        trace: img.trace,
        monodromy: m,
        floquet: Floquet::of(&m),
        residual: scaled_norm(f, [1.0, 1.0]),
        iterations: 0,
    };
    Some(Eval { f, jac, orbit })
}

/// The unit null vector of the 2 × 3 matrix `j` (the cross product of its rows).
fn null_vector(j: &[[f64; 3]; 2]) -> Option<[f64; 3]> {
    let (a, b) = (j[0], j[1]);
    let t = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let n = libm::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    (n > 0.0 && n.is_finite()).then(|| [t[0] / n, t[1] / n, t[2] / n])
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Solves `a z = b` (3 × 3) by Gaussian elimination with partial pivoting.
fn solve3(mut a: [[f64; 3]; 3], mut b: [f64; 3]) -> Option<[f64; 3]> {
    for c in 0..3 {
        let p = (c..3).max_by(|&i, &k| a[i][c].abs().total_cmp(&a[k][c].abs()))?;
        if a[p][c].abs().partial_cmp(&1e-300) != Some(core::cmp::Ordering::Greater) {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        let pivot = a[c];
        for r in c + 1..3 {
            let f = a[r][c] / pivot[c];
            for (x, p) in a[r].iter_mut().zip(pivot).skip(c) {
                *x -= f * p;
            }
            b[r] -= f * b[c];
        }
    }
    let mut z = [0.0; 3];
    for r in (0..3).rev() {
        let s: f64 = (r + 1..3).map(|k| a[r][k] * z[k]).sum();
        z[r] = (b[r] - s) / a[r][r];
    }
    z.iter().all(|v| v.is_finite()).then_some(z)
}

/// Newton's corrector from the predictor `zp` on `F(z) = 0`, `t·(z − zp) = 0`: the corrected
/// point and its evaluation, with the iterations taken.
fn correct<T: Real>(
    fr: &Frame,
    zp: [f64; 3],
    t: &[f64; 3],
    s: &ContinuationSettings,
    fd_step: f64,
) -> Option<([f64; 3], Eval<T>, u32)> {
    let mut z = zp;
    for it in 0..s.newton.max_iterations {
        let e = evaluate::<T>(fr, &z, fd_step)?;
        let res = scaled_norm(e.f, [1.0, 1.0]);
        if res <= s.newton.tolerance {
            return Some((z, e, it));
        }
        let a = [e.jac[0], e.jac[1], *t];
        let g = [-e.f[0], -e.f[1], -(dot(t, &z) - dot(t, &zp))];
        let dz = solve3(a, g)?;
        for k in 0..3 {
            z[k] += dz[k];
        }
        if dz.iter().any(|v| v.abs() > 1.0) {
            return None;
        }
    }
    let e = evaluate::<T>(fr, &z, fd_step)?;
    (scaled_norm(e.f, [1.0, 1.0]) <= s.newton.tolerance).then_some((z, e, s.newton.max_iterations))
}

/// The state of the walk along a branch.
#[derive(Debug, Clone, Copy)]
struct Node<T> {
    z: [f64; 3],
    t: [f64; 3],
    e: Eval<T>,
}

/// The fold, doubling and Neimark–Sacker tests at `o` (NaN where one has no value).
fn tests<T: Real>(o: &Orbit<T>) -> [f64; 3] {
    EventKind::BY_MULTIPLIERS.map(|k| k.multiplier_test(o).unwrap_or(f64::NAN))
}

fn critical(kind: EventKind, f: &Floquet) -> Multiplier {
    let near = |target: f64| {
        if (f.mu[0].re - target).abs() + f.mu[0].im.abs()
            <= (f.mu[1].re - target).abs() + f.mu[1].im.abs()
        {
            f.mu[0]
        } else {
            f.mu[1]
        }
    };
    match kind {
        EventKind::Fold => near(1.0),
        EventKind::PeriodDoubling => near(-1.0),
        EventKind::NeimarkSacker | EventKind::Grazing => f.mu[0],
    }
}

/// How far a located multiplier may lie from its critical value (+1 for a fold, −1 for a
/// doubling, the unit circle for a Neimark–Sacker) for the test's change of sign to be a
/// bifurcation rather than a jump of the monodromy between two orbits of the branch.
pub const CRITICAL_TOL: f64 = 0.05;

fn critical_distance(kind: EventKind, mu: Multiplier) -> f64 {
    match kind {
        EventKind::Fold => libm::hypot(mu.re - 1.0, mu.im),
        EventKind::PeriodDoubling => libm::hypot(mu.re + 1.0, mu.im),
        EventKind::NeimarkSacker => libm::fabs(libm::hypot(mu.re, mu.im) - 1.0),
        EventKind::Grazing => 0.0,
    }
}

/// The located folds met since the fold test last held its sign for a span of the parameter
/// (or the doubling test's changes at jumps of the monodromy, [`BifEvent::at_jump`]), held back
/// as one cluster until the branch has moved [`ContinuationSettings::fold_retreat`] from the
/// farthest of them (in the parameter, the way the branch has come: from its start, or from
/// the last cluster told, to the first of them), or meets another event first, or ends; told
/// then, as its farthest, only if the test's sign is no longer the one before the cluster (at
/// a fold the critical multiplier passes +1 for good; a test changing sign and back, however
/// often and whichever changes were located, is kinks of the discretised map). One farther
/// than that from the held cluster's farthest starts a new cluster.
struct HeldCluster<E> {
    held: Option<Cluster<E>>,
    /// [`ContinuationSettings::kink_span`], scaled.
    span: f64,
    /// [`ContinuationSettings::fold_retreat`], scaled.
    retreat: f64,
    /// Where the branch has come from: its start, or the last cluster told.
    from: f64,
}

/// A cluster of located changes of a test's sign (folds, or doublings at jumps).
struct Cluster<E> {
    /// The test positive before the first.
    before: bool,
    /// The way the branch has come to the first (+1: increasing parameter, −1: decreasing).
    dir: f64,
    /// The farthest fold the way `dir` says, and its value.
    far: (f64, E),
    /// The latest fold's value.
    last: f64,
    changes: SignChanges,
}

impl<E> HeldCluster<E> {
    /// Nothing held, on a branch from `from`.
    fn new(span: f64, retreat: f64, from: f64) -> Self {
        Self {
            held: None,
            span,
            retreat,
            from,
        }
    }

    /// A new located change (a fold, or a doubling at a jump) at `value`, the test positive
    /// before it if `before` (for folds: where it last held its sign for the span): it joins
    /// the held cluster if within the retreat of its farthest; else the held one (to report now
    /// if its sign before is not `before`) gives way to a new cluster.
    fn add(&mut self, value: f64, before: bool, ev: E) -> Option<(E, SignChanges)> {
        if let Some(c) = &mut self.held
            && libm::fabs(value - c.far.0) < self.retreat
        {
            c.changes.count += 1;
            c.changes.span = [c.changes.span[0].min(value), c.changes.span[1].max(value)];
            c.last = value;
            if (value - c.far.0) * c.dir > 0.0 {
                c.far = (value, ev);
            }
            return None;
        }
        let told = self.told(before);
        let dir = if value >= self.from { 1.0 } else { -1.0 };
        self.held = Some(Cluster {
            before,
            dir,
            far: (value, ev),
            last: value,
            changes: SignChanges {
                count: 1,
                span: [value, value],
            },
        });
        told
    }

    /// The held cluster if the branch, now at `value` with the fold test positive if `now`,
    /// has moved the retreat away from its farthest fold, to report now if the test kept its
    /// new sign (else it is dropped).
    fn release_past(&mut self, value: f64, now: bool) -> Option<(E, SignChanges)> {
        let past = self
            .held
            .as_ref()
            .is_some_and(|c| libm::fabs(value - c.far.0) >= self.retreat);
        if past { self.release(now) } else { None }
    }

    /// Where the branch stalls at `value`: a cluster whose latest fold lies within the kink
    /// span is the kink that stalls it (dropped); another is released.
    fn release_at_stall(&mut self, value: f64, now: bool) -> Option<(E, SignChanges)> {
        if self
            .held
            .as_ref()
            .is_some_and(|c| libm::fabs(value - c.last) < self.span)
        {
            self.held = None;
        }
        self.release(now)
    }

    /// The held cluster, to report now if the fold test, positive if `now` at the branch's
    /// last point, kept its new sign (another event comes first, or the branch ends).
    fn release(&mut self, now: bool) -> Option<(E, SignChanges)> {
        self.told(now)
    }

    /// The held cluster taken, its farthest to report if the test's sign `now` is not the one
    /// before it (the branch has come from there since).
    fn told(&mut self, now: bool) -> Option<(E, SignChanges)> {
        let c = self.held.take()?;
        if c.before == now {
            return None;
        }
        self.from = c.far.0;
        Some((c.far.1, c.changes))
    }
}

/// Continues the branch through `start` (a converged orbit) in `settings.param`, towards
/// increasing values if `direction > 0` (else decreasing), or along `initial_tangent` if given
/// (in the scaled unknowns `(x₀/s₀, x₁/s₁, λ/s_λ)`: branch switching). Every accepted point goes
/// to `on_point` (the start first), every located bifurcation to `on_event` (in the order met;
/// [`ControlFlow::Break`] ends the branch there: [`BranchEnd::Stopped`]). Folds are told as
/// clusters: the located folds within [`ContinuationSettings::fold_retreat`] of the farthest
/// of them, told as that one (with the count and span of the cluster's sign changes in
/// [`BifEvent::changes`]) once the branch has moved that far from it, or before the next event
/// or the branch's end, if the fold test's sign is no longer the one it held for
/// [`ContinuationSettings::kink_span`] before the cluster; a cluster whose latest fold lies
/// within the kink span of where the branch stalls is the kink that stalls it. Changes of the
/// test's sign that are undone are kinks of the discretised map and are not told.
pub fn continue_branch<T: Real>(
    start: &Orbit<T>,
    settings: &ContinuationSettings,
    direction: f64,
    initial_tangent: Option<[f64; 3]>,
    on_point: impl FnMut(&BranchPoint<T>),
    on_event: impl FnMut(&BifEvent<T>) -> ControlFlow<()>,
) -> BranchEnd {
    match Branch::start(
        start,
        settings,
        direction,
        initial_tangent,
        on_point,
        on_event,
    ) {
        Ok(mut branch) => branch.run(),
        Err(end) => end,
    }
}

/// A branch being continued ([`continue_branch`]): its frame, its last point and the points
/// before it, the held folds and doublings, the step, and where its points and events go. Each
/// step of the walk is a method; one that ends the branch breaks with the end
/// ([`ControlFlow::Break`]).
struct Branch<'s, T: Real, P, E> {
    settings: &'s ContinuationSettings,
    fr: Frame,
    fd_step: f64,
    /// Started along a given tangent (a branch switch).
    switched: bool,
    on_point: P,
    on_event: E,
    /// The branch's last accepted point.
    node: Node<T>,
    /// The point before it (none at the start).
    previous: Option<Node<T>>,
    /// The branch's points before `node`, a few of them (the grazing monitors' base).
    history: heapless::Deque<Node<T>, 8>,
    /// Folds, held as clusters ([`HeldCluster`]).
    held: HeldCluster<BifEvent<T>>,
    /// Period doublings across jumps of the monodromy, held as folds are.
    held_doubling: HeldCluster<BifEvent<T>>,
    /// The fold test's sign where it last held for a span of the parameter.
    settled: bool,
    /// Where the fold test last changed sign (a located fold or not).
    last_change: Option<f64>,
    /// The next step's length (scaled).
    h: f64,
}

/// Whether the fold test is positive at `n`.
fn fold_positive<T: Real>(n: &Node<T>) -> bool {
    n.e.orbit.floquet.fold_test() > 0.0
}

/// Whether the period-doubling test is positive at `n`.
fn doubling_positive<T: Real>(n: &Node<T>) -> bool {
    n.e.orbit.floquet.doubling_test() > 0.0
}

impl<'s, T: Real, P, E> Branch<'s, T, P, E>
where
    P: FnMut(&BranchPoint<T>),
    E: FnMut(&BifEvent<T>) -> ControlFlow<()>,
{
    /// The branch at `start` (reported to `on_point`), its tangent oriented by `direction` or
    /// given; the end where the start cannot be evaluated or has no tangent.
    fn start(
        start: &Orbit<T>,
        settings: &'s ContinuationSettings,
        direction: f64,
        initial_tangent: Option<[f64; 3]>,
        mut on_point: P,
        on_event: E,
    ) -> Result<Self, BranchEnd> {
        let s_lambda = match settings.param {
            Param::OmegaRatio => 1.0,
            Param::GapM => start.at.params.amplitude_m,
        };
        let fr = Frame {
            at: start.at,
            param: settings.param,
            q: start.q,
            s: start.at.scales(),
            s_lambda,
        };
        let fd_step = if T::EPSILON < 1e-10 { 1e-6 } else { 1e-3 };
        let value0 = start.at.get(settings.param);
        let z0 = fr.z_of(&start.x, value0);
        let Some(e0) = evaluate::<T>(&fr, &z0, fd_step) else {
            return Err(BranchEnd::StepTooSmall(value0));
        };
        let Some(mut t0) = initial_tangent.or_else(|| null_vector(&e0.jac)) else {
            return Err(BranchEnd::StepTooSmall(value0));
        };
        if initial_tangent.is_none() && t0[2] * direction < 0.0 {
            t0 = t0.map(|v| -v);
        }
        let node = Node {
            z: z0,
            t: t0,
            e: e0,
        };
        let mut first = *start;
        first.at = fr.point(&z0);
        on_point(&BranchPoint {
            value: value0,
            orbit: first,
        });
        let cluster = || {
            HeldCluster::new(
                settings.kink_span * s_lambda,
                settings.fold_retreat * s_lambda,
                value0,
            )
        };
        Ok(Self {
            settings,
            fr,
            fd_step,
            switched: initial_tangent.is_some(),
            on_point,
            on_event,
            node,
            previous: None,
            history: heapless::Deque::new(),
            held: cluster(),
            held_doubling: cluster(),
            settled: fold_positive(&node),
            last_change: None,
            h: settings.steps.first,
        })
    }

    /// The branch's points to its end: within the point budget, each step taken, its grazing
    /// and multiplier events told, and the point accepted.
    fn run(&mut self) -> BranchEnd {
        match self.walk() {
            ControlFlow::Break(end) => end,
            ControlFlow::Continue(()) => {
                let value = self.node.z[2] * self.fr.s_lambda;
                match self.release_all(self.node) {
                    ControlFlow::Break(end) => end,
                    ControlFlow::Continue(()) => BranchEnd::MaxPoints(value),
                }
            }
        }
    }

    /// [`Branch::run`]'s steps until one ends the branch, or the point budget is spent.
    fn walk(&mut self) -> ControlFlow<BranchEnd> {
        for _ in 0..self.settings.max_points {
            let (b, iters, h_step) = self.step()?;
            self.grazing_between(&b, h_step)?;
            let fold_changed = self.multiplier_events(&b, h_step)?;
            self.release_past(b.z[2] * self.fr.s_lambda, b)?;
            self.accept(b, iters, fold_changed);
        }
        ControlFlow::Continue(())
    }

    /// A step: predict, correct, check the tangent turned little and the corrected point is in
    /// the range, halving the step until one is taken: the point, Newton's iterations and the
    /// step's length. A step below the smallest ends the branch: at the range's end, at a
    /// grazing (Newton cannot follow the branch where the map's derivative is singular), or
    /// there.
    fn step(&mut self) -> ControlFlow<BranchEnd, (Node<T>, u32, f64)> {
        let (settings, s_lambda) = (self.settings, self.fr.s_lambda);
        let value_a = self.node.z[2] * s_lambda;
        // (With the rounding of an edge's value scaled and back.)
        let slack = 1e-12 * (settings.range[1] - settings.range[0]).abs();
        let in_range = |v: f64| v >= settings.range[0] - slack && v <= settings.range[1] + slack;
        loop {
            // A step whose prediction would leave the range is shortened to end on its edge
            // (`edge`, scaled), where it is corrected at that value: a branch reaches the
            // range's end rather than stopping a step short.
            let (h_step, edge) = step_to_edge(settings.range, &self.node, self.h, s_lambda);
            if settings.steps.below_min(h_step) {
                // At the range's edge heading out of it (the step to the edge below the
                // smallest, or gap 0 going down where it is 0): the range's end.
                let reach = 2.0 * settings.steps.min * s_lambda;
                if at_edge_heading_out(settings.range, value_a, self.node.t[2], reach) {
                    self.release_all(self.node)?;
                    return ControlFlow::Break(BranchEnd::RangeEnd(value_a));
                }
                // A fold within the span of where the branch stalls is the kink that stalls
                // it: not told.
                self.release_at_stall(value_a, self.node)?;
                // Newton cannot follow the branch: at a grazing the map's derivative is
                // singular (an impact about to appear or vanish), said as such.
                if let Some((value, beyond, extrapolated)) =
                    grazing_end(&self.fr, settings, &self.node, self.history.front())
                {
                    let orbit = self.node.e.orbit;
                    let _ = (self.on_event)(&BifEvent {
                        kind: EventKind::Grazing,
                        value,
                        orbit,
                        critical: critical(EventKind::Grazing, &orbit.floquet),
                        impacts_beyond: beyond,
                        changes: None,
                        at_jump: false,
                        extrapolated,
                    });
                    return ControlFlow::Break(BranchEnd::Grazing(value));
                }
                return ControlFlow::Break(BranchEnd::StepTooSmall(value_a));
            }
            let node = &self.node;
            let zp = [
                node.z[0] + h_step * node.t[0],
                node.z[1] + h_step * node.t[1],
                edge.unwrap_or(node.z[2] + h_step * node.t[2]),
            ];
            let across = if edge.is_some() {
                [0.0, 0.0, 1.0]
            } else {
                node.t
            };
            match correct::<T>(&self.fr, zp, &across, settings, self.fd_step) {
                Some((z, e, iters)) => {
                    let Some(mut t) = null_vector(&e.jac) else {
                        self.h = h_step * 0.5;
                        continue;
                    };
                    if dot(&t, &node.t) < 0.0 {
                        t = t.map(|v| -v);
                    }
                    // A corrected point outside the range (the corrector moves across the
                    // tangent) is retried shorter, as a turn too sharp is.
                    if dot(&t, &node.t) < MIN_TURN_COSINE || !in_range(z[2] * s_lambda) {
                        self.h = h_step * 0.5;
                        continue;
                    }
                    return ControlFlow::Continue((Node { z, t, e }, iters, h_step));
                }
                None => self.h = h_step * 0.5,
            }
        }
    }

    /// A grazing between the last point and `b` (the step `h_step` to it): the impact count
    /// changed, located between them and told; it ends the branch.
    fn grazing_between(&mut self, b: &Node<T>, h_step: f64) -> ControlFlow<BranchEnd> {
        let impacts = self.node.e.orbit.trace.impacts;
        if b.e.orbit.trace.impacts == impacts {
            return ControlFlow::Continue(());
        }
        let (ev, _) = locate(
            &self.fr,
            &self.node,
            h_step,
            self.settings,
            self.fd_step,
            |e, _| e.orbit.trace.impacts == impacts,
        );
        let value = ev.z[2] * self.fr.s_lambda;
        self.release_all(self.node)?;
        let _ = (self.on_event)(&BifEvent {
            kind: EventKind::Grazing,
            value,
            orbit: ev.e.orbit,
            critical: critical(EventKind::Grazing, &ev.e.orbit.floquet),
            impacts_beyond: b.e.orbit.trace.impacts,
            changes: None,
            at_jump: false,
            extrapolated: false,
        });
        ControlFlow::Break(BranchEnd::Grazing(value))
    }

    /// The multiplier events between the last point and `b`: each test that changed sign
    /// located, told in the order met (folds held as clusters, doublings at a jump of the
    /// monodromy held likewise, a change far from its critical multiplier otherwise dropped);
    /// whether the fold test changed sign.
    fn multiplier_events(&mut self, b: &Node<T>, h_step: f64) -> ControlFlow<BranchEnd, bool> {
        let value_a = self.node.z[2] * self.fr.s_lambda;
        // After a branch switch the start is a pitchfork of `P^q` (a multiplier at +1 there by
        // construction): the first step's fold test is not an event.
        let (mut ta, tb) = (tests(&self.node.e.orbit), tests(&b.e.orbit));
        if self.switched && self.previous.is_none() {
            ta[0] = f64::NAN;
        }
        let mut found: heapless::Vec<BifEvent<T>, 3> = heapless::Vec::new();
        for (k, kind) in [
            EventKind::Fold,
            EventKind::PeriodDoubling,
            EventKind::NeimarkSacker,
        ]
        .into_iter()
        .enumerate()
        {
            if ta[k].is_finite() && tb[k].is_finite() && (ta[k] > 0.0) != (tb[k] > 0.0) {
                let side_a = ta[k] > 0.0;
                let (ev, _) = locate(
                    &self.fr,
                    &self.node,
                    h_step,
                    self.settings,
                    self.fd_step,
                    |e, _| {
                        let v = tests(&e.orbit)[k];
                        !v.is_finite() || (v > 0.0) == side_a
                    },
                );
                let mu = critical(kind, &ev.e.orbit.floquet);
                let event = BifEvent {
                    kind,
                    value: ev.z[2] * self.fr.s_lambda,
                    orbit: ev.e.orbit,
                    critical: mu,
                    impacts_beyond: ev.e.orbit.trace.impacts,
                    changes: None,
                    at_jump: false,
                    extrapolated: false,
                };
                // A test function can also change sign by a jump of the monodromy (a kink of
                // the discretised map): the located multiplier is then far from its critical
                // value, and that is no bifurcation, unless the doubling test keeps its new
                // sign (held as folds are: the multiplier went past −1 by the jump).
                if critical_distance(kind, mu) > CRITICAL_TOL {
                    if kind == EventKind::PeriodDoubling {
                        let at_jump = BifEvent {
                            at_jump: true,
                            ..event
                        };
                        let released = self.held_doubling.add(event.value, side_a, at_jump);
                        self.tell(released)?;
                    }
                    continue;
                }
                let _ = found.push(event);
            }
        }
        // In the order met along the step.
        found.sort_unstable_by(|x, y| {
            (x.value - value_a)
                .abs()
                .total_cmp(&(y.value - value_a).abs())
        });
        for ev in found {
            if ev.kind == EventKind::Fold {
                let released = self.held.add(ev.value, self.settled, ev);
                self.tell(released)?;
            } else {
                self.release_all(*b)?;
                if (self.on_event)(&ev).is_break() {
                    return ControlFlow::Break(BranchEnd::Stopped(ev.value));
                }
            }
        }
        ControlFlow::Continue(ta[0].is_finite() && (ta[0] > 0.0) != (tb[0] > 0.0))
    }

    /// `b` (the step to it taken in `iters` Newton iterations) as the branch's next point:
    /// where the fold test last settled or changed (`fold_changed`), the point reported, the
    /// history kept, and the next step's length.
    fn accept(&mut self, b: Node<T>, iters: u32, fold_changed: bool) {
        let value_b = b.z[2] * self.fr.s_lambda;
        if fold_changed {
            self.last_change = Some(value_b);
        } else if self
            .last_change
            .is_none_or(|c| libm::fabs(value_b - c) >= self.held.span)
        {
            self.settled = fold_positive(&b);
        }
        (self.on_point)(&BranchPoint {
            value: value_b,
            orbit: b.e.orbit,
        });
        self.previous = Some(self.node);
        if self.history.is_full() {
            let _ = self.history.pop_front();
        }
        let _ = self.history.push_back(self.node);
        self.node = b;
        self.h = if iters <= 2 {
            (self.h * 1.5).min(self.settings.steps.max)
        } else if iters >= 5 {
            self.h * 0.7
        } else {
            self.h
        };
    }

    /// Tells a held cluster that was let go (`released`, if it tells one); the branch ends
    /// there if the caller stops it.
    fn tell(&mut self, released: Option<(BifEvent<T>, SignChanges)>) -> ControlFlow<BranchEnd> {
        if let Some((mut ev, changes)) = released {
            ev.changes = Some(changes);
            if (self.on_event)(&ev).is_break() {
                return ControlFlow::Break(BranchEnd::Stopped(ev.value));
            }
        }
        ControlFlow::Continue(())
    }

    /// Tells everything both holders hold, at the branch's point `n` (another event comes, or
    /// the branch ends).
    fn release_all(&mut self, n: Node<T>) -> ControlFlow<BranchEnd> {
        let released = self.held.release(fold_positive(&n));
        self.tell(released)?;
        let released = self.held_doubling.release(doubling_positive(&n));
        self.tell(released)
    }

    /// Tells what both holders let go once the branch, at `n` (its value `value`), has moved
    /// the retreat past it ([`HeldCluster::release_past`]).
    fn release_past(&mut self, value: f64, n: Node<T>) -> ControlFlow<BranchEnd> {
        let released = self.held.release_past(value, fold_positive(&n));
        self.tell(released)?;
        let released = self
            .held_doubling
            .release_past(value, doubling_positive(&n));
        self.tell(released)
    }

    /// Tells what both holders let go where the branch stalls at `n` (its value `value`;
    /// [`HeldCluster::release_at_stall`]).
    fn release_at_stall(&mut self, value: f64, n: Node<T>) -> ControlFlow<BranchEnd> {
        let released = self.held.release_at_stall(value, fold_positive(&n));
        self.tell(released)?;
        let released = self
            .held_doubling
            .release_at_stall(value, doubling_positive(&n));
        self.tell(released)
    }
}

/// The step from `node` along its tangent: `h`, or, where the prediction at `h` would leave
/// `range` (parameter units; `s_lambda`, the parameter's scale), the shorter step that ends on
/// the edge it heads for (0 or less where `node` lies on that edge already) with that edge's
/// scaled value.
fn step_to_edge<T>(range: [f64; 2], node: &Node<T>, h: f64, s_lambda: f64) -> (f64, Option<f64>) {
    let dz = node.t[2];
    let predicted = (node.z[2] + h * dz) * s_lambda;
    let edge = if dz > 0.0 && predicted > range[1] {
        range[1]
    } else if dz < 0.0 && predicted < range[0] {
        range[0]
    } else {
        return (h, None);
    };
    let edge = edge / s_lambda;
    ((edge - node.z[2]) / dz, Some(edge))
}

/// Whether `value` lies at an end of `range` (within `reach`, twice the smallest step in the
/// parameter's units, or 10⁻⁹ of the range's width) and `dvalue`, the tangent's component in
/// the parameter, points out of the range there: the step left to the edge
/// ([`step_to_edge`]) is below the smallest, or the steps that stalled there were the ones
/// that headed for it.
fn at_edge_heading_out(range: [f64; 2], value: f64, dvalue: f64, reach: f64) -> bool {
    let eps = (1e-9 * (range[1] - range[0]).abs()).max(reach);
    (dvalue < 0.0 && value <= range[0] + eps) || (dvalue > 0.0 && value >= range[1] - eps)
}

/// Whether a branch whose steps fell below the minimum at `last` ends at a grazing, where, and
/// the impacts per period beyond it. The monitors, in units of the cart's motion: the free
/// flight's closest approach `g = δ_max/A0` (an impact appears at `g = 0`), and the slowest
/// arrival `g = −(v/(A0 Ω))²` (one vanishes; its square is linear in the parameter). The one
/// nearer 0 must lie within `settings.grazing_near` of it (the arrival's within 9× that: `v`
/// within `3 √near` of `A0 Ω`); the grazing is its zero extrapolated linearly from `base` (up
/// to eight points back: the stalled steps are short) through the last point if that lies ahead
/// within four times their distance (then said extrapolated: the third value), else the last
/// value.
fn grazing_end<T: Real>(
    fr: &Frame,
    s: &ContinuationSettings,
    last: &Node<T>,
    base: Option<&Node<T>>,
) -> Option<(f64, u32, bool)> {
    let a0 = fr.at.params.amplitude_m;
    let v0 = a0 * fr.at.omega_ratio * fr.at.params.omega_n();
    // (monitor value, an impact appears)
    let monitor = |n: &Node<T>| {
        let t = &n.e.orbit.trace;
        let free = t.closest_free_m / a0;
        let arrival = if t.slowest_arrival_m_s.is_finite() {
            -(t.slowest_arrival_m_s / v0) * (t.slowest_arrival_m_s / v0)
        } else {
            f64::NEG_INFINITY
        };
        if free >= arrival {
            (free, true)
        } else {
            (arrival, false)
        }
    };
    let (g1, appears) = monitor(last);
    // The arrival monitor is a square: its threshold is one on `v/(A0 Ω)` of 3 √near.
    let near = if appears {
        s.grazing_near
    } else {
        9.0 * s.grazing_near
    };
    if g1.is_nan() || g1 <= -near {
        return None;
    }
    let impacts = last.e.orbit.trace.impacts;
    let beyond = if appears {
        impacts + 1
    } else {
        impacts.saturating_sub(1)
    };
    let v1 = last.z[2] * fr.s_lambda;
    let Some(b) = base else {
        return Some((v1, beyond, false));
    };
    let (g0, same) = monitor(b);
    let v0b = b.z[2] * fr.s_lambda;
    if same != appears || g1 == g0 {
        return Some((v1, beyond, false));
    }
    let zero = v1 - g1 * (v1 - v0b) / (g1 - g0);
    let ahead = (zero - v1) * (v1 - v0b) >= 0.0 && (zero - v1).abs() <= 4.0 * (v1 - v0b).abs();
    Some(if zero.is_finite() && ahead {
        (zero, beyond, zero != v1)
    } else {
        (v1, beyond, false)
    })
}

/// Bisects the step from `a` (where `same(a)` holds) to the step `h` (where it does not) until
/// the parameter is known to `locate_tol`; returns the last point where `same` holds, and the
/// first where it does not.
fn locate<T: Real>(
    fr: &Frame,
    a: &Node<T>,
    h: f64,
    s: &ContinuationSettings,
    fd_step: f64,
    same: impl Fn(&Eval<T>, &[f64; 3]) -> bool,
) -> (Node<T>, f64) {
    let (mut lo, mut hi) = (0.0, h);
    let mut best = *a;
    let mut beyond = h;
    for _ in 0..60 {
        let lam_lo = (a.z[2] + lo * a.t[2]) * fr.s_lambda;
        let lam_hi = (a.z[2] + hi * a.t[2]) * fr.s_lambda;
        if (lam_hi - lam_lo).abs() <= s.locate_tol && hi - lo < 1e-3 {
            break;
        }
        if hi - lo < 1e-14 {
            break;
        }
        let mid = 0.5 * (lo + hi);
        let zp = [
            a.z[0] + mid * a.t[0],
            a.z[1] + mid * a.t[1],
            a.z[2] + mid * a.t[2],
        ];
        match correct::<T>(fr, zp, &a.t, s, fd_step) {
            Some((z, e, _)) if same(&e, &z) => {
                lo = mid;
                best = Node { z, t: a.t, e };
            }
            _ => {
                hi = mid;
                beyond = mid;
            }
        }
    }
    (best, beyond)
}

/// Branch switching at a period doubling (`event`, of a branch of period `q`): the orbit of
/// period `2q` at the doubling point (the same state: a fixed point of `P^{2q}` too) with the
/// tangent of the doubled branch there, the critical eigenvector at fixed parameter (in the
/// scaled unknowns of [`continue_branch`]: `(v₀/s₀, v₁/s₁, 0)`, `s` the cart's scales). The
/// doubled branch is the other half of `P^{2q}`'s pitchfork (Kuznetsov 2004, §10.3); pass both
/// to [`continue_branch`]. `None` if `event` is not a period doubling, is one across a jump
/// ([`BifEvent::at_jump`]: no multiplier at −1 to take the eigenvector of), `2q` exceeds
/// [`super::map::MAX_Q`] or the map cannot be evaluated.
pub fn doubling_start<T: Real>(event: &BifEvent<T>) -> Option<(Orbit<T>, [f64; 3])> {
    if event.kind != EventKind::PeriodDoubling
        || event.at_jump
        || 2 * event.orbit.q > super::map::MAX_Q
    {
        return None;
    }
    let o = &event.orbit;
    let v = Floquet::eigenvector(&o.monodromy, event.critical.re)?;
    let s = o.at.scales();
    let t = [v[0] / s[0], v[1] / s[1], 0.0];
    let n = libm::sqrt(t[0] * t[0] + t[1] * t[1]);
    let (img, m) = tangent(&o.at, 2 * o.q, o.x).ok()?;
    let f = [
        img.x[0].to_f64() - o.x[0].to_f64(),
        img.x[1].to_f64() - o.x[1].to_f64(),
    ];
    let doubled = Orbit {
        at: o.at,
        q: 2 * o.q,
        x: o.x,
        trace: img.trace,
        monodromy: m,
        floquet: Floquet::of(&m),
        residual: scaled_norm(f, s),
        iterations: 0,
    };
    Some((doubled, [t[0] / n, t[1] / n, 0.0]))
}

#[cfg(test)]
mod tests {
    use super::{HeldCluster, SignChanges};

    fn changes(count: u32, span: [f64; 2]) -> SignChanges {
        SignChanges { count, span }
    }

    #[test]
    fn a_held_fold_is_told_once_the_branch_is_the_retreat_past_it() {
        let mut held = HeldCluster::new(1e-5, 1e-2, 1.0);
        assert_eq!(held.add(2.0, true, 'a'), None);
        // Still within the retreat: held.
        assert_eq!(held.release_past(2.0 + 0.5e-2, false), None);
        assert_eq!(held.release_past(2.0 - 0.9e-2, false), None);
        // The retreat past it, either way: told once.
        let told = held.release_past(2.0 - 1.5e-2, false);
        assert_eq!(told, Some(('a', changes(1, [2.0, 2.0]))));
        assert_eq!(held.release_past(2.1, false), None);
        assert_eq!(held.release(true), None);
    }

    #[test]
    fn a_fold_whose_test_changed_sign_back_is_not_told() {
        let mut held = HeldCluster::new(1e-5, 1e-2, 1.0);
        // The test positive before the fold and positive again past it.
        assert_eq!(held.add(2.0, true, 'a'), None);
        assert_eq!(held.release_past(2.0 - 1.5e-2, true), None);
        assert_eq!(held.release(false), None, "dropped, not held");
        // Released by another event or the branch's end: the same rule.
        assert_eq!(held.add(2.0, false, 'b'), None);
        assert_eq!(held.release(false), None);
        assert_eq!(held.add(2.0, false, 'c'), None);
        assert_eq!(held.release(true), Some(('c', changes(1, [2.0, 2.0]))));
        // A next fold farther than the retreat whose test before it has the sign the held one
        // had before it: the held one's change was undone between them.
        assert_eq!(held.add(2.0, true, 'd'), None);
        assert_eq!(held.add(2.1, true, 'e'), None);
        let told = held.add(2.2, false, 'f');
        assert_eq!(told, Some(('e', changes(1, [2.1, 2.1]))));
    }

    /// The branch zig-zags over kinks on its way up to a fold at 1.8279 and on its way back
    /// (the fold test changing sign at each turn): one fold, the farthest, with every change.
    #[test]
    fn a_cluster_of_folds_is_one_fold_at_its_farthest() {
        let mut held = HeldCluster::new(1e-5, 1e-2, 1.0);
        let turns = [
            1.8233, 1.82349, 1.82361, 1.82359, 1.8279, 1.8277, 1.8275, 1.8264,
        ];
        for (k, v) in turns.into_iter().enumerate() {
            // (The test negative before the cluster.)
            assert_eq!(held.add(v, false, k), None);
        }
        // Back 0.01 from 1.8279 with the test positive (an odd count of changes): told.
        assert_eq!(held.release_past(1.8200, true), None);
        let told = held.release_past(1.8178, true);
        assert_eq!(told, Some((4, changes(8, [1.8233, 1.8279]))));
        // The same going down: the farthest is the smallest value.
        for (k, v) in [1.5, 1.4995, 1.4998].into_iter().enumerate() {
            assert_eq!(held.add(v, true, k), None);
        }
        assert_eq!(held.release(false), Some((1, changes(3, [1.4995, 1.5]))));
        // The farthest the way the branch has come (from its start at 1.0 up), whichever way it
        // moved at the first change: Lankarani–Nikravesh at 2.4 mm, the upper edge.
        let mut held = HeldCluster::new(1e-5, 1e-2, 1.0);
        for (k, v) in [1.79686, 1.79000, 1.79776, 1.79300].into_iter().enumerate() {
            assert_eq!(held.add(v, false, k), None);
        }
        assert_eq!(held.release(true), Some((2, changes(4, [1.79, 1.79776]))));
    }

    #[test]
    fn two_folds_that_undo_each_other_are_a_zig_zag_and_neither_is_told() {
        let mut held = HeldCluster::new(1e-5, 1e-2, 1.0);
        assert_eq!(held.add(2.0, true, 'a'), None);
        assert_eq!(held.add(2.0 + 0.3e-5, true, 'b'), None);
        assert_eq!(held.release(true), None);
        assert_eq!(held.release_past(3.0, true), None);
        // Two folds farther apart than the retreat: the first is told when the second comes,
        // the second held.
        assert_eq!(held.add(2.0, true, 'c'), None);
        let told = held.add(2.0 + 2e-2, false, 'd');
        assert_eq!(told, Some(('c', changes(1, [2.0, 2.0]))));
        assert_eq!(held.release(true), Some(('d', changes(1, [2.02, 2.02]))));
    }

    #[test]
    fn a_fold_within_the_kink_span_of_a_stall_is_not_told() {
        let mut held = HeldCluster::new(1e-5, 1e-2, 1.0);
        assert_eq!(held.add(2.0, true, 'a'), None);
        assert_eq!(held.release_at_stall(2.0 - 0.5e-5, false), None);
        assert_eq!(held.add(2.0, true, 'b'), None);
        assert_eq!(
            held.release_at_stall(2.0 - 5e-5, false),
            Some(('b', changes(1, [2.0, 2.0])))
        );
    }
}

//! One whole RK4 step in free flight and the test that accepts it in one piece: the kernel of
//! both [`super::Simulator::step`]'s first try and the lockstep lanes ([`super::lanes`]), so
//! that the two take the same steps bit for bit.
//!
//! The step is accepted if the hammer stays clear of the surface: `δ ≤ −η_δ` at every RK4
//! stage and at the end, and, if the step turned round (`δ̇` from positive to negative), the
//! peak bound under the two tangent lines stays below `−η_δ` too.

use nalgebra::Vector2;

use super::rk4::rk4_step;
use crate::model::hammer::{BeamFree, FreeFlight, Viscous, WiresFree};
use crate::real::Real;

/// The state a free-flight step carries: `x = (x0, x1)`, the field's second component `a` at
/// `x`, the penetration `d` (m) and its rate `dd` (m/s).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct FreeState<T> {
    pub(crate) x0: T,
    pub(crate) x1: T,
    pub(crate) a: T,
    pub(crate) d: T,
    pub(crate) dd: T,
}

/// Which `(sin θ, cos θ)` the wire pendulum's field takes, and whether it is exact there.
pub(crate) trait Trig {
    /// Whether a step's RK4 stages are inlined by force on the host: the stepper's steps one at
    /// a time, whose stages the compiler otherwise leaves as calls (the lanes inline theirs,
    /// and forcing it there changes their vector code for the worse).
    const INLINE_STAGES: bool;
    /// `(sin x, cos x, exact)`.
    fn sin_cos<T: Real>(x: T) -> (T, T, bool);
}

/// [`Real::sin_cos`]: exact at every angle (the stepper).
pub(crate) struct FullTrig;

impl Trig for FullTrig {
    // (The MCU keeps one copy of a stage for flash: `stage`.)
    const INLINE_STAGES: bool = cfg!(feature = "std");
    #[inline(always)]
    fn sin_cos<T: Real>(x: T) -> (T, T, bool) {
        let (s, c) = x.sin_cos();
        (s, c, true)
    }
}

/// [`Real::sin_cos_small`]: branch-free, exact (bit for bit [`Real::sin_cos`]) for
/// `|x| ≤ 1/8` only, which it reports (the lanes).
pub(crate) struct SmallTrig;

impl Trig for SmallTrig {
    const INLINE_STAGES: bool = false;
    #[inline(always)]
    fn sin_cos<T: Real>(x: T) -> (T, T, bool) {
        let (s, c) = x.sin_cos_small();
        let lim = T::from_f64(0.125);
        (s, c, (x <= lim) & (x >= -lim))
    }
}

/// The free-flight field of one suspension, as a step evaluates it: [`WiresFree`] and
/// [`BeamFree`] (the suspension known at compile time: the lanes, one kernel per suspension)
/// or [`FreeFlight`] (known at run time: the stepper, one kernel for both).
pub(crate) trait FreeField<T: Real>: Copy {
    /// The field at `(y0, y1)` with `sin Ωt = sin_phase`: `(acceleration, δ, δ̇, exact)`,
    /// `exact` saying whether `G`'s sine was exact there; the pendulum's viscous term as `V`
    /// has it (the beams' damping is always in their field).
    fn field<G: Trig, V: Viscous>(&self, y0: T, y1: T, sin_phase: T) -> (T, T, T, bool);
}

impl<T: Real> FreeField<T> for WiresFree<T> {
    #[inline(always)]
    fn field<G: Trig, V: Viscous>(&self, y0: T, y1: T, sin_phase: T) -> (T, T, T, bool) {
        let (st, ct, exact) = G::sin_cos(y0);
        let (a, d, dd) = self.eval::<V>(y1, (st, ct), sin_phase);
        (a, d, dd, exact)
    }
}

impl<T: Real> FreeField<T> for BeamFree<T> {
    #[inline(always)]
    fn field<G: Trig, V: Viscous>(&self, y0: T, y1: T, sin_phase: T) -> (T, T, T, bool) {
        let (a, d, dd) = self.eval(y0, y1, sin_phase);
        (a, d, dd, true)
    }
}

impl<T: Real> FreeField<T> for FreeFlight<T> {
    #[inline(always)]
    fn field<G: Trig, V: Viscous>(&self, y0: T, y1: T, sin_phase: T) -> (T, T, T, bool) {
        match self {
            FreeFlight::Wires(w) => w.field::<G, V>(y0, y1, sin_phase),
            FreeFlight::Beam(b) => b.field::<G, V>(y0, y1, sin_phase),
        }
    }
}

/// One RK4 stage's field `(y1, acceleration)`, noting whether it came within `−neg_eta` of the
/// surface and whether it was exact. (On the MCU one copy that the stages call: flash; on the
/// host inlined.)
#[cfg_attr(feature = "std", inline(always))]
#[cfg_attr(not(feature = "std"), inline(never))]
fn stage<T: Real, F: FreeField<T>, G: Trig, V: Viscous>(
    c: &F,
    y: &Vector2<T>,
    s: T,
    neg_eta: T,
    touched: &mut bool,
    exact: &mut bool,
) -> Vector2<T> {
    let (a, d, _, ok) = c.field::<G, V>(y[0], y[1], s);
    *touched |= d > neg_eta;
    *exact &= ok;
    Vector2::new(y[1], a)
}

/// One RK4 step of `h` seconds in free flight from `st`, with `sin Ωt` `s_mid`, `s_end` at
/// the midpoint and the end: the end state, whether every field evaluation was exact (`G`),
/// whether a stage or the end came within `eta` of the surface, and whether the step turned
/// round (then [`peak_near`] tests its peak; [`free_step`] takes both). The pendulum's viscous
/// term as `V` has it.
#[inline(always)]
pub(crate) fn free_step_parts<T: Real, F: FreeField<T>, G: Trig, V: Viscous>(
    c: &F,
    st: &FreeState<T>,
    h: T,
    s_mid: T,
    s_end: T,
    eta: T,
) -> (FreeState<T>, bool, bool, bool) {
    let neg_eta = -eta;
    let mut touched = false;
    let mut exact = true;
    let (x, k1) = (Vector2::new(st.x0, st.x1), Vector2::new(st.x1, st.a));
    let x1 = if G::INLINE_STAGES {
        rk4_step(
            &x,
            &k1,
            h,
            s_mid,
            s_end,
            #[inline(always)]
            |y, s| stage::<T, F, G, V>(c, y, s, neg_eta, &mut touched, &mut exact),
        )
    } else {
        rk4_step(&x, &k1, h, s_mid, s_end, |y, s| {
            stage::<T, F, G, V>(c, y, s, neg_eta, &mut touched, &mut exact)
        })
    };
    let (a, d, dd, ok) = c.field::<G, V>(x1[0], x1[1], s_end);
    let near = touched | (d > neg_eta);
    // Turned round inside the step: the peak lies under the two tangent lines.
    let turned = (st.dd > T::zero()) & (dd < T::zero());
    let next = FreeState {
        x0: x1[0],
        x1: x1[1],
        a,
        d,
        dd,
    };
    (next, exact & ok, near, turned)
}

/// Whether the peak of a step that turned round (from `start` to `end`, `h` seconds) lies
/// above `neg_eta` under the two tangent lines ([`free_step`]'s last test).
#[inline(always)]
pub(crate) fn peak_near<T: Real>(
    start: &FreeState<T>,
    end: &FreeState<T>,
    h: T,
    neg_eta: T,
) -> bool {
    let t_star = (end.d - start.d - end.dd * h) / (start.dd - end.dd);
    start.d + start.dd * t_star > neg_eta
}

/// [`free_step_parts`] with the peak test: the end state, whether every field evaluation was
/// exact (`G`), and whether the step comes within `eta` of the surface (then
/// [`super::Simulator::step`] splits it; module docs).
#[inline(always)]
pub(crate) fn free_step<T: Real, F: FreeField<T>, G: Trig, V: Viscous>(
    c: &F,
    st: &FreeState<T>,
    h: T,
    s_mid: T,
    s_end: T,
    eta: T,
) -> (FreeState<T>, bool, bool) {
    let (next, exact, near, turned) = free_step_parts::<T, F, G, V>(c, st, h, s_mid, s_end, eta);
    (next, exact, near | (turned & peak_near(st, &next, h, -eta)))
}

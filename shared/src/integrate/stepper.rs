//! The period-locked switch-model integrator.
//!
//! - `N` RK4 steps per excitation period, `h = T/N`, so the stroboscopic Poincaré section
//!   `t = kT` falls exactly on step boundaries.
//! - Time is an integer step index plus an offset inside the step; the excitation
//!   `sin Ωt` at the step's start, midpoint and end comes from a table of `2N` values computed
//!   once, and inside a step from the angle-addition formula with a short polynomial
//!   ([`Real::sin_cos`]), so there is no `t += h` drift in f32.
//! - A step is first tried in one piece in free flight. It is accepted if the hammer stays
//!   clear of the surface (`δ ≤ −η_δ` at both ends, no RK4 stage touched the contact region,
//!   and, if the step turned round, its tangent-line peak bound stays below `−η_δ`).
//! - Otherwise the step is split at the time the trial's cubic Hermite dense output first comes
//!   within `η_δ` of the surface (or peaks): one free-flight RK4 step up to half a contact
//!   sub-step before it, then sub-steps of `h_c = (π/ω_c)/K` with the full switch model while the hammer
//!   is in or near contact (`ω_c` the contact frequency,
//!   [`crate::model::ContactLaw::contact_omega`], `K` sub-steps per contact half-period), then a
//!   free trial again over the rest of the step. The last sub-step is shortened to end on the
//!   step grid. A sub-step costs one RK4 step, or two when a switching event (arrival or
//!   departure) falls inside it (the state at the event comes from the first one's dense output;
//!   [`Simulator::step`]).
//! - After a departure the hammer flies clear in one free-flight sub-step (twice the time to
//!   `δ = −η_δ`, at most a quarter of the contact period); while it rests on or creeps along
//!   the surface (slow relative to it, contact force balancing the others) a sub-step is
//!   [`resting_substeps`]`(K) = min(8, K/2)` sub-steps `h_c` long: `ω_c · R h_c ≤ π/2`,
//!   inside RK4's stability region at every `K` (`|R(λh)|` 0.55 per sub-step at the rig's contact
//!   damping ratio 0.469, exact `e^{Re λh}` 0.48), so the contact's own oscillation, which the
//!   resting test has already found below `ε`, keeps dying out, and the slow quasi-static motion
//!   (time scale `1/Ω`, ≥ 20 ms) is followed to RK4 accuracy.
//! - An impact therefore costs about `K` sub-steps plus a few free-flight segments, whatever `N`;
//!   resting contact costs one sub-step per `R h_c`. The cost of a period is bounded by
//!   `N (2 + 2M)` RK4 steps with `M = ceil(h/h_c)`.

use nalgebra::Vector2;

use super::dense::{DenseStep, hermite_min, root_in_unit};
use super::free::{FreeState, FullTrig, free_step};
use super::near::NearTrial;
#[cfg(doc)]
use super::plan::resting_substeps;
use super::plan::{PhaseTable, StepPlan, StepSettings, SubstepRule, step_s};
use super::rk4::rk4_step_compensated;
use crate::error::ParamError;
use crate::model::contact::LawCoeffs;
use crate::model::hammer::{AsSet, FieldEval, FieldMode};
use crate::model::{Hammer, Region, RigParams, SwitchBands};
use crate::real::Real;

/// Impact speed (m/s) at which the power laws' contact time is estimated for the sub-step size:
/// faster than any impact of the thesis' rigs (≤ 0.2 m/s), so real contacts get at least `K`
/// sub-steps per half-period.
pub const SUBSTEP_REFERENCE_SPEED_M_S: f64 = 0.5;

pub use super::plan::RESTING_TOLERANCE;

/// Floor of the Lankarani–Nikravesh approach speed, m/s (avoids dividing by a grazing speed of 0).
const MIN_APPROACH_SPEED_M_S: f64 = 1e-4;

/// The state after one RK4 step, free-flight segment or sub-step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepSample<T> {
    /// Index of the step `h = T/N` this sample lies in, counted from the last reset.
    pub step: u64,
    /// Time since that step's start, s (`h` at the step's end).
    pub offset: T,
    /// Whether this sample ends an excitation period (a Poincaré-section instant).
    pub period_end: bool,
    /// State vector (`(θ, θ̇)` for wires, `(u, u̇)` for beams).
    pub x: Vector2<T>,
    /// Penetration `δ`, m.
    pub delta: T,
    /// Smallest penetration since the previous sample, m (`≤ delta`): the cubic Hermite
    /// interpolant of `δ` (from `δ`, `δ̇` at both ends) over the segment this sample ends, so
    /// that a hop off the surface between two samples shows (`crate::observe::impact`).
    pub delta_min: T,
    /// Penetration rate `δ̇ = u̇`, m/s.
    pub delta_dot: T,
    /// Contact force `F_i`, N.
    pub force: T,
    /// Switch-model region.
    pub region: Region,
}

impl<T: Real> StepSample<T> {
    /// Time since the last reset, s, for step length `step_s` ([`Simulator::step_s`]).
    pub fn time_s(&self, step_s: f64) -> f64 {
        self.step as f64 * step_s + self.offset.to_f64()
    }
}

/// What a simulator's RK4 steps were, by kind (cost diagnostics: [`Simulator::counts`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StepCounts {
    /// Whole free-flight steps `h = T/N` taken in lockstep lanes ([`super::lanes`]).
    pub lane_steps: u64,
    /// Free-flight trials over the rest of a step taken one at a time (one RK4 step each,
    /// accepted or split).
    pub free_trials: u64,
    /// Of those, the trials that came near the surface: the step was split and the trial's
    /// RK4 step discarded.
    pub split_trials: u64,
    /// Free-flight segments up to half a sub-step before the surface.
    pub segments: u64,
    /// Contact sub-steps (the switch model near and in contact; one RK4 step each).
    pub substeps: u64,
    /// Sub-steps with a switching event inside (one more RK4 step each).
    pub events: u64,
}

impl StepCounts {
    /// All RK4 steps: lane steps, trials, segments, sub-steps and the events' second steps.
    pub fn rk4_steps(&self) -> u64 {
        self.lane_steps + self.free_trials + self.segments + self.substeps + self.events
    }
}

impl core::ops::AddAssign for StepCounts {
    /// The steps of two runs added up, kind by kind.
    fn add_assign(&mut self, o: StepCounts) {
        self.lane_steps += o.lane_steps;
        self.free_trials += o.free_trials;
        self.split_trials += o.split_trials;
        self.segments += o.segments;
        self.substeps += o.substeps;
        self.events += o.events;
    }
}

/// Penetration and its rate where a segment (a free-flight step or segment, or a sub-step)
/// starts, `offset` s into the current step.
#[derive(Clone, Copy)]
struct SegmentStart<T> {
    offset: T,
    delta: T,
    delta_dot: T,
}

/// Which function of the penetration `δ` and its rate a switching event is the rising zero of
/// (Leine's switch model; the contact law continued past its ends, `unswitched_force`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum EventCase {
    /// Contact ends: the force falling through 0 (`−F`, the law continued, rising).
    Leaves,
    /// Free flight from outside the surface: `δ` rising through 0.
    Arrives,
    /// Free flight from inside the surface (a departure's band): the force rising through 0.
    Presses,
}

impl EventCase {
    /// The event function at `(δ, δ̇)` (m, m/s) with approach speed `v_in` (m/s).
    #[inline(always)]
    fn value<T: Real>(self, law: &LawCoeffs<T>, d: T, dd: T, v_in: T) -> T {
        match self {
            EventCase::Leaves => -law.unswitched_force(d, dd, v_in),
            EventCase::Arrives => d,
            EventCase::Presses => law.unswitched_force(d, dd, v_in),
        }
    }
}

/// The search for a switching event inside one sub-step ([`Simulator::substep_switch`]).
#[derive(Clone, Copy)]
pub(super) struct SwitchSearch<T: Real> {
    /// The trial's dense output over the sub-step.
    pub(super) dense: DenseStep<T>,
    /// The event function at its start and end.
    pub(super) ends: (T, T),
    pub(super) case: EventCase,
    /// Approach speed, m/s.
    pub(super) v_in: T,
    /// Width of the final bracket, a fraction of the sub-step.
    pub(super) tol: T,
    /// Where the sub-step starts, s into the current step, and `sin Ωt` at its end.
    pub(super) offset: T,
    pub(super) s_end: T,
    /// Whether it starts touching.
    pub(super) touching: bool,
}

impl<T: Real> SwitchSearch<T> {
    /// The event function of `case` (this search's) at fraction `f` of the sub-step.
    // On the MCU a function of its own, called by the search (inlined there it cost 1.2 KB of
    // flash; measured).
    #[cfg_attr(feature = "std", inline(always))]
    #[cfg_attr(not(feature = "std"), inline(never))]
    pub(super) fn event_at(&self, hammer: &Hammer<T>, case: EventCase, f: T) -> T {
        let (d, dd) = hammer.penetration(&self.dense.at(f));
        case.value(&hammer.switch().law, d, dd, self.v_in)
    }

    /// The sub-step ended with its switching event at fraction `frac` of it, in the step whose
    /// `(Ω, sin Ωt, cos Ωt)` at its start is `(omega, sin0, cos0)` (rad/s, 1, 1): the old mode
    /// to the event (the trial's dense output), the approach speed taken there on an arrival,
    /// and the switch model from it to the sub-step's end (one compensated RK4 step, Leine's
    /// switch model as Eq. 3-27–3-29 have it).
    #[inline(always)]
    pub(super) fn finish(
        &self,
        hammer: &Hammer<T>,
        frac: T,
        (omega, sin0, cos0): (T, T, T),
    ) -> Handback<T> {
        let half = T::from_f64(0.5);
        // `sin Ωt` at `dt` into the step (`Simulator::sin_at`).
        let sin_at = |dt: T| {
            let (s, c) = (omega * dt).sin_cos();
            sin0 * c + cos0 * s
        };
        let (offset, len, s_end) = (self.offset, self.dense.h, self.s_end);
        let tau = frac * len;
        // The state at the event from the trial's dense output (cubic Hermite: error
        // `h_c^4/384 · |d⁴x/dt⁴|`, as small as a fresh RK4 step's to `τ`, which it replaces).
        let x_a = self.dense.at(frac);
        let kin_a = hammer.kinematics(&x_a);
        let v_in = if self.touching {
            self.v_in
        } else {
            kin_a.1.max_of(min_approach())
        };
        let rest = len - tau;
        let at_a = hammer.field_with(&x_a, kin_a, sin_at(offset + tau), v_in);
        let s_rest = sin_at(offset + tau + rest * half);
        let (x, carry) = rk4_step_compensated(
            &x_a,
            &Vector2::new(T::zero(), T::zero()),
            &at_a.dx,
            rest,
            s_rest,
            s_end,
            |y, s| hammer.field(y, s, v_in).dx,
        );
        Handback {
            x,
            carry,
            at_x: hammer.field(&x, s_end, v_in),
            approach_speed: v_in,
        }
    }

    /// Where the event falls, as a fraction of the sub-step (Illinois regula falsi,
    /// [`root_in_unit`]).
    #[inline(always)]
    pub(super) fn locate(&self, hammer: &Hammer<T>) -> T {
        // On the host the search with the event function of this case alone (the case a
        // constant in each arm): where only `δ` counts, its rate and the cosine behind it are
        // not computed.
        #[cfg(feature = "std")]
        {
            let root = |case| root_in_unit(self.tol, self.ends, |f| self.event_at(hammer, case, f));
            match self.case {
                EventCase::Leaves => root(EventCase::Leaves),
                EventCase::Arrives => root(EventCase::Arrives),
                EventCase::Presses => root(EventCase::Presses),
            }
        }
        // On the MCU one search for the three (a third of the code; the same results).
        #[cfg(not(feature = "std"))]
        root_in_unit(self.tol, self.ends, |f| self.event_at(hammer, self.case, f))
    }
}

/// A contact lane's sub-step waiting for its switching event to be located
/// ([`Simulator::switch_begin`], [`locate_switches`], [`Simulator::switch_end`]).
#[derive(Clone, Copy)]
pub(crate) struct PendingSwitch<T: Real> {
    seg: SegmentStart<T>,
    pub(super) search: SwitchSearch<T>,
}

/// Where a simulator stands inside its current step, between two segments
/// ([`Simulator::advance`]).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Cursor<T> {
    /// Time since the step's start, s.
    offset: T,
    /// Time to the step's end, s.
    rest: T,
    /// Whether no segment has been taken yet.
    first: bool,
    /// Whether a free-flight trial from here came near the surface so soon that the next
    /// segment is a sub-step ([`Simulator::advance`] with `hand_substep`).
    near: bool,
    /// `sin Ωt` at the step's midpoint and end.
    s_mid: T,
    s_end: T,
}

/// An ordinary sub-step that the contact lanes take ([`Simulator::plain_substep`]).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct SubPlan<T> {
    /// Length, s.
    pub(crate) len: T,
    /// Whether it ends the step.
    pub(crate) last: bool,
    /// Whether it starts in a band (then RK4's first stage is the mode's field at `s_start`).
    pub(crate) band: bool,
    /// `sin Ωt` at its start (if `band`).
    pub(crate) s_start: T,
    /// Where it starts, s into the current step (the contact lanes take `sin Ωt` at its
    /// midpoint and end with [`Simulator::sin_at`]'s operations).
    pub(crate) offset: T,
    /// `sin Ωt` at the step's end (the sub-step's end if `last`).
    pub(crate) step_end: T,
    /// Whether it starts touching (then in the contact mode `f+`, else free flight `f−`).
    pub(crate) touching: bool,
    /// Time from its start to the step's end, s.
    pub(crate) rest: T,
}

/// Where a run stands after ordinary sub-steps taken in the contact lanes
/// ([`super::contact_lanes`]) without the simulator: what [`Simulator::commit_substep`] would
/// have left ([`Simulator::resume_substeps`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct LaneResume<T> {
    /// The state the run takes back.
    pub(crate) state: Handback<T>,
    /// Time since the step's start and to its end, s.
    pub(crate) offset: T,
    pub(crate) rest: T,
    /// Sub-steps taken.
    pub(crate) substeps: u32,
}

/// How far the switching-event lanes ([`super::switch_lanes`]) took a sub-step's event, for
/// [`Simulator::switch_end`].
#[derive(Debug, Clone, Copy)]
pub(crate) enum EventFound<T> {
    /// Not at all: the event is located and the sub-step ended alone.
    Alone,
    /// Located, at this fraction of the sub-step (the sub-step is ended alone).
    At(T),
    /// Located and the sub-step ended: what [`Simulator::switch_finish`] would have left.
    Ended(Handback<T>),
}

/// The state a lane hands back to its run's simulator after sub-steps it took itself (a sub-step
/// ended after its switching event, [`EventFound::Ended`], or ordinary sub-steps,
/// [`LaneResume`]): the state, its carry, its switch-model field and the approach speed of the
/// current impact (m/s).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Handback<T> {
    pub(crate) x: Vector2<T>,
    pub(crate) carry: Vector2<T>,
    pub(crate) at_x: FieldEval<T>,
    pub(crate) approach_speed: T,
}

/// A contact lane's sub-step for [`Simulator::commit_substep`].
#[derive(Debug, Clone, Copy)]
pub(crate) enum LaneTrial<T> {
    /// The trial ends in the mode of its start: the end state, its carry and its switch-model
    /// field.
    Stays {
        x: Vector2<T>,
        carry: Vector2<T>,
        end: FieldEval<T>,
    },
    /// The trial `x` ends in the other mode: a switching event inside (`s_end`: `sin Ωt` at
    /// the sub-step's end).
    Switches { x: Vector2<T>, s_end: T },
    /// A sine outside the lanes' short range: the stepper takes the sub-step.
    Inexact,
}

/// What changes from step to step.
#[derive(Debug, Clone, Copy)]
struct StepState<T> {
    x: Vector2<T>,
    /// Rounding error of `x`'s compensated updates (free-flight segments and sub-steps, see
    /// `rk4_step_compensated`; whole free-flight steps leave it for the next one).
    carry: Vector2<T>,
    /// Field at `x` (RK4's first stage of the next step).
    at_x: FieldEval<T>,
    /// Step index within the period, `0..N` (`steps mod N`).
    k: u32,
    /// Steps since the last reset (at phase 0).
    steps: u64,
    /// Approach speed of the current impact, m/s (Lankarani–Nikravesh).
    approach_speed: T,
    /// RK4 steps and sub-steps since construction, by kind.
    counts: StepCounts,
}

/// Fixed-step switch-model integrator for one rig, gap and excitation frequency: the compiled
/// [`Hammer`], its [`StepPlan`], the shared [`PhaseTable`] and a small step state.
#[derive(Debug, Clone)]
pub struct Simulator<'t, T: Real> {
    phases: &'t PhaseTable<T>,
    plan: StepPlan<T>,
    hammer: Hammer<T>,
    state: StepState<T>,
}

impl<'t, T: Real> Simulator<'t, T> {
    /// A simulator at rest relative to the cart (`u = 0`, `u̇ = 0`) at phase 0, on the step
    /// grid of `phases` (built for `steps.steps_per_period`).
    ///
    /// # Errors
    /// [`ParamError`] for invalid parameters, gap (m, `0 ..= 0.05`), `omega_exc` (rad/s), bands
    /// or step settings, a table for another `N` (`steps_per_period`), or more than 10^6
    /// contact sub-steps per step (`substeps`).
    pub fn new(
        params: &RigParams,
        gap_m: f64,
        omega_exc: f64,
        bands: &SwitchBands,
        steps: &StepSettings,
        phases: &'t PhaseTable<T>,
    ) -> Result<Self, ParamError> {
        steps.validate()?;
        let hammer = Hammer::<T>::new(params, gap_m, omega_exc, bands)?;
        let omega_c = params
            .contact
            .contact_omega(params.mass_kg, SUBSTEP_REFERENCE_SPEED_M_S);
        Self::from_hammer(hammer, omega_c, steps, phases)
    }

    /// A simulator at rest relative to the cart at phase 0 for an already compiled `hammer`
    /// (e.g. one without excitation for a drop test, [`crate::analysis::drop`]); `omega_c`
    /// (rad/s) is the contact frequency that sets the sub-step
    /// ([`crate::model::ContactLaw::contact_omega`]).
    ///
    /// # Errors
    /// [`ParamError`] for invalid step settings, a table for another `N`
    /// (`steps_per_period`), a non-finite or non-positive `omega_c`, or more than 10^6 contact
    /// sub-steps per step (`substeps`).
    pub fn from_hammer(
        hammer: Hammer<T>,
        omega_c: f64,
        steps: &StepSettings,
        phases: &'t PhaseTable<T>,
    ) -> Result<Self, ParamError> {
        if phases.steps_per_period() != steps.steps_per_period {
            return Err(ParamError::BadRange {
                field: "steps_per_period",
                reason: "the phase table was built for another number of steps per period",
            });
        }
        let plan = StepPlan::new(hammer.omega_exc(), omega_c, steps)?;
        let x = Vector2::new(T::zero(), T::zero());
        let approach_speed = min_approach();
        Ok(Simulator {
            phases,
            plan,
            hammer,
            state: StepState {
                x,
                carry: Vector2::new(T::zero(), T::zero()),
                at_x: hammer.field(&x, T::zero(), approach_speed),
                k: 0,
                steps: 0,
                approach_speed,
                counts: StepCounts::default(),
            },
        })
    }

    /// Locates switching events to a few rounding units of the float type instead of
    /// `2^-14` of the sub-step (at most 40 evaluations of the event function on the step's
    /// dense output, as always). The production setting makes the stroboscopic map piecewise
    /// smooth with steps of about 1e-5 of the cart's amplitude where the root finder's last
    /// iterate changes; Newton's method on periodic orbits (`crate::orbit`) needs it smooth.
    /// Nothing else changes: the same steps, sub-steps, fields and switch model.
    pub fn locate_events_exactly(&mut self) {
        self.plan.event_tol = T::from_f64(4.0 * T::EPSILON);
    }

    /// Restarts at phase 0 from relative displacement `u_m` (m) and velocity `du_m_s` (m/s).
    ///
    /// # Errors
    /// [`ParamError`] for non-finite values or (wires) `|u| ≥ l/2`.
    pub fn reset_relative(&mut self, u_m: f64, du_m_s: f64) -> Result<(), ParamError> {
        let x = self.hammer.state_from_relative(u_m, du_m_s)?;
        self.reset_state(x);
        Ok(())
    }

    /// Restarts at phase 0 from state vector `x` (keeps the rig and frequency).
    pub fn reset_state(&mut self, x: Vector2<T>) {
        let approach_speed = min_approach();
        self.state = StepState {
            x,
            carry: Vector2::new(T::zero(), T::zero()),
            at_x: self.hammer.field(&x, T::zero(), approach_speed),
            k: 0,
            steps: 0,
            approach_speed,
            counts: self.state.counts,
        };
    }

    /// The compiled model.
    pub fn hammer(&self) -> &Hammer<T> {
        &self.hammer
    }
    /// Current state vector.
    pub fn state(&self) -> Vector2<T> {
        self.state.x
    }
    /// Penetration `δ` (m) at the current state, as evaluated with the current step's field.
    pub fn state_penetration(&self) -> T {
        self.state.at_x.delta
    }
    /// Current `(u, u̇)`, m and m/s.
    pub fn relative(&self) -> (T, T) {
        self.hammer.relative(&self.state.x)
    }
    /// `N`, steps per period.
    pub fn steps_per_period(&self) -> u32 {
        self.phases.steps_per_period()
    }
    /// Step `h = T/N`, s (f64).
    pub fn step_s(&self) -> f64 {
        step_s(self.hammer.omega_exc(), self.steps_per_period())
    }
    /// Completed excitation periods since the last reset.
    pub fn periods_done(&self) -> u32 {
        (self.state.steps / u64::from(self.steps_per_period())) as u32
    }
    /// Whether the simulator stands at a period's start (`t = kT`, the Poincaré section).
    #[inline(always)]
    pub(crate) fn at_period_start(&self) -> bool {
        self.state.k == 0
    }
    /// RK4 steps and sub-steps executed since construction (cost diagnostics).
    pub fn rk4_steps(&self) -> u64 {
        self.state.counts.rk4_steps()
    }
    /// The same by kind.
    pub fn counts(&self) -> StepCounts {
        self.state.counts
    }

    /// What [`Simulator::sin_at`] takes besides `dt`: `Ω`, and `sin Ωt`, `cos Ωt` at the
    /// current step's start (for the contact lanes).
    #[inline(always)]
    pub(crate) fn step_phase(&self) -> (T, T, T) {
        let k = self.state.k as usize;
        (
            self.plan.omega,
            self.phases.sin_half(2 * k),
            self.phases.cos_start(k),
        )
    }

    /// `sin Ωt` at `dt` seconds (`0 ≤ Ω dt ≤ 2π/N`) after the start of the current step.
    #[inline(always)]
    fn sin_at(&self, dt: T) -> T {
        let (s, c) = (self.plan.omega * dt).sin_cos();
        let k = self.state.k as usize;
        self.phases.sin_half(2 * k) * c + self.phases.cos_start(k) * s
    }

    /// Whether the hammer is clear of the surface: free region and `δ ≤ −η_δ`.
    #[inline(always)]
    fn clear(&self) -> bool {
        let e = &self.state.at_x;
        e.region == Region::Free && e.delta <= -self.hammer.eta_delta()
    }

    /// The free-flight state for a lockstep lane ([`super::lanes`]), if this simulator may
    /// take whole free-flight steps in lockstep now (clear of the surface); with the steps
    /// left to its period's end (the period's last step included).
    #[inline(always)]
    pub(super) fn lane_start(&self) -> Option<(FreeState<T>, u32)> {
        if !self.clear() {
            return None;
        }
        Some((self.free_state(), self.steps_per_period() - self.state.k))
    }

    /// The current state as the free-flight kernel takes it.
    #[inline(always)]
    fn free_state(&self) -> FreeState<T> {
        let (x, e) = (self.state.x, self.state.at_x);
        FreeState {
            x0: x[0],
            x1: x[1],
            a: e.dx[1],
            d: e.delta,
            dd: e.delta_dot,
        }
    }

    /// The constants of a lockstep lane: free-flight coefficients and `h`.
    #[inline(always)]
    pub(super) fn lane_constants(&self) -> (crate::model::hammer::FreeFlight<T>, T) {
        (self.hammer.free_flight(), self.plan.h)
    }

    /// The lockstep lanes' kind of this simulator: the phase table, whether the suspension is
    /// the wire pendulum, `η_δ`, and whether it is the damped pendulum (the [`Damped`]
    /// kernel).
    ///
    /// [`Damped`]: crate::model::hammer::Damped
    #[inline(always)]
    pub(super) fn lane_kind(&self) -> (&'t PhaseTable<T>, bool, T, bool) {
        (
            self.phases,
            self.hammer.is_wires(),
            self.hammer.eta_delta(),
            self.hammer.is_damped_wires(),
        )
    }

    /// Ends `taken` whole free-flight steps taken in a lockstep lane ([`super::lanes`]) at
    /// state `st`: where as many [`Simulator::step`] calls would have left the simulator.
    #[inline(always)]
    pub(super) fn lane_finish(&mut self, st: &FreeState<T>, taken: u32) {
        let s = &mut self.state;
        (s.x, s.at_x) = clear_of_surface(st);
        // A lane stops at its period's end at the latest.
        s.k += taken;
        if s.k >= self.phases.steps_per_period() {
            s.k = 0;
        }
        s.steps += u64::from(taken);
        s.counts.lane_steps += u64::from(taken);
    }

    /// Advances one step of `h = T/N`, calling `observe` after every segment of it (the whole
    /// step in free flight, or the free-flight segments and contact sub-steps it was split into).
    #[inline]
    pub fn step<O: FnMut(&StepSample<T>)>(&mut self, observe: &mut O) {
        let mut c = self.begin_step();
        while !self.advance::<false, O>(&mut c, false, observe) {}
    }

    /// [`Simulator::step`] with the split of a free-flight trial that comes near the surface
    /// located to round-off and differentiated through its root (`NearTrial::search_exact`)
    /// instead of halved to 1/8192 of the step: the periodic-orbit map's step
    /// (`crate::orbit`), smooth in the state where the production step jumps. Everything else
    /// is [`Simulator::step`]'s.
    #[inline]
    pub(crate) fn step_exact<O: FnMut(&StepSample<T>)>(&mut self, observe: &mut O) {
        let mut c = self.begin_step();
        while !self.advance::<true, O>(&mut c, false, observe) {}
    }

    /// Where the next step starts (its first segment).
    #[inline(always)]
    pub(crate) fn begin_step(&self) -> Cursor<T> {
        let (s_mid, s_end) = self.phases.step_mid_end(self.state.k);
        Cursor {
            offset: T::zero(),
            rest: self.plan.h,
            first: true,
            near: false,
            s_mid,
            s_end,
        }
    }

    /// One segment of the current step from `c` (a free-flight trial over the rest of the
    /// step, a free-flight segment, or a sub-step), reported to `observe`. Returns whether the
    /// step is done. With `hand_substep`, a trial that comes near the surface too soon for a
    /// free-flight segment leaves the sub-step that follows to the caller (marked in `c`: then
    /// [`Simulator::plain_substep`] gives it), and nothing is reported. `EXACT`: the near split
    /// as [`Simulator::step_exact`] takes it.
    #[inline(always)]
    pub(crate) fn advance<const EXACT: bool, O: FnMut(&StepSample<T>)>(
        &mut self,
        c: &mut Cursor<T>,
        hand_substep: bool,
        observe: &mut O,
    ) -> bool {
        match self.free_flight_segment(c, observe) {
            Some(Ok(done)) => return done,
            Some(Err(trial)) => {
                let t_near = if EXACT {
                    trial.search_exact(&self.hammer)
                } else {
                    trial.search_alone(&self.hammer)
                };
                if let Some(done) = self.after_near(c, t_near, hand_substep, observe) {
                    return done;
                }
            }
            None => {}
        }
        self.substep_segment(c, observe)
    }

    /// [`Simulator::advance`] up to a free-flight trial that comes near the surface: that
    /// trial (`Err`, nothing taken yet), whose search [`Simulator::advance_near`] takes
    /// with the time it found (so that the caller may search several runs' trials together,
    /// `near::NearLanes`).
    #[inline(always)]
    pub(crate) fn advance_until_near<O: FnMut(&StepSample<T>)>(
        &mut self,
        c: &mut Cursor<T>,
        observe: &mut O,
    ) -> Result<bool, NearTrial<T>> {
        match self.free_flight_segment(c, observe) {
            Some(r) => r,
            None => Ok(self.substep_segment(c, observe)),
        }
    }

    /// [`Simulator::advance`] after a free-flight trial from `c` came near the surface, first
    /// within `η_δ` of it `t_near` s into the trial (`NearTrial`'s search).
    #[inline(always)]
    pub(crate) fn advance_near<O: FnMut(&StepSample<T>)>(
        &mut self,
        c: &mut Cursor<T>,
        t_near: T,
        hand_substep: bool,
        observe: &mut O,
    ) -> bool {
        match self.after_near(c, t_near, hand_substep, observe) {
            Some(done) => done,
            None => self.substep_segment(c, observe),
        }
    }

    /// A free-flight trial over the rest of the step from `c` if the hammer is clear of the
    /// surface (`None`: the next segment is a sub-step): `Ok(true)`, the step taken whole; or
    /// the trial that came near the surface, to be searched.
    #[inline(always)]
    fn free_flight_segment<O: FnMut(&StepSample<T>)>(
        &mut self,
        c: &mut Cursor<T>,
        observe: &mut O,
    ) -> Option<Result<bool, NearTrial<T>>> {
        if !self.clear() || c.near {
            return None;
        }
        let (sm, se) = if c.first {
            (c.s_mid, c.s_end)
        } else {
            (self.sin_at(c.offset + c.rest * T::from_f64(0.5)), c.s_end)
        };
        Some(match self.free_trial(c.rest, sm, se) {
            Ok((x1, end)) => {
                let seg = self.segment_start(c.offset);
                self.state.x = x1;
                self.state.at_x = end;
                self.finish_step(&seg, observe);
                Ok(true)
            }
            Err(trial) => Err(trial),
        })
    }

    /// After a free-flight trial from `c` came near the surface `t_near` s into it: the
    /// free-flight segment to half a sub-step short of that (`Some(false)`), the sub-step
    /// handed to the caller (`Some(false)`, with `hand_substep`), or `None`: the next segment
    /// is a sub-step from here.
    #[inline(always)]
    fn after_near<O: FnMut(&StepSample<T>)>(
        &mut self,
        c: &mut Cursor<T>,
        t_near: T,
        hand_substep: bool,
        observe: &mut O,
    ) -> Option<bool> {
        let h_c = self.plan.substep.h_c;
        // Stop half a sub-step short of the surface, so that the arrival falls inside the
        // next sub-step (not on its boundary, where the switch would go through the Σ_α band
        // instead of being located).
        let tau = t_near - h_c * T::from_f64(0.5);
        if tau > h_c * T::from_f64(0.25) {
            let seg = self.segment_start(c.offset);
            self.free_segment(c.offset, tau);
            c.offset += tau;
            c.rest -= tau;
            c.first = false;
            observe(&self.sample(c.offset, false, &seg));
            return Some(false);
        }
        if hand_substep {
            c.near = true;
            return Some(false);
        }
        None
    }

    /// The sub-step that is the next segment from `c` ([`Simulator::advance`]).
    #[inline(always)]
    fn substep_segment<O: FnMut(&StepSample<T>)>(
        &mut self,
        c: &mut Cursor<T>,
        observe: &mut O,
    ) -> bool {
        // Where this segment starts (for the smallest δ over it, reported with its sample).
        let seg = self.segment_start(c.offset);
        c.first = false;
        c.near = false;
        let (len, last) = self.substep_len(c);
        if last {
            self.substep(c.offset, len, c.s_end);
            self.finish_step(&seg, observe);
            return true;
        }
        let s_next = self.sin_at(c.offset + len);
        self.substep(c.offset, len, s_next);
        c.offset += len;
        c.rest -= len;
        observe(&self.sample(c.offset, false, &seg));
        false
    }

    /// Where a segment starts `offset` s into the current step.
    #[inline(always)]
    fn segment_start(&self, offset: T) -> SegmentStart<T> {
        SegmentStart {
            offset,
            delta: self.state.at_x.delta,
            delta_dot: self.state.at_x.delta_dot,
        }
    }

    /// The next sub-step's length from `c` and whether it ends the step (then it is the rest
    /// of the step).
    #[inline(always)]
    fn substep_len(&self, c: &Cursor<T>) -> (T, bool) {
        let e = &self.state.at_x;
        self.plan.substep.len(
            self.hammer.eta_delta(),
            e.region == Region::Free,
            e.region == Region::Contact,
            e.delta,
            e.delta_dot,
            e.dx[1],
            || self.hammer.contact_accel(e.force),
            c.rest,
        )
    }

    /// The rule for the length of this simulator's sub-steps.
    #[inline(always)]
    pub(crate) fn substep_rule(&self) -> SubstepRule<T> {
        self.plan.substep
    }

    /// The next segment from `c` if it is an ordinary sub-step that the contact lanes
    /// ([`super::contact_lanes`]) can take: not clear of the surface (or a free-flight trial
    /// from here came near it: `Cursor::near`), with the linear contact law. Its length, whether it ends the step, `sin Ωt` at its start (used if it starts in
    /// a band, where RK4's first stage is the mode's field, not the switch model's), midpoint
    /// and end, and whether it starts touching.
    #[inline(always)]
    pub(crate) fn plain_substep(&self, c: &Cursor<T>) -> Option<SubPlan<T>> {
        let e = &self.state.at_x;
        let clear = self.clear() && !c.near;
        if clear || !matches!(self.hammer.switch().law, LawCoeffs::Linear { .. }) {
            return None;
        }
        let band = matches!(e.region, Region::BandAlpha | Region::BandBeta);
        let s_start = if band {
            self.sin_at(c.offset)
        } else {
            T::zero()
        };
        let (len, last) = self.substep_len(c);
        Some(SubPlan {
            len,
            last,
            band,
            s_start,
            offset: c.offset,
            step_end: c.s_end,
            touching: e.region.touching(),
            rest: c.rest,
        })
    }

    /// Ends the sub-step `p` ([`Simulator::plain_substep`]) from `c` with the contact lanes'
    /// `trial` ([`LaneTrial`]): what [`Simulator::substep`] computes, bit for bit, without
    /// repeating what the lanes computed. Reports the sample; returns whether the step is done.
    #[inline(always)]
    pub(crate) fn commit_substep<O: FnMut(&StepSample<T>)>(
        &mut self,
        c: &mut Cursor<T>,
        p: &SubPlan<T>,
        trial: LaneTrial<T>,
        observe: &mut O,
    ) -> bool {
        let seg = self.segment_start(c.offset);
        c.first = false;
        c.near = false;
        match trial {
            LaneTrial::Stays { x, carry, end } => {
                let start = self.state.at_x;
                let s = &mut self.state;
                s.counts.substeps += 1;
                if !p.touching && start.delta <= T::zero() {
                    s.approach_speed = start.delta_dot.max_of(min_approach());
                }
                s.x = x;
                s.carry = carry;
                s.at_x = end;
            }
            LaneTrial::Switches { x, s_end } => {
                let pending = self.switch_begin(c, p, x, s_end);
                return self.switch_end(c, p, &pending, EventFound::Alone, observe);
            }
            LaneTrial::Inexact => {
                let s_end = if p.last {
                    p.step_end
                } else {
                    self.sin_at(c.offset + p.len)
                };
                self.substep(c.offset, p.len, s_end);
            }
        }
        self.end_substep(c, p, &seg, observe)
    }

    /// After the sub-step `p` from `c` (whose segment started at `seg`): the step's end, or
    /// the cursor moved past it; reports the sample and returns whether the step is done.
    #[inline(always)]
    fn end_substep<O: FnMut(&StepSample<T>)>(
        &mut self,
        c: &mut Cursor<T>,
        p: &SubPlan<T>,
        seg: &SegmentStart<T>,
        observe: &mut O,
    ) -> bool {
        if p.last {
            self.finish_step(seg, observe);
            return true;
        }
        c.offset += p.len;
        c.rest -= p.len;
        observe(&self.sample(c.offset, false, seg));
        false
    }

    /// The state a contact lane starts a sub-step from: `x`, its carry, the field there and
    /// the approach speed (m/s).
    #[inline(always)]
    pub(crate) fn substep_start(&self) -> (Vector2<T>, Vector2<T>, FieldEval<T>, T) {
        let s = &self.state;
        (s.x, s.carry, s.at_x, s.approach_speed)
    }

    /// Takes back the run after the ordinary sub-steps `r` that the contact lanes committed
    /// themselves (each as [`Simulator::commit_substep`] would have, inside the current step):
    /// the state, the approach speed, the sub-step count and the cursor `c`.
    #[inline(always)]
    pub(crate) fn resume_substeps(&mut self, c: &mut Cursor<T>, r: &LaneResume<T>) {
        self.take_back(&r.state);
        self.state.counts.substeps += u64::from(r.substeps);
        c.offset = r.offset;
        c.rest = r.rest;
        c.first = false;
        c.near = false;
    }

    /// Tries `rest` seconds (to the end of the step) in free flight from the current state, with
    /// `sin Ωt` `s_mid`, `s_end` at the segment's midpoint and end ([`super::free`]). `Ok` with
    /// the end state and its switch-model field if the hammer stays clear; otherwise `Err`
    /// with the trial, whose dense output is to be searched for where it first comes within
    /// `η_δ` of the surface, or peaks ([`NearTrial`]).
    #[cfg_attr(feature = "std", inline(always))]
    #[cfg_attr(not(feature = "std"), inline(never))]
    fn free_trial(
        &mut self,
        rest: T,
        s_mid: T,
        s_end: T,
    ) -> Result<(Vector2<T>, FieldEval<T>), NearTrial<T>> {
        let hammer = self.hammer;
        let eta = hammer.eta_delta();
        let st = self.free_state();
        // A plain update (the carry is left for the next compensated one): the increment of a
        // free-flight step is a tenth of the state, not small enough for compensation to pay,
        // and the lockstep lanes take the same steps without carrying a second state.
        let c = hammer.free_flight();
        let (next, _, near) = free_step::<T, _, FullTrig, AsSet>(&c, &st, rest, s_mid, s_end, eta);
        if !near {
            self.state.counts.free_trials += 1;
            return Ok(clear_of_surface(&next));
        }
        Err(self.split_trial(rest, &next))
    }

    /// The free-flight trial of `rest` s from the current state that ended at `next` and came
    /// near the surface, counted as a split trial.
    #[inline(always)]
    fn split_trial(&mut self, rest: T, next: &FreeState<T>) -> NearTrial<T> {
        let (x0, start) = (self.state.x, self.state.at_x);
        let (x1, end) = clear_of_surface(next);
        self.state.counts.free_trials += 1;
        self.state.counts.split_trials += 1;
        NearTrial {
            dense: DenseStep {
                x0,
                f0: start.dx,
                x1,
                f1: end.dx,
                h: rest,
            },
            start_delta: start.delta,
            eta: self.hammer.eta_delta(),
        }
    }

    /// The trial [`Simulator::advance_until_near`] would take first from the step's start
    /// ([`Simulator::begin_step`]; the hammer clear of the surface), given its end `next` from
    /// a lockstep lane that stopped before it because it came near the surface
    /// (`Lockstep::take_trial`: the same step bit for bit): counted as that trial is.
    #[inline(always)]
    pub(crate) fn lane_trial(&mut self, next: &FreeState<T>) -> NearTrial<T> {
        debug_assert!(self.clear());
        self.split_trial(self.plan.h, next)
    }

    /// One free-flight RK4 step of `len` seconds from `offset` (s into the current step).
    #[inline(always)]
    fn free_segment(&mut self, offset: T, len: T) {
        let hammer = self.hammer;
        let v_in = self.state.approach_speed;
        let s_mid = self.sin_at(offset + len * T::from_f64(0.5));
        let s_end = self.sin_at(offset + len);
        let s = &mut self.state;
        (s.x, s.carry) =
            rk4_step_compensated(&s.x, &s.carry, &s.at_x.dx, len, s_mid, s_end, |y, s| {
                hammer.field_in(FieldMode::Free, y, s, v_in).dx
            });
        s.at_x = hammer.field(&s.x, s_end, v_in);
        s.counts.segments += 1;
    }

    /// One sub-step of `len` seconds from `offset` (s into the current step) with the full
    /// switch model; `s_end` is `sin Ωt` at its end.
    ///
    /// The field is discontinuous where contact begins (the spring–dashpot force jumps to `c δ̇`)
    /// and has a kink where it ends (`h_β = 0`); a fixed step straddling either loses accuracy in
    /// proportion to where the event falls, which shows as jitter of the Poincaré section. So the
    /// sub-step is first taken in the mode of its start (free flight `f−`, or contact `f+` with
    /// the law continued past `h_β = 0`). If the switch model disagrees at the end, the event
    /// time `τ` is found by Illinois regula falsi on the step's cubic Hermite dense output (free → contact:
    /// `δ` or, when already inside, `h_β` rising through 0; contact → free: `h_β` falling
    /// through 0), the hammer is integrated in the old mode to `τ` and with the switch model from
    /// `τ` to the end of the sub-step.
    #[inline]
    fn substep(&mut self, offset: T, len: T, s_end: T) {
        let hammer = self.hammer;
        let s_mid = self.sin_at(offset + len * T::from_f64(0.5));
        let (touching, k1) = self.substep_begin(offset);
        let v_in = self.state.approach_speed;
        let mode = FieldMode::of_start(touching);
        let (trial, carry) = rk4_step_compensated(
            &self.state.x,
            &self.state.carry,
            &k1.dx,
            len,
            s_mid,
            s_end,
            |y, s| hammer.field_in(mode, y, s, v_in).dx,
        );
        let end = hammer.field(&trial, s_end, v_in);
        if end.region.touching() == touching {
            self.state.x = trial;
            self.state.carry = carry;
            self.state.at_x = end;
            return;
        }
        self.substep_switch(offset, len, s_end, touching, k1, trial);
    }

    /// The start of a sub-step from `offset` (s into the current step): counts it, notes the
    /// approach speed of an arrival from free flight, and returns whether it starts touching
    /// (its mode: contact `f+`, else free flight `f−`) and RK4's first stage there.
    #[inline]
    fn substep_begin(&mut self, offset: T) -> (bool, FieldEval<T>) {
        let start = self.state.at_x;
        self.state.counts.substeps += 1;
        let touching = start.region.touching();
        if !touching && start.delta <= T::zero() {
            self.state.approach_speed = start.delta_dot.max_of(min_approach());
        }
        let mode = FieldMode::of_start(touching);
        // Outside the bands the switch-model field at the start is the mode's field: reuse it.
        let k1 = match start.region {
            Region::Free | Region::Contact => start,
            Region::BandAlpha | Region::BandBeta => self.hammer.field_in(
                mode,
                &self.state.x,
                self.sin_at(offset),
                self.state.approach_speed,
            ),
        };
        (touching, k1)
    }

    /// The rest of a sub-step of `len` seconds from `offset` whose `trial` (RK4 in the mode of
    /// its start, `touching`, with first stage `k1`) ends in the other mode: the switching
    /// event located on the trial's dense output, the old mode to it and the switch model from
    /// it to the sub-step's end ([`Simulator::substep`]).
    // On the MCU inlined into its one caller (a smaller stack; measured).
    #[cfg_attr(not(feature = "std"), inline(always))]
    fn substep_switch(
        &mut self,
        offset: T,
        len: T,
        s_end: T,
        touching: bool,
        k1: FieldEval<T>,
        trial: Vector2<T>,
    ) {
        let search = self.switch_search(offset, len, s_end, touching, k1, trial);
        let frac = search.locate(&self.hammer);
        self.switch_finish(&search, frac);
    }

    /// The search for the switching event inside a sub-step whose `trial` ends in the other
    /// mode ([`Simulator::substep_switch`]): the trial's dense output, the event function's
    /// case and its values at the ends.
    #[inline(always)]
    fn switch_search(
        &self,
        offset: T,
        len: T,
        s_end: T,
        touching: bool,
        k1: FieldEval<T>,
        trial: Vector2<T>,
    ) -> SwitchSearch<T> {
        let hammer = &self.hammer;
        let start = self.state.at_x;
        let v_in = self.state.approach_speed;
        let mode = FieldMode::of_start(touching);
        let end_mode = hammer.field_in(mode, &trial, s_end, v_in);
        let case = if touching {
            EventCase::Leaves
        } else if start.delta <= T::zero() {
            EventCase::Arrives
        } else {
            EventCase::Presses
        };
        let law = hammer.switch().law;
        // At its ends the dense output is the start and the trial (its weights there are
        // exactly 1 and 0), whose penetrations the field evaluations hold (`Hammer::penetration`
        // is the field's own): the event function there without evaluating it again.
        let search = SwitchSearch {
            dense: DenseStep {
                x0: self.state.x,
                f0: k1.dx,
                x1: trial,
                f1: end_mode.dx,
                h: len,
            },
            ends: (
                case.value(&law, start.delta, start.delta_dot, v_in),
                case.value(&law, end_mode.delta, end_mode.delta_dot, v_in),
            ),
            case,
            v_in,
            tol: self.plan.event_tol,
            offset,
            s_end,
            touching,
        };
        debug_assert!(
            search.ends.0 == search.event_at(hammer, case, T::zero())
                && search.ends.1 == search.event_at(hammer, case, T::from_f64(1.0)),
            "the event function at the sub-step's ends: {:?}",
            search.ends
        );
        search
    }

    /// Ends the sub-step of `search` with its switching event at fraction `frac` of it
    /// ([`SwitchSearch::finish`]).
    #[inline(always)]
    fn switch_finish(&mut self, search: &SwitchSearch<T>, frac: T) {
        let done = search.finish(&self.hammer, frac, self.step_phase());
        self.switch_done(&done);
    }

    /// Takes the state a sub-step ended after its switching event.
    #[inline(always)]
    fn switch_done(&mut self, done: &Handback<T>) {
        self.take_back(done);
        // The trial and the rest of the sub-step.
        self.state.counts.events += 1;
    }

    /// Takes back the state a lane (or [`SwitchSearch::finish`]) left.
    #[inline(always)]
    fn take_back(&mut self, h: &Handback<T>) {
        let s = &mut self.state;
        (s.x, s.carry, s.at_x) = (h.x, h.carry, h.at_x);
        s.approach_speed = h.approach_speed;
    }

    /// A contact lane's sub-step `p` from `c` whose trial `x` ends in the other mode
    /// ([`LaneTrial::Switches`]), up to its switching event: the search for the event, to be
    /// located alone or with others' (`switch_lanes`) and ended by [`Simulator::switch_end`].
    /// Together the two are [`Simulator::commit_substep`] of that trial, bit for bit.
    #[inline(always)]
    pub(crate) fn switch_begin(
        &mut self,
        c: &mut Cursor<T>,
        p: &SubPlan<T>,
        x: Vector2<T>,
        s_end: T,
    ) -> PendingSwitch<T> {
        let seg = self.segment_start(c.offset);
        c.first = false;
        c.near = false;
        let (touching, k1) = self.substep_begin(c.offset);
        PendingSwitch {
            seg,
            search: self.switch_search(c.offset, p.len, s_end, touching, k1, x),
        }
    }

    /// Ends the sub-step `p` of [`Simulator::switch_begin`] with its event as `found` has it
    /// (located and the sub-step ended here, or either in the switching-event lanes): reports
    /// the sample; returns whether the step is done.
    #[inline(always)]
    pub(crate) fn switch_end<O: FnMut(&StepSample<T>)>(
        &mut self,
        c: &mut Cursor<T>,
        p: &SubPlan<T>,
        pending: &PendingSwitch<T>,
        found: EventFound<T>,
        observe: &mut O,
    ) -> bool {
        let frac = match found {
            EventFound::Alone => Some(pending.search.locate(&self.hammer)),
            EventFound::At(frac) => Some(frac),
            EventFound::Ended(done) => {
                self.switch_done(&done);
                None
            }
        };
        if let Some(frac) = frac {
            self.switch_finish(&pending.search, frac);
        }
        self.end_substep(c, p, &pending.seg, observe)
    }

    /// Ends the current step: advances the step counters and reports the sample.
    #[inline(always)]
    fn finish_step<O: FnMut(&StepSample<T>)>(&mut self, seg: &SegmentStart<T>, observe: &mut O) {
        let sample = self.sample(self.plan.h, true, seg);
        self.state.steps += 1;
        self.state.k += 1;
        if self.state.k == self.steps_per_period() {
            self.state.k = 0;
        }
        observe(&sample);
    }

    #[inline(always)]
    fn sample(&self, offset: T, step_end: bool, seg: &SegmentStart<T>) -> StepSample<T> {
        let e = &self.state.at_x;
        StepSample {
            step: self.state.steps,
            offset,
            period_end: step_end && self.state.k + 1 == self.steps_per_period(),
            x: self.state.x,
            delta: e.delta,
            delta_min: hermite_min(
                seg.delta,
                seg.delta_dot,
                e.delta,
                e.delta_dot,
                offset - seg.offset,
            ),
            delta_dot: e.delta_dot,
            force: e.force,
            region: e.region,
        }
    }

    /// Runs to the end of the current excitation period (`N` steps from a period's start).
    pub fn run_period<O: FnMut(&StepSample<T>)>(&mut self, observe: &mut O) {
        loop {
            self.step(observe);
            if self.state.k == 0 {
                return;
            }
        }
    }
}

#[cfg(test)]
impl<T: Real> Simulator<'_, T> {
    /// This simulator with `other`'s step counts (to compare everything else).
    pub(crate) fn with_counts_of(&self, other: &Self) -> Self {
        let mut s = self.clone();
        s.state.counts = other.state.counts;
        s
    }
}

/// Floor of the Lankarani–Nikravesh approach speed (avoids dividing by a grazing speed of 0).
#[inline(always)]
pub(crate) fn min_approach<T: Real>() -> T {
    T::from_f64(MIN_APPROACH_SPEED_M_S)
}

/// The state and switch-model field of a free-flight state clear of the surface (there the
/// free field is the switch-model field): the reverse of [`Simulator::free_state`].
#[inline(always)]
fn clear_of_surface<T: Real>(st: &FreeState<T>) -> (Vector2<T>, FieldEval<T>) {
    let eval = FieldEval {
        dx: Vector2::new(st.x1, st.a),
        force: T::zero(),
        region: Region::Free,
        delta: st.d,
        delta_dot: st.dd,
    };
    (Vector2::new(st.x0, st.x1), eval)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulator_state_is_small() {
        // The phase tables are shared by reference; what each simulator carries is the hammer,
        // its step plan and the step state.
        let size = core::mem::size_of::<Simulator<'_, f32>>();
        assert!(size <= 256, "Simulator<f32> is {size} bytes");
        // Far smaller than the tables it refers to (holding them by value fails this).
        assert!(
            size * 16 < core::mem::size_of::<PhaseTable<f32>>(),
            "{size} bytes"
        );
    }
}

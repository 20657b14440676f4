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
//!   [`RESTING_SUBSTEPS`] `h_c` long.
//! - An impact therefore costs about `K` sub-steps plus a few free-flight segments, whatever `N`;
//!   resting contact costs one sub-step per `8 h_c`. The cost of a period is bounded by
//!   `N (2 + 2M)` RK4 steps with `M = ceil(h/h_c)`.

use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

use super::dense::{DenseStep, hermite_min, root_in_unit};
use super::rk4::{rk4_step, rk4_step_compensated};
use crate::error::{ParamError, check_count, check_range};
use crate::model::hammer::{FieldEval, FieldMode};
use crate::model::{Hammer, Region, RigParams, SwitchBands};
use crate::real::Real;

/// Impact speed (m/s) at which the power laws' contact time is estimated for the sub-step size:
/// faster than any impact of the thesis' rigs (≤ 0.2 m/s), so real contacts get at least `K`
/// sub-steps per half-period.
pub const SUBSTEP_REFERENCE_SPEED_M_S: f64 = 0.5;

/// Largest `N` (the excitation tables hold `3N` values).
pub const MAX_STEPS_PER_PERIOD: u32 = 512;

/// Largest `M = ceil(h/h_c)`, contact sub-steps per step.
const MAX_SUBSTEPS: f64 = 1e6;

/// Contact sub-steps `h_c` per sub-step while the hammer rests on the surface
/// ([`Simulator`]). At the production `K = 16` that is `ω_c · 8 h_c = π/2`, inside RK4's
/// stability region with room to spare (`|R(λh)|` 0.55 per sub-step at the rig's contact damping
/// ratio 0.469, exact `e^{Re λh}` 0.48): the contact's own oscillation, which the resting test
/// has already found below `ε`, keeps dying out, and the slow quasi-static motion (time scale
/// `1/Ω`, ≥ 20 ms) is followed to RK4 accuracy. Measured on the 2,000-point accuracy sample:
/// the regime agreement with the f64 reference stays within its run-to-run scatter (README).
pub const RESTING_SUBSTEPS: u32 = 8;

/// `ε` of the resting test: the contact force balances the others to `ε`, and the
/// penetration rate is below `ε ω_c δ`.
pub const RESTING_TOLERANCE: f64 = 0.1;

/// Floor of the Lankarani–Nikravesh approach speed, m/s (avoids dividing by a grazing speed of 0).
const MIN_APPROACH_SPEED_M_S: f64 = 1e-4;

/// Fixed-step settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StepSettings {
    /// `N`: RK4 steps per excitation period (16..=512).
    pub steps_per_period: u32,
    /// `K`: sub-steps per contact half-period `π/ω_c` (4..=1024).
    pub substeps_per_contact: u32,
}

impl Default for StepSettings {
    /// The production settings (f32 on the MCU): `N = 64`, `K = 16`.
    fn default() -> Self {
        StepSettings {
            steps_per_period: 64,
            substeps_per_contact: 16,
        }
    }
}

impl StepSettings {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`ParamError::CountOutOfRange`] naming the field.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_count(
            "steps_per_period",
            self.steps_per_period,
            16,
            MAX_STEPS_PER_PERIOD,
        )?;
        check_count("substeps_per_contact", self.substeps_per_contact, 4, 1024)?;
        Ok(())
    }

    /// Both counts multiplied by `factor` (for convergence studies), saturating.
    pub fn refined(&self, factor: u32) -> Self {
        StepSettings {
            steps_per_period: self.steps_per_period.saturating_mul(factor),
            substeps_per_contact: self.substeps_per_contact.saturating_mul(factor),
        }
    }
}

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

/// Penetration and its rate where a segment (a free-flight step or segment, or a sub-step)
/// starts, `offset` s into the current step.
struct SegmentStart<T> {
    offset: T,
    delta: T,
    delta_dot: T,
}

/// Fixed-step switch-model integrator for one rig, gap and excitation frequency.
#[derive(Debug, Clone)]
pub struct Simulator<T: Real> {
    pub(super) hammer: Hammer<T>,
    pub(super) x: Vector2<T>,
    /// Rounding error of `x`'s compensated updates (free-flight segments and sub-steps, see
    /// `rk4_step_compensated`; whole free-flight steps leave it for the next one).
    pub(super) carry: Vector2<T>,
    /// Field at `x` (RK4's first stage of the next step).
    pub(super) at_x: FieldEval<T>,
    pub(super) n: u32,
    /// Step index within the period, `0..N`.
    pub(super) k: u32,
    period: u32,
    /// Steps since the last reset.
    pub(super) steps: u64,
    pub(super) h: T,
    /// Contact sub-step `h_c`, s.
    h_c: T,
    /// `sin(2π j/(2N))`, `j = 0..2N` (half-step phases).
    pub(super) sin_half: [T; 2 * MAX_STEPS_PER_PERIOD as usize],
    /// `cos(2π k/N)`, `k = 0..N` (step starts).
    cos_start: [T; MAX_STEPS_PER_PERIOD as usize],
    /// `Ω`, rad/s.
    omega: T,
    approach_speed: T,
    min_approach: T,
    h_f64: f64,
    h_c_f64: f64,
    /// Longest free-flight sub-step after a departure, s: `π/(2 ω_c)`, half the contact
    /// half-period at the reference speed (the shortest contact of the law).
    receding_max: T,
    /// `ω_c`, rad/s (the contact frequency that sets `h_c`).
    omega_c: T,
    pub(super) rk4_steps: u64,
}

impl<T: Real> Simulator<T> {
    /// A simulator at rest relative to the cart (`u = 0`, `u̇ = 0`) at phase 0.
    ///
    /// # Errors
    /// [`ParamError`] for invalid parameters, gap (m, `0 ..= 0.05`), `omega_exc` (rad/s), bands
    /// or step settings, or more than 10^6 contact sub-steps per step (`substeps`).
    pub fn new(
        params: &RigParams,
        gap_m: f64,
        omega_exc: f64,
        bands: &SwitchBands,
        steps: &StepSettings,
    ) -> Result<Self, ParamError> {
        steps.validate()?;
        let hammer = Hammer::<T>::new(params, gap_m, omega_exc, bands)?;
        let omega_c = params
            .contact
            .contact_omega(params.mass_kg, SUBSTEP_REFERENCE_SPEED_M_S);
        Self::from_hammer(hammer, omega_c, steps)
    }

    /// A simulator at rest relative to the cart at phase 0 for an already compiled `hammer`
    /// (e.g. one whose excitation was switched off for a drop test,
    /// [`crate::analysis::drop`]); `omega_c` (rad/s) is the contact frequency that sets the
    /// sub-step ([`crate::model::ContactLaw::contact_omega`]).
    ///
    /// # Errors
    /// [`ParamError`] for invalid step settings, a non-finite or non-positive `omega_c`, or
    /// more than 10^6 contact sub-steps per step (`substeps`).
    pub fn from_hammer(
        hammer: Hammer<T>,
        omega_c: f64,
        steps: &StepSettings,
    ) -> Result<Self, ParamError> {
        steps.validate()?;
        check_range("omega_c", omega_c, 1e-6, 1e12)?;
        let omega_exc = hammer.omega_exc;
        let period_s = 2.0 * core::f64::consts::PI / omega_exc;
        let n = steps.steps_per_period;
        let h = period_s / f64::from(n);
        let h_c_max = core::f64::consts::PI / omega_c / f64::from(steps.substeps_per_contact);
        let m_f = libm::ceil(h / h_c_max);
        check_range("substeps", m_f, 1.0, MAX_SUBSTEPS)?;
        let h_c = h / m_f;
        let mut sin_half = [T::zero(); 2 * MAX_STEPS_PER_PERIOD as usize];
        let mut cos_start = [T::zero(); MAX_STEPS_PER_PERIOD as usize];
        let dphi = core::f64::consts::PI / f64::from(n);
        for (j, v) in sin_half.iter_mut().take(2 * n as usize).enumerate() {
            *v = T::from_f64(libm::sin(dphi * j as f64));
        }
        for (k, v) in cos_start.iter_mut().take(n as usize).enumerate() {
            *v = T::from_f64(libm::cos(2.0 * dphi * k as f64));
        }
        let x = Vector2::new(T::zero(), T::zero());
        let min_approach = T::from_f64(MIN_APPROACH_SPEED_M_S);
        let at_x = hammer.field(&x, T::zero(), min_approach);
        Ok(Simulator {
            hammer,
            x,
            carry: Vector2::new(T::zero(), T::zero()),
            at_x,
            n,
            k: 0,
            period: 0,
            steps: 0,
            h: T::from_f64(h),
            h_c: T::from_f64(h_c),
            sin_half,
            cos_start,
            omega: T::from_f64(omega_exc),
            approach_speed: min_approach,
            min_approach,
            h_f64: h,
            h_c_f64: h_c,
            receding_max: T::from_f64(0.5 * core::f64::consts::PI / omega_c),
            omega_c: T::from_f64(omega_c),
            rk4_steps: 0,
        })
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
        self.x = x;
        self.carry = Vector2::new(T::zero(), T::zero());
        self.k = 0;
        self.period = 0;
        self.steps = 0;
        self.approach_speed = self.min_approach;
        self.at_x = self.hammer.field(&x, T::zero(), self.approach_speed);
    }

    /// The compiled model.
    pub fn hammer(&self) -> &Hammer<T> {
        &self.hammer
    }
    /// Current state vector.
    pub fn state(&self) -> Vector2<T> {
        self.x
    }
    /// Penetration `δ` (m) at the current state, as evaluated with the current step's field.
    pub fn state_penetration(&self) -> T {
        self.at_x.delta
    }
    /// Current `(u, u̇)`, m and m/s.
    pub fn relative(&self) -> (T, T) {
        self.hammer.relative(&self.x)
    }
    /// `N`, steps per period.
    pub fn steps_per_period(&self) -> u32 {
        self.n
    }
    /// Step `h = T/N`, s (f64).
    pub fn step_s(&self) -> f64 {
        self.h_f64
    }
    /// Contact sub-step `h_c = h/M`, s (f64).
    pub fn substep_s(&self) -> f64 {
        self.h_c_f64
    }
    /// Completed excitation periods since the last reset.
    pub fn periods_done(&self) -> u32 {
        self.period
    }
    /// RK4 steps and sub-steps executed since construction (cost diagnostics).
    pub fn rk4_steps(&self) -> u64 {
        self.rk4_steps
    }

    /// `sin Ωt` at `dt` seconds (`0 ≤ Ω dt ≤ 2π/N`) after the start of the current step.
    #[inline(always)]
    fn sin_at(&self, dt: T) -> T {
        let (s, c) = (self.omega * dt).sin_cos();
        let k = self.k as usize;
        self.sin_half[2 * k] * c + self.cos_start[k] * s
    }

    /// Whether the hammer is clear of the surface: free region and `δ ≤ −η_δ`.
    #[inline(always)]
    pub(super) fn clear(&self, e: &FieldEval<T>) -> bool {
        e.region == Region::Free && e.delta <= -self.hammer.switch.eta_delta
    }

    /// Advances one step of `h = T/N`, calling `observe` after every segment of it (the whole
    /// step in free flight, or the free-flight segments and contact sub-steps it was split into).
    #[inline]
    pub fn step<O: FnMut(&StepSample<T>)>(&mut self, observe: &mut O) {
        let k2 = 2 * self.k as usize;
        let j_end = if self.k + 1 == self.n { 0 } else { k2 + 2 };
        let (s_mid, s_end) = (self.sin_half[k2 + 1], self.sin_half[j_end]);
        let mut offset = T::zero();
        let mut rest = self.h;
        let mut first = true;
        loop {
            // Where this segment starts (for the smallest δ over it, reported with its sample).
            let seg = SegmentStart {
                offset,
                delta: self.at_x.delta,
                delta_dot: self.at_x.delta_dot,
            };
            if self.clear(&self.at_x) {
                let (sm, se) = if first {
                    (s_mid, s_end)
                } else {
                    (self.sin_at(offset + rest * T::from_f64(0.5)), s_end)
                };
                match self.free_trial(rest, sm, se) {
                    Ok((x1, end)) => {
                        self.x = x1;
                        self.at_x = end;
                        self.finish_step(&seg, observe);
                        return;
                    }
                    Err(t_near) => {
                        // Stop half a sub-step short of the surface, so that the arrival
                        // falls inside the next sub-step (not on its boundary, where the
                        // switch would go through the Σ_α band instead of being located).
                        let tau = t_near - self.h_c * T::from_f64(0.5);
                        if tau > self.h_c * T::from_f64(0.25) {
                            self.free_segment(offset, tau);
                            offset += tau;
                            rest -= tau;
                            first = false;
                            observe(&self.sample(offset, false, &seg));
                            continue;
                        }
                    }
                }
            }
            first = false;
            let len = match self.receding_len(rest) {
                Some(len) => len,
                None if self.resting() => self.h_c * T::from_u32(RESTING_SUBSTEPS),
                None => self.h_c,
            };
            if rest <= len {
                self.substep(offset, rest, s_end);
                self.finish_step(&seg, observe);
                return;
            }
            let s_next = self.sin_at(offset + len);
            self.substep(offset, len, s_next);
            offset += len;
            rest -= len;
            observe(&self.sample(offset, false, &seg));
        }
    }

    /// Whether the hammer rests on (or creeps along) the surface, so that the sub-step may be
    /// [`RESTING_SUBSTEPS`] times longer: it moves slowly relative to the surface
    /// (`|δ̇| ≤ ε ω_c max(|δ|, η_δ)`: an arrival at that speed is a touch, not an impact), and in
    /// contact (`Γ+`) the contact's own fast motion has died out (the contact force balances the
    /// others: `|ẍ| ≤ ε F/m` in the state's units); `ε` = [`RESTING_TOLERANCE`]. In the bands
    /// and in free flight there is no contact spring, hence no fast oscillation; an arrival or a
    /// departure inside the longer sub-step is located as in any sub-step.
    #[inline(always)]
    fn resting(&self) -> bool {
        let e = &self.at_x;
        let eps = T::from_f64(RESTING_TOLERANCE);
        let scale = e.delta.abs().max_of(self.hammer.switch.eta_delta);
        if e.delta_dot.abs() > eps * self.omega_c * scale {
            return false;
        }
        e.region != Region::Contact || e.dx[1].abs() <= eps * self.hammer.contact_accel(e.force)
    }

    /// After a departure (free region, `δ > −η_δ`, moving away from the surface: `δ̇ < 0`), the
    /// length of the one free-flight sub-step that takes the hammer clear: twice the time to
    /// `δ = −η_δ` at the current speed, at most the rest of the step and at most
    /// [`Simulator::receding_max`] (a quarter of the shortest contact period, so that a whole
    /// re-contact cannot hide inside it; a re-contact that is still on at its end is located as
    /// in any sub-step). `None` where ordinary sub-steps apply (it would not be longer than one).
    #[inline(always)]
    fn receding_len(&self, rest: T) -> Option<T> {
        let e = &self.at_x;
        if e.region != Region::Free || e.delta_dot >= T::zero() {
            return None;
        }
        let eta = self.hammer.switch.eta_delta;
        let to_clear = (e.delta + eta) / (T::zero() - e.delta_dot);
        let len = (to_clear * T::from_f64(2.0))
            .min_of(self.receding_max)
            .min_of(rest);
        (len > self.h_c).then_some(len)
    }

    /// Tries `rest` seconds (to the end of the step) in free flight from the current state, with
    /// `sin Ωt` `s_mid`, `s_end` at the segment's midpoint and end. `Ok` with the end state and
    /// its switch-model field if the hammer stays clear; otherwise `Err` with the time (s from
    /// the segment's start) at which the trial's dense output first comes within `η_δ` of the
    /// surface, or peaks.
    #[inline(always)]
    fn free_trial(&mut self, rest: T, s_mid: T, s_end: T) -> Result<(Vector2<T>, FieldEval<T>), T> {
        let hammer = self.hammer;
        let eta = hammer.switch.eta_delta;
        let v_in = self.approach_speed;
        let start = self.at_x;
        // In free flight `f−` (so that the trial is the free dense output used below); a stage
        // within η_δ of the surface is where the switch model would have left `Γ−`.
        let mut touched = false;
        // A plain update (the carry is left for the next compensated one): the increment of a
        // free-flight step is a tenth of the state, not small enough for compensation to pay,
        // and the lockstep lanes take the same steps without carrying a second state.
        let x1 = rk4_step(&self.x, &start.dx, rest, s_mid, s_end, |y, s| {
            let (acc, delta) = hammer.free_accel(y, s);
            touched |= delta > -eta;
            Vector2::new(y[1], acc)
        });
        // Clear of the surface, the free field is the switch-model field.
        let end = hammer.field_in(FieldMode::Free, &x1, s_end, v_in);
        self.rk4_steps += 1;
        let mut near = touched || end.delta > -eta;
        if !near && start.delta_dot > T::zero() && end.delta_dot < T::zero() {
            // Turned round inside the step: the peak lies under the two tangent lines.
            let slope = start.delta_dot - end.delta_dot;
            let t_star = (end.delta - start.delta - end.delta_dot * rest) / slope;
            near = start.delta + start.delta_dot * t_star > -eta;
        }
        if !near {
            return Ok((x1, end));
        }
        // Where the free-flight dense output first comes near the surface (or peaks).
        let dense = DenseStep {
            x0: self.x,
            f0: start.dx,
            x1,
            f1: end.dx,
            h: rest,
        };
        let delta_at = |t: T| hammer.penetration(&dense.at(t / rest)).0;
        const SAMPLES: u32 = 8;
        let dt = rest / T::from_u32(SAMPLES);
        let (mut best_t, mut best_d) = (T::zero(), start.delta);
        for i in 1..=SAMPLES {
            let t = dt * T::from_u32(i);
            let d = delta_at(t);
            if d > -eta {
                // Refine the crossing of −η_δ between the previous sample and this one.
                // (Bisection, 10 halvings, to 1/8192 of the step: this only places the start of the
                // sub-steps.)
                let (mut lo, mut hi) = (t - dt, t);
                for _ in 0..10 {
                    let mid = (lo + hi) * T::from_f64(0.5);
                    if delta_at(mid) > -eta {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                return Err(lo);
            }
            if d > best_d {
                best_t = t;
                best_d = d;
            }
        }
        Err(best_t)
    }

    /// One free-flight RK4 step of `len` seconds from `offset` (s into the current step).
    #[inline(always)]
    fn free_segment(&mut self, offset: T, len: T) {
        let hammer = self.hammer;
        let v_in = self.approach_speed;
        let s_mid = self.sin_at(offset + len * T::from_f64(0.5));
        let s_end = self.sin_at(offset + len);
        (self.x, self.carry) = rk4_step_compensated(
            &self.x,
            &self.carry,
            &self.at_x.dx,
            len,
            s_mid,
            s_end,
            |y, s| hammer.field_in(FieldMode::Free, y, s, v_in).dx,
        );
        self.at_x = hammer.field(&self.x, s_end, v_in);
        self.rk4_steps += 1;
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
        let half = T::from_f64(0.5);
        let s_mid = self.sin_at(offset + len * half);
        let start = self.at_x;
        self.rk4_steps += 1;
        let touching = start.region.touching();
        if !touching && start.delta <= T::zero() {
            self.approach_speed = start.delta_dot.max_of(self.min_approach);
        }
        let v_in = self.approach_speed;
        let mode = if touching {
            FieldMode::Contact
        } else {
            FieldMode::Free
        };
        // Outside the bands the switch-model field at the start is the mode's field: reuse it.
        let k1 = match start.region {
            Region::Free | Region::Contact => start,
            Region::BandAlpha | Region::BandBeta => {
                hammer.field_in(mode, &self.x, self.sin_at(offset), v_in)
            }
        };
        let (trial, carry) =
            rk4_step_compensated(&self.x, &self.carry, &k1.dx, len, s_mid, s_end, |y, s| {
                hammer.field_in(mode, y, s, v_in).dx
            });
        let end = hammer.field(&trial, s_end, v_in);
        if end.region.touching() == touching {
            self.x = trial;
            self.carry = carry;
            self.at_x = end;
            return;
        }
        // A switching event inside the sub-step.
        let end_mode = hammer.field_in(mode, &trial, s_end, v_in);
        let law = hammer.switch.law;
        let arrival_by_distance = start.delta <= T::zero();
        let event = |y: &Vector2<T>| {
            let (d, dd) = hammer.penetration(y);
            if touching {
                -law.unswitched_force(d, dd, v_in)
            } else if arrival_by_distance {
                d
            } else {
                law.unswitched_force(d, dd, v_in)
            }
        };
        let dense = DenseStep {
            x0: self.x,
            f0: k1.dx,
            x1: trial,
            f1: end_mode.dx,
            h: len,
        };
        let frac = root_in_unit(|f| event(&dense.at(f)));
        let tau = frac * len;
        // The state at the event from the trial's dense output (cubic Hermite: error
        // `h_c^4/384 · |d⁴x/dt⁴|`, as small as a fresh RK4 step's to `τ`, which it replaces).
        let x_a = dense.at(frac);
        if !touching {
            let (_, v_a) = hammer.penetration(&x_a);
            self.approach_speed = v_a.max_of(self.min_approach);
        }
        let v_in = self.approach_speed;
        let rest = len - tau;
        let at_a = hammer.field(&x_a, self.sin_at(offset + tau), v_in);
        (self.x, self.carry) = rk4_step_compensated(
            &x_a,
            &Vector2::new(T::zero(), T::zero()),
            &at_a.dx,
            rest,
            self.sin_at(offset + tau + rest * half),
            s_end,
            |y, s| hammer.field(y, s, v_in).dx,
        );
        self.at_x = hammer.field(&self.x, s_end, v_in);
        // The trial and the rest of the sub-step.
        self.rk4_steps += 1;
    }

    /// Ends the current step: advances the step counters and reports the sample.
    #[inline(always)]
    fn finish_step<O: FnMut(&StepSample<T>)>(&mut self, seg: &SegmentStart<T>, observe: &mut O) {
        let sample = self.sample(self.h, true, seg);
        self.steps += 1;
        self.k += 1;
        if self.k == self.n {
            self.k = 0;
            self.period += 1;
        }
        observe(&sample);
    }

    #[inline(always)]
    fn sample(&self, offset: T, step_end: bool, seg: &SegmentStart<T>) -> StepSample<T> {
        let e = &self.at_x;
        StepSample {
            step: self.steps,
            offset,
            period_end: step_end && self.k + 1 == self.n,
            x: self.x,
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

    /// Runs one full excitation period (`N` steps).
    pub fn run_period<O: FnMut(&StepSample<T>)>(&mut self, observe: &mut O) {
        let target = self.period + 1;
        while self.period < target {
            self.step(observe);
        }
    }
}

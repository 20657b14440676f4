//! The period-locked switch-model integrator.
//!
//! - `N` RK4 steps per excitation period, `h = T/N`, so the stroboscopic Poincaré section
//!   `t = kT` falls exactly on step boundaries.
//! - Time is an integer step index; the excitation phase of a stage is
//!   `2π · j / (2N)` (or `/(2NM)` in sub-steps) from integers reduced modulo one period, so
//!   there is no `t += h` drift in f32.
//! - A step is first tried in one piece. If the hammer is in or near contact at either end
//!   (`δ > −η_δ`), if the step turned round and its tangent-line peak bound reaches `−η_δ`, or if
//!   any RK4 stage touched the contact region, the step is redone as `M` equal sub-steps with
//!   the full switch model. `M = ceil(h / h_c)`, `h_c = (π/ω_c)/K` with `ω_c` the contact
//!   frequency ([`crate::model::ContactLaw::contact_omega`]) and `K` sub-steps per contact
//!   half-period. A sub-step costs one RK4 step, or three when a switching event (arrival or
//!   departure) falls inside it ([`Simulator::step`]). The cost of a period is therefore bounded
//!   by `N (1 + 3M)` RK4 steps; in practice it is `N` plus about `2M` per impact.

use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

use super::rk4::rk4_step;
use crate::error::{ParamError, check_count, check_range};
use crate::model::hammer::{FieldEval, FieldMode};
use crate::model::{Hammer, Region, RigParams, SwitchBands};
use crate::real::Real;

/// Impact speed (m/s) at which the power laws' contact time is estimated for the sub-step size:
/// faster than any impact of the thesis' rigs (≤ 0.2 m/s), so real contacts get at least `K`
/// sub-steps per half-period.
pub const SUBSTEP_REFERENCE_SPEED_M_S: f64 = 0.5;

/// Largest phase denominator `2NM`: integers up to 2^24 are exact in f32.
const MAX_PHASE_DENOMINATOR: u64 = 1 << 24;

/// Floor of the Lankarani–Nikravesh approach speed, m/s (avoids dividing by a grazing speed of 0).
const MIN_APPROACH_SPEED_M_S: f64 = 1e-4;

/// Fixed-step settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StepSettings {
    /// `N`: RK4 steps per excitation period (16..=8192).
    pub steps_per_period: u32,
    /// `K`: sub-steps per contact half-period `π/ω_c` (4..=1024).
    pub substeps_per_contact: u32,
}

impl Default for StepSettings {
    /// The production settings (f32 on the MCU): `N = 256`, `K = 32`.
    fn default() -> Self {
        StepSettings {
            steps_per_period: 256,
            substeps_per_contact: 32,
        }
    }
}

impl StepSettings {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`ParamError::CountOutOfRange`] naming the field.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_count("steps_per_period", self.steps_per_period, 16, 8192)?;
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

/// The state after one RK4 step or sub-step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepSample<T> {
    /// Time in sub-step units since the start: `t = t_num · h_sub` ([`Simulator::substep_s`]).
    pub t_num: u64,
    /// Whether this sample ends an excitation period (a Poincaré-section instant).
    pub period_end: bool,
    /// State vector (`(θ, θ̇)` for wires, `(u, u̇)` for beams).
    pub x: Vector2<T>,
    /// Penetration `δ`, m.
    pub delta: T,
    /// Penetration rate `δ̇ = u̇`, m/s.
    pub delta_dot: T,
    /// Contact force `F_i`, N.
    pub force: T,
    /// Switch-model region.
    pub region: Region,
}

/// Fixed-step switch-model integrator for one rig, gap and excitation frequency.
#[derive(Debug, Clone)]
pub struct Simulator<T: Real> {
    hammer: Hammer<T>,
    x: Vector2<T>,
    /// Field at `x` (RK4's first stage of the next step).
    at_x: FieldEval<T>,
    n: u32,
    m: u32,
    /// Macro step index within the period, `0..N`.
    k: u32,
    period: u32,
    h: T,
    h_sub: T,
    macro_phase: T,
    sub_phase: T,
    /// `Ω`, rad/s.
    omega: T,
    approach_speed: T,
    min_approach: T,
    h_f64: f64,
    rk4_steps: u64,
}

impl<T: Real> Simulator<T> {
    /// A simulator at rest relative to the cart (`u = 0`, `u̇ = 0`) at phase 0.
    ///
    /// # Errors
    /// [`ParamError`] for invalid parameters, gap (m, `0 ..= 0.05`), `omega_exc` (rad/s), bands
    /// or step settings, or a sub-step count whose phase denominator `2NM` exceeds 2^24.
    pub fn new(
        params: &RigParams,
        gap_m: f64,
        omega_exc: f64,
        bands: &SwitchBands,
        steps: &StepSettings,
    ) -> Result<Self, ParamError> {
        steps.validate()?;
        let hammer = Hammer::<T>::new(params, gap_m, omega_exc, bands)?;
        let period_s = 2.0 * core::f64::consts::PI / omega_exc;
        let n = steps.steps_per_period;
        let h = period_s / f64::from(n);
        let omega_c = params
            .contact
            .contact_omega(params.mass_kg, SUBSTEP_REFERENCE_SPEED_M_S);
        let h_c = core::f64::consts::PI / omega_c / f64::from(steps.substeps_per_contact);
        let m_f = libm::ceil(h / h_c);
        check_range(
            "substeps",
            m_f,
            1.0,
            (MAX_PHASE_DENOMINATOR / (2 * u64::from(n))) as f64,
        )?;
        let m = m_f as u32;
        let two_pi = 2.0 * core::f64::consts::PI;
        let x = Vector2::new(T::zero(), T::zero());
        let min_approach = T::from_f64(MIN_APPROACH_SPEED_M_S);
        let at_x = hammer.field(&x, T::zero(), min_approach);
        Ok(Simulator {
            hammer,
            x,
            at_x,
            n,
            m,
            k: 0,
            period: 0,
            h: T::from_f64(h),
            h_sub: T::from_f64(h / f64::from(m)),
            macro_phase: T::from_f64(two_pi / f64::from(2 * n)),
            sub_phase: T::from_f64(two_pi / (2.0 * f64::from(n) * f64::from(m))),
            omega: T::from_f64(omega_exc),
            approach_speed: min_approach,
            min_approach,
            h_f64: h,
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
        self.k = 0;
        self.period = 0;
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
    /// Current `(u, u̇)`, m and m/s.
    pub fn relative(&self) -> (T, T) {
        self.hammer.relative(&self.x)
    }
    /// `N`, steps per period.
    pub fn steps_per_period(&self) -> u32 {
        self.n
    }
    /// `M`, sub-steps per step in and near contact.
    pub fn substeps(&self) -> u32 {
        self.m
    }
    /// Sub-step length `h/M`, s (f64).
    pub fn substep_s(&self) -> f64 {
        self.h_f64 / f64::from(self.m)
    }
    /// Completed excitation periods since the last reset.
    pub fn periods_done(&self) -> u32 {
        self.period
    }
    /// RK4 steps and sub-steps executed since construction (cost diagnostics).
    pub fn rk4_steps(&self) -> u64 {
        self.rk4_steps
    }

    #[inline(always)]
    fn macro_sin(&self, j: u32) -> T {
        let j = if j >= 2 * self.n { j - 2 * self.n } else { j };
        (T::from_u32(j) * self.macro_phase).sin()
    }

    #[inline(always)]
    fn sub_sin(&self, j: u32) -> T {
        let den = 2 * self.n * self.m;
        let j = if j >= den { j - den } else { j };
        (T::from_u32(j) * self.sub_phase).sin()
    }

    /// Advances one step of `h = T/N` (as `M` sub-steps if in or near contact), calling
    /// `observe` after the step or after every sub-step.
    #[inline]
    pub fn step<O: FnMut(&StepSample<T>)>(&mut self, observe: &mut O) {
        let eta = self.hammer.switch.eta_delta;
        let k = self.k;
        let start = self.at_x;
        let mut near = start.delta > -eta || start.region != Region::Free;
        if !near {
            // Try the whole step in free flight.
            let hammer = self.hammer;
            let v_in = self.approach_speed;
            let mut touched = false;
            let s_mid = self.macro_sin(2 * k + 1);
            let s_end = self.macro_sin(2 * k + 2);
            let x1 = rk4_step(&self.x, &start.dx, self.h, s_mid, s_end, |y, s| {
                let e = hammer.field(y, s, v_in);
                touched |= e.region != Region::Free;
                e.dx
            });
            let end = hammer.field(&x1, s_end, v_in);
            self.rk4_steps += 1;
            near = touched || end.delta > -eta || end.region != Region::Free;
            if !near && start.delta_dot > T::zero() && end.delta_dot < T::zero() {
                // Turned round inside the step: the peak lies under the two tangent lines.
                let slope = start.delta_dot - end.delta_dot;
                let t_star = (end.delta - start.delta - end.delta_dot * self.h) / slope;
                near = start.delta + start.delta_dot * t_star > -eta;
            }
            if !near {
                self.x = x1;
                self.at_x = end;
                self.advance_macro();
                observe(&self.sample(self.m));
                return;
            }
        }
        // Sub-steps with the full switch model.
        let base = 2 * k * self.m;
        for i in 0..self.m {
            self.substep(base + 2 * i);
            if i + 1 == self.m {
                self.advance_macro();
            }
            observe(&self.sample(i + 1));
        }
    }

    /// One sub-step from half-sub-step phase index `j` (the step spans `j .. j + 2`).
    ///
    /// The field is discontinuous where contact begins (the spring–dashpot force jumps to `c δ̇`)
    /// and has a kink where it ends (`h_β = 0`); a fixed step straddling either loses accuracy in
    /// proportion to where the event falls, which shows as jitter of the Poincaré section. So the
    /// sub-step is first taken in the mode of its start (free flight `f−`, or contact `f+` with
    /// the law continued past `h_β = 0`). If the switch model disagrees at the end, the event
    /// time `τ` is found by bisection on the step's cubic Hermite dense output (free → contact:
    /// `δ` or, when already inside, `h_β` rising through 0; contact → free: `h_β` falling
    /// through 0), the hammer is integrated in the old mode to `τ` and with the switch model from
    /// `τ` to the end of the sub-step. The step grid is unchanged.
    #[inline]
    fn substep(&mut self, j: u32) {
        let hammer = self.hammer;
        let s_mid = self.sub_sin(j + 1);
        let s_end = self.sub_sin(j + 2);
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
                hammer.field_in(mode, &self.x, self.sin_at(j, T::zero()), v_in)
            }
        };
        let trial = rk4_step(&self.x, &k1.dx, self.h_sub, s_mid, s_end, |y, s| {
            hammer.field_in(mode, y, s, v_in).dx
        });
        let end = hammer.field(&trial, s_end, v_in);
        if end.region.touching() == touching {
            self.x = trial;
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
        let tau = event_time(&self.x, &k1.dx, &trial, &end_mode.dx, self.h_sub, event);
        let half = T::from_f64(0.5);
        let x_a = rk4_step(
            &self.x,
            &k1.dx,
            tau,
            self.sin_at(j, tau * half),
            self.sin_at(j, tau),
            |y, s| hammer.field_in(mode, y, s, v_in).dx,
        );
        if !touching {
            let (_, v_a) = hammer.penetration(&x_a);
            self.approach_speed = v_a.max_of(self.min_approach);
        }
        let v_in = self.approach_speed;
        let rest = self.h_sub - tau;
        let at_a = hammer.field(&x_a, self.sin_at(j, tau), v_in);
        self.x = rk4_step(
            &x_a,
            &at_a.dx,
            rest,
            self.sin_at(j, tau + rest * half),
            s_end,
            |y, s| hammer.field(y, s, v_in).dx,
        );
        self.at_x = hammer.field(&self.x, s_end, v_in);
        // The trial, the step to the event and the rest of the sub-step.
        self.rk4_steps += 2;
    }

    /// `sin(Ω t)` at `dt` seconds after half-sub-step phase index `j`.
    #[inline(always)]
    fn sin_at(&self, j: u32, dt: T) -> T {
        (T::from_u32(j) * self.sub_phase + self.omega * dt).sin()
    }

    #[inline(always)]
    fn advance_macro(&mut self) {
        self.k += 1;
        if self.k == self.n {
            self.k = 0;
            self.period += 1;
        }
    }

    #[inline(always)]
    fn sample(&self, sub_end: u32) -> StepSample<T> {
        // After advance_macro the step index has moved on when sub_end == M.
        let (period, k) = if sub_end == self.m {
            if self.k == 0 {
                (self.period - 1, self.n - 1)
            } else {
                (self.period, self.k - 1)
            }
        } else {
            (self.period, self.k)
        };
        let t_num = (u64::from(period) * u64::from(self.n) + u64::from(k)) * u64::from(self.m)
            + u64::from(sub_end);
        StepSample {
            t_num,
            period_end: sub_end == self.m && self.k == 0,
            x: self.x,
            delta: self.at_x.delta,
            delta_dot: self.at_x.delta_dot,
            force: self.at_x.force,
            region: self.at_x.region,
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

/// Time `τ ∈ (0, h]` at which `event` rises through 0 along the cubic Hermite interpolant of
/// the step `x0 → x1` (slopes `f0`, `f1`), by bisection; `event(x0) ≤ 0 < event(x1)` is the
/// caller's premise (if it fails, the bisection returns a time at one end of the step).
#[inline]
fn event_time<T: Real, G: Fn(&Vector2<T>) -> T>(
    x0: &Vector2<T>,
    f0: &Vector2<T>,
    x1: &Vector2<T>,
    f1: &Vector2<T>,
    h: T,
    event: G,
) -> T {
    let one = T::from_f64(1.0);
    let two = T::from_f64(2.0);
    let three = T::from_f64(3.0);
    let half = T::from_f64(0.5);
    let at = |s: T| {
        let s2 = s * s;
        let s3 = s2 * s;
        let h00 = two * s3 - three * s2 + one;
        let h10 = (s3 - two * s2 + s) * h;
        let h01 = three * s2 - two * s3;
        let h11 = (s3 - s2) * h;
        x0 * h00 + f0 * h10 + x1 * h01 + f1 * h11
    };
    let (mut lo, mut hi) = (T::zero(), one);
    for _ in 0..32 {
        let mid = (lo + hi) * half;
        if event(&at(mid)) > T::zero() {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi * h
}

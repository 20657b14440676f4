//! What the integrator's steps are, fixed before the first one: the step settings (`N`, `K`),
//! the excitation phase on the step grid ([`PhaseTable`], shared by every simulator with the
//! same `N`) and one simulator's step lengths ([`StepPlan`]).

use serde::{Deserialize, Serialize};

use crate::error::{ParamError, check_count, check_range};
use crate::real::Real;

/// Largest `N` (a [`PhaseTable`] holds `3N` values).
pub const MAX_STEPS_PER_PERIOD: u32 = 512;

/// Largest `M = ceil(h/h_c)`, contact sub-steps per step.
const MAX_SUBSTEPS: f64 = 1e6;

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
        check_steps_per_period(self.steps_per_period)?;
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

/// `sin Ωt` and `cos Ωt` on the step grid of `N` steps per period: at every half step
/// (`sin(π j/N)`, `j < 2N`, and at `j = 2N` the period's end, which is the next period's start:
/// entry 0 again) and at every step start (`cos(2π k/N)`, `k < N`), from `libm` in
/// f64 rounded to `T`. It depends on `N` only, so one table serves every simulator of a grid.
#[derive(Debug, Clone)]
pub struct PhaseTable<T> {
    n: u32,
    sin_half: [T; 2 * MAX_STEPS_PER_PERIOD as usize + 1],
    cos_start: [T; MAX_STEPS_PER_PERIOD as usize],
}

impl<T: Real> PhaseTable<T> {
    /// The table for `steps_per_period` steps per period.
    ///
    /// # Errors
    /// [`ParamError::CountOutOfRange`] (`steps_per_period`, `16 ..= 512`).
    pub fn new(steps_per_period: u32) -> Result<Self, ParamError> {
        let n = check_steps_per_period(steps_per_period)?;
        let mut t = PhaseTable {
            n,
            sin_half: [T::zero(); 2 * MAX_STEPS_PER_PERIOD as usize + 1],
            cos_start: [T::zero(); MAX_STEPS_PER_PERIOD as usize],
        };
        fill(n, &mut t.sin_half, &mut t.cos_start);
        Ok(t)
    }

    /// `N`, steps per period.
    #[inline(always)]
    pub fn steps_per_period(&self) -> u32 {
        self.n
    }

    /// `sin(π j/N)`: `sin Ωt` at half step `j` (`j ≤ 2N`; step `k` starts at `j = 2k`; entry
    /// `2N` is entry 0).
    #[inline(always)]
    pub(crate) fn sin_half(&self, j: usize) -> T {
        self.sin_half[j]
    }

    /// `cos(2π k/N)`: `cos Ωt` at the start of step `k` (`k < N`).
    #[inline(always)]
    pub(crate) fn cos_start(&self, k: usize) -> T {
        self.cos_start[k]
    }

    /// `sin Ωt` at the midpoint and the end of step `k` (`k < N`; the end of the last step is
    /// the next period's start).
    #[inline(always)]
    pub(crate) fn step_mid_end(&self, k: u32) -> (T, T) {
        let k2 = 2 * k as usize;
        (self.sin_half[k2 + 1], self.sin_half[k2 + 2])
    }
}

/// The table's values for `n` steps per period (out of line: `libm`'s sine and cosine are
/// compiled once, not into every caller; flash on the MCU).
#[inline(never)]
fn fill<T: Real>(n: u32, sin_half: &mut [T], cos_start: &mut [T]) {
    let dphi = core::f64::consts::PI / f64::from(n);
    for (j, v) in sin_half.iter_mut().take(2 * n as usize).enumerate() {
        *v = T::from_f64(libm::sin(dphi * j as f64));
    }
    // The period's end is the next period's start, exactly (not the rounded `sin 2π`).
    let start = sin_half.first().copied().unwrap_or_else(T::zero);
    if let Some(end) = sin_half.get_mut(2 * n as usize) {
        *end = start;
    }
    for (k, v) in cos_start.iter_mut().take(n as usize).enumerate() {
        *v = T::from_f64(libm::cos(2.0 * dphi * k as f64));
    }
}

/// One simulator's step lengths in its float type: `h = T/N`, the contact sub-step
/// `h_c = h/M` with `M = ceil(h / ((π/ω_c)/K))`, and the constants the stepper derives from
/// `Ω` and `ω_c`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepPlan<T> {
    /// `h`, s.
    pub(crate) h: T,
    /// `h_c`, s.
    pub(crate) h_c: T,
    /// `Ω` rounded to `T`, rad/s (the phase inside a step).
    pub(crate) omega: T,
    /// `ω_c`, rad/s: the contact frequency that sets `h_c`.
    pub(crate) omega_c: T,
    /// The sub-step while the hammer rests on the surface, `R h_c` with
    /// `R = `[`resting_substeps`]`(K)`, s.
    pub(crate) h_rest: T,
    /// Longest free-flight sub-step after a departure, `π/(2 ω_c)` s: half the contact
    /// half-period at the reference speed (the shortest contact of the law).
    pub(crate) receding_max: T,
    /// Width, as a fraction of the sub-step, below which a switching event's bracket stops
    /// shrinking: `2^-14` in production ([`super::dense::EVENT_TOL`]); a few rounding units
    /// where the map must be smooth to round-off ([`super::Simulator::locate_events_exactly`]).
    pub(crate) event_tol: T,
}

impl<T: Real> StepPlan<T> {
    /// The plan for excitation `omega_exc` and contact frequency `omega_c` (rad/s) with
    /// `steps`.
    ///
    /// # Errors
    /// [`ParamError`] for invalid step settings, a non-finite or non-positive `omega_c`, or
    /// more than 10^6 contact sub-steps per step (`substeps`).
    pub fn new(omega_exc: f64, omega_c: f64, steps: &StepSettings) -> Result<Self, ParamError> {
        steps.validate()?;
        check_range("omega_c", omega_c, 1e-6, 1e12)?;
        let h = step_s(omega_exc, steps.steps_per_period);
        let h_c_max = core::f64::consts::PI / omega_c / f64::from(steps.substeps_per_contact);
        let m = check_range("substeps", libm::ceil(h / h_c_max), 1.0, MAX_SUBSTEPS)?;
        Ok(StepPlan {
            h: T::from_f64(h),
            h_c: T::from_f64(h / m),
            omega: T::from_f64(omega_exc),
            omega_c: T::from_f64(omega_c),
            h_rest: T::from_f64(h / m) * T::from_u32(resting_substeps(steps.substeps_per_contact)),
            receding_max: T::from_f64(0.5 * core::f64::consts::PI / omega_c),
            event_tol: T::from_f64(super::dense::EVENT_TOL),
        })
    }
}

/// Contact sub-steps `h_c` per sub-step while the hammer rests on the surface, for `K`
/// sub-steps per contact half-period: `R = min(8, K/2)`, so that the resting sub-step is at
/// most a quarter of the contact period, `ω_c · R h_c ≤ π/2`, inside RK4's stability region for
/// every `K` (`|R(λh)|` 0.55 per sub-step at the spring–dashpot law's damping ratio 0.469;
/// test `resting_substep_is_stable` in `shared/tests/analytic.rs`), and no longer than `8 h_c`
/// for the finer convergence references. The production `K = 16` gives 8, the embedded
/// `K = 8` gives 4.
pub fn resting_substeps(substeps_per_contact: u32) -> u32 {
    (substeps_per_contact / 2).clamp(1, 8)
}

/// `N` within `16 ..= MAX_STEPS_PER_PERIOD` ([`ParamError::CountOutOfRange`] otherwise).
fn check_steps_per_period(n: u32) -> Result<u32, ParamError> {
    check_count("steps_per_period", n, 16, MAX_STEPS_PER_PERIOD)
}

/// `h = (2π/Ω)/N`, s, in f64.
#[inline]
pub(crate) fn step_s(omega_exc: f64, steps_per_period: u32) -> f64 {
    2.0 * core::f64::consts::PI / omega_exc / f64::from(steps_per_period)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phase_table_holds_the_step_grid() {
        let t = PhaseTable::<f64>::new(64).unwrap();
        for k in 0..64u32 {
            let (mid, end) = t.step_mid_end(k);
            let phase = |steps: f64| libm::sin(core::f64::consts::TAU * steps / 64.0);
            assert!((mid - phase(f64::from(k) + 0.5)).abs() < 1e-15);
            assert!((end - phase(f64::from(k + 1))).abs() < 1e-15);
            let c = libm::cos(core::f64::consts::TAU * f64::from(k) / 64.0);
            assert!((t.cos_start(k as usize) - c).abs() < 1e-15);
        }
        assert!(matches!(
            PhaseTable::<f32>::new(8),
            Err(ParamError::CountOutOfRange {
                field: "steps_per_period",
                ..
            })
        ));
    }

    #[test]
    fn plan_divides_the_step_into_whole_substeps() {
        // Ω = 2π rad/s (T = 1 s), N = 64: h = 1/64 s; ω_c = 1000 rad/s, K = 16:
        // h_c ≤ π/1000/16 ≈ 196 µs → M = ceil(15.625 ms / 196 µs) = 80.
        let plan =
            StepPlan::<f64>::new(core::f64::consts::TAU, 1000.0, &StepSettings::default()).unwrap();
        assert_eq!(libm::round(plan.h / plan.h_c), 80.0);
        assert!((plan.h - 1.0 / 64.0).abs() < 1e-15);
        // h_c = h/M, not the upper bound π/ω_c/K it was sized by.
        assert!((plan.h_c - 1.0 / 64.0 / 80.0).abs() < 1e-18);
        assert!(matches!(
            StepPlan::<f32>::new(1.0, f64::NAN, &StepSettings::default()),
            Err(ParamError::NotFinite { field: "omega_c" })
        ));
    }
}

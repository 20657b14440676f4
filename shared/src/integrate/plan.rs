//! What the integrator's steps are, fixed before the first one: the step settings (`N`, `K`),
//! the excitation phase on the step grid ([`PhaseTable`], shared by every simulator with the
//! same `N`) and one simulator's step lengths ([`StepPlan`]).

use serde::{Deserialize, Serialize};

#[cfg(all(feature = "std", target_arch = "x86_64"))]
use super::isa::Isa;
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

    /// [`PhaseTable::step_mid_end`] of every lane's step `k[i]`, clamped to `N − 1` (a lane
    /// past its period's end reads a valid entry): `(sin Ωt at the midpoints, at the ends)`,
    /// read with one gather instruction per array where `isa` has one ([`Isa::gather`]);
    /// `None` where it has not (the caller reads the lanes one by one).
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[inline(always)]
    pub(crate) fn step_mid_end_gathered<const L: usize>(
        &self,
        isa: Isa,
        k: &[u32; L],
    ) -> Option<([T; L], [T; L])> {
        let last = self.n - 1;
        let mut j = [0u32; L];
        for i in 0..L {
            j[i] = 2 * k[i].min(last) + 1;
        }
        let mid = isa.gather(&self.sin_half, &j)?;
        for ji in &mut j {
            *ji += 1;
        }
        Some((mid, isa.gather(&self.sin_half, &j)?))
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
    /// `Ω` rounded to `T`, rad/s (the phase inside a step).
    pub(crate) omega: T,
    /// The contact sub-step `h_c` and the rule for the sub-steps' lengths.
    pub(crate) substep: SubstepRule<T>,
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
            omega: T::from_f64(omega_exc),
            substep: SubstepRule {
                h_c: T::from_f64(h / m),
                h_rest: T::from_f64(h / m)
                    * T::from_u32(resting_substeps(steps.substeps_per_contact)),
                receding_max: T::from_f64(0.5 * core::f64::consts::PI / omega_c),
                eps_omega_c: T::from_f64(RESTING_TOLERANCE) * T::from_f64(omega_c),
            },
            event_tol: T::from_f64(super::dense::EVENT_TOL),
        })
    }
}

/// `ε` of the resting test: the contact force balances the others to `ε`, and the
/// penetration rate is below `ε ω_c δ` (the resting sub-step of [`resting_substeps`]).
pub const RESTING_TOLERANCE: f64 = 0.1;

/// The rule for a contact sub-step's length (`Simulator::plain_substep`), as lanes of
/// several runs can evaluate it without a branch: `h_c`, the resting sub-step, the longest
/// receding sub-step and `ε ω_c` of the resting test.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SubstepRule<T> {
    pub(crate) h_c: T,
    pub(crate) h_rest: T,
    pub(crate) receding_max: T,
    pub(crate) eps_omega_c: T,
}

impl<T: Real> SubstepRule<T> {
    /// The next sub-step's length from a state in the free region or not (`free`), in `Γ+` or
    /// not (`contact`), at penetration `delta` (m) moving at `delta_dot` (m/s), with the second
    /// component of the field `acc` and the contact force's part of it `contact_acc()`
    /// (`Hammer::contact_accel`; asked for only in `Γ+`), `rest` s before the step's end, and
    /// whether it ends the
    /// step (then it is `rest`):
    /// - after a departure (free, `δ̇ < 0`), the one free-flight sub-step that takes the hammer
    ///   clear: twice the time to `δ = −η_δ` at the current speed, at most the rest of the step
    ///   and at most `π/(2 ω_c)` (a quarter of the shortest contact period, so that a whole
    ///   re-contact cannot hide inside it; a re-contact still on at its end is located as in any
    ///   sub-step), where that is longer than `h_c`;
    /// - while the hammer rests on (or creeps along) the surface, [`resting_substeps`] times
    ///   `h_c`: it moves slowly relative to the surface (`|δ̇| ≤ ε ω_c max(|δ|, η_δ)`: an
    ///   arrival at that speed is a touch, not an impact), and in contact (`Γ+`) the contact's
    ///   own fast motion has died out (the contact force balances the others: `|ẍ| ≤ ε F/m` in
    ///   the state's units); `ε` = [`RESTING_TOLERANCE`]. In the bands and in free flight there
    ///   is no contact spring, hence no fast oscillation; an arrival or a departure inside the
    ///   longer sub-step is located as in any sub-step;
    /// - else `h_c`.
    // Negated comparisons: the rule as it reads, a NaN going the way it always went.
    #[allow(clippy::too_many_arguments, clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    pub(crate) fn len(
        &self,
        eta_delta: T,
        free: bool,
        contact: bool,
        delta: T,
        delta_dot: T,
        acc: T,
        contact_acc: impl FnOnce() -> T,
        rest: T,
    ) -> (T, bool) {
        let zero = T::zero();
        // (0 where it does not apply: never longer than `h_c`.)
        let receding_len = if free && !(delta_dot >= zero) {
            let to_clear = (delta + eta_delta) / (zero - delta_dot);
            (to_clear * T::from_f64(2.0))
                .min_of(self.receding_max)
                .min_of(rest)
        } else {
            zero
        };
        let receding = receding_len > self.h_c;
        let resting = || {
            let scale = delta.abs().max_of(eta_delta);
            let eps = T::from_f64(RESTING_TOLERANCE);
            !(delta_dot.abs() > self.eps_omega_c * scale)
                && (!contact || acc.abs() <= eps * contact_acc())
        };
        let len = if receding {
            receding_len
        } else if resting() {
            self.h_rest
        } else {
            self.h_c
        };
        if rest <= len {
            (rest, true)
        } else {
            (len, false)
        }
    }
}

/// Contact sub-steps `h_c` per sub-step while the hammer rests on the surface, for `K`
/// sub-steps per contact half-period: `R = min(8, K/2)`, so that the resting sub-step is at
/// most a quarter of the contact period, `ω_c · R h_c ≤ π/2`, inside RK4's stability region for
/// every `K` (`|R(λh)|` 0.55 per sub-step at the spring–dashpot law's damping ratio 0.469;
/// test `resting_substep_is_stable` in `shared/tests/all/analytic.rs`), and no longer than `8 h_c`
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
        assert_eq!(libm::round(plan.h / plan.substep.h_c), 80.0);
        assert!((plan.h - 1.0 / 64.0).abs() < 1e-15);
        // h_c = h/M, not the upper bound π/ω_c/K it was sized by.
        assert!((plan.substep.h_c - 1.0 / 64.0 / 80.0).abs() < 1e-18);
        assert!(matches!(
            StepPlan::<f32>::new(1.0, f64::NAN, &StepSettings::default()),
            Err(ParamError::NotFinite { field: "omega_c" })
        ));
    }
}

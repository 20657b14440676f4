//! The canonical protocol (MODEL.md): from the simulator's current state (by default at rest
//! relative to the cart at phase 0), a transient of at most `max_transient_periods` periods that
//! ends early once the Poincaré section repeats with a period `q ≤ max_q` to `steady_tol` for
//! `steady_cycles` consecutive cycles of `q`; then an observation window of `observe_periods`
//! periods in which the regime, the impacts and the maximum impact force are measured.
//!
//! Tolerances are relative to the cart's motion: displacement over `A0`, velocity over `A0 Ω`
//! ([`StroboPoint::distance`]).

use heapless::Vec;
use serde::{Deserialize, Serialize};

use super::impact::{ImpactEvent, ImpactTracker};
use super::poincare::{HISTORY, SectionHistory, StroboPoint};
use super::regime::{Regime, classify};
use crate::error::{ParamError, check_count, check_range};
use crate::integrate::{Simulator, StepSample};
use crate::real::Real;

/// Largest observation window, periods.
pub const MAX_OBSERVE_PERIODS: usize = 256;

/// Protocol settings (defaults: MODEL.md "Canonical protocol").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Protocol {
    /// Longest transient, periods (200).
    pub max_transient_periods: u32,
    /// Largest period `q` searched, periods (16).
    pub max_q: u32,
    /// Steady-state tolerance on the scaled Poincaré distance (1e-4).
    pub steady_tol: f64,
    /// Consecutive repeating cycles of `q` that declare a steady state (3).
    pub steady_cycles: u32,
    /// Observation window, periods (64).
    pub observe_periods: u32,
    /// Tolerance on the scaled Poincaré distance for classifying the window (1e-3: looser than
    /// `steady_tol` so that a state that is still converging at the end of a full-length
    /// transient is not called irregular).
    pub classify_tol: f64,
}

impl Default for Protocol {
    fn default() -> Self {
        Protocol {
            max_transient_periods: 200,
            max_q: 16,
            steady_tol: 1e-4,
            steady_cycles: 3,
            observe_periods: 64,
            classify_tol: 1e-3,
        }
    }
}

impl Protocol {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`ParamError`] naming the field: `max_q` 1..=16, `steady_cycles` 1..=3 (the history holds
    /// 64 = 4·16 periods), `observe_periods` `2·max_q ..= 256`, tolerances in `1e-9 ..= 1`.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_count(
            "max_transient_periods",
            self.max_transient_periods,
            0,
            1_000_000,
        )?;
        check_count("max_q", self.max_q, 1, 16)?;
        check_count(
            "steady_cycles",
            self.steady_cycles,
            1,
            (HISTORY as u32 / self.max_q) - 1,
        )?;
        check_count(
            "observe_periods",
            self.observe_periods,
            2 * self.max_q,
            MAX_OBSERVE_PERIODS as u32,
        )?;
        check_range("steady_tol", self.steady_tol, 1e-9, 1.0)?;
        check_range("classify_tol", self.classify_tol, 1e-9, 1.0)?;
        Ok(())
    }
}

/// What the protocol measured at one operating point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PointResult {
    /// Impact regime of the observation window.
    pub regime: Regime,
    /// Arrivals (impacts) in the observation window.
    pub impacts: u32,
    /// Maximum contact force over the observation window, N.
    pub max_force_n: f64,
    /// The same over the hammer weight: `F_i/mg`.
    pub impact_force_mg: f64,
    /// Transient periods run before the window.
    pub transient_periods: u32,
    /// Whether the transient ended on a detected steady state (not on its length limit).
    pub settled: bool,
    /// RK4 steps and sub-steps spent (cost diagnostics).
    pub rk4_steps: u64,
}

/// Hooks into a protocol run; every method defaults to doing nothing.
/// `window` tells whether the event lies in the observation window.
pub trait Observer<T> {
    /// After every RK4 step or sub-step.
    fn sample(&mut self, _s: &StepSample<T>, _window: bool) {}
    /// At every Poincaré-section instant `t = kT`.
    fn strobe(&mut self, _p: &StroboPoint<T>, _window: bool) {}
    /// At the end of every impact episode, with its peak force (N).
    fn impact(&mut self, _peak_n: T, _window: bool) {}
}

impl<T> Observer<T> for () {}

/// Runs the protocol from `sim`'s current state and phase. `weight_n` is `m g` (N) for `F_i/mg`.
///
/// # Errors
/// [`ParamError`] if `protocol` is invalid.
pub fn run_protocol<T: Real, O: Observer<T>>(
    sim: &mut Simulator<T>,
    protocol: &Protocol,
    weight_n: f64,
    obs: &mut O,
) -> Result<PointResult, ParamError> {
    protocol.validate()?;
    let hammer = *sim.hammer();
    let u_scale = hammer.amplitude;
    let v_scale = T::from_f64(hammer.amplitude.to_f64() * hammer.omega_exc);
    let steady_tol = T::from_f64(protocol.steady_tol);
    let (delta0, _) = hammer.penetration(&sim.state());
    let mut tracker = ImpactTracker::new(hammer.switch.eta_delta, delta0);
    let rk4_start = sim.rk4_steps();

    // Transient.
    let mut history = SectionHistory::<T>::default();
    let mut transient = 0;
    let mut settled = false;
    while transient < protocol.max_transient_periods {
        run_observed_period(sim, &mut tracker, obs, false);
        transient += 1;
        let (u, du) = sim.relative();
        let p = StroboPoint { u, du };
        obs.strobe(&p, false);
        history.push(p);
        if history
            .repeating_period(
                protocol.max_q as usize,
                protocol.steady_cycles as usize,
                steady_tol,
                u_scale,
                v_scale,
            )
            .is_some()
        {
            settled = true;
            break;
        }
    }

    // Observation window.
    let mut section: Vec<StroboPoint<T>, MAX_OBSERVE_PERIODS> = Vec::new();
    let mut impacts: Vec<u16, MAX_OBSERVE_PERIODS> = Vec::new();
    let mut max_force = T::zero();
    let mut total = 0u32;
    for _ in 0..protocol.observe_periods {
        let (arrivals, fmax) = run_observed_period(sim, &mut tracker, obs, true);
        max_force = max_force.max_of(fmax);
        total += u32::from(arrivals);
        let (u, du) = sim.relative();
        let p = StroboPoint { u, du };
        obs.strobe(&p, true);
        // Capacities hold by validation (observe_periods ≤ 256).
        let _ = section.push(p);
        let _ = impacts.push(arrivals);
    }
    let regime = classify(
        &section,
        &impacts,
        protocol.max_q as usize,
        T::from_f64(protocol.classify_tol),
        u_scale,
        v_scale,
    );
    let max_force_n = max_force.to_f64();
    Ok(PointResult {
        regime,
        impacts: total,
        max_force_n,
        impact_force_mg: max_force_n / weight_n,
        transient_periods: transient,
        settled,
        rk4_steps: sim.rk4_steps() - rk4_start,
    })
}

/// One period: feeds the tracker and the observer; returns (arrivals, max force in N).
fn run_observed_period<T: Real, O: Observer<T>>(
    sim: &mut Simulator<T>,
    tracker: &mut ImpactTracker<T>,
    obs: &mut O,
    window: bool,
) -> (u16, T) {
    let mut arrivals = 0u16;
    let mut fmax = T::zero();
    sim.run_period(&mut |s: &StepSample<T>| {
        fmax = fmax.max_of(s.force);
        match tracker.update(s.delta, s.force) {
            Some(ImpactEvent::Arrival) => arrivals = arrivals.saturating_add(1),
            Some(ImpactEvent::End { peak_n }) => obs.impact(peak_n, window),
            None => {}
        }
        obs.sample(s, window);
    });
    (arrivals, fmax)
}

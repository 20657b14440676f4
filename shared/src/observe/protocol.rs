//! The canonical protocol (docs/model.md, "Canonical protocol"): from the simulator's current state (by default at rest
//! relative to the cart at phase 0), a transient of at most `max_transient_periods` periods that
//! ends early once the Poincaré section repeats with a period `q ≤ max_q` to `steady_tol` for
//! `steady_cycles` consecutive cycles of `q`; then an observation window of `observe_periods`
//! periods in which the regime, the impacts and the maximum impact force are measured.
//!
//! Tolerances are relative to the cart's motion: displacement over `A0`, velocity over `A0 Ω`
//! ([`StroboPoint::distance`]).

use heapless::Vec;
use serde::{Deserialize, Serialize};

use super::impact::{DEFAULT_SEPARATION_M, ImpactEvent, ImpactTracker};
use super::poincare::{HISTORY, SectionHistory, StroboPoint};
use super::regime::{Regime, classify};
use crate::error::{ParamError, check_count, check_range};
use crate::integrate::contact_lanes::{QuietSample, SampleBook};
use crate::integrate::{Simulator, StepSample};
use crate::real::Real;

/// Largest observation window, periods.
pub const MAX_OBSERVE_PERIODS: usize = 256;

/// Protocol settings (defaults: docs/model.md, "Canonical protocol").
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
    /// Separation that ends an impact episode, m (1e-6; [`DEFAULT_SEPARATION_M`]): re-contacts
    /// before the hammer has left the surface by this much belong to the same impact.
    #[serde(default = "default_separation_m")]
    pub separation_m: f64,
}

fn default_separation_m() -> f64 {
    DEFAULT_SEPARATION_M
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
            separation_m: DEFAULT_SEPARATION_M,
        }
    }
}

impl Protocol {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`ParamError`] naming the field: `max_q` 1..=16, `steady_cycles` 1..=3 (the history holds
    /// 64 = 4·16 periods), `observe_periods` `2·max_q ..= 256`, tolerances in `1e-9 ..= 1`,
    /// `separation_m` in `1e-12 ..= 1e-3` m.
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
        check_range("separation_m", self.separation_m, 1e-12, 1e-3)?;
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
    /// Whether [`Observer::sample`] does anything. If not, steps in free flight clear of the
    /// surface may be taken without calling it ([`ProtocolRun::free_flight_allowed`]).
    const SAMPLES: bool = true;
    /// After every RK4 step or sub-step.
    fn sample(&mut self, _s: &StepSample<T>, _window: bool) {}
    /// At every Poincaré-section instant `t = kT`.
    fn strobe(&mut self, _p: &StroboPoint<T>, _window: bool) {}
    /// At the end of every impact episode, with its peak force (N).
    fn impact(&mut self, _peak_n: T, _window: bool) {}
    /// Whether the observer has seen enough and the run should end now (checked after each
    /// Poincaré section; e.g. the trajectory has reached a known attractor,
    /// [`super::recurrence::RecurrenceWatch`]). The [`PointResult`] of a run ended this way
    /// describes only the periods run.
    fn stop(&self) -> bool {
        false
    }
}

impl<T> Observer<T> for () {
    const SAMPLES: bool = false;
}

/// Runs the protocol from `sim`'s current state and phase. `weight_n` is `m g` (N) for `F_i/mg`.
///
/// # Errors
/// [`ParamError`] if `protocol` is invalid.
pub fn run_protocol<T: Real, O: Observer<T>>(
    sim: &mut Simulator<'_, T>,
    protocol: &Protocol,
    weight_n: f64,
    obs: &mut O,
) -> Result<PointResult, ParamError> {
    let mut run = ProtocolRun::new(sim, protocol, weight_n)?;
    loop {
        if let Some(result) = run.step(sim, obs) {
            return Ok(result);
        }
    }
}

/// The protocol as a resumable computation, advanced one integrator step at a time by
/// [`ProtocolRun::step`] ([`run_protocol`] loops over it). Several runs stepped in turn on one
/// core overlap their floating-point latency chains (`crate::analysis::batch`).
#[derive(Debug, Clone)]
pub struct ProtocolRun<T: Real> {
    protocol: Protocol,
    weight_n: f64,
    u_scale: T,
    v_scale: T,
    steady_tol: T,
    tracker: ImpactTracker<T>,
    rk4_start: u64,
    history: SectionHistory<T>,
    transient: u32,
    settled: bool,
    in_window: bool,
    observed: u32,
    arrivals: u16,
    period_force: T,
    max_force: T,
    total: u32,
    section: Vec<StroboPoint<T>, MAX_OBSERVE_PERIODS>,
    impacts: Vec<u16, MAX_OBSERVE_PERIODS>,
    done: Option<PointResult>,
}

impl<T: Real> ProtocolRun<T> {
    /// Starts the protocol from `sim`'s current state and phase (which must be at a period
    /// boundary, as after construction or a reset). `weight_n` is `m g`, N.
    ///
    /// # Errors
    /// [`ParamError`] if `protocol` is invalid.
    pub fn new(
        sim: &Simulator<'_, T>,
        protocol: &Protocol,
        weight_n: f64,
    ) -> Result<Self, ParamError> {
        protocol.validate()?;
        let hammer = *sim.hammer();
        let (delta0, _) = hammer.penetration(&sim.state());
        let in_window = protocol.max_transient_periods == 0;
        Ok(ProtocolRun {
            protocol: *protocol,
            weight_n,
            u_scale: hammer.amplitude(),
            v_scale: T::from_f64(hammer.amplitude().to_f64() * hammer.omega_exc()),
            steady_tol: T::from_f64(protocol.steady_tol),
            tracker: ImpactTracker::new(T::from_f64(protocol.separation_m), delta0),
            rk4_start: sim.rk4_steps(),
            history: SectionHistory::default(),
            transient: 0,
            settled: false,
            in_window,
            observed: 0,
            arrivals: 0,
            period_force: T::zero(),
            max_force: T::zero(),
            total: 0,
            section: Vec::new(),
            impacts: Vec::new(),
            done: None,
        })
    }

    /// Advances `sim` by one integrator step (feeding the tracker and `obs`); at a period end,
    /// takes the Poincaré point and decides whether the transient is over. Returns the result
    /// once the observation window is complete (and from then on returns it without stepping).
    pub fn step<O: Observer<T>>(
        &mut self,
        sim: &mut Simulator<'_, T>,
        obs: &mut O,
    ) -> Option<PointResult> {
        if self.done.is_some() {
            return self.done;
        }
        let mut period_end = false;
        sim.step(&mut |s: &StepSample<T>| period_end |= self.sample(s, obs));
        self.end_step(sim, obs, period_end)
    }

    /// Feeds one sample of the current step to the impact tracker and `obs` (what
    /// [`ProtocolRun::step`] does with each sample of its step, for callers that take the
    /// segments of a step themselves, `crate::analysis::batch`). Returns whether it ends a
    /// period.
    #[inline(always)]
    pub fn sample<O: Observer<T>>(&mut self, s: &StepSample<T>, obs: &mut O) -> bool {
        let window = self.in_window;
        self.period_force = self.period_force.max_of(s.force);
        match self.tracker.update(s.delta, s.delta_min, s.force) {
            Some(ImpactEvent::Arrival) => self.arrivals = self.arrivals.saturating_add(1),
            Some(ImpactEvent::End { peak_n }) => obs.impact(peak_n, window),
            None => {}
        }
        obs.sample(s, window);
        s.period_end
    }

    /// The book of the samples (impact tracker and the period's largest force) for a contact
    /// lane that takes quiet samples for this run ([`QuietSample`]).
    #[inline(always)]
    pub(crate) fn sample_book(&self) -> SampleBook<T> {
        let (separation, prev_delta, in_episode, peak) = self.tracker.parts();
        SampleBook {
            separation,
            prev_delta,
            in_episode,
            peak,
            period_force: self.period_force,
        }
    }

    /// Takes back the book after quiet samples a contact lane took.
    #[inline(always)]
    pub(crate) fn resume_book(&mut self, book: &SampleBook<T>) {
        self.tracker.resume(book.prev_delta, book.peak);
        self.period_force = book.period_force;
    }

    /// Ends a step whose samples went to [`ProtocolRun::sample`] (`period_end`: whether one of
    /// them ended a period): at a period end, takes the Poincaré point and decides whether the
    /// transient is over. Returns the result once the observation window is complete.
    pub fn end_step<O: Observer<T>>(
        &mut self,
        sim: &Simulator<'_, T>,
        obs: &mut O,
        period_end: bool,
    ) -> Option<PointResult> {
        if !period_end {
            return None;
        }
        let window = self.in_window;
        let (u, du) = sim.relative();
        let p = StroboPoint { u, du };
        obs.strobe(&p, window);
        if obs.stop() {
            self.done = Some(self.result(sim));
            return self.done;
        }
        let (arrivals, fmax) = (self.arrivals, self.period_force);
        self.arrivals = 0;
        self.period_force = T::zero();
        if !window {
            self.transient += 1;
            self.history.push(p);
            let repeating = self
                .history
                .repeating_period(
                    self.protocol.max_q as usize,
                    self.protocol.steady_cycles as usize,
                    self.steady_tol,
                    self.u_scale,
                    self.v_scale,
                )
                .is_some();
            if repeating {
                self.settled = true;
            }
            if repeating || self.transient >= self.protocol.max_transient_periods {
                self.in_window = true;
            }
            return None;
        }
        self.max_force = self.max_force.max_of(fmax);
        self.total += u32::from(arrivals);
        // Capacities hold by validation (observe_periods ≤ 256).
        let _ = self.section.push(p);
        let _ = self.impacts.push(arrivals);
        self.observed += 1;
        if self.observed < self.protocol.observe_periods {
            return None;
        }
        self.done = Some(self.result(sim));
        self.done
    }

    /// Whether `sim` may now take whole free-flight steps outside [`ProtocolRun::step`]
    /// ([`crate::integrate::lanes`], which stop before every step that affects
    /// the protocol: a Poincaré-section instant or one near the surface): the run is not done,
    /// no impact episode is open, and the observer ignores samples. Such steps must be booked
    /// with [`ProtocolRun::after_free_flight`].
    #[inline]
    pub fn free_flight_allowed<O: Observer<T>>(&self) -> bool {
        !O::SAMPLES && self.done.is_none() && !self.tracker.in_episode()
    }

    /// Books free-flight steps taken on `sim` since the last [`ProtocolRun::step`]: in free
    /// flight clear of the surface they change only the impact tracker's last penetration
    /// (the force is 0, so the period's maximum stays).
    #[inline]
    pub fn after_free_flight(&mut self, sim: &Simulator<'_, T>) {
        self.tracker.clear_at(sim.state_penetration());
    }

    fn result(&self, sim: &Simulator<'_, T>) -> PointResult {
        let regime = classify(
            &self.section,
            &self.impacts,
            self.protocol.max_q as usize,
            T::from_f64(self.protocol.classify_tol),
            self.u_scale,
            self.v_scale,
        );
        let max_force_n = self.max_force.to_f64();
        PointResult {
            regime,
            impacts: self.total,
            max_force_n,
            impact_force_mg: max_force_n / self.weight_n,
            transient_periods: self.transient,
            settled: self.settled,
            rk4_steps: sim.rk4_steps() - self.rk4_start,
        }
    }
}

impl<T: Real> QuietSample<T> for ProtocolRun<T> {
    /// [`ProtocolRun::sample`] of a sample without an impact event (the tracker's
    /// [`ImpactTracker::quiet`]): the period's largest force and the tracker's previous
    /// penetration and peak.
    #[inline(always)]
    fn take(book: &SampleBook<T>, delta: T, delta_min: T, force: T) -> (SampleBook<T>, bool) {
        let quiet = ImpactTracker::quiet(
            book.separation,
            book.prev_delta,
            book.in_episode,
            delta,
            delta_min,
        );
        let peak = if book.in_episode {
            book.peak.max_of(force)
        } else {
            book.peak
        };
        let next = SampleBook {
            prev_delta: delta,
            peak,
            period_force: book.period_force.max_of(force),
            ..*book
        };
        (next, quiet)
    }
}

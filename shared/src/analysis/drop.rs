//! The drop test of the contact-law identification (thesis §3.3.2, Figs. 3.8–3.10): the cart
//! stands still (no excitation), the hammer is pulled back from the impact surface by
//! `release` and let go at rest; it swings (wires) or springs (beam) into the surface and
//! bounces several times. The measured force–time trace of these impacts is what the thesis
//! fitted the contact laws to (MATLAB `fminsearch` on the peak forces).
//!
//! The simulation is the same switch-model integrator as every other analysis
//! ([`Simulator`]), on the rig compiled by [`Hammer::new`] with its excitation term set to
//! zero (`A0 Ω² = 0`): Eq. (3-16) (wires) or Eq. (3-33) (beam springs) with `y(t) = 0`.
//! The integrator still needs a step grid: the fictitious "excitation period" is the free
//! hammer's natural period `2π/ω`, so `steps_per_period` of [`StepSettings`] is the number of
//! RK4 steps per natural period here; the contact sub-steps are the usual ones
//! (`substeps_per_contact` per contact half-period).

use crate::error::{ParamError, check_range};
use crate::integrate::{PhaseTable, Simulator, StepSample, StepSettings};
use crate::model::{Hammer, RigParams, SwitchBands};
use crate::observe::{DEFAULT_SEPARATION_M, ImpactEvent, ImpactTracker};
use crate::real::Real;

use crate::integrate::stepper::SUBSTEP_REFERENCE_SPEED_M_S;

/// Longest drop simulation, s.
pub const MAX_DROP_DURATION_S: f64 = 1e4;

/// One drop test: where the surface is, where the hammer is let go, how long to watch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DropSpec {
    /// Gap between the hammer's rest position and the impact surface, m (`0 ..= 0.05`; the
    /// thesis' drop test: 0, the hammer resting against the surface).
    pub gap_m: f64,
    /// Distance from the impact surface at which the hammer is released at rest, m
    /// (`> gap`: the hammer starts at `u0 = gap − release`; thesis: about 3 mm).
    pub release_m: f64,
    /// Simulated time, s (`0 < duration ≤ 1e4`).
    pub duration_s: f64,
    /// Stop after this many impacts have ended (0: no limit, run for `duration_s`).
    pub max_impacts: u32,
}

impl DropSpec {
    /// Checks the spec (the gap is checked by [`Hammer::new`], the start `u0` by
    /// [`Simulator::reset_relative`]).
    ///
    /// # Errors
    /// [`ParamError`] naming `release_m` (`gap_m + 1e-6 ..= 0.1` m) or `duration_s`.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_range("gap_m", self.gap_m, 0.0, 0.05)?;
        check_range("release_m", self.release_m, self.gap_m + 1e-6, 0.1)?;
        check_range("duration_s", self.duration_s, 1e-6, MAX_DROP_DURATION_S)?;
        Ok(())
    }
}

/// One integrator sample of a drop test (after every RK4 step, free-flight segment or contact
/// sub-step).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DropSample {
    /// Time since the release, s.
    pub t_s: f64,
    /// Hammer displacement `u` (the cart stands still: `u = x`), m; the surface is at `u = gap`.
    pub u_m: f64,
    /// Hammer velocity `u̇`, m/s.
    pub du_m_s: f64,
    /// Contact force `F_i`, N.
    pub force_n: f64,
}

/// One impact of a drop test: from the arrival through `δ = 0` until the hammer has left the
/// surface by the separation [`DEFAULT_SEPARATION_M`] (1 µm), re-contacts included
/// ([`ImpactTracker`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DropImpact {
    /// 0 for the first impact.
    pub index: u32,
    /// Time of the sample that detected the arrival, s (within one contact sub-step after it).
    pub arrival_s: f64,
    /// Approach speed `δ̇` of the last sample before the arrival, m/s.
    pub approach_speed_m_s: f64,
    /// Peak contact force over the episode, N.
    pub peak_n: f64,
    /// Time of the peak sample, s.
    pub peak_s: f64,
    /// Time at which the episode ended (`δ` below minus the separation), s.
    pub end_s: f64,
}

/// What [`run_drop`] reports, in time order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DropRecord {
    /// An integrator sample.
    Sample(DropSample),
    /// An impact episode has ended.
    Impact(DropImpact),
}

/// Totals of a drop run.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DropSummary {
    /// Impacts that ended within the run.
    pub impacts: u32,
    /// Simulated time, s.
    pub t_end_s: f64,
    /// RK4 steps and sub-steps spent (cost diagnostics).
    pub rk4_steps: u64,
}

/// A simulator of the drop test `spec`, released (at rest, `u = gap − release`), on the step
/// grid of `phases` (built for `steps.steps_per_period`).
///
/// # Errors
/// [`ParamError`] for invalid parameters, bands, steps or spec, a table for another `N`, or a
/// start the suspension cannot take (wires: `|u0| ≥ l/2`).
pub fn drop_simulator<'t, T: Real>(
    params: &RigParams,
    spec: &DropSpec,
    bands: &SwitchBands,
    steps: &StepSettings,
    phases: &'t PhaseTable<T>,
) -> Result<Simulator<'t, T>, ParamError> {
    spec.validate()?;
    let hammer = Hammer::<T>::new(params, spec.gap_m, params.omega_n(), bands)?;
    let omega_c = params
        .contact
        .contact_omega(params.mass_kg, SUBSTEP_REFERENCE_SPEED_M_S);
    let mut sim = Simulator::from_hammer(hammer.without_excitation(), omega_c, steps, phases)?;
    sim.reset_relative(spec.gap_m - spec.release_m, 0.0)?;
    Ok(sim)
}

/// Runs the drop test `spec` with the switch-model integrator in the float type `T`, reporting
/// every sample and every impact to `report` in time order. The initial state is reported as
/// the first sample (`t = 0`).
///
/// # Errors
/// As [`drop_simulator`].
pub fn run_drop<T: Real, F: FnMut(&DropRecord)>(
    params: &RigParams,
    spec: &DropSpec,
    bands: &SwitchBands,
    steps: &StepSettings,
    mut report: F,
) -> Result<DropSummary, ParamError> {
    let phases = PhaseTable::new(steps.steps_per_period)?;
    let mut sim = drop_simulator::<T>(params, spec, bands, steps, &phases)?;
    let hammer = *sim.hammer();
    let h = sim.step_s();
    let (d0, dd0) = hammer.penetration(&sim.state());
    let mut tracker = ImpactTracker::new(T::from_f64(DEFAULT_SEPARATION_M), d0);
    let (u0, du0) = sim.relative();
    report(&DropRecord::Sample(DropSample {
        t_s: 0.0,
        u_m: u0.to_f64(),
        du_m_s: du0.to_f64(),
        force_n: 0.0,
    }));
    let mut summary = DropSummary::default();
    let mut prev_rate = dd0.to_f64();
    let mut current: Option<DropImpact> = None;
    let mut t = 0.0;
    let mut done = false;
    while t < spec.duration_s && !done {
        sim.step(&mut |s: &StepSample<T>| {
            t = s.time_s(h);
            let (u, du) = hammer.relative(&s.x);
            let force = s.force.to_f64();
            report(&DropRecord::Sample(DropSample {
                t_s: t,
                u_m: u.to_f64(),
                du_m_s: du.to_f64(),
                force_n: force,
            }));
            match tracker.update(s.delta, s.delta_min, s.force) {
                Some(ImpactEvent::Arrival) => {
                    current = Some(DropImpact {
                        index: summary.impacts,
                        arrival_s: t,
                        approach_speed_m_s: prev_rate,
                        peak_n: force,
                        peak_s: t,
                        end_s: t,
                    });
                }
                Some(ImpactEvent::End { .. }) => {
                    if let Some(mut imp) = current.take() {
                        imp.end_s = t;
                        if !done {
                            report(&DropRecord::Impact(imp));
                            summary.impacts += 1;
                            done = spec.max_impacts > 0 && summary.impacts >= spec.max_impacts;
                        }
                    }
                }
                None => {
                    if let Some(imp) = current.as_mut()
                        && force > imp.peak_n
                    {
                        imp.peak_n = force;
                        imp.peak_s = t;
                    }
                }
            }
            prev_rate = s.delta_dot.to_f64();
        });
    }
    summary.t_end_s = t;
    summary.rk4_steps = sim.rk4_steps();
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::contact::spring_dashpot_restitution;
    use crate::model::{ContactLaw, RigId};
    use std::vec::Vec;

    /// The impacts of a drop at gap 0 from `release_m` over `duration_s` (at most
    /// `max_impacts`), at `steps` = (steps per natural period, sub-steps per contact).
    fn impacts(
        params: &RigParams,
        release_m: f64,
        duration_s: f64,
        max_impacts: u32,
        steps: (u32, u32),
    ) -> Vec<DropImpact> {
        let spec = DropSpec {
            gap_m: 0.0,
            release_m,
            duration_s,
            max_impacts,
        };
        let steps = StepSettings {
            steps_per_period: steps.0,
            substeps_per_contact: steps.1,
        };
        let mut out = Vec::new();
        run_drop::<f64, _>(params, &spec, &SwitchBands::default(), &steps, |r| {
            if let DropRecord::Impact(i) = r {
                out.push(*i);
            }
        })
        .unwrap();
        out
    }

    #[test]
    fn wire_drop_hits_at_a_quarter_period_with_the_energy_speed_and_closed_form_restitution() {
        // Wires at gap 0, released 3 mm from the surface: a free pendulum, so the first arrival
        // is at a quarter of the natural period (plus the small-angle correction, < 0.01 %) at
        // the energy speed sqrt(2 g l (1 − cos θ0)); each spring–dashpot impact multiplies the
        // speed by the closed-form restitution (0.317 for Table 3.1) and the free flight
        // between impacts is half a period.
        let p = RigId::Wires.preset();
        let imp = impacts(&p, 3e-3, 1.0, 3, (256, 64));
        assert_eq!(imp.len(), 3);
        let w = p.omega_n();
        let quarter = core::f64::consts::FRAC_PI_2 / w;
        assert!((imp[0].arrival_s - quarter).abs() < 2e-5, "{imp:?}");
        let theta0 = libm::asin(3e-3 / 0.075);
        let v = libm::sqrt(2.0 * 9.81 * 0.075 * (1.0 - libm::cos(theta0)));
        assert!(
            (imp[0].approach_speed_m_s - v).abs() < 1e-3 * v,
            "{} vs {v}",
            imp[0].approach_speed_m_s
        );
        let (e, tc) = spring_dashpot_restitution(5.5e6, 1.2e3, 0.298).unwrap();
        for k in 1..3 {
            let ratio = imp[k].approach_speed_m_s / imp[k - 1].approach_speed_m_s;
            assert!((ratio - e).abs() < 3e-3, "impact {k}: {ratio} vs {e}");
            // One contact time, the flight from the exit penetration δ_c = (c/k)·e v (where
            // k δ + c δ̇ = 0) back to δ = 0 at speed e v, i.e. c/k, and half a natural period.
            let dt = imp[k].arrival_s - imp[k - 1].arrival_s;
            let expect = core::f64::consts::PI / w + tc + 1.2e3 / 5.5e6;
            assert!((dt - expect).abs() < 5e-5, "{dt} vs {expect}");
        }
        // The excitation is off: the same drop at another (fictitious) step grid agrees.
        let coarse = impacts(&p, 3e-3, 1.0, 3, (128, 32));
        assert!((coarse[0].peak_n - imp[0].peak_n).abs() < 2e-3 * imp[0].peak_n);
    }

    #[test]
    fn linear_impact_peak_matches_the_closed_form_contact() {
        // One spring–dashpot impact at speed v: F(t) = v e^{−ζω t}[c cos ω_d t + ((k − cζω)/ω_d)
        // sin ω_d t]; its maximum, found on a fine grid, is the simulated peak (the suspension's
        // force is 1e-3 of the contact force during the 0.6 ms contact).
        let mut p = RigId::Beam170.preset();
        p.contact = ContactLaw::SpringDashpot {
            stiffness_n_m: 4e6,
            damping_n_s_m: 600.0,
        };
        let imp = impacts(&p, 2e-3, 0.2, 1, (256, 256));
        assert_eq!(imp.len(), 1);
        let v = imp[0].approach_speed_m_s;
        let (k, c, m) = (4e6, 600.0, p.mass_kg);
        let wn = libm::sqrt(k / m);
        let z = c / (2.0 * libm::sqrt(k * m));
        let wd = wn * libm::sqrt(1.0 - z * z);
        let peak = (0..20000)
            .map(|i| {
                let t = i as f64 * 1e-8;
                v * libm::exp(-z * wn * t)
                    * (c * libm::cos(wd * t) + (k - c * z * wn) / wd * libm::sin(wd * t))
            })
            .fold(0.0, f64::max);
        assert!(
            (imp[0].peak_n - peak).abs() < 3e-3 * peak,
            "{} vs {peak}",
            imp[0].peak_n
        );
    }

    #[test]
    fn bad_specs_are_named() {
        let p = RigId::Wires.preset();
        let b = SwitchBands::default();
        let s = StepSettings::default();
        let mut spec = DropSpec {
            gap_m: 1e-3,
            release_m: 0.5e-3,
            duration_s: 1.0,
            max_impacts: 0,
        };
        let phases = PhaseTable::new(s.steps_per_period).unwrap();
        assert!(matches!(
            drop_simulator::<f64>(&p, &spec, &b, &s, &phases),
            Err(ParamError::OutOfRange {
                field: "release_m",
                ..
            })
        ));
        spec.release_m = 3e-3;
        spec.duration_s = f64::NAN;
        assert!(matches!(
            drop_simulator::<f64>(&p, &spec, &b, &s, &phases),
            Err(ParamError::NotFinite {
                field: "duration_s"
            })
        ));
    }
}

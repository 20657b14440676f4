//! Time series of one operating point: every RK4 step or sub-step of a run from a given
//! initial state, with the impacts counted.

use anyhow::{Context, Result};
use serde::Serialize;
use shared::Real;
use shared::integrate::{PhaseTable, Simulator, StepSample};
use shared::observe::{ImpactEvent, ImpactTracker};
use shared::orbit::{MapPoint, exponent_along_with};

use crate::config::Setup;

/// One CSV row (after every RK4 step or sub-step).
#[derive(Debug, Clone, Serialize)]
pub struct TsRow {
    /// Time since the start, s.
    pub t_s: f64,
    /// Relative displacement `u`, mm.
    pub u_mm: f64,
    /// Relative velocity `u̇`, mm/s.
    pub du_mm_s: f64,
    /// Absolute hammer displacement `x = u + A0 sin Ωt`, mm (Eq. 3-18).
    pub x_mm: f64,
    /// Contact force `F_i`, N.
    pub impact_force_n: f64,
    /// `F_i/mg`.
    pub impact_force_mg: f64,
    /// Switch-model region: free, contact, band-alpha, band-beta.
    pub region: &'static str,
    /// Whether the row is a Poincaré-section instant `t = kT`.
    pub poincare: bool,
    /// At a Poincaré instant after `k ≥ 1` periods: the running estimate of the largest
    /// Lyapunov exponent over the first `k` periods, per period (empty elsewhere).
    pub lyapunov_per_period: Option<f64>,
}

/// Summary of a run.
#[derive(Debug, Clone, Copy, Default)]
pub struct TsSummary {
    /// Impacts (arrivals).
    pub impacts: u32,
    /// Largest episode peak, `F_i/mg`.
    pub max_force_mg: f64,
    /// The largest Lyapunov exponent along the written trajectory over the run, per period,
    /// and its uncertainty (half the difference of the run's halves); `None` for a run of one
    /// period.
    pub lyapunov: Option<(f64, f64)>,
    /// Where the impacts stopped for the rest of the run (at least [`IMPACT_FREE_TAIL`]
    /// periods): the motion the run ends on is another than the one its exponent averages over.
    pub impacts_stopped: Option<ImpactsStopped>,
}

/// Fewest impact-free periods at the end of a run, after impacts, that [`TsSummary`] reports
/// as the impacts having stopped (the response's exponent window).
pub const IMPACT_FREE_TAIL: u32 = 64;

/// A run whose impacts stopped: a transient that escaped to a non-impacting motion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImpactsStopped {
    /// The period (1-based) in which the last impact arrived.
    pub last_impact_period: u32,
    /// Periods after it, to the run's end.
    pub impact_free_periods: u32,
    /// The largest Lyapunov exponent along the written trajectory over those periods, per
    /// period, and its uncertainty: the non-impacting motion's (0 for the undamped wire
    /// pendulum, `−2πζ/(Ω/ω)` for a damped linear suspension).
    pub lyapunov: (f64, f64),
}

/// One run of a time series: `periods` excitation periods at `omega_exc` (rad/s) and gap
/// `gap_m` (m), from the relative state `(u0_m, v0_m_s)` (m, m/s) at phase 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeriesSpec {
    /// Gap, m.
    pub gap_m: f64,
    /// Excitation angular frequency `Ω`, rad/s.
    pub omega_exc: f64,
    /// Excitation periods to simulate.
    pub periods: u32,
    /// Initial relative displacement, m.
    pub u0_m: f64,
    /// Initial relative velocity, m/s.
    pub v0_m_s: f64,
}

/// Simulates `spec` in the setup's precision: one row at `t = 0` and one after every RK4 step
/// or sub-step, and the impacts counted.
///
/// # Errors
/// Invalid parameters or initial state.
pub fn simulate(setup: &Setup, spec: &SeriesSpec) -> Result<(Vec<TsRow>, TsSummary)> {
    crate::with_precision!(setup.precision, T => time_series::<T>(setup, spec))
}

fn time_series<T: Real>(setup: &Setup, spec: &SeriesSpec) -> Result<(Vec<TsRow>, TsSummary)> {
    let &SeriesSpec {
        gap_m,
        omega_exc,
        periods,
        u0_m,
        v0_m_s,
    } = spec;
    let phases = PhaseTable::new(setup.settings.steps.steps_per_period)?;
    let mut sim = Simulator::<T>::new(
        &setup.params,
        gap_m,
        omega_exc,
        &setup.settings.bands,
        &setup.settings.steps,
        &phases,
    )?;
    sim.reset_relative(u0_m, v0_m_s)
        .context("initial state (--u0-mm, --v0-mm-s)")?;
    let hammer = *sim.hammer();
    let h_sub = sim.step_s();
    let a0 = setup.params.amplitude_m;
    let mg = setup.params.weight_n();
    let (d0, _) = hammer.penetration(&sim.state());
    let mut tracker = ImpactTracker::new(T::from_f64(setup.settings.protocol.separation_m), d0);
    let mut summary = TsSummary::default();
    let (u, du) = sim.relative();
    // The written trajectory's states on the section (t = 0 and each period's end).
    let mut section = Vec::with_capacity(periods as usize + 1);
    section.push(sim.state());
    // The period (1-based) of the last arrival; 0 before any.
    let mut last_impact_period = 0u32;
    let mut rows = vec![TsRow {
        t_s: 0.0,
        u_mm: u.to_f64() * 1e3,
        du_mm_s: du.to_f64() * 1e3,
        x_mm: u.to_f64() * 1e3,
        impact_force_n: 0.0,
        impact_force_mg: 0.0,
        region: "free",
        poincare: true,
        lyapunov_per_period: None,
    }];
    for _ in 0..periods {
        sim.run_period(&mut |s: &StepSample<T>| {
            match tracker.update(s.delta, s.delta_min, s.force) {
                Some(ImpactEvent::Arrival) => {
                    summary.impacts += 1;
                    // The periods completed before this one, counted by their section points.
                    last_impact_period = section.len() as u32;
                }
                Some(ImpactEvent::End { peak_n }) => {
                    summary.max_force_mg = summary.max_force_mg.max(peak_n.to_f64() / mg);
                }
                None => {}
            }
            let (u, du) = hammer.relative(&s.x);
            let t = s.time_s(h_sub);
            let u = u.to_f64();
            let f = s.force.to_f64();
            rows.push(TsRow {
                t_s: t,
                u_mm: u * 1e3,
                du_mm_s: du.to_f64() * 1e3,
                x_mm: (u + a0 * (omega_exc * t).sin()) * 1e3,
                impact_force_n: f,
                impact_force_mg: f / mg,
                region: match s.region {
                    shared::model::Region::Free => "free",
                    shared::model::Region::Contact => "contact",
                    shared::model::Region::BandAlpha => "band-alpha",
                    shared::model::Region::BandBeta => "band-beta",
                },
                poincare: s.period_end,
                lyapunov_per_period: None,
            });
            if s.period_end {
                section.push(s.x);
            }
        });
    }
    if let Some(p) = tracker.current_peak() {
        summary.max_force_mg = summary.max_force_mg.max(p.to_f64() / mg);
    }
    // The exponent along the written trajectory: the tangent carried from each of its Poincaré
    // points by the map's `DP` there (the orbit tools' map, events located to round-off), its
    // running estimate at each Poincaré row.
    if periods >= 2 {
        let at = MapPoint {
            params: setup.params,
            settings: setup.settings,
            gap_m,
            omega_ratio: omega_exc / setup.params.omega_n(),
        };
        let mut running = Vec::with_capacity(periods as usize);
        let e = exponent_along_with(&at, &section, |_, estimate| {
            running.push(estimate);
        })?;
        for (k, r) in rows.iter_mut().skip(1).filter(|r| r.poincare).enumerate() {
            r.lyapunov_per_period = running.get(k).copied();
        }
        summary.lyapunov = Some((e.per_period, e.uncertainty()));
        let impact_free_periods = periods - last_impact_period;
        if summary.impacts > 0 && impact_free_periods >= IMPACT_FREE_TAIL {
            let tail = &section[last_impact_period as usize..];
            let e = exponent_along_with(&at, tail, |_, _| {})?;
            summary.impacts_stopped = Some(ImpactsStopped {
                last_impact_period,
                impact_free_periods,
                lyapunov: (e.per_period, e.uncertainty()),
            });
        }
    }
    Ok((rows, summary))
}

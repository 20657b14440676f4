//! `simulate`'s report is of the trajectory it writes: the exponent is carried along the written
//! Poincaré points, so that a chaotic transient which escapes to the non-impacting motion shows
//! in the running estimate, and the summary names the motion the run ends on.

use host_sim::config::Setup;
use host_sim::precision::Precision;
use host_sim::series::{IMPACT_FREE_TAIL, SeriesSpec, simulate};
use shared::model::RigId;

/// The wire rig at 2.4 mm, Ω/ω 1.7, in f64 over 50,000 periods, from rest: a chaotic transient
/// (exponent about +0.27 per period) that escapes, after some 9,000 periods, to the
/// non-impacting motion. The wire pendulum is undamped, so that motion conserves phase-space
/// area (the map's Jacobian has determinant 1: the exponents sum to 0) and, bounded, has both
/// exponents 0: the exponent over the impact-free periods must be 0 to within the run's
/// resolution, and the running estimate falls as the impact-free periods dilute the transient's.
#[test]
fn a_transient_that_escapes_to_the_non_impacting_motion_is_reported_as_it_ends() {
    let mut setup = Setup::preset(RigId::Wires).unwrap();
    setup.precision = Precision::F64;
    let periods = 50_000;
    let (rows, summary) = simulate(
        &setup,
        &SeriesSpec {
            gap_m: 2.4e-3,
            omega_exc: 1.7 * setup.params.omega_n(),
            periods,
            u0_m: 0.0,
            v0_m_s: 0.0,
        },
    )
    .unwrap();
    let stop = summary
        .impacts_stopped
        .expect("the impacts stop within 50,000 periods");
    println!("{summary:?}");
    let n = stop.last_impact_period;
    assert_eq!(stop.impact_free_periods, periods - n);
    assert!(stop.impact_free_periods >= IMPACT_FREE_TAIL);
    // The running estimate at each Poincaré row (row k: after k periods).
    let running: Vec<f64> = rows
        .iter()
        .filter(|r| r.poincare)
        .skip(1)
        .map(|r| r.lyapunov_per_period.unwrap())
        .collect();
    assert_eq!(running.len(), periods as usize);
    // Up to the last impact: chaotic, clearly positive.
    let chaotic = running[n as usize - 1];
    assert!(chaotic > 0.2, "{chaotic}");
    // After it: the conservative non-impacting motion's 0.
    let (tail, tail_u) = stop.lyapunov;
    assert!(tail.abs() < 1e-3 && tail_u < 1e-3, "{tail} ± {tail_u}");
    // The running estimate falls with the impact-free periods: at the end it is the transient's
    // sum diluted by the whole run (plus the tail's ~0), and the run's figure is that value.
    let last = *running.last().unwrap();
    let diluted = chaotic * f64::from(n) / f64::from(periods);
    assert!((last - diluted).abs() < 2e-3, "{last} vs {diluted}");
    let (whole, _) = summary.lyapunov.unwrap();
    assert_eq!(whole, last);
    // No impact after period n in the written rows: every contact after it is below the
    // impact tracker's threshold (a graze of less than 1 N).
    let period_s = 2.0 * std::f64::consts::PI / (1.7 * setup.params.omega_n());
    let after = f64::from(n) * period_s;
    let late_peak = rows
        .iter()
        .filter(|r| r.t_s > after)
        .map(|r| r.impact_force_n)
        .fold(0.0, f64::max);
    assert!(late_peak < 1.0, "{late_peak} N after period {n}");
}

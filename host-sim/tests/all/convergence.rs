//! Convergence of the production settings (f32, N = 256, K = 32, default bands) on the wire-rig
//! response at 0.0 mm gap, Ω/ω 0.5–5.0 step 0.05 (91 points):
//! - against f64 with 4× finer steps and sub-steps and 4× narrower bands: same regime and
//!   `F_i/mg` within 2 % at every point away from regime boundaries;
//! - halving both bands (f32) changes `F_i/mg` by < 1 % at those points.

use host_sim::config::Setup;
use host_sim::precision::Precision;
use host_sim::runner::{OperatingPoint, evaluate_all};
use shared::analysis::{SelectionSpec, SimSettings};
use shared::model::RigId;
use shared::observe::PointResult;

fn setup(precision: Precision, settings: SimSettings) -> Setup {
    Setup {
        rig: RigId::Wires,
        params: RigId::Wires.preset(),
        settings,
        selection: SelectionSpec::default(),
        precision,
        uncertainty: None,
        calibration: None,
    }
}

fn response(s: &Setup) -> Vec<PointResult> {
    let pts: Vec<OperatingPoint> = (0..91)
        .map(|i| OperatingPoint {
            gap_m: 0.0,
            omega_ratio: 0.5 + 0.05 * f64::from(i),
        })
        .collect();
    evaluate_all(s, &pts, "test").unwrap()
}

/// Indices whose regime equals both neighbours' in `reference` (away from regime boundaries).
fn interior(reference: &[PointResult]) -> Vec<usize> {
    (1..reference.len() - 1)
        .filter(|&i| {
            reference[i - 1].regime == reference[i].regime
                && reference[i + 1].regime == reference[i].regime
        })
        .collect()
}

#[test]
fn f32_production_agrees_with_f64_four_times_finer() {
    let base = SimSettings::default();
    let prod = response(&setup(Precision::F32, base));
    let fine = response(&setup(Precision::F64, base.refined(4)));
    let inner = interior(&fine);
    assert!(inner.len() > 60, "only {} interior points", inner.len());
    let mut worst: f64 = 0.0;
    for &i in &inner {
        let (a, b) = (&prod[i], &fine[i]);
        assert_eq!(a.regime, b.regime, "Ω/ω = {:.2}", 0.5 + 0.05 * i as f64);
        let rel = (a.impact_force_mg - b.impact_force_mg).abs() / b.impact_force_mg.max(1e-9);
        worst = worst.max(rel);
        assert!(
            rel < 0.02,
            "Ω/ω = {:.2}: F_i/mg {} vs {}",
            0.5 + 0.05 * i as f64,
            a.impact_force_mg,
            b.impact_force_mg
        );
    }
    eprintln!(
        "f32 vs f64×4: {} interior points, worst F_i/mg difference {:.3} %",
        inner.len(),
        worst * 100.0
    );
    // The 1/1 band of the thesis' Fig. 3.12 is there in both.
    assert!(
        inner
            .iter()
            .filter(|&&i| fine[i].regime == shared::observe::Regime::ONE_ONE)
            .count()
            > 20
    );
}

#[test]
fn halving_eta_changes_results_below_1pct() {
    let base = SimSettings::default();
    let mut half = base;
    half.bands = base.bands.scaled(0.5);
    let a = response(&setup(Precision::F32, base));
    let b = response(&setup(Precision::F32, half));
    let inner = interior(&a);
    let mut worst: f64 = 0.0;
    for &i in &inner {
        assert_eq!(
            a[i].regime,
            b[i].regime,
            "Ω/ω = {:.2}",
            0.5 + 0.05 * i as f64
        );
        let rel =
            (a[i].impact_force_mg - b[i].impact_force_mg).abs() / a[i].impact_force_mg.max(1e-9);
        worst = worst.max(rel);
        assert!(
            rel < 0.01,
            "Ω/ω = {:.2}: {} vs {}",
            0.5 + 0.05 * i as f64,
            a[i].impact_force_mg,
            b[i].impact_force_mg
        );
    }
    eprintln!("η vs η/2: worst F_i/mg difference {:.4} %", worst * 100.0);
}

//! Accuracy of the production settings on the thesis' Peterka grid (issue 3):
//! a reproducible random sample of the wire-rig grid (gap 0.00–3.42 mm × 1.00–7.11 Hz, steps
//! 0.01), each point run with the f32 production settings and with f64 and 4× finer steps,
//! sub-steps and bands; prints every disagreement and the summary.
//!
//! `cargo run --release -p host-sim --example grid_accuracy -- [SAMPLES=2000] [SEED=777] [MODE]`
//! with MODE `f32` (default: f32 production vs f64×4), `f64` (f64 at the production steps vs
//! f64×4: what f32 costs) or `ref` (f64×4 vs f64×8: the reference's own reproducibility).
//! In the `f32` and `f64` modes the points are also run with f64×8, and the agreement is
//! reported again over the points where the reference is converged (×4 and ×8 agree): the
//! others have no settled answer to agree with. A fourth argument `labels` compares the labels
//! that the largest Lyapunov exponent gives (as `response` and `bifurcation` print them:
//! `chaotic`, or the period an extended run finds) instead of the protocol's.

use rayon::prelude::*;
use shared::Real;
use shared::analysis::SimSettings;
use shared::model::{RigId, RigParams};
use shared::observe::{PointResult, Regime};
use shared::orbit::{LabelSettings, MapPoint, label, settle};

/// The protocol's result from rest at `(gap_m, Ω/ω)`, its regime replaced by the exponent's
/// label if `labelled`.
fn evaluate<T: Real>(
    params: &RigParams,
    gap_m: f64,
    omega_ratio: f64,
    settings: &SimSettings,
    labelled: bool,
) -> PointResult {
    let at = MapPoint {
        params: *params,
        settings: *settings,
        gap_m,
        omega_ratio,
    };
    let (mut r, x) = settle::<T>(&at, 0.0, 0.0).expect("valid point");
    if labelled {
        r.regime = label::<T>(&at, &r, x, &LabelSettings::default())
            .expect("valid point")
            .regime;
    }
    r
}

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(2000);
    let mut seed: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(777);
    let mode = args.next().unwrap_or_else(|| "f32".into());
    let labelled = args.next().as_deref() == Some("labels");
    let p = RigId::Wires.preset();
    let base = SimSettings::default();
    let (s, r) = match mode.as_str() {
        "f32" | "f64" => (base, base.refined(4)),
        "ref" => (base.refined(4), base.refined(8)),
        other => {
            eprintln!("MODE must be f32, f64 or ref, not {other}");
            std::process::exit(2);
        }
    };
    let fn_hz = p.natural_freq_hz();
    // Knuth's MMIX LCG: the sample depends only on the seed.
    let mut rnd = |m: u64| {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (seed >> 33) % m
    };
    let pts: Vec<(f64, f64)> = (0..n)
        .map(|_| (rnd(343) as f64 * 0.01, 1.0 + rnd(612) as f64 * 0.01))
        .collect();
    let res: Vec<_> = pts
        .par_iter()
        .map(|&(g, f)| {
            let a = if mode == "f32" {
                evaluate::<f32>(&p, g * 1e-3, f / fn_hz, &s, labelled)
            } else {
                evaluate::<f64>(&p, g * 1e-3, f / fn_hz, &s, labelled)
            };
            let b = evaluate::<f64>(&p, g * 1e-3, f / fn_hz, &r, labelled);
            // Whether the reference is converged (in `ref` mode `b` is already ×8).
            let converged = mode == "ref"
                || evaluate::<f64>(&p, g * 1e-3, f / fn_hz, &base.refined(8), labelled).regime
                    == b.regime;
            (g, f, a, b, converged)
        })
        .collect();
    let (mut same, mut both11, mut over2, mut worst) = (0, 0, 0, 0.0f64);
    let (mut sporadic, mut count, mut other) = (0, 0, 0);
    let (mut conv, mut conv_same) = (0, 0);
    for (g, f, a, b, converged) in &res {
        if *converged {
            conv += 1;
            conv_same += usize::from(a.regime == b.regime);
        }
        if a.regime == b.regime {
            same += 1;
        } else {
            let kind = match (a.regime, b.regime) {
                (Regime::NoImpact, _) | (_, Regime::NoImpact) => {
                    sporadic += 1;
                    "impacts in one, none in the other"
                }
                (Regime::Periodic { q: qa, .. }, Regime::Periodic { q: qb, .. }) if qa == qb => {
                    count += 1;
                    "same period, impact count differs"
                }
                _ => {
                    other += 1;
                    "period or irregular differs"
                }
            };
            println!(
                "gap {g:.2} mm, {f:.2} Hz (Ω/ω {:.3}): {mode} {} vs reference {}  (F_i/mg {:.3} / {:.3}, transient {} / {}) — {kind}{}",
                f / fn_hz,
                a.regime,
                b.regime,
                a.impact_force_mg,
                b.impact_force_mg,
                a.transient_periods,
                b.transient_periods,
                if *converged {
                    ""
                } else {
                    " (reference not converged)"
                }
            );
        }
        if a.regime == Regime::ONE_ONE && b.regime == Regime::ONE_ONE {
            both11 += 1;
            let e = (a.impact_force_mg / b.impact_force_mg - 1.0).abs();
            worst = worst.max(e);
            if e > 0.02 {
                over2 += 1;
            }
        }
    }
    println!(
        "same regime at {same}/{n} points ({:.2} %); disagreements: {sporadic} sporadic impact / no impact, \
         {count} impact count, {other} period or irregular; both 1/1 at {both11}: worst F_i/mg difference {:.3} %, {over2} above 2 %",
        100.0 * same as f64 / n as f64,
        100.0 * worst
    );
    if mode != "ref" {
        println!(
            "reference converged (f64×4 = f64×8) at {conv}/{n} points; there the regime agrees at \
             {conv_same}/{conv} ({:.2} %)",
            100.0 * conv_same as f64 / conv as f64
        );
    }
}

//! The long-run check of a response's labels (docs/accuracy.md, "The labels the Lyapunov
//! exponent gives"): every `chaotic` and `irregular` point of a `host-sim response --out` CSV is
//! run again from rest with the production stepper in f64 (the fixed-step switch model, not the
//! orbit tools' map the labels come from) for PERIODS periods, and a period `q ≤ 64` is sought
//! on its Poincaré points as the labels' runs seek it: the last `3 × 64` points repeating with
//! lag `q` to 1e-3 of the scales, impacts per period equal, checked every 16 periods (no impact
//! over them: the non-impacting motion). Prints each such point's outcome and the counts.
//!
//! ```sh
//! target/release/host-sim response --rig wires --gap-mm 1.0 --omega-ratio 0.5:5.0:0.01 --out fr.csv
//! cargo run --release -p host-sim --example long_run -- fr.csv wires 1.0 [PERIODS=4000]
//! ```
//!
//! The rig is a preset name (its own contact law, default settings), the gap in mm, as the
//! response was made. An unreadable file, a malformed row, a bad rig, gap or period count is an
//! error naming it.

use anyhow::{Context, Result, bail};
use rayon::prelude::*;
use shared::analysis::{SimSettings, simulator_at};
use shared::integrate::{PhaseTable, StepSample};
use shared::model::{RigId, RigParams};
use shared::observe::poincare::StroboPoint;
use shared::observe::regime::classify;
use shared::observe::{ImpactTracker, Regime};

/// Largest period sought.
const MAX_Q: usize = 64;
/// Points the period is sought over: three cycles of the largest.
const SPAN: usize = 3 * MAX_Q;

/// From rest at `(gap_m, omega_ratio)`, f64, up to `periods` periods: the first regime other
/// than `irregular` its last `SPAN` Poincaré points show (checked every 16 periods) and the
/// period it showed at, or `None`.
fn long_run(
    params: &RigParams,
    settings: &SimSettings,
    gap_m: f64,
    omega_ratio: f64,
    periods: u32,
) -> Result<Option<(Regime, u32)>> {
    let table = PhaseTable::<f64>::new(settings.steps.steps_per_period)?;
    let mut sim = simulator_at(params, gap_m, omega_ratio, settings, &table)?;
    let (d0, _) = sim.hammer().penetration(&sim.state());
    let mut tracker = ImpactTracker::new(settings.protocol.separation_m, d0);
    let a0 = params.amplitude_m;
    let (u_scale, v_scale) = (a0, a0 * omega_ratio * params.omega_n());
    let mut section: std::collections::VecDeque<StroboPoint<f64>> = Default::default();
    let mut impacts: std::collections::VecDeque<u16> = Default::default();
    for k in 1..=periods {
        let mut n = 0u16;
        sim.run_period(&mut |s: &StepSample<f64>| {
            if tracker.update(s.delta, s.delta_min, s.force).is_some() {
                n = n.saturating_add(1);
            }
        });
        if section.len() == SPAN {
            section.pop_front();
            impacts.pop_front();
        }
        let (u, du) = sim.relative();
        section.push_back(StroboPoint { u, du });
        impacts.push_back(n);
        if section.len() == SPAN && k % 16 == 0 {
            let (s, i) = (
                section.make_contiguous().to_vec(),
                impacts.make_contiguous(),
            );
            let r = classify(&s, i, MAX_Q, 1e-3, u_scale, v_scale);
            if r != Regime::Irregular {
                return Ok(Some((r, k)));
            }
        }
    }
    Ok(None)
}

fn run(path: &str, rig: &str, gap_mm: f64, periods: u32) -> Result<()> {
    let rig: RigId = rig
        .parse()
        .map_err(|e| anyhow::anyhow!("rig {rig:?}: {e}"))?;
    if !(0.0..=100.0).contains(&gap_mm) {
        bail!("gap {gap_mm} mm: must be in 0 ..= 100");
    }
    if !(SPAN as u32..=1_000_000).contains(&periods) {
        bail!("PERIODS {periods}: must be in {SPAN} ..= 1,000,000");
    }
    let params = rig.preset();
    let settings = SimSettings::default();
    let mut reader =
        csv::Reader::from_path(path).with_context(|| format!("{path}: cannot open"))?;
    let head = reader.headers()?.clone();
    let col = |name: &str| {
        head.iter()
            .position(|h| h == name)
            .with_context(|| format!("{path}: no column {name}"))
    };
    let (c_ratio, c_regime) = (col("omega_ratio")?, col("regime")?);
    let mut points = Vec::new();
    for (i, rec) in reader.records().enumerate() {
        let rec = rec.with_context(|| format!("{path}: line {}", i + 2))?;
        let ratio: f64 = rec[c_ratio]
            .parse()
            .with_context(|| format!("{path}: line {}: omega_ratio", i + 2))?;
        let label = rec[c_regime].to_string();
        if label == "chaotic" || label == "irregular" {
            points.push((ratio, label));
        }
    }
    let found: Vec<Result<Option<(Regime, u32)>>> = points
        .par_iter()
        .map(|(r, _)| long_run(&params, &settings, gap_mm * 1e-3, *r, periods))
        .collect();
    let mut counts = std::collections::BTreeMap::<(&str, bool), usize>::new();
    for ((ratio, label), f) in points.iter().zip(found) {
        let f = f.with_context(|| format!("Ω/ω {ratio}"))?;
        match f {
            Some((regime, k)) => println!("Ω/ω {ratio:.4} {label}: {regime} from period {k}"),
            None => println!("Ω/ω {ratio:.4} {label}: no period within {periods} periods"),
        }
        *counts.entry((label.as_str(), f.is_some())).or_default() += 1;
    }
    for label in ["chaotic", "irregular"] {
        let with = counts.get(&(label, true)).copied().unwrap_or(0);
        let without = counts.get(&(label, false)).copied().unwrap_or(0);
        println!(
            "{rig} {gap_mm} mm: {label} {}: a period within {periods} periods at {with}",
            with + without
        );
    }
    Ok(())
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if !(3..=4).contains(&args.len()) {
        bail!("usage: long_run RESPONSE.csv RIG GAP_MM [PERIODS=4000]");
    }
    let gap_mm: f64 = args[2]
        .parse()
        .with_context(|| format!("GAP_MM {:?}", args[2]))?;
    let periods: u32 = match args.get(3) {
        Some(p) => p.parse().with_context(|| format!("PERIODS {p:?}"))?,
        None => 4000,
    };
    run(&args[0], &args[1], gap_mm, periods)
}

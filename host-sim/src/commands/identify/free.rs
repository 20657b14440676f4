//! `identify free`: the suspension from a free decay, reported and written as a config.

use anyhow::{Context, Result};
use serde::Serialize;
use shared::error::check_range;
use shared::model::{RigId, Suspension};

use super::FreeArgs;
use crate::config::config_text;
use crate::identify::free::{FreeDecay, identify_free};
use crate::output::{Outputs, distinct_files};
use crate::trace::read_trace;

#[derive(Serialize)]
struct FreeReport {
    #[serde(flatten)]
    decay: FreeDecay,
    mass_kg: f64,
    stiffness_n_m: f64,
    damping_n_s_m: f64,
    pendulum_length_m: f64,
}

pub(super) fn run(a: &FreeArgs) -> Result<()> {
    if let Some(out) = &a.out {
        distinct_files(
            &[("--trace", a.trace.as_path())],
            &[("--out", out.as_path())],
        )?;
    }
    check_range("mass_kg", a.mass_kg, 1e-6, 1e3).context("--mass-kg")?;
    let trace = read_trace(
        &a.trace,
        &a.time.format(a.value_col.as_deref(), a.unit.to_si()),
        if a.unit.is_acceleration() {
            "acceleration"
        } else {
            "displacement"
        },
    )?;
    let decay =
        identify_free(&trace).with_context(|| format!("free decay {}", a.trace.display()))?;
    let mut params = a.rig.preset();
    params.mass_kg = a.mass_kg;
    params.suspension = decay.suspension(&params.suspension, params.gravity_m_s2);
    params.validate().with_context(|| {
        format!(
            "the identified suspension is out of range (natural frequency {:.4e} Hz, where the \
             {} preset has {:.3} Hz: is the time column's unit right? --time-unit, or \
             --sample-rate-hz)",
            decay.natural_freq_hz,
            a.rig,
            a.rig.preset().natural_freq_hz()
        )
    })?;
    let report = FreeReport {
        decay,
        mass_kg: a.mass_kg,
        stiffness_n_m: decay.stiffness_n_m(a.mass_kg),
        damping_n_s_m: decay.damping_n_s_m(a.mass_kg),
        pendulum_length_m: decay.pendulum_length_m(params.gravity_m_s2),
    };
    if let Some(note) = other_rig_note(a.rig, decay.natural_freq_hz) {
        eprintln!("! note: {note}");
    }
    let mut outputs = Outputs::new();
    if let Some(p) = &a.out {
        let tmp = outputs.reserve(p)?;
        let model = match params.suspension {
            Suspension::Wires { .. } => format!(
                "pendulum l = g/w^2 = {:.6e} m; zeta: the viscous term -2 zeta w dtheta/dt \
                 added to Eq. 3-26 (docs/model.md)",
                report.pendulum_length_m
            ),
            Suspension::Beam { .. } => format!(
                "k = m w^2 = {:.5e} N/m (Eq. 3-34), c = 2 zeta m w = {:.5e} N s/m",
                report.stiffness_n_m, report.damping_n_s_m
            ),
        };
        let comment = format!(
            "host-sim identify free: {} ({:.1} cycles): f_n = {:.5} Hz (95 %: {:.5} .. {:.5}), \
             zeta = {:.6} (95 %: {:.6} .. {:.6})\n{model}",
            a.trace.display(),
            decay.cycles,
            decay.natural_freq_hz,
            decay.natural_freq_ci95_hz[0],
            decay.natural_freq_ci95_hz[1],
            decay.damping_ratio,
            decay.damping_ratio_ci95[0],
            decay.damping_ratio_ci95[1],
        );
        std::fs::write(
            &tmp,
            config_text(
                &comment,
                &params,
                &a.rig.preset(),
                &["mass_kg", "suspension"],
            )?,
        )
        .with_context(|| format!("writing {}", p.display()))?;
    }
    outputs.commit()?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "Free decay {}: {} samples, {:.1} cycles, fit residual {:.2} % of the signal rms",
        a.trace.display(),
        trace.t_s.len(),
        decay.cycles,
        100.0 * decay.residual_rel
    );
    println!(
        "  natural frequency ω/2π = {:.5} Hz (95 %: {:.5} – {:.5}; damped {:.5} Hz)",
        decay.natural_freq_hz,
        decay.natural_freq_ci95_hz[0],
        decay.natural_freq_ci95_hz[1],
        decay.damped_freq_hz
    );
    println!(
        "  damping ratio ζ = {:.6} (95 %: {:.6} – {:.6}); correlation with ω {:+.3}",
        decay.damping_ratio,
        decay.damping_ratio_ci95[0],
        decay.damping_ratio_ci95[1],
        decay.correlation_fn_zeta
    );
    println!(
        "  m = {} kg: k = m ω² = {:.5e} N/m (Eq. 3-34), c = 2ζmω = {:.5e} N s/m; as a pendulum l = g/ω² = {:.2} mm",
        a.mass_kg,
        report.stiffness_n_m,
        report.damping_n_s_m,
        report.pendulum_length_m * 1e3
    );
    if let Some(p) = &a.out {
        println!(
            "  wrote {} (suspension of the {} rig; use it with --rig {} --config)",
            p.display(),
            a.rig,
            a.rig
        );
    }
    Ok(())
}

/// Beyond this relative difference from the `--rig` preset's natural frequency, the decay may
/// be another rig's: a real rig differs from the thesis' by a few per cent.
const OTHER_RIG_REL: f64 = 0.2;

/// A note where the identified natural frequency `freq_hz` lies more than [`OTHER_RIG_REL`]
/// from the `rig` preset's, with every preset's to choose from.
fn other_rig_note(rig: RigId, freq_hz: f64) -> Option<String> {
    let preset = rig.preset().natural_freq_hz();
    let rel = freq_hz / preset - 1.0;
    (rel.abs() > OTHER_RIG_REL).then(|| {
        let presets: Vec<String> = RigId::ALL
            .iter()
            .map(|r| format!("{r} {:.2}", r.preset().natural_freq_hz()))
            .collect();
        format!(
            "ω/2π = {freq_hz:.4} Hz lies {:.0} % {} the {rig} preset's {preset:.2} Hz: if the \
             decay is another rig's, give its --rig (the presets' ω/2π: {} Hz)",
            100.0 * rel.abs(),
            if rel < 0.0 { "below" } else { "above" },
            presets.join(", ")
        )
    })
}

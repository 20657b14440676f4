//! `host-sim drop`: a drop test of the plant simulation recorded like a force sensor (optional
//! noise and offset): the synthetic "measurement" for `identify contact`, or the prediction of a
//! drop test with identified parameters. With `--record displacement` the hammer's
//! displacement instead: with the surface out of reach, a free decay for `identify free`.

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use shared::analysis::drop::DropSpec;
use shared::error::{ParamError, check_range};

use crate::config::RigOpts;
use crate::config::Setup;
use crate::identify::cost::{PROFILE_MIN_SAMPLES, simulate_drop};
use crate::identify::synth::{
    Recorded, Sensor, TRUTH_STEPS, clean_record, record_displacement, synthetic_drop,
};
use crate::output::Outputs;
use crate::precision::Precision;

/// Arguments of `drop`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct DropArgs {
    /// Rig (suspension, mass) and contact law (--law, --config); --precision is ignored
    /// (always f64).
    #[command(flatten)]
    pub rig: RigOpts,
    /// Gap between the hammer's rest position and the surface, mm.
    #[arg(long, default_value_t = 0.0)]
    pub gap_mm: f64,
    /// Distance from the surface at which the hammer is released at rest, mm (> gap).
    #[arg(long, default_value_t = 3.0)]
    pub release_mm: f64,
    /// Recorded time from the release, s (0 < t ≤ 100).
    #[arg(long, default_value_t = 1.0)]
    pub duration_s: f64,
    /// Sample rate of the recording, Hz.
    #[arg(long, default_value_t = 50_000.0)]
    pub sample_rate_hz: f64,
    /// Gaussian sensor noise, standard deviation in % of the largest force (displacement: of
    /// the largest |u|).
    #[arg(long, default_value_t = 0.0)]
    pub noise_pct: f64,
    /// Sensor offset added to every sample, N (force only).
    #[arg(long, default_value_t = 0.0)]
    pub offset_n: f64,
    /// What the sensor records: the contact force (N), or the hammer's displacement from its
    /// rest position (mm; wires: l sin θ). With the surface out of reach (release < 2 × gap)
    /// the displacement is a free decay of the suspension, for `identify free`.
    #[arg(long, value_enum, default_value = "force")]
    pub record: Recorded,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// CSV output: `#` comment lines with the setup, then t_s, force_n.
    #[arg(value_parser = crate::output::out_target, long, value_name = "FILE.csv")]
    pub out: PathBuf,
}

/// `e` with the command-line flag of the field it names (`sample_rate_hz` → `--sample-rate-hz`),
/// where it names one.
fn named_flag(e: anyhow::Error) -> anyhow::Error {
    match e.downcast_ref::<ParamError>().map(ParamError::field) {
        Some(field) => {
            let flag = format!("--{}", field.replace('_', "-"));
            e.context(flag)
        }
        None => e,
    }
}

/// Runs `drop`.
///
/// # Errors
/// Bad input or I/O failure.
pub fn run(a: &DropArgs) -> Result<()> {
    a.rig.check_outputs(&[("--out", Some(&a.out))])?;
    let mut opts = a.rig.clone();
    opts.precision = Precision::F64;
    let setup = Setup::from_opts(&opts)?;
    let gap_m = setup.gap_m("--gap-mm", a.gap_mm)?;
    check_range("duration_s", a.duration_s, 1e-3, 100.0).context("--duration-s")?;
    check_range("release_mm", a.release_mm, a.gap_mm + 1e-3, 100.0).context("--release-mm")?;
    let spec = DropSpec {
        gap_m,
        release_m: a.release_mm * 1e-3,
        duration_s: a.duration_s,
        max_impacts: 0,
    };
    let sensor = Sensor {
        sample_rate_hz: a.sample_rate_hz,
        noise_pct: a.noise_pct,
        offset_n: a.offset_n,
        seed: a.seed,
    };
    let trace = match a.record {
        Recorded::Force => {
            synthetic_drop(&setup.params, &spec, &TRUTH_STEPS, &sensor).map_err(named_flag)?
        }
        Recorded::Displacement => {
            anyhow::ensure!(
                a.offset_n == 0.0,
                "--offset-n is a force offset: not with --record displacement"
            );
            let clean = clean_record(
                &setup.params,
                &spec,
                &TRUTH_STEPS,
                a.sample_rate_hz,
                Recorded::Displacement,
            )
            .map_err(named_flag)?;
            let mut t =
                record_displacement(&clean, a.noise_pct, 0.0, a.seed).map_err(named_flag)?;
            for u in &mut t.value {
                *u *= 1e3;
            }
            t
        }
    };
    let (column, unit) = match a.record {
        Recorded::Force => ("force_n", "N"),
        Recorded::Displacement => ("u_mm", "mm"),
    };
    let mut outputs = Outputs::new();
    let tmp = outputs.reserve(&a.out)?;
    {
        let file =
            std::fs::File::create(&tmp).with_context(|| format!("writing {}", a.out.display()))?;
        let mut w = std::io::BufWriter::new(file);
        writeln!(
            w,
            "# host-sim drop: {} rig, m = {} kg, suspension {}, contact {}",
            setup.rig,
            setup.params.mass_kg,
            serde_json::to_string(&setup.params.suspension)?,
            serde_json::to_string(&setup.params.contact)?
        )?;
        writeln!(
            w,
            "# released at rest {} mm from the surface, gap {} mm; noise {} % of peak (seed {}), offset {} N",
            a.release_mm, a.gap_mm, a.noise_pct, a.seed, a.offset_n
        )?;
        writeln!(w, "# sample_rate_hz = {}", a.sample_rate_hz)?;
        writeln!(w, "t_s,{column}")?;
        for (t, f) in trace.t_s.iter().zip(&trace.value) {
            match a.record {
                Recorded::Force => writeln!(w, "{t:.7},{f:.6}")?,
                Recorded::Displacement => writeln!(w, "{t:.7},{f:.7e}")?,
            }
        }
        w.flush()?;
    }
    outputs.commit()?;
    let peak = trace
        .value
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    println!(
        "wrote {}: {} samples over {} s, largest sample {:.3} {unit}",
        a.out.display(),
        trace.t_s.len(),
        a.duration_s,
        peak
    );
    if a.record == Recorded::Force {
        // How finely the record resolves a contact: what `identify contact` can do with it.
        let sim = simulate_drop(&setup.params, &spec, &TRUTH_STEPS, false)?;
        if let Some(first) = sim.impacts.first() {
            let (lasts, at_half) = (first.duration_s(), first.fwhm_s());
            let (n_lasts, n_half) = (lasts * a.sample_rate_hz, at_half * a.sample_rate_hz);
            println!(
                "  the first contact lasts {:.3} ms ({:.3} ms at half maximum): {n_lasts:.1} \
                 samples at {} Hz ({n_half:.1} at half maximum); {}",
                1e3 * lasts,
                1e3 * at_half,
                a.sample_rate_hz,
                if n_lasts < 3.0 {
                    "fewer than the 3 that time an impact: `identify contact` cannot use this \
                     record, record faster"
                        .to_string()
                } else if n_half < PROFILE_MIN_SAMPLES {
                    format!(
                        "enough to time the impacts; the profile error wants \
                         {PROFILE_MIN_SAMPLES:.0} or more at half maximum"
                    )
                } else {
                    "enough for the profile error".to_string()
                }
            );
        }
    }
    Ok(())
}

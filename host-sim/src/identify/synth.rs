//! Synthetic drop tests: the plant simulation ([`shared::analysis::drop`]) sampled like a
//! force sensor, with Gaussian noise and a constant offset; or its displacement `u(t)` sampled
//! like a displacement sensor (with the surface out of reach: a free decay of the suspension,
//! for `identify free`). Used by the recovery tests and the worked examples
//! (`docs/identification.md`).

use anyhow::{Result, ensure};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use shared::analysis::drop::{DropRecord, DropSpec, run_drop};
use shared::error::check_range;
use shared::integrate::StepSettings;
use shared::model::{ContactLaw, RigId, RigParams, SwitchBands};

use super::cost::{DropSetup, DropTest, FIT_STEPS, resample, simulate_drop};
use super::data::analyse_drop;
use crate::trace::Trace;

/// Integrator settings of the synthetic "measurements": finer than the fit's
/// ([`super::cost::FIT_STEPS`]), so that a recovery test does not fit the integrator's own
/// discretisation (512 steps per natural period, 256 sub-steps per contact half-period).
pub const TRUTH_STEPS: StepSettings = StepSettings {
    steps_per_period: 512,
    substeps_per_contact: 256,
};

/// How the synthetic sensor records.
#[derive(Debug, Clone, Copy)]
pub struct Sensor {
    /// Sample rate, Hz (1 ..= 1e7).
    pub sample_rate_hz: f64,
    /// Noise standard deviation as a percentage of the largest force (0 ..= 100).
    pub noise_pct: f64,
    /// Constant offset added to every sample, N.
    pub offset_n: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl Sensor {
    /// The sensor of the recovery tests and the worked example: 50 kHz, 1 % noise, 0.5 N
    /// offset, noise seed `seed`.
    #[must_use]
    pub fn lab(seed: u64) -> Self {
        Self {
            sample_rate_hz: 50e3,
            noise_pct: 1.0,
            offset_n: 0.5,
            seed,
        }
    }
}

/// The drop test of the recovery tests and the worked example: the wire rig with contact law
/// `law`, released at rest `release_mm` above the surface at 0.0 mm gap, 1.2 s recorded.
#[derive(Debug, Clone, Copy)]
pub struct LabDrop {
    /// The true contact law.
    pub law: ContactLaw,
    /// Release distance from the surface, mm.
    pub release_mm: f64,
}

impl LabDrop {
    /// The wire rig's parameters with the true law.
    #[must_use]
    pub fn params(&self) -> RigParams {
        let mut p = RigId::Wires.preset();
        p.contact = self.law;
        p
    }

    /// The drop: 0.0 mm gap, released `release_mm`, 1.2 s, every impact.
    #[must_use]
    pub fn spec(&self) -> DropSpec {
        DropSpec {
            gap_m: 0.0,
            release_m: self.release_mm * 1e-3,
            duration_s: 1.2,
            max_impacts: 0,
        }
    }

    /// The noise-free trace at [`Sensor::lab`]'s 50 kHz, simulated at [`TRUTH_STEPS`].
    ///
    /// # Errors
    /// Invalid law or release distance (named).
    pub fn clean(&self) -> Result<Trace> {
        clean_record(
            &self.params(),
            &self.spec(),
            &TRUTH_STEPS,
            50e3,
            Recorded::Force,
        )
    }

    /// `clean` as [`Sensor::lab`] with noise seed `seed` records it, preprocessed (offset,
    /// the first 6 impacts), with the fit's setup ([`FIT_STEPS`]).
    ///
    /// # Errors
    /// No impact found in the trace.
    pub fn measured(&self, clean: &Trace, seed: u64) -> Result<DropTest> {
        let trace = record(clean, &Sensor::lab(seed))?;
        Ok(DropTest {
            setup: DropSetup {
                params: self.params(),
                gap_m: 0.0,
                release_m: self.release_mm * 1e-3,
                steps: FIT_STEPS,
            },
            data: analyse_drop(&trace, 6)?,
        })
    }
}

/// The drop test `spec` of `params` recorded by `sensor`: the simulated force (linear
/// interpolation between the integrator's samples) at `t = i / rate`, `0 ≤ t ≤ duration`,
/// plus offset and noise.
///
/// # Errors
/// Invalid parameters, spec or sensor settings (named).
pub fn synthetic_drop(
    params: &RigParams,
    spec: &DropSpec,
    steps: &StepSettings,
    sensor: &Sensor,
) -> Result<Trace> {
    let clean = clean_record(params, spec, steps, sensor.sample_rate_hz, Recorded::Force)?;
    record(&clean, sensor)
}

/// Samples of a record of `spec` at `sample_rate_hz` (both ends included).
///
/// # Errors
/// A rate outside `1 ..= 1e7` Hz, or more than 5·10⁷ samples.
fn sample_count(spec: &DropSpec, sample_rate_hz: f64) -> Result<usize> {
    check_range("sample_rate_hz", sample_rate_hz, 1.0, 1e7)?;
    let samples_n = (spec.duration_s * sample_rate_hz).floor() as usize + 1;
    ensure!(
        samples_n <= 50_000_000,
        "{samples_n} samples: lower the rate or the duration"
    );
    Ok(samples_n)
}

/// What a drop record measures (`host-sim drop --record`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Recorded {
    /// The contact force `F_i`, N (column `force_n`).
    Force,
    /// The hammer's displacement `u`, mm (column `u_mm`).
    Displacement,
}

/// The drop test `spec` of `params` sampled at `t = i / sample_rate_hz`, `0 ≤ t ≤ duration`,
/// without noise or offset, by the plant model's switch-model integrator at `steps` (f64):
/// - [`Recorded::Force`]: the contact force `F_i` (N), linearly interpolated between the
///   integrator's samples;
/// - [`Recorded::Displacement`]: the hammer's displacement `u(t)` (m; the cart stands still,
///   `u = x`; wires: `l sin θ`), each sample the cubic Hermite interpolant of the integrator's
///   `(u, u̇)` either side (error O(h⁴)). With the surface out of reach (`spec.release_m < 2
///   gap_m`: the hammer, released `release − gap` from its rest position, swings at most as far
///   the other way) it is a free decay of the suspension: the record of `identify free` (the
///   wire pendulum with its viscous term, the beams with theirs).
///
/// # Errors
/// Invalid parameters or spec, a rate outside `1 ..= 1e7` Hz, or more than 5·10⁷ samples.
pub fn clean_record(
    params: &RigParams,
    spec: &DropSpec,
    steps: &StepSettings,
    sample_rate_hz: f64,
    what: Recorded,
) -> Result<Trace> {
    let samples_n = sample_count(spec, sample_rate_hz)?;
    let t_s: Vec<f64> = (0..samples_n).map(|i| i as f64 / sample_rate_hz).collect();
    let value = match what {
        Recorded::Force => {
            let sim = simulate_drop(params, spec, steps, true)?;
            resample(&sim.samples, t_s.iter().copied())
        }
        Recorded::Displacement => displacement_at(params, spec, steps, &t_s)?,
    };
    Ok(Trace { t_s, value })
}

/// A clean force trace ([`clean_record`], at `sensor`'s rate) as `sensor` records it: plus its
/// offset and Gaussian noise of `noise_pct` % of the largest force (ChaCha8 seeded with `seed`:
/// the same samples on every machine).
///
/// # Errors
/// Sensor settings out of range (named).
pub fn record(clean: &Trace, sensor: &Sensor) -> Result<Trace> {
    check_range("noise_pct", sensor.noise_pct, 0.0, 100.0)?;
    check_range("offset_n", sensor.offset_n, -1e6, 1e6)?;
    let fmax = clean.value.iter().copied().fold(0.0, f64::max);
    with_noise(
        clean,
        sensor.noise_pct / 100.0 * fmax,
        sensor.offset_n,
        sensor.seed,
    )
}

/// `clean` plus `offset` and Gaussian noise of standard deviation `sd` (ChaCha8 seeded with
/// `seed`).
fn with_noise(clean: &Trace, sd: f64, offset: f64, seed: u64) -> Result<Trace> {
    let normal = Normal::new(0.0, sd)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let value = clean
        .value
        .iter()
        .map(|f| f + offset + normal.sample(&mut rng))
        .collect();
    Ok(Trace {
        t_s: clean.t_s.clone(),
        value,
    })
}

/// The hammer's displacement (m) at the times `t_s` of [`clean_record`]'s displacement record.
fn displacement_at(
    params: &RigParams,
    spec: &DropSpec,
    steps: &StepSettings,
    t_s: &[f64],
) -> Result<Vec<f64>> {
    let mut sim: Vec<(f64, f64, f64)> = Vec::new();
    run_drop::<f64, _>(params, spec, &SwitchBands::default(), steps, |r| {
        if let DropRecord::Sample(s) = r
            && sim.last().is_none_or(|&(t, _, _)| s.t_s > t)
        {
            sim.push((s.t_s, s.u_m, s.du_m_s));
        }
    })?;
    let mut j = 0;
    let value = t_s
        .iter()
        .map(|&t| {
            while j + 2 < sim.len() && sim[j + 1].0 < t {
                j += 1;
            }
            match (sim.get(j), sim.get(j + 1)) {
                (Some(&(t0, u0, v0)), Some(&(t1, u1, v1))) => {
                    let h = t1 - t0;
                    let s = ((t - t0) / h).clamp(0.0, 1.0);
                    let (s2, s3) = (s * s, s * s * s);
                    (2.0 * s3 - 3.0 * s2 + 1.0) * u0
                        + (s3 - 2.0 * s2 + s) * h * v0
                        + (-2.0 * s3 + 3.0 * s2) * u1
                        + (s3 - s2) * h * v1
                }
                (Some(&(_, u0, _)), None) => u0,
                _ => 0.0,
            }
        })
        .collect();
    Ok(value)
}

/// A clean displacement ([`clean_record`]) as a displacement sensor records it: plus
/// `offset_m` and Gaussian noise of `noise_pct` % of the largest `|u|` (ChaCha8 seeded with
/// `seed`).
///
/// # Errors
/// `noise_pct` outside `0 ..= 100` or `offset_m` outside `±1` m (named).
pub fn record_displacement(
    clean: &Trace,
    noise_pct: f64,
    offset_m: f64,
    seed: u64,
) -> Result<Trace> {
    check_range("noise_pct", noise_pct, 0.0, 100.0)?;
    check_range("offset_m", offset_m, -1.0, 1.0)?;
    let umax = clean.value.iter().map(|u| u.abs()).fold(0.0, f64::max);
    with_noise(clean, noise_pct / 100.0 * umax, offset_m, seed)
}

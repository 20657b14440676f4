//! Synthetic drop tests: the plant simulation ([`shared::analysis::drop`]) sampled like a
//! force sensor, with Gaussian noise and a constant offset. Used by the recovery tests and the
//! worked example (`docs/identification.md`).

use anyhow::{Result, ensure};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};
use shared::analysis::drop::DropSpec;
use shared::error::check_range;
use shared::integrate::StepSettings;
use shared::model::RigParams;

use super::contact::simulate_drop;
use crate::trace::Trace;

/// Integrator settings of the synthetic "measurements": finer than the fit's
/// ([`super::contact::FIT_STEPS`]), so that a recovery test does not fit the integrator's own
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
    check_range("sample_rate_hz", sensor.sample_rate_hz, 1.0, 1e7)?;
    check_range("noise_pct", sensor.noise_pct, 0.0, 100.0)?;
    check_range("offset_n", sensor.offset_n, -1e6, 1e6)?;
    let samples_n = (spec.duration_s * sensor.sample_rate_hz).floor() as usize + 1;
    ensure!(
        samples_n <= 50_000_000,
        "{samples_n} samples: lower the rate or the duration"
    );
    let sim = simulate_drop(params, spec, steps, true)?;
    let s = &sim.samples;
    let fmax = s.iter().map(|p| p.1).fold(0.0, f64::max);
    let normal = Normal::new(0.0, sensor.noise_pct / 100.0 * fmax)?;
    let mut rng = StdRng::seed_from_u64(sensor.seed);
    let mut t_s = Vec::with_capacity(samples_n);
    let mut value = Vec::with_capacity(samples_n);
    let mut j = 0;
    for i in 0..samples_n {
        let t = i as f64 / sensor.sample_rate_hz;
        while j + 1 < s.len() && s[j + 1].0 < t {
            j += 1;
        }
        let f = if j + 1 < s.len() {
            let (t0, f0) = s[j];
            let (t1, f1) = s[j + 1];
            if t1 > t0 {
                f0 + (f1 - f0) * ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
            } else {
                f1
            }
        } else {
            s.last().map_or(0.0, |p| p.1)
        };
        t_s.push(t);
        value.push(f + sensor.offset_n + normal.sample(&mut rng));
    }
    Ok(Trace { t_s, value })
}

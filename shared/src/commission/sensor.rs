//! The sensor check (step 1): the force at rest against the calibration.

use crate::control::config::CODE_FULL_SCALE;
use crate::control::{FaultSettings, RestStats, SAMPLE_RATE_HZ, SensorChain, SensorMonitor};

/// Largest mean force at rest, N: a larger one is an offset the calibration does not know
/// (`calib offset_v`), or a hammer leaning on the surface.
pub const MAX_OFFSET_N: f32 = 1.0;
/// Largest standard deviation of the force at rest, N (the drop identification needs impacts
/// of ten times the noise; the default chain has 0.2 N).
pub const MAX_NOISE_N: f32 = 1.0;
/// Largest deviation of the measured sample rate from the controller's, %.
pub const MAX_RATE_DEVIATION_PCT: f32 = 1.0;

/// Why the sensor check failed (the first of these that holds).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SensorFailure {
    /// The ADC lost samples (overruns).
    Lost,
    /// A sample sat on an ADC rail: the amplifier saturated, the sensor is open or stuck.
    Rail,
    /// The mean force is beyond [`MAX_OFFSET_N`].
    Offset,
    /// The force's spread is beyond [`MAX_NOISE_N`].
    Noise,
    /// The samples came at a rate off [`SAMPLE_RATE_HZ`] by more than
    /// [`MAX_RATE_DEVIATION_PCT`].
    Rate,
}

/// The force at rest, in N through the active calibration, and the verdict.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorCheck {
    /// Mean force, N (0 for a calibration that knows the amplifier's offset).
    pub offset_n: f32,
    /// Standard deviation, N.
    pub noise_n: f32,
    /// Smallest force, N.
    pub min_n: f32,
    /// Largest force, N.
    pub max_n: f32,
    /// Measured sample rate, Hz.
    pub rate_hz: f32,
    /// Samples the ADC lost.
    pub lost: u32,
    /// Why it failed; `None`: passed.
    pub failure: Option<SensorFailure>,
}

impl SensorCheck {
    /// The verdict on `stats` through `sensor`, the rails as the fault checks set them.
    pub fn of(stats: &RestStats, sensor: &SensorChain, faults: &FaultSettings) -> SensorCheck {
        // Volts per code over volts per newton: the chain's own formula, on the fractional
        // mean (the difference of two forces near −20 N would lose the last digits).
        let volts_per_code = sensor.adc_full_scale_v / CODE_FULL_SCALE;
        let offset_n = (stats.mean_code() * volts_per_code - sensor.offset_v) / sensor.volts_per_n;
        let noise_n = stats.sd_code() * volts_per_code / sensor.volts_per_n;
        let rate_hz = stats.rate_hz();
        let rails = SensorMonitor::new(faults);
        let nominal = SAMPLE_RATE_HZ as f32;
        let failure = if stats.lost > 0 || stats.samples == 0 {
            Some(SensorFailure::Lost)
        } else if rails.at_rail(stats.min) || rails.at_rail(stats.max) {
            Some(SensorFailure::Rail)
        } else if offset_n.abs().partial_cmp(&MAX_OFFSET_N) != Some(core::cmp::Ordering::Less) {
            Some(SensorFailure::Offset)
        } else if noise_n.partial_cmp(&MAX_NOISE_N) != Some(core::cmp::Ordering::Less) {
            Some(SensorFailure::Noise)
        } else if ((rate_hz / nominal - 1.0).abs() * 100.0).partial_cmp(&MAX_RATE_DEVIATION_PCT)
            != Some(core::cmp::Ordering::Less)
        {
            Some(SensorFailure::Rate)
        } else {
            None
        };
        SensorCheck {
            offset_n,
            noise_n,
            min_n: sensor.force_n(stats.min),
            max_n: sensor.force_n(stats.max),
            rate_hz,
            lost: stats.lost,
            failure,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::RestProbe;

    fn check(codes: impl Fn(u64) -> Option<u16>, period_us: u64) -> SensorCheck {
        let mut p = RestProbe::new(2000);
        for k in 0..2000 {
            p.push(codes(k), k * period_us);
        }
        SensorCheck::of(
            &p.done().unwrap(),
            &SensorChain::default(),
            &FaultSettings::default(),
        )
    }

    #[test]
    fn a_quiet_sensor_at_its_offset_passes_and_each_defect_names_itself() {
        let sensor = SensorChain::default();
        // The amplifier's offset: 0.2 V → 248.24 codes; ±1 code around 248.
        let rest = |k: u64| Some(247 + (k % 3) as u16);
        let c = check(rest, 100);
        assert_eq!(c.failure, None, "{c:?}");
        // Mean 248 codes, through the chain (an independent route: force_n of the mean).
        assert!((c.offset_n - sensor.force_n(248)).abs() < 1e-4, "{c:?}");
        // Codes 247, 248, 249 equally: sd = sqrt(2/3) codes.
        let sd = (2.0f32 / 3.0).sqrt() * sensor.code_step_n();
        assert!((c.noise_n - sd).abs() < 1e-4, "{} vs {sd}", c.noise_n);
        assert!((c.rate_hz - 10_000.0).abs() < 0.01);
        // An offset of 2 N (25 codes) the calibration does not know.
        let c = check(|k| Some(272 + (k % 3) as u16), 100);
        assert_eq!(c.failure, Some(SensorFailure::Offset), "{c:?}");
        // Noise of ±30 codes (2.4 N).
        let c = check(|k| Some(218 + 30 * (k % 3) as u16), 100);
        assert_eq!(c.failure, Some(SensorFailure::Noise), "{c:?}");
        // An open sensor: the amplifier at its upper rail.
        assert_eq!(
            check(|_| Some(4095), 100).failure,
            Some(SensorFailure::Rail)
        );
        // Samples 2 % slow.
        assert_eq!(check(rest, 102).failure, Some(SensorFailure::Rate));
        // An overrun.
        assert_eq!(
            check(|k| (k != 7).then_some(248), 100).failure,
            Some(SensorFailure::Lost)
        );
    }
}

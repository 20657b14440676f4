//! The controller's configuration: sampling rate, the drive and sensing chains (codes ↔ physical
//! units), the safe operating window, and the detector, tracking and fault settings.
//!
//! Defaults describe the rig as wired in docs/operator.md (wiring table): 12-bit DAC and ADC at
//! 3.3 V full scale, a power amplifier + shaker giving 1 mm of cart amplitude per volt of DAC
//! sine amplitude, and a charge amplifier of 10 mV/N with a 0.2 V offset (−20 N … 310 N on the
//! ADC's range).

use serde::{Deserialize, Serialize};

use crate::error::{ParamError, check_range};

/// Largest gap the controller takes, mm.
pub const MAX_GAP_MM: f32 = 10.0;
/// Longest link timeout, s.
pub const MAX_LINK_TIMEOUT_S: f32 = 3600.0;
/// Shortest link timeout other than 0 (off), s: ten milliseconds, so that a positive request
/// is never rounded to no samples (which would mean off).
pub const MIN_LINK_TIMEOUT_S: f32 = 0.01;

/// Force sampling rate, Hz: the ADC is triggered from a hardware timer at this rate and the
/// sampling task runs once per sample.
pub const SAMPLE_RATE_HZ: u32 = 10_000;
/// Sampling period, µs (`1e6 / SAMPLE_RATE_HZ`).
pub const SAMPLE_PERIOD_US: u32 = 1_000_000 / SAMPLE_RATE_HZ;
/// Full scale of the 12-bit converters, codes.
pub const CODE_FULL_SCALE: f32 = 4096.0;
/// DAC mid-scale: zero drive.
pub const DAC_MID: u16 = 2048;

/// DAC code → volts → power amplifier → cart displacement.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DriveChain {
    /// DAC full-scale voltage, V (3.3).
    pub dac_full_scale_v: f32,
    /// Cart displacement amplitude per volt of DAC sine amplitude (amplifier + shaker), mm/V (1.0).
    pub cart_mm_per_v: f32,
}

impl Default for DriveChain {
    fn default() -> Self {
        DriveChain {
            dac_full_scale_v: 3.3,
            cart_mm_per_v: 1.0,
        }
    }
}

impl DriveChain {
    /// DAC codes of sine amplitude per mm of cart amplitude.
    pub fn codes_per_mm(&self) -> f32 {
        CODE_FULL_SCALE / self.dac_full_scale_v / self.cart_mm_per_v
    }

    /// Largest cart amplitude the DAC can produce around mid-scale, mm.
    pub fn max_amplitude_mm(&self) -> f32 {
        (f32::from(DAC_MID) - 1.0) / self.codes_per_mm()
    }
}

/// Force → charge amplifier → ADC code.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorChain {
    /// Charge amplifier gain, V/N (0.01).
    pub volts_per_n: f32,
    /// Charge amplifier output at zero force, V (0.2).
    pub offset_v: f32,
    /// ADC full-scale voltage, V (3.3).
    pub adc_full_scale_v: f32,
}

impl Default for SensorChain {
    fn default() -> Self {
        SensorChain {
            volts_per_n: 0.01,
            offset_v: 0.2,
            adc_full_scale_v: 3.3,
        }
    }
}

impl SensorChain {
    /// Force (N) of an ADC code.
    pub fn force_n(&self, code: u16) -> f32 {
        (f32::from(code) * (self.adc_full_scale_v / CODE_FULL_SCALE) - self.offset_v)
            / self.volts_per_n
    }

    /// ADC code (unclamped, fractional) of a force (N): the inverse of [`SensorChain::force_n`].
    pub fn code_of(&self, force_n: f32) -> f32 {
        (force_n * self.volts_per_n + self.offset_v) * (CODE_FULL_SCALE / self.adc_full_scale_v)
    }

    /// Checks the calibration.
    ///
    /// # Errors
    /// [`ParamError`] naming the field and its allowed range.
    pub fn validate(&self) -> Result<(), ParamError> {
        let f = |name, v: f32, lo, hi| check_range(name, f64::from(v), lo, hi).map(|_| ());
        f("volts_per_n", self.volts_per_n, 1e-5, 1.0)?;
        f("offset_v", self.offset_v, 0.0, 1.65)?;
        f("adc_full_scale_v", self.adc_full_scale_v, 0.5, 10.0)
    }

    /// The force of one ADC code, N (the quantisation step).
    pub fn code_step_n(&self) -> f32 {
        self.force_n(1) - self.force_n(0)
    }

    /// Largest force before the ADC's upper rail, N.
    pub fn max_force_n(&self) -> f32 {
        self.force_n(crate::hal::ADC_MAX)
    }
}

/// The safe operating window: the drive never leaves it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Limits {
    /// Lowest drive frequency, Hz (1.0).
    pub freq_min_hz: f32,
    /// Highest drive frequency, Hz (30.0).
    pub freq_max_hz: f32,
    /// Largest cart amplitude, mm (1.5).
    pub amplitude_max_mm: f32,
    /// Frequency slew limit, Hz/s (0.5).
    pub freq_slew_hz_per_s: f32,
    /// Amplitude ramp for soft start and soft stop, mm/s (0.5).
    pub amp_ramp_mm_per_s: f32,
    /// Amplitude ramp of an abort (fault), mm/s (4.0).
    pub abort_ramp_mm_per_s: f32,
    /// Impact force that trips the over-force abort, N (280; the beam-170 rig's predicted
    /// operating force is ≈ 235 N).
    pub force_limit_n: f32,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            freq_min_hz: 1.0,
            freq_max_hz: 30.0,
            amplitude_max_mm: 1.5,
            freq_slew_hz_per_s: 0.5,
            amp_ramp_mm_per_s: 0.5,
            abort_ramp_mm_per_s: 4.0,
            force_limit_n: 280.0,
        }
    }
}

/// Impact detector settings ([`crate::control::ImpactDetector`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DetectorSettings {
    /// An impact starts when the force rises above this, N (3.0 ≈ 1 mg of the hammer).
    pub threshold_n: f32,
    /// It ends when the force falls below `threshold_n − hysteresis_n`, N (1.5).
    pub hysteresis_n: f32,
    /// Re-contacts within this time after the end belong to the same impact (chattering), s
    /// (0.005).
    pub refractory_s: f32,
}

impl Default for DetectorSettings {
    fn default() -> Self {
        DetectorSettings {
            threshold_n: 3.0,
            hysteresis_n: 1.5,
            refractory_s: 0.005,
        }
    }
}

/// Tracking (hill climbing) settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackSettings {
    /// First and largest move of the tracker's centre, Hz (0.04); its probes sit half of it
    /// either side of the centre.
    pub step_hz: f32,
    /// Smallest move, Hz (0.01): a move halves at each reversal down to this.
    pub min_step_hz: f32,
    /// Cycles ignored after a frequency change before measuring (6).
    pub settle_cycles: u16,
    /// Cycles measured per evaluation (8).
    pub measure_cycles: u16,
    /// Relative difference of the mean peak force between the tracker's two sides treated as
    /// real, not noise (0.002).
    pub improve_rel: f32,
}

impl Default for TrackSettings {
    fn default() -> Self {
        TrackSettings {
            step_hz: 0.04,
            min_step_hz: 0.01,
            settle_cycles: 6,
            measure_cycles: 8,
            improve_rel: 0.002,
        }
    }
}

/// Sensor fault settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FaultSettings {
    /// While driving at full amplitude after impacts were seen, no impact for this long (or
    /// 1.5 periods of the last measured regime, whichever is longer) means the sensor is open, s
    /// (0.4).
    pub no_signal_s: f32,
    /// Codes this close to 0 or 4095 count as pinned at a rail (8).
    pub rail_margin_codes: u16,
    /// Pinned at a rail for this long while the drive is on is a stuck sensor, s (0.02; impact
    /// pulses last ~1 ms).
    pub rail_s: f32,
    /// A sample later than this after the previous one is a missed deadline, µs (250).
    pub deadline_us: u32,
}

impl Default for FaultSettings {
    fn default() -> Self {
        FaultSettings {
            no_signal_s: 0.4,
            rail_margin_codes: 8,
            rail_s: 0.02,
            deadline_us: 250,
        }
    }
}

/// Everything the controller needs besides the rig and gap (which come from the console).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerConfig {
    /// Drive chain.
    pub drive: DriveChain,
    /// Sensing chain.
    pub sensor: SensorChain,
    /// Safe window.
    pub limits: Limits,
    /// Impact detector.
    pub detector: DetectorSettings,
    /// Tracking.
    pub track: TrackSettings,
    /// Sensor faults.
    pub faults: FaultSettings,
}

impl ControllerConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`ParamError`] naming the field and its allowed range.
    pub fn validate(&self) -> Result<(), ParamError> {
        let f = |name, v: f32, lo, hi| check_range(name, f64::from(v), lo, hi).map(|_| ());
        f("dac_full_scale_v", self.drive.dac_full_scale_v, 0.5, 10.0)?;
        f("cart_mm_per_v", self.drive.cart_mm_per_v, 0.01, 100.0)?;
        self.sensor.validate()?;
        let l = &self.limits;
        f("freq_min_hz", l.freq_min_hz, 0.1, 100.0)?;
        f(
            "freq_max_hz",
            l.freq_max_hz,
            f64::from(l.freq_min_hz),
            200.0,
        )?;
        f(
            "amplitude_max_mm",
            l.amplitude_max_mm,
            0.0,
            f64::from(self.drive.max_amplitude_mm()),
        )?;
        f("freq_slew_hz_per_s", l.freq_slew_hz_per_s, 1e-3, 100.0)?;
        f("amp_ramp_mm_per_s", l.amp_ramp_mm_per_s, 1e-3, 100.0)?;
        f("abort_ramp_mm_per_s", l.abort_ramp_mm_per_s, 1e-3, 1000.0)?;
        f(
            "force_limit_n",
            l.force_limit_n,
            1.0,
            f64::from(self.sensor.max_force_n()),
        )?;
        let d = &self.detector;
        f(
            "threshold_n",
            d.threshold_n,
            0.01,
            f64::from(l.force_limit_n),
        )?;
        f(
            "hysteresis_n",
            d.hysteresis_n,
            0.0,
            f64::from(d.threshold_n),
        )?;
        f("refractory_s", d.refractory_s, 0.0, 0.1)?;
        let t = &self.track;
        f("step_hz", t.step_hz, 1e-4, 1.0)?;
        f("min_step_hz", t.min_step_hz, 1e-4, f64::from(t.step_hz))?;
        f("settle_cycles", f32::from(t.settle_cycles), 0.0, 1000.0)?;
        f("measure_cycles", f32::from(t.measure_cycles), 1.0, 16.0)?;
        f("improve_rel", t.improve_rel, 0.0, 0.5)?;
        let fs = &self.faults;
        f("no_signal_s", fs.no_signal_s, 0.01, 60.0)?;
        f(
            "rail_margin_codes",
            f32::from(fs.rail_margin_codes),
            0.0,
            512.0,
        )?;
        f("rail_s", fs.rail_s, 1e-4, 10.0)?;
        check_range(
            "deadline_us",
            f64::from(fs.deadline_us),
            f64::from(SAMPLE_PERIOD_US) + 1.0,
            1e6,
        )?;
        Ok(())
    }
}

/// Seconds → whole samples at [`SAMPLE_RATE_HZ`] (at least `min`).
pub(crate) fn samples(seconds: f32, min: u32) -> u32 {
    let n = seconds * SAMPLE_RATE_HZ as f32;
    // `as` saturates (NaN → 0): no panic.
    (libm::roundf(n) as u32).max(min)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sensor_chain_round_trips_and_spans_the_rig_forces() {
        let s = SensorChain::default();
        for f in [-10.0f32, 0.0, 3.0, 95.9, 234.6] {
            let code = s.code_of(f);
            assert!(
                (s.force_n(libm::roundf(code) as u16) - f).abs() < 0.05,
                "{f}"
            );
        }
        // One code is 3.3 V / 4096 / 10 mV/N = 0.0806 N.
        assert!((s.force_n(1001) - s.force_n(1000) - 0.080_566).abs() < 1e-5);
        // The beam-170 rig's predicted 80.3 mg (235 N) fits under the rail with the 280 N limit.
        assert!(s.max_force_n() > 300.0 && s.max_force_n() < 311.0);
    }

    #[test]
    fn default_config_is_valid_and_bad_fields_are_named() {
        ControllerConfig::default().validate().unwrap();
        let mut c = ControllerConfig::default();
        c.limits.freq_max_hz = 0.5;
        assert!(matches!(
            c.validate(),
            Err(ParamError::OutOfRange {
                field: "freq_max_hz",
                ..
            })
        ));
        let mut c = ControllerConfig::default();
        c.sensor.volts_per_n = f32::NAN;
        assert!(matches!(
            c.validate(),
            Err(ParamError::NotFinite {
                field: "volts_per_n"
            })
        ));
        let mut c = ControllerConfig::default();
        c.limits.amplitude_max_mm = 1.6; // the DAC gives at most 2047 / 1241.2 = 1.649 mm
        c.validate().unwrap();
        c.limits.amplitude_max_mm = 1.7;
        assert!(c.validate().is_err());
    }

    #[test]
    fn drive_chain_amplitude() {
        let d = DriveChain::default();
        // 0.89 mm (the thesis' A0) is 0.89 V of DAC amplitude = 1104.7 codes.
        assert!((0.89 * d.codes_per_mm() - 1104.7).abs() < 0.1);
        assert!((d.max_amplitude_mm() - 1.6492).abs() < 1e-3);
    }
}

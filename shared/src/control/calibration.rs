//! The rig's calibration: the sensing chain (charge amplifier, ADC), the drive chain (DAC, power
//! amplifier and shaker) and the safe operating window — what differs from one rig's wiring to
//! the next, set at run time (the console's `calib <field> <value>`) and kept in flash with the
//! model. The detector, tracking and fault settings stay the firmware's
//! ([`ControllerConfig`]'s defaults).

use core::fmt;
use core::str::FromStr;

use serde::{Deserialize, Serialize};

use super::config::{ControllerConfig, DriveChain, Limits, SensorChain};
use crate::error::ParamError;

/// The calibration part of a [`ControllerConfig`].
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Calibration {
    /// Force → charge amplifier → ADC.
    pub sensor: SensorChain,
    /// DAC → power amplifier → cart.
    pub drive: DriveChain,
    /// The safe operating window.
    pub limits: Limits,
}

impl Calibration {
    /// The calibration of `config`.
    pub fn of(config: &ControllerConfig) -> Calibration {
        Calibration {
            sensor: config.sensor,
            drive: config.drive,
            limits: config.limits,
        }
    }

    /// `config` with this calibration, validated as a whole ([`ControllerConfig::validate`]:
    /// a 0 V/N sensor, a window upside down, a force limit past the ADC's rail are refused).
    ///
    /// # Errors
    /// [`ParamError`] naming the field and its range.
    pub fn applied_to(&self, config: &ControllerConfig) -> Result<ControllerConfig, ParamError> {
        let c = ControllerConfig {
            sensor: self.sensor,
            drive: self.drive,
            limits: self.limits,
            ..*config
        };
        c.validate()?;
        Ok(c)
    }

    /// The value of `field`.
    pub fn value(&self, field: CalibField) -> f32 {
        match field {
            CalibField::VoltsPerN => self.sensor.volts_per_n,
            CalibField::OffsetV => self.sensor.offset_v,
            CalibField::AdcFullScaleV => self.sensor.adc_full_scale_v,
            CalibField::DacFullScaleV => self.drive.dac_full_scale_v,
            CalibField::CartMmPerV => self.drive.cart_mm_per_v,
            CalibField::FreqMinHz => self.limits.freq_min_hz,
            CalibField::FreqMaxHz => self.limits.freq_max_hz,
            CalibField::AmplitudeMaxMm => self.limits.amplitude_max_mm,
            CalibField::FreqSlewHzPerS => self.limits.freq_slew_hz_per_s,
            CalibField::AmpRampMmPerS => self.limits.amp_ramp_mm_per_s,
            CalibField::AbortRampMmPerS => self.limits.abort_ramp_mm_per_s,
            CalibField::ForceLimitN => self.limits.force_limit_n,
        }
    }

    /// This calibration with `field` set to `value` (unchecked: [`Calibration::applied_to`]
    /// checks).
    pub fn with(&self, field: CalibField, value: f32) -> Calibration {
        let mut c = *self;
        let slot = match field {
            CalibField::VoltsPerN => &mut c.sensor.volts_per_n,
            CalibField::OffsetV => &mut c.sensor.offset_v,
            CalibField::AdcFullScaleV => &mut c.sensor.adc_full_scale_v,
            CalibField::DacFullScaleV => &mut c.drive.dac_full_scale_v,
            CalibField::CartMmPerV => &mut c.drive.cart_mm_per_v,
            CalibField::FreqMinHz => &mut c.limits.freq_min_hz,
            CalibField::FreqMaxHz => &mut c.limits.freq_max_hz,
            CalibField::AmplitudeMaxMm => &mut c.limits.amplitude_max_mm,
            CalibField::FreqSlewHzPerS => &mut c.limits.freq_slew_hz_per_s,
            CalibField::AmpRampMmPerS => &mut c.limits.amp_ramp_mm_per_s,
            CalibField::AbortRampMmPerS => &mut c.limits.abort_ramp_mm_per_s,
            CalibField::ForceLimitN => &mut c.limits.force_limit_n,
        };
        *slot = value;
        c
    }
}

/// A number of the calibration, by its field name in [`ControllerConfig`] (and the TOML's
/// `[calibration.sensor]`, `[calibration.drive]`, `[calibration.limits]` tables).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalibField {
    /// [`SensorChain::volts_per_n`].
    VoltsPerN,
    /// [`SensorChain::offset_v`].
    OffsetV,
    /// [`SensorChain::adc_full_scale_v`].
    AdcFullScaleV,
    /// [`DriveChain::dac_full_scale_v`].
    DacFullScaleV,
    /// [`DriveChain::cart_mm_per_v`].
    CartMmPerV,
    /// [`Limits::freq_min_hz`].
    FreqMinHz,
    /// [`Limits::freq_max_hz`].
    FreqMaxHz,
    /// [`Limits::amplitude_max_mm`].
    AmplitudeMaxMm,
    /// [`Limits::freq_slew_hz_per_s`].
    FreqSlewHzPerS,
    /// [`Limits::amp_ramp_mm_per_s`].
    AmpRampMmPerS,
    /// [`Limits::abort_ramp_mm_per_s`].
    AbortRampMmPerS,
    /// [`Limits::force_limit_n`].
    ForceLimitN,
}

impl CalibField {
    /// Every field, in the order the calibration is shown.
    pub const ALL: [CalibField; 12] = [
        CalibField::VoltsPerN,
        CalibField::OffsetV,
        CalibField::AdcFullScaleV,
        CalibField::DacFullScaleV,
        CalibField::CartMmPerV,
        CalibField::FreqMinHz,
        CalibField::FreqMaxHz,
        CalibField::AmplitudeMaxMm,
        CalibField::FreqSlewHzPerS,
        CalibField::AmpRampMmPerS,
        CalibField::AbortRampMmPerS,
        CalibField::ForceLimitN,
    ];

    /// The field's name.
    pub const fn name(self) -> &'static str {
        match self {
            CalibField::VoltsPerN => "volts_per_n",
            CalibField::OffsetV => "offset_v",
            CalibField::AdcFullScaleV => "adc_full_scale_v",
            CalibField::DacFullScaleV => "dac_full_scale_v",
            CalibField::CartMmPerV => "cart_mm_per_v",
            CalibField::FreqMinHz => "freq_min_hz",
            CalibField::FreqMaxHz => "freq_max_hz",
            CalibField::AmplitudeMaxMm => "amplitude_max_mm",
            CalibField::FreqSlewHzPerS => "freq_slew_hz_per_s",
            CalibField::AmpRampMmPerS => "amp_ramp_mm_per_s",
            CalibField::AbortRampMmPerS => "abort_ramp_mm_per_s",
            CalibField::ForceLimitN => "force_limit_n",
        }
    }
}

impl fmt::Display for CalibField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for CalibField {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        CalibField::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s))
            .ok_or(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_field_is_set_alone_and_bad_calibrations_are_refused() {
        let config = ControllerConfig::default();
        let cal = Calibration::of(&config);
        assert_eq!(cal.applied_to(&config).unwrap(), config);
        for field in CalibField::ALL {
            let v = cal.value(field);
            let c = cal.with(field, v * 0.999);
            assert_eq!(c.value(field), v * 0.999);
            for other in CalibField::ALL.into_iter().filter(|f| *f != field) {
                assert_eq!(c.value(other), cal.value(other), "{field} moved {other}");
            }
            let e = cal.with(field, f32::NAN).applied_to(&config).unwrap_err();
            assert_eq!(e.field(), field.name(), "{e}");
        }
        // A sensor of 0 V/N, a window upside down.
        let e = cal
            .with(CalibField::VoltsPerN, 0.0)
            .applied_to(&config)
            .unwrap_err();
        assert_eq!(e.field(), "volts_per_n");
        let e = cal
            .with(CalibField::FreqMaxHz, 0.5)
            .applied_to(&config)
            .unwrap_err();
        assert_eq!(e.field(), "freq_max_hz");
    }
}

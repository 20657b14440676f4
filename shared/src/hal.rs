//! The hardware the controller talks to, as small traits of the project's own (embedded-hal 1.0
//! has no ADC or DAC trait). The firmware implements them over the STM32F407's peripherals
//! (ADC1, DAC1, TIM2); host-sim implements them with mocks against a simulated plant.
//!
//! Codes are the converters' raw 12-bit values (`0 ..= 4095`); the calibration from codes to
//! newtons and millimetres lives in [`crate::control::config`].

/// Full scale of the 12-bit converters (ADC and DAC): codes `0 ..= ADC_MAX`.
pub const ADC_MAX: u16 = 4095;

/// Why a force sample could not be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleError {
    /// The converter's data register was overwritten before it was read (ADC `OVR`).
    Overrun,
    /// The conversion did not finish in time.
    Timeout,
}

/// The impact force sensor behind its charge amplifier: one conversion per call.
pub trait ForceSource {
    /// Reads one raw sample, code `0 ..= 4095`.
    ///
    /// # Errors
    /// [`SampleError`] when the converter overran or timed out.
    fn read_code(&mut self) -> Result<u16, SampleError>;
}

/// The analog output that feeds the cart shaker's power amplifier.
pub trait DriveOutput {
    /// Sets the output, code `0 ..= 4095` (mid-scale 2048 is zero drive).
    fn write_code(&mut self, code: u16);
}

/// A monotonic time base, microseconds since start (wraps after ~584,000 years).
pub trait TimeBase {
    /// Now, µs.
    fn now_us(&self) -> u64;
}

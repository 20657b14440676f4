//! The force ADC's end of conversion as the sampling task serves it: the STM32F4 ADC's status
//! register (ADC_SR, RM0090 Rev 19 §13.13.1) holds its flags as `rc_w0` bits — a write of 0
//! clears a flag, a write of 1 leaves it — and the regular data register (ADC_DR) is read once
//! per conversion. The procedure lives here, over [`AdcRegisters`], so that it is tested on the
//! desktop against a model of those bits; the firmware implements the trait over ADC1.
//!
//! - A conversion ends: read ADC_DR (the read clears EOC, §13.13.1), keep its 12 bits.
//! - An overrun (OVR: a result was not read before the next one, with EOCS = 1, §13.8.2): write
//!   ADC_SR with OVR = 0 and every other flag 1 ([`SR_CLEAR_OVR`]), so that only OVR is cleared
//!   — a read-modify-write would write 0 to an EOC set between its read and its write and lose
//!   that conversion —, then read ADC_DR (§13.8.1: the data register must be read; its value,
//!   written over, is discarded) and report [`SampleError::Overrun`].
//! - Before the first trigger ([`discard_pending`]): every flag cleared, ADC_DR read, so that a
//!   conversion of the set-up (the HAL's VREFINT calibration) is not taken for the first sample.

use crate::hal::SampleError;

/// ADC_SR.AWD: analog watchdog flag (bit 0).
pub const SR_AWD: u32 = 1 << 0;
/// ADC_SR.EOC: regular conversion ended (bit 1).
pub const SR_EOC: u32 = 1 << 1;
/// ADC_SR.JEOC: injected conversion ended (bit 2).
pub const SR_JEOC: u32 = 1 << 2;
/// ADC_SR.JSTRT: injected conversion started (bit 3).
pub const SR_JSTRT: u32 = 1 << 3;
/// ADC_SR.STRT: regular conversion started (bit 4).
pub const SR_STRT: u32 = 1 << 4;
/// ADC_SR.OVR: overrun (bit 5).
pub const SR_OVR: u32 = 1 << 5;
/// Every `rc_w0` flag of ADC_SR (bits 5:0; bits 31:6 are reserved, written 0).
pub const SR_FLAGS: u32 = SR_AWD | SR_EOC | SR_JEOC | SR_JSTRT | SR_STRT | SR_OVR;
/// The ADC_SR value that clears OVR and no other flag: `0x1F`.
pub const SR_CLEAR_OVR: u32 = SR_FLAGS & !SR_OVR;
/// The ADC_SR value that clears every flag: `0`.
pub const SR_CLEAR_ALL: u32 = 0;
/// ADC_DR's 12-bit result (right-aligned, 12-bit resolution).
pub const DR_MASK: u32 = 0x0FFF;

/// An ADC's status and data registers.
pub trait AdcRegisters {
    /// Reads ADC_SR.
    fn status(&mut self) -> u32;
    /// Writes ADC_SR (`rc_w0` bits: 0 clears a flag, 1 leaves it).
    fn write_status(&mut self, value: u32);
    /// Reads ADC_DR (clears EOC).
    fn data(&mut self) -> u32;
}

/// Serves an end-of-conversion interrupt: the converted code `0 ..= 4095`.
///
/// # Errors
/// [`SampleError::Overrun`] when OVR is set: OVR alone is cleared and the data register read
/// and discarded (RM0090 §13.8.1, §13.13.1).
pub fn read_conversion(adc: &mut impl AdcRegisters) -> Result<u16, SampleError> {
    if adc.status() & SR_OVR != 0 {
        adc.write_status(SR_CLEAR_OVR);
        let _ = adc.data();
        return Err(SampleError::Overrun);
    }
    Ok((adc.data() & DR_MASK) as u16)
}

/// Before the first trigger: every flag cleared and the data register read, so that the first
/// end of conversion is the first triggered sample's.
pub fn discard_pending(adc: &mut impl AdcRegisters) {
    adc.write_status(SR_CLEAR_ALL);
    let _ = adc.data();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ADC_SR and ADC_DR as RM0090 §13.13.1 and §13.8.2 describe them: `rc_w0` flags, EOC
    /// cleared by a read of DR, OVR set when a conversion ends while EOC is still set. A
    /// conversion can be made to end between the status read and the status write (`race`).
    #[derive(Default)]
    struct ModelAdc {
        sr: u32,
        dr: u32,
        /// Conversion results queued to end right after the next status read.
        race: Option<u32>,
        reads_of_dr: u32,
    }

    impl ModelAdc {
        /// A conversion ends with `code`.
        fn convert(&mut self, code: u32) {
            if self.sr & SR_EOC != 0 {
                self.sr |= SR_OVR;
            }
            self.dr = code;
            self.sr |= SR_EOC | SR_STRT;
        }
    }

    impl AdcRegisters for ModelAdc {
        fn status(&mut self) -> u32 {
            let sr = self.sr;
            if let Some(code) = self.race.take() {
                self.convert(code);
            }
            sr
        }
        fn write_status(&mut self, value: u32) {
            // rc_w0: a 0 clears, a 1 leaves.
            self.sr &= value | !SR_FLAGS;
        }
        fn data(&mut self) -> u32 {
            self.reads_of_dr += 1;
            self.sr &= !SR_EOC;
            self.dr
        }
    }

    /// A read-modify-write clear of OVR without a data read (what the procedure must not do).
    fn clear_by_modify(adc: &mut ModelAdc) -> Result<u16, SampleError> {
        let sr = adc.status();
        if sr & SR_OVR != 0 {
            adc.write_status(sr & !SR_OVR);
            return Err(SampleError::Overrun);
        }
        Ok((adc.data() & DR_MASK) as u16)
    }

    #[test]
    fn a_conversion_reads_the_data_register_and_clears_eoc() {
        let mut adc = ModelAdc::default();
        adc.convert(0x1ABC);
        assert_eq!(read_conversion(&mut adc), Ok(0x0ABC));
        assert_eq!(adc.sr & SR_EOC, 0);
        assert_eq!(adc.reads_of_dr, 1);
    }

    #[test]
    fn an_overrun_clears_only_ovr_and_reads_the_data_register() {
        // Two conversions without a read: OVR.
        let mut adc = ModelAdc::default();
        adc.convert(100);
        adc.convert(200);
        assert_ne!(adc.sr & SR_OVR, 0);
        // A third ends between the status read and the status write.
        adc.race = Some(300);
        assert_eq!(read_conversion(&mut adc), Err(SampleError::Overrun));
        // OVR is clear, the data register was read, and the next interrupt reads a clean
        // conversion: the written value 0x1F touched no flag but OVR.
        assert_eq!(SR_CLEAR_OVR, 0x1F);
        assert_eq!(adc.sr & SR_OVR, 0);
        assert_eq!(adc.reads_of_dr, 1);
        adc.convert(400);
        assert_eq!(read_conversion(&mut adc), Ok(400));
        assert_eq!(adc.sr & (SR_OVR | SR_EOC), 0);
    }

    #[test]
    fn the_model_sees_what_a_read_modify_write_loses() {
        // OVR with EOC already read (cleared), and a conversion ending between the status read
        // and the status write: the read-modify-write writes back the 0 it read into EOC and
        // clears the new conversion's flag (no interrupt will come for it); the procedure
        // writes 1 everywhere but OVR.
        let mut adc = ModelAdc {
            sr: SR_OVR,
            race: Some(300),
            ..ModelAdc::default()
        };
        assert_eq!(clear_by_modify(&mut adc), Err(SampleError::Overrun));
        assert_eq!(adc.sr & SR_EOC, 0, "the conversion in between lost its EOC");
        let mut adc = ModelAdc {
            sr: SR_OVR | SR_AWD,
            race: Some(300),
            ..ModelAdc::default()
        };
        assert_eq!(read_conversion(&mut adc), Err(SampleError::Overrun));
        assert_eq!(adc.sr & SR_AWD, SR_AWD, "a flag other than OVR was cleared");
        assert_eq!(adc.reads_of_dr, 1);

        // Without the data read, EOC stays set after an overrun: the interrupt comes again at
        // once and the overwriting (late) result is taken as the next sample.
        let mut adc = ModelAdc::default();
        adc.convert(100);
        adc.convert(200);
        assert_eq!(clear_by_modify(&mut adc), Err(SampleError::Overrun));
        assert_ne!(
            adc.sr & SR_EOC,
            0,
            "EOC left set: a second interrupt at once"
        );
        assert_eq!(clear_by_modify(&mut adc), Ok(200));
        // The procedure here: EOC clear after the overrun, the next sample is the next
        // conversion.
        let mut adc = ModelAdc::default();
        adc.convert(100);
        adc.convert(200);
        assert_eq!(read_conversion(&mut adc), Err(SampleError::Overrun));
        assert_eq!(adc.sr & (SR_EOC | SR_OVR), 0);
        adc.convert(300);
        assert_eq!(read_conversion(&mut adc), Ok(300));
    }

    #[test]
    fn the_first_trigger_finds_no_flag_and_no_stale_result() {
        let mut adc = ModelAdc::default();
        // The set-up's calibration conversion, unread, and an overrun on top.
        adc.convert(1500);
        adc.convert(1500);
        discard_pending(&mut adc);
        assert_eq!(adc.sr & SR_FLAGS, 0);
        adc.convert(42);
        assert_eq!(read_conversion(&mut adc), Ok(42));
    }
}

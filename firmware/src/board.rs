//! The board's implementations of the controller's hardware traits (`shared::hal`):
//! the force sensor on ADC1/PA1, the shaker drive on DAC1/PA4, and a µs time base from the
//! core's cycle counter (DWT CYCCNT, 168 MHz, extended to 64 bits).

use shared::hal::{DriveOutput, ForceSource, SampleError, TimeBase};
use stm32f4xx_hal::{
    adc::{Adc, config::SampleTime},
    dac::{C1, DacExt, DacOut, DacPin},
    gpio::{Analog, PA1, PA4},
    pac,
    rcc::Rcc,
};

/// The charge amplifier's output on ADC1 channel 1 (PA1): one software-started conversion per
/// sample (15 ADC cycles + 12 at 21 MHz: 1.3 µs), polled with a bounded wait so that a stuck
/// converter gives [`SampleError::Timeout`] instead of hanging (the HAL's `convert` has a panic
/// path, which the sampling task must not have).
pub struct ForceAdc {
    _adc: Adc<pac::ADC1>,
    _pin: PA1<Analog>,
}

/// Polls of the end-of-conversion flag before giving up (≈ 10 µs at 168 MHz).
const EOC_POLLS: u32 = 400;

impl ForceAdc {
    /// Takes the HAL-configured ADC (clock, power, 12-bit right-aligned) and selects channel 1
    /// with a 15-cycle sample time as the single regular conversion.
    pub fn new(adc: Adc<pac::ADC1>, pin: PA1<Analog>) -> Self {
        // SAFETY: ADC1 belongs to this struct from here on; these writes configure its regular
        // sequence (length 1, channel 1) and channel 1's sample time (15 cycles = 0b001).
        let regs = unsafe { &*pac::ADC1::ptr() };
        regs.sqr1().modify(|_, w| unsafe { w.l().bits(0) });
        regs.sqr3().modify(|_, w| unsafe { w.sq1().bits(1) });
        regs.smpr2()
            .modify(|_, w| unsafe { w.smp1().bits(SampleTime::Cycles_15 as u8) });
        ForceAdc {
            _adc: adc,
            _pin: pin,
        }
    }
}

impl ForceSource for ForceAdc {
    fn read_code(&mut self) -> Result<u16, SampleError> {
        // SAFETY: ADC1 is owned by this struct (see `new`).
        let regs = unsafe { &*pac::ADC1::ptr() };
        if regs.sr().read().ovr().bit_is_set() {
            regs.sr().modify(|_, w| w.ovr().clear_bit());
            return Err(SampleError::Overrun);
        }
        regs.sr().modify(|_, w| w.eoc().clear_bit());
        regs.cr2().modify(|_, w| w.swstart().set_bit());
        for _ in 0..EOC_POLLS {
            if regs.sr().read().eoc().bit_is_set() {
                return Ok((regs.dr().read().bits() & 0x0FFF) as u16);
            }
        }
        Err(SampleError::Timeout)
    }
}

/// DAC1 on PA4, 12-bit right-aligned, feeding the power amplifier.
pub struct DacDrive {
    ch: C1,
}

impl DacDrive {
    /// Enables DAC1 on PA4 at mid-scale (zero drive).
    pub fn new(dac: pac::DAC, pin: PA4<Analog>, rcc: &mut Rcc) -> Self {
        let mut ch = dac.constrain(pin, rcc);
        ch.enable();
        ch.set_value(shared::control::config::DAC_MID);
        DacDrive { ch }
    }
}

impl DriveOutput for DacDrive {
    fn write_code(&mut self, code: u16) {
        self.ch.set_value(code.min(shared::hal::ADC_MAX));
    }
}

/// Microseconds from the cycle counter, advanced by [`CycleClock::tick`] at every sample (CYCCNT
/// wraps every 2³² / 168 MHz = 25.6 s; the sampling task ticks it every 100 µs). Only 32-bit
/// arithmetic per tick (the M4 divides 32-bit integers in hardware; a 64-bit division would
/// be a library call in the ISR).
pub struct CycleClock {
    last: u32,
    us: u64,
    rem: u32,
    cycles_per_us: u32,
}

impl CycleClock {
    /// Starts the cycle counter.
    pub fn new(
        dcb: &mut cortex_m::peripheral::DCB,
        mut dwt: cortex_m::peripheral::DWT,
        sysclk_hz: u32,
    ) -> Self {
        dcb.enable_trace();
        dwt.enable_cycle_counter();
        CycleClock {
            last: cortex_m::peripheral::DWT::cycle_count(),
            us: 0,
            rem: 0,
            cycles_per_us: (sysclk_hz / 1_000_000).max(1),
        }
    }

    /// Advances the clock to now.
    pub fn tick(&mut self) {
        let now = cortex_m::peripheral::DWT::cycle_count();
        let delta = now.wrapping_sub(self.last);
        self.last = now;
        let cpu = self.cycles_per_us;
        self.us += u64::from(delta / cpu);
        self.rem += delta % cpu;
        if self.rem >= cpu {
            self.rem -= cpu;
            self.us += 1;
        }
    }
}

impl TimeBase for CycleClock {
    /// µs at the last [`CycleClock::tick`].
    fn now_us(&self) -> u64 {
        self.us
    }
}

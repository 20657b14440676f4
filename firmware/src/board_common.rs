//! What the rig board (`board_rig.rs`) and the emulator board (`board_emu.rs`) share: the
//! shape of the parts the app gets, ADC1's status and data registers, the console's USART2
//! set-up and receive path, and the 64-bit extension of TIM5's 32-bit µs count.

use shared::console::RxError;
use stm32f4xx_hal::gpio::{PA2, PA3};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::Rcc;
use stm32f4xx_hal::serial::{self, Serial};

use crate::config::CONSOLE_BAUD;

/// What the app gets from the board this image is built for, over that board's types (each
/// board names its own: `board::Parts`).
pub struct BoardParts<Adc, Dac, Clock, Serial, Capture, Dog, Trigger, Flash> {
    /// ADC1 on PA1.
    pub adc: Adc,
    /// DAC1 on PA4.
    pub dac: Dac,
    /// µs time base.
    pub clock: Clock,
    /// USART2.
    pub serial: Serial,
    /// ADC2 at the capture rate.
    pub capture: Capture,
    /// The watchdog.
    pub watchdog: Dog,
    /// ADC1's trigger (TIM2), started once interrupts are on.
    pub trigger: Trigger,
    /// The settings store's flash (a NOR flash of `config::STORE_BYTES`).
    pub store: Flash,
}

/// USART2 on PA2/PA3 (AF7), [`CONSOLE_BAUD`] 8N1, receive interrupt on.
pub fn console_usart(usart2: pac::USART2, pins: (PA2, PA3), rcc: &mut Rcc) -> Serial<pac::USART2> {
    let config = serial::Config::default().baudrate(CONSOLE_BAUD.bps());
    let mut usart = match Serial::new(usart2, pins, config, rcc) {
        Ok(s) => s,
        Err(_) => defmt::panic!("USART2 configuration rejected"),
    };
    usart.listen(serial::Event::RxNotEmpty);
    usart
}

/// A received byte, a receive error, or `None` when nothing came.
pub fn read_byte(usart: &mut Serial<pac::USART2>) -> Option<Result<u8, RxError>> {
    use embedded_hal_nb::serial::Read as _;
    match usart.read() {
        Ok(b) => Some(Ok(b)),
        Err(nb::Error::WouldBlock) => None,
        Err(nb::Error::Other(e)) => Some(Err(rx_error(e))),
    }
}

fn rx_error(e: serial::Error) -> RxError {
    match e {
        serial::Error::Overrun => RxError::Overrun,
        serial::Error::FrameFormat => RxError::Framing,
        serial::Error::Noise => RxError::Noise,
        _ => RxError::Parity,
    }
}

/// TIM5's 32-bit µs count extended to 64 bits (read at least once per 71 minutes).
#[derive(Default)]
pub struct Micros64 {
    last: u32,
    high: u64,
}

impl Micros64 {
    /// The 64-bit count for the 32-bit reading `now`, µs.
    pub fn extend(&mut self, now: u32) -> u64 {
        if now < self.last {
            self.high += 1 << 32;
        }
        self.last = now;
        self.high + u64::from(now)
    }
}

/// ADC1's status and data registers (RM0090 §13.13.1, §13.13.14), for
/// `shared::adc_status`'s end-of-conversion service.
pub struct Adc1;

impl shared::adc_status::AdcRegisters for Adc1 {
    fn status(&mut self) -> u32 {
        // SAFETY: a read of ADC1_SR; ADC1's results belong to the sampling task.
        unsafe { &*pac::ADC1::ptr() }.sr().read().bits()
    }
    fn write_status(&mut self, value: u32) {
        // SAFETY: ADC1_SR's rc_w0 flags: the value clears exactly the flags written 0.
        unsafe { &*pac::ADC1::ptr() }
            .sr()
            .write(|w| unsafe { w.bits(value) });
    }
    fn data(&mut self) -> u32 {
        // SAFETY: a read of ADC1_DR (clears EOC).
        unsafe { &*pac::ADC1::ptr() }.dr().read().bits()
    }
}

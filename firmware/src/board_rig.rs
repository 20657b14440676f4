//! The rig board: the STM32F407 (8 MHz HSE, 168 MHz core) and its peripherals, through
//! stm32f4xx-hal where it offers them.
//!
//! | peripheral | use |
//! |---|---|
//! | TIM2 | 10 kHz update event → trigger output (TRGO) → starts each ADC1 conversion (no interrupt) |
//! | ADC1, PA1 | force sensor; end-of-conversion interrupt runs the sampling task; overrun flag = a sample not read in time |
//! | DAC1, PA4 | shaker drive |
//! | TIM5 | free-running 32-bit µs counter (the controller's time base) |
//! | USART2, PA2/PA3 | console, 115200 8N1, receive and transmit-empty interrupts |
//! | TIM3 + ADC2 + DMA2 stream 2 | capture: 100 kHz conversions of PA1 into a double buffer of 2 × 64 samples |
//! | IWDG | 2 s watchdog, fed by the report task's health check |
//! | SysTick | the RTIC monotonic (1 kHz), independent of the sampling |
//!
//! Where the HAL offers nothing (ADC overrun flag, clearing the ADC's start bit), the registers
//! are read or written directly, each marked.

use cortex_m::peripheral::NVIC;
use panic_probe as _;
use shared::console::{Board, RxError};
use shared::control::config::DAC_MID;
use shared::hal::{DriveOutput, ForceSource, SampleError};
use stm32f4xx_hal::adc::Adc;
use stm32f4xx_hal::adc::config::{
    AdcConfig, Continuous, Eoc, ExternalTrigger, SampleTime, Sequence, TriggerMode,
};
use stm32f4xx_hal::dac::{C1, DacExt, DacOut, DacPin};
use stm32f4xx_hal::dma::config::DmaConfig;
use stm32f4xx_hal::dma::{PeripheralToMemory, Stream2, StreamsTuple, Transfer};
use stm32f4xx_hal::pac::{self, DMA2};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Config, Enable};
use stm32f4xx_hal::serial::{self, Serial};
use stm32f4xx_hal::timer::{CounterHz, CounterUs, Timer};
use stm32f4xx_hal::watchdog::IndependentWatchdog;

use rig_firmware::board_common::{BoardParts, Micros64, console_usart, read_byte};
use rig_firmware::config::{CAPTURE_BLOCK, SYSCLK_HZ, WATCHDOG_MS};

/// Which image this is (`id`).
pub const BOARD: Board = Board::Rig;

/// What this board gives the app.
pub type Parts = BoardParts<ForceAdc, DacDrive, MicrosClock, ConsoleSerial, CaptureInput, Watchdog>;

type CaptureTransfer =
    Transfer<Stream2<DMA2>, 1, pac::ADC2, PeripheralToMemory, &'static mut [u16; CAPTURE_BLOCK]>;

/// Sets up the board.
pub fn init(
    dp: pac::Peripherals,
    _nvic: &mut NVIC,
    bufs: [&'static mut [u16; CAPTURE_BLOCK]; 3],
) -> Parts {
    let mut rcc = dp.RCC.freeze(Config::hse(8.MHz()).sysclk(SYSCLK_HZ.Hz()));
    let gpioa = dp.GPIOA.split(&mut rcc);
    let pa1 = gpioa.pa1.into_analog();

    // ADC1: the HAL's set-up (calibration), then conversions on TIM2's trigger output with an
    // interrupt at each end of conversion (EOCS = 1, so a result not read before the next one
    // sets the overrun flag).
    let mut adc = Adc::new(dp.ADC1, true, AdcConfig::default(), &mut rcc);
    adc.configure_channel(&pa1, Sequence::One, SampleTime::Cycles_15);
    adc.set_external_trigger((TriggerMode::RisingEdge, ExternalTrigger::Tim_2_trgo));
    adc.set_continuous(Continuous::Single);
    adc.set_end_of_conversion_interrupt(Eoc::Conversion);
    adc.enable();

    // ADC2 on the same pin, for the capture: TIM3's trigger output, DMA. The HAL constructs
    // only ADC1 (its set-up calibrates on ADC1's internal reference), so ADC2 is set up with
    // registers: channel 1 (PA1), 15-cycle sample time, 12 bits, conversion on TIM3 TRGO's
    // rising edge, a DMA request after each conversion.
    <pac::ADC2 as Enable>::enable(&mut rcc);
    let adc2 = dp.ADC2;
    adc2.sqr1().write(|w| w.l().set(0));
    adc2.sqr3().write(|w| unsafe { w.sq1().bits(1) });
    adc2.smpr2().write(|w| w.smp1().cycles15());
    adc2.cr1().write(|w| w.res().twelve_bit());
    adc2.cr2().write(|w| {
        w.exten().rising_edge();
        w.extsel().tim3trgo();
        w.dma().enabled();
        w.dds().continuous();
        w.adon().enabled()
    });

    let dac = DacDrive::new(dp.DAC, gpioa.pa4.into_analog(), &mut rcc);

    // TIM5: µs counter.
    let mut micros: CounterUs<pac::TIM5> = dp.TIM5.counter_us(&mut rcc);
    if micros.start(u32::MAX.micros()).is_err() {
        defmt::panic!("TIM5 cannot count µs");
    }

    // TIM2: 10 kHz, update event on the trigger output (no interrupt: ADC1 converts on it).
    let mut tim2 = Timer::new(dp.TIM2, &mut rcc);
    tim2.set_master_mode(pac::tim2::cr2::MMS::Update);
    let mut tim2: CounterHz<pac::TIM2> = tim2.counter_hz();
    if tim2.start(shared::control::SAMPLE_RATE_HZ.Hz()).is_err() {
        defmt::panic!("TIM2 cannot run at the sample rate");
    }

    // TIM3: the capture rate, same way; started while a capture records.
    let mut tim3 = Timer::new(dp.TIM3, &mut rcc);
    tim3.set_master_mode(pac::tim3::cr2::MMS::Update);
    let tim3: CounterHz<pac::TIM3> = tim3.counter_hz();

    // DMA2 stream 2 channel 1: ADC2 → two 64-sample buffers in turn (double buffer), an
    // interrupt when one is full; the third buffer is the one being read.
    let streams = StreamsTuple::new(dp.DMA2, &mut rcc);
    let [a, b, spare] = bufs;
    let dma = DmaConfig::default()
        .transfer_complete_interrupt(true)
        .memory_increment(true)
        .double_buffer(true);
    let mut transfer: CaptureTransfer =
        Transfer::init_peripheral_to_memory(streams.2, adc2, a, Some(b), dma);
    transfer.start(|_| {});

    let usart = console_usart(dp.USART2, (gpioa.pa2, gpioa.pa3), &mut rcc);

    let mut iwdg = IndependentWatchdog::new(dp.IWDG);
    iwdg.start(WATCHDOG_MS.millis());

    BoardParts {
        adc: ForceAdc { adc },
        dac,
        clock: MicrosClock {
            timer: micros,
            count: Micros64::default(),
        },
        serial: ConsoleSerial { usart },
        capture: CaptureInput {
            timer: tim3,
            transfer,
            spare: Some(spare),
        },
        watchdog: Watchdog { iwdg },
    }
}

/// The force sensor on ADC1: the conversion TIM2 started.
pub struct ForceAdc {
    adc: Adc<pac::ADC1>,
}

impl ForceSource for ForceAdc {
    fn read_code(&mut self) -> Result<u16, SampleError> {
        // The HAL has no overrun accessor: ADC1's status register, read and its OVR bit
        // cleared here (the sampling task owns ADC1's results).
        // SAFETY: a read of ADC1_SR and a write clearing only OVR.
        let sr = unsafe { &*pac::ADC1::ptr() }.sr();
        if sr.read().ovr().bit_is_set() {
            sr.modify(|_, w| w.ovr().clear_bit());
            return Err(SampleError::Overrun);
        }
        // Reading the data register clears the end-of-conversion flag.
        Ok(self.adc.current_sample() & 0x0FFF)
    }
}

/// DAC1 on PA4, 12-bit right-aligned, feeding the power amplifier.
pub struct DacDrive {
    ch: C1,
}

impl DacDrive {
    fn new(
        dac: pac::DAC,
        pin: stm32f4xx_hal::gpio::PA4<stm32f4xx_hal::gpio::Analog>,
        rcc: &mut stm32f4xx_hal::rcc::Rcc,
    ) -> Self {
        let mut ch = dac.constrain(pin, rcc);
        ch.enable();
        ch.set_value(DAC_MID);
        DacDrive { ch }
    }
}

impl DriveOutput for DacDrive {
    fn write_code(&mut self, code: u16) {
        self.ch.set_value(code.min(shared::hal::ADC_MAX));
    }
}

/// µs since start-up from TIM5 (32-bit, extended to 64 bits at every read).
pub struct MicrosClock {
    timer: CounterUs<pac::TIM5>,
    count: Micros64,
}

impl MicrosClock {
    /// Now, µs.
    pub fn now_us(&mut self) -> u64 {
        self.count.extend(self.timer.now().ticks())
    }
}

/// USART2.
pub struct ConsoleSerial {
    usart: Serial<pac::USART2>,
}

impl ConsoleSerial {
    /// A received byte, a receive error, or `None`.
    pub fn read(&mut self) -> Option<Result<u8, RxError>> {
        read_byte(&mut self.usart)
    }

    /// Whether the transmit register is empty while sending.
    pub fn tx_ready(&self) -> bool {
        self.usart.is_tx_empty()
    }

    /// Writes a byte into the transmit register.
    pub fn write(&mut self, byte: u8) {
        use embedded_hal_nb::serial::Write as _;
        let _ = self.usart.write(byte);
    }

    /// More bytes may follow: the transmit-empty interrupt will come.
    pub fn more_tx(&mut self) {}

    /// Nothing left to send: no more transmit-empty interrupts.
    pub fn stop_tx(&mut self) {
        self.usart.unlisten(serial::Event::TxEmpty);
    }

    /// Bytes were queued: transmit-empty interrupts on.
    pub fn kick_tx(&mut self) {
        self.usart.listen(serial::Event::TxEmpty);
    }
}

/// ADC2 at the capture rate: TIM3 triggers, DMA2 fills the double buffer.
pub struct CaptureInput {
    timer: CounterHz<pac::TIM3>,
    transfer: CaptureTransfer,
    spare: Option<&'static mut [u16; CAPTURE_BLOCK]>,
}

impl CaptureInput {
    /// Starts the conversions.
    pub fn start(&mut self) {
        let _ = self.timer.start(shared::capture::CAPTURE_RATE_HZ.Hz());
    }

    /// Stops them.
    pub fn stop(&mut self) {
        let _ = self.timer.cancel();
    }

    /// The buffer the DMA just filled, to `f`; the spare buffer takes its place.
    pub fn take_block(&mut self, f: impl FnOnce(&[u16])) {
        let Some(spare) = self.spare.take() else {
            return;
        };
        match self.transfer.next_transfer(spare) {
            Ok((full, _)) => {
                f(&full[..]);
                self.spare = Some(full);
            }
            Err(e) => {
                // Not ready or a transfer error: keep the buffer for the next interrupt.
                use stm32f4xx_hal::dma::DMAError::{NotReady, Overrun, SmallBuffer};
                let (NotReady(b) | SmallBuffer(b) | Overrun(b)) = e;
                self.spare = Some(b);
            }
        }
    }
}

/// The independent watchdog.
pub struct Watchdog {
    iwdg: IndependentWatchdog,
}

impl Watchdog {
    /// Feeds it.
    pub fn feed(&mut self, _now_ms: u32) {
        self.iwdg.feed();
    }

    /// The hardware resets the MCU by itself when not fed.
    pub fn check(&mut self, _now_ms: u32) {}
}

/// No test hooks on the rig.
pub fn hook(_line: &str, _now_ms: u32) -> Option<heapless::String<96>> {
    None
}

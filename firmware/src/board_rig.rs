//! The rig board: the STM32F407 (8 MHz HSE, 168 MHz core) and its peripherals, through
//! stm32f4xx-hal where it offers them and with registers where the board needs what it does not
//! (the timers' exact reloads, the capture's DMA stream, the ADCs' status flags). Every clock
//! and reload comes from `rig_firmware::clock_tree`, checked there at compile time against
//! RM0090 Rev 19; `tests/tests/all/register_trace.rs` runs this image's start-up in an instruction
//! emulator and checks the registers it writes.
//!
//! | peripheral | use |
//! |---|---|
//! | TIM2 | 10 kHz update event → trigger output (TRGO) → starts each ADC1 conversion (no interrupt); started after `init`, with interrupts on |
//! | ADC1, PA1 | force sensor; end-of-conversion interrupt runs the sampling task; overrun flag = a sample not read in time |
//! | DAC1, PA4 | shaker drive |
//! | TIM5 | free-running 32-bit µs counter (the controller's time base), full 2³² period |
//! | USART2, PA2/PA3 | console, 115200 8N1, receive and transmit-empty interrupts |
//! | TIM3 + ADC2 + DMA2 stream 2 | capture: 100 kHz conversions of PA1 into a double buffer of 2 × 64 samples, half a period off ADC1's |
//! | IWDG | 2 s watchdog, fed by the report task's health check; stopped while a debugger halts the core |
//! | SysTick | the RTIC monotonic (1 kHz), independent of the sampling |

use cortex_m::peripheral::NVIC;
use panic_probe as _;
use shared::adc_status::{SR_CLEAR_OVR, discard_pending, read_conversion};
use shared::capture_dma::{BlockTracker, CaptureStream, StreamState};
use shared::console::{Board, RxError};
use shared::control::config::DAC_MID;
use shared::hal::{DriveOutput, ForceSource, SampleError};
use stm32f4xx_hal::adc::Adc;
use stm32f4xx_hal::adc::config::{
    AdcConfig, Clock, Continuous, Eoc, ExternalTrigger, SampleTime, Sequence, TriggerMode,
};
use stm32f4xx_hal::dac::{C1, DacExt, DacOut, DacPin};
use stm32f4xx_hal::pac::{self, Interrupt};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Config, Enable, Reset};
use stm32f4xx_hal::serial::{self, Serial};
use stm32f4xx_hal::watchdog::IndependentWatchdog;

use rig_firmware::board_common::{Adc1, BoardParts, Micros64, console_usart, read_byte};
use rig_firmware::clock_tree::{
    ADC_PRESCALER, ADC_SAMPLE_CYCLES, HCLK_HZ, HSE_HZ, PCLK1_HZ, PCLK2_HZ, TIM2_ARR, TIM3_ARR,
    TIM3_PERIOD, TIM3_PHASE, TIM5_ARR, TIM5_PSC,
};
use rig_firmware::config::{
    CAPTURE_BLOCK, HSE_BYPASS, STORE_ADDRESS, STORE_BYTES, STORE_SECTORS, SYSCLK_HZ, WATCHDOG_MS,
};

/// Which image this is (`id`).
pub const BOARD: Board = Board::Rig;

/// What this board gives the app.
pub type Parts = BoardParts<
    ForceAdc,
    DacDrive,
    MicrosClock,
    ConsoleSerial,
    CaptureInput,
    Watchdog,
    SamplingTrigger,
    StoreFlash,
>;

/// ADC_CCR.ADCPRE for `clock_tree::ADC_PRESCALER` (RM0090 §13.13.16).
const ADC_CLOCK: Clock = match ADC_PRESCALER {
    2 => Clock::Pclk2_div_2,
    4 => Clock::Pclk2_div_4,
    6 => Clock::Pclk2_div_6,
    8 => Clock::Pclk2_div_8,
    _ => panic!("ADC_PRESCALER is 2, 4, 6 or 8"),
};
/// ADC_SMPRx for `clock_tree::ADC_SAMPLE_CYCLES` (§13.13.4–5).
const ADC_SAMPLE_TIME: SampleTime = match ADC_SAMPLE_CYCLES {
    15 => SampleTime::Cycles_15,
    _ => panic!("ADC_SAMPLE_CYCLES: only 15 is set up"),
};

/// The capture's DMA stream: DMA2 stream 2, channel 1 = ADC2 (RM0090 §10.3.3, Table 43).
const CAPTURE_STREAM: usize = 2;
/// DMA_SxCR of the capture's stream, enable bit clear (§10.5.5): CHSEL = 1 (ADC2), PL = very
/// high, DBM (double buffer: M0 then M1 then M0 …, §10.3.9), CT = 0 (M0 first), CIRC (forced
/// by DBM), MSIZE = PSIZE = half-word, MINC, DIR = peripheral to memory, interrupts on a
/// full buffer (TCIE), a transfer error (TEIE) and a direct-mode error (DMEIE).
const CAPTURE_DMA_CR: u32 = (1 << 25) // CHSEL = 001
    | (0b11 << 16) // PL: very high
    | (1 << 18) // DBM
    | (0b01 << 13) // MSIZE: 16 bits
    | (0b01 << 11) // PSIZE: 16 bits
    | (1 << 10) // MINC
    | (1 << 8) // CIRC
    | (1 << 4) // TCIE
    | (1 << 2) // TEIE
    | (1 << 1); // DMEIE
/// DMA_SxCR.EN.
const DMA_EN: u32 = 1 << 0;
/// DMA_SxCR.CT: the buffer being filled (0: M0).
const DMA_CT: u32 = 1 << 19;
/// Stream 2's flags in DMA_LISR and their clear bits in DMA_LIFCR (§10.5.1, §10.5.3): FEIF2
/// (16), DMEIF2 (18), TEIF2 (19), HTIF2 (20), TCIF2 (21).
const STREAM2_FEIF: u32 = 1 << 16;
const STREAM2_DMEIF: u32 = 1 << 18;
const STREAM2_TEIF: u32 = 1 << 19;
const STREAM2_HTIF: u32 = 1 << 20;
const STREAM2_TCIF: u32 = 1 << 21;
const STREAM2_ALL: u32 = STREAM2_FEIF | STREAM2_DMEIF | STREAM2_TEIF | STREAM2_HTIF | STREAM2_TCIF;
/// Polls of EN after a disable (an ongoing transfer finishes first, §10.3.17: a few bus cycles).
const DISABLE_POLLS: u32 = 1_000;

/// The RCC set-up for the clock tree of `clock_tree` (HSE, PLL to 168 MHz, APB1 /4, APB2 /2;
/// the HAL sets the flash wait states for SYSCLK, RM0090 §3.5.1).
fn clock_config() -> Config {
    let cfg = Config::hse(HSE_HZ.Hz())
        .sysclk(SYSCLK_HZ.Hz())
        .hclk(HCLK_HZ.Hz())
        .pclk1(PCLK1_HZ.Hz())
        .pclk2(PCLK2_HZ.Hz());
    if HSE_BYPASS {
        cfg.bypass_hse_oscillator()
    } else {
        cfg
    }
}

/// Sets up the board. Nothing is triggered yet: the sampling starts with
/// [`SamplingTrigger::start`] once interrupts are on, the capture with [`CaptureInput::start`].
pub fn init(
    dp: pac::Peripherals,
    _nvic: &mut NVIC,
    bufs: &'static mut [[u16; CAPTURE_BLOCK]; 2],
) -> Parts {
    // A debugger's halt stops the IWDG (DBGMCU_APB1_FZ.DBG_IWDG_STOP, RM0090 §38.16.4,
    // §21.3.3); otherwise a breakpoint held for 2 s resets the board.
    dp.DBGMCU
        .apb1_fz()
        .modify(|_, w| w.dbg_iwdg_stop().set_bit());

    let mut rcc = dp.RCC.freeze(clock_config());
    let gpioa = dp.GPIOA.split(&mut rcc);
    let pa1 = gpioa.pa1.into_analog();

    // ADC1: the HAL's set-up (ADC clock PCLK2/4 = 21 MHz, its VREFINT calibration), then
    // conversions on TIM2's trigger output with an interrupt at each end of conversion (EOCS =
    // 1, so a result not read before the next one sets the overrun flag, §13.8.2).
    let mut adc = Adc::new(
        dp.ADC1,
        true,
        AdcConfig::default().clock(ADC_CLOCK),
        &mut rcc,
    );
    adc.configure_channel(&pa1, Sequence::One, ADC_SAMPLE_TIME);
    adc.set_external_trigger((TriggerMode::RisingEdge, ExternalTrigger::Tim_2_trgo));
    adc.set_continuous(Continuous::Single);
    adc.set_end_of_conversion_interrupt(Eoc::Conversion);
    adc.enable();

    // ADC2 on the same pin, for the capture: TIM3's trigger output, DMA. The HAL constructs
    // only ADC1 (its set-up calibrates on ADC1's internal reference), so ADC2 is set up with
    // registers: channel 1 (PA1), 15-cycle sample time, 12 bits, conversion on TIM3 TRGO's
    // rising edge, a DMA request after each conversion (DDS = 1: for ever, as double-buffer
    // mode needs, §13.8.1). ADC1's reset above reset it too (one reset for all ADCs).
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

    // TIM5: a µs counter over the full 32 bits (ARR = 0xFFFF_FFFF, §18.4.12): the prescaler
    // is loaded by an update event (UG, with URS so that it sets no flag, §18.4.1, §18.4.6).
    <pac::TIM5 as Enable>::enable(&mut rcc);
    <pac::TIM5 as Reset>::reset(&mut rcc);
    let tim5 = dp.TIM5;
    tim5.psc().write(|w| w.psc().set(TIM5_PSC as u16));
    tim5.arr().write(|w| unsafe { w.bits(TIM5_ARR) });
    tim5.cr1().write(|w| w.urs().set_bit());
    tim5.egr().write(|w| w.ug().set_bit());
    tim5.cr1().write(|w| w.urs().set_bit().cen().set_bit());

    // TIM2: 10 kHz update events on its trigger output (MMS = 010, §18.4.2), no interrupt,
    // prescaler 1 (its reset value: no update event needed, so no trigger now). Counting
    // starts in `SamplingTrigger::start`.
    <pac::TIM2 as Enable>::enable(&mut rcc);
    <pac::TIM2 as Reset>::reset(&mut rcc);
    let tim2 = dp.TIM2;
    tim2.arr().write(|w| unsafe { w.bits(TIM2_ARR) });
    tim2.cr2().write(|w| w.mms().update());

    // TIM3: the capture rate, the same way; counts while a capture records.
    <pac::TIM3 as Enable>::enable(&mut rcc);
    <pac::TIM3 as Reset>::reset(&mut rcc);
    let tim3 = dp.TIM3;
    tim3.arr().write(|w| unsafe { w.bits(TIM3_ARR) });
    tim3.cr2().write(|w| w.mms().update());

    // DMA2 stream 2 channel 1: ADC2's data register → M0, M1, M0 … (the two halves of
    // `bufs`), configured disabled (§10.3.17); enabled at each capture's start.
    <pac::DMA2 as Enable>::enable(&mut rcc);
    <pac::DMA2 as Reset>::reset(&mut rcc);
    let dma = dp.DMA2;
    let bufs_addr = bufs.as_mut_ptr() as usize;
    {
        let st = dma.st(CAPTURE_STREAM);
        st.par()
            .write(|w| unsafe { w.bits(adc2.dr().as_ptr() as u32) });
        st.m0ar().write(|w| unsafe { w.bits(bufs_addr as u32) });
        st.m1ar()
            .write(|w| unsafe { w.bits((bufs_addr + 2 * CAPTURE_BLOCK) as u32) });
        st.ndtr().write(|w| unsafe { w.bits(CAPTURE_BLOCK as u32) });
        st.cr().write(|w| unsafe { w.bits(CAPTURE_DMA_CR) });
    }

    let usart = console_usart(dp.USART2, (gpioa.pa2, gpioa.pa3), &mut rcc);

    let mut iwdg = IndependentWatchdog::new(dp.IWDG);
    iwdg.start(WATCHDOG_MS.millis());

    BoardParts {
        adc: ForceAdc { _adc: adc },
        dac,
        clock: MicrosClock {
            _tim5: tim5,
            count: Micros64::default(),
        },
        serial: ConsoleSerial { usart },
        capture: CaptureInput {
            tim3,
            dma,
            adc2,
            bufs_addr,
            tracker: BlockTracker::new(),
        },
        watchdog: Watchdog { iwdg },
        trigger: SamplingTrigger { tim2 },
        store: StoreFlash::new(dp.FLASH),
    }
}

/// Before a `reset`: nothing to stop (the drive is idle, the DAC at mid-scale; the reset
/// returns every peripheral to its reset state, RM0090 §7.1.2).
pub fn before_reset() {}

/// ADC1's trigger, TIM2.
pub struct SamplingTrigger {
    tim2: pac::TIM2,
}

impl SamplingTrigger {
    /// Starts the sampling: ADC1's flags cleared and its data register read (the set-up's
    /// calibration conversion is not a sample; an overrun latched before the first trigger
    /// would read as an `adc-overrun` fault), the ADC interrupt's pending bit cleared, then
    /// TIM2 counting: its first update, 100 µs later, starts the first conversion. Called once,
    /// with interrupts on, so that the first end of conversion is served (RM0090 §13.8.2).
    pub fn start(&mut self) {
        discard_pending(&mut Adc1);
        NVIC::unpend(Interrupt::ADC);
        self.tim2.cr1().modify(|_, w| w.cen().set_bit());
    }
}

/// The force sensor on ADC1: the conversion TIM2 started.
pub struct ForceAdc {
    // Owned so that nothing else reconfigures ADC1; its registers are read through `Adc1`.
    _adc: Adc<pac::ADC1>,
}

impl ForceSource for ForceAdc {
    fn read_code(&mut self) -> Result<u16, SampleError> {
        read_conversion(&mut Adc1)
    }
}

/// DAC1 on PA4, 12-bit right-aligned, output buffer on, feeding the power amplifier.
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

/// TIM5's count, µs.
fn tim5_now_us() -> u32 {
    // SAFETY: a read of TIM5_CNT; TIM5 only counts after `init`.
    unsafe { &*pac::TIM5::ptr() }.cnt().read().bits()
}

/// µs since start-up from TIM5 (32-bit, extended to 64 bits at every read).
pub struct MicrosClock {
    // Owned so that nothing else reconfigures TIM5; its counter is read through `tim5_now_us`.
    _tim5: pac::TIM5,
    count: Micros64,
}

impl MicrosClock {
    /// Now, µs.
    pub fn now_us(&mut self) -> u64 {
        self.count.extend(tim5_now_us())
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

/// ADC2 at the capture rate: TIM3 triggers, DMA2 stream 2 fills the double buffer; the
/// bookkeeping (late service, lost blocks, re-arming) is `shared::capture_dma`'s.
pub struct CaptureInput {
    tim3: pac::TIM3,
    dma: pac::DMA2,
    adc2: pac::ADC2,
    /// The two buffers' address (the DMA writes them: read with volatile reads only).
    bufs_addr: usize,
    tracker: BlockTracker,
}

impl CaptureInput {
    /// Starts the conversions of a new capture, if they are not running: the stream re-armed
    /// (no sample of an earlier capture left in a half-filled buffer reaches this one), TIM3
    /// started half a capture period off TIM2's update (ADC1 and ADC2 never sample PA1 at
    /// once). While running, it does nothing: the capture's sample phase stays.
    pub fn start(&mut self) {
        if self.tim3.cr1().read().cen().bit_is_set() {
            return;
        }
        self.stream().rearm();
        // SAFETY: a read of TIM2's counter (TIM2 belongs to the sampling trigger).
        let tim2_cnt = unsafe { &*pac::TIM2::ptr() }.cnt().read().bits();
        let cnt = (tim2_cnt % TIM3_PERIOD + TIM3_PHASE) % TIM3_PERIOD;
        self.tim3.cnt().write(|w| unsafe { w.bits(cnt) });
        self.tracker.start(tim5_now_us());
        self.tim3.cr1().modify(|_, w| w.cen().set_bit());
    }

    /// Stops them (the stream stays as it is: the next start re-arms it).
    pub fn stop(&mut self) {
        self.tim3.cr1().modify(|_, w| w.cen().clear_bit());
        self.tracker.stop();
    }

    /// A new capture was armed: its conversions start afresh.
    pub fn restart(&mut self) {
        self.stop();
        self.start();
    }

    /// Serves the stream: `f` gets the samples lost since the last call and the newest full
    /// block (empty when there is none). Called on the stream's interrupt and once a second
    /// (a stalled stream raises none).
    pub fn take_block(&mut self, f: impl FnOnce(u32, &[u16])) {
        let mut block = [0u16; CAPTURE_BLOCK];
        let tracker = &mut self.tracker;
        let mut stream = Stream2 {
            dma: &self.dma,
            adc2: &self.adc2,
            bufs_addr: self.bufs_addr,
        };
        let s = tracker.service(&mut stream, &mut block);
        let n = if s.block { CAPTURE_BLOCK } else { 0 };
        f(s.lost_samples, block.get(..n).unwrap_or(&[]));
    }

    fn stream(&self) -> Stream2<'_> {
        Stream2 {
            dma: &self.dma,
            adc2: &self.adc2,
            bufs_addr: self.bufs_addr,
        }
    }
}

/// DMA2 stream 2 and ADC2, for `shared::capture_dma`.
struct Stream2<'a> {
    dma: &'a pac::DMA2,
    adc2: &'a pac::ADC2,
    bufs_addr: usize,
}

impl CaptureStream for Stream2<'_> {
    fn clear_complete(&mut self) {
        self.dma.lifcr().write(|w| unsafe { w.bits(STREAM2_TCIF) });
    }

    fn state(&mut self) -> StreamState {
        let st = self.dma.st(CAPTURE_STREAM);
        // CT and NDTR as one pair: read CT again after NDTR; a buffer switch in between (at
        // most one in a few cycles) shows as a changed CT.
        let mut cr = st.cr().read().bits();
        let mut ndtr = st.ndtr().read().bits();
        for _ in 0..2 {
            let again = st.cr().read().bits();
            if (again ^ cr) & DMA_CT == 0 {
                break;
            }
            cr = again;
            ndtr = st.ndtr().read().bits();
        }
        let isr = self.dma.lisr().read().bits();
        StreamState {
            enabled: cr & DMA_EN != 0,
            target: u8::from(cr & DMA_CT != 0),
            remaining: ndtr as u16,
            error: isr & (STREAM2_TEIF | STREAM2_DMEIF) != 0,
            adc_overrun: self.adc2.sr().read().ovr().bit_is_set(),
            now_us: tim5_now_us(),
        }
    }

    fn copy(&mut self, target: u8, out: &mut [u16; CAPTURE_BLOCK]) {
        let base = self.bufs_addr + usize::from(target & 1) * 2 * CAPTURE_BLOCK;
        for (i, o) in out.iter_mut().enumerate() {
            // SAFETY: inside the 2 × CAPTURE_BLOCK buffers of `init` ('static); the DMA writes
            // them, hence volatile reads. A copy the DMA overtakes is caught by the tracker.
            let code = unsafe { core::ptr::read_volatile((base + 2 * i) as *const u16) };
            *o = code & 0x0FFF;
        }
    }

    /// RM0090 §10.3.17 (stream configuration) and §13.8.1 (recovering ADC2 from an overrun
    /// when the DMA is used: re-initialise the DMA, clear OVR, then the next trigger converts).
    fn rearm(&mut self) {
        let st = self.dma.st(CAPTURE_STREAM);
        // No requests from ADC2 while the stream is set up.
        self.adc2.cr2().modify(|_, w| w.dma().disabled());
        // Disable the stream and wait until it is (an ongoing transfer ends first); its
        // configuration bits can be written only then.
        st.cr().modify(|r, w| unsafe { w.bits(r.bits() & !DMA_EN) });
        for _ in 0..DISABLE_POLLS {
            if st.cr().read().bits() & DMA_EN == 0 {
                break;
            }
        }
        // Its flags cleared (a set flag would keep the interrupt pending), then M0 first (CT
        // = 0 in CAPTURE_DMA_CR) with a whole block to go.
        self.dma.lifcr().write(|w| unsafe { w.bits(STREAM2_ALL) });
        st.cr().write(|w| unsafe { w.bits(CAPTURE_DMA_CR) });
        st.ndtr().write(|w| unsafe { w.bits(CAPTURE_BLOCK as u32) });
        // ADC2's overrun cleared alone (rc_w0) and its stale result read.
        self.adc2.sr().write(|w| unsafe { w.bits(SR_CLEAR_OVR) });
        let _ = self.adc2.dr().read().bits();
        st.cr()
            .write(|w| unsafe { w.bits(CAPTURE_DMA_CR | DMA_EN) });
        self.adc2.cr2().modify(|_, w| w.dma().enabled());
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

/// The settings store's flash: sectors [`STORE_SECTORS`] from [`STORE_ADDRESS`], erased by
/// sector and programmed by 32-bit word (x32 parallelism: VDD 2.7 – 3.6 V, RM0090 §3.6.2), as
/// a NOR flash for `shared::store` (offsets from [`STORE_ADDRESS`]). Each operation unlocks the
/// flash (FLASH_KEYR, §3.6.1), waits for BSY to clear, checks the error flags and locks it again;
/// the data cache is reset after a change so that no stale line is read (FLASH_ACR.DCRST,
/// §3.9.1). While it erases or programs, the CPU stalls on every flash fetch (one bank,
/// §3.6.3–3.6.4): the console service pauses the controller's deadline checks around a save.
pub struct StoreFlash {
    flash: pac::FLASH,
}

/// Why a flash operation failed: FLASH_SR's error flags (PGSERR, PGPERR, PGAERR, WRPERR,
/// OPERR), or an address outside the store.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StoreFlashError(u32);

impl embedded_storage_async::nor_flash::NorFlashError for StoreFlashError {
    fn kind(&self) -> embedded_storage_async::nor_flash::NorFlashErrorKind {
        if self.0 == OUT_OF_STORE {
            embedded_storage_async::nor_flash::NorFlashErrorKind::OutOfBounds
        } else {
            embedded_storage_async::nor_flash::NorFlashErrorKind::Other
        }
    }
}

/// [`StoreFlashError`]'s value for an address outside the store.
const OUT_OF_STORE: u32 = u32::MAX;
/// FLASH_KEYR's unlock sequence (RM0090 §3.6.1).
const FLASH_KEYS: [u32; 2] = [0x4567_0123, 0xCDEF_89AB];
/// FLASH_SR's error flags: PGSERR (7), PGPERR (6), PGAERR (5), WRPERR (4), OPERR (1).
const FLASH_SR_ERRORS: u32 = 0b1111_0010;
/// FLASH_CR.PSIZE for x32 parallelism (RM0090 §3.9.5).
const PSIZE_X32: u8 = 0b10;
/// Bytes of a store sector.
const SECTOR_BYTES: u32 = STORE_BYTES / STORE_SECTORS.len() as u32;

impl StoreFlash {
    fn new(flash: pac::FLASH) -> Self {
        StoreFlash { flash }
    }

    fn unlock(&mut self) {
        if self.flash.cr().read().lock().bit_is_set() {
            for key in FLASH_KEYS {
                self.flash.keyr().write(|w| unsafe { w.key().bits(key) });
            }
        }
    }

    /// Waits for the operation to end; its error flags (cleared), locked again.
    fn finish(&mut self) -> Result<(), StoreFlashError> {
        while self.flash.sr().read().bsy().bit_is_set() {}
        let errors = self.flash.sr().read().bits() & FLASH_SR_ERRORS;
        // rc_w1 flags: writing 1 clears them (EOP too).
        self.flash.sr().write(|w| unsafe { w.bits(errors | 1) });
        self.flash
            .cr()
            .modify(|_, w| w.ser().clear_bit().pg().clear_bit());
        if errors != 0 {
            return Err(StoreFlashError(errors));
        }
        Ok(())
    }

    fn lock(&mut self) {
        self.flash.cr().modify(|_, w| w.lock().set_bit());
        // The data cache may hold lines of what was just erased or programmed.
        self.flash.acr().modify(|_, w| w.dcen().clear_bit());
        self.flash.acr().modify(|_, w| w.dcrst().set_bit());
        self.flash.acr().modify(|_, w| w.dcrst().clear_bit());
        self.flash.acr().modify(|_, w| w.dcen().set_bit());
    }

    fn check(offset: u32, len: usize, unit: u32) -> Result<(), StoreFlashError> {
        let end = offset
            .checked_add(len as u32)
            .ok_or(StoreFlashError(OUT_OF_STORE))?;
        if end > STORE_BYTES || !offset.is_multiple_of(unit) || !(len as u32).is_multiple_of(unit) {
            return Err(StoreFlashError(OUT_OF_STORE));
        }
        Ok(())
    }
}

impl embedded_storage_async::nor_flash::ErrorType for StoreFlash {
    type Error = StoreFlashError;
}

impl embedded_storage_async::nor_flash::ReadNorFlash for StoreFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), StoreFlashError> {
        Self::check(offset, bytes.len(), 1)?;
        for (i, b) in bytes.iter_mut().enumerate() {
            let at = (STORE_ADDRESS + offset) as usize + i;
            // SAFETY: inside the store's sectors (checked above), which no code or data uses.
            *b = unsafe { core::ptr::read_volatile(at as *const u8) };
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        STORE_BYTES as usize
    }
}

impl embedded_storage_async::nor_flash::NorFlash for StoreFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = SECTOR_BYTES as usize;

    /// Sector erase (RM0090 §3.6.3): SER, SNB, PSIZE, then STRT; BSY until done.
    async fn erase(&mut self, from: u32, to: u32) -> Result<(), StoreFlashError> {
        let len = to.checked_sub(from).ok_or(StoreFlashError(OUT_OF_STORE))?;
        Self::check(from, len as usize, SECTOR_BYTES)?;
        self.unlock();
        let mut result = Ok(());
        for k in (from / SECTOR_BYTES)..(to / SECTOR_BYTES) {
            let snb = STORE_SECTORS[k as usize];
            self.flash.cr().modify(|_, w| unsafe {
                w.psize().bits(PSIZE_X32).ser().set_bit().snb().bits(snb)
            });
            self.flash.cr().modify(|_, w| w.strt().set_bit());
            result = self.finish();
            if result.is_err() {
                break;
            }
        }
        self.lock();
        result
    }

    /// Word programming (RM0090 §3.6.4): PG and PSIZE x32, one 32-bit write per word; BSY
    /// until done.
    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), StoreFlashError> {
        Self::check(offset, bytes.len(), 4)?;
        self.unlock();
        let mut result = Ok(());
        for (k, word) in bytes.chunks_exact(4).enumerate() {
            self.flash
                .cr()
                .modify(|_, w| unsafe { w.psize().bits(PSIZE_X32).pg().set_bit() });
            let at = STORE_ADDRESS + offset + 4 * k as u32;
            let value = u32::from_le_bytes([word[0], word[1], word[2], word[3]]);
            // SAFETY: a word inside the store's sectors (checked above), programmed as RM0090
            // §3.6.4 says, with PG set.
            unsafe { core::ptr::write_volatile(at as *mut u32, value) };
            result = self.finish();
            if result.is_err() {
                break;
            }
        }
        self.lock();
        result
    }
}

/// The flash allows a word written again with bits cleared only (RM0090 §3.6.4).
impl embedded_storage_async::nor_flash::MultiwriteNorFlash for StoreFlash {}

//! The emulator board: the rig image's peripherals as QEMU 7.2's `netduinoplus2` (STM32F405,
//! the F407's memory map) provides them, with stand-ins for what it lacks. Everything else —
//! the RTIC app, its tasks and priorities, the console service, TIM2 at 10 kHz, USART2 — is
//! the rig image's (`app.rs`).
//!
//! What differs from the rig board (`board_rig.rs`), and why:
//! - clocks: QEMU has no RCC (the HAL's `freeze` waits forever for the HSE); its timers count a
//!   fixed 1 GHz, so TIM2/TIM3/TIM5 are set up for that, with registers, no prescaler;
//! - ADC: QEMU converts on software start only (no timer trigger, no end-of-conversion flag or
//!   interrupt) and returns a synthetic sawtooth (+7 codes per read); the HAL's set-up reads
//!   factory calibration QEMU does not have. So a TIM2 interrupt starts ADC1 and pends the ADC
//!   interrupt, which runs the same sampling task;
//! - capture: no DMA in QEMU: a TIM3 interrupt at 100 kHz reads ADC2 into a queue and pends the
//!   DMA interrupt every 64 samples, which runs the same capture task;
//! - DAC: not modelled: the code is kept for `emu dac`;
//! - watchdog: not modelled: a stand-in, checked by the report task, prints `watchdog: … reset`
//!   and ends the emulation where the IWDG would reset the MCU (not fed for 2 s). It needs the
//!   report task alive (a real IWDG also resets a hung CPU), and it does not reboot: after a
//!   reset QEMU's timer model restarts its tick offset at the reset time, which would stretch
//!   every timer period by that time;
//! - USART2 ready: QEMU drops what reaches the UART before it is enabled, so the image prints
//!   `console: USART2 ready` (semihosting) once it is, and a desktop writes only after that;
//! - USART2 transmit: QEMU sends a byte synchronously and raises no transmit-empty interrupt,
//!   so the UART interrupt is pended in software while bytes wait;
//! - test hooks on the console, answered before the console service: `emu stall` (TIM2 stops:
//!   sampling stalls), `emu dac` (the last DAC code), `emu adc <code>` (the force ADC reads
//!   this code instead of QEMU's sawtooth; `emu adc off` gives the sawtooth back), `emu overflow`
//!   (recursion until the stack overflows).

use core::sync::atomic::{AtomicU16, AtomicU32, Ordering};

use cortex_m::peripheral::NVIC;
use cortex_m_semihosting::hprintln;
use heapless::spsc::{Consumer, Producer, Queue};
use shared::console::{Board, RxError};
use shared::control::config::DAC_MID;
use shared::hal::{DriveOutput, ForceSource, SampleError};
use stm32f4xx_hal::pac::{self, Interrupt, interrupt};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::serial::Serial;

use rig_firmware::board_common::{Adc1, BoardParts, Micros64, console_usart, read_byte};
use rig_firmware::config::{CAPTURE_BLOCK, STORE_BYTES, WATCHDOG_MS};

/// Which image this is (`id`).
pub const BOARD: Board = Board::Emulator;

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

/// The settings store's flash on the emulator: RAM, as QEMU's board emulates no flash
/// controller. It lies past the 128 KiB of SRAM the image uses (`memory.x`), at 0x2002_0000:
/// QEMU's STM32F405 maps 192 KiB of SRAM there in one block (and no CCM RAM), and no section of
/// the image names it, so QEMU's system reset (which reloads the image's sections) leaves it as
/// it was: a `save` survives a `reset` as on the board. A marker word after it says it was set
/// up (at QEMU's start the RAM reads zero: erased then). The same geometry as the board's (two
/// 16 KiB pages, 32-bit words); no stall on writes.
pub type StoreFlash = shared::store::ram_flash::RamFlash<&'static mut [u8]>;

/// Where the emulator's store lies: QEMU's SRAM past the image's 128 KiB.
const QEMU_STORE: usize = 0x2002_0000;
/// The marker after the store: its bytes were erased once.
const STORE_MARKER: u32 = 0x5e77_1295;

/// The emulator's store, erased the first time after QEMU starts.
fn store_flash() -> StoreFlash {
    let len = STORE_BYTES as usize;
    let marker = (QEMU_STORE + len) as *mut u32;
    // SAFETY: QEMU's netduinoplus2 maps SRAM up to 0x2002_FFFF, no section of this image is
    // placed past 0x2001_FFFF (`memory.x`), and this is its only user, made once in `init`.
    let bytes = unsafe {
        if core::ptr::read_volatile(marker) != STORE_MARKER {
            core::ptr::write_bytes(QEMU_STORE as *mut u8, 0xff, len);
            core::ptr::write_volatile(marker, STORE_MARKER);
        }
        core::slice::from_raw_parts_mut(QEMU_STORE as *mut u8, len)
    };
    shared::store::ram_flash::RamFlash::new(bytes)
}

/// QEMU's timer clock: 1 GHz whatever the RCC, and a period of `ARR` ticks as long as the
/// prescaler and counter are never written (its model adds the tick offset of those writes to
/// every period).
const TIMER_CLOCK_HZ: u32 = 1_000_000_000;
/// NVIC priority of the stand-in interrupts (logical 5: above every RTIC task, as hardware
/// triggers are).
const STANDIN_PRIORITY: u8 = (16 - 5) << 4;

/// Capture samples between the TIM3 stand-in and the capture task.
const CAPTURE_QUEUE: usize = 4 * CAPTURE_BLOCK;
static mut CAPTURE_Q: Queue<u16, CAPTURE_QUEUE> = Queue::new();
static mut CAPTURE_TX: Option<Producer<'static, u16>> = None;
/// Capture samples the full queue could not take (lost, as a late DMA block on the rig).
static CAPTURE_DROPPED: AtomicU32 = AtomicU32::new(0);
static DAC_CODE: AtomicU16 = AtomicU16::new(DAC_MID);
/// The code `emu adc` holds the force ADC at ([`ADC_FREE`]: QEMU's sawtooth).
static ADC_HOLD: AtomicU16 = AtomicU16::new(ADC_FREE);
/// No code held.
const ADC_FREE: u16 = u16::MAX;

/// Sets up the emulated board.
pub fn init(
    dp: pac::Peripherals,
    nvic: &mut NVIC,
    _bufs: &'static mut [[u16; CAPTURE_BLOCK]; 2],
) -> Parts {
    // No clock set-up: QEMU does not model the RCC.
    let mut rcc = dp.RCC.constrain();
    let gpioa = dp.GPIOA.split(&mut rcc);

    // ADC1 and ADC2 on, 12-bit (QEMU: no calibration, software start only).
    dp.ADC1.cr2().write(|w| w.adon().set_bit());
    dp.ADC2.cr2().write(|w| w.adon().set_bit());

    // TIM5: a free-running 32-bit µs counter (1 GHz / 1000).
    dp.TIM5
        .psc()
        .write(|w| w.psc().set((TIMER_CLOCK_HZ / 1_000_000 - 1) as u16));
    dp.TIM5.arr().write(|w| unsafe { w.bits(u32::MAX) });
    dp.TIM5.cr1().write(|w| w.cen().set_bit());

    // TIM2 (10 kHz) starts in `SamplingTrigger::start`, once interrupts are on.

    let usart = console_usart(dp.USART2, (gpioa.pa2, gpioa.pa3), &mut rcc);
    // QEMU drops what reaches USART2 before it is enabled: a desktop waits for this line
    // (semihosting, QEMU's stdout) before it writes to the pty.
    hprintln!("console: USART2 ready");

    // The capture queue: the TIM3 stand-in produces, the capture task consumes.
    // SAFETY: split once here, before the interrupts that use the halves are enabled.
    let (tx, rx) = unsafe { (*core::ptr::addr_of_mut!(CAPTURE_Q)).split() };
    // SAFETY: written once before TIM3's interrupt is enabled; afterwards only TIM3 uses it.
    unsafe { *core::ptr::addr_of_mut!(CAPTURE_TX) = Some(tx) };

    // SAFETY: priorities set before the interrupts are unmasked; TIM2/TIM3 touch no RTIC
    // resource.
    unsafe {
        nvic.set_priority(Interrupt::TIM2, STANDIN_PRIORITY);
        nvic.set_priority(Interrupt::TIM3, STANDIN_PRIORITY);
        NVIC::unmask(Interrupt::TIM2);
        NVIC::unmask(Interrupt::TIM3);
    }
    let _ = dp.DAC;
    BoardParts {
        adc: ForceAdc,
        dac: DacDrive,
        clock: MicrosClock::default(),
        serial: ConsoleSerial {
            usart,
            txing: false,
        },
        capture: CaptureInput { rx },
        watchdog: Watchdog { last_feed_ms: 0 },
        trigger: SamplingTrigger,
        store: store_flash(),
    }
}

/// Before a `reset`: the stand-in timers stopped (QEMU's STM32 timer model keeps running
/// through a system reset, and the restarted image's timers then run at the wrong pace).
pub fn before_reset() {
    // SAFETY: TIM2 and TIM3 are the stand-ins' own; the board restarts right after.
    unsafe {
        (*pac::TIM2::ptr()).cr1().write(|w| w.bits(0));
        (*pac::TIM2::ptr()).dier().write(|w| w.bits(0));
        (*pac::TIM3::ptr()).cr1().write(|w| w.bits(0));
        (*pac::TIM3::ptr()).dier().write(|w| w.bits(0));
    }
}

/// ADC1's trigger: the TIM2 stand-in.
pub struct SamplingTrigger;

impl SamplingTrigger {
    /// Starts TIM2's 10 kHz update interrupt (the rig's order: once interrupts are on). The
    /// interrupt and the counter are enabled before ARR, whose write arms QEMU's timer (at
    /// 1 GHz, ARR ticks per period).
    pub fn start(&mut self) {
        // SAFETY: TIM2 is the sampling trigger, this its only set-up.
        let t = unsafe { &*pac::TIM2::ptr() };
        let arr = TIMER_CLOCK_HZ / shared::control::SAMPLE_RATE_HZ;
        t.dier().write(|w| w.uie().set_bit());
        t.cr1().write(|w| w.cen().set_bit());
        t.arr().write(|w| unsafe { w.bits(arr) });
    }
}

/// TIM2 stand-in for the hardware trigger: start ADC1, raise the end-of-conversion interrupt.
#[interrupt]
fn TIM2() {
    // SAFETY: TIM2's status register (clear the update flag) and ADC1's start bit; the app
    // does not touch TIM2, and ADC1 only through `ForceAdc`'s data-register read.
    unsafe {
        (*pac::TIM2::ptr()).sr().write(|w| w.bits(!1));
        (*pac::ADC1::ptr())
            .cr2()
            .modify(|_, w| w.swstart().set_bit());
    }
    NVIC::pend(Interrupt::ADC);
}

/// TIM3 stand-in for the capture DMA: one ADC2 sample per 10 µs into the queue, the DMA
/// interrupt every block.
#[interrupt]
fn TIM3() {
    // SAFETY: TIM3's status register; ADC2 belongs to the capture (QEMU converts on the
    // data-register read after a software start).
    let code = unsafe {
        (*pac::TIM3::ptr()).sr().write(|w| w.bits(!1));
        let adc = &*pac::ADC2::ptr();
        adc.cr2().modify(|_, w| w.swstart().set_bit());
        (adc.dr().read().bits() & 0x0FFF) as u16
    };
    // SAFETY: only this interrupt uses the producer after `init`.
    if let Some(tx) = unsafe { (*core::ptr::addr_of_mut!(CAPTURE_TX)).as_mut() } {
        if tx.enqueue(code).is_err() {
            CAPTURE_DROPPED.fetch_add(1, Ordering::Relaxed);
        }
        if tx.len() >= CAPTURE_BLOCK {
            NVIC::pend(Interrupt::DMA2_STREAM2);
        }
    }
}

/// The force sensor on ADC1: the conversion the TIM2 stand-in started.
pub struct ForceAdc;

impl ForceSource for ForceAdc {
    fn read_code(&mut self) -> Result<u16, SampleError> {
        // The rig's procedure (QEMU never sets OVR).
        let code = shared::adc_status::read_conversion(&mut Adc1)?;
        match ADC_HOLD.load(Ordering::Relaxed) {
            ADC_FREE => Ok(code),
            held => Ok(held),
        }
    }
}

/// The drive: QEMU has no DAC, the code is kept (`emu dac`).
pub struct DacDrive;

impl DriveOutput for DacDrive {
    fn write_code(&mut self, code: u16) {
        DAC_CODE.store(code.min(shared::hal::ADC_MAX), Ordering::Relaxed);
    }
}

/// µs since start-up from TIM5 (32-bit, extended to 64 bits at every read).
#[derive(Default)]
pub struct MicrosClock {
    count: Micros64,
}

impl MicrosClock {
    /// Now, µs.
    pub fn now_us(&mut self) -> u64 {
        // SAFETY: a read of TIM5's counter, which only this clock uses.
        let now = unsafe { (*pac::TIM5::ptr()).cnt().read().bits() };
        self.count.extend(now)
    }
}

/// USART2.
pub struct ConsoleSerial {
    usart: Serial<pac::USART2>,
    txing: bool,
}

impl ConsoleSerial {
    /// A received byte, a receive error, or `None`.
    pub fn read(&mut self) -> Option<Result<u8, RxError>> {
        read_byte(&mut self.usart)
    }

    /// Whether a byte may be written (and one is being sent).
    pub fn tx_ready(&self) -> bool {
        self.txing
    }

    /// Writes a byte (QEMU sends it at once).
    pub fn write(&mut self, byte: u8) {
        use embedded_hal_nb::serial::Write as _;
        let _ = self.usart.write(byte);
    }

    /// More bytes may follow: QEMU raises no transmit-empty interrupt, pend the UART's.
    pub fn more_tx(&mut self) {
        NVIC::pend(Interrupt::USART2);
    }

    /// Nothing left to send.
    pub fn stop_tx(&mut self) {
        self.txing = false;
    }

    /// Bytes were queued: start sending.
    pub fn kick_tx(&mut self) {
        self.txing = true;
        NVIC::pend(Interrupt::USART2);
    }
}

/// ADC2 at the capture rate (the TIM3 stand-in).
pub struct CaptureInput {
    rx: Consumer<'static, u16>,
}

impl CaptureInput {
    /// Starts sampling, if it is not running: samples queued from an earlier capture are
    /// dropped first (as the rig re-arms its DMA stream). While running, it does nothing.
    pub fn start(&mut self) {
        // SAFETY: TIM3 belongs to the capture.
        let t = unsafe { &*pac::TIM3::ptr() };
        if t.cr1().read().cen().bit_is_clear() {
            // TIM3's interrupt is off: the queue has no producer now.
            while self.rx.dequeue().is_some() {}
            CAPTURE_DROPPED.store(0, Ordering::Relaxed);
            t.dier().write(|w| w.uie().set_bit());
            t.cr1().write(|w| w.cen().set_bit());
            t.arr()
                .write(|w| unsafe { w.bits(TIMER_CLOCK_HZ / shared::capture::CAPTURE_RATE_HZ) });
        }
    }

    /// Stops sampling.
    pub fn stop(&mut self) {
        // SAFETY: TIM3 belongs to the capture.
        let t = unsafe { &*pac::TIM3::ptr() };
        t.dier().write(|w| w.uie().clear_bit());
        t.cr1().write(|w| w.cen().clear_bit());
    }

    /// A new capture was armed: its sampling starts afresh.
    pub fn restart(&mut self) {
        self.stop();
        self.start();
    }

    /// Hands the samples dropped since the last call (the queue was full) and those queued
    /// so far (up to a block) to `f`. (The dropped samples came after some of the queued ones:
    /// the emulator counts them but does not keep their place, as the rig's DMA does.)
    pub fn take_block(&mut self, f: impl FnOnce(u32, &[u16])) {
        let mut block = [0u16; CAPTURE_BLOCK];
        let mut n = 0;
        while n < CAPTURE_BLOCK {
            let Some(c) = self.rx.dequeue() else { break };
            if let Some(slot) = block.get_mut(n) {
                *slot = c;
            }
            n += 1;
        }
        let lost = CAPTURE_DROPPED.swap(0, Ordering::Relaxed);
        f(lost, block.get(..n).unwrap_or(&[]));
    }
}

/// The watchdog stand-in: ends the emulation where the IWDG would reset the MCU (not fed for
/// [`WATCHDOG_MS`]).
pub struct Watchdog {
    last_feed_ms: u32,
}

impl Watchdog {
    /// Feeds it.
    pub fn feed(&mut self, now_ms: u32) {
        self.last_feed_ms = now_ms;
    }

    /// Ends the emulation if it was not fed in time (the IWDG resets the MCU on the rig).
    pub fn check(&mut self, now_ms: u32) {
        let starved = now_ms.wrapping_sub(self.last_feed_ms);
        if starved >= WATCHDOG_MS {
            hprintln!(
                "watchdog: reset, not fed for {} ms: last_feed_ms={} now_ms={}",
                starved,
                self.last_feed_ms,
                now_ms
            );
            hold_for_host();
            cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
        }
    }
}

/// QEMU's own time to wait before the emulation ends, centiseconds.
const HOLD_CS: usize = 100;

/// Holds the emulation's end for [`HOLD_CS`] of QEMU's processor time, so that the desktop has
/// read what the board sent before it. While the board idles, its time runs far ahead of the
/// host's (`-icount sleep=off`): the second between the last lines and the reset can pass in a
/// millisecond, and a pty drops what is unread when QEMU closes it (on the rig the reset waits
/// its own second).
fn hold_for_host() {
    let clock_cs = || {
        // SAFETY: SYS_CLOCK takes no argument and only reads the host's clock.
        unsafe { cortex_m_semihosting::syscall1(cortex_m_semihosting::nr::CLOCK, 0) }
    };
    let start = clock_cs();
    while clock_cs().wrapping_sub(start) < HOLD_CS {}
}

/// The emulator's test hooks (`emu …` lines), answered before the console service.
pub fn hook(line: &str, now_ms: u32) -> Option<heapless::String<96>> {
    use core::fmt::Write as _;
    let mut out = heapless::String::new();
    let words = line.trim();
    if words == "emu stall" {
        // SAFETY: TIM2 is the sampling trigger; stopping its interrupt stalls the sampling.
        unsafe { (*pac::TIM2::ptr()).dier().write(|w| w.uie().clear_bit()) };
        let _ = write!(out, "ok sampling stalled at uptime_ms={now_ms}");
    } else if let Some(arg) = words.strip_prefix("emu adc ") {
        let held = match arg.trim() {
            "off" => Some(ADC_FREE),
            n => n.parse::<u16>().ok().filter(|&c| c <= shared::hal::ADC_MAX),
        };
        match held {
            Some(c) => {
                ADC_HOLD.store(c, Ordering::Relaxed);
                let _ = write!(out, "ok adc {}", arg.trim());
            }
            None => {
                let _ = write!(out, "error: emu adc takes a code 0 ..= 4095 or off");
            }
        }
    } else if words == "emu dac" {
        let _ = write!(out, "dac_code={}", DAC_CODE.load(Ordering::Relaxed));
    } else if words == "emu overflow" {
        let depth = overflow(0);
        let _ = write!(out, "error: the stack did not overflow ({depth})");
    } else {
        return None;
    }
    Some(out)
}

/// Recurses with 1 KiB frames until the stack runs out.
#[inline(never)]
fn overflow(depth: u32) -> u32 {
    let mut frame = [0u8; 1024];
    frame[0] = depth as u8;
    let frame = core::hint::black_box(&mut frame);
    if depth > 1_000_000 {
        return depth;
    }
    overflow(depth + 1).wrapping_add(u32::from(frame[0]))
}

/// The emulator's panic: printed on QEMU's stdout, QEMU exits with a failure.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

/// A HardFault (e.g. the stack overflowing into the unmapped space below RAM, with flip-link):
/// printed, and QEMU exits with a failure.
#[cortex_m_rt::exception]
unsafe fn HardFault(ef: &cortex_m_rt::ExceptionFrame) -> ! {
    hprintln!("HardFault at pc=0x{:08x}", ef.pc());
    cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

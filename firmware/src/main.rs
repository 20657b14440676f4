//! Firmware of the vibro-impact rig: an RTIC 2 application for the STM32F407 (Cortex-M4F,
//! 168 MHz). Thin glue around `shared::control::Controller`:
//!
//! | task            | trigger                     | priority | does                                         |
//! |-----------------|-----------------------------|----------|----------------------------------------------|
//! | `sample`        | TIM2 update, 10 kHz         | 3        | ADC1 → `Controller::on_sample` → DAC1        |
//! | `console`       | USART2 RX                   | 2        | bytes → lines → `parse` → `execute` → reply  |
//! | `report`        | every 10,000 samples (1 s)  | 2        | logs events + status, feeds the watchdog     |
//! | `model`         | start-up, `rig`/`gap`/`tune`| 1        | `shared::control::predict` (the selection)   |
//!
//! Wiring, console commands and faults: README, "Firmware".
//! Build: `cargo fw-build`; flash and watch the defmt log: `cargo fw` (probe-rs).
//! On the host this crate compiles to a stub so that `cargo build --workspace` works.
#![cfg_attr(target_os = "none", no_std, no_main)]

/// Configuration of the rig this board drives at power-up (the console changes rig and gap).
pub mod config {
    use shared::model::RigId;

    /// The rig at power-up.
    pub const RIG: RigId = RigId::Wires;
    /// The gap at power-up, mm (field use: 0.0 mm).
    pub const GAP_MM: f32 = 0.0;
    /// Core clock, Hz.
    pub const SYSCLK_HZ: u32 = 168_000_000;
    /// Independent watchdog timeout, ms.
    pub const WATCHDOG_MS: u32 = 2_000;
}

#[cfg(target_os = "none")]
mod board;

#[cfg(target_os = "none")]
#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true, dispatchers = [EXTI0, EXTI1])]
mod app {
    use core::fmt::Write as _;

    use defmt_rtt as _;
    use panic_probe as _;
    use shared::control::{
        Controller, ControllerConfig, Event, LineBuffer, SAMPLE_RATE_HZ, predict, respond,
    };
    use shared::hal::{DriveOutput, ForceSource, TimeBase};
    use stm32f4xx_hal::{
        adc::{Adc, config::AdcConfig},
        pac,
        prelude::*,
        rcc::Config,
        serial::{self, Rx, Serial, Tx},
        timer::{CounterHz, Event as TimerEvent, Flag},
        watchdog::IndependentWatchdog,
    };

    use crate::board::{CycleClock, DacDrive, ForceAdc};
    use crate::config::{GAP_MM, RIG, SYSCLK_HZ, WATCHDOG_MS};

    /// Longest console reply (the status line is about 250 characters); longer is cut.
    const REPLY_CAPACITY: usize = 384;

    #[shared]
    struct Shared {
        controller: Controller,
    }

    #[local]
    struct Local {
        timer: CounterHz<pac::TIM2>,
        adc: ForceAdc,
        dac: DacDrive,
        clock: CycleClock,
        rx: Rx<pac::USART2>,
        tx: Tx<pac::USART2>,
        line: LineBuffer,
        watchdog: IndependentWatchdog,
        last_samples: u64,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let dp = cx.device;
        let mut rcc = dp.RCC.freeze(Config::hse(8.MHz()).sysclk(SYSCLK_HZ.Hz()));
        let gpioa = dp.GPIOA.split(&mut rcc);

        let adc = Adc::new(dp.ADC1, true, AdcConfig::default(), &mut rcc);
        let adc = ForceAdc::new(adc, gpioa.pa1.into_analog());
        let dac = DacDrive::new(dp.DAC, gpioa.pa4.into_analog(), &mut rcc);

        let serial_config = serial::Config::default().baudrate(115_200.bps());
        let (tx, mut rx) =
            match Serial::new(dp.USART2, (gpioa.pa2, gpioa.pa3), serial_config, &mut rcc) {
                Ok(s) => s.split(),
                Err(_) => defmt::panic!("USART2 configuration rejected"),
            };
        rx.listen();

        let controller = match Controller::new(ControllerConfig::default(), RIG, GAP_MM) {
            Ok(c) => c,
            Err(_) => defmt::panic!("the built-in controller configuration is invalid"),
        };

        let mut watchdog = IndependentWatchdog::new(dp.IWDG);
        watchdog.start(WATCHDOG_MS.millis());

        let mut timer = dp.TIM2.counter_hz(&mut rcc);
        if timer.start(SAMPLE_RATE_HZ.Hz()).is_err() {
            defmt::panic!("TIM2 cannot run at {=u32} Hz", SAMPLE_RATE_HZ);
        }
        timer.listen(TimerEvent::Update);

        let mut core = cx.core;
        let clock = CycleClock::new(&mut core.DCB, core.DWT, SYSCLK_HZ);

        defmt::info!(
            "vibro-impact rig firmware: rig {=str}, gap {=f32} mm, sampling at {=u32} Hz",
            RIG.name(),
            GAP_MM,
            SAMPLE_RATE_HZ
        );
        model::spawn().ok();
        (
            Shared { controller },
            Local {
                timer,
                adc,
                dac,
                clock,
                rx,
                tx,
                line: LineBuffer::default(),
                watchdog,
                last_samples: 0,
            },
        )
    }

    #[idle]
    fn idle(_cx: idle::Context) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// The sampling task: one force sample in, one drive sample out, every 100 µs.
    #[task(
        binds = TIM2,
        priority = 3,
        shared = [controller],
        local = [timer, adc, dac, clock, until_report: u32 = SAMPLE_RATE_HZ]
    )]
    fn sample(mut cx: sample::Context) {
        cx.local.timer.clear_flags(Flag::Update);
        let code = cx.local.adc.read_code();
        cx.local.clock.tick();
        let now_us = cx.local.clock.now_us();
        let out = cx.shared.controller.lock(|c| c.on_sample(code, now_us));
        cx.local.dac.write_code(out);
        // A report every SAMPLE_RATE_HZ samples (1 s), counted down without a division.
        *cx.local.until_report -= 1;
        if *cx.local.until_report == 0 {
            *cx.local.until_report = SAMPLE_RATE_HZ;
            report::spawn().ok();
        }
    }

    /// The console: collects bytes into lines, runs each command, answers one line.
    #[task(binds = USART2, priority = 2, shared = [controller], local = [rx, tx, line])]
    fn console(mut cx: console::Context) {
        while let Ok(byte) = cx.local.rx.read() {
            let Some(line) = cx.local.line.push(byte) else {
                continue;
            };
            // Format under the lock (microseconds), send after it: a blocking UART write inside
            // the lock would hold off the sampling task for milliseconds.
            let mut reply: heapless::String<REPLY_CAPACITY> = heapless::String::new();
            let model_needed = cx.shared.controller.lock(|c| {
                respond(c, line, &mut reply).ok();
                c.model_request_open()
            });
            let tx = &mut *cx.local.tx;
            tx.write_str(&reply).ok();
            tx.write_str("\r\n").ok();
            if model_needed {
                model::spawn().ok();
            }
        }
    }

    /// Once a second: logs what happened, the status line, and feeds the watchdog while the
    /// sampling task keeps its rate.
    #[task(priority = 2, shared = [controller], local = [watchdog, last_samples])]
    async fn report(mut cx: report::Context) {
        let (status, samples, model_needed) = cx
            .shared
            .controller
            .lock(|c| (c.status(), c.samples(), c.model_request_open()));
        while let Some(event) = cx.shared.controller.lock(|c| c.pop_event()) {
            match event {
                Event::State { from, to } => {
                    defmt::info!("state {=str} -> {=str}", from.as_str(), to.as_str())
                }
                Event::Fault(f) => defmt::error!("FAULT {=str}: drive ramping to zero", f.as_str()),
                Event::ModelReady(p) => defmt::info!(
                    "model: target {=f32} Hz, 1/1 band {=f32}..{=f32} Hz, F_i/mg {=f32}",
                    p.target_hz,
                    p.band_hz[0],
                    p.band_hz[1],
                    p.impact_force_mg
                ),
                Event::ModelFailed => defmt::warn!("model: no robust 1/1 target"),
            }
        }
        defmt::info!("{}", defmt::Display2Format(&status));
        // Healthy: at least 90 % of the expected samples since the last report.
        let done = samples.wrapping_sub(*cx.local.last_samples);
        *cx.local.last_samples = samples;
        if done >= u64::from(SAMPLE_RATE_HZ) * 9 / 10 {
            cx.local.watchdog.feed();
        } else {
            defmt::error!(
                "sampling stalled ({=u64} samples in 1 s): not feeding the watchdog",
                done
            );
        }
        if model_needed {
            model::spawn().ok();
        }
    }

    /// The model: runs the on-target selection for every open request (lowest priority, so
    /// sampling and the console preempt it).
    #[task(priority = 1, shared = [controller])]
    async fn model(mut cx: model::Context) {
        while let Some(req) = cx.shared.controller.lock(|c| c.take_model_request()) {
            defmt::info!(
                "model: computing rig {=str} gap {=f32} mm",
                req.rig.name(),
                req.gap_mm
            );
            let result = predict(req.rig, req.gap_mm);
            cx.shared
                .controller
                .lock(|c| c.set_prediction(req.generation, result));
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "firmware for {} at {} mm gap: build it for the MCU with `cargo fw-build` (thumbv7em-none-eabihf)",
        config::RIG,
        config::GAP_MM
    );
}

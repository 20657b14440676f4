//! The RTIC application, the same source for the rig image (`firmware`, `src/main.rs`) and the
//! emulator image (`firmware-qemu`, `src/emulator.rs`): each binary brings its own
//! `board` module (the peripherals), and nothing here differs between them.
//!
//! | task      | trigger                                         | priority | does                                            |
//! |-----------|-------------------------------------------------|----------|-------------------------------------------------|
//! | `sample`  | ADC end of conversion (TIM2 TRGO starts it, 10 kHz) | 4    | ADC1 → `Controller::on_sample` → DAC1           |
//! | `console` | USART2 (byte received, transmit register empty) | 3        | bytes ↔ the link's queues                       |
//! | `capture` | DMA2 stream 2 (half of the capture buffer full, or a transfer error) | 3 | capture-rate samples → the segment store |
//! | `serve`   | woken by `console`, `sample`, `report`          | 2        | one reply per line; telemetry and event lines   |
//! | `report`  | every second on the SysTick monotonic           | 2        | health check and watchdog; the capture's stall check; the defmt status log |
//! | `start_sampling` | once, when interrupts come on after `init` | 2     | starts TIM2, ADC1's trigger                     |
//! | `model`   | start-up, a new model, `gap`, `tune`            | 1        | `shared::control::predict` (the selection) on the active model |
//!
//! The sampling task preempts everything, so nothing but a short lock delays a sample. The
//! capture task preempts the console service and the report, which format lines for longer
//! than a capture block lasts (0.64 ms); a block it serves late anyway is counted lost
//! (`shared::capture_dma`). The sampling starts only once interrupts are on: the first
//! conversion's end is served, instead of overrunning while `init` still runs.
//!
//! Nothing is formatted or sent under a lock that the sampling task needs for long: the console
//! service copies what it needs out of the controller, formats outside every lock, and queues
//! the text for the UART, which drains it from its interrupt.
//!
//! At power-up the board loads its settings (the rig model, gap and calibration) from the
//! store in flash (`shared::store`, sectors 1–2), or, when the store holds none it can use
//! (empty, corrupt, another version, refused by the controller's checks), runs the preset of
//! `config::RIG` at `config::GAP_MM` with the default calibration, and says why (`id`'s
//! `store=`, the defmt log). A `save` writes the flash from the console service: the CPU stalls
//! on the flash meanwhile, so the controller counts the late samples instead of faulting.

#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true, dispatchers = [EXTI0, EXTI1])]
mod app {
    use core::sync::atomic::{AtomicU32, Ordering};

    use defmt_rtt as _;
    use rtic::Mutex;
    use rtic_monotonics::systick::prelude::*;
    use rtic_sync::signal::{SignalReader, SignalWriter};
    use shared::capture::Capture;
    use shared::commission::{Commission, RigPieces};
    use shared::console::link::Link;
    use shared::console::serve::{
        AsyncText, ReplyText, RigAccess, answer, format_answer, format_async, next_commission_line,
        poll_commission, sent_commission_line, split_tag,
    };
    use shared::console::{BoardInfo, Token};
    use shared::control::{Controller, ControllerConfig, Event, Status, predict};
    use shared::hal::{DriveOutput, ForceSource};
    use shared::health::{Health, HealthCheck};
    use shared::observe::Regime;
    use shared::store::{SettingsStore, StartUp, Store, start_up};

    use crate::board;
    use rig_firmware::config::{
        CAPTURE_BLOCK, FIRMWARE_VERSION, GAP_MM, RIG, STORE_BYTES, SYSCLK_HZ,
    };

    systick_monotonic!(Mono, 1_000);

    /// Longest time between two sampling-task runs since start-up, µs (`diag`).
    static SAMPLE_GAP_MAX_US: AtomicU32 = AtomicU32::new(0);

    /// The console's link and its UART.
    pub struct Console {
        /// Lines in, replies and asynchronous lines out.
        pub link: Link,
        /// USART2.
        pub serial: board::ConsoleSerial,
    }

    /// The capture's segment store and its sampling input.
    pub struct CaptureRes {
        /// Segments.
        pub store: &'static mut Capture,
        /// ADC2 at the capture rate.
        pub input: board::CaptureInput,
    }

    #[shared]
    struct Shared {
        controller: Controller,
        console: Console,
        capture: CaptureRes,
        store: Store<board::StoreFlash>,
    }

    #[local]
    struct Local {
        adc: board::ForceAdc,
        dac: board::DacDrive,
        clock: board::MicrosClock,
        watchdog: board::Watchdog,
        trigger: board::SamplingTrigger,
        wake_from_sample: SignalWriter<'static, ()>,
        wake_from_console: SignalWriter<'static, ()>,
        wake_from_report: SignalWriter<'static, ()>,
        wake: SignalReader<'static, ()>,
    }

    fn uptime_ms() -> u32 {
        Mono::now().duration_since_epoch().to_millis()
    }

    fn board_info() -> BoardInfo {
        BoardInfo {
            firmware: FIRMWARE_VERSION,
            board: board::BOARD,
            uptime_ms: u64::from(uptime_ms()),
            stack_hwm_bytes: rig_firmware::stack::high_water_bytes(),
            stack_size_bytes: rig_firmware::stack::size_bytes(),
            sample_gap_max_us: SAMPLE_GAP_MAX_US.load(Ordering::Relaxed),
        }
    }

    #[init(local = [
        capture_store: Capture = Capture::new(),
        capture_bufs: [[u16; CAPTURE_BLOCK]; 2] = [[0; CAPTURE_BLOCK]; 2],
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        rig_firmware::stack::paint();
        let mut core = cx.core;
        let parts = board::init(cx.device, &mut core.NVIC, cx.local.capture_bufs);
        Mono::start(core.SYST, SYSCLK_HZ);
        let mut controller = match Controller::new(ControllerConfig::default(), RIG, GAP_MM) {
            Ok(c) => c,
            Err(_) => defmt::panic!("the built-in controller configuration is invalid"),
        };
        let mut store = match Store::new(parts.store, 0..STORE_BYTES) {
            Ok(s) => s,
            Err(_) => defmt::panic!("the settings store's range is not whole sectors"),
        };
        load_settings(&mut store, &mut controller);
        let (writer, reader) = rtic_sync::make_signal!(());
        defmt::info!(
            "vibro-impact rig firmware {=u16}.{=u16}.{=u16} ({=str} board): rig {=str} {=u32:08x}, gap {=f32} mm, sampling at {=u32} Hz",
            FIRMWARE_VERSION.major,
            FIRMWARE_VERSION.minor,
            FIRMWARE_VERSION.patch,
            board::BOARD.token(),
            controller.status().rig.source.token(),
            controller.status().rig.hash,
            controller.gap_mm(),
            shared::control::SAMPLE_RATE_HZ
        );
        start_sampling::spawn().ok();
        model::spawn().ok();
        serve::spawn().ok();
        report::spawn().ok();
        (
            Shared {
                controller,
                console: Console {
                    link: Link::new(),
                    serial: parts.serial,
                },
                capture: CaptureRes {
                    store: cx.local.capture_store,
                    input: parts.capture,
                },
                store,
            },
            Local {
                adc: parts.adc,
                dac: parts.dac,
                clock: parts.clock,
                watchdog: parts.watchdog,
                trigger: parts.trigger,
                wake_from_sample: writer.clone(),
                wake_from_console: writer.clone(),
                wake_from_report: writer,
                wake: reader,
            },
        )
    }

    /// The stored settings into the controller, or the preset it was made with, saying why.
    fn load_settings(store: &mut Store<board::StoreFlash>, controller: &mut Controller) {
        match start_up(store, controller) {
            StartUp::Stored { save } => defmt::info!(
                "settings: save {=u32} loaded: model {=u32:08x}, gap {=f32} mm",
                save,
                controller.status().rig.hash,
                controller.gap_mm()
            ),
            StartUp::Fallback {
                state,
                saves,
                field,
            } => defmt::warn!(
                "settings: store {=str} (save {=u32}{=str}{=str}): running the {=str} preset at {=f32} mm, default calibration",
                state.token(),
                saves,
                if field.is_some() {
                    ", refused field "
                } else {
                    ""
                },
                field.unwrap_or(""),
                RIG.name(),
                GAP_MM
            ),
        }
    }

    /// Starts ADC1's trigger once interrupts are on (they come on when `init` returns): the
    /// first end of conversion then runs the sampling task at once.
    #[task(priority = 2, local = [trigger])]
    async fn start_sampling(cx: start_sampling::Context) {
        cx.local.trigger.start();
    }

    #[idle]
    fn idle(_cx: idle::Context) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// The sampling task: one force sample in, one drive sample out, every 100 µs, on the ADC's
    /// end-of-conversion interrupt (the conversion itself is started by TIM2's trigger output).
    #[task(
        binds = ADC,
        priority = 4,
        shared = [controller],
        local = [adc, dac, clock, wake_from_sample, last_us: u64 = 0]
    )]
    fn sample(mut cx: sample::Context) {
        let code = cx.local.adc.read_code();
        let now_us = cx.local.clock.now_us();
        let last = core::mem::replace(cx.local.last_us, now_us);
        if last != 0 {
            let gap = u32::try_from(now_us.wrapping_sub(last)).unwrap_or(u32::MAX);
            SAMPLE_GAP_MAX_US.fetch_max(gap, Ordering::Relaxed);
        }
        let (out, news) = cx
            .shared
            .controller
            .lock(|c| (c.on_sample(code, now_us), c.async_pending()));
        cx.local.dac.write_code(out);
        if news {
            cx.local.wake_from_sample.write(());
        }
    }

    /// The UART: received bytes (and receive errors) into the link, the next queued byte out;
    /// every line's end feeds the controller's link-loss watchdog.
    #[task(binds = USART2, priority = 3, shared = [console, controller], local = [wake_from_console])]
    fn console(mut cx: console::Context) {
        let (ready, line_end) = cx.shared.console.lock(|con| {
            let mut line_end = false;
            while let Some(rx) = con.serial.read() {
                match rx {
                    Ok(byte) => line_end |= con.link.on_rx_byte(byte),
                    Err(e) => con.link.on_rx_error(e),
                }
            }
            if con.serial.tx_ready() {
                match con.link.pop_tx() {
                    Some(byte) => {
                        con.serial.write(byte);
                        con.serial.more_tx();
                    }
                    None => con.serial.stop_tx(),
                }
            }
            (con.link.ready(), line_end)
        });
        if line_end {
            cx.shared.controller.lock(Controller::link_alive);
        }
        if ready {
            cx.local.wake_from_console.write(());
        }
    }

    /// [`RigAccess`] over the console service's locks: each closure runs under its resource's
    /// lock only.
    struct Access<'a, C, K, L, S> {
        controller: &'a mut C,
        capture: &'a mut K,
        console: &'a mut L,
        store: &'a mut S,
        /// The service's own: no lock.
        commission: &'a mut Commission,
        reset: bool,
    }

    impl<C, K, L, S> RigPieces for Access<'_, C, K, L, S>
    where
        C: Mutex<T = Controller>,
        K: Mutex<T = CaptureRes>,
        L: Mutex<T = Console>,
        S: Mutex<T = Store<board::StoreFlash>>,
    {
        fn controller<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> R {
            self.controller.lock(f)
        }
        fn capture<R>(&mut self, f: impl FnOnce(&mut Capture) -> R) -> R {
            self.capture.lock(|c| f(c.store))
        }
        fn store<R>(&mut self, f: impl FnOnce(&mut dyn SettingsStore) -> R) -> R {
            // Only the console service takes the store: this lock blocks nothing else.
            self.store.lock(|s| f(s))
        }
    }

    impl<C, K, L, S> RigAccess for Access<'_, C, K, L, S>
    where
        C: Mutex<T = Controller>,
        K: Mutex<T = CaptureRes>,
        L: Mutex<T = Console>,
        S: Mutex<T = Store<board::StoreFlash>>,
    {
        fn board(&mut self) -> BoardInfo {
            board_info()
        }
        fn link<R>(&mut self, f: impl FnOnce(&mut Link) -> R) -> R {
            self.console.lock(|c| f(&mut c.link))
        }
        fn commission<R>(&mut self, f: impl FnOnce(&mut Commission) -> R) -> R {
            f(self.commission)
        }
        fn reset_after_reply(&mut self) {
            self.reset = true;
        }
    }

    /// The service's [`Access`] over its context `cx`.
    macro_rules! access {
        ($cx:ident) => {
            Access {
                controller: &mut $cx.shared.controller,
                capture: &mut $cx.shared.capture,
                console: &mut $cx.shared.console,
                store: &mut $cx.shared.store,
                commission: $cx.local.commission,
                reset: false,
            }
        };
    }

    /// The console service: answers every waiting line (one reply each), advances the
    /// commissioning sequence, then sends the asynchronous lines (the sequence's first); sleeps
    /// until woken again (a line, a record, the report's second).
    #[task(
        priority = 2,
        shared = [controller, console, capture, store],
        local = [wake, commission: Commission = Commission::new()]
    )]
    async fn serve(mut cx: serve::Context) {
        let mut reply = ReplyText::new();
        let mut line = AsyncText::new();
        loop {
            cx.local.wake.wait().await;
            loop {
                let Some(pending) = cx.shared.console.lock(|c| c.link.next_line()) else {
                    break;
                };
                let arms = cx.shared.capture.lock(|c| c.store.arm_count());
                // The board's test hooks see the line without its tag; their reply gets it back.
                let hooked = match pending.as_line() {
                    shared::console::Line::Text(t) => split_tag(t)
                        .ok()
                        .and_then(|(tag, rest)| Some((tag, board::hook(rest, uptime_ms())?))),
                    _ => None,
                };
                let mut reset = false;
                match hooked {
                    Some((tag, text)) => {
                        reply.clear();
                        if let Some(t) = tag {
                            let _ = core::fmt::Write::write_fmt(&mut reply, format_args!("#{t} "));
                        }
                        let _ = reply.push_str(&text);
                    }
                    None => {
                        let mut access = access!(cx);
                        let response = answer(&mut access, pending.as_line());
                        reset = access.reset;
                        format_answer(&response, &mut reply);
                    }
                }
                // A capture armed by this line: its sampling starts afresh, before anything else
                // can hand the new capture a block (a running capture's conversions are left
                // alone); a model request: start the model task.
                cx.shared.capture.lock(|c| {
                    if c.store.active() && c.store.arm_count() != arms {
                        c.input.restart();
                    }
                });
                send(&mut cx.shared.console, reply.as_bytes());
                if reset {
                    restart(&mut cx.shared.console).await;
                }
                if cx.shared.controller.lock(|c| c.model_request_open()) {
                    model::spawn().ok();
                }
            }
            // The commissioning sequence: its step advanced (a capture it armed starts its
            // sampling afresh, a model it applied starts the model task), its records sent.
            let arms = cx.shared.capture.lock(|c| c.store.arm_count());
            let mut access = access!(cx);
            poll_commission(&mut access);
            while next_commission_line(&mut access, &mut reply) {
                send(access.console, reply.as_bytes());
                sent_commission_line(&mut access);
            }
            cx.shared.capture.lock(|c| {
                if c.store.active() && c.store.arm_count() != arms {
                    c.input.restart();
                }
            });
            if cx.shared.controller.lock(|c| c.model_request_open()) {
                model::spawn().ok();
            }
            while let Some(rec) = cx.shared.controller.lock(|c| c.pop_async()) {
                if format_async(&rec, &mut line)
                    && cx.shared.console.lock(|c| c.link.reserve_async(line.len()))
                {
                    send(&mut cx.shared.console, line.as_bytes());
                }
            }
        }
    }

    /// `reset`: waits for the reply to leave the UART (at most 100 ms: 640 bytes take 56 ms at
    /// 115200 Bd), then restarts the board (AIRCR.SYSRESETREQ).
    async fn restart(console: &mut impl Mutex<T = Console>) {
        defmt::info!("reset: restarting at the console's request");
        for _ in 0..100 {
            if console.lock(|c| c.link.tx_free() == shared::console::link::TX_CAPACITY) {
                break;
            }
            Mono::delay(1.millis()).await;
        }
        // The last byte leaves the shift register in 87 µs.
        Mono::delay(2.millis()).await;
        board::before_reset();
        cortex_m::peripheral::SCB::sys_reset();
    }

    /// Bytes per lock when queueing text: the console's lock holds off the sampling task, so it
    /// is taken for short pieces (≈ 2 µs each on the rig), not for a whole 600-byte reply.
    const SEND_CHUNK: usize = 32;

    /// Queues a line (`\r\n` appended) in short pieces and starts the UART sending.
    fn send(console: &mut impl Mutex<T = Console>, text: &[u8]) {
        for piece in text.chunks(SEND_CHUNK).chain([&b"\r\n"[..]]) {
            console.lock(|c| {
                c.link.push_bytes(piece);
                c.serial.kick_tx();
            });
        }
    }

    /// The capture: a block of capture-rate samples into the segment store (after the samples
    /// lost before it, if any); its sampling stops when the capture ends.
    #[task(binds = DMA2_STREAM2, priority = 3, shared = [capture])]
    fn capture(mut cx: capture::Context) {
        cx.shared.capture.lock(serve_capture);
    }

    /// Serves the capture's input into its store.
    fn serve_capture(c: &mut CaptureRes) {
        let store = &mut *c.store;
        c.input.take_block(|lost, block| {
            store.skip(lost);
            store.push_block(block);
        });
        if !c.store.active() {
            c.input.stop();
        }
    }

    /// Once a second: the health check on the monotonic (samples taken against time elapsed)
    /// feeds the watchdog only while sampling keeps ≥ 90 % of its rate; a recording capture's
    /// input is served (a stalled stream raises no interrupt); events, lost capture samples and
    /// the status line to the defmt log.
    #[task(priority = 2, shared = [controller, capture], local = [watchdog, wake_from_report])]
    async fn report(mut cx: report::Context) {
        let mut health = HealthCheck::new();
        let mut lost_logged = 0;
        let mut next = Mono::now();
        loop {
            next += 1000.millis();
            Mono::delay_until(next).await;
            let now_ms = uptime_ms();
            let (status, samples, model_needed) = cx
                .shared
                .controller
                .lock(|c| (c.status(), c.samples(), c.model_request_open()));
            while let Some(event) = cx.shared.controller.lock(|c| c.pop_event()) {
                log_event(event);
            }
            match health.check(samples, now_ms) {
                Health::Feed => cx.local.watchdog.feed(now_ms),
                Health::Stalled { samples, expected } => {
                    defmt::error!(
                        "sampling stalled ({=u32} of {=u32} samples): not feeding the watchdog",
                        samples,
                        expected
                    );
                    cx.shared
                        .controller
                        .lock(|c| c.report_stall(samples, expected));
                    cx.local.wake_from_report.write(());
                }
            }
            cx.local.watchdog.check(now_ms);
            // A capture whose stream raises no interrupt (stalled) is served here: its loss is
            // counted and the stream re-armed, so the capture still ends at its time.
            let (armed, lost) = cx.shared.capture.lock(|c| {
                if c.store.active() {
                    serve_capture(c);
                }
                (c.store.arm_count(), c.store.lost_samples())
            });
            if lost != lost_logged {
                if lost > 0 {
                    defmt::warn!(
                        "capture {=u32}: {=u32} samples lost (blocks served late)",
                        armed,
                        lost
                    );
                }
                lost_logged = lost;
            }
            log_status(&status);
            if model_needed {
                model::spawn().ok();
            }
            // The console service's second: a commissioning step waits on time.
            cx.local.wake_from_report.write(());
        }
    }

    /// The status line in defmt's binary encoding (formatted on the host). Not
    /// `Display2Format`: defmt-rtt keeps interrupts off while it logs, and formatting the
    /// 250-character line there would delay the sampling task by ~100 µs.
    fn log_status(s: &Status) {
        let (p, q) = match s.regime {
            Some(Regime::Periodic { p, q }) => (p, q),
            _ => (0, 0),
        };
        defmt::info!(
            "status: {=str} rig {=str} {=u32:08x} gap {=f32} mm, drive {=f32} Hz {=f32} mm, regime {=u16}/{=u16}, peak {=f32} N, fault {=str}, impacts {=u32}, lost cycles {=u32}",
            s.state.token(),
            s.rig.source.token(),
            s.rig.hash,
            s.gap_mm,
            s.freq_hz,
            s.amplitude_mm,
            p,
            q,
            s.peak.map_or(0.0, |p| p.n),
            s.fault.map_or("none", |f| f.token()),
            s.impacts,
            s.lost_cycles
        );
    }

    fn log_event(event: Event) {
        match event {
            Event::State { from, to } => {
                defmt::info!("state {=str} -> {=str}", from.token(), to.token())
            }
            Event::Fault(f) => defmt::error!("FAULT {=str}: drive ramping to zero", f.token()),
            Event::ModelReady(p) => defmt::info!(
                "model: target {=f32} Hz, 1/1 band {=f32}..{=f32} Hz, F_i/mg {=f32}",
                p.target_hz,
                p.band_hz[0],
                p.band_hz[1],
                p.impact_force_mg
            ),
            Event::ModelFailed => defmt::warn!("model: no robust 1/1 target"),
            Event::SamplingStalled { samples, expected } => {
                defmt::error!("sampling stalled: {=u32} of {=u32}", samples, expected)
            }
        }
    }

    /// The model: runs the on-target selection for every open request (lowest priority, so
    /// sampling and the console preempt it).
    #[task(priority = 1, shared = [controller])]
    async fn model(mut cx: model::Context) {
        while let Some(req) = cx.shared.controller.lock(|c| c.take_model_request()) {
            defmt::info!(
                "model: computing model {=u32:08x} gap {=f32} mm",
                req.model_hash,
                req.gap_mm
            );
            let result = predict(&req.params, req.gap_mm);
            cx.shared
                .controller
                .lock(|c| c.set_prediction(req.generation, result));
        }
    }
}

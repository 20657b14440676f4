//! The rig's whole firmware image — RTIC app, tasks, priorities, the console over USART2, TIM2
//! at 10 kHz — on QEMU's `netduinoplus2` (the `firmware-qemu` image: the rig image's app with
//! stand-ins for what QEMU lacks, listed in `firmware/src/board_emu.rs`), driven through its
//! USART2 on a pseudo-terminal by the same client as the rig (`host_sim::rig_link::RigPort`).
//!
//! Needs the image (`cargo fw-build`) and `qemu-system-arm`: ignored unless asked for
//! (`cargo test -p e2e-tests -- --include-ignored`; `.ci/run`), where a missing tool fails.
//! `-icount shift=3`: every guest instruction takes 8 ns of emulated time (125 MIPS, slower than
//! the rig's Cortex-M4 at 168 MHz), and timers, SysTick and the emulated UART follow emulated
//! time.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use host_sim::rig_link::{LinkOptions, RigPort, SeqCounter};
use shared::capture::CaptureState;
use shared::console::{Board, Exact};
use shared::control::{AsyncKind, AsyncRecord, Event, Fault, ModelStatus, State, Status, predict};
use shared::control::{CalibField, Calibration};
use shared::model::{ContactLawKind, ModelEdit, ModelField, RigId, params_hash};

/// Emulated time per guest instruction at `-icount shift=3`, s.
const INSN_S: f64 = 8e-9;
/// The model task's budget on the rig, instructions (0.5 s at 168 MHz).
const PREDICT_BUDGET_INSNS: f64 = 84e6;
/// SRAM, bytes.
const RAM_BYTES: u64 = 128 * 1024;
/// What the emulator image prints (semihosting) once its console UART is enabled.
const UART_READY: &str = "console: USART2 ready";

/// One emulation at a time: each QEMU runs its CPU flat out (`sleep=off`), and three of them
/// on the reference machine's two cores left a pty unanswered for 20 s about once in ten runs.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// QEMU running the emulator image, its stdout (semihosting) collected; it holds the turn
/// ([`ONE_AT_A_TIME`]) until it is dropped.
struct Qemu {
    child: Child,
    pty: PathBuf,
    out: Arc<Mutex<String>>,
    _turn: std::sync::MutexGuard<'static, ()>,
}

impl Qemu {
    /// QEMU started on the emulator image, its console up (panics where the image or QEMU is
    /// missing).
    fn start() -> Qemu {
        let elf = e2e_tests::qemu_image("firmware-qemu");
        // (A test that failed holding the turn poisoned the lock; the next may still run.)
        let turn = ONE_AT_A_TIME
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let mut child = Command::new("qemu-system-arm")
            .args([
                "-machine",
                "netduinoplus2",
                "-nographic",
                "-monitor",
                "none",
            ])
            .args(["-serial", "null", "-serial", "pty"])
            .args(["-semihosting-config", "enable=on,target=native"])
            .args(["-icount", "shift=3,sleep=off", "-kernel"])
            .arg(&elf)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run qemu-system-arm");
        let out = Arc::new(Mutex::new(String::new()));
        for stream in [
            Box::new(child.stdout.take().unwrap()) as Box<dyn std::io::Read + Send>,
            Box::new(child.stderr.take().unwrap()),
        ] {
            let out = Arc::clone(&out);
            std::thread::spawn(move || {
                for line in BufReader::new(stream).lines().map_while(Result::ok) {
                    let mut o = out.lock().unwrap();
                    o.push_str(&line);
                    o.push('\n');
                }
            });
        }
        // The pty, and the image's word that its UART is on: QEMU drops what reaches a UART
        // not yet enabled, so a line sent earlier could be lost or cut.
        let end = Instant::now() + Duration::from_secs(30);
        let pty = loop {
            let text = out.lock().unwrap().clone();
            let pty = text.split_whitespace().find(|w| w.starts_with("/dev/pts/"));
            if let Some(p) = pty
                && text.contains(UART_READY)
            {
                break PathBuf::from(p);
            }
            assert!(
                Instant::now() < end,
                "QEMU did not open its pty, or the image did not say `{UART_READY}`:\n{text}"
            );
            std::thread::sleep(Duration::from_millis(20));
        };
        Qemu {
            child,
            pty,
            out,
            _turn: turn,
        }
    }

    fn port(&self) -> RigPort {
        self.port_with(LinkOptions::with_timeout(Duration::from_secs(20)))
    }

    /// The console with `opts`; a link that does not come up fails with what QEMU said.
    fn port_with(&self, opts: LinkOptions) -> RigPort {
        RigPort::open(&self.pty, opts).unwrap_or_else(|e| {
            panic!(
                "{e:#} ({}); QEMU said:\n{}",
                self.pty.display(),
                self.out.lock().unwrap()
            )
        })
    }

    /// Waits for QEMU to end (at most `wall`); its output.
    fn wait_exit(&mut self, wall: Duration) -> String {
        let end = Instant::now() + wall;
        while self.child.try_wait().unwrap().is_none() {
            assert!(
                Instant::now() < end,
                "QEMU still running:\n{}",
                self.output()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        std::thread::sleep(Duration::from_millis(100));
        self.output()
    }

    fn output(&self) -> String {
        self.out.lock().unwrap().clone()
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Polls `status` until `what` holds.
fn wait_status(port: &mut RigPort, what: impl Fn(&Status) -> bool) -> Status {
    let (s, came) = port
        .wait_status(what, Duration::from_secs(60), Duration::from_millis(10))
        .unwrap();
    assert!(came, "never came: {s}");
    s
}

/// The next event record that `what` picks (other records are counted in `seq`).
fn wait_event(
    port: &mut RigPort,
    what: impl Fn(&Event) -> bool,
    seq: &mut SeqCounter,
) -> AsyncRecord {
    let end = Instant::now() + Duration::from_secs(60);
    loop {
        assert!(Instant::now() < end, "no such event");
        if let Some(r) = port.next_record(Duration::from_millis(200)).unwrap() {
            seq.see(r.seq);
            if let AsyncKind::Event(e) = r.kind
                && what(&e)
            {
                return r;
            }
        }
    }
}

fn model_ready(e: &Event) -> bool {
    matches!(e, Event::ModelReady(_))
}

/// The host's on-target prediction as the status line prints it.
fn host_model_text(rig: RigId, gap_mm: f32) -> (String, u32) {
    let p = predict(&rig.preset(), gap_mm).unwrap();
    (
        format!(
            "model=ready target_hz={} band_hz={}..{} predicted_mg={}",
            Exact::f32(p.target_hz),
            Exact::f32(p.band_hz[0]),
            Exact::f32(p.band_hz[1]),
            Exact::f32(p.impact_force_mg)
        ),
        p.target_hz.to_bits(),
    )
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware images (cargo fw-build)"]
fn the_whole_image_runs_its_console_model_sampling_faults_and_watchdog() {
    let mut qemu = Qemu::start();
    let mut port = qemu.port();

    // Boot to the console.
    assert_eq!(port.id().board, Board::Emulator);
    assert_eq!(
        port.id().rig.source,
        shared::control::ModelSource::Preset(RigId::Wires)
    );
    assert!(
        port.send_line("help")
            .unwrap()
            .starts_with("commands: status")
    );
    let (host_text, host_bits) = host_model_text(RigId::Wires, 0.0);
    let status = wait_status(&mut port, |s| matches!(s.model, ModelStatus::Ready(_)));
    assert!(
        status.to_string().contains(&host_text),
        "{status}\nvs the host: {host_text}"
    );

    // The model recomputes on `gap`: pending at once, ready with the host's bits, within the
    // emulated time of the instruction budget, while sampling keeps 10 kHz.
    let mut seq = SeqCounter::default();
    assert_eq!(port.send_line("stream on").unwrap(), "ok");
    assert_eq!(port.send_line("gap 0.5").unwrap(), "ok");
    // Pending at once (or, on a loaded machine, already the new gap's target: never the old).
    let gap_half = predict(&RigId::Wires.preset(), 0.5).unwrap().target_hz;
    match port.status().unwrap().model {
        ModelStatus::Pending => {}
        ModelStatus::Ready(t) => assert_eq!(t.target_hz, gap_half),
        m => panic!("{m:?}"),
    }
    wait_event(&mut port, model_ready, &mut seq);
    let d0 = port.diag().unwrap();
    assert_eq!(port.send_line("gap 0").unwrap(), "ok");
    let ready = wait_event(&mut port, model_ready, &mut seq);
    let d1 = port.diag().unwrap();
    let AsyncKind::Event(Event::ModelReady(target)) = ready.kind else {
        unreachable!()
    };
    assert_eq!(
        target.target_hz.to_bits(),
        host_bits,
        "on-target {ready} vs the host's bits"
    );
    let took_s = (ready.sample as f64 - d0.samples as f64) / 1e4;
    let budget_s = PREDICT_BUDGET_INSNS * INSN_S / 0.85;
    eprintln!("model computed in {took_s:.3} s of emulated time (budget {budget_s:.3} s)");
    assert!(took_s > 0.0 && took_s < budget_s, "{took_s} s");
    let (samples, ms) = (
        (d1.samples - d0.samples) as f64,
        (d1.uptime_ms - d0.uptime_ms) as f64,
    );
    let rate = samples / ms * 1e3;
    eprintln!("sampling while the model computed: {samples} samples in {ms} ms ({rate:.1} Hz)");
    // 10 samples per ms: `uptime_ms` is whole milliseconds at both ends (±10 samples) and each
    // count may be one sample short of its millisecond.
    assert!((samples - 10.0 * ms).abs() <= 11.0, "{rate} Hz");
    assert_eq!(d1.lost_cycles, 0);
    let status = port.status().unwrap();
    assert!(
        status.fault.is_none() && status.to_string().contains(&host_text),
        "{status}"
    );

    // `rig` recomputes too.
    assert_eq!(port.send_line("rig beam-170").unwrap(), "ok");
    let beam = wait_event(&mut port, model_ready, &mut seq);
    let beam_bits = predict(&RigId::Beam170.preset(), 0.0)
        .unwrap()
        .target_hz
        .to_bits();
    assert!(
        beam.to_string()
            .contains(&format!("target_bits={beam_bits:#010x}")),
        "{beam}"
    );
    assert_eq!(port.send_line("rig wires").unwrap(), "ok");
    wait_event(&mut port, model_ready, &mut seq);

    // Bad lines: answered `error: …`, nothing changes.
    let before = port.send_line("status").unwrap();
    assert!(
        port.send_raw_line(b"\xff\xfe\x01\x02\x7fgarbage\xc3")
            .unwrap()
            .starts_with("error:")
    );
    let long = "gap 0.5".repeat(20);
    let err = port.send_line(&long).unwrap_err().to_string();
    assert!(err.contains("line too long or not text"), "{err}");
    assert_eq!(
        port.send_line("fly").unwrap(),
        "error: unknown command (try `help`)"
    );
    assert!(
        port.send_line("gap 11")
            .unwrap()
            .starts_with("error: gap (mm) out of range")
    );
    assert!(
        port.send_line("freq 0.5")
            .unwrap()
            .starts_with("error: frequency out of the safe window")
    );
    // Lines sent while a long reply goes out are answered, in order, each with its tag.
    let replies = port.send_lines(&["help", "gap 99", "status"]).unwrap();
    assert!(replies[0].starts_with("commands:"), "{replies:?}");
    assert!(replies[1].starts_with("error: gap (mm)"), "{replies:?}");
    assert_eq!(replies[2], before);
    assert_eq!(port.send_line("status").unwrap(), before);

    // Streaming: consecutive sequence numbers while the console keeps answering.
    let mut cycles = SeqCounter::default();
    let mut t = 0;
    while t < 6 {
        if let Some(r) = port.next_record(Duration::from_secs(5)).unwrap() {
            cycles.see(r.seq);
            if matches!(r.kind, AsyncKind::Cycle(_)) {
                t += 1;
                assert_eq!(port.status().unwrap().state, State::Idle);
            }
        }
    }
    assert_eq!(cycles.lost, 0, "telemetry lines lost");

    // `start` on QEMU's synthetic ADC signal: a sawtooth over the whole ADC range (+7 codes
    // per read, 585 reads per sweep) reads up to 310 N within 58.5 ms: the over-force abort.
    assert_eq!(port.send_line("start").unwrap(), "ok");
    let fault = wait_event(&mut port, |e| matches!(e, Event::Fault(_)), &mut seq);
    assert!(
        matches!(fault.kind, AsyncKind::Event(Event::Fault(Fault::OverForce))),
        "{fault}"
    );
    let s = wait_status(&mut port, |s| s.amplitude_mm == 0.0);
    assert!(
        s.state == State::Fault && s.fault == Some(Fault::OverForce),
        "{s}"
    );
    assert_eq!(port.send_line("emu dac").unwrap(), "dac_code=2048");
    assert_eq!(
        port.send_line("start").unwrap(),
        "error: fault latched: clear first"
    );
    // Still latched 0.3 s of the board's own time later (3,000 samples).
    let from = port.diag().unwrap().samples;
    let end = Instant::now() + Duration::from_secs(60);
    while port.diag().unwrap().samples < from + 3_000 {
        assert!(Instant::now() < end, "the board's sample count stopped");
    }
    assert_eq!(port.status().unwrap().fault, Some(Fault::OverForce));
    assert_eq!(port.send_line("clear").unwrap(), "ok");
    let s = port.status().unwrap();
    assert!(s.state == State::Idle && s.fault.is_none(), "{s}");

    // A capture records the sawtooth's crossings.
    assert!(
        port.send_line("capture arm 1 0.2")
            .unwrap()
            .starts_with("capture state=armed")
    );
    let end = Instant::now() + Duration::from_secs(30);
    let cap = loop {
        let c = port
            .capture_status(shared::capture::CaptureCommand::Status)
            .unwrap();
        if c.state == CaptureState::Done {
            break c;
        }
        assert!(Instant::now() < end, "{c}");
    };
    assert_eq!(cap.segments, 32, "{cap}");
    assert_eq!(port.segment(31).unwrap().k, 31);
    // The board's identification reads this capture through the image's capture lock: a
    // sawtooth is no drop, refused with its reason; `capture adopt` drafts nothing.
    let model = port.send_line("model").unwrap();
    for line in ["capture identify", "capture adopt"] {
        let reply = port.send_line(line).unwrap();
        eprintln!("{line}: {reply}");
        assert!(
            matches!(
                reply.parse::<shared::console::Answer>(),
                Ok(shared::console::Answer::Identify(
                    shared::console::IdentifyLine(Err(_))
                ))
            ),
            "{line}: {reply}"
        );
    }
    assert_eq!(port.send_line("model").unwrap(), model);

    // The board's commissioning through the image's console service: its sensor check reads
    // the sawtooth (not a sensor at rest) and fails with its numbers, the sequence ends there,
    // the model unchanged; the `!C` records come in order as the firmware sends them.
    let reply = port.send_line("commission start").unwrap();
    assert!(
        reply.starts_with("commission step=sensor ending=no"),
        "{reply}"
    );
    let mut records = Vec::new();
    while !records
        .last()
        .is_some_and(|n: &shared::commission::Numbered| n.progress.ends())
    {
        let n = port
            .next_commission(Duration::from_secs(30))
            .unwrap()
            .unwrap_or_else(|| panic!("no commissioning record: {records:?}"));
        eprintln!("{}", shared::console::commission::CommissionLine(n));
        records.push(n);
    }
    use shared::commission::{EndReason, Progress, Step};
    assert!(
        matches!(
            records[1].progress,
            Progress::Sensor(c) if c.failure.is_some()
        ),
        "{records:?}"
    );
    assert_eq!(
        records.last().unwrap().progress,
        Progress::Kept {
            at: Step::Sensor,
            reason: EndReason::Failed
        }
    );
    assert_eq!(
        records.iter().map(|n| n.seq).collect::<Vec<_>>(),
        (0..records.len() as u32).collect::<Vec<_>>()
    );
    assert_eq!(port.send_line("model").unwrap(), model);

    // The stack after all of the above: the model task's depth with the interrupts on top.
    let d = port.diag().unwrap();
    let (hwm, size) = (f64::from(d.stack_hwm_bytes), f64::from(d.stack_size_bytes));
    let static_ram = RAM_BYTES as f64 - size;
    eprintln!(
        "stack high-water mark {hwm} B of a {size} B stack; static RAM {static_ram} B; \
         static + stack + 8 KiB = {:.1} KiB",
        (static_ram + hwm + 8192.0) / 1024.0
    );
    assert!(
        hwm > 30_000.0 && static_ram + hwm + 8192.0 <= RAM_BYTES as f64,
        "{d}"
    );
    // Nothing held the sampling task off for long: the longest gap between two samples.
    let gap = f64::from(d.sample_gap_max_us);
    eprintln!("longest gap between samples: {gap} µs (period 100 µs)");
    assert!((100.0..150.0).contains(&gap), "{d}");

    // A stalled sampling task stops the watchdog feeding: the health check sees it within a
    // second or two, and 2 s after the last feed the watchdog (stand-in) resets the MCU.
    let stalled = port.send_line("emu stall").unwrap();
    let t_stall: f64 = stalled
        .strip_prefix("ok sampling stalled at uptime_ms=")
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{stalled}"));
    let ev = wait_event(
        &mut port,
        |e| matches!(e, Event::SamplingStalled { .. }),
        &mut seq,
    );
    let AsyncKind::Event(Event::SamplingStalled { expected, .. }) = ev.kind else {
        unreachable!()
    };
    assert!(expected >= 9_000, "{ev}");
    let out = qemu.wait_exit(Duration::from_secs(60));
    let line = out
        .lines()
        .find(|l| l.starts_with("watchdog:"))
        .unwrap_or_else(|| panic!("no watchdog reset:\n{out}"));
    let num = |key: &str| -> f64 {
        line.split_whitespace()
            .find_map(|w| w.strip_prefix(key)?.strip_prefix('=')?.parse().ok())
            .unwrap_or_else(|| panic!("`{key}=` missing in: {line}"))
    };
    let (last_feed, now) = (num("last_feed_ms"), num("now_ms"));
    assert!(
        last_feed - t_stall < 2000.0 && now - last_feed >= 2000.0,
        "stall at {t_stall} ms: {line}"
    );
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware images (cargo fw-build)"]
fn a_stack_overflow_faults_instead_of_overwriting_static_data() {
    let mut qemu = Qemu::start();
    let mut port = qemu.port();
    assert!(port.send_line("emu overflow").is_err());
    let out = qemu.wait_exit(Duration::from_secs(60));
    // flip-link: the stack sits at the bottom of RAM, so the overflow reaches 0x1fff_ffff
    // (unmapped) and faults; the fault cannot even be stacked: the CPU locks up (on the rig the
    // watchdog then resets it).
    let sp = out
        .lines()
        .find_map(|l| l.split_whitespace().find_map(|w| w.strip_prefix("R13=")))
        .unwrap_or_else(|| panic!("no fault:\n{out}"));
    let sp = u32::from_str_radix(sp, 16).unwrap();
    assert!(out.contains("Lockup") || out.contains("HardFault"), "{out}");
    assert!(
        sp < 0x2000_0000,
        "stack pointer 0x{sp:08x} at the fault:\n{out}"
    );
}

/// The rig's own link-loss watchdog on the whole image: started by the client with a 2 s link
/// timeout and then left without a line, the emulated board stops its drive 2 s (of its own
/// time) after the last line, and the drive is at zero within the abort ramp.
#[test]
#[ignore = "needs qemu-system-arm and the firmware images (cargo fw-build)"]
fn a_silent_link_brings_the_drive_to_zero() {
    let qemu = Qemu::start();
    // No watchdog of the client's own and no keep-alives: this test plays a desktop that dies.
    let opts = LinkOptions {
        link_timeout_s: 0.0,
        ..LinkOptions::with_timeout(Duration::from_secs(20))
    };
    let mut port = qemu.port_with(opts);
    wait_status(&mut port, |s| matches!(s.model, ModelStatus::Ready(_)));
    // A quiet force signal (QEMU's sawtooth would trip the over-force abort).
    assert_eq!(port.send_line("emu adc 248").unwrap(), "ok adc 248");
    assert_eq!(port.send_line("link-timeout 2").unwrap(), "ok");
    assert_eq!(port.diag().unwrap().link_timeout_ms, 2000);
    assert_eq!(port.send_line("stream on").unwrap(), "ok");
    assert_eq!(port.send_line("freq 3").unwrap(), "ok");
    assert_eq!(port.send_line("start").unwrap(), "ok");
    // From here on, not a byte is sent: the records tell what the board does.
    let mut seq = SeqCounter::default();
    let started = wait_event(
        &mut port,
        |e| {
            matches!(
                e,
                Event::State {
                    to: State::Ramp,
                    ..
                }
            )
        },
        &mut seq,
    );
    let lost = wait_event(&mut port, |e| matches!(e, Event::Fault(_)), &mut seq);
    assert!(
        matches!(lost.kind, AsyncKind::Event(Event::Fault(Fault::LinkLost))),
        "{lost}"
    );
    let after_s = (lost.sample - started.sample) as f64 / 1e4;
    eprintln!("link lost {after_s:.4} s after the last line");
    assert!((2.0..2.01).contains(&after_s), "{after_s} s");
    // The abort ramp (4 mm/s from at most 0.89 mm): the drive at zero within 0.25 s.
    let end = Instant::now() + Duration::from_secs(60);
    let zero = loop {
        assert!(Instant::now() < end, "the drive never reached zero");
        if let Some(r) = port.next_record(Duration::from_secs(5)).unwrap()
            && let AsyncKind::Cycle(c) = r.kind
            && c.amplitude_mm == 0.0
        {
            break r;
        }
    };
    let to_zero_s = (zero.sample - lost.sample) as f64 / 1e4;
    eprintln!("drive at zero {to_zero_s:.3} s after the fault");
    assert!(to_zero_s < 0.25 + 1.0 / 3.0, "{to_zero_s} s");
    assert_eq!(port.send_line("emu dac").unwrap(), "dac_code=2048");
    let s = port.status().unwrap();
    assert_eq!((s.state, s.fault), (State::Fault, Some(Fault::LinkLost)));
}

/// Rig engineers' models pushed to the emulator image and saved — the wire rig damped with a
/// heavier hammer and the Hunt–Crossley law `identify contact` fits to the rig's drop test, and
/// the 170 mm beam with a hammer of its own — each with a calibration of its own: the board
/// computes the desktop's target, band and `F_i/mg` on each bit for bit; after another model (a
/// preset), `revert` brings the stored one back from the store, the same bits again. (The reset
/// itself is tested on the virtual rig, `host-sim/tests/rig.rs`: under QEMU's `netduinoplus2`
/// the image restarted by a system reset gets no more timer or UART interrupts,
/// docs/operator.md.)
#[test]
#[ignore = "needs qemu-system-arm and the firmware images (cargo fw-build)"]
fn pushed_models_run_on_the_board_and_come_back_from_its_store() {
    let qemu = Qemu::start();
    let mut port = qemu.port();
    let hunt_crossley = [
        ModelEdit::Law(ContactLawKind::HuntCrossley),
        ModelEdit::Set(ModelField::Stiffness, 5_354_900.0),
        ModelEdit::Set(ModelField::Exponent, 1.0),
        ModelEdit::Set(ModelField::LambdaSM, 68.4774),
        ModelEdit::Set(ModelField::DampingRatio, 0.01),
        ModelEdit::Set(ModelField::MassKg, 0.31),
    ]
    .into_iter()
    .try_fold(RigId::Wires.preset(), |p, e| p.edited(e))
    .unwrap();
    let beam = RigId::Beam170
        .preset()
        .edited(ModelEdit::Set(ModelField::MassKg, 0.35))
        .unwrap();
    for (k, (params, volts_per_n)) in [(hunt_crossley, 0.0098f32), (beam, 0.0102)]
        .into_iter()
        .enumerate()
    {
        let calibration = Calibration::default().with(CalibField::VoltsPerN, volts_per_n);
        let host = predict(&params, 0.0).unwrap();
        let pushed =
            host_sim::rig_link::model::push(&mut port, &params, Some(&calibration), true).unwrap();
        assert_eq!(pushed.hash, params_hash(&params));
        assert_eq!(
            pushed.saved.map(|s| s.hash),
            Some(Some(params_hash(&params)))
        );
        let check = |port: &mut RigPort| {
            let s = wait_status(port, |s| matches!(s.model, ModelStatus::Ready(_)));
            let ModelStatus::Ready(t) = s.model else {
                unreachable!()
            };
            assert_eq!(s.rig.hash, params_hash(&params), "{s}");
            assert_eq!(s.rig.source, shared::control::ModelSource::Stored, "{s}");
            assert_eq!(t.target_hz.to_bits(), host.target_hz.to_bits(), "{s}");
            assert_eq!(
                t.band_hz.map(f32::to_bits),
                host.band_hz.map(f32::to_bits),
                "{s}"
            );
            assert_eq!(
                t.impact_force_mg.to_bits(),
                host.impact_force_mg.to_bits(),
                "{s}"
            );
        };
        check(&mut port);
        // Another model, then the stored one back.
        assert_eq!(port.send_line("rig wires").unwrap(), "ok");
        let model = port.send_line("revert").unwrap();
        assert!(model.starts_with("model of=active rig=stored "), "{model}");
        check(&mut port);
        let store = port.send_line("store").unwrap();
        assert_eq!(
            store,
            format!(
                "store state=ok saves={} rig_hash={:08x}",
                k + 1,
                params_hash(&params)
            )
        );
        assert_eq!(
            port.send_line("calib").unwrap().split(' ').nth(2),
            Some(format!("volts_per_n={volts_per_n}").as_str())
        );
    }
}

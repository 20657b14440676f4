//! `host-sim rig` against a hostile peer: a pseudo-terminal played by the test as a rig that
//! drops, delays, duplicates, garbles, floods, sends NaN, lies about sizes, goes quiet, goes
//! back in sequence and in time. Every case ends in bounded time, with a non-zero exit and a
//! message naming what failed, and leaves no file but a marked partial one.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use shared::capture::{CaptureState, CaptureStatus};
use shared::console::serve::split_tag;
use shared::console::{Answer, Board, DiagInfo, IdInfo, LinkStats, ModelOf, ModelView, Version};
use shared::control::{
    AsyncKind, AsyncRecord, CycleTelemetry, ModelStatus, Reply, SAMPLE_RATE_HZ, SensorChain, State,
    Status, Target,
};
use shared::control::{ModelId, ModelSource};
use shared::model::RigId;
use shared::store::StoreState;

use crate::common;
use common::leftovers;

/// What the fake rig does besides answering like a rig.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Misbehaviour {
    /// Never answers `status`.
    DropsStatus,
    /// Answers `status` 1.5 s late (the client waits 0.5 s).
    DelaysStatus,
    /// Sends every reply twice.
    Duplicates,
    /// Answers `status` with escape codes, bells and NUL bytes.
    Garbles,
    /// After `stream on`: 20 MB without a line end.
    FloodsAfterStream,
    /// Telemetry whose time is NaN.
    NanTelemetry,
    /// Telemetry whose sequence numbers go back.
    SequenceBack,
    /// Telemetry whose time goes back.
    TimeBack,
    /// The capture claims 100,000 segments.
    CaptureTooManySegments,
    /// The capture stays armed forever (its sample count still advancing).
    CaptureStaysArmed,
    /// A calibration of 0 V/N in `id`.
    ZeroCalibration,
    /// An unexpected untagged `ok` before the reply to `status`.
    UnexpectedOk,
    /// 70 KiB of garbage without a line end, then an untagged `ok`, before the reply to `status`.
    LongGarbageThenOk,
    /// The drive never reaches `dwell` (telemetry stays in `ramp`).
    NeverDwells,
    /// Stops answering after connecting.
    GoesQuiet,
    /// Never dwells (as `NeverDwells`), and every `stop` is lost on the way (`error: line
    /// lost`, untagged, as a damaged line gets).
    LosesStop,
    /// Echoes every line it receives, tagged ones too (a console left with `echo on` by a
    /// firmware that echoed everything), before its reply.
    Echoes,
    /// Never dwells; an untagged garbage line before each reply to `stop` and `status`; after
    /// a `stop` its status says `stopping` at 0.5 mm.
    NoisyStop,
    /// Never dwells; acknowledges `stop`, yet its status still says `dwell` at 0.89 mm.
    AcksStopButDrives,
    /// A status with `freq_hz=NaN amp_mm=inf`.
    NanStatus,
    /// `ok` in answer to `status`.
    OkToStatus,
    /// Nothing: answers and streams like a rig.
    Behaves,
}

/// The fake rig's state.
struct Fake {
    bad: Misbehaviour,
    streaming: bool,
    seq: u32,
    sample: u64,
    capture_samples: u32,
    lines: usize,
    /// Every line received (tags stripped).
    log: Vec<String>,
    /// A `stop` came.
    stopped: bool,
    /// Reads of the pty that found nothing (everything sent before them had been read and
    /// answered): what [`drained`] waits on.
    empty_reads: u64,
}

fn id_info(bad: Misbehaviour) -> IdInfo {
    IdInfo {
        firmware: Version::of("0.1.0"),
        board: Board::Virtual,
        rig: ModelId::of(&RigId::Wires.preset(), ModelSource::Preset(RigId::Wires)),
        store: StoreState::Empty,
        gap_mm: 0.0,
        sample_rate_hz: SAMPLE_RATE_HZ,
        capture_rate_hz: 100_000,
        sensor: SensorChain {
            volts_per_n: if bad == Misbehaviour::ZeroCalibration {
                0.0
            } else {
                0.01
            },
            ..SensorChain::default()
        },
        mass_kg: 0.298,
        freq_window_hz: [1.0, 30.0],
        slew_hz_per_s: 0.5,
        ramp_mm_per_s: 0.5,
        force_limit_n: 280.0,
    }
}

fn status(state: State) -> Status {
    Status {
        state,
        rig: ModelId::of(&RigId::Wires.preset(), ModelSource::Preset(RigId::Wires)),
        gap_mm: 0.0,
        freq_hz: 1.0,
        amplitude_mm: 0.0,
        regime: None,
        peak: None,
        model: ModelStatus::Ready(Target {
            target_hz: 3.64,
            band_hz: [2.1, 4.7],
            impact_force_mg: 32.8,
        }),
        force_vs_model_pct: None,
        fault: None,
        impacts: 0,
        lost_cycles: 0,
    }
}

impl Fake {
    /// The reply text to `line` (tag stripped), or `None` for no reply.
    fn reply(&mut self, line: &str) -> Option<String> {
        use Misbehaviour::*;
        self.lines += 1;
        self.log.push(line.to_string());
        if self.bad == GoesQuiet && self.lines > 3 {
            return None;
        }
        let word = line.split_whitespace().next().unwrap_or("");
        let answer = match word {
            "id" => Answer::Id(id_info(self.bad)),
            "model" => Answer::Model(ModelView {
                of: ModelOf::Active(ModelSource::Preset(RigId::Wires)),
                params: RigId::Wires.preset(),
            }),
            "diag" => Answer::Diag(DiagInfo {
                samples: self.sample,
                uptime_ms: self.sample / 10,
                sample_gap_max_us: 100,
                link: LinkStats::default(),
                lost_cycles: 0,
                stack_hwm_bytes: 0,
                stack_size_bytes: 0,
                link_timeout_ms: 0,
            }),
            "status" => match self.bad {
                DropsStatus => return None,
                OkToStatus => Answer::Reply(Reply::Ok),
                NoisyStop if self.stopped => {
                    let mut s = status(State::Stopping);
                    s.amplitude_mm = 0.5;
                    Answer::Reply(Reply::Status(s))
                }
                AcksStopButDrives if self.stopped => {
                    let mut s = status(State::Dwell);
                    (s.amplitude_mm, s.freq_hz) = (0.89, 3.0);
                    Answer::Reply(Reply::Status(s))
                }
                _ => Answer::Reply(Reply::Status(status(State::Idle))),
            },
            "stop" => {
                self.stopped = true;
                Answer::Reply(Reply::Ok)
            }
            "stream" => {
                self.streaming = line.ends_with("on");
                Answer::Reply(Reply::Ok)
            }
            "capture" => {
                let armed = line.contains("arm");
                Answer::Capture(CaptureStatus {
                    state: if armed || self.bad == CaptureStaysArmed {
                        CaptureState::Armed
                    } else {
                        CaptureState::Done
                    },
                    segments: 0,
                    samples: self.capture_samples,
                    level_n: 1.0,
                })
            }
            _ => Answer::Reply(Reply::Ok),
        };
        let mut text = answer.to_string();
        if self.bad == CaptureTooManySegments && word == "capture" && !line.contains("arm") {
            text = text.replace(" segments=0 ", " segments=100000 ");
        }
        if self.bad == NanStatus && word == "status" {
            text = text.replacen("freq_hz=1.0000", "freq_hz=NaN", 1).replacen(
                "amp_mm=0.000",
                "amp_mm=inf",
                1,
            );
            assert!(text.contains("NaN") && text.contains("inf"), "{text}");
        }
        Some(text)
    }

    /// What the rig sends on its own every 20 ms of wall time: 20 ms of its own time, or
    /// 200 ms for a fake that never dwells (a sweep's dwell deadline is counted in the rig's
    /// time: the client gives up on it after seconds instead of tens of seconds).
    fn tick(&mut self) -> Vec<u8> {
        use Misbehaviour::*;
        let never_dwells = matches!(
            self.bad,
            NeverDwells | LosesStop | NoisyStop | AcksStopButDrives
        );
        self.sample += if never_dwells { 2000 } else { 200 };
        self.capture_samples = self.capture_samples.saturating_add(2000);
        if !self.streaming {
            return Vec::new();
        }
        if self.bad == FloodsAfterStream {
            self.streaming = false;
            return vec![b'x'; 20 << 20];
        }
        let state = if never_dwells {
            State::Ramp
        } else {
            State::Dwell
        };
        let rec = AsyncRecord {
            seq: self.seq,
            sample: self.sample,
            kind: AsyncKind::Cycle(CycleTelemetry {
                state,
                freq_hz: 3.0,
                amplitude_mm: 0.89,
                impacts: 1,
                peak_n: 90.0,
                impulse_n_s: 0.028,
                regime: None,
                fault: None,
                lost_cycles: 0,
            }),
        };
        self.seq += 1;
        let mut text = rec.to_string();
        match self.bad {
            SequenceBack if self.seq > 105 => {
                text = text.replacen(&format!("seq={}", rec.seq), "seq=1", 1)
            }
            TimeBack if self.seq > 105 => {
                let t = format!("t_s={:.4}", rec.sample as f64 / 1e4);
                text = text.replacen(&t, "t_s=0.0100", 1);
            }
            _ => {}
        }
        if self.bad == NanTelemetry {
            // `t_s=nan` in place of the time.
            let t = format!("t_s={:.4}", rec.sample as f64 / 1e4);
            text = rec.to_string().replacen(&t, "t_s=nan", 1);
        }
        format!("{text}\r\n").into_bytes()
    }
}

/// A pseudo-terminal the test plays the rig on, misbehaving as `bad`.
fn fake_rig(bad: Misbehaviour) -> PathBuf {
    fake_rig_logged(bad).0
}

/// [`fake_rig`], with the fake's state (its log of the lines received).
fn fake_rig_logged(bad: Misbehaviour) -> (PathBuf, Arc<Mutex<Fake>>) {
    let pair = nix::pty::openpty(None, None).unwrap();
    let mut t = nix::sys::termios::tcgetattr(&pair.slave).unwrap();
    nix::sys::termios::cfmakeraw(&mut t);
    nix::sys::termios::tcsetattr(&pair.slave, nix::sys::termios::SetArg::TCSANOW, &t).unwrap();
    let path = nix::unistd::ttyname(&pair.slave).unwrap();
    let master = std::fs::File::from(pair.master);
    let flags = nix::fcntl::fcntl(&master, nix::fcntl::FcntlArg::F_GETFL).unwrap();
    nix::fcntl::fcntl(
        &master,
        nix::fcntl::FcntlArg::F_SETFL(
            nix::fcntl::OFlag::from_bits_truncate(flags) | nix::fcntl::OFlag::O_NONBLOCK,
        ),
    )
    .unwrap();
    let fake = Arc::new(Mutex::new(Fake {
        bad,
        streaming: false,
        seq: 100,
        sample: 0,
        capture_samples: 0,
        lines: 0,
        log: Vec::new(),
        stopped: false,
        empty_reads: 0,
    }));
    let state = Arc::clone(&fake);
    std::thread::spawn(move || {
        let _slave = pair.slave;
        let mut master = master;
        let mut buf = Vec::new();
        let mut chunk = [0u8; 4096];
        let mut delayed: Vec<(Instant, Vec<u8>)> = Vec::new();
        let send = |master: &mut std::fs::File, bytes: &[u8]| {
            let mut rest = bytes;
            let end = Instant::now() + Duration::from_secs(30);
            while !rest.is_empty() && Instant::now() < end {
                match master.write(rest) {
                    Ok(n) => rest = &rest[n..],
                    Err(_) => std::thread::sleep(Duration::from_millis(1)),
                }
            }
        };
        loop {
            std::thread::sleep(Duration::from_millis(20));
            match master.read(&mut chunk) {
                Ok(0) => return,
                Ok(n) => buf.extend_from_slice(&chunk[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    fake.lock().unwrap().empty_reads += 1;
                }
                Err(e) if e.raw_os_error() == Some(nix::libc::EIO) => {}
                Err(_) => return,
            }
            while let Some(end) = buf.iter().position(|&b| b == b'\n') {
                let raw: Vec<u8> = buf.drain(..=end).collect();
                let line = String::from_utf8_lossy(&raw).trim().to_string();
                if line.is_empty() {
                    continue; // a keep-alive
                }
                let (tag, rest) = split_tag(&line).unwrap();
                let rest = rest.trim();
                let Some(text) = fake.lock().unwrap().reply(rest) else {
                    continue;
                };
                let tagged = match tag {
                    Some(t) => format!("#{t} {text}\r\n"),
                    None => format!("{text}\r\n"),
                };
                let word = rest.split_whitespace().next().unwrap_or("");
                use Misbehaviour::*;
                match (bad, word) {
                    (DelaysStatus, "status") => delayed.push((
                        Instant::now() + Duration::from_millis(1500),
                        tagged.into_bytes(),
                    )),
                    (Duplicates, _) => {
                        send(&mut master, tagged.as_bytes());
                        send(&mut master, tagged.as_bytes());
                    }
                    (Garbles, "status") => send(
                        &mut master,
                        b"\x1b[2J\x07\x00\xff garbage\x1b]0;title\x07\r\n",
                    ),
                    (UnexpectedOk, "status") => {
                        send(&mut master, b"ok\r\n");
                        send(&mut master, tagged.as_bytes());
                    }
                    (LosesStop, "stop") => send(&mut master, b"error: line lost\r\n"),
                    (Echoes, _) => {
                        send(&mut master, format!("{line}\r\n").as_bytes());
                        send(&mut master, tagged.as_bytes());
                    }
                    (NoisyStop, "stop" | "status") => {
                        send(&mut master, b"%% line noise: 0x55aa\r\n");
                        send(&mut master, tagged.as_bytes());
                    }
                    (LongGarbageThenOk, "status") => {
                        let mut v = vec![b'g'; 70 << 10];
                        v.extend_from_slice(b"ok\r\n");
                        send(&mut master, &v);
                        send(&mut master, tagged.as_bytes());
                    }
                    _ => send(&mut master, tagged.as_bytes()),
                }
            }
            let now = Instant::now();
            for (_, bytes) in delayed.iter().filter(|(t, _)| *t <= now) {
                send(&mut master, bytes);
            }
            delayed.retain(|(t, _)| *t > now);
            let spontaneous = fake.lock().unwrap().tick();
            if !spontaneous.is_empty() {
                send(&mut master, &spontaneous);
            }
        }
    });
    (path, state)
}

/// The fake's log once it has read and answered everything sent to it before the call (a
/// client that has exited): two reads started since found nothing more (at most 10 s).
fn drained(fake: &Mutex<Fake>) -> Vec<String> {
    let seen = fake.lock().unwrap().empty_reads;
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        {
            let f = fake.lock().unwrap();
            if f.empty_reads >= seen + 2 {
                return f.log.clone();
            }
        }
        assert!(Instant::now() < end, "the fake rig read nothing for 10 s");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// `host-sim rig --port PORT --timeout-s 0.5 ARGS` in `dir`, run to its end; asserts it ended
/// non-zero within `wall`.
fn rig_fails(port: &Path, dir: &Path, args: &str, wall: Duration) -> String {
    let started = Instant::now();
    let out: Output = Command::new(assert_cmd::cargo::cargo_bin("host-sim"))
        .current_dir(dir)
        .arg("rig")
        .arg("--port")
        .arg(port)
        .args(["--timeout-s", "0.5"])
        .args(args.split_whitespace())
        .output()
        .unwrap();
    let took = started.elapsed();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "{args}: succeeded\n{stderr}");
    assert!(took < wall, "{args}: {took:?} (bound {wall:?})\n{stderr}");
    // Garbage is shown escaped and bounded: no control character reaches the terminal.
    assert!(
        !stderr.chars().any(|c| c.is_control() && c != '\n'),
        "{args}: raw control characters on stderr"
    );
    assert!(
        stderr.len() < 20_000,
        "{args}: {} bytes on stderr",
        stderr.len()
    );
    stderr
}

/// Runs a case in a fresh directory; asserts the message and that no file is left.
fn case(bad: Misbehaviour, args: &str, expect: &[&str], wall_s: u64) {
    let dir = tempfile::tempdir().unwrap();
    let port = fake_rig(bad);
    let stderr = rig_fails(&port, dir.path(), args, Duration::from_secs(wall_s));
    for e in expect {
        assert!(stderr.contains(e), "{bad:?}: `{e}` not in:\n{stderr}");
    }
    let left: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| !n.contains(".partial."))
        .collect();
    assert!(left.is_empty(), "{bad:?}: files left: {left:?}");
    assert!(leftovers(dir.path()).is_empty());
}

/// A [`case`] for each entry, side by side (each with its own fake rig, client and directory:
/// the tests' time is spent waiting out the client's timeouts, and their waits overlap).
fn cases(list: &[(Misbehaviour, &str, &[&str], u64)]) {
    std::thread::scope(|s| {
        let running: Vec<_> = list
            .iter()
            .map(|&(bad, args, expect, wall_s)| s.spawn(move || case(bad, args, expect, wall_s)))
            .collect();
        for r in running {
            if let Err(panic) = r.join() {
                std::panic::resume_unwind(panic);
            }
        }
    });
}

#[test]
fn a_peer_that_drops_delays_or_goes_quiet_is_a_timeout_naming_the_command() {
    cases(&[
        (
            Misbehaviour::DropsStatus,
            "send status",
            &["no reply to `status` within 0.5 s"],
            10,
        ),
        // The late reply is not taken for the next command's.
        (
            Misbehaviour::DelaysStatus,
            "send status",
            &["no reply to `status` within 0.5 s"],
            10,
        ),
        (
            Misbehaviour::GoesQuiet,
            "send status",
            &["no reply to `status`"],
            10,
        ),
    ]);
}

#[test]
fn replies_are_matched_to_their_commands() {
    cases(&[
        // A duplicated reply arrives while the next command waits: a link error naming both.
        (
            Misbehaviour::Duplicates,
            "send status diag",
            &["link error", "waited for its reply", "diag"],
            10,
        ),
        (
            Misbehaviour::UnexpectedOk,
            "send status",
            &["link error: `ok` arrived while", "status"],
            10,
        ),
    ]);
    // The tail of an over-long garbage line is discarded with it, never read as a reply: the
    // status line that follows is the reply, with a warning.
    let port = fake_rig(Misbehaviour::LongGarbageThenOk);
    let out = Command::new(assert_cmd::cargo::cargo_bin("host-sim"))
        .arg("rig")
        .arg("--port")
        .arg(&port)
        .args(["--timeout-s", "2", "send", "status"])
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.starts_with("state=idle "), "{stdout}");
    assert!(stderr.contains("bytes without a line end"), "{stderr}");
}

#[test]
fn garbled_lines_are_shown_escaped_and_bounded() {
    cases(&[
        (
            Misbehaviour::Garbles,
            "send status",
            &["\\u{1b}[2J\\u{7}\\0", "no reply to `status`"],
            10,
        ),
        // 20 MB without a line end: discarded by the 64 KiB, reported a bounded number of times;
        // the log ends for want of telemetry.
        (
            Misbehaviour::FloodsAfterStream,
            "log --seconds 5 --out log.csv",
            &["without a line end", "no telemetry"],
            40,
        ),
    ]);
}

#[test]
fn bad_numbers_and_lies_are_refused_at_the_edge() {
    cases(&[
        (
            Misbehaviour::ZeroCalibration,
            "send status",
            &["`id` reply does not read", "volts_per_n"],
            10,
        ),
        (
            Misbehaviour::NanTelemetry,
            "log --seconds 2 --out log.csv",
            &["t_s=", "no telemetry"],
            40,
        ),
        (
            Misbehaviour::CaptureTooManySegments,
            "capture --seconds 0.5 --out drop.csv",
            &["`capture`", "segments="],
            20,
        ),
        (
            Misbehaviour::CaptureStaysArmed,
            "capture --seconds 0.05 --out drop.csv",
            &["past its end"],
            20,
        ),
    ]);
}

#[test]
fn sequences_and_clocks_that_go_back_are_errors() {
    cases(&[
        (
            Misbehaviour::SequenceBack,
            "log --seconds 60 --out log.csv",
            &["sequence numbers went back"],
            30,
        ),
        (
            Misbehaviour::TimeBack,
            "log --seconds 60 --out log.csv",
            &["clock went back"],
            30,
        ),
    ]);
}

/// A three-point sweep, one cycle to settle and two to dwell, into `fr.csv`.
const SHORT_SWEEP: &str =
    "sweep --freq-hz 3:3.2:0.1 --settle-cycles 1 --dwell-cycles 2 --out fr.csv";

/// A sweep that ends before its first point says so and writes no file (a partial file of no
/// points would hold not even a header).
#[test]
fn a_sweep_whose_rig_never_dwells_ends_before_its_first_point_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let port = fake_rig(Misbehaviour::NeverDwells);
    let stderr = rig_fails(&port, dir.path(), SHORT_SWEEP, Duration::from_secs(60));
    assert!(stderr.contains("did not dwell"), "{stderr}");
    assert!(stderr.contains("last seen: state=ramp"), "{stderr}");
    assert!(
        stderr.contains("0 of 3 points; the rig is idle, drive at 0.000 mm; no point was measured: nothing written"),
        "{stderr}"
    );
    assert!(!dir.path().join("fr.csv").exists());
    assert!(!dir.path().join("fr.partial.csv").exists());
    assert!(leftovers(dir.path()).is_empty());
}

/// The drive guard's `stop` lost on the way: the client sends it again (three times in all),
/// says the drive may still run, and leaves the rig's link-loss watchdog armed (no
/// `link-timeout 0` after a failed stop).
#[test]
fn a_lost_stop_is_retried_and_the_watchdog_stays_armed() {
    let dir = tempfile::tempdir().unwrap();
    let (port, fake) = fake_rig_logged(Misbehaviour::LosesStop);
    let stderr = rig_fails(&port, dir.path(), SHORT_SWEEP, Duration::from_secs(60));
    assert!(stderr.contains("`stop` failed 3 times"), "{stderr}");
    assert!(stderr.contains("the drive may still run"), "{stderr}");
    assert!(!stderr.contains("ramped to zero"), "{stderr}");
    let log = drained(&fake);
    let stops = log.iter().filter(|l| *l == "stop").count();
    assert_eq!(stops, 3, "{log:?}");
    let last_stop = log.iter().rposition(|l| l == "stop").unwrap();
    assert!(
        !log[last_stop..]
            .iter()
            .any(|l| l.starts_with("link-timeout")),
        "{log:?}"
    );
}

/// A `link-timeout` or `stream on` the operator sends (tagged by them or not) is left as they
/// set it when the client closes (the client's own settings are undone, theirs are not).
#[test]
fn the_operators_settings_are_left_as_set() {
    // (`send` asks no `status`: this fake answers every line it is sent at once.)
    let (port, fake) = fake_rig_logged(Misbehaviour::DelaysStatus);
    for (args, last) in [
        (vec!["send", "link-timeout 30"], "link-timeout 30"),
        (vec!["send", "stream on"], "stream on"),
        // A tag the operator typed is the port's to give: the line goes with the port's own.
        (vec!["send", "#7 link-timeout 20"], "link-timeout 20"),
    ] {
        let out = Command::new(assert_cmd::cargo::cargo_bin("host-sim"))
            .arg("rig")
            .arg("--port")
            .arg(&port)
            .args(&args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let log = drained(&fake);
        let kind = last.split_whitespace().next().unwrap();
        let final_setting = log.iter().rfind(|l| l.starts_with(kind)).unwrap();
        assert_eq!(final_setting, last, "{log:?}");
    }
}

/// A console whose echo repeats every line, tagged ones too: the echo of a request is never
/// taken for its reply; the client connects and its commands get through.
#[test]
fn an_echo_is_never_taken_for_a_reply() {
    let port = fake_rig(Misbehaviour::Echoes);
    for (args, first) in [
        (["send", "status"], "state=idle "),
        (["send", "stop"], "ok"),
    ] {
        let out = Command::new(assert_cmd::cargo::cargo_bin("host-sim"))
            .arg("rig")
            .arg("--port")
            .arg(&port)
            .args(["--timeout-s", "2"])
            .args(args)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(stdout.starts_with(first), "{args:?}: {stdout}");
    }
}

/// The drive guard's `stop` through garbage (an untagged line before each of its replies): one
/// `stop` suffices and the guard says the state the status reported. A rig that acknowledges
/// `stop` while its status still says it drives is not believed: `stop` goes three times and
/// the guard says what the status said.
#[test]
fn the_guards_stop_gets_through_noise_and_is_judged_by_the_status() {
    let dir = tempfile::tempdir().unwrap();
    let (port, fake) = fake_rig_logged(Misbehaviour::NoisyStop);
    let stderr = rig_fails(&port, dir.path(), SHORT_SWEEP, Duration::from_secs(60));
    assert!(
        stderr.contains(
            "stopping the drive: `stop` answered `ok`; the rig is stopping, its drive ramping \
             down from 0.500 mm"
        ),
        "{stderr}"
    );
    let log = drained(&fake);
    assert_eq!(log.iter().filter(|l| *l == "stop").count(), 1, "{log:?}");

    let (port, fake) = fake_rig_logged(Misbehaviour::AcksStopButDrives);
    let stderr = rig_fails(&port, dir.path(), SHORT_SWEEP, Duration::from_secs(60));
    assert!(stderr.contains("`stop` failed 3 times"), "{stderr}");
    assert!(
        stderr.contains("yet the status says dwell at 0.890 mm, 3.0000 Hz"),
        "{stderr}"
    );
    assert!(stderr.contains("the drive may still run"), "{stderr}");
    let log = drained(&fake);
    assert_eq!(log.iter().filter(|l| *l == "stop").count(), 3, "{log:?}");
}

/// `rig send` prints a reply only once it has been read and found of its line's kind: a
/// status with NaN and infinity, or `ok` in answer to `status`, is an error naming the field or
/// the kind, with nothing printed; `--raw` prints what came.
#[test]
fn send_checks_what_it_prints() {
    let dir = tempfile::tempdir().unwrap();
    for (bad, says) in [
        (Misbehaviour::NanStatus, "freq_hz"),
        (
            Misbehaviour::OkToStatus,
            "the reply to `status` is of another kind: `ok`",
        ),
    ] {
        let port = fake_rig(bad);
        let out = Command::new(assert_cmd::cargo::cargo_bin("host-sim"))
            .current_dir(dir.path())
            .arg("rig")
            .arg("--port")
            .arg(&port)
            .args(["send", "status"])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{bad:?}: exit 0");
        assert!(out.stdout.is_empty(), "{bad:?}: printed {:?}", out.stdout);
        assert!(stderr.contains(says), "{bad:?}: {stderr}");
        assert!(stderr.contains("`--raw` prints it unchecked"), "{stderr}");
    }
    let port = fake_rig(Misbehaviour::NanStatus);
    let out = Command::new(assert_cmd::cargo::cargo_bin("host-sim"))
        .arg("rig")
        .arg("--port")
        .arg(&port)
        .args(["send", "--raw", "status"])
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("freq_hz=NaN amp_mm=inf"));
}

/// A wait reads what has arrived before it names a silence: telemetry the rig sent while no wait
/// ran is handed out by a zero wait (what `rig console --telemetry` polls with, and what a wait
/// resumed past its deadline finds).
#[test]
fn a_zero_wait_reads_what_has_arrived() {
    use host_sim::rig_link::{LinkOptions, RigPort};
    let (path, fake) = fake_rig_logged(Misbehaviour::Behaves);
    let mut port = RigPort::open(&path, LinkOptions::with_timeout(Duration::from_secs(2))).unwrap();
    port.command(shared::control::Command::Stream(true))
        .unwrap();
    // The fake streams a line every 20 ms: wait (without reading) until it has sent a few.
    let seq0 = fake.lock().unwrap().seq;
    let end = Instant::now() + Duration::from_secs(10);
    while fake.lock().unwrap().seq < seq0 + 3 {
        assert!(Instant::now() < end, "the fake sent no telemetry for 10 s");
        std::thread::sleep(Duration::from_millis(5));
    }
    let first = port.next_record(Duration::ZERO).unwrap();
    assert!(first.is_some(), "a zero wait missed what had arrived");
    let second = port.next_record(Duration::ZERO).unwrap().unwrap();
    assert_eq!(second.seq, first.unwrap().seq + 1);
}

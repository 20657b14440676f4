//! The console service: one received line in, one [`Answer`] out, for the firmware's console
//! task and the virtual rig alike. The rig's pieces are reached through [`RigAccess`], whose
//! methods each hold a lock only for the closure they run (the firmware implements it over its
//! RTIC resources); the answer is plain data, formatted by its [`fmt::Display`] after every
//! lock is released.
//!
//! Replies (one line each, no line ending): `ok`, the status line, the help line, `id …`,
//! `diag …`, `capture …`, `segment …`, or `error: …` (then nothing changed, except `error: start
//! tripped fault …`, which latched the fault). Asynchronous lines
//! (`!T`, `!E`: [`AsyncRecord`]) are never replies: a reply never starts with `!`.

use core::fmt;

use super::capture::{CAPTURE_RATE_HZ, Capture, CaptureCommand, CaptureStatus, SegmentView};
use super::config::{SAMPLE_RATE_HZ, SensorChain};
use super::console::{Command, Line, ParseError, Request, parse};
use super::controller::Controller;
use super::fixed::Fixed;
use super::link::{LinkStats, MAX_REPLY};
use super::status::{AsyncRecord, CommandError, Reply, State};
use crate::model::RigId;

/// What the board tells about itself (`id`, `diag`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardInfo {
    /// Firmware version.
    pub firmware: &'static str,
    /// Which image: `rig` (the STM32F407 board), `emulator` (QEMU) or `virtual` (host-sim).
    pub board: &'static str,
    /// Time since start-up, ms (the board's independent time base).
    pub uptime_ms: u64,
    /// Deepest stack use so far, bytes (0 where not measured).
    pub stack_hwm_bytes: u32,
    /// The stack's size (the RAM the static data leaves), bytes (0 where not known).
    pub stack_size_bytes: u32,
    /// Longest time between two runs of the sampling task, µs (100 at 10 kHz; 0 where not
    /// measured).
    pub sample_gap_max_us: u32,
}

/// Access to the rig's pieces, each for the duration of one closure.
pub trait RigAccess {
    /// Runs `f` on the controller.
    fn controller<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> R;
    /// Runs `f` on the capture.
    fn capture<R>(&mut self, f: impl FnOnce(&mut Capture) -> R) -> R;
    /// The board's identity and health figures.
    fn board(&mut self) -> BoardInfo;
    /// The link's counters.
    fn link_stats(&mut self) -> LinkStats;
}

/// `id`: what produced a log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdInfo {
    /// The board.
    pub board: BoardInfo,
    /// Rig selected now.
    pub rig: RigId,
    /// Gap set now, mm.
    pub gap_mm: f32,
    /// The force sensor's calibration as the controller uses it.
    pub sensor: SensorChain,
    /// Hammer mass of the rig's model, kg.
    pub mass_kg: f32,
    /// The safe window of drive frequencies, Hz.
    pub freq_window_hz: [f32; 2],
}

impl fmt::Display for IdInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "id firmware={} board={} rig={} gap_mm={} sample_rate_hz={} capture_rate_hz={} volts_per_n={} offset_v={} adc_full_scale_v={} mass_kg={} freq_window_hz={}..{}",
            self.board.firmware,
            self.board.board,
            self.rig.name(),
            Fixed(self.gap_mm, 2),
            SAMPLE_RATE_HZ,
            CAPTURE_RATE_HZ,
            Fixed(self.sensor.volts_per_n, 6),
            Fixed(self.sensor.offset_v, 4),
            Fixed(self.sensor.adc_full_scale_v, 4),
            Fixed(self.mass_kg, 4),
            Fixed(self.freq_window_hz[0], 2),
            Fixed(self.freq_window_hz[1], 2)
        )
    }
}

/// `diag`: the link's and the board's health.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiagInfo {
    /// Samples the controller has processed.
    pub samples: u64,
    /// The board's figures.
    pub board: BoardInfo,
    /// The link's counters.
    pub link: LinkStats,
    /// Cycles lost from `1/1` while tracking.
    pub lost_cycles: u32,
}

impl fmt::Display for DiagInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "diag samples={} uptime_ms={} sample_gap_max_us={} rx_errors={} lines_lost={} async_sent={} async_dropped={} lost_cycles={} stack_hwm_bytes={} stack_size_bytes={}",
            self.samples,
            self.board.uptime_ms,
            self.board.sample_gap_max_us,
            self.link.rx_errors,
            self.link.lines_lost,
            self.link.async_sent,
            self.link.async_dropped,
            self.lost_cycles,
            self.board.stack_hwm_bytes,
            self.board.stack_size_bytes
        )
    }
}

/// Why a `capture` or `start` was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureError {
    /// `capture arm` while the drive is not idle.
    NotIdle,
    /// `start` while a capture records.
    Running,
    /// `capture get k` beyond the recorded segments.
    NoSegment {
        /// Asked for.
        k: u16,
        /// Recorded.
        recorded: u16,
    },
}

impl fmt::Display for CaptureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CaptureError::NotIdle => f.write_str("capture only while idle: stop first"),
            CaptureError::Running => {
                f.write_str("a capture is recording: wait for it or `capture stop`")
            }
            CaptureError::NoSegment { k, recorded } => {
                write!(f, "segment {k} not recorded ({recorded} recorded)")
            }
        }
    }
}

/// Why a line was answered with `error: …`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AnswerError {
    /// The line does not parse.
    Parse(ParseError),
    /// The controller refused the command.
    Command(CommandError),
    /// The capture refused.
    Capture(CaptureError),
    /// A receive error hit the line (or the line queue was full): it did not run.
    Lost,
    /// The line was too long or not text.
    Bad,
}

impl fmt::Display for AnswerError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AnswerError::Parse(e) => write!(f, "{e}"),
            AnswerError::Command(e) => write!(f, "{e}"),
            AnswerError::Capture(e) => write!(f, "{e}"),
            AnswerError::Lost => f.write_str("line lost"),
            AnswerError::Bad => f.write_str("line too long or not text"),
        }
    }
}

/// The answer to one line. A segment (330 bytes) makes it large; it lives on the console
/// task's stack for one reply (no heap on the MCU to box it).
#[derive(Debug, Clone, Copy, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum Answer {
    /// The controller's reply (`ok`, status, help).
    Reply(Reply),
    /// `id`.
    Id(IdInfo),
    /// `diag`.
    Diag(DiagInfo),
    /// `capture`, `capture arm`, `capture stop`: the capture's state line.
    Capture(CaptureStatus),
    /// `capture get k`.
    Segment(SegmentView),
    /// Refused (nothing changed), or a `start` that tripped a fault
    /// ([`CommandError::Tripped`]).
    Error(AnswerError),
}

impl fmt::Display for Answer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Answer::Reply(r) => write!(f, "{r}"),
            Answer::Id(i) => write!(f, "{i}"),
            Answer::Diag(d) => write!(f, "{d}"),
            Answer::Capture(c) => write!(f, "{c}"),
            Answer::Segment(s) => write!(f, "{s}"),
            Answer::Error(e) => write!(f, "error: {e}"),
        }
    }
}

/// Answers one line.
pub fn answer(rig: &mut impl RigAccess, line: Line<'_>) -> Answer {
    let text = match line {
        Line::Text(t) => t,
        Line::Bad => return Answer::Error(AnswerError::Bad),
        Line::Lost => return Answer::Error(AnswerError::Lost),
    };
    let request = match parse(text) {
        Ok(r) => r,
        Err(e) => return Answer::Error(AnswerError::Parse(e)),
    };
    match request {
        Request::Control(Command::Start) if rig.capture(|c| c.active()) => {
            Answer::Error(AnswerError::Capture(CaptureError::Running))
        }
        Request::Control(cmd) => match rig.controller(|c| c.execute(cmd)) {
            Ok(r) => Answer::Reply(r),
            Err(e) => Answer::Error(AnswerError::Command(e)),
        },
        Request::Id => {
            let board = rig.board();
            let (rig_id, gap_mm, sensor, limits) = rig.controller(|c| {
                let s = c.status();
                (s.rig, s.gap_mm, c.config().sensor, c.config().limits)
            });
            Answer::Id(IdInfo {
                board,
                rig: rig_id,
                gap_mm,
                sensor,
                mass_kg: rig_id.preset().mass_kg as f32,
                freq_window_hz: [limits.freq_min_hz, limits.freq_max_hz],
            })
        }
        Request::Diag => {
            let board = rig.board();
            let link = rig.link_stats();
            let (samples, lost_cycles) = rig.controller(|c| (c.samples(), c.status().lost_cycles));
            Answer::Diag(DiagInfo {
                samples,
                board,
                link,
                lost_cycles,
            })
        }
        Request::Capture(cmd) => capture(rig, cmd),
    }
}

fn capture(rig: &mut impl RigAccess, cmd: CaptureCommand) -> Answer {
    match cmd {
        CaptureCommand::Status => Answer::Capture(rig.capture(|c| c.status())),
        CaptureCommand::Stop => Answer::Capture(rig.capture(|c| {
            c.stop();
            c.status()
        })),
        CaptureCommand::Arm { level_n, seconds } => {
            let (state, sensor) = rig.controller(|c| (c.state(), c.config().sensor));
            if state != State::Idle {
                return Answer::Error(AnswerError::Capture(CaptureError::NotIdle));
            }
            Answer::Capture(rig.capture(|c| {
                c.arm(&sensor, level_n, seconds);
                c.status()
            }))
        }
        CaptureCommand::Get(k) => match rig.capture(|c| c.segment(k).ok_or(c.status().segments)) {
            Ok(seg) => Answer::Segment(seg),
            Err(recorded) => Answer::Error(AnswerError::Capture(CaptureError::NoSegment {
                k,
                recorded,
            })),
        },
    }
}

/// A reply line being formatted ([`MAX_REPLY`] bytes).
pub type ReplyText = heapless::String<MAX_REPLY>;
/// An asynchronous line being formatted.
pub type AsyncText = heapless::String<192>;

/// Formats `answer` into `out` (cleared first); a reply that does not fit is replaced by an
/// error line (no reply is that long: tested).
pub fn format_answer(answer: &Answer, out: &mut ReplyText) {
    use core::fmt::Write as _;
    out.clear();
    if write!(out, "{answer}").is_err() {
        out.clear();
        let _ = out.push_str("error: reply too long");
    }
}

/// Formats an asynchronous line into `out` (cleared first); `false` if it does not fit.
pub fn format_async(record: &AsyncRecord, out: &mut AsyncText) -> bool {
    use core::fmt::Write as _;
    out.clear();
    write!(out, "{record}").is_ok()
}

/// [`RigAccess`] over plain references: the virtual rig and tests, where nothing preempts.
pub struct Direct<'a> {
    /// The controller.
    pub controller: &'a mut Controller,
    /// The capture.
    pub capture: &'a mut Capture,
    /// The board's figures.
    pub board: BoardInfo,
    /// The link's counters.
    pub link: LinkStats,
}

impl RigAccess for Direct<'_> {
    fn controller<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> R {
        f(self.controller)
    }
    fn capture<R>(&mut self, f: impl FnOnce(&mut Capture) -> R) -> R {
        f(self.capture)
    }
    fn board(&mut self) -> BoardInfo {
        self.board
    }
    fn link_stats(&mut self) -> LinkStats {
        self.link
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::ControllerConfig;
    use crate::control::capture::SEGMENT_LEN;
    use std::string::String;

    const BOARD: BoardInfo = BoardInfo {
        firmware: "0.0.0-test",
        board: "virtual",
        uptime_ms: 1234,
        stack_hwm_bytes: 0,
        stack_size_bytes: 0,
        sample_gap_max_us: 0,
    };

    fn say(c: &mut Controller, cap: &mut Capture, line: &str) -> String {
        let mut d = Direct {
            controller: c,
            capture: cap,
            board: BOARD,
            link: LinkStats::default(),
        };
        let a = answer(&mut d, Line::Text(line));
        let mut out = ReplyText::new();
        format_answer(&a, &mut out);
        String::from(out.as_str())
    }

    #[test]
    fn console_lines_get_their_replies() {
        let mut c = Controller::new(ControllerConfig::default(), RigId::Wires, 0.0).unwrap();
        let mut cap = Capture::new();
        assert_eq!(
            say(&mut c, &mut cap, "id"),
            "id firmware=0.0.0-test board=virtual rig=wires gap_mm=0.00 sample_rate_hz=10000 \
             capture_rate_hz=100000 volts_per_n=0.010000 offset_v=0.2000 adc_full_scale_v=3.3000 \
             mass_kg=0.2980 freq_window_hz=1.00..30.00"
        );
        assert!(say(&mut c, &mut cap, "diag").starts_with("diag samples=0 uptime_ms=1234 "));
        assert_eq!(say(&mut c, &mut cap, "stream on"), "ok");
        assert!(c.streaming());
        assert_eq!(
            say(&mut c, &mut cap, "bogus"),
            "error: unknown command (try `help`)"
        );
        assert!(say(&mut c, &mut cap, "help").starts_with("commands: status"));
        assert!(
            say(&mut c, &mut cap, "capture arm 2 1").starts_with("capture state=armed segments=0")
        );
        // While a capture records, the drive stays off.
        assert_eq!(
            say(&mut c, &mut cap, "start"),
            "error: a capture is recording: wait for it or `capture stop`"
        );
        assert_eq!(
            say(&mut c, &mut cap, "capture get 0"),
            "error: segment 0 not recorded (0 recorded)"
        );
        assert!(say(&mut c, &mut cap, "capture stop").starts_with("capture state=done"));
        // A receive error's line is answered and runs nothing.
        let mut d = Direct {
            controller: &mut c,
            capture: &mut cap,
            board: BOARD,
            link: LinkStats::default(),
        };
        assert_eq!(answer(&mut d, Line::Lost), Answer::Error(AnswerError::Lost));
    }

    #[test]
    fn the_longest_replies_fit() {
        let seg = Answer::Segment(SegmentView {
            k: 31,
            start: u32::MAX,
            codes: [4095; SEGMENT_LEN],
        });
        let mut out = ReplyText::new();
        format_answer(&seg, &mut out);
        assert!(out.starts_with("segment k=31"), "{out}");
        let diag = Answer::Diag(DiagInfo {
            samples: u64::MAX,
            board: BoardInfo {
                uptime_ms: u64::MAX,
                stack_hwm_bytes: u32::MAX,
                stack_size_bytes: u32::MAX,
                sample_gap_max_us: u32::MAX,
                ..BOARD
            },
            link: LinkStats {
                rx_errors: u32::MAX,
                lines_lost: u32::MAX,
                async_sent: u32::MAX,
                async_dropped: u32::MAX,
            },
            lost_cycles: u32::MAX,
        });
        format_answer(&diag, &mut out);
        assert!(out.starts_with("diag "), "{out}");
        let c = Controller::new(ControllerConfig::default(), RigId::Beam135, 10.0).unwrap();
        format_answer(&Answer::Reply(Reply::Status(c.status())), &mut out);
        assert!(out.starts_with("state=idle"), "{out}");
        format_answer(&Answer::Reply(Reply::Help), &mut out);
        assert!(out.starts_with("commands:"), "{out}");
    }
}

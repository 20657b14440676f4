//! The operator console (USART2, 115200 8N1): bytes are collected into lines by [`LineBuffer`]
//! and each line is parsed by [`parse`] into a [`Request`]. A bad line gives a [`ParseError`]
//! and changes nothing.
//!
//! Commands: `status`, `rig <wires|beam-170|beam-150|beam-135>`, `gap <mm>`, `start`, `stop`,
//! `tune`, `freq <Hz>`, `clear`, `stream <on|off>` (the controller's, [`Command`]); `id`,
//! `diag`, `capture [arm [level_N] [seconds] | stop | get <k>]`, `help` (answered by
//! [`super::serve`]). Case-insensitive; extra spaces and a trailing `\r` are ignored.

use core::fmt;

use super::capture::{CAPTURE_MAX_S, CaptureCommand, DEFAULT_LEVEL_N, DEFAULT_SECONDS, SEGMENTS};
use super::fixed::{Fixed, parse_decimal};
use crate::model::RigId;

/// Longest accepted line, bytes (without the newline).
pub const MAX_LINE: usize = 64;
/// Largest gap accepted at the console, mm.
pub const MAX_GAP_MM: f32 = 10.0;
/// Largest trigger level of `capture arm`, N.
pub const MAX_CAPTURE_LEVEL_N: f32 = 100.0;

/// A command for the controller ([`super::Controller::execute`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// Print the status line.
    Status,
    /// Select the rig (only while idle).
    Rig(RigId),
    /// Set the gap, mm (only while idle).
    Gap(f32),
    /// Ramp up and track the target (or dwell at the manual frequency).
    Start,
    /// Ramp down to idle.
    Stop,
    /// Recompute the target frequency with the model.
    Tune,
    /// Dwell at this frequency, Hz.
    Freq(f32),
    /// Clear a latched fault.
    Clear,
    /// List the commands.
    Help,
    /// Per-cycle telemetry and event lines on (`true`) or off.
    Stream(bool),
}

/// One console line, parsed: a controller command or one of the console's own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// For the controller.
    Control(Command),
    /// Identify the firmware, rig and sensor calibration.
    Id,
    /// Link and board diagnostics (samples, lost lines, stack).
    Diag,
    /// The force capture for drop tests.
    Capture(CaptureCommand),
}

/// Why a line was rejected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParseError {
    /// Nothing but spaces.
    Empty,
    /// The line was longer than [`MAX_LINE`] bytes or not UTF-8.
    TooLong,
    /// The first word is not a command.
    UnknownCommand,
    /// The command needs an argument.
    MissingArgument(&'static str),
    /// An argument was given to a command that takes none, or too many.
    UnexpectedArgument,
    /// The rig name is not one of the four.
    UnknownRig,
    /// `stream` takes `on` or `off`.
    OnOff,
    /// `capture` takes `arm`, `stop` or `get`.
    UnknownCapture,
    /// The number is not a finite decimal number.
    BadNumber(&'static str),
    /// The number is outside its range.
    OutOfRange {
        /// Argument name with unit.
        field: &'static str,
        /// Smallest allowed.
        min: f32,
        /// Largest allowed.
        max: f32,
    },
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParseError::Empty => f.write_str("empty line"),
            ParseError::TooLong => write!(f, "line longer than {MAX_LINE} characters"),
            ParseError::UnknownCommand => f.write_str("unknown command (try `help`)"),
            ParseError::MissingArgument(what) => write!(f, "missing argument: {what}"),
            ParseError::UnexpectedArgument => f.write_str("unexpected argument"),
            ParseError::UnknownRig => {
                f.write_str("rig must be wires, beam-170, beam-150 or beam-135")
            }
            ParseError::OnOff => f.write_str("stream takes on or off"),
            ParseError::UnknownCapture => {
                f.write_str("capture takes arm [level_N] [seconds], stop or get <k>")
            }
            ParseError::BadNumber(what) => write!(f, "{what} must be a number"),
            ParseError::OutOfRange { field, min, max } => write!(
                f,
                "{field} out of range: allowed {} ..= {}",
                Fixed(*min, 2),
                Fixed(*max, 2)
            ),
        }
    }
}

/// The help text, one line.
pub const HELP: &str = "commands: status | rig <wires|beam-170|beam-150|beam-135> | gap <mm> | start | stop | tune | freq <Hz> | clear | stream <on|off> | id | diag | capture [arm [level_N] [seconds] | stop | get <k>] | help";

/// Parses one line.
///
/// # Errors
/// [`ParseError`] saying what is wrong; no state is touched.
pub fn parse(line: &str) -> Result<Request, ParseError> {
    let mut words = line.split_ascii_whitespace();
    let Some(word) = words.next() else {
        return Err(ParseError::Empty);
    };
    let args: [Option<&str>; 3] = [words.next(), words.next(), words.next()];
    if words.next().is_some() {
        return Err(ParseError::UnexpectedArgument);
    }
    let n_args = args.iter().flatten().count();
    let takes = |max: usize, r: Request| {
        if n_args > max {
            Err(ParseError::UnexpectedArgument)
        } else {
            Ok(r)
        }
    };
    let control = |c: Command| takes(0, Request::Control(c));
    let arg = args[0];
    let eq = |name: &str| word.eq_ignore_ascii_case(name);
    if eq("status") {
        control(Command::Status)
    } else if eq("start") {
        control(Command::Start)
    } else if eq("stop") {
        control(Command::Stop)
    } else if eq("tune") {
        control(Command::Tune)
    } else if eq("clear") {
        control(Command::Clear)
    } else if eq("help") {
        control(Command::Help)
    } else if eq("id") {
        takes(0, Request::Id)
    } else if eq("diag") {
        takes(0, Request::Diag)
    } else if eq("rig") {
        let name = arg.ok_or(ParseError::MissingArgument("rig name"))?;
        let rig = [RigId::Wires, RigId::Beam170, RigId::Beam150, RigId::Beam135]
            .into_iter()
            .find(|r| r.name().eq_ignore_ascii_case(name))
            .ok_or(ParseError::UnknownRig)?;
        takes(1, Request::Control(Command::Rig(rig)))
    } else if eq("gap") {
        let v = number(arg, "gap (mm)")?;
        let g = in_range(v, "gap (mm)", 0.0, MAX_GAP_MM)?;
        takes(1, Request::Control(Command::Gap(g)))
    } else if eq("freq") {
        let v = number(arg, "frequency (Hz)")?;
        // The window check is the controller's (it depends on the configuration).
        let f = in_range(v, "frequency (Hz)", 0.0, 1000.0)?;
        takes(1, Request::Control(Command::Freq(f)))
    } else if eq("stream") {
        let on = match arg {
            Some(a) if a.eq_ignore_ascii_case("on") => true,
            Some(a) if a.eq_ignore_ascii_case("off") => false,
            Some(_) => return Err(ParseError::OnOff),
            None => return Err(ParseError::MissingArgument("on or off")),
        };
        takes(1, Request::Control(Command::Stream(on)))
    } else if eq("capture") {
        parse_capture(args, n_args)
    } else {
        Err(ParseError::UnknownCommand)
    }
}

fn parse_capture(args: [Option<&str>; 3], n_args: usize) -> Result<Request, ParseError> {
    let Some(sub) = args[0] else {
        return Ok(Request::Capture(CaptureCommand::Status));
    };
    let too_many = |max: usize| n_args > max;
    let cmd = if sub.eq_ignore_ascii_case("arm") {
        let level_n = match args[1] {
            Some(_) => in_range(
                number(args[1], "level (N)")?,
                "level (N)",
                0.1,
                MAX_CAPTURE_LEVEL_N,
            )?,
            None => DEFAULT_LEVEL_N,
        };
        let seconds = match args[2] {
            Some(_) => in_range(number(args[2], "seconds")?, "seconds", 0.01, CAPTURE_MAX_S)?,
            None => DEFAULT_SECONDS,
        };
        CaptureCommand::Arm { level_n, seconds }
    } else if sub.eq_ignore_ascii_case("stop") {
        if too_many(1) {
            return Err(ParseError::UnexpectedArgument);
        }
        CaptureCommand::Stop
    } else if sub.eq_ignore_ascii_case("get") {
        if too_many(2) {
            return Err(ParseError::UnexpectedArgument);
        }
        let k = number(args[1], "segment")?;
        let max = (SEGMENTS - 1) as f32;
        let k = in_range(k, "segment", 0.0, max)?;
        if k != libm::floorf(k) {
            return Err(ParseError::BadNumber("segment"));
        }
        CaptureCommand::Get(k as u16)
    } else {
        return Err(ParseError::UnknownCapture);
    };
    Ok(Request::Capture(cmd))
}

fn number(arg: Option<&str>, what: &'static str) -> Result<f32, ParseError> {
    let s = arg.ok_or(ParseError::MissingArgument(what))?;
    parse_decimal(s).ok_or(ParseError::BadNumber(what))
}

fn in_range(v: f32, field: &'static str, min: f32, max: f32) -> Result<f32, ParseError> {
    if (min..=max).contains(&v) {
        Ok(v)
    } else {
        Err(ParseError::OutOfRange { field, min, max })
    }
}

/// Why the receiver flagged a byte (the UART's status bits).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RxError {
    /// A byte arrived before the previous one was read (`ORE`): at least one byte is missing.
    Overrun,
    /// No stop bit where one was expected (`FE`).
    Framing,
    /// Noise detected on the line while sampling the byte (`NF`).
    Noise,
    /// Parity mismatch (`PE`; not used at 8N1).
    Parity,
}

/// Collects received bytes into lines. A line whose bytes were received with an error
/// ([`LineBuffer::error`]) or that overflowed [`MAX_LINE`] is handed out as [`Line::Lost`] or
/// [`Line::Bad`] at its end, never as text: a corrupted command cannot run.
#[derive(Debug, Clone, Default)]
pub struct LineBuffer {
    buf: heapless::Vec<u8, MAX_LINE>,
    overflow: bool,
    /// A receive error happened since the line began.
    error: bool,
    /// The buffer holds a line already handed out: start afresh at the next byte.
    done: bool,
}

/// A finished line from [`LineBuffer::push`].
#[derive(Debug, Clone, PartialEq)]
pub enum Line<'a> {
    /// A complete line (without `\r`/`\n`).
    Text(&'a str),
    /// The line was longer than [`MAX_LINE`] or not UTF-8; it is discarded.
    Bad,
    /// A receive error (overrun, framing, noise, parity) hit the line; it is discarded.
    Lost,
}

impl LineBuffer {
    /// Adds one byte; returns the line at `\n` or `\r`. Empty lines are skipped, unless a
    /// receive error was flagged since the last line (then the lost line is reported).
    pub fn push(&mut self, byte: u8) -> Option<Line<'_>> {
        if core::mem::take(&mut self.done) {
            self.buf.clear();
        }
        if byte == b'\n' || byte == b'\r' {
            if core::mem::take(&mut self.error) {
                self.overflow = false;
                self.buf.clear();
                return Some(Line::Lost);
            }
            if core::mem::take(&mut self.overflow) {
                self.buf.clear();
                return Some(Line::Bad);
            }
            if self.buf.is_empty() {
                return None;
            }
            self.done = true;
            return Some(match core::str::from_utf8(&self.buf) {
                Ok(s) => Line::Text(s),
                Err(_) => Line::Bad,
            });
        }
        if self.buf.push(byte).is_err() {
            self.overflow = true;
        }
        None
    }

    /// Flags a receive error: the line being received (or, between lines, the next one) is
    /// discarded at its end and reported as [`Line::Lost`].
    pub fn error(&mut self) {
        if core::mem::take(&mut self.done) {
            self.buf.clear();
        }
        self.error = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_parse() {
        let c = |cmd| Ok(Request::Control(cmd));
        assert_eq!(parse("status"), c(Command::Status));
        assert_eq!(parse("  START \r"), c(Command::Start));
        assert_eq!(parse("rig beam-170"), c(Command::Rig(RigId::Beam170)));
        assert_eq!(parse("RIG Wires"), c(Command::Rig(RigId::Wires)));
        assert_eq!(parse("gap 0.3"), c(Command::Gap(0.3)));
        assert_eq!(parse("freq 3.66"), c(Command::Freq(3.66)));
        assert_eq!(parse("tune"), c(Command::Tune));
        assert_eq!(parse("clear"), c(Command::Clear));
        assert_eq!(parse("stop"), c(Command::Stop));
        assert_eq!(parse("stream ON"), c(Command::Stream(true)));
        assert_eq!(parse("stream off"), c(Command::Stream(false)));
        assert_eq!(parse("id"), Ok(Request::Id));
        assert_eq!(parse("diag"), Ok(Request::Diag));
        assert_eq!(
            parse("capture"),
            Ok(Request::Capture(CaptureCommand::Status))
        );
        assert_eq!(
            parse("capture arm"),
            Ok(Request::Capture(CaptureCommand::Arm {
                level_n: DEFAULT_LEVEL_N,
                seconds: DEFAULT_SECONDS
            }))
        );
        assert_eq!(
            parse("capture arm 2.5 1.5"),
            Ok(Request::Capture(CaptureCommand::Arm {
                level_n: 2.5,
                seconds: 1.5
            }))
        );
        assert_eq!(
            parse("capture get 7"),
            Ok(Request::Capture(CaptureCommand::Get(7)))
        );
        assert_eq!(
            parse("capture stop"),
            Ok(Request::Capture(CaptureCommand::Stop))
        );
    }

    #[test]
    fn bad_lines_are_named() {
        assert_eq!(parse(""), Err(ParseError::Empty));
        assert_eq!(parse("go"), Err(ParseError::UnknownCommand));
        assert_eq!(parse("gap"), Err(ParseError::MissingArgument("gap (mm)")));
        assert_eq!(
            parse("gap -1"),
            Err(ParseError::OutOfRange {
                field: "gap (mm)",
                min: 0.0,
                max: 10.0
            })
        );
        assert_eq!(parse("gap nan"), Err(ParseError::BadNumber("gap (mm)")));
        assert_eq!(parse("gap inf"), Err(ParseError::BadNumber("gap (mm)")));
        assert_eq!(parse("freq 3 4"), Err(ParseError::UnexpectedArgument));
        assert_eq!(parse("start now"), Err(ParseError::UnexpectedArgument));
        assert_eq!(parse("rig beam-200"), Err(ParseError::UnknownRig));
        assert_eq!(
            parse("stream"),
            Err(ParseError::MissingArgument("on or off"))
        );
        assert_eq!(parse("stream maybe"), Err(ParseError::OnOff));
        assert_eq!(parse("id now"), Err(ParseError::UnexpectedArgument));
        assert_eq!(parse("capture fire"), Err(ParseError::UnknownCapture));
        assert_eq!(
            parse("capture get 1.5"),
            Err(ParseError::BadNumber("segment"))
        );
        assert!(matches!(
            parse("capture get 99"),
            Err(ParseError::OutOfRange {
                field: "segment",
                ..
            })
        ));
        assert!(matches!(
            parse("capture arm 0"),
            Err(ParseError::OutOfRange {
                field: "level (N)",
                ..
            })
        ));
        assert_eq!(
            parse("capture stop now"),
            Err(ParseError::UnexpectedArgument)
        );
        assert_eq!(parse("gap 1 2 3 4"), Err(ParseError::UnexpectedArgument));
    }

    #[test]
    fn line_buffer_splits_lines_and_drops_long_ones() {
        let mut b = LineBuffer::default();
        let mut lines = std::vec::Vec::new();
        for &byte in b"status\r\n\ngap 0.3\n"
            .iter()
            .chain([b'x'; 70].iter())
            .chain(b"\nstop\n")
        {
            match b.push(byte) {
                Some(Line::Text(s)) => lines.push(std::string::String::from(s)),
                Some(Line::Bad) => lines.push("<bad>".into()),
                Some(Line::Lost) => lines.push("<lost>".into()),
                None => {}
            }
        }
        assert_eq!(lines, ["status", "gap 0.3", "<bad>", "stop"]);
        let mut b = LineBuffer::default();
        let mut got = None;
        for &byte in &[0xff, 0xfe, b'\n'] {
            if let Some(l) = b.push(byte) {
                got = Some(l == Line::Bad);
            }
        }
        assert_eq!(got, Some(true));
    }

    #[test]
    fn a_receive_error_discards_the_line_it_hits() {
        // `gap 0.5` with its `.` lost to an overrun: the rest arrives as `gap 05`, which must
        // not run.
        let mut b = LineBuffer::default();
        let mut out = std::vec::Vec::new();
        for (i, &byte) in b"gap 05\nstatus\n".iter().enumerate() {
            if i == 5 {
                b.error();
            }
            match b.push(byte) {
                Some(Line::Text(s)) => out.push(std::string::String::from(s)),
                Some(Line::Lost) => out.push("<lost>".into()),
                Some(Line::Bad) => out.push("<bad>".into()),
                None => {}
            }
        }
        assert_eq!(out, ["<lost>", "status"]);
        // An error between lines (noise on an idle line) costs the next line, not more; an
        // error right after a line's end does not reach back into it.
        let mut b = LineBuffer::default();
        assert_eq!(b.push(b'x'), None);
        assert_eq!(b.push(b'\n'), Some(Line::Text("x")));
        b.error();
        assert_eq!(b.push(b'\n'), Some(Line::Lost));
        assert_eq!(b.push(b'y'), None);
        assert_eq!(b.push(b'\n'), Some(Line::Text("y")));
    }
}

//! The operator console (USART2, 115200 8N1): bytes are collected into lines by [`LineBuffer`]
//! and each line is parsed by [`parse`] into a [`Command`]. A bad line gives a [`ParseError`]
//! and changes nothing.
//!
//! Commands: `status`, `rig <wires|beam-170|beam-150|beam-135>`, `gap <mm>`, `start`, `stop`,
//! `tune`, `freq <Hz>`, `clear`, `help`. Case-insensitive; extra spaces and a trailing `\r` are
//! ignored.

use core::fmt;

use super::controller::Controller;
use super::fixed::{Fixed, parse_decimal};
use crate::model::RigId;

/// Longest accepted line, bytes (without the newline).
pub const MAX_LINE: usize = 64;
/// Largest gap accepted at the console, mm.
pub const MAX_GAP_MM: f32 = 10.0;

/// One console command.
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
    /// An argument was given to a command that takes none, or a second one.
    UnexpectedArgument,
    /// The rig name is not one of the four.
    UnknownRig,
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
pub const HELP: &str = "commands: status | rig <wires|beam-170|beam-150|beam-135> | gap <mm> | start | stop | tune | freq <Hz> | clear";

/// Parses one line.
///
/// # Errors
/// [`ParseError`] saying what is wrong; no state is touched.
pub fn parse(line: &str) -> Result<Command, ParseError> {
    let mut words = line.split_ascii_whitespace();
    let Some(word) = words.next() else {
        return Err(ParseError::Empty);
    };
    let arg = words.next();
    if words.next().is_some() {
        return Err(ParseError::UnexpectedArgument);
    }
    let no_arg = |c: Command| match arg {
        None => Ok(c),
        Some(_) => Err(ParseError::UnexpectedArgument),
    };
    let eq = |name: &str| word.eq_ignore_ascii_case(name);
    if eq("status") {
        no_arg(Command::Status)
    } else if eq("start") {
        no_arg(Command::Start)
    } else if eq("stop") {
        no_arg(Command::Stop)
    } else if eq("tune") {
        no_arg(Command::Tune)
    } else if eq("clear") {
        no_arg(Command::Clear)
    } else if eq("help") {
        no_arg(Command::Help)
    } else if eq("rig") {
        let name = arg.ok_or(ParseError::MissingArgument("rig name"))?;
        [RigId::Wires, RigId::Beam170, RigId::Beam150, RigId::Beam135]
            .into_iter()
            .find(|r| r.name().eq_ignore_ascii_case(name))
            .map(Command::Rig)
            .ok_or(ParseError::UnknownRig)
    } else if eq("gap") {
        let v = number(arg, "gap (mm)")?;
        in_range(v, "gap (mm)", 0.0, MAX_GAP_MM).map(Command::Gap)
    } else if eq("freq") {
        let v = number(arg, "frequency (Hz)")?;
        // The window check is the controller's (it depends on the configuration).
        in_range(v, "frequency (Hz)", 0.0, 1000.0).map(Command::Freq)
    } else {
        Err(ParseError::UnknownCommand)
    }
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

/// Runs one console line on the controller and writes its one-line reply (no line ending) to
/// `out`: `ok`, the status line, the help line, or `error: …` (then nothing changed). The
/// firmware's USART2 task and host-sim's virtual rig both answer through this.
///
/// # Errors
/// Only `out`'s write errors.
pub fn respond<W: fmt::Write>(c: &mut Controller, line: Line<'_>, out: &mut W) -> fmt::Result {
    let text = match line {
        Line::Bad => return out.write_str("error: line too long or not text"),
        Line::Text(t) => t,
    };
    match parse(text) {
        Err(e) => write!(out, "error: {e}"),
        Ok(cmd) => match c.execute(cmd) {
            Ok(reply) => write!(out, "{reply}"),
            Err(e) => write!(out, "error: {e}"),
        },
    }
}

/// Collects received bytes into lines.
#[derive(Debug, Clone, Default)]
pub struct LineBuffer {
    buf: heapless::Vec<u8, MAX_LINE>,
    overflow: bool,
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
}

impl LineBuffer {
    /// Adds one byte; returns the line at `\n` or `\r`. Empty lines are skipped.
    pub fn push(&mut self, byte: u8) -> Option<Line<'_>> {
        if core::mem::take(&mut self.done) {
            self.buf.clear();
        }
        if byte == b'\n' || byte == b'\r' {
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_parse() {
        assert_eq!(parse("status"), Ok(Command::Status));
        assert_eq!(parse("  START \r"), Ok(Command::Start));
        assert_eq!(parse("rig beam-170"), Ok(Command::Rig(RigId::Beam170)));
        assert_eq!(parse("RIG Wires"), Ok(Command::Rig(RigId::Wires)));
        assert_eq!(parse("gap 0.3"), Ok(Command::Gap(0.3)));
        assert_eq!(parse("freq 3.66"), Ok(Command::Freq(3.66)));
        assert_eq!(parse("tune"), Ok(Command::Tune));
        assert_eq!(parse("clear"), Ok(Command::Clear));
        assert_eq!(parse("stop"), Ok(Command::Stop));
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
}

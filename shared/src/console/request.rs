//! The request grammar: one console line → one [`Request`] ([`parse`]), or a [`ParseError`]
//! that says what is wrong (and changes nothing). [`Request`]'s [`fmt::Display`] writes the line
//! that parses back to it, which is how the desktop sends requests.
//!
//! Commands: `status`, `rig <name>` (a name of [`RigId::ALL`]), `gap <mm>`, `start`, `stop`,
//! `tune`, `freq <Hz>`, `clear`, `stream <on|off>` (the controller's, [`Command`]); `id`,
//! `diag`, `capture [arm [level_N] [seconds] | stop | get <k> | identify | adopt]`, `help` (answered by
//! [`super::serve`]). Case-insensitive; extra spaces and a trailing `\r` are ignored.

use core::fmt;
use core::str::FromStr;

use super::decimal::{Decimal, Exact, parse_decimal, parse_exact};
use crate::capture::{CAPTURE_MAX_S, CaptureCommand, DEFAULT_LEVEL_N, DEFAULT_SECONDS, SEGMENTS};
use crate::control::{CalibField, Command, MAX_GAP_MM};
use crate::model::{ContactLawKind, ModelEdit, ModelField, RigId, SuspensionKind};

/// Largest trigger level of `capture arm`, N.
pub const MAX_CAPTURE_LEVEL_N: f32 = 100.0;
/// Smallest trigger level of `capture arm`, N.
pub const MIN_CAPTURE_LEVEL_N: f32 = 0.1;
/// Shortest capture of `capture arm`, s.
pub const MIN_CAPTURE_S: f32 = 0.01;
pub use crate::control::{MAX_LINK_TIMEOUT_S, MIN_LINK_TIMEOUT_S};
/// Largest number `freq` takes before the controller's own window check, Hz.
pub const MAX_FREQ_HZ: f32 = 1000.0;

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
    /// List the commands.
    Help,
    /// Echo received characters back (for a terminal program; off at power-up).
    Echo(bool),
    /// `model`: the rig model (the draft's while one is open).
    Model,
    /// `model <field> <value>`, `model law <name>`, `model suspension <wires|beam>`.
    EditModel(ModelEdit),
    /// `calib`: the calibration (the draft's while one is open).
    Calib,
    /// `calib <field> <value>`.
    EditCalib(CalibField, f32),
    /// `draft begin|apply|discard`: stage edits, apply them whole, or drop them.
    Draft(DraftCommand),
    /// `save`: the active model, gap and calibration to flash.
    Save,
    /// `revert`: the stored model, gap and calibration back.
    Revert,
    /// `store`: what the store holds.
    Store,
    /// `reset`: restart the board (idle only).
    Reset,
    /// `commission [start|accept|abort]`: the board's commissioning sequence.
    Commission(CommissionCommand),
}

/// `commission`'s subcommands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommissionCommand {
    /// `commission`: where the sequence is.
    Status,
    /// Start it (drive idle).
    Start,
    /// Store the commissioned model (after its verification passed).
    Accept,
    /// End it now, keeping the model the rig ran before.
    Abort,
}

impl CommissionCommand {
    /// Every subcommand with a word.
    pub const ALL: [CommissionCommand; 3] = [
        CommissionCommand::Start,
        CommissionCommand::Accept,
        CommissionCommand::Abort,
    ];

    /// Its word (empty for the status).
    pub const fn name(self) -> &'static str {
        match self {
            CommissionCommand::Status => "",
            CommissionCommand::Start => "start",
            CommissionCommand::Accept => "accept",
            CommissionCommand::Abort => "abort",
        }
    }
}

/// `draft`'s subcommands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DraftCommand {
    /// Open a draft (a copy of the active model and calibration).
    Begin,
    /// Apply it whole, or nothing.
    Apply,
    /// Drop it.
    Discard,
}

impl DraftCommand {
    /// Every subcommand.
    pub const ALL: [DraftCommand; 3] = [
        DraftCommand::Begin,
        DraftCommand::Apply,
        DraftCommand::Discard,
    ];

    /// Its word.
    pub const fn name(self) -> &'static str {
        match self {
            DraftCommand::Begin => "begin",
            DraftCommand::Apply => "apply",
            DraftCommand::Discard => "discard",
        }
    }
}

/// An argument of a command, as named in [`ParseError`]s.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arg {
    /// `rig`'s name.
    RigName,
    /// `gap`'s value, mm.
    GapMm,
    /// `freq`'s value, Hz.
    FreqHz,
    /// `stream`'s `on` or `off`.
    OnOff,
    /// `capture arm`'s trigger level, N.
    LevelN,
    /// `capture arm`'s time, s.
    Seconds,
    /// `capture get`'s segment number.
    Segment,
    /// `link-timeout`'s time, s.
    LinkTimeoutS,
    /// A model or calibration field's value.
    Value,
    /// `model`'s or `calib`'s field.
    Field,
}

impl Arg {
    /// Every argument.
    pub const ALL: [Arg; 10] = [
        Arg::RigName,
        Arg::GapMm,
        Arg::FreqHz,
        Arg::OnOff,
        Arg::LevelN,
        Arg::Seconds,
        Arg::Segment,
        Arg::LinkTimeoutS,
        Arg::Value,
        Arg::Field,
    ];

    /// Whether it takes a whole number (`capture get`'s segment); the other numbers are
    /// decimal.
    pub fn whole(self) -> bool {
        self == Arg::Segment
    }

    /// Its name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Arg::RigName => "rig name",
            Arg::GapMm => "gap (mm)",
            Arg::FreqHz => "frequency (Hz)",
            Arg::OnOff => "on or off",
            Arg::LevelN => "level (N)",
            Arg::Seconds => "seconds",
            Arg::Segment => "segment",
            Arg::LinkTimeoutS => "link timeout (s)",
            Arg::Value => "value",
            Arg::Field => "field",
        }
    }
}

/// Why a line was rejected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParseError {
    /// Nothing but spaces.
    Empty,
    /// The line was longer than [`super::MAX_LINE`] bytes or not UTF-8.
    TooLong,
    /// The first word is not a command.
    UnknownCommand,
    /// The command needs an argument.
    MissingArgument(Arg),
    /// An argument was given to a command that takes none, or too many.
    UnexpectedArgument,
    /// The rig name is not one of the four.
    UnknownRig,
    /// `stream` and `echo` take `on` or `off`.
    OnOff,
    /// `capture` takes `arm`, `stop`, `get`, `identify` or `adopt`.
    UnknownCapture,
    /// The number is not a finite decimal number (or not a whole one where one is needed).
    BadNumber(Arg),
    /// A `#` at the line's start not followed by a tag: 1 to 9 digits, then a space.
    BadTag,
    /// `model` takes a field of the model, `law <name>` or `suspension <kind>`.
    UnknownModelField,
    /// `calib` takes a field of the calibration.
    UnknownCalibField,
    /// A contact law's name that is not one of the four.
    UnknownLaw,
    /// A suspension that is not `wires` or `beam`.
    UnknownSuspension,
    /// `draft` takes `begin`, `apply` or `discard`.
    UnknownDraft,
    /// `commission` takes nothing, `start`, `accept` or `abort`.
    UnknownCommission,
    /// The number is outside its range.
    OutOfRange {
        /// The argument.
        field: Arg,
        /// Smallest allowed.
        min: f32,
        /// Largest allowed.
        max: f32,
    },
}

/// A text that lists names, built at compile time so that it follows the one list of the names
/// (e.g. [`RigId::NAMES`]): `head`, the names with `sep` between them and `last` before the last
/// one, then `tail`. [`list_text!`] makes it a `&'static str`.
struct NameList<'a> {
    head: &'a str,
    names: &'a [&'a str],
    sep: &'a str,
    last: &'a str,
    tail: &'a str,
}

impl<'a> NameList<'a> {
    /// `head` then `a, b or c`.
    const fn either(head: &'a str, names: &'a [&'a str]) -> Self {
        Self {
            head,
            names,
            sep: ", ",
            last: " or ",
            tail: "",
        }
    }

    /// The pieces of the text, in order, `i` from 0 while it returns `Some`.
    const fn piece(&self, i: usize) -> Option<&'a str> {
        let n = self.names.len();
        if i == 0 {
            return Some(self.head);
        }
        // Then name 0, sep, name 1, ..., last, name n-1 (2n - 1 pieces), then the tail.
        let k = i - 1;
        if k + 1 < 2 * n {
            return Some(if k.is_multiple_of(2) {
                self.names[k / 2]
            } else if k + 3 == 2 * n {
                self.last
            } else {
                self.sep
            });
        }
        if k + 1 == 2 * n || (n == 0 && k == 0) {
            return Some(self.tail);
        }
        None
    }

    /// The text's length in bytes.
    const fn len(&self) -> usize {
        let mut len = 0;
        let mut i = 0;
        while let Some(p) = self.piece(i) {
            len += p.len();
            i += 1;
        }
        len
    }

    /// The text's bytes; `N` is [`NameList::len`].
    const fn bytes<const N: usize>(&self) -> [u8; N] {
        let mut out = [0; N];
        let mut at = 0;
        let mut i = 0;
        while let Some(p) = self.piece(i) {
            let p = p.as_bytes();
            let mut j = 0;
            while j < p.len() {
                out[at] = p[j];
                at += 1;
                j += 1;
            }
            i += 1;
        }
        assert!(at == N, "the text's length is NameList::len");
        out
    }
}

/// The text of a [`NameList`], as a `&'static str` built at compile time.
macro_rules! list_text {
    ($list:expr) => {{
        const LIST: NameList<'static> = $list;
        const BYTES: [u8; LIST.len()] = LIST.bytes();
        match core::str::from_utf8(&BYTES) {
            Ok(text) => text,
            Err(_) => panic!("names and pieces are whole UTF-8 strings"),
        }
    }};
}

const EMPTY: &str = "empty line";
const UNKNOWN_COMMAND: &str = "unknown command (try `help`)";
const UNEXPECTED: &str = "unexpected argument";
const UNKNOWN_RIG: &str = list_text!(NameList::either("rig must be ", &RigId::NAMES));
const ON_OFF: &str = "stream and echo take on or off";
const UNKNOWN_CAPTURE: &str =
    "capture takes arm [level_N] [seconds], stop, get <k>, identify or adopt";
const BAD_TAG: &str = "a tag is # and 1 to 9 digits, then a space";
const MISSING: &str = "missing argument: ";
const NOT_A_NUMBER: &str =
    " must be a plain decimal number such as 0.25 (no exponent, at most 9 significant digits)";
const NOT_A_WHOLE_NUMBER: &str = " must be a whole number";
const NOT_AN_EXACT_NUMBER: &str = " must be a plain decimal number (at most 15 significant digits and 22 decimals) or 0x and the 16 hex digits of its bits";
const UNKNOWN_MODEL_FIELD: &str =
    "model takes a field (`model` shows them), law <name> or suspension <wires|beam>";
const UNKNOWN_CALIB_FIELD: &str = "calib takes a field (`calib` shows them)";
const UNKNOWN_LAW: &str = list_text!(NameList::either("law must be ", &ContactLawKind::NAMES));
const UNKNOWN_SUSPENSION: &str = "suspension must be wires or beam";
const UNKNOWN_DRAFT: &str = "draft takes begin, apply or discard";
const UNKNOWN_COMMISSION: &str = "commission takes start, accept or abort (or nothing)";
const OUT_OF_RANGE: (&str, &str) = (" out of range: allowed ", " ..= ");

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParseError::Empty => f.write_str(EMPTY),
            ParseError::TooLong => write!(f, "line longer than {} characters", super::MAX_LINE),
            ParseError::UnknownCommand => f.write_str(UNKNOWN_COMMAND),
            ParseError::MissingArgument(a) => write!(f, "{MISSING}{}", a.name()),
            ParseError::UnexpectedArgument => f.write_str(UNEXPECTED),
            ParseError::UnknownRig => f.write_str(UNKNOWN_RIG),
            ParseError::OnOff => f.write_str(ON_OFF),
            ParseError::UnknownCapture => f.write_str(UNKNOWN_CAPTURE),
            ParseError::BadTag => f.write_str(BAD_TAG),
            ParseError::UnknownModelField => f.write_str(UNKNOWN_MODEL_FIELD),
            ParseError::UnknownCalibField => f.write_str(UNKNOWN_CALIB_FIELD),
            ParseError::UnknownLaw => f.write_str(UNKNOWN_LAW),
            ParseError::UnknownSuspension => f.write_str(UNKNOWN_SUSPENSION),
            ParseError::UnknownDraft => f.write_str(UNKNOWN_DRAFT),
            ParseError::UnknownCommission => f.write_str(UNKNOWN_COMMISSION),
            ParseError::BadNumber(a) => {
                let rule = number_rule(*a);
                write!(f, "{}{rule}", a.name())
            }
            ParseError::OutOfRange { field, min, max } => write!(
                f,
                "{}{}{}{}{}",
                field.name(),
                OUT_OF_RANGE.0,
                Decimal(*min, 2),
                OUT_OF_RANGE.1,
                Decimal(*max, 2)
            ),
        }
    }
}

impl FromStr for ParseError {
    type Err = ();

    /// The error of a text [`fmt::Display`] wrote.
    fn from_str(s: &str) -> Result<Self, ()> {
        let unit = [
            ParseError::Empty,
            ParseError::TooLong,
            ParseError::UnknownCommand,
            ParseError::UnexpectedArgument,
            ParseError::UnknownRig,
            ParseError::OnOff,
            ParseError::UnknownCapture,
            ParseError::BadTag,
            ParseError::UnknownModelField,
            ParseError::UnknownCalibField,
            ParseError::UnknownLaw,
            ParseError::UnknownSuspension,
            ParseError::UnknownDraft,
            ParseError::UnknownCommission,
        ];
        if let Some(e) = unit.into_iter().find(|e| super::displays_as(e, s)) {
            return Ok(e);
        }
        if let Some(name) = s.strip_prefix(MISSING) {
            return arg_named(name).map(ParseError::MissingArgument);
        }
        for rule in [NOT_A_NUMBER, NOT_A_WHOLE_NUMBER, NOT_AN_EXACT_NUMBER] {
            if let Some(name) = s.strip_suffix(rule) {
                return arg_named(name)
                    .ok()
                    .filter(|a| number_rule(*a) == rule)
                    .map(ParseError::BadNumber)
                    .ok_or(());
            }
        }
        let (name, range) = s.split_once(OUT_OF_RANGE.0).ok_or(())?;
        let (min, max) = range.split_once(OUT_OF_RANGE.1).ok_or(())?;
        Ok(ParseError::OutOfRange {
            field: arg_named(name)?,
            min: parse_decimal(min).ok_or(())?,
            max: parse_decimal(max).ok_or(())?,
        })
    }
}

/// What a number of `arg` must be.
fn number_rule(arg: Arg) -> &'static str {
    match arg {
        Arg::Segment => NOT_A_WHOLE_NUMBER,
        Arg::Value => NOT_AN_EXACT_NUMBER,
        _ => NOT_A_NUMBER,
    }
}

fn arg_named(name: &str) -> Result<Arg, ()> {
    Arg::ALL.into_iter().find(|a| a.name() == name).ok_or(())
}

/// The help text, one line.
pub const HELP: &str = list_text!(NameList {
    head: "commands: status | rig <",
    names: &RigId::NAMES,
    sep: "|",
    last: "|",
    tail: "> (a preset) | gap <mm> | start | stop | tune | freq <Hz> | clear | stream <on|off> | link-timeout <s> (0: off) | echo <on|off> | id | diag | capture [arm [level_N] [seconds] | stop | get <k> | identify | adopt] | model [<field> <value> | law <name> | suspension <wires|beam>] | calib [<field> <value>] | draft <begin|apply|discard> | save | revert | store | reset | commission [start|accept|abort] | help; a line may start with #<n>, its reply then does too",
});

// The help line, tagged (`#` and 9 digits, a space), fits a reply: a rig or command added to it
// that would not stops the build here.
const _: () = assert!(HELP.len() + 11 <= super::link::MAX_REPLY);

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
        takes(0, Request::Help)
    } else if eq("id") {
        takes(0, Request::Id)
    } else if eq("diag") {
        takes(0, Request::Diag)
    } else if eq("rig") {
        let name = arg.ok_or(ParseError::MissingArgument(Arg::RigName))?;
        let rig = RigId::ALL
            .into_iter()
            .find(|r| r.name().eq_ignore_ascii_case(name))
            .ok_or(ParseError::UnknownRig)?;
        takes(1, Request::Control(Command::Rig(rig)))
    } else if eq("gap") {
        let g = in_range(number(arg, Arg::GapMm)?, Arg::GapMm, 0.0, MAX_GAP_MM)?;
        takes(1, Request::Control(Command::Gap(g)))
    } else if eq("freq") {
        // The window check is the controller's (it depends on the configuration).
        let f = in_range(number(arg, Arg::FreqHz)?, Arg::FreqHz, 0.0, MAX_FREQ_HZ)?;
        takes(1, Request::Control(Command::Freq(f)))
    } else if eq("stream") {
        takes(1, Request::Control(Command::Stream(on_off(arg)?)))
    } else if eq("echo") {
        takes(1, Request::Echo(on_off(arg)?))
    } else if eq("link-timeout") {
        let s = in_range(
            number(arg, Arg::LinkTimeoutS)?,
            Arg::LinkTimeoutS,
            0.0,
            MAX_LINK_TIMEOUT_S,
        )?;
        takes(1, Request::Control(Command::LinkTimeout(s)))
    } else if eq("capture") {
        parse_capture(args, n_args)
    } else if eq("model") {
        parse_model(args, n_args)
    } else if eq("calib") {
        let Some(name) = arg else {
            return Ok(Request::Calib);
        };
        let field = name.parse().map_err(|()| ParseError::UnknownCalibField)?;
        let v = exact(args[1])?;
        takes(2, Request::EditCalib(field, v as f32))
    } else if eq("draft") {
        let name = arg.ok_or(ParseError::UnknownDraft)?;
        let d = DraftCommand::ALL
            .into_iter()
            .find(|d| d.name().eq_ignore_ascii_case(name))
            .ok_or(ParseError::UnknownDraft)?;
        takes(1, Request::Draft(d))
    } else if eq("save") {
        takes(0, Request::Save)
    } else if eq("revert") {
        takes(0, Request::Revert)
    } else if eq("store") {
        takes(0, Request::Store)
    } else if eq("reset") {
        takes(0, Request::Reset)
    } else if eq("commission") {
        let c = match arg {
            None => CommissionCommand::Status,
            Some(name) => CommissionCommand::ALL
                .into_iter()
                .find(|c| c.name().eq_ignore_ascii_case(name))
                .ok_or(ParseError::UnknownCommission)?,
        };
        takes(1, Request::Commission(c))
    } else {
        Err(ParseError::UnknownCommand)
    }
}

fn parse_capture(args: [Option<&str>; 3], n_args: usize) -> Result<Request, ParseError> {
    let Some(sub) = args[0] else {
        return Ok(Request::Capture(CaptureCommand::Status));
    };
    let too_many = |max: usize| n_args > max;
    // An optional number: its default when absent, else in `min ..= max`.
    let optional = |arg: Option<&str>, what: Arg, default: f32, min: f32, max: f32| match arg {
        Some(_) => in_range(number(arg, what)?, what, min, max),
        None => Ok(default),
    };
    let cmd = if sub.eq_ignore_ascii_case("arm") {
        CaptureCommand::Arm {
            level_n: optional(
                args[1],
                Arg::LevelN,
                DEFAULT_LEVEL_N,
                MIN_CAPTURE_LEVEL_N,
                MAX_CAPTURE_LEVEL_N,
            )?,
            seconds: optional(
                args[2],
                Arg::Seconds,
                DEFAULT_SECONDS,
                MIN_CAPTURE_S,
                CAPTURE_MAX_S,
            )?,
        }
    } else if sub.eq_ignore_ascii_case("stop") {
        if too_many(1) {
            return Err(ParseError::UnexpectedArgument);
        }
        CaptureCommand::Stop
    } else if sub.eq_ignore_ascii_case("identify") || sub.eq_ignore_ascii_case("adopt") {
        if too_many(1) {
            return Err(ParseError::UnexpectedArgument);
        }
        if sub.eq_ignore_ascii_case("adopt") {
            CaptureCommand::Adopt
        } else {
            CaptureCommand::Identify
        }
    } else if sub.eq_ignore_ascii_case("get") {
        if too_many(2) {
            return Err(ParseError::UnexpectedArgument);
        }
        let k = number(args[1], Arg::Segment)?;
        let max = (SEGMENTS - 1) as f32;
        let k = in_range(k, Arg::Segment, 0.0, max)?;
        if k != libm::floorf(k) {
            return Err(ParseError::BadNumber(Arg::Segment));
        }
        CaptureCommand::Get(k as u16)
    } else {
        return Err(ParseError::UnknownCapture);
    };
    Ok(Request::Capture(cmd))
}

fn parse_model(args: [Option<&str>; 3], n_args: usize) -> Result<Request, ParseError> {
    let Some(word) = args[0] else {
        return Ok(Request::Model);
    };
    if n_args > 2 {
        return Err(ParseError::UnexpectedArgument);
    }
    let edit = if word.eq_ignore_ascii_case("law") {
        let name = args[1].ok_or(ParseError::MissingArgument(Arg::Field))?;
        ModelEdit::Law(
            ContactLawKind::ALL
                .into_iter()
                .find(|k| k.name().eq_ignore_ascii_case(name))
                .ok_or(ParseError::UnknownLaw)?,
        )
    } else if word.eq_ignore_ascii_case("suspension") {
        let name = args[1].ok_or(ParseError::MissingArgument(Arg::Field))?;
        ModelEdit::Suspension(
            name.parse::<SuspensionKind>()
                .map_err(|()| ParseError::UnknownSuspension)?,
        )
    } else {
        let field: ModelField = word.parse().map_err(|()| ParseError::UnknownModelField)?;
        ModelEdit::Set(field, exact(args[1])?)
    };
    Ok(Request::EditModel(edit))
}

/// A model or calibration value: [`parse_exact`]'s.
fn exact(arg: Option<&str>) -> Result<f64, ParseError> {
    let s = arg.ok_or(ParseError::MissingArgument(Arg::Value))?;
    parse_exact(s).ok_or(ParseError::BadNumber(Arg::Value))
}

fn on_off(arg: Option<&str>) -> Result<bool, ParseError> {
    match arg {
        Some(a) if a.eq_ignore_ascii_case("on") => Ok(true),
        Some(a) if a.eq_ignore_ascii_case("off") => Ok(false),
        Some(_) => Err(ParseError::OnOff),
        None => Err(ParseError::MissingArgument(Arg::OnOff)),
    }
}

fn number(arg: Option<&str>, what: Arg) -> Result<f32, ParseError> {
    let s = arg.ok_or(ParseError::MissingArgument(what))?;
    parse_decimal(s).ok_or(ParseError::BadNumber(what))
}

fn in_range(v: f32, field: Arg, min: f32, max: f32) -> Result<f32, ParseError> {
    if (min..=max).contains(&v) {
        Ok(v)
    } else {
        Err(ParseError::OutOfRange { field, min, max })
    }
}

fn on_off_text(on: bool) -> &'static str {
    if on { "on" } else { "off" }
}

/// The line of a request: what [`parse`] reads back as the same request (numbers in their
/// shortest exact decimal form; meant for the desktop, which sends requests).
impl fmt::Display for Request {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Request::Control(c) => match c {
                Command::Status => f.write_str("status"),
                Command::Rig(r) => write!(f, "rig {}", r.name()),
                Command::Gap(g) => write!(f, "gap {g}"),
                Command::Start => f.write_str("start"),
                Command::Stop => f.write_str("stop"),
                Command::Tune => f.write_str("tune"),
                Command::Freq(hz) => write!(f, "freq {hz}"),
                Command::Clear => f.write_str("clear"),
                Command::Stream(on) => write!(f, "stream {}", on_off_text(on)),
                Command::LinkTimeout(s) => write!(f, "link-timeout {s}"),
            },
            Request::Echo(on) => write!(f, "echo {}", on_off_text(on)),
            Request::Id => f.write_str("id"),
            Request::Diag => f.write_str("diag"),
            Request::Help => f.write_str("help"),
            Request::Model => f.write_str("model"),
            Request::EditModel(ModelEdit::Set(field, v)) => {
                write!(f, "model {field} {}", Exact::f64(v))
            }
            Request::EditModel(ModelEdit::Law(kind)) => write!(f, "model law {kind}"),
            Request::EditModel(ModelEdit::Suspension(kind)) => {
                write!(f, "model suspension {kind}")
            }
            Request::Calib => f.write_str("calib"),
            Request::EditCalib(field, v) => write!(f, "calib {field} {}", Exact::f32(v)),
            Request::Draft(d) => write!(f, "draft {}", d.name()),
            Request::Save => f.write_str("save"),
            Request::Revert => f.write_str("revert"),
            Request::Store => f.write_str("store"),
            Request::Reset => f.write_str("reset"),
            Request::Commission(CommissionCommand::Status) => f.write_str("commission"),
            Request::Commission(c) => write!(f, "commission {}", c.name()),
            Request::Capture(c) => match c {
                CaptureCommand::Status => f.write_str("capture"),
                CaptureCommand::Arm { level_n, seconds } => {
                    write!(f, "capture arm {level_n} {seconds}")
                }
                CaptureCommand::Stop => f.write_str("capture stop"),
                CaptureCommand::Get(k) => write!(f, "capture get {k}"),
                CaptureCommand::Identify => f.write_str("capture identify"),
                CaptureCommand::Adopt => f.write_str("capture adopt"),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

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
        assert_eq!(parse("HELP"), Ok(Request::Help));
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
        assert_eq!(parse("gap"), Err(ParseError::MissingArgument(Arg::GapMm)));
        assert_eq!(
            parse("gap -1"),
            Err(ParseError::OutOfRange {
                field: Arg::GapMm,
                min: 0.0,
                max: 10.0
            })
        );
        assert_eq!(parse("gap nan"), Err(ParseError::BadNumber(Arg::GapMm)));
        assert_eq!(parse("gap inf"), Err(ParseError::BadNumber(Arg::GapMm)));
        // A number the console's decimal reader does not take says what it takes.
        let e = parse("gap 1e-3").unwrap_err();
        assert_eq!(e, ParseError::BadNumber(Arg::GapMm));
        assert_eq!(
            e.to_string(),
            "gap (mm) must be a plain decimal number such as 0.25 (no exponent, at most 9 \
             significant digits)"
        );
        assert_eq!(
            parse("capture get 1.5").unwrap_err().to_string(),
            "segment must be a whole number"
        );
        assert_eq!(parse("freq 3 4"), Err(ParseError::UnexpectedArgument));
        assert_eq!(parse("start now"), Err(ParseError::UnexpectedArgument));
        assert_eq!(parse("rig beam-200"), Err(ParseError::UnknownRig));
        assert_eq!(
            parse("stream"),
            Err(ParseError::MissingArgument(Arg::OnOff))
        );
        assert_eq!(parse("stream maybe"), Err(ParseError::OnOff));
        assert_eq!(parse("id now"), Err(ParseError::UnexpectedArgument));
        assert_eq!(parse("capture fire"), Err(ParseError::UnknownCapture));
        assert_eq!(
            parse("capture get 1.5"),
            Err(ParseError::BadNumber(Arg::Segment))
        );
        assert!(matches!(
            parse("capture get 99"),
            Err(ParseError::OutOfRange {
                field: Arg::Segment,
                ..
            })
        ));
        assert!(matches!(
            parse("capture arm 0"),
            Err(ParseError::OutOfRange {
                field: Arg::LevelN,
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
    fn error_texts_read_back() {
        for line in [
            "",
            "go",
            "gap",
            "gap -1",
            "gap nan",
            "freq 3 4",
            "rig beam-200",
            "stream",
            "stream maybe",
            "capture fire",
            "capture get 1.5",
            "capture get 99",
            "capture arm 0",
            "capture arm 1 100",
        ] {
            let e = parse(line).unwrap_err();
            assert_eq!(e.to_string().parse::<ParseError>(), Ok(e), "{line}");
        }
        assert_eq!(
            "line longer than 64 characters".parse(),
            Ok(ParseError::TooLong)
        );
        assert!("gap (mm) must be a numbr".parse::<ParseError>().is_err());
        // Each rule reads back only for the arguments it is said of.
        assert!(
            "gap (mm) must be a whole number"
                .parse::<ParseError>()
                .is_err()
        );
        assert!(
            "segment must be a plain decimal number such as 0.25 (no exponent, at most 9 \
             significant digits)"
                .parse::<ParseError>()
                .is_err()
        );
    }

    #[test]
    fn name_lists_follow_their_lists() {
        // The texts that list rigs and laws are built from `RigId::ALL` and
        // `ContactLawKind::ALL`: a new rig or law is in each of them.
        let either = |names: &[&str]| {
            let (last, rest) = names.split_last().unwrap();
            std::format!("{} or {last}", rest.join(", "))
        };
        let rigs: std::vec::Vec<&str> = RigId::ALL.iter().map(|r| r.name()).collect();
        let laws: std::vec::Vec<&str> = ContactLawKind::ALL.iter().map(|k| k.name()).collect();
        assert_eq!(
            ParseError::UnknownRig.to_string(),
            std::format!("rig must be {}", either(&rigs))
        );
        assert_eq!(
            ParseError::UnknownLaw.to_string(),
            std::format!("law must be {}", either(&laws))
        );
        assert!(HELP.starts_with(&std::format!(
            "commands: status | rig <{}> (a preset) | gap <mm> |",
            rigs.join("|")
        )));
        for r in RigId::ALL {
            assert_eq!(
                parse(&std::format!("rig {r}")),
                Ok(Request::Control(Command::Rig(r)))
            );
        }
        // The builder's edges: one name, two, none.
        const ONE: &str = list_text!(NameList::either("x: ", &["a"]));
        const TWO: &str = list_text!(NameList::either("x: ", &["a", "b"]));
        const NONE: &str = list_text!(NameList {
            head: "<",
            names: &[],
            sep: "|",
            last: "|",
            tail: ">"
        });
        assert_eq!((ONE, TWO, NONE), ("x: a", "x: a or b", "<>"));
    }
}

//! The console service: one received line in, one [`Answer`] out, for the firmware's console
//! task and the virtual rig alike. The rig's pieces are reached through [`RigAccess`], whose
//! methods each hold a lock only for the closure they run (the firmware implements it over its
//! RTIC resources); the answer is plain data, formatted by its [`core::fmt::Display`] after
//! every lock is released.
//!
//! Every line gets one [`Response`]; an `error: …` means nothing changed, except `error: start
//! tripped fault …`, which latched the fault. A line that starts with a tag `#<n> ` (n: 1 to 9
//! digits) gets its reply with the same tag, so that the desktop matches every reply to its
//! line. Asynchronous lines (`!T`, `!E`: [`AsyncRecord`]) are never replies: a reply never starts
//! with `!`.

use core::fmt;
use core::str::FromStr;

use super::commission::{CommissionLine, CommissionView};
use super::drop_id::IdentifyLine;
use super::fields::WireError;
use super::framing::Line;
use super::link::{Link, MAX_REPLY};
use super::reply::{Answer, AnswerError, BoardInfo, CaptureError, DiagInfo, IdInfo};
use super::request::CommissionCommand;
use super::request::{DraftCommand, ParseError, Request, parse};
use super::settings::{CalibView, ModelOf, ModelView, SettingsRefusal, StoreRefusal, StoreView};
use crate::capture::{CAPTURE_RATE_HZ, Capture, CaptureCommand};
use crate::commission::{Commission, CommissionRefusal, RigPieces, identify_capture, store_active};
use crate::control::{
    AsyncRecord, Command, CommandError, Controller, ModelSource, SAMPLE_RATE_HZ, SettingsError,
    State,
};
use crate::store::SettingsStore;

/// Access to the rig's pieces ([`RigPieces`]: the controller, the capture, the store), each for
/// the duration of one closure, and to the console's own.
pub trait RigAccess: RigPieces {
    /// The board's identity and health figures.
    fn board(&mut self) -> BoardInfo;
    /// Runs `f` on the console's link (its counters, its echo).
    fn link<R>(&mut self, f: impl FnOnce(&mut Link) -> R) -> R;
    /// Runs `f` on the commissioning sequence (the console service's own).
    fn commission<R>(&mut self, f: impl FnOnce(&mut Commission) -> R) -> R;
    /// A `reset` was accepted: restart the board once its reply has gone out.
    fn reset_after_reply(&mut self);
}

/// The reply to one line, and the tag of the line it answers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Response {
    /// The line's tag (`#<n> ` at its start), repeated before the reply.
    pub tag: Option<u32>,
    /// The reply.
    pub answer: Answer,
}

/// Longest tag, digits.
const TAG_DIGITS: usize = 9;

/// A line's tag and the rest: `#<n> rest` → `(Some(n), rest)`; a line without `#` →
/// `(None, line)`.
///
/// # Errors
/// [`ParseError::BadTag`]: a `#` not followed by 1 to 9 digits and a space (or the line's end).
pub fn split_tag(line: &str) -> Result<(Option<u32>, &str), ParseError> {
    // Bytes, not chars: no Unicode tables on the MCU for the ASCII this reads.
    let start = line.bytes().take_while(u8::is_ascii_whitespace).count();
    let Some(rest) = line.get(start..).and_then(|l| l.strip_prefix('#')) else {
        return Ok((None, line));
    };
    let mut tag: u32 = 0;
    let mut digits = 0;
    for b in rest.bytes() {
        if !b.is_ascii_digit() {
            break;
        }
        // At most 9 digits: below 10⁹, no overflow.
        tag = tag.wrapping_mul(10).wrapping_add(u32::from(b - b'0'));
        digits += 1;
    }
    let after = rest.get(digits..).unwrap_or("");
    if digits == 0
        || digits > TAG_DIGITS
        || !(after.is_empty()
            || after
                .as_bytes()
                .first()
                .is_some_and(u8::is_ascii_whitespace))
    {
        return Err(ParseError::BadTag);
    }
    Ok((Some(tag), after))
}

impl fmt::Display for Response {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(t) = self.tag {
            write!(f, "#{t} ")?;
        }
        write!(f, "{}", self.answer)
    }
}

impl FromStr for Response {
    type Err = WireError;

    /// Reads a reply line, tagged or not.
    fn from_str(s: &str) -> Result<Self, WireError> {
        let (tag, rest) = split_tag(s).map_err(|_| WireError::Bad("#"))?;
        let rest = if tag.is_some() {
            rest.strip_prefix(' ').ok_or(WireError::Bad("#"))?
        } else {
            rest
        };
        Ok(Response {
            tag,
            answer: rest.parse()?,
        })
    }
}

/// Answers one line.
pub fn answer(rig: &mut impl RigAccess, line: Line<'_>) -> Response {
    let text = match line {
        Line::Text(t) => t,
        Line::Bad => return untagged(AnswerError::Bad),
        Line::Lost => return untagged(AnswerError::Lost),
    };
    let (tag, text) = match split_tag(text) {
        Ok(t) => t,
        Err(e) => return untagged(AnswerError::Parse(e)),
    };
    Response {
        tag,
        answer: answer_request(rig, parse(text)),
    }
}

fn untagged(e: AnswerError) -> Response {
    Response {
        tag: None,
        answer: Answer::Error(e),
    }
}

fn answer_request(rig: &mut impl RigAccess, request: Result<Request, ParseError>) -> Answer {
    let request = match request {
        Ok(r) => r,
        Err(e) => return Answer::Error(AnswerError::Parse(e)),
    };
    if let Some(step) = rig.commission(|c| c.phase().step())
        && !taken_while_commissioning(&request)
    {
        return Answer::Error(AnswerError::Commission(CommissionRefusal::Busy(step)));
    }
    match request {
        Request::Commission(cmd) => commission(rig, cmd),
        Request::Control(Command::Start) if rig.capture(|c| c.active()) => {
            Answer::Error(AnswerError::Capture(CaptureError::Running))
        }
        Request::Control(cmd) => match rig.controller(|c| c.execute(cmd)) {
            Ok(r) => Answer::Reply(r),
            Err(e) => Answer::Error(AnswerError::Command(e)),
        },
        Request::Help => Answer::Help,
        Request::Echo(on) => {
            rig.link(|l| l.set_echo(on));
            Answer::Reply(crate::control::Reply::Ok)
        }
        Request::Id => {
            let board = rig.board();
            let store = rig.store(|s| s.status().state);
            let (rig_id, mass_kg, gap_mm, sensor, limits) = rig.controller(|c| {
                let (params, id) = c.model();
                (
                    id,
                    params.mass_kg as f32,
                    c.gap_mm(),
                    c.config().sensor,
                    c.config().limits,
                )
            });
            Answer::Id(IdInfo {
                firmware: board.firmware,
                board: board.board,
                rig: rig_id,
                store,
                gap_mm,
                sample_rate_hz: SAMPLE_RATE_HZ,
                capture_rate_hz: CAPTURE_RATE_HZ,
                sensor,
                mass_kg,
                freq_window_hz: [limits.freq_min_hz, limits.freq_max_hz],
                slew_hz_per_s: limits.freq_slew_hz_per_s,
                ramp_mm_per_s: limits.amp_ramp_mm_per_s,
                force_limit_n: limits.force_limit_n,
            })
        }
        Request::Diag => {
            let board = rig.board();
            let link = rig.link(|l| l.stats());
            let (samples, lost_cycles, link_timeout) = rig.controller(|c| {
                (
                    c.samples(),
                    c.status().lost_cycles,
                    c.link_timeout_samples(),
                )
            });
            Answer::Diag(DiagInfo {
                samples,
                uptime_ms: board.uptime_ms,
                sample_gap_max_us: board.sample_gap_max_us,
                link,
                lost_cycles,
                stack_hwm_bytes: board.stack_hwm_bytes,
                stack_size_bytes: board.stack_size_bytes,
                link_timeout_ms: ms_of_samples(link_timeout),
            })
        }
        Request::Capture(cmd) => capture(rig, cmd),
        Request::Model => rig.controller(|c| model_line(c)),
        Request::EditModel(edit) => {
            settled(rig.controller(|c| c.edit_model(edit).map(|()| model_line(c))))
        }
        Request::Calib => rig.controller(|c| calib_line(c)),
        Request::EditCalib(field, value) => {
            settled(rig.controller(|c| c.edit_calibration(field, value).map(|()| calib_line(c))))
        }
        Request::Draft(d) => settled(rig.controller(|c| {
            match d {
                DraftCommand::Begin => c.begin_draft(),
                DraftCommand::Apply => c.apply_draft(),
                DraftCommand::Discard => c.discard_draft(),
            }
            .map(|()| model_line(c))
        })),
        Request::Store => Answer::Store(store_line(rig)),
        Request::Save => save(rig),
        Request::Revert => revert(rig),
        Request::Reset => match idle(rig) {
            Ok(()) => {
                rig.reset_after_reply();
                Answer::Reply(crate::control::Reply::Ok)
            }
            Err(e) => Answer::Error(e),
        },
    }
}

/// The model line: the draft's while one is open, else the active model's.
fn model_line(c: &Controller) -> Answer {
    Answer::Model(match c.draft() {
        Some(d) => ModelView {
            of: ModelOf::Draft,
            params: d.params,
        },
        None => {
            let (params, id) = c.model();
            ModelView {
                of: ModelOf::Active(id.source),
                params: *params,
            }
        }
    })
}

/// The calibration line: the draft's while one is open, else the active one.
fn calib_line(c: &Controller) -> Answer {
    Answer::Calib(match c.draft() {
        Some(d) => CalibView {
            draft: true,
            calibration: d.calibration,
        },
        None => CalibView {
            draft: false,
            calibration: c.calibration(),
        },
    })
}

/// The answer of a settings change: its line, or its refusal.
fn settled(result: Result<Answer, SettingsError>) -> Answer {
    match result {
        Ok(a) => a,
        Err(e) => Answer::Error(refusal(e)),
    }
}

fn refusal(e: SettingsError) -> AnswerError {
    match (e, SettingsRefusal::of(e)) {
        (SettingsError::Command(c), _) => AnswerError::Command(c),
        (_, Some(r)) => AnswerError::Settings(r),
        // `of` answers every error but the command's.
        (_, None) => AnswerError::Settings(SettingsRefusal::NoDraft),
    }
}

fn store_line(rig: &mut impl RigAccess) -> StoreView {
    let s = rig.store(|s| s.status());
    StoreView {
        state: s.state,
        saves: s.saves,
        hash: s.hash,
    }
}

/// The drive idle and no capture recording (what touching the flash or resetting needs).
fn idle(rig: &mut impl RigAccess) -> Result<(), AnswerError> {
    let state = rig.controller(|c| c.state());
    match state {
        State::Idle => {}
        State::Fault => return Err(AnswerError::Command(CommandError::FaultLatched)),
        s => return Err(AnswerError::Command(CommandError::NotIdle(s))),
    }
    if rig.capture(|c| c.active()) {
        return Err(AnswerError::Capture(CaptureError::Running));
    }
    Ok(())
}

/// `save`: the active settings to the store, the controller's deadline checks paused while the
/// flash is written (the CPU stalls on the board's flash).
fn save(rig: &mut impl RigAccess) -> Answer {
    if let Err(e) = idle(rig) {
        return Answer::Error(e);
    }
    match store_active(rig) {
        Ok(_) => Answer::Store(store_line(rig)),
        Err(e) => Answer::Error(AnswerError::Store(StoreRefusal::SaveFailed(e))),
    }
}

/// What may run while a commissioning sequence does: reading, the drive's `stop` and `clear`,
/// the link's own settings, `reset` (nothing of the sequence is stored) and the sequence's
/// commands.
fn taken_while_commissioning(request: &Request) -> bool {
    match request {
        Request::Control(c) => matches!(
            c,
            Command::Status
                | Command::Stop
                | Command::Clear
                | Command::Stream(_)
                | Command::LinkTimeout(_)
        ),
        Request::Capture(c) => matches!(
            c,
            CaptureCommand::Status | CaptureCommand::Get(_) | CaptureCommand::Identify
        ),
        Request::Id
        | Request::Diag
        | Request::Help
        | Request::Echo(_)
        | Request::Model
        | Request::Calib
        | Request::Store
        | Request::Reset
        | Request::Commission(_) => true,
        Request::EditModel(_)
        | Request::EditCalib(..)
        | Request::Draft(_)
        | Request::Save
        | Request::Revert => false,
    }
}

/// Runs `f` on the commissioning sequence and the rig together (the sequence is taken out of
/// its place meanwhile).
fn with_commission<A: RigAccess, R>(
    rig: &mut A,
    f: impl FnOnce(&mut Commission, &mut A) -> R,
) -> R {
    let mut seq = rig.commission(core::mem::take);
    let r = f(&mut seq, rig);
    rig.commission(|c| *c = seq);
    r
}

fn commission_view(rig: &mut impl RigAccess) -> Answer {
    Answer::Commission(rig.commission(|c| CommissionView::of(c.phase(), c.records())))
}

fn commission(rig: &mut impl RigAccess, cmd: CommissionCommand) -> Answer {
    let done = match cmd {
        CommissionCommand::Status => Ok(()),
        CommissionCommand::Start => with_commission(rig, |c, r| c.start(r)),
        CommissionCommand::Abort => with_commission(rig, |c, r| c.abort(r)),
        CommissionCommand::Accept => {
            return match with_commission(rig, |c, r| c.accept(r)) {
                Ok(Ok(_)) => Answer::Store(store_line(rig)),
                Ok(Err(e)) => Answer::Error(AnswerError::Store(StoreRefusal::SaveFailed(e))),
                Err(e) => Answer::Error(AnswerError::Commission(e)),
            };
        }
    };
    match done {
        Ok(()) => commission_view(rig),
        Err(e) => Answer::Error(AnswerError::Commission(e)),
    }
}

/// Advances the commissioning sequence (the console service calls it whenever it wakes).
pub fn poll_commission(rig: &mut impl RigAccess) {
    if rig.commission(|c| c.busy()) {
        with_commission(rig, |c, r| c.poll(r));
    }
}

/// Formats the oldest unsent `!C` line into `out` if the link has room for it now (it then
/// counts as sent: call [`sent_commission_line`] once it is queued); `false` when none waits
/// or it must wait for room.
pub fn next_commission_line(rig: &mut impl RigAccess, out: &mut ReplyText) -> bool {
    use core::fmt::Write as _;
    let Some(n) = rig.commission(|c| c.peek().copied()) else {
        return false;
    };
    out.clear();
    if write!(out, "{}", CommissionLine(n)).is_err() {
        // No record is that long (tested): never sent rather than cut.
        rig.commission(|c| c.pop());
        return false;
    }
    rig.link(|l| l.fits_async(out.len()))
}

/// The line [`next_commission_line`] gave was queued.
pub fn sent_commission_line(rig: &mut impl RigAccess) {
    rig.commission(|c| c.pop());
}

/// `revert`: the stored settings back (a load may repair the store, writing flash: paused as a
/// save).
fn revert(rig: &mut impl RigAccess) -> Answer {
    if let Err(e) = idle(rig) {
        return Answer::Error(e);
    }
    rig.controller(|c| c.pause_sampling());
    let loaded = rig.store(|s| s.load());
    rig.controller(|c| c.resume_sampling());
    let Some(settings) = loaded.settings else {
        return Answer::Error(AnswerError::Store(StoreRefusal::NothingToRevert(
            loaded.state,
        )));
    };
    match rig.controller(|c| c.load_settings(&settings, ModelSource::Stored)) {
        Ok(()) => rig.controller(|c| model_line(c)),
        Err(e) => {
            rig.store(|s| s.note_invalid());
            Answer::Error(refusal(e))
        }
    }
}

/// Samples at [`SAMPLE_RATE_HZ`] as whole ms.
fn ms_of_samples(samples: u32) -> u32 {
    u32::try_from(u64::from(samples) * 1000 / u64::from(SAMPLE_RATE_HZ)).unwrap_or(u32::MAX)
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
            if state == State::Fault {
                // As every command refused in a fault says: `stop` does not leave it.
                return Answer::Error(AnswerError::Command(CommandError::FaultLatched));
            }
            if state != State::Idle {
                return Answer::Error(AnswerError::Capture(CaptureError::NotIdle));
            }
            Answer::Capture(rig.capture(|c| {
                c.arm(&sensor, level_n, seconds);
                c.status()
            }))
        }
        CaptureCommand::Identify | CaptureCommand::Adopt if rig.capture(|c| c.active()) => {
            Answer::Error(AnswerError::Capture(CaptureError::Running))
        }
        CaptureCommand::Identify => Answer::Identify(IdentifyLine(identify_capture(rig))),
        CaptureCommand::Adopt => match identify_capture(rig) {
            Ok(id) if id.law_fits() => settled(rig.controller(|c| {
                let base = c.draft().map_or(*c.model().0, |d| d.params);
                let params = id.applied_to(&base).map_err(SettingsError::Invalid)?;
                c.draft_model(params).map(|()| model_line(c))
            })),
            other => Answer::Identify(IdentifyLine(other)),
        },
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
pub type AsyncText = heapless::String<{ super::link::MAX_ASYNC }>;

/// Formats `response` into `out` (cleared first); a reply that does not fit is replaced by an
/// error line (no reply is that long: tested).
pub fn format_answer(response: &Response, out: &mut ReplyText) {
    use core::fmt::Write as _;
    out.clear();
    if write!(out, "{response}").is_err() {
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
    /// The link.
    pub link: &'a mut Link,
    /// The settings store.
    pub store: &'a mut dyn SettingsStore,
    /// The commissioning sequence.
    pub commission: &'a mut Commission,
    /// A `reset` was accepted (the caller restarts once the reply is out).
    pub reset: bool,
}

impl RigPieces for Direct<'_> {
    fn controller<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> R {
        f(self.controller)
    }
    fn capture<R>(&mut self, f: impl FnOnce(&mut Capture) -> R) -> R {
        f(self.capture)
    }
    fn store<R>(&mut self, f: impl FnOnce(&mut dyn SettingsStore) -> R) -> R {
        f(self.store)
    }
}

impl RigAccess for Direct<'_> {
    fn board(&mut self) -> BoardInfo {
        self.board
    }
    fn link<R>(&mut self, f: impl FnOnce(&mut Link) -> R) -> R {
        f(self.link)
    }
    fn commission<R>(&mut self, f: impl FnOnce(&mut Commission) -> R) -> R {
        f(self.commission)
    }
    fn reset_after_reply(&mut self) {
        self.reset = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::{SEGMENT_LEN, SegmentView};
    use crate::console::Board;
    use crate::console::link::LinkStats;
    use crate::console::reply::Version;
    use crate::control::{ControllerConfig, ModelStatus, PeakForce, Reply, Status, Target};
    use crate::model::RigId;
    use crate::store::Store;
    use crate::store::ram_flash::{PAGE_BYTES, RamFlash};
    use std::string::String;

    const BOARD: BoardInfo = BoardInfo {
        firmware: Version {
            major: 0,
            minor: 0,
            patch: 0,
        },
        board: Board::Virtual,
        uptime_ms: 1234,
        stack_hwm_bytes: 0,
        stack_size_bytes: 0,
        sample_gap_max_us: 0,
    };

    /// A store in RAM for a test (two pages, erased).
    fn ram_store(mem: &mut [u8]) -> Store<RamFlash<&mut [u8]>> {
        let len = mem.len() as u32;
        Store::new(RamFlash::erased(mem), 0..len).unwrap()
    }

    fn say(c: &mut Controller, cap: &mut Capture, line: &str) -> String {
        let mut link = Link::new();
        let mut mem = std::vec![0u8; 2 * PAGE_BYTES];
        let mut store = ram_store(&mut mem);
        let mut d = Direct {
            controller: c,
            capture: cap,
            board: BOARD,
            link: &mut link,
            store: &mut store,
            commission: &mut Commission::new(),
            reset: false,
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
            std::format!(
                "id firmware=0.0.0 board=virtual rig=wires rig_hash={:08x} store=empty \
                 gap_mm=0.00 sample_rate_hz=10000 capture_rate_hz=100000 volts_per_n=0.01 \
                 offset_v=0.2 adc_full_scale_v=3.3 mass_kg=0.298 freq_window_hz=1..30 \
                 slew_hz_per_s=0.5 ramp_mm_per_s=0.5 force_limit_n=280",
                crate::model::params_hash(&RigId::Wires.preset())
            )
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
        // With a fault latched, `capture arm` says what every refused command says then.
        c.on_sample(Err(crate::hal::SampleError::Overrun), 100);
        assert_eq!(c.state(), State::Fault);
        assert_eq!(
            say(&mut c, &mut cap, "capture arm 2 1"),
            "error: fault latched: clear first"
        );
        assert_eq!(say(&mut c, &mut cap, "clear"), "ok");
        // Tagged lines get tagged replies; a bad tag is refused untagged.
        assert_eq!(say(&mut c, &mut cap, "#17 stream off"), "#17 ok");
        assert!(!c.streaming());
        assert_eq!(
            say(&mut c, &mut cap, "  #4294967 bogus"),
            "#4294967 error: unknown command (try `help`)"
        );
        assert_eq!(
            say(&mut c, &mut cap, "#12x status"),
            "error: a tag is # and 1 to 9 digits, then a space"
        );
        assert_eq!(
            say(&mut c, &mut cap, "#1234567890 status"),
            "error: a tag is # and 1 to 9 digits, then a space"
        );
        assert_eq!(say(&mut c, &mut cap, "#5"), "#5 error: empty line");
        // A receive error's line is answered, untagged (its tag is not known), and runs nothing.
        let mut link = Link::new();
        let mut mem = std::vec![0u8; 2 * PAGE_BYTES];
        let mut store = ram_store(&mut mem);
        let mut d = Direct {
            controller: &mut c,
            capture: &mut cap,
            board: BOARD,
            link: &mut link,
            store: &mut store,
            commission: &mut Commission::new(),
            reset: false,
        };
        assert_eq!(
            answer(&mut d, Line::Lost),
            Response {
                tag: None,
                answer: Answer::Error(AnswerError::Lost)
            }
        );
        // `echo` is the link's.
        assert_eq!(say_on(&mut d, "echo on"), "ok");
        assert!(d.link.echo());
    }

    fn say_on(d: &mut Direct<'_>, line: &str) -> String {
        std::string::ToString::to_string(&answer(d, Line::Text(line)))
    }

    #[test]
    fn the_longest_replies_fit() {
        let tagged = |answer| Response {
            tag: Some(999_999_999),
            answer,
        };
        let seg = tagged(Answer::Segment(SegmentView {
            k: 31,
            start: u32::MAX,
            codes: [4095; SEGMENT_LEN],
        }));
        let mut out = ReplyText::new();
        format_answer(&seg, &mut out);
        assert!(out.starts_with("#999999999 segment k=31"), "{out}");
        let diag = tagged(Answer::Diag(DiagInfo {
            samples: u64::MAX,
            uptime_ms: u64::MAX,
            stack_hwm_bytes: u32::MAX,
            stack_size_bytes: u32::MAX,
            sample_gap_max_us: u32::MAX,
            link: LinkStats {
                rx_errors: u32::MAX,
                lines_lost: u32::MAX,
                async_sent: u32::MAX,
                async_dropped: u32::MAX,
            },
            lost_cycles: u32::MAX,
            link_timeout_ms: u32::MAX,
        }));
        format_answer(&diag, &mut out);
        assert!(out.starts_with("#999999999 diag "), "{out}");
        // The longest status: every field present at its widest.
        let big = 999_999.9;
        let status = Status {
            state: State::Stopping,
            rig: crate::control::ModelId {
                source: crate::control::ModelSource::Preset(RigId::Beam170),
                hash: u32::MAX,
            },
            gap_mm: 10.0,
            freq_hz: 999.9999,
            amplitude_mm: 99.999,
            regime: Some(crate::observe::Regime::Periodic {
                p: u16::MAX,
                q: u16::MAX,
            }),
            peak: Some(PeakForce { n: big, mg: big }),
            model: ModelStatus::Ready(Target {
                target_hz: 999.9999,
                band_hz: [999.999, 999.999],
                impact_force_mg: big,
            }),
            force_vs_model_pct: Some(-big),
            fault: Some(crate::control::Fault::MissedDeadline),
            impacts: u32::MAX,
            lost_cycles: u32::MAX,
        };
        format_answer(&tagged(Answer::Reply(Reply::Status(status))), &mut out);
        assert!(out.starts_with("#999999999 state=stopping"), "{out}");
        assert!(
            out.ends_with(&std::format!("lost_cycles={}", u32::MAX)),
            "{out}"
        );
        format_answer(&tagged(Answer::Help), &mut out);
        assert!(out.starts_with("#999999999 commands:"), "{out}");
    }
}

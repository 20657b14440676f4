//! The desktop side of the rig's serial console (`host-sim rig --port …`): the transport only.
//! Every line and reply is `shared::console`'s (the firmware's own types and text); this module
//! sends requests, matches each reply to its request by a tag, sorts the asynchronous records
//! from the replies, counts sequence numbers, and bounds every wait. Built on it: the log
//! ([`log`]), the drop-test capture ([`capture`]) and the measured frequency response ([`sweep`]).
//! The same code talks to the board over USB-serial, to the firmware under QEMU and to the
//! virtual rig (`hil --serve-pty`), all through a serial device path.
//!
//! What the link guarantees:
//! - **Replies matched to requests.** Every request goes out as `#<n> <line>`; a reply with
//!   another tag, or an untagged one, is a link error naming both lines, never taken as the
//!   answer.
//! - **Every wait has a bound** (the reply timeout, the telemetry's quiet time, or a deadline the
//!   caller derives from what it waits for), and every wait ends early on Ctrl-C, SIGTERM or
//!   SIGHUP ([`crate::interrupt`]).
//! - **The drive is never left on by a failure.** [`RigPort::guard_drive`] arms a guard: when
//!   the port is dropped while armed (an error, an interruption, a panic), it sends `stop` and
//!   reads the status after it, through noise and echoes, until the status shows the drive
//!   stopping (bounded), and prints the state the rig reported. A command that set manual
//!   frequencies ([`RigPort::retune_on_close`]) hands the next `start` back to the model's
//!   target (`tune`) on the way out. On top, the rig's own link-loss watchdog (`link-timeout`,
//!   armed at connection, fed by keep-alive empty lines) stops the drive if this program dies
//!   without a word.
//! - **A known console state at connection**, whatever a terminal session left: a line end
//!   first (ending a half-typed line), then `id` until a reply comes. The rig never echoes a
//!   tagged line, and an echo of a request is never taken for its reply (no reply is the text
//!   of a request), so a console left with `echo on` does not matter.
//! - **Causes as they happened**: a wait reads what has arrived before it names a silence, and
//!   time this program spent stopped (SIGSTOP and SIGCONT, a suspended laptop) does not count
//!   against its bound: after it resumes, the rig's own lines say what it did meanwhile.
//! - **Values checked at the edge**: replies and records are parsed by `shared::console`, which
//!   refuses non-finite and out-of-range numbers; a line that does not read is reported on stderr
//!   (escaped, at most [`SHOWN_GARBLED`] of them shown, all counted) and skipped.

pub mod capture;
pub mod commission;
pub mod log;
pub mod model;
pub mod sweep;

use std::io::{ErrorKind, Read, Write};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, TryRecvError, channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail, ensure};
use shared::capture::{CaptureCommand, CaptureStatus, SegmentView};
use shared::commission::Numbered;
use shared::console::commission::{CommissionLine, PREFIX as COMMISSION_PREFIX};
use shared::console::serve::split_tag;
use shared::console::{Answer, AnswerError, DiagInfo, IdInfo, Request, WireError};
use shared::control::{AsyncRecord, Command, Reply, State, Status};

use crate::interrupt;

/// Garbled or malformed lines shown on stderr (the rest are counted).
pub const SHOWN_GARBLED: u64 = 10;
/// Characters of a garbled line shown.
const SHOWN_CHARS: usize = 120;
/// Bytes without a line end after which the reader discards what it holds and the rest of
/// that line.
const MAX_PENDING_BYTES: usize = 1 << 16;
/// Times the drive guard sends `stop` before it gives up (each waits the reply timeout).
pub const STOP_ATTEMPTS: u32 = 3;
/// Granularity of every wait (how soon Ctrl-C is seen).
const POLL: Duration = Duration::from_millis(50);
/// A pause between two looks of a waiting loop (which looks every [`POLL`]) longer than this is
/// this program having been stopped (SIGSTOP, a suspended laptop): not time spent waiting.
const FROZEN: Duration = Duration::from_secs(1);

/// A wait's end: an instant, moved on by the time this program was found stopped since it was
/// set ([`FROZEN`]), which the wait did not spend listening.
#[derive(Debug, Clone, Copy)]
struct Deadline {
    at: Instant,
    /// [`RigPort`]'s stopped time when the deadline was set.
    frozen: Duration,
}

/// What the reader thread hands over.
/// An asynchronous line, of either kind.
enum Async {
    Record(AsyncRecord),
    Commission(Numbered),
}

enum Incoming {
    Reply { tag: Option<u32>, text: String },
    Record(AsyncRecord),
    Commission(Numbered),
    Closed(String),
}

/// How to talk to the rig.
#[derive(Debug, Clone, Copy)]
pub struct LinkOptions {
    /// Baud rate (8N1).
    pub baud: u32,
    /// Longest wait for one reply.
    pub timeout: Duration,
    /// The rig's link-loss watchdog while connected, s (0: off): the rig stops its drive when
    /// no line arrives for this long; the port sends a keep-alive empty line every quarter of it.
    pub link_timeout_s: f32,
}

impl LinkOptions {
    /// The options of the tests and the examples: 115200 baud, `timeout`, a 10 s watchdog.
    pub fn with_timeout(timeout: Duration) -> Self {
        LinkOptions {
            baud: 115_200,
            timeout,
            link_timeout_s: DEFAULT_LINK_TIMEOUT_S,
        }
    }
}

/// The link-loss watchdog armed while a `host-sim rig` command runs, s.
pub const DEFAULT_LINK_TIMEOUT_S: f32 = 10.0;

/// A refused request: the rig answered `error: …`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("the rig refused `{line}`: {error}")]
pub struct Refused {
    /// The request.
    pub line: String,
    /// Why.
    pub error: AnswerError,
}

/// Counts asynchronous records, and those lost on the way (gaps in the sequence numbers).
#[derive(Debug, Clone, Copy, Default)]
pub struct SeqCounter {
    last: Option<u32>,
    /// Records received (duplicates excluded).
    pub received: u64,
    /// Records missing between the first and the last received.
    pub lost: u64,
    /// Records received twice (dropped).
    pub duplicates: u64,
}

/// What a sequence number says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seq {
    /// In order (possibly after a gap, counted as lost).
    Next,
    /// The same as the last one: a duplicate.
    Duplicate,
    /// Behind the last one: the rig restarted, or the link replays old lines.
    Back {
        /// The last number seen.
        last: u32,
    },
}

impl SeqCounter {
    /// Notes a received sequence number.
    pub fn see(&mut self, seq: u32) -> Seq {
        if let Some(last) = self.last {
            let step = seq.wrapping_sub(last);
            if step == 0 {
                self.duplicates += 1;
                return Seq::Duplicate;
            }
            if step > u32::MAX / 2 {
                return Seq::Back { last };
            }
            self.lost += u64::from(step - 1);
        }
        self.received += 1;
        self.last = Some(seq);
        Seq::Next
    }
}

/// A connection to the rig's console.
pub struct RigPort {
    writer: Box<dyn serialport::SerialPort>,
    incoming: Receiver<Incoming>,
    reader: Option<JoinHandle<()>>,
    stop: Arc<AtomicBool>,
    garbled: Arc<AtomicU64>,
    records: std::collections::VecDeque<AsyncRecord>,
    /// The commissioning's records (`!C`) received and not yet taken.
    commission: std::collections::VecDeque<Numbered>,
    /// Send `commission abort` when the port closes ([`RigPort::abort_commission_on_close`]).
    abort_commission: bool,
    opts: LinkOptions,
    next_tag: u32,
    /// Tags of requests given up (interrupted, timed out): their late replies are dropped.
    abandoned: std::collections::VecDeque<u32>,
    last_write: Instant,
    /// The rig's time (samples) of the latest record, and what it was at the last line sent:
    /// a rig that runs faster than real time (the virtual rig) is kept alive by its own clock.
    rig_now: Option<u64>,
    rig_at_write: Option<u64>,
    guard: bool,
    /// What `id` said when the connection was made.
    id: IdInfo,
    /// The `id` reply as received (for file headers).
    id_line: String,
    closed: Option<String>,
    /// The link-loss watchdog's time to leave the rig with, s: what `diag` said at the
    /// connection, or what the operator set since (`rig send link-timeout …`).
    leave_link_timeout_s: f32,
    /// Whether the operator turned telemetry on (`rig send stream on`): then it stays on.
    leave_streaming: bool,
    /// Send `tune` when the port closes ([`RigPort::retune_on_close`]).
    retune: bool,
    /// [`RigPort::stop_now`] could not stop the drive: the watchdog stays armed at the close.
    stop_failed: bool,
    /// Time this program was found stopped while waiting, in all ([`Deadline`]).
    frozen: Duration,
}

impl RigPort {
    /// Opens `path`, discards whatever the rig was sending, synchronises on an `id` exchange
    /// (so a stale reply cannot be taken for the next command's) and arms the rig's link-loss
    /// watchdog.
    ///
    /// # Errors
    /// The port does not exist or cannot be opened; no `id` reply within the timeout; an `id`
    /// reply that does not read (a calibration of 0 or NaN, another protocol's rates).
    pub fn open(path: &Path, opts: LinkOptions) -> Result<Self> {
        anyhow::ensure!(
            path.exists(),
            "--port {}: no such device (is the rig connected, or the virtual rig running?)",
            path.display()
        );
        interrupt::install();
        let port = serialport::new(path.to_string_lossy(), opts.baud)
            .timeout(POLL)
            .open()
            .with_context(|| format!("--port {}: cannot open", path.display()))?;
        let _ = port.clear(serialport::ClearBuffer::All);
        let reader_port = port
            .try_clone()
            .with_context(|| format!("--port {}", path.display()))?;
        let (tx, incoming) = channel();
        let stop = Arc::new(AtomicBool::new(false));
        let garbled = Arc::new(AtomicU64::new(0));
        let reader = {
            let (stop, garbled) = (Arc::clone(&stop), Arc::clone(&garbled));
            std::thread::spawn(move || read_lines(reader_port, &stop, &garbled, &tx))
        };
        let mut rig = RigPort {
            writer: port,
            incoming,
            reader: Some(reader),
            stop,
            garbled,
            records: std::collections::VecDeque::new(),
            commission: std::collections::VecDeque::new(),
            abort_commission: false,
            opts,
            next_tag: 1,
            abandoned: std::collections::VecDeque::new(),
            last_write: Instant::now(),
            rig_now: None,
            rig_at_write: None,
            guard: false,
            id: placeholder_id(),
            id_line: String::new(),
            closed: None,
            leave_link_timeout_s: 0.0,
            leave_streaming: false,
            retune: false,
            stop_failed: false,
            frozen: Duration::ZERO,
        };
        rig.sync()?;
        if opts.link_timeout_s > 0.0 {
            rig.command(Command::LinkTimeout(opts.link_timeout_s))?;
        }
        Ok(rig)
    }

    /// Sends `id` (again every second: a board still starting up drops what it receives)
    /// until a reply to one of them comes, then one `diag`, whose reply comes after any late
    /// replies to the other `id`s: from then on every reply answers its own line.
    fn sync(&mut self) -> Result<()> {
        // A line end first: a line an operator's terminal session left half typed ends here
        // (the rig refuses it, untagged), instead of spoiling the first `id`.
        self.write("")?;
        let deadline = Instant::now() + self.opts.timeout;
        let first = self.next_tag;
        let mut next_send = Instant::now();
        // What came instead of the reply (stale output, another program's talk), for the
        // timeout's message.
        let mut seen: Option<String> = None;
        loop {
            if Instant::now() >= next_send {
                let tag = self.take_tag();
                self.write(&format!("#{tag} id"))?;
                next_send = Instant::now() + Duration::from_secs(1);
            }
            let wait = Deadline {
                at: deadline.min(next_send),
                frozen: self.frozen,
            };
            match self.recv(wait, true)? {
                // The echo of an `id` (a rig that echoes tagged lines), not its reply.
                Some(Incoming::Reply { tag: Some(_), text }) if text == "id" => {}
                Some(Incoming::Reply { tag: Some(t), text })
                    if (first..self.next_tag).contains(&t) =>
                {
                    let id = match text.parse::<Answer>() {
                        Ok(Answer::Id(id)) => id,
                        Ok(_) => continue,
                        Err(e) => bail!(
                            "the rig's `id` reply does not read ({e}): {}",
                            escaped(&text)
                        ),
                    };
                    self.id = id;
                    self.id_line = text;
                    break;
                }
                Some(Incoming::Closed(why)) => bail!("the rig closed the link: {why}"),
                Some(Incoming::Reply { tag, text }) => {
                    seen = Some(escaped(&match tag {
                        Some(t) => format!("#{t} {text}"),
                        None => text,
                    }));
                }
                Some(Incoming::Record(_) | Incoming::Commission(_)) => {}
                None if Instant::now() >= deadline => bail!(
                    "no reply to `id` within {:.1} s{}: is this the rig's console (115200 8N1)?",
                    self.opts.timeout.as_secs_f64(),
                    seen.map_or(String::new(), |l| format!(
                        " (received instead, last: `{l}`)"
                    ))
                ),
                None => {}
            }
        }
        let tag = self.take_tag();
        self.write(&format!("#{tag} diag"))?;
        let deadline = self.deadline(self.opts.timeout);
        loop {
            match self.recv(deadline, true)? {
                Some(Incoming::Reply { tag: Some(t), text }) if t == tag && text != "diag" => {
                    // The watchdog as the operator left it, to leave it so again.
                    if let Ok(Answer::Diag(d)) = text.parse::<Answer>() {
                        self.leave_link_timeout_s = d.link_timeout_ms as f32 / 1e3;
                    }
                    return Ok(());
                }
                Some(Incoming::Closed(why)) => bail!("the rig closed the link: {why}"),
                Some(_) => {}
                None => bail!("no reply to `diag` after `id`"),
            }
        }
    }

    fn take_tag(&mut self) -> u32 {
        let t = self.next_tag;
        // Tags have at most 9 digits.
        self.next_tag = if t >= 999_999_999 { 1 } else { t + 1 };
        t
    }

    fn write(&mut self, line: &str) -> Result<()> {
        if let Some(why) = &self.closed {
            bail!("the rig closed the link: {why}");
        }
        self.last_write = Instant::now();
        self.rig_at_write = self.rig_now;
        let sent = self
            .writer
            .write_all(format!("{line}\n").as_bytes())
            .and_then(|()| self.writer.flush());
        if let Err(e) = sent {
            let what = if line.is_empty() {
                "a keep-alive"
            } else {
                line
            };
            let why = format!("sending `{what}`: {e}");
            self.closed = Some(why.clone());
            bail!("the rig closed the link ({why})");
        }
        Ok(())
    }

    /// Sends a keep-alive (an empty line: no reply) when a quarter of the link timeout has
    /// passed since the last line, by the wall clock or by the rig's (whichever is faster).
    fn keep_alive(&mut self) -> Result<()> {
        if self.opts.link_timeout_s <= 0.0 {
            return Ok(());
        }
        let quarter = self.opts.link_timeout_s / 4.0;
        let by_wall = self.last_write.elapsed() >= Duration::from_secs_f32(quarter);
        let by_rig = match (self.rig_now, self.rig_at_write) {
            (Some(now), Some(then)) => {
                now.saturating_sub(then) as f32 >= quarter * shared::control::SAMPLE_RATE_HZ as f32
            }
            (Some(_), None) => true,
            _ => false,
        };
        if by_wall || by_rig {
            self.write("")?;
        }
        Ok(())
    }

    /// A wait's end `after` from now (see [`Deadline`]).
    fn deadline(&self, after: Duration) -> Deadline {
        Deadline {
            at: Instant::now() + after,
            frozen: self.frozen,
        }
    }

    /// The next incoming item before `deadline` (`None` after it), keeping the link alive;
    /// ends early on an interruption unless `ignore_interrupt`. What had already arrived when
    /// the deadline passes is still read (a zero wait reads what is queued). Time this program
    /// was found stopped while waiting ([`FROZEN`]) moves every pending deadline on by as much:
    /// after SIGSTOP and SIGCONT the lines the rig kept sending wait in the port, and they, not
    /// a silence, say what happened.
    fn recv(&mut self, deadline: Deadline, ignore_interrupt: bool) -> Result<Option<Incoming>> {
        let mut last = Instant::now();
        loop {
            if !ignore_interrupt {
                interrupt::check()?;
            }
            self.keep_alive()?;
            let now = Instant::now();
            let away = now.saturating_duration_since(last);
            if away > FROZEN {
                self.frozen += away;
            }
            last = now;
            let end = deadline.at + self.frozen.saturating_sub(deadline.frozen);
            let got = if now >= end {
                match self.incoming.try_recv() {
                    Ok(i) => Ok(i),
                    Err(TryRecvError::Empty) => return Ok(None),
                    Err(TryRecvError::Disconnected) => Err(RecvTimeoutError::Disconnected),
                }
            } else {
                self.incoming.recv_timeout((end - now).min(POLL))
            };
            match got {
                Ok(Incoming::Closed(why)) => {
                    self.closed = Some(why.clone());
                    return Ok(Some(Incoming::Closed(why)));
                }
                Ok(Incoming::Record(r)) => {
                    self.rig_now = Some(self.rig_now.map_or(r.sample, |n| n.max(r.sample)));
                    self.keep_alive()?;
                    return Ok(Some(Incoming::Record(r)));
                }
                Ok(Incoming::Commission(c)) => {
                    self.rig_now = Some(self.rig_now.map_or(c.sample, |n| n.max(c.sample)));
                    self.keep_alive()?;
                    return Ok(Some(Incoming::Commission(c)));
                }
                Ok(i) => return Ok(Some(i)),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => {
                    let why = self
                        .closed
                        .clone()
                        .unwrap_or_else(|| "device closed".into());
                    self.closed = Some(why.clone());
                    return Ok(Some(Incoming::Closed(why)));
                }
            }
        }
    }

    /// Sends `line` tagged and returns the text of its reply (without the tag). `lenient` (the
    /// drive guard's last words): an interruption does not end the wait, and a reply to another
    /// line is skipped rather than an error.
    fn exchange(&mut self, line: &str, lenient: bool) -> Result<String> {
        let sent = self.take_tag();
        self.write(&format!("#{sent} {line}"))?;
        let deadline = self.deadline(self.opts.timeout);
        let result = self.await_reply(sent, line, deadline, lenient);
        if result.is_err() {
            // Its reply may still come: it must not be taken for another line's.
            if self.abandoned.len() >= 64 {
                self.abandoned.pop_front();
            }
            self.abandoned.push_back(sent);
        }
        result
    }

    fn await_reply(
        &mut self,
        sent: u32,
        line: &str,
        deadline: Deadline,
        lenient: bool,
    ) -> Result<String> {
        loop {
            match self.recv(deadline, lenient)? {
                Some(Incoming::Reply { tag: Some(t), .. })
                    if t != sent && (lenient || self.abandoned.contains(&t)) => {}
                Some(Incoming::Record(r)) => self.records.push_back(r),
                Some(Incoming::Commission(c)) => self.commission.push_back(c),
                // The echo of the request (a rig that echoes tagged lines): no reply is ever
                // the text of a request (`shared`'s protocol tests).
                Some(Incoming::Reply { tag: Some(t), text }) if t == sent && text == line => {}
                Some(Incoming::Reply { tag: Some(t), text }) if t == sent => return Ok(text),
                Some(Incoming::Reply { tag: None, text })
                    if matches!(
                        text.parse::<Answer>(),
                        Ok(Answer::Error(AnswerError::Lost | AnswerError::Bad))
                    ) =>
                {
                    bail!(
                        "the rig could not read `{line}` ({}): a damaged link (see `diag rx_errors`)",
                        text.trim_start_matches("error: ")
                    )
                }
                // The drive guard's last words get through noise: only their own reply counts.
                Some(Incoming::Reply { tag: None, .. }) if lenient => {}
                Some(Incoming::Reply { tag, text }) => bail!(
                    "link error: `{}` arrived while `#{sent} {line}` waited for its reply (the rig and this client disagree on the conversation)",
                    escaped(&match tag {
                        Some(t) => format!("#{t} {text}"),
                        None => text,
                    })
                ),
                Some(Incoming::Closed(why)) => {
                    bail!("the rig closed the link while `{line}` waited for its reply: {why}")
                }
                None => bail!(
                    "no reply to `{line}` within {:.1} s (the rig stopped answering)",
                    self.opts.timeout.as_secs_f64()
                ),
            }
        }
    }

    /// Sends a console line as it is (tagged on the way, in place of a tag the operator typed)
    /// and returns the reply's text: for `rig send` and `rig console`, which print what the rig
    /// says.
    ///
    /// # Errors
    /// A line break in `line` ([`request_line`], nothing sent), no reply within the timeout, a
    /// reply to another line, the link closed, Ctrl-C.
    pub fn send_line(&mut self, line: &str) -> Result<String> {
        let line = request_line(line)?;
        let reply = self.exchange(line, false)?;
        self.operator_set(line, &reply);
        Ok(reply)
    }

    /// Sends a console line as the operator typed it ([`RigPort::send_line`]) and checks its
    /// reply as every other command's ([`check_reply`]). `rig send` and `rig run` print only
    /// replies that passed.
    ///
    /// # Errors
    /// As [`RigPort::send_line`] and [`check_reply`].
    pub fn send_checked(&mut self, line: &str) -> Result<(String, Answer)> {
        let reply = self.send_line(line)?;
        let answer = check_reply(line, &reply)?;
        Ok((reply, answer))
    }

    /// The next asynchronous record within `quiet`, or an error that says which silence it
    /// was: nothing came, or only lines that did not read (each shown or counted as it came).
    /// `during` ends the message (`at 3.4 Hz`, `after \`stream on\``).
    ///
    /// # Errors
    /// No record within `quiet`; as [`RigPort::next_record`].
    pub fn expect_record(&mut self, quiet: Duration, during: &str) -> Result<AsyncRecord> {
        let garbled = self.garbled();
        if let Some(r) = self.next_record(quiet)? {
            return Ok(r);
        }
        let q = quiet.as_secs_f64();
        match self.garbled() - garbled {
            0 => bail!("no telemetry for {q:.1} s {during}: nothing came from the rig"),
            n => bail!(
                "no telemetry that reads for {q:.1} s {during}: {n} {} came that did not read \
                 (see the warnings above)",
                if n == 1 { "line" } else { "lines" }
            ),
        }
    }

    /// Takes note of a setting the operator made with a line of their own (`link-timeout`,
    /// `stream`) that the rig accepted: the port leaves the rig so when it closes, and, if it
    /// keeps the link alive at all (a link timeout of its own, not `--link-timeout-s 0`), keeps
    /// it alive at the operator's watchdog time.
    fn operator_set(&mut self, line: &str, reply: &str) {
        if !matches!(reply.parse::<Answer>(), Ok(Answer::Reply(_))) {
            return;
        }
        match shared::console::parse(line) {
            Ok(Request::Control(Command::LinkTimeout(s))) => {
                self.leave_link_timeout_s = s;
                if self.opts.link_timeout_s > 0.0 {
                    self.opts.link_timeout_s = s;
                }
            }
            Ok(Request::Control(Command::Stream(on))) => self.leave_streaming = on,
            _ => {}
        }
    }

    /// Sends several console lines at once (pipelined, each tagged) and returns the texts of their replies
    /// in order: every reply must come, in order, each with its line's tag.
    ///
    /// # Errors
    /// As [`RigPort::send_line`], for the first line whose reply fails.
    pub fn send_lines(&mut self, lines: &[&str]) -> Result<Vec<String>> {
        let lines = lines
            .iter()
            .map(|l| request_line(l))
            .collect::<Result<Vec<&str>>>()?;
        let tags: Vec<u32> = lines.iter().map(|_| self.take_tag()).collect();
        let text: String = lines
            .iter()
            .zip(&tags)
            .map(|(l, t)| format!("#{t} {l}\n"))
            .collect();
        self.write(text.trim_end_matches('\n'))?;
        let mut out = Vec::new();
        for (line, &tag) in lines.iter().zip(&tags) {
            let deadline = self.deadline(self.opts.timeout);
            let reply = self.await_reply(tag, line, deadline, false)?;
            self.operator_set(line, &reply);
            out.push(reply);
        }
        Ok(out)
    }

    /// Sends `bytes` as one tagged line (they need not be text) and returns the reply's text
    /// (an `error: …` for bytes the rig cannot read): how the rig treats garbage.
    ///
    /// # Errors
    /// No reply within the timeout, a reply to another line, the link closed, Ctrl-C.
    pub fn send_raw_line(&mut self, bytes: &[u8]) -> Result<String> {
        let tag = self.take_tag();
        if let Some(why) = &self.closed {
            bail!("the rig closed the link: {why}");
        }
        let mut line = format!("#{tag} ").into_bytes();
        line.extend_from_slice(bytes);
        line.push(b'\n');
        self.last_write = Instant::now();
        self.writer
            .write_all(&line)
            .and_then(|()| self.writer.flush())?;
        let deadline = self.deadline(self.opts.timeout);
        loop {
            match self.recv(deadline, false)? {
                Some(Incoming::Record(r)) => self.records.push_back(r),
                Some(Incoming::Commission(c)) => self.commission.push_back(c),
                Some(Incoming::Reply { tag: t, text }) if t == Some(tag) || t.is_none() => {
                    return Ok(text);
                }
                Some(Incoming::Reply { text, .. }) => bail!("unexpected reply `{text}`"),
                Some(Incoming::Closed(why)) => bail!("the rig closed the link: {why}"),
                None => bail!("no reply to a raw line"),
            }
        }
    }

    /// Sends a request and reads its reply.
    ///
    /// # Errors
    /// As [`RigPort::send_line`], or a reply that does not read.
    pub fn request(&mut self, request: &Request) -> Result<Answer> {
        let line = request.to_string();
        let text = self.exchange(&line, false)?;
        read_answer(&line, &text)
    }

    /// [`RigPort::request`], with an `error: …` reply turned into [`Refused`].
    ///
    /// # Errors
    /// As [`RigPort::request`], or the rig refused.
    pub fn request_ok(&mut self, request: &Request) -> Result<Answer> {
        match self.request(request)? {
            Answer::Error(error) => Err(Refused {
                line: request.to_string(),
                error,
            }
            .into()),
            a => Ok(a),
        }
    }

    /// Runs a controller command.
    ///
    /// # Errors
    /// As [`RigPort::request_ok`], or a reply of another kind.
    pub fn command(&mut self, command: Command) -> Result<Reply> {
        match self.request_ok(&Request::Control(command))? {
            Answer::Reply(r) => Ok(r),
            a => bail!("unexpected reply to `{}`: {a}", Request::Control(command)),
        }
    }

    /// The rig's status.
    ///
    /// # Errors
    /// As [`RigPort::command`].
    pub fn status(&mut self) -> Result<Status> {
        match self.command(Command::Status)? {
            Reply::Status(s) => Ok(s),
            r => bail!("unexpected reply to `status`: {}", Answer::Reply(r)),
        }
    }

    /// Reads the status every `every` until `what` holds or `wall` of wall time has passed:
    /// the last status read and whether `what` held of it (`false`: the time ran out). Each
    /// read is bounded by the link's reply timeout, so the wait ends within `wall` and one
    /// timeout.
    ///
    /// # Errors
    /// As [`RigPort::status`], or an interruption (Ctrl-C) between two reads.
    pub fn wait_status(
        &mut self,
        what: impl Fn(&Status) -> bool,
        wall: Duration,
        every: Duration,
    ) -> Result<(Status, bool)> {
        let end = Instant::now() + wall;
        loop {
            let s = self.status()?;
            if what(&s) {
                return Ok((s, true));
            }
            if Instant::now() >= end {
                return Ok((s, false));
            }
            crate::interrupt::check()?;
            std::thread::sleep(every);
        }
    }

    /// The rig's diagnostics.
    ///
    /// # Errors
    /// As [`RigPort::request_ok`].
    pub fn diag(&mut self) -> Result<DiagInfo> {
        match self.request_ok(&Request::Diag)? {
            Answer::Diag(d) => Ok(d),
            a => bail!("unexpected reply to `diag`: {a}"),
        }
    }

    /// The rig's active model (`model`).
    ///
    /// # Errors
    /// As [`RigPort::request_ok`]; a draft open on the rig (its model line is the draft's:
    /// apply or discard it first).
    pub fn model(&mut self) -> Result<shared::model::RigParams> {
        match self.request_ok(&Request::Model)? {
            Answer::Model(m) => match m.of {
                shared::console::ModelOf::Active(_) => Ok(m.params),
                shared::console::ModelOf::Draft => bail!(
                    "a draft is open on the rig (`rig send \"draft apply\"` or \"draft discard\" \
                     first): its model line shows the draft"
                ),
            },
            a => bail!("unexpected reply to `model`: {a}"),
        }
    }

    /// A capture command whose reply is the capture's state.
    ///
    /// # Errors
    /// As [`RigPort::request_ok`].
    pub fn capture_status(&mut self, c: CaptureCommand) -> Result<CaptureStatus> {
        match self.request_ok(&Request::Capture(c))? {
            Answer::Capture(s) => Ok(s),
            a => bail!("unexpected reply to `{}`: {a}", Request::Capture(c)),
        }
    }

    /// Segment `k` of the capture.
    ///
    /// # Errors
    /// As [`RigPort::request_ok`].
    pub fn segment(&mut self, k: u16) -> Result<SegmentView> {
        let req = Request::Capture(CaptureCommand::Get(k));
        match self.request_ok(&req)? {
            Answer::Segment(s) if s.k == k => Ok(s),
            a => bail!("unexpected reply to `{req}`: {a}"),
        }
    }

    /// The next asynchronous record, waiting at most `wait` (`None` then). A reply that
    /// arrives while no request waits is a link error.
    ///
    /// # Errors
    /// The link closed, an unexpected reply, Ctrl-C.
    pub fn next_record(&mut self, wait: Duration) -> Result<Option<AsyncRecord>> {
        if let Some(r) = self.records.pop_front() {
            return Ok(Some(r));
        }
        Ok(match self.next_async(wait, false)? {
            Some(Async::Record(r)) => Some(r),
            _ => None,
        })
    }

    /// The next commissioning record (`!C`), waiting at most `wait` (`None` then); telemetry
    /// that arrives meanwhile is kept for [`RigPort::next_record`].
    ///
    /// # Errors
    /// The link closed, a reply while no request waited, Ctrl-C.
    pub fn next_commission(&mut self, wait: Duration) -> Result<Option<Numbered>> {
        if let Some(c) = self.commission.pop_front() {
            return Ok(Some(c));
        }
        Ok(match self.next_async(wait, true)? {
            Some(Async::Commission(c)) => Some(c),
            _ => None,
        })
    }

    /// The next asynchronous line of the kind asked for (`commission`: a `!C` line, else a
    /// record), the other kind queued for its own reader meanwhile.
    fn next_async(&mut self, wait: Duration, commission: bool) -> Result<Option<Async>> {
        let deadline = self.deadline(wait);
        loop {
            return match self.recv(deadline, false)? {
                None => Ok(None),
                Some(Incoming::Record(r)) if commission => {
                    self.records.push_back(r);
                    continue;
                }
                Some(Incoming::Record(r)) => Ok(Some(Async::Record(r))),
                Some(Incoming::Commission(c)) if commission => Ok(Some(Async::Commission(c))),
                Some(Incoming::Commission(c)) => {
                    self.commission.push_back(c);
                    continue;
                }
                Some(Incoming::Closed(why)) => Err(anyhow!("the rig closed the link: {why}")),
                Some(Incoming::Reply { tag: Some(t), .. }) if self.abandoned.contains(&t) => {
                    continue;
                }
                Some(Incoming::Reply { tag, text }) => bail!(
                    "link error: a reply arrived while no request waited: {}",
                    escaped(&match tag {
                        Some(t) => format!("#{t} {text}"),
                        None => text,
                    })
                ),
            };
        }
    }

    /// From now on, closing the port sends `commission abort` first (before the drive
    /// guard's `stop`): a commissioning this program started never outlives it.
    pub fn abort_commission_on_close(&mut self, on: bool) {
        self.abort_commission = on;
    }

    /// Drops the records received so far.
    pub fn drain_records(&mut self) {
        self.records.clear();
        while let Ok(i) = self.incoming.try_recv() {
            if let Incoming::Closed(why) = i {
                self.closed = Some(why);
            }
        }
    }

    /// The rig's own clock (`diag uptime_ms`), s.
    ///
    /// # Errors
    /// As [`RigPort::diag`].
    pub fn uptime_s(&mut self) -> Result<f64> {
        Ok(self.diag()?.uptime_ms as f64 / 1e3)
    }

    /// What `id` said at the connection.
    pub fn id(&self) -> &IdInfo {
        &self.id
    }

    /// The `id` reply as received.
    pub fn id_line(&self) -> &str {
        &self.id_line
    }

    /// The hammer's weight `m g` of the rig's model, N.
    pub fn weight_n(&self) -> f64 {
        f64::from(self.id.mass_kg) * shared::model::rig::GRAVITY_M_S2
    }

    /// Reply timeout.
    pub fn timeout(&self) -> Duration {
        self.opts.timeout
    }

    /// Lines that did not read, so far (reported on stderr as they came, the first
    /// [`SHOWN_GARBLED`] of them).
    pub fn garbled(&self) -> u64 {
        self.garbled.load(Ordering::Relaxed)
    }

    /// Arms the drive guard: from now on, dropping the port (an error, an interruption, a
    /// panic) stops the drive first, until [`RigPort::release_drive`].
    pub fn guard_drive(&mut self) {
        self.guard = true;
    }

    /// Disarms the drive guard: the command ended as planned and leaves the drive as it is.
    pub fn release_drive(&mut self) {
        self.guard = false;
    }

    /// A refusal made before anything that moves the rig was sent: the guard released, so that
    /// a run of the operator's is left as it was found (a failure of the link keeps the guard
    /// armed). Returns `why`, to be returned as the error.
    pub fn refuse(&mut self, why: anyhow::Error) -> anyhow::Error {
        self.release_drive();
        why
    }

    /// Stops the drive (the guard's action) and says on stderr what the rig reported: sends
    /// `stop` and reads the status after it, and judges by the state the status gives (idle,
    /// stopping, or a fault, which ramps the drive down itself), not by the first line that
    /// comes: noise, echoes and replies to other lines are skipped, a `stop` the rig could not
    /// read or did not answer is sent again, and so is one the rig acknowledged while its status
    /// still says it drives, up to [`STOP_ATTEMPTS`] times in all (each read bounded by the reply
    /// timeout). Ends a capture being armed. Whether the rig reported its drive stopping.
    fn stop_drive(&mut self) -> std::result::Result<String, String> {
        let mut last = String::new();
        for _ in 0..STOP_ATTEMPTS {
            match self.exchange("stop", true) {
                Ok(reply) if matches!(reply.parse::<Answer>(), Ok(Answer::Reply(Reply::Ok))) => {}
                Ok(reply) => {
                    last = format!("answered `{}`", escaped(&reply));
                    continue;
                }
                Err(e) => {
                    last = format!("{e:#}");
                    continue;
                }
            }
            // The state the rig reports now, read again if noise spoils a reading.
            let mut status = None;
            for _ in 0..STOP_ATTEMPTS {
                match self.exchange("status", true).map(|t| t.parse::<Status>()) {
                    Ok(Ok(s)) => {
                        status = Some(s);
                        break;
                    }
                    Ok(Err(e)) => {
                        last = format!("`stop` answered `ok`; the status did not read: {e}")
                    }
                    Err(e) => last = format!("`stop` answered `ok`; no status: {e:#}"),
                }
            }
            let Some(s) = status else { continue };
            match stopping(&s) {
                Some(state) => {
                    // A capture being armed ends too (its segments stay readable).
                    let _ = self.exchange("capture stop", true);
                    return Ok(state);
                }
                None => {
                    last = format!(
                        "`stop` answered `ok`, yet the status says {} at {:.3} mm, {:.4} Hz",
                        shared::console::Token::token(s.state),
                        s.amplitude_mm,
                        s.freq_hz
                    );
                }
            }
        }
        Err(format!(
            "`stop` failed {STOP_ATTEMPTS} times (last: {last}); the drive may still run: the \
             rig's link-loss watchdog (left armed) stops it {:.0} s after the last line, or stop \
             it at the rig",
            self.opts.link_timeout_s
        ))
    }

    /// The drive guard's action now rather than when the port closes: stops the drive as
    /// `RigPort::stop_drive` does, prints the outcome (`stopping the drive: …`) and disarms
    /// the guard. Returns the outcome: the state the rig reported, or why the stop failed (the
    /// rig's link-loss watchdog is then left armed when the port closes).
    pub fn stop_now(&mut self) -> std::result::Result<String, String> {
        let outcome = self.stop_drive();
        self.guard = false;
        self.stop_failed = outcome.is_err();
        say_stopped(&outcome);
        outcome
    }

    /// From now on, closing the port sends `tune` (after the guard's `stop`), handing the next
    /// `start` back to the model's target: for a command that sets manual frequencies (a
    /// sweep), whatever ends it. [`RigPort::tuned`] says it was done.
    pub fn retune_on_close(&mut self) {
        self.retune = true;
    }

    /// The model's target is back (`tune` answered): closing the port need not send it.
    pub fn tuned(&mut self) {
        self.retune = false;
    }
}

/// The guard's line on stderr.
fn say_stopped(outcome: &std::result::Result<String, String>) {
    match outcome {
        Ok(state) => eprintln!("stopping the drive: `stop` answered `ok`; {state}"),
        Err(why) => eprintln!("stopping the drive: {why}"),
    }
}

/// What the guard says of a status after `stop`, if it shows the drive stopping: idle, ramping
/// down, or in a fault (which ramps the drive to zero itself). `None`: it still drives.
fn stopping(s: &Status) -> Option<String> {
    match s.state {
        State::Idle => Some(format!(
            "the rig is idle, drive at {:.3} mm",
            s.amplitude_mm
        )),
        State::Stopping => Some(format!(
            "the rig is stopping, its drive ramping down from {:.3} mm",
            s.amplitude_mm
        )),
        State::Fault if s.amplitude_mm == 0.0 => Some(format!(
            "the rig is in fault `{}`, its drive at 0.000 mm",
            s.fault.map_or("?", shared::console::Token::token),
        )),
        State::Fault => Some(format!(
            "the rig is in fault `{}`, its drive ramping down from {:.3} mm",
            s.fault.map_or("?", shared::console::Token::token),
            s.amplitude_mm
        )),
        State::Ramp | State::Dwell | State::Track => None,
    }
}

impl Drop for RigPort {
    fn drop(&mut self) {
        if self.closed.is_none() && self.abort_commission {
            match self.exchange("commission abort", true) {
                Ok(r) => eprintln!(
                    "aborting the commissioning: `commission abort` answered `{}`",
                    escaped(&r)
                ),
                Err(e) => eprintln!("aborting the commissioning: {e:#}"),
            }
        }
        if self.closed.is_none() {
            let stopped = !self.stop_failed
                && (!self.guard || {
                    let outcome = self.stop_drive();
                    say_stopped(&outcome);
                    outcome.is_ok()
                });
            if self.retune && stopped {
                match self.exchange("tune", true) {
                    Ok(r) if matches!(r.parse::<Answer>(), Ok(Answer::Reply(Reply::Ok))) => {}
                    Ok(r) => eprintln!(
                        "warning: `tune` answered `{}`: the next `start` may run at the last \
                         manual frequency; `rig send tune` hands it back to the model's target",
                        escaped(&r)
                    ),
                    Err(e) => eprintln!(
                        "warning: `tune` failed ({e:#}): the next `start` may run at the last \
                         manual frequency; `rig send tune` hands it back to the model's target"
                    ),
                }
            }
            // Leave the rig as the operator had it: telemetry off unless they turned it on, the
            // watchdog as it was at the connection or as they set it, but armed whatever it
            // was while a drive this port started may still run.
            if !self.leave_streaming {
                let _ = self.exchange("stream off", true);
            }
            if stopped && self.opts.link_timeout_s != self.leave_link_timeout_s {
                let line = Request::Control(Command::LinkTimeout(self.leave_link_timeout_s));
                let _ = self.exchange(&line.to_string(), true);
            }
        }
        let n = self.garbled();
        if n > SHOWN_GARBLED {
            eprintln!("warning: {n} lines from the rig did not read and were skipped");
        }
        // Stop the reader (it polls with a short timeout) so that its handle on the device is
        // closed too: the port is free for the next program.
        self.stop.store(true, Ordering::Relaxed);
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
    }
}

/// An `IdInfo` until the real one arrives.
fn placeholder_id() -> IdInfo {
    IdInfo {
        firmware: shared::console::Version::of(""),
        board: shared::console::Board::Rig,
        rig: shared::control::ModelId::of(
            &shared::model::RigId::Wires.preset(),
            shared::control::ModelSource::Preset(shared::model::RigId::Wires),
        ),
        store: shared::store::StoreState::Empty,
        gap_mm: 0.0,
        sample_rate_hz: shared::control::SAMPLE_RATE_HZ,
        capture_rate_hz: shared::capture::CAPTURE_RATE_HZ,
        sensor: shared::control::SensorChain::default(),
        mass_kg: 0.0,
        freq_window_hz: [0.0, 0.0],
        slew_hz_per_s: 0.0,
        ramp_mm_per_s: 0.0,
        force_limit_n: 0.0,
    }
}

/// The reply `text` to `line`, read.
fn read_answer(line: &str, text: &str) -> Result<Answer> {
    text.parse::<Answer>().map_err(|e: WireError| {
        anyhow!(
            "the reply to `{line}` does not read ({e}): {}",
            escaped(text)
        )
    })
}

/// Checks the reply `reply` to the operator's `line`: it reads (`shared::console`'s parser
/// refuses non-finite and out-of-range values, naming the field) and is of the kind the line
/// gets ([`Answer::answers`]).
///
/// # Errors
/// A reply that does not read; a reply of another kind; a reply other than an error to a line
/// this client does not read as a request (a firmware of another version).
pub fn check_reply(line: &str, reply: &str) -> Result<Answer> {
    let sent = untagged(line.trim());
    let answer = read_answer(sent, reply)?;
    match shared::console::parse(sent) {
        Ok(request) => ensure!(
            answer.answers(&request),
            "the reply to `{sent}` is of another kind: `{}` (the rig and this client disagree on \
             the conversation)",
            escaped(reply)
        ),
        Err(e) => ensure!(
            matches!(answer, Answer::Error(_)),
            "the rig answered `{}` to `{sent}`, which this client does not read as a request \
             ({e}): is the firmware of another version (`id`)?",
            escaped(reply)
        ),
    }
    Ok(answer)
}

/// `text` escaped (control characters and non-ASCII shown as escapes) and cut at
/// 120 characters.
pub fn escaped(text: &str) -> String {
    let mut out: String = text
        .chars()
        .take(SHOWN_CHARS)
        .flat_map(char::escape_debug)
        .collect();
    if text.chars().count() > SHOWN_CHARS {
        out.push_str(&format!("… ({} characters)", text.chars().count()));
    }
    out
}

/// Reports a line that does not read (the first [`SHOWN_GARBLED`] on stderr), counting it.
fn garbled_line(garbled: &AtomicU64, why: &str, raw: &[u8]) {
    let n = garbled.fetch_add(1, Ordering::Relaxed) + 1;
    if n <= SHOWN_GARBLED {
        eprintln!(
            "warning: {why} skipped: {}",
            escaped(&String::from_utf8_lossy(raw))
        );
        if n == SHOWN_GARBLED {
            eprintln!("warning: further lines that do not read are counted, not shown");
        }
    }
}

/// The reader thread: splits the byte stream into lines; replies (with their tag) and parsed
/// records to the channel, lines that do not read to stderr (bounded).
fn read_lines(
    mut port: Box<dyn serialport::SerialPort>,
    stop: &AtomicBool,
    garbled: &AtomicU64,
    out: &Sender<Incoming>,
) {
    let mut buf: Vec<u8> = Vec::new();
    let mut chunk = [0u8; 4096];
    let mut zero_reads = 0u32;
    // After an over-long run without a line end: drop bytes up to the next line end.
    let mut skipping = false;
    while !stop.load(Ordering::Relaxed) {
        match port.read(&mut chunk) {
            Ok(0) => {
                zero_reads += 1;
                if zero_reads > 20 {
                    let _ = out.send(Incoming::Closed("device closed".into()));
                    return;
                }
                std::thread::sleep(Duration::from_millis(5));
                continue;
            }
            Ok(n) => {
                zero_reads = 0;
                buf.extend_from_slice(&chunk[..n]);
            }
            Err(e) if e.kind() == ErrorKind::TimedOut || e.kind() == ErrorKind::Interrupted => {}
            Err(e) => {
                let _ = out.send(Incoming::Closed(e.to_string()));
                return;
            }
        }
        while let Some(end) = buf.iter().position(|&b| b == b'\n' || b == b'\r') {
            let raw: Vec<u8> = buf.drain(..=end).collect();
            let raw = &raw[..raw.len() - 1];
            if std::mem::take(&mut skipping) || raw.is_empty() {
                continue;
            }
            let Ok(text) = std::str::from_utf8(raw) else {
                garbled_line(garbled, "a line that is not text", raw);
                continue;
            };
            let item = match read_line(text) {
                Ok(item) => item,
                Err(why) => match resynchronised(text) {
                    // Bytes lost on the link (a client that did not read while the rig wrote)
                    // glue the head of one line to the next whole line: the head is damage,
                    // the tail is read.
                    Some((at, item)) => {
                        garbled_line(
                            garbled,
                            &format!("{why}: its end lost on the link, the line glued to it read;"),
                            &raw[..at],
                        );
                        item
                    }
                    None => {
                        garbled_line(garbled, &why, raw);
                        continue;
                    }
                },
            };
            if out.send(item).is_err() {
                return;
            }
        }
        if buf.len() > MAX_PENDING_BYTES {
            garbled_line(
                garbled,
                &format!(
                    "{} bytes without a line end (the rest of that line too)",
                    buf.len()
                ),
                &buf[..SHOWN_CHARS.min(buf.len())],
            );
            buf.clear();
            skipping = true;
        }
    }
}

/// One line from the rig, read: a commissioning line, an asynchronous record or a reply.
///
/// # Errors
/// What does not read, as the warning names it.
fn read_line(text: &str) -> std::result::Result<Incoming, String> {
    if text.starts_with(COMMISSION_PREFIX) {
        text.parse::<CommissionLine>()
            .map(|c| Incoming::Commission(c.0))
            .map_err(|e| format!("a commissioning line that does not read ({e})"))
    } else if text.starts_with('!') {
        text.parse::<AsyncRecord>()
            .map(Incoming::Record)
            .map_err(|e| format!("an asynchronous line that does not read ({e})"))
    } else {
        split_tag(text)
            .map(|(tag, rest)| Incoming::Reply {
                tag,
                text: rest.trim_start().to_string(),
            })
            .map_err(|_| "a reply with a malformed tag".to_string())
    }
}

/// A line that does not read because bytes were lost inside it: the last whole line glued to
/// its end, from the last line-start marker (`!` of a record or a commissioning line, `#` of a
/// tagged reply) whose tail reads, with the marker's byte offset. Records and commissioning
/// lines hold neither marker (`shared::console`'s formats), so a marker inside one that does
/// not read starts another line; an untagged reply cannot be told from damage and is not
/// looked for.
fn resynchronised(text: &str) -> Option<(usize, Incoming)> {
    text.char_indices()
        .rev()
        .filter(|&(at, c)| at > 0 && (c == '!' || c == '#'))
        .find_map(|(at, _)| match read_line(&text[at..]) {
            Ok(item @ (Incoming::Record(_) | Incoming::Commission(_))) => Some((at, item)),
            Ok(item @ Incoming::Reply { tag: Some(_), .. }) => Some((at, item)),
            _ => None,
        })
}

/// `line` without a tag the operator typed, if it is one request: with a line break (`\n`, `\r`)
/// in it the rig would read two requests and answer one of them unasked.
///
/// # Errors
/// A line break in `line`.
pub fn request_line(line: &str) -> Result<&str> {
    ensure!(
        !line.bytes().any(shared::console::is_line_end),
        "`{}` holds a line break: the rig would read it as two requests; give one request a line",
        line.escape_debug()
    );
    Ok(untagged(line))
}

/// `line` without a tag the operator typed (`#5 status`): the port tags every line it sends
/// with its own, by which it matches the reply. A malformed tag is left for the rig to refuse.
fn untagged(line: &str) -> &str {
    match split_tag(line) {
        Ok((Some(_), rest)) => rest.trim_start(),
        _ => line,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sequence_numbers_count_gaps_duplicates_and_going_back() {
        let mut s = SeqCounter::default();
        let seen: Vec<Seq> = [5, 6, 9, 9, 10, 3].into_iter().map(|q| s.see(q)).collect();
        assert_eq!(
            seen,
            [
                Seq::Next,
                Seq::Next,
                Seq::Next,
                Seq::Duplicate,
                Seq::Next,
                Seq::Back { last: 10 }
            ]
        );
        assert_eq!((s.received, s.lost, s.duplicates), (4, 2, 1));
        // Wrapping at u32::MAX is in order.
        let mut s = SeqCounter::default();
        assert_eq!(s.see(u32::MAX), Seq::Next);
        assert_eq!(s.see(0), Seq::Next);
        assert_eq!(s.lost, 0);
    }

    /// A clean-clone CI run read this line: a client stopped while the rig streamed, the pty
    /// full, the record's end lost and the reply to the client's next request written after it.
    #[test]
    fn a_line_glued_to_the_head_of_a_cut_one_is_read() {
        let cut = "!T seq=182 t_s=82.9095 state=fault freq_hz=2.2000 amp_mm=0.000";
        let glued = format!("{cut}#10 error: fault latched: clear first");
        assert!(read_line(&glued).is_err());
        match resynchronised(&glued) {
            Some((at, Incoming::Reply { tag, text })) => {
                assert_eq!(at, cut.len());
                assert_eq!(tag, Some(10));
                assert_eq!(text, "error: fault latched: clear first");
            }
            _ => panic!("the reply was not found in {glued}"),
        }
        let record = "!T seq=190 t_s=83.3095 state=fault freq_hz=2.2000 amp_mm=0.000 impacts=0 \
                      peak_n=- impulse_n_s=- regime=- fault=link-lost lost_cycles=0";
        let Ok(Incoming::Record(whole)) = read_line(record) else {
            panic!("{record} does not read");
        };
        match resynchronised(&format!("{cut}{record}")) {
            Some((at, Incoming::Record(r))) => {
                assert_eq!(at, cut.len());
                assert_eq!(r, whole);
            }
            _ => panic!("the record was not found after the cut one"),
        }
        // Damage with a marker whose tail does not read, and an untagged tail: nothing read.
        assert!(resynchronised("!T seq=18#x2 !E junk").is_none());
        assert!(resynchronised("!T seq=18 t_s=1ok").is_none());
        assert!(resynchronised("#1").is_none());
    }

    #[test]
    fn garbage_is_shown_escaped_and_bounded() {
        let e = escaped("a\u{1b}[2J\u{7}\u{0}b");
        assert_eq!(e, "a\\u{1b}[2J\\u{7}\\0b");
        let long = "x".repeat(1000);
        let e = escaped(&long);
        assert!(e.len() < 200 && e.ends_with("(1000 characters)"), "{e}");
    }
}

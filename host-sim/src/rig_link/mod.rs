//! The desktop side of the rig's serial console (`host-sim rig --port …`): a connection that
//! sends one line and waits for its one reply ([`RigPort::command`]), while a reader thread
//! sorts the asynchronous `!T`/`!E` lines ([`AsyncLine`]) from the replies; and what is built on
//! it: the log ([`log`]), the drop-test capture ([`capture`]) and the measured frequency
//! response ([`sweep`]). The same code talks to the board over USB-serial, to the firmware
//! under QEMU and to the virtual rig (`hil --serve-pty`), all through a serial device path.
//!
//! Link failures are errors that say what happened, never hangs: a port that does not open, no
//! reply within the timeout (naming the command), the rig gone (the device closed). A line
//! that is neither a reply nor a well-formed asynchronous line is reported on stderr with its
//! text and skipped.

pub mod capture;
pub mod log;
pub mod protocol;
pub mod sweep;

use std::io::{ErrorKind, Read, Write};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};

pub use protocol::{AsyncLine, CycleLine, EventLine, RigIdentity, SeqCounter};

/// What the reader thread hands over.
enum Incoming {
    Reply(String),
    Closed(String),
}

/// A connection to the rig's console.
pub struct RigPort {
    writer: Box<dyn serialport::SerialPort>,
    replies: Receiver<Incoming>,
    asyncs: Receiver<AsyncLine>,
    reader: Option<JoinHandle<()>>,
    stop: Arc<AtomicBool>,
    timeout: Duration,
    /// What `id` said when the connection was made.
    pub id: RigIdentity,
    closed: Option<String>,
}

impl RigPort {
    /// Opens `path` at `baud`, discards whatever the rig was sending, and synchronises on an
    /// `id` exchange (so a stale reply cannot be taken for the next command's).
    ///
    /// # Errors
    /// The port does not exist or cannot be opened; no `id` reply within `timeout`.
    pub fn open(path: &Path, baud: u32, timeout: Duration) -> Result<Self> {
        anyhow::ensure!(
            path.exists(),
            "--port {}: no such device (is the rig connected, or the virtual rig running?)",
            path.display()
        );
        let port = serialport::new(path.to_string_lossy(), baud)
            .timeout(Duration::from_millis(50))
            .open()
            .with_context(|| format!("--port {}: cannot open", path.display()))?;
        let _ = port.clear(serialport::ClearBuffer::All);
        let reader_port = port
            .try_clone()
            .with_context(|| format!("--port {}", path.display()))?;
        let (reply_tx, replies) = channel();
        let (async_tx, asyncs) = channel();
        let stop = Arc::new(AtomicBool::new(false));
        let stop_reader = Arc::clone(&stop);
        let reader = std::thread::spawn(move || {
            read_lines(reader_port, &stop_reader, reply_tx, async_tx);
        });
        let mut rig = RigPort {
            writer: port,
            replies,
            asyncs,
            reader: Some(reader),
            stop,
            timeout,
            id: RigIdentity::default(),
            closed: None,
        };
        rig.sync()?;
        Ok(rig)
    }

    /// Sends `id` (again every second: a board still starting up drops what it receives)
    /// until its reply comes, and keeps it; then one `diag` exchange, whose reply comes after
    /// any duplicate `id` replies, so that every later reply answers its own line.
    fn sync(&mut self) -> Result<()> {
        let deadline = Instant::now() + self.timeout;
        let mut next_send = Instant::now();
        loop {
            if Instant::now() >= next_send {
                self.write_line("id")?;
                next_send = Instant::now() + Duration::from_secs(1);
            }
            let left = deadline
                .min(next_send)
                .saturating_duration_since(Instant::now());
            match self.replies.recv_timeout(left) {
                Ok(Incoming::Reply(r)) if r.starts_with("id ") => {
                    self.id = protocol::parse_id(&r)?;
                    break;
                }
                Ok(Incoming::Reply(_)) => {}
                Ok(Incoming::Closed(why)) => bail!("the rig closed the link: {why}"),
                Err(RecvTimeoutError::Timeout) if Instant::now() < deadline => {}
                Err(RecvTimeoutError::Timeout) => bail!(
                    "no reply to `id` within {:.1} s: is this the rig's console (115200 8N1)?",
                    self.timeout.as_secs_f64()
                ),
                Err(RecvTimeoutError::Disconnected) => bail!("the link closed"),
            }
        }
        self.write_line("diag")?;
        loop {
            let left = deadline.saturating_duration_since(Instant::now()) + self.timeout;
            match self.replies.recv_timeout(left) {
                Ok(Incoming::Reply(r)) if r.starts_with("diag ") => return Ok(()),
                Ok(Incoming::Reply(_)) => {}
                Ok(Incoming::Closed(why)) => bail!("the rig closed the link: {why}"),
                Err(_) => bail!("no reply to `diag` after `id`"),
            }
        }
    }

    fn write_line(&mut self, line: &str) -> Result<()> {
        if let Some(why) = &self.closed {
            bail!("the rig closed the link: {why}");
        }
        self.writer
            .write_all(format!("{line}\n").as_bytes())
            .and_then(|()| self.writer.flush())
            .with_context(|| format!("sending `{line}`"))
    }

    /// Sends `line` and returns its reply (`ok`, a status line, `error: …`, …).
    ///
    /// # Errors
    /// No reply within the timeout, or the link closed.
    pub fn command(&mut self, line: &str) -> Result<String> {
        self.write_line(line)?;
        self.reply(line)
    }

    /// Sends raw bytes (which should end a line) without waiting: pair with
    /// [`RigPort::reply`], once per line sent.
    ///
    /// # Errors
    /// The link closed.
    pub fn send_bytes(&mut self, bytes: &[u8]) -> Result<()> {
        if let Some(why) = &self.closed {
            bail!("the rig closed the link: {why}");
        }
        self.writer
            .write_all(bytes)
            .and_then(|()| self.writer.flush())
            .context("sending bytes")
    }

    /// The next reply; `what` names the line it answers in errors.
    ///
    /// # Errors
    /// No reply within the timeout, or the link closed.
    pub fn reply(&mut self, line: &str) -> Result<String> {
        match self.replies.recv_timeout(self.timeout) {
            Ok(Incoming::Reply(r)) => Ok(r),
            Ok(Incoming::Closed(why)) => {
                self.closed = Some(why.clone());
                bail!("the rig closed the link while `{line}` waited for its reply: {why}")
            }
            Err(RecvTimeoutError::Timeout) => bail!(
                "no reply to `{line}` within {:.1} s (the rig stopped answering)",
                self.timeout.as_secs_f64()
            ),
            Err(RecvTimeoutError::Disconnected) => bail!("the link closed during `{line}`"),
        }
    }

    /// [`RigPort::command`], with an `error: …` reply turned into an error.
    ///
    /// # Errors
    /// As [`RigPort::command`], or the rig refused the command.
    pub fn command_ok(&mut self, line: &str) -> Result<String> {
        let r = self.command(line)?;
        if let Some(e) = r.strip_prefix("error: ") {
            bail!("the rig refused `{line}`: {e}");
        }
        Ok(r)
    }

    /// The next asynchronous line, waiting at most `wait`.
    ///
    /// # Errors
    /// The link closed (the rig went away).
    pub fn next_async(&mut self, wait: Duration) -> Result<Option<AsyncLine>> {
        match self.asyncs.recv_timeout(wait) {
            Ok(a) => Ok(Some(a)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => {
                // The reader ended: say why if it told the reply channel.
                let why = match self.replies.try_recv() {
                    Ok(Incoming::Closed(w)) => w,
                    _ => self
                        .closed
                        .clone()
                        .unwrap_or_else(|| "device closed".into()),
                };
                self.closed = Some(why.clone());
                Err(anyhow!("the rig closed the link: {why}"))
            }
        }
    }

    /// Drops the asynchronous lines received so far.
    pub fn drain_async(&mut self) {
        while self.asyncs.try_recv().is_ok() {}
    }

    /// The rig's own clock (`diag uptime_ms`), s.
    ///
    /// # Errors
    /// As [`RigPort::command`], or a malformed `diag` reply.
    pub fn uptime_s(&mut self) -> Result<f64> {
        let d = self.command_ok("diag")?;
        let ms: u64 = protocol::field(&d, "uptime_ms")
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| anyhow!("malformed diag reply: {d}"))?;
        Ok(ms as f64 / 1e3)
    }

    /// Reply timeout.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }
}

impl Drop for RigPort {
    fn drop(&mut self) {
        // Stop the reader (it polls with a short timeout) so that its handle on the device is
        // closed too: the port is free for the next program.
        self.stop.store(true, Ordering::Relaxed);
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
    }
}

/// The reader thread: splits the byte stream into lines; replies to one channel, parsed
/// asynchronous lines to the other, garbled lines to stderr.
fn read_lines(
    mut port: Box<dyn serialport::SerialPort>,
    stop: &AtomicBool,
    replies: Sender<Incoming>,
    asyncs: Sender<AsyncLine>,
) {
    let mut buf: Vec<u8> = Vec::new();
    let mut chunk = [0u8; 4096];
    let mut zero_reads = 0u32;
    while !stop.load(Ordering::Relaxed) {
        match port.read(&mut chunk) {
            Ok(0) => {
                zero_reads += 1;
                if zero_reads > 20 {
                    let _ = replies.send(Incoming::Closed("device closed".into()));
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
                let _ = replies.send(Incoming::Closed(e.to_string()));
                return;
            }
        }
        while let Some(end) = buf.iter().position(|&b| b == b'\n' || b == b'\r') {
            let raw: Vec<u8> = buf.drain(..=end).collect();
            let raw = &raw[..raw.len() - 1];
            if raw.is_empty() {
                continue;
            }
            let Ok(text) = std::str::from_utf8(raw) else {
                eprintln!(
                    "warning: garbled line skipped: {}",
                    String::from_utf8_lossy(raw)
                );
                continue;
            };
            if text.starts_with('!') {
                match protocol::parse_async(text) {
                    Some(a) => {
                        if asyncs.send(a).is_err() {
                            return;
                        }
                    }
                    None => eprintln!("warning: unknown asynchronous line skipped: {text}"),
                }
            } else if replies.send(Incoming::Reply(text.to_string())).is_err() {
                return;
            }
        }
        if buf.len() > 1 << 16 {
            eprintln!("warning: 64 KiB without a line end discarded");
            buf.clear();
        }
    }
}

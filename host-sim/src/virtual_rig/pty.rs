//! The virtual rig behind a pseudo-terminal (`host-sim hil --serve-pty`): the session of
//! [`super::session`] with its console on a pty instead of the scenario's timed lines, so that
//! `host-sim rig --port /dev/pts/N` (or any serial terminal) talks to it as to the board over
//! USB-serial. Bytes in and out are the firmware's: the same `shared::console::Link` and console service.
//!
//! The serial line is modelled at 115200 8N1 (11,520 bytes per second of rig time, both ways):
//! what the client writes is taken from the pty at the line rate (a faster writer waits, as for
//! a wire), so a flood costs the rig neither memory nor time; bytes the client does not take (a
//! full pty buffer) are lost as on a real wire. Rig time runs
//! `speed` times faster than the wall clock (1: real time), or as fast as the machine allows.

use std::fs::File;
use std::io::{ErrorKind, Read, Write};
use std::os::fd::OwnedFd;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use nix::fcntl::{FcntlArg, OFlag, fcntl};
use nix::pty::openpty;
use nix::sys::termios::{SetArg, cfmakeraw, tcgetattr, tcsetattr};
use shared::console::RxError;
use shared::console::link::TX_CAPACITY;
use shared::console::serve::{AsyncText, ReplyText, format_answer, format_async};
use shared::control::SAMPLE_RATE_HZ;

use super::session::{HilRun, HilSetup, Session};

/// The console's line rate, bytes per second (115200 baud, 10 bits per byte).
pub const UART_BYTES_PER_S: f64 = 11_520.0;

/// A pseudo-terminal pair: the rig holds the master; clients open the slave's path (and may
/// come and go: with no client, what the rig sends is lost, as on an unplugged cable).
pub struct Pty {
    master: File,
    path: PathBuf,
}

impl Pty {
    /// Opens a pty in raw mode (no echo, no line editing), master non-blocking.
    ///
    /// # Errors
    /// The system refuses a pty.
    pub fn open() -> Result<Self> {
        let pair = openpty(None, None).context("cannot open a pseudo-terminal")?;
        let mut t = tcgetattr(&pair.slave).context("pty attributes")?;
        cfmakeraw(&mut t);
        tcsetattr(&pair.slave, SetArg::TCSANOW, &t).context("pty raw mode")?;
        let flags = fcntl(&pair.master, FcntlArg::F_GETFL).context("pty flags")?;
        fcntl(
            &pair.master,
            FcntlArg::F_SETFL(OFlag::from_bits_truncate(flags) | OFlag::O_NONBLOCK),
        )
        .context("pty non-blocking")?;
        let path = nix::unistd::ttyname(&pair.slave).context("pty name")?;
        // The slave is not kept open here: a client's exclusive-access flag then ends with its
        // last close.
        drop::<OwnedFd>(pair.slave);
        Ok(Pty {
            master: File::from(pair.master),
            path,
        })
    }

    /// The path clients open (`/dev/pts/N`).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Takes up to `max` bytes of what the client sent into the receive FIFO (what does not
    /// fit is dropped and counted there); the rest waits in the pty, as bytes wait for a wire
    /// at the line rate. Returns the bytes taken.
    ///
    /// # Errors
    /// A read error other than "nothing there".
    pub fn read_into(&mut self, fifo: &mut RxFifo, max: usize) -> Result<usize> {
        let mut chunk = [0u8; 256];
        let mut taken = 0;
        while taken < max {
            let want = (max - taken).min(chunk.len());
            match self.master.read(&mut chunk[..want]) {
                Ok(0) => break,
                Ok(n) => {
                    fifo.push(&chunk[..n]);
                    taken += n;
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                // EIO: no client has the slave open.
                Err(e) if e.raw_os_error() == Some(nix::libc::EIO) => break,
                Err(e) => return Err(e).context("reading the pty"),
            }
        }
        Ok(taken)
    }

    /// Writes what the pty takes; returns the bytes it did not take (lost, as on a wire).
    pub fn write_lossy(&mut self, bytes: &[u8]) -> usize {
        let mut rest = bytes;
        while !rest.is_empty() {
            match self.master.write(rest) {
                Ok(0) => break,
                Ok(n) => rest = &rest[n..],
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(_) => break,
            }
        }
        rest.len()
    }
}

/// The receive side of the virtual rig's UART: a bounded FIFO (what a USB-serial adapter
/// holds) drained at the line rate; bytes that find it full are dropped and counted, and the
/// line they belong to is lost (a receive overrun, as the board's UART flags it).
#[derive(Debug, Default)]
pub struct RxFifo {
    bytes: std::collections::VecDeque<u8>,
    /// Bytes received.
    pub received: usize,
    /// Bytes dropped because the FIFO was full.
    pub dropped: usize,
    /// Bytes were dropped since the link was last told.
    overrun: bool,
}

/// Capacity of the receive FIFO, bytes.
pub const RX_FIFO: usize = 256;

impl RxFifo {
    fn push(&mut self, bytes: &[u8]) {
        self.received += bytes.len();
        let room = RX_FIFO - self.bytes.len();
        let (keep, drop) = bytes.split_at(bytes.len().min(room));
        self.bytes.extend(keep);
        if !drop.is_empty() {
            self.dropped += drop.len();
            self.overrun = true;
        }
    }

    /// The next byte for the UART, or an overrun to report first (`Err`).
    fn pop(&mut self) -> Option<Result<u8, RxError>> {
        if std::mem::take(&mut self.overrun) {
            return Some(Err(RxError::Overrun));
        }
        self.bytes.pop_front().map(Ok)
    }
}

/// How the served rig runs.
#[derive(Debug, Clone, Copy)]
pub struct ServeOptions {
    /// Rig time over wall time (1: real time); `f64::INFINITY`: as fast as possible.
    pub speed: f64,
    /// Stop after this much rig time, s (`None`: until interrupted).
    pub seconds: Option<f64>,
}

/// What the server counted besides the session.
#[derive(Debug, Clone, Copy, Default)]
pub struct ServeStats {
    /// Bytes the pty did not take (no client reading fast enough).
    pub tx_lost_bytes: usize,
    /// Bytes received.
    pub rx_bytes: usize,
    /// Bytes received that found the receive FIFO full (dropped).
    pub rx_dropped_bytes: usize,
}

/// Serves the virtual rig on a new pty: `ready` gets its path once it is open (the command
/// prints `pty: /dev/pts/N` there); runs until `seconds` of rig time or Ctrl-C/SIGTERM.
///
/// # Errors
/// Invalid setup, pty failures.
pub fn serve(
    setup: &HilSetup,
    opts: &ServeOptions,
    ready: impl FnOnce(&Path),
) -> Result<(HilRun, ServeStats)> {
    anyhow::ensure!(
        opts.speed > 0.0 && !opts.speed.is_nan(),
        "--speed = {} is out of range: allowed > 0",
        opts.speed
    );
    if let Some(s) = opts.seconds {
        anyhow::ensure!(
            s.is_finite() && s > 0.0 && s <= 1e7,
            "--seconds = {s} is out of range: allowed (0, 1e7]"
        );
    }
    let mut session = Session::new(setup)?;
    let mut pty = Pty::open()?;
    crate::interrupt::install();
    ready(pty.path());

    let fs = f64::from(SAMPLE_RATE_HZ);
    let per_sample = UART_BYTES_PER_S / fs;
    let end = opts.seconds.map(|s| (s * fs).round() as u64);
    let mut rx = RxFifo::default();
    let mut tx: Vec<u8> = Vec::new();
    let (mut rx_credit, mut tx_credit, mut wire_credit) = (0.0f64, 0.0f64, 0.0f64);
    let mut reply = ReplyText::new();
    let mut line = AsyncText::new();
    let mut stats = ServeStats::default();
    let start = Instant::now();
    loop {
        let k = session.samples();
        if end.is_some_and(|e| k >= e) {
            break;
        }
        if k.is_multiple_of(10) {
            // Every millisecond of rig time: the pty both ways, and the pace.
            if crate::interrupt::requested() {
                break;
            }
            // The wire carries at most the line rate: a client that writes faster is held
            // back in the pty (a flood never holds the loop, so telemetry keeps its pace).
            wire_credit = (wire_credit + UART_BYTES_PER_S * 1e-3).min(UART_BYTES_PER_S * 2e-3);
            wire_credit -= pty.read_into(&mut rx, wire_credit as usize)? as f64;
            if !tx.is_empty() {
                stats.tx_lost_bytes += pty.write_lossy(&tx);
                tx.clear();
            }
            if opts.speed.is_finite() {
                let due = Duration::from_secs_f64(k as f64 / fs / opts.speed);
                let now = start.elapsed();
                if due > now + Duration::from_micros(500) {
                    std::thread::sleep(due - now);
                }
            }
        }
        session.begin_sample()?;
        // UART receive at the line rate; every line's end feeds the link-loss watchdog.
        rx_credit = (rx_credit + per_sample).min(1.0 + per_sample);
        while rx_credit >= 1.0 {
            let Some(b) = rx.pop() else {
                rx_credit = rx_credit.min(1.0);
                break;
            };
            match b {
                Ok(b) => {
                    if session.link_mut().on_rx_byte(b) {
                        session.controller_mut().link_alive();
                    }
                    rx_credit -= 1.0;
                }
                Err(e) => session.link_mut().on_rx_error(e),
            }
        }
        // The console service: every line it can answer now (none after an accepted `reset`:
        // the board restarts once that reply is out).
        while !session.restart_pending()
            && let Some(pending) = session.link_mut().next_line()
        {
            let a = session.answer(pending.as_line());
            format_answer(&a, &mut reply);
            session.link_mut().push_reply(&reply);
        }
        if session.restart_pending() && session.link_mut().tx_free() == TX_CAPACITY {
            session.restart()?;
        }
        session.end_sample();
        session.send_commission_lines();
        while let Some(rec) = session.controller_mut().pop_async() {
            if format_async(&rec, &mut line) {
                session.link_mut().push_async(&line);
            }
        }
        // UART transmit at the line rate.
        tx_credit = (tx_credit + per_sample).min(1.0 + per_sample);
        while tx_credit >= 1.0 {
            let Some(b) = session.link_mut().pop_tx() else {
                tx_credit = tx_credit.min(1.0);
                break;
            };
            tx.push(b);
            tx_credit -= 1.0;
        }
    }
    stats.rx_bytes = rx.received;
    stats.rx_dropped_bytes = rx.dropped;
    stats.tx_lost_bytes += pty.write_lossy(&tx);
    Ok((session.finish(), stats))
}

//! The console's serial link, hardware-free: received bytes become lines ([`LineBuffer`]) that
//! wait in a short queue for the console service ([`super::serve`]); replies and asynchronous
//! lines wait in a bounded transmit queue that the UART drains one byte at a time (the
//! firmware's USART2 TXE interrupt; the virtual rig at the baud rate).
//!
//! Guarantees, each tested here:
//! - every received line gets exactly one reply, in order: the service takes a line only when
//!   the transmit queue has room for the longest reply ([`REPLY_ROOM`]); a line that finds the
//!   line queue full is answered `error: line lost` once the queue has drained;
//! - a line hit by a receive error (overrun, framing, noise) never runs: it is answered
//!   `error: line lost` and counted;
//! - asynchronous lines (telemetry, events) are queued only while that leaves [`REPLY_ROOM`]
//!   free, so they can never hold a reply back; when they do not fit they are dropped and
//!   counted (their sequence numbers show the gap on the desktop);
//! - replies never hold telemetry back either: the service takes a line only while the room
//!   for its reply and for one asynchronous line after it is free ([`SERVE_ROOM`]), so a flood
//!   of lines that each get a reply still leaves every telemetry line its place.

use heapless::{Deque, String};

use super::framing::{Line, LineBuffer, MAX_LINE, RxError, is_line_end};

/// Transmit queue, bytes.
pub const TX_CAPACITY: usize = 2048;
/// Longest reply line, bytes, without the line ending (a capture segment is 811).
pub const MAX_REPLY: usize = 840;
/// Free transmit space a reply needs (the reply and `\r\n`).
pub const REPLY_ROOM: usize = MAX_REPLY + 2;
/// Longest asynchronous line, bytes, without the line ending (a telemetry line is about 150).
pub const MAX_ASYNC: usize = 192;
/// Free transmit space an asynchronous line needs at most (the line and `\r\n`).
pub const ASYNC_ROOM: usize = MAX_ASYNC + 2;
/// Free transmit space the service needs to take a line: its reply's, and after it what one
/// asynchronous line needs to be queued (its own room and the reply room it must leave).
pub const SERVE_ROOM: usize = REPLY_ROOM + ASYNC_ROOM + REPLY_ROOM;
const _: () = assert!(SERVE_ROOM < TX_CAPACITY);
/// Complete lines waiting for the service.
pub const PENDING_LINES: usize = 4;

/// A received line waiting for the service.
#[derive(Debug, Clone, PartialEq)]
pub enum PendingLine {
    /// Text to parse.
    Text(String<MAX_LINE>),
    /// Longer than [`MAX_LINE`] or not UTF-8.
    Bad,
    /// Hit by a receive error, or found the line queue full.
    Lost,
}

impl PendingLine {
    /// As a [`Line`] for [`super::serve::answer`].
    pub fn as_line(&self) -> Line<'_> {
        match self {
            PendingLine::Text(s) => Line::Text(s.as_str()),
            PendingLine::Bad => Line::Bad,
            PendingLine::Lost => Line::Lost,
        }
    }
}

/// Counters of the link (`diag`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkStats {
    /// Receive errors flagged by the UART.
    pub rx_errors: u32,
    /// Lines answered `error: line lost` (receive error or line queue full).
    pub lines_lost: u32,
    /// Asynchronous lines queued.
    pub async_sent: u32,
    /// Asynchronous lines dropped because the transmit queue was too full.
    pub async_dropped: u32,
}

/// The link.
#[derive(Debug, Clone, Default)]
pub struct Link {
    rx: LineBuffer,
    pending: Deque<PendingLine, PENDING_LINES>,
    /// Lines that found `pending` full: answered `error: line lost` after it drains.
    overflowed: u32,
    tx: Deque<u8, TX_CAPACITY>,
    stats: LinkStats,
    /// Received characters are echoed back (`echo on`).
    echo: bool,
}

impl Link {
    /// An idle link.
    pub fn new() -> Self {
        Self::default()
    }

    /// A received byte; `true` at a line's end (`\n` or `\r`, an empty line too: what
    /// keeps the controller's link-loss watchdog fed). With the echo on, what the line buffer
    /// says a terminal should show of it is queued ([`LineBuffer::echo`]).
    pub fn on_rx_byte(&mut self, byte: u8) -> bool {
        let end = is_line_end(byte);
        let pending = match self.rx.push(byte) {
            None => None,
            Some(Line::Text(s)) => {
                let mut owned = String::new();
                // `s` is at most MAX_LINE bytes: it fits.
                let _ = owned.push_str(s);
                Some(PendingLine::Text(owned))
            }
            Some(Line::Bad) => Some(PendingLine::Bad),
            Some(Line::Lost) => Some(PendingLine::Lost),
        };
        if self.echo {
            self.echo_last();
        }
        if let Some(pending) = pending {
            if self.overflowed > 0 || self.pending.is_full() {
                self.overflowed = self.overflowed.saturating_add(1);
            } else {
                let _ = self.pending.push_back(pending);
            }
        }
        end
    }

    /// Queues the echo of the byte just received, only while that leaves room for a reply (an
    /// echo is never worth a reply).
    fn echo_last(&mut self) {
        let mut echo = [0u8; 3];
        let mut n = 0;
        for (to, &from) in echo.iter_mut().zip(self.rx.echo()) {
            *to = from;
            n += 1;
        }
        if n > 0 && self.tx_free() >= n + REPLY_ROOM {
            self.push_bytes(echo.get(..n).unwrap_or_default());
        }
    }

    /// Turns the echo on or off.
    pub fn set_echo(&mut self, on: bool) {
        self.echo = on;
    }

    /// Whether received characters are echoed.
    pub fn echo(&self) -> bool {
        self.echo
    }

    /// A byte received with an error (the byte, if any, is discarded).
    pub fn on_rx_error(&mut self, _error: RxError) {
        self.stats.rx_errors = self.stats.rx_errors.saturating_add(1);
        self.rx.error();
    }

    /// Whether a line waits and the transmit queue has room for its reply.
    pub fn ready(&self) -> bool {
        self.has_line() && self.tx_free() >= SERVE_ROOM
    }

    /// Whether a line waits for the service.
    pub fn has_line(&self) -> bool {
        !self.pending.is_empty() || self.overflowed > 0
    }

    /// The next line for the service, if one waits and its reply will fit.
    pub fn next_line(&mut self) -> Option<PendingLine> {
        if self.tx_free() < SERVE_ROOM {
            return None;
        }
        let line = match self.pending.pop_front() {
            Some(l) => l,
            None if self.overflowed > 0 => {
                self.overflowed -= 1;
                PendingLine::Lost
            }
            None => return None,
        };
        if line == PendingLine::Lost {
            self.stats.lines_lost = self.stats.lines_lost.saturating_add(1);
        }
        Some(line)
    }

    /// Queues a reply line (`\r\n` appended; cut at [`MAX_REPLY`]). The service calls it once
    /// per line taken with [`Link::next_line`], which guaranteed the room.
    pub fn push_reply(&mut self, text: &str) {
        let body = text.as_bytes();
        let body = body.get(..MAX_REPLY).unwrap_or(body);
        for &b in body.iter().chain(b"\r\n") {
            if self.tx.push_back(b).is_err() {
                break;
            }
        }
    }

    /// Queues an asynchronous line (`\r\n` appended) if that leaves room for a reply; otherwise
    /// drops it and counts it. Returns whether it was queued.
    pub fn push_async(&mut self, text: &str) -> bool {
        if !self.reserve_async(text.len()) {
            return false;
        }
        self.push_bytes(text.as_bytes());
        self.push_bytes(b"\r\n");
        true
    }

    /// Whether an asynchronous line of `len` bytes (plus `\r\n`) may be queued now, counted as
    /// sent or dropped. For a caller that queues the line in pieces ([`Link::push_bytes`], each
    /// under a short lock): the room only grows meanwhile, as only the UART takes bytes out.
    pub fn reserve_async(&mut self, len: usize) -> bool {
        let fits = self.fits_async(len);
        if !fits {
            self.stats.async_dropped = self.stats.async_dropped.saturating_add(1);
        }
        fits
    }

    /// Whether an asynchronous line of `len` bytes (plus `\r\n`) fits now, leaving a reply its
    /// room; if so it counts as sent (queue it with [`Link::push_bytes`]). Unlike
    /// [`Link::reserve_async`], a line that does not fit is not counted: its sender keeps it
    /// and tries again (the commissioning's records, which are never dropped).
    pub fn fits_async(&mut self, len: usize) -> bool {
        let fits = self.tx_free() >= len + 2 + REPLY_ROOM;
        if fits {
            self.stats.async_sent = self.stats.async_sent.saturating_add(1);
        }
        fits
    }

    /// Queues raw bytes (as many as fit): a piece of a reply whose room [`Link::next_line`]
    /// guaranteed, or of an asynchronous line [`Link::reserve_async`] admitted.
    pub fn push_bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if self.tx.push_back(b).is_err() {
                break;
            }
        }
    }

    /// The next byte to transmit.
    pub fn pop_tx(&mut self) -> Option<u8> {
        self.tx.pop_front()
    }

    /// Free transmit space, bytes.
    pub fn tx_free(&self) -> usize {
        TX_CAPACITY - self.tx.len()
    }

    /// The counters.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;
    use std::vec::Vec;

    fn feed(link: &mut Link, bytes: &[u8]) {
        for &b in bytes {
            link.on_rx_byte(b);
        }
    }

    fn drain(link: &mut Link) -> std::string::String {
        let mut out = Vec::new();
        while let Some(b) = link.pop_tx() {
            out.push(b);
        }
        std::string::String::from_utf8(out).unwrap()
    }

    #[test]
    fn one_reply_per_line_in_order_even_when_the_line_queue_overflows() {
        let mut link = Link::new();
        // Seven lines at once: four wait, three overflow and are answered `lost` after them.
        feed(&mut link, b"a\nb\nc\nd\ne\nf\ng\n");
        let mut answered = Vec::new();
        while let Some(l) = link.next_line() {
            answered.push(match l {
                PendingLine::Text(s) => s.to_string(),
                other => std::format!("{other:?}"),
            });
            link.push_reply("r");
        }
        assert_eq!(answered, ["a", "b", "c", "d", "Lost", "Lost", "Lost"]);
        assert_eq!(link.stats().lines_lost, 3);
        assert_eq!(drain(&mut link), "r\r\n".repeat(7));
    }

    #[test]
    fn replies_wait_for_room_and_async_lines_never_take_it() {
        let mut link = Link::new();
        let long = "x".repeat(100);
        // Telemetry fills the queue up to the reply reserve, then is dropped.
        let mut queued = 0;
        for _ in 0..40 {
            if link.push_async(&long) {
                queued += 1;
            }
        }
        assert_eq!(queued, (TX_CAPACITY - REPLY_ROOM) / 102);
        assert!(link.stats().async_dropped > 0);
        assert!(link.tx_free() >= REPLY_ROOM);
        // A line waits until the UART has made room for its reply and one telemetry line after
        // it (a reply never holds telemetry back), and is then served before any new telemetry.
        feed(&mut link, b"status\n");
        assert!(!link.ready());
        while !link.ready() {
            link.pop_tx().unwrap();
        }
        assert_eq!(link.tx_free(), SERVE_ROOM);
        let l = link.next_line().unwrap();
        assert_eq!(l, PendingLine::Text(String::try_from("status").unwrap()));
        link.push_reply(&"y".repeat(MAX_REPLY));
        // Now the queue is too full for another reply: the next line waits.
        feed(&mut link, b"id\n");
        assert!(!link.ready() && link.has_line());
        assert_eq!(link.next_line(), None);
        // The UART drains it; the line is served once that room is free again.
        let mut drained = 0;
        while !link.ready() {
            link.pop_tx().unwrap();
            drained += 1;
        }
        assert_eq!(link.tx_free(), SERVE_ROOM);
        assert!(drained > 0);
    }

    #[test]
    fn a_flood_of_lines_leaves_every_telemetry_line_its_place() {
        // A line every byte time, each answered at length, while a telemetry line of the
        // longest kind comes every 400 byte times (half the line's rate; the rig's telemetry
        // takes at most 40 %): the UART drains one byte per step. Every telemetry line is
        // queued, none dropped, and the replies take the rest of the line.
        let mut link = Link::new();
        let telemetry = "t".repeat(MAX_ASYNC);
        let (mut queued, mut replies) = (0, 0);
        for step in 0..200_000 {
            feed(&mut link, b"x\n");
            while let Some(_line) = link.next_line() {
                link.push_reply("error: unknown command (try `help`)");
                replies += 1;
            }
            if step % 400 == 0 {
                assert!(
                    link.push_async(&telemetry),
                    "telemetry dropped at step {step}"
                );
                queued += 1;
            }
            link.pop_tx();
        }
        assert_eq!((queued, link.stats().async_dropped), (500, 0));
        // The replies' share: what the telemetry left of 200,000 byte times, 37 bytes each.
        let left = 200_000 - 500 * (MAX_ASYNC + 2);
        assert!(
            replies * 37 > left * 9 / 10 && replies * 37 <= left + TX_CAPACITY,
            "{replies}"
        );
    }

    #[test]
    fn a_receive_error_loses_the_line_and_is_counted() {
        let mut link = Link::new();
        feed(&mut link, b"gap 0");
        link.on_rx_error(RxError::Overrun);
        feed(&mut link, b"5\nstart\n");
        assert_eq!(link.next_line(), Some(PendingLine::Lost));
        assert_eq!(
            link.next_line(),
            Some(PendingLine::Text(String::try_from("start").unwrap()))
        );
        assert_eq!(link.stats().rx_errors, 1);
        assert_eq!(link.stats().lines_lost, 1);
    }

    #[test]
    fn line_ends_are_reported_and_the_echo_shows_what_was_typed() {
        let mut link = Link::new();
        let ends: Vec<bool> = b"ab\r\n".iter().map(|&b| link.on_rx_byte(b)).collect();
        assert_eq!(ends, [false, false, true, true]);
        assert_eq!(drain(&mut link), "", "no echo by default");
        link.set_echo(true);
        feed(&mut link, b"statx\x7fus\r");
        assert_eq!(drain(&mut link), "statx\x08 \x08us\r\n");
        // A backspace with nothing to erase, and an escape sequence, are not echoed; nor is a
        // program's tagged line (so a client never reads its request's echo for the reply).
        feed(&mut link, b"\x7f\x1b[A#9 status\n");
        assert_eq!(drain(&mut link), "");
        let l = link.next_line();
        assert_eq!(l, Some(PendingLine::Text(String::try_from("ab").unwrap())));
        let l = link.next_line();
        assert_eq!(
            l,
            Some(PendingLine::Text(String::try_from("status").unwrap()))
        );
        let l = link.next_line();
        assert_eq!(
            l,
            Some(PendingLine::Text(String::try_from("#9 status").unwrap()))
        );
        // The echo never takes a reply's room.
        while link.push_async(&"z".repeat(100)) {}
        feed(&mut link, b"xyz");
        assert!(link.tx_free() >= REPLY_ROOM);
    }
}

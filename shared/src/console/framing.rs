//! Line framing of the console: received bytes become lines ([`LineBuffer`]); a line hit by a
//! receive error ([`RxError`]) or longer than [`MAX_LINE`] is handed out as lost or bad, never as
//! text, so a corrupted command cannot run.

/// Longest accepted line, bytes (without the newline).
pub const MAX_LINE: usize = 64;

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

/// Whether `byte` ends a line (`\n` or `\r`): a text that holds one is two lines to the rig.
#[inline]
pub const fn is_line_end(byte: u8) -> bool {
    byte == b'\n' || byte == b'\r'
}

/// Backspace (`BS`, as Ctrl-H and some terminals send it).
pub const BACKSPACE: u8 = 0x08;
/// Delete (`DEL`, what most terminal programs send for the Backspace key).
pub const DELETE: u8 = 0x7f;

impl LineBuffer {
    /// Adds one byte; returns the line at `\n` or `\r`. Empty lines are skipped, unless a
    /// receive error was flagged since the last line (then the lost line is reported).
    /// [`BACKSPACE`] and [`DELETE`] remove the last byte of the line being received (line
    /// editing from a terminal program); on an over-long line they change nothing.
    pub fn push(&mut self, byte: u8) -> Option<Line<'_>> {
        if core::mem::take(&mut self.done) {
            self.buf.clear();
        }
        if byte == BACKSPACE || byte == DELETE {
            if !self.overflow {
                self.buf.pop();
            }
            return None;
        }
        if is_line_end(byte) {
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

    /// Bytes of the line being received so far.
    pub fn len(&self) -> usize {
        if self.done { 0 } else { self.buf.len() }
    }

    /// Whether no byte of a line is being held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
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

    #[test]
    fn backspace_and_delete_edit_the_line() {
        let mut b = LineBuffer::default();
        let mut got = std::vec::Vec::new();
        for &byte in b"statx\x7fus\n\x08\x08gap 1\x082\n" {
            if let Some(Line::Text(s)) = b.push(byte) {
                got.push(std::string::String::from(s));
            }
        }
        assert_eq!(got, ["status", "gap 2"]);
        // On an over-long line a backspace cannot bring it back under the limit.
        let mut b = LineBuffer::default();
        for _ in 0..MAX_LINE + 1 {
            b.push(b'x');
        }
        b.push(DELETE);
        assert_eq!(b.push(b'\n'), Some(Line::Bad));
    }
}

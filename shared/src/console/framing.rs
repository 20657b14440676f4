//! Line framing of the console: received bytes become lines ([`LineBuffer`]) with a terminal's
//! line editing, and what a terminal should show of each byte (the echo) is decided here with
//! the edit, so that the echo always shows what the rig will parse. A line hit by a receive
//! error ([`RxError`]) is handed out as lost, one longer than [`MAX_LINE`] or holding a control
//! byte as bad, never as text, so a corrupted command cannot run.
//!
//! Line editing (for an operator at a terminal program; a program's lines pass unchanged):
//! - Backspace ([`BACKSPACE`]) and Delete ([`DELETE`]) remove the last character (a whole UTF-8
//!   sequence), echoed as `BS SPACE BS`; with nothing to remove, nothing is echoed.
//! - TAB is kept (the parser reads it as a space) and echoed as a space.
//! - Escape sequences (arrow and function keys: `ESC [ … final`, `ESC O x`, `ESC x`) are
//!   swallowed whole: neither kept nor echoed.
//! - Any other control byte spoils the line (refused at its end as [`Line::Bad`]) and is echoed
//!   in caret notation (`^G` for BEL), so the operator sees why.
//! - The byte that would make the line longer than [`MAX_LINE`] refuses it at once
//!   ([`Line::Bad`], before its end); the rest of that line, up to its end, is discarded
//!   unechoed. The echo ends the shown line there, so the refusal prints on a line of its own.
//! - A line whose first byte other than a space or TAB is `#` is a program's tagged line
//!   (`#<n> …`): nothing of it is echoed, so that a client never reads the echo of its request
//!   for the reply, whatever a terminal session left the echo at.

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

/// Where an escape sequence being swallowed stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
enum Escape {
    /// Not in one.
    #[default]
    None,
    /// After `ESC`: the next byte says which kind.
    Start,
    /// In a control sequence (`ESC [`): up to its final byte (`0x40 ..= 0x7e`).
    Csi,
    /// After `ESC O` (application-mode keys): one more byte.
    Ss3,
}

/// Whether the line being received is a program's tagged line (never echoed).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
enum Tagged {
    /// Only spaces or TABs so far: not known yet.
    #[default]
    Unknown,
    Yes,
    No,
}

/// Collects received bytes into lines, with line editing (the module's doc). A line whose bytes
/// were received with an error ([`LineBuffer::error`]) is handed out as [`Line::Lost`] at its
/// end; one that held a control byte as [`Line::Bad`] at its end; one that overflows
/// [`MAX_LINE`] as [`Line::Bad`] at once. Never as text: a corrupted command cannot run. Every
/// received line (bytes up to a line end) gets exactly one [`Line`], or none if empty.
#[derive(Debug, Clone, Default)]
pub struct LineBuffer {
    buf: heapless::Vec<u8, MAX_LINE>,
    /// The line overflowed and was handed out as bad: discard up to its end.
    skipping: bool,
    /// A receive error happened since the line began.
    error: bool,
    /// A control byte was received in the line: it is bad.
    control: bool,
    /// The buffer holds a line already handed out: start afresh at the next byte.
    done: bool,
    escape: Escape,
    tagged: Tagged,
    /// The last byte was `\r`: a `\n` right after it is the same line end (not echoed twice).
    after_cr: bool,
    /// What a terminal should show for the last byte pushed.
    echo: [u8; 3],
    echo_len: u8,
}

/// A finished line from [`LineBuffer::push`].
#[derive(Debug, Clone, PartialEq)]
pub enum Line<'a> {
    /// A complete line (without `\r`/`\n`).
    Text(&'a str),
    /// The line was longer than [`MAX_LINE`], held a control byte or was not UTF-8; it is
    /// discarded.
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
/// Escape (`ESC`), which starts the sequences of arrow and function keys.
pub const ESCAPE: u8 = 0x1b;
/// What the echo shows for a removed character: back, blank it, back.
pub const ERASE: &[u8] = b"\x08 \x08";

impl LineBuffer {
    /// Adds one byte; returns the line at `\n` or `\r` (or at once, refused, when it overflows
    /// [`MAX_LINE`]). Empty lines are skipped, unless a receive error was flagged since the last
    /// line (then the lost line is reported). The edits and the echo are the module's.
    pub fn push(&mut self, byte: u8) -> Option<Line<'_>> {
        self.echo_len = 0;
        if core::mem::take(&mut self.done) {
            self.buf.clear();
        }
        let after_cr = core::mem::replace(&mut self.after_cr, byte == b'\r');
        if is_line_end(byte) {
            return self.end_line(byte == b'\n' && after_cr);
        }
        if self.skipping {
            return None;
        }
        match self.escape {
            Escape::None => {}
            Escape::Start => {
                self.escape = match byte {
                    b'[' => Escape::Csi,
                    b'O' => Escape::Ss3,
                    _ => Escape::None,
                };
                return None;
            }
            Escape::Csi => {
                if (0x40..=0x7e).contains(&byte) {
                    self.escape = Escape::None;
                }
                return None;
            }
            Escape::Ss3 => {
                self.escape = Escape::None;
                return None;
            }
        }
        match byte {
            ESCAPE => self.escape = Escape::Start,
            // A spoiled line is refused whatever follows: an erasure would not mend it.
            BACKSPACE | DELETE if !self.control => {
                if self.pop_char() {
                    self.show(ERASE);
                }
            }
            BACKSPACE | DELETE => {}
            b'\t' => return self.keep(byte, b' '),
            0x00..=0x1f => {
                self.control = true;
                self.show(&[b'^', byte + 0x40]);
            }
            _ => return self.keep(byte, byte),
        }
        None
    }

    /// The line's end: the line handed out (or nothing for an empty one), the state reset.
    fn end_line(&mut self, second_of_crlf: bool) -> Option<Line<'_>> {
        self.escape = Escape::None;
        let error = core::mem::take(&mut self.error);
        let control = core::mem::take(&mut self.control);
        if core::mem::take(&mut self.skipping) {
            // Refused when it overflowed, its shown line ended then.
            self.tagged = Tagged::Unknown;
            self.buf.clear();
            return None;
        }
        if !second_of_crlf {
            self.show(b"\r\n");
        }
        self.tagged = Tagged::Unknown;
        if error || control {
            self.buf.clear();
            return Some(if error { Line::Lost } else { Line::Bad });
        }
        if self.buf.is_empty() {
            return None;
        }
        self.done = true;
        Some(match core::str::from_utf8(&self.buf) {
            Ok(s) => Line::Text(s),
            Err(_) => Line::Bad,
        })
    }

    /// Keeps `byte` (shown as `shown`), or refuses the line at once when it would overflow.
    fn keep(&mut self, byte: u8, shown: u8) -> Option<Line<'_>> {
        if self.tagged == Tagged::Unknown && byte != b' ' && byte != b'\t' {
            self.tagged = if byte == b'#' {
                Tagged::Yes
            } else {
                Tagged::No
            };
        }
        if self.buf.push(byte).is_ok() {
            self.show(&[shown]);
            return None;
        }
        // The refusal's reply prints on a line of its own.
        self.show(b"\r\n");
        self.skipping = true;
        self.buf.clear();
        self.control = false;
        Some(if core::mem::take(&mut self.error) {
            Line::Lost
        } else {
            Line::Bad
        })
    }

    /// Removes the last character (its UTF-8 continuation bytes and lead byte); whether there
    /// was one.
    fn pop_char(&mut self) -> bool {
        let Some(mut b) = self.buf.pop() else {
            return false;
        };
        while b & 0xc0 == 0x80 {
            match self.buf.pop() {
                Some(x) => b = x,
                None => break,
            }
        }
        true
    }

    /// Sets the echo of the byte being pushed (nothing on a program's tagged line).
    fn show(&mut self, bytes: &[u8]) {
        if self.tagged == Tagged::Yes {
            return;
        }
        let mut n = 0u8;
        for (to, &from) in self.echo.iter_mut().zip(bytes) {
            *to = from;
            n += 1;
        }
        self.echo_len = n;
    }

    /// What a terminal should show for the last byte pushed (empty: nothing), for a link whose
    /// echo is on: the byte itself, [`ERASE`], `\r\n` at a line's end (once for `\r\n`), or a
    /// control byte in caret notation.
    pub fn echo(&self) -> &[u8] {
        // (`get`: no index check that could panic in the console's interrupt.)
        self.echo
            .get(..usize::from(self.echo_len))
            .unwrap_or_default()
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
    /// discarded at its end and reported as [`Line::Lost`]. A line already refused for its
    /// length has had its one reply: the error is counted by the link, not reported again.
    pub fn error(&mut self) {
        if core::mem::take(&mut self.done) {
            self.buf.clear();
        }
        if !self.skipping {
            self.error = true;
        }
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
        // The byte past the limit refuses the line at once; what follows up to its end,
        // a backspace included, is discarded without a second answer.
        let mut b = LineBuffer::default();
        for _ in 0..MAX_LINE {
            assert_eq!(b.push(b'x'), None);
        }
        assert_eq!(b.push(b'x'), Some(Line::Bad));
        assert_eq!(b.push(DELETE), None);
        assert_eq!(b.push(b'y'), None);
        assert_eq!(b.push(b'\n'), None);
        // A receive error in the discarded part does not answer the line again.
        let mut b = LineBuffer::default();
        for _ in 0..=MAX_LINE {
            b.push(b'x');
        }
        b.error();
        assert_eq!(b.push(b'\n'), None);
        assert_eq!(b.push(b'z'), None);
        assert_eq!(b.push(b'\n'), Some(Line::Text("z")));
    }

    /// `bytes` through a line buffer: what its echo showed, and the lines it handed out.
    fn typed(bytes: &[u8]) -> (std::string::String, std::vec::Vec<std::string::String>) {
        let mut b = LineBuffer::default();
        let mut echo = std::vec::Vec::new();
        let mut lines = std::vec::Vec::new();
        for &byte in bytes {
            let line = b.push(byte).map(|l| match l {
                Line::Text(s) => std::string::String::from(s),
                Line::Bad => "<bad>".into(),
                Line::Lost => "<lost>".into(),
            });
            echo.extend_from_slice(b.echo());
            lines.extend(line);
        }
        (
            std::string::String::from_utf8_lossy(&echo).into_owned(),
            lines,
        )
    }

    #[test]
    fn the_echo_shows_what_the_rig_will_parse() {
        // A TAB is kept (the parser's word separator) and shown as a space: `sta⇥tus` shows
        // `sta tus`, two words, as the parser reads it.
        assert_eq!(
            typed(b"sta\ttus\r"),
            ("sta tus\r\n".into(), vec!["sta\ttus".into()])
        );
        // Arrow keys (CSI and SS3 forms) and Alt+key are swallowed whole.
        assert_eq!(
            typed(b"sta\x1b[D\x1bOAtu\x1bxs\x1b[1;5C\n"),
            ("status\r\n".into(), vec!["status".into()])
        );
        // Another control byte spoils the line, shown in caret notation; an erasure does not
        // mend it.
        assert_eq!(
            typed(b"st\x07op\x7f\n"),
            ("st^Gop\r\n".into(), vec!["<bad>".into()])
        );
        // A UTF-8 character is erased whole.
        assert_eq!(
            typed("gé\x7f\x7fid\n".as_bytes()),
            ("gé\x08 \x08\x08 \x08id\r\n".into(), vec!["id".into()])
        );
        // Over the limit: the echo ends the shown line where the line was refused, and shows
        // nothing more of it.
        let mut long = vec![b'x'; MAX_LINE + 1];
        long.extend_from_slice(b"yy\x7f\nok\n");
        let (echo, lines) = typed(&long);
        assert_eq!(echo, format!("{}\r\nok\r\n", "x".repeat(MAX_LINE)));
        assert_eq!(lines, ["<bad>", "ok"]);
        // `\r\n` is one line end, shown once.
        assert_eq!(typed(b"a\r\n\r\n"), ("a\r\n\r\n".into(), vec!["a".into()]));
        // A program's tagged line is never echoed (the blanks before its `#` are).
        assert_eq!(
            typed(b"#5 status\n  #6 id\r\n"),
            ("  ".into(), vec!["#5 status".into(), "  #6 id".into()])
        );
    }
}

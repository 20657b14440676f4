//! The operator console's protocol, both directions, in one place: what the firmware writes and
//! what the desktop reads are the same types with one [`core::fmt::Display`] and one
//! [`core::str::FromStr`] each, checked by a round trip (`parse(format(x)) == x`, `shared`'s
//! tests). The controller ([`crate::control`]) holds no text: this module maps text to and from
//! its types.
//!
//! The link: USART2, 115200 8N1, lines of at most [`MAX_LINE`] bytes ended by `\n` or `\r`.
//!
//! - [`framing`]: received bytes → lines ([`LineBuffer`]); receive errors spoil the line they hit.
//! - [`link`]: the line queue and the bounded transmit queue ([`Link`]) that keeps room for a
//!   reply, so telemetry never holds one back.
//! - [`request`]: the request grammar, one line → one [`Request`] ([`parse`], [`HELP`]).
//! - [`reply`]: the replies, one line per request: `ok`, the status line, the help line,
//!   `id …`, `diag …`, `capture …`, `segment …`, or `error: …` ([`Answer`]).
//! - [`record`]: the asynchronous lines while streaming, `!T` (a drive cycle) and `!E` (an
//!   event) ([`crate::control::AsyncRecord`]); a reply never starts with `!`.
//! - [`settings`]: the model, calibration and store lines, and the refusals of their changes.
//! - [`serve`]: one line in, one [`Answer`] out, for the firmware and the virtual rig alike.
//! - [`decimal`], [`fields`], [`token`], [`board`]: decimal numbers, `key=value` fields, the
//!   names of states, faults, rigs and stores, and which image answers.
//!
//! The text of every line, with an example of each, is in docs/operator.md ("The console").

pub mod board;
pub mod commission;
pub mod decimal;
pub mod drop_id;
pub mod fields;
pub mod framing;
pub mod link;
pub mod record;
pub mod reply;
pub mod request;
pub mod serve;
pub mod settings;
pub mod token;

pub use board::Board;
pub use decimal::{Decimal, Exact, parse_decimal, parse_exact};
pub use drop_id::IdentifyLine;
pub use fields::WireError;
pub use framing::{Line, LineBuffer, MAX_LINE, RxError, is_line_end};
pub use link::{Link, LinkStats, PendingLine};
pub use reply::{Answer, AnswerError, BoardInfo, CaptureError, DiagInfo, IdInfo, Version};
pub use request::{Arg, DraftCommand, HELP, ParseError, Request, parse};
pub use serve::{Direct, RigAccess, answer, format_answer, format_async};
pub use settings::{
    CalibView, FieldProblem, ModelOf, ModelView, SettingsRefusal, StoreRefusal, StoreView,
};
pub use token::Token;

/// Whether `value`'s text is `text` (compared as it is written, without allocating).
pub(crate) fn displays_as(value: &impl core::fmt::Display, text: &str) -> bool {
    struct Cmp<'a> {
        rest: &'a str,
        same: bool,
    }
    impl core::fmt::Write for Cmp<'_> {
        fn write_str(&mut self, s: &str) -> core::fmt::Result {
            match self.rest.strip_prefix(s) {
                Some(r) if self.same => self.rest = r,
                _ => self.same = false,
            }
            Ok(())
        }
    }
    let mut c = Cmp {
        rest: text,
        same: true,
    };
    let _ = core::fmt::write(&mut c, format_args!("{value}"));
    c.same && c.rest.is_empty()
}

//! `key=value` fields, as the replies and asynchronous lines carry them: [`Fields`] reads them
//! in order and checks each value at the edge (finite, in range, a known name), so that a bad
//! number from the link is an error naming its field, never a value.

use core::fmt;

use super::decimal::parse_decimal;
use super::token::Token;

/// Why a reply or asynchronous line does not read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireError {
    /// The line is not of the kind asked for (its first word, or its shape).
    Kind,
    /// The field `key=` is missing where it belongs.
    Missing(&'static str),
    /// The value of `key=` does not read: not a number, not finite, out of its range, or an
    /// unknown name.
    Bad(&'static str),
    /// Text after the last field.
    Trailing,
    /// The value of `key=` disagrees with another field or with this protocol (a length, a
    /// rate, a capacity).
    Mismatch(&'static str),
}

impl fmt::Display for WireError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WireError::Kind => f.write_str("not a line of the expected kind"),
            WireError::Missing(k) => write!(f, "`{k}=` missing"),
            WireError::Bad(k) => write!(
                f,
                "bad value of `{k}=` (not a finite number in range, or an unknown name)"
            ),
            WireError::Trailing => f.write_str("unexpected text after the last field"),
            WireError::Mismatch(k) => write!(
                f,
                "`{k}=` disagrees with the rest of the line or with this client's protocol"
            ),
        }
    }
}

/// Reads the `key=value` words of a line in order.
pub struct Fields<'a> {
    words: core::str::SplitAsciiWhitespace<'a>,
}

impl<'a> Fields<'a> {
    /// The fields of `text` (the line after its first word, if that is not a field).
    pub fn new(text: &'a str) -> Self {
        Fields {
            words: text.split_ascii_whitespace(),
        }
    }

    /// The value of the next field, which must be `key`.
    ///
    /// # Errors
    /// [`WireError::Missing`] when the next word is not `key=…`.
    pub fn raw(&mut self, key: &'static str) -> Result<&'a str, WireError> {
        self.words
            .next()
            .and_then(|w| w.strip_prefix(key)?.strip_prefix('='))
            .ok_or(WireError::Missing(key))
    }

    /// The fields of a line of the kind that starts with `kind` (`"id "`, `"diag "`, …).
    ///
    /// # Errors
    /// [`WireError::Kind`] for a line of another kind.
    pub fn after(line: &'a str, kind: &str) -> Result<Self, WireError> {
        line.strip_prefix(kind)
            .map(Fields::new)
            .ok_or(WireError::Kind)
    }

    /// The value of the next field if it is `key` (an optional field), else `None` (and the
    /// field stays next).
    pub fn optional(&mut self, key: &'static str) -> Option<&'a str> {
        let mut ahead = self.words.clone();
        let v = ahead.next()?.strip_prefix(key)?.strip_prefix('=')?;
        self.words = ahead;
        Some(v)
    }

    /// The next field `key` as a decimal number in `lo ..= hi`.
    ///
    /// # Errors
    /// Missing, or not a finite decimal number in range.
    pub fn decimal(&mut self, key: &'static str, lo: f32, hi: f32) -> Result<f32, WireError> {
        let v = self.raw(key)?;
        decimal(key, v, lo, hi)
    }

    /// The next field `key` as `-` (`None`) or a decimal number in `lo ..= hi`.
    ///
    /// # Errors
    /// Missing, or neither `-` nor a finite decimal number in range.
    pub fn opt_decimal(
        &mut self,
        key: &'static str,
        lo: f32,
        hi: f32,
    ) -> Result<Option<f32>, WireError> {
        match self.raw(key)? {
            "-" => Ok(None),
            v => decimal(key, v, lo, hi).map(Some),
        }
    }

    /// The next field `key` as an unsigned integer.
    ///
    /// # Errors
    /// Missing, or not a whole number of this type.
    pub fn int<T: core::str::FromStr>(&mut self, key: &'static str) -> Result<T, WireError> {
        let v = self.raw(key)?;
        if !v.bytes().all(|b| b.is_ascii_digit()) {
            return Err(WireError::Bad(key));
        }
        v.parse().map_err(|_| WireError::Bad(key))
    }

    /// The next field `key` as a name ([`Token`]).
    ///
    /// # Errors
    /// Missing, or not a known name.
    pub fn token<T: Token>(&mut self, key: &'static str) -> Result<T, WireError> {
        T::from_token(self.raw(key)?).ok_or(WireError::Bad(key))
    }

    /// The next field `key`, read by `read`.
    ///
    /// # Errors
    /// Missing, or `read` gives `None`.
    pub fn with<T>(
        &mut self,
        key: &'static str,
        read: impl FnOnce(&str) -> Option<T>,
    ) -> Result<T, WireError> {
        read(self.raw(key)?).ok_or(WireError::Bad(key))
    }

    /// Checks that nothing follows.
    ///
    /// # Errors
    /// [`WireError::Trailing`].
    pub fn end(mut self) -> Result<(), WireError> {
        match self.words.next() {
            None => Ok(()),
            Some(_) => Err(WireError::Trailing),
        }
    }
}

/// `v` as a decimal number in `lo ..= hi` (the field `key`'s).
///
/// # Errors
/// [`WireError::Bad`].
pub fn decimal(key: &'static str, v: &str, lo: f32, hi: f32) -> Result<f32, WireError> {
    parse_decimal(v)
        .filter(|x| (lo..=hi).contains(x))
        .ok_or(WireError::Bad(key))
}

/// `a..b` as two decimal numbers in `lo ..= hi`, `a ≤ b` (a band or a window).
///
/// # Errors
/// [`WireError::Bad`].
pub fn range(key: &'static str, v: &str, lo: f32, hi: f32) -> Result<[f32; 2], WireError> {
    let (a, b) = v.split_once("..").ok_or(WireError::Bad(key))?;
    let (a, b) = (decimal(key, a, lo, hi)?, decimal(key, b, lo, hi)?);
    if a > b {
        return Err(WireError::Bad(key));
    }
    Ok([a, b])
}

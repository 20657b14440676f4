//! Decimal numbers as the console writes and reads them: [`Decimal`] prints an `f32` with a
//! fixed number of decimals through integer formatting and [`parse_decimal`] reads a plain
//! decimal number; [`Exact`] and [`parse_exact`] carry an `f64` bit for bit (the rig model and
//! calibration, which the board and the desktop must hold identically). All avoid `core`'s
//! float formatting and parsing machinery, tens of KiB of flash on the MCU.

use core::fmt;

/// An `f32` shown with `decimals` (0..=6) decimals, rounded half away from zero. NaN prints
/// `nan`, infinities `inf`/`-inf`, and magnitudes ≥ 1e12 `big`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decimal(pub f32, pub u8);

impl fmt::Display for Decimal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Decimal(x, decimals) = *self;
        if x.is_nan() {
            return f.write_str("nan");
        }
        if x.is_infinite() {
            return f.write_str(if x > 0.0 { "inf" } else { "-inf" });
        }
        let d = decimals.min(6);
        let scale = 10u64.pow(u32::from(d));
        let mag = f64::from(x).abs();
        if mag >= 1e12 {
            return f.write_str("big");
        }
        let v = libm::round(mag * scale as f64) as u64;
        if x < 0.0 && v != 0 {
            f.write_str("-")?;
        }
        write!(f, "{}", v / scale)?;
        if d > 0 {
            write!(f, ".{:0width$}", v % scale, width = usize::from(d))?;
        }
        Ok(())
    }
}

/// Parses `[+-]digits[.digits]` (at most 9 significant digits) into an `f32`, correctly
/// rounded for up to 7 significant digits. `None` for anything else (exponents, `nan`, `inf`,
/// empty).
pub fn parse_decimal(s: &str) -> Option<f32> {
    let (neg, body) = match s.as_bytes().first()? {
        b'-' => (true, s.get(1..)?),
        b'+' => (false, s.get(1..)?),
        _ => (false, s),
    };
    let (int, frac) = match body.split_once('.') {
        Some((i, f)) => (i, f),
        None => (body, ""),
    };
    if int.is_empty() && frac.is_empty() {
        return None;
    }
    let mut mantissa: u64 = 0;
    let mut digits = 0u32;
    for b in int.bytes().chain(frac.bytes()) {
        if !b.is_ascii_digit() {
            return None;
        }
        if mantissa == 0 && b == b'0' {
            continue; // leading zeros are not significant
        }
        digits += 1;
        if digits > 9 {
            return None;
        }
        mantissa = mantissa * 10 + u64::from(b - b'0');
    }
    let frac_digits = u32::try_from(frac.len()).ok()?;
    if frac_digits > 18 {
        return None;
    }
    let v = mantissa as f64 / libm::pow(10.0, f64::from(frac_digits));
    let v = v as f32;
    Some(if neg { -v } else { v })
}

/// Most significant digits [`Exact`] writes and [`parse_exact`] reads as a decimal: up to 15, any
/// decimal is read correctly rounded by one exact division or product (the mantissa below 2⁵³,
/// the power of ten exact below 10²³: Clinger's fast path).
pub const EXACT_DIGITS: u32 = 15;
/// Most decimals (or trailing zeros) in such a decimal.
const EXACT_POW10: i32 = 22;

/// `10^k` for `0 ≤ k ≤ 22`, each exact in `f64`.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// `10^k`, exact for `0 ≤ k ≤ 22` (1 beyond: the callers stay within).
fn pow10(k: i32) -> f64 {
    usize::try_from(k)
        .ok()
        .and_then(|k| POW10.get(k))
        .copied()
        .unwrap_or(1.0)
}

/// `mantissa · 10^exp10`, correctly rounded (`mantissa < 2⁵³`, `|exp10| ≤ 22`: both factors are
/// exact, so one IEEE operation rounds once).
fn scaled(mantissa: u64, exp10: i32) -> f64 {
    let m = mantissa as f64;
    if exp10 >= 0 {
        m * pow10(exp10)
    } else {
        m / pow10(-exp10)
    }
}

/// A number written so that [`parse_exact`] reads back the same bits: the shortest plain
/// decimal of at most [`EXACT_DIGITS`] significant digits that does (`0.298`, `5500000`,
/// `-0.0075`), or, for a value no such decimal gives (17 digits, below 10⁻²², NaN), its bits as
/// `0x` and 16 hex digits (`0x3fd3126e978d4fe0`, the `f64`'s). [`Exact::f32`]: an `f32`, read
/// back as `parse_exact(s) as f32` (the way a TOML file's value reaches an `f32` field).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exact {
    value: f64,
    single: bool,
}

impl Exact {
    /// An `f64`.
    pub const fn f64(value: f64) -> Exact {
        Exact {
            value,
            single: false,
        }
    }

    /// An `f32` (written widened; read back through `f64` and `as f32`).
    pub fn f32(value: f32) -> Exact {
        Exact {
            value: f64::from(value),
            single: true,
        }
    }

    /// Whether `v`, read back, is this number.
    fn reads_back(&self, v: f64) -> bool {
        if self.single {
            (v as f32).to_bits() == (self.value.abs() as f32).to_bits()
        } else {
            v == self.value.abs()
        }
    }

    /// The digits and power of ten of the shortest round-tripping decimal of `|x|`, if any.
    #[inline(never)] // cold (console replies), and large inlined
    fn decimal(&self) -> Option<(u64, i32)> {
        let mag = self.value.abs();
        if mag == 0.0 {
            return Some((0, 0));
        }
        if !mag.is_finite() {
            return None;
        }
        // The decimal exponent of the leading digit (off by one at most: both neighbours tried).
        let lead = libm::floor(libm::log10(mag)) as i32;
        for digits in 1..=EXACT_DIGITS as i32 {
            let exp10 = lead + 1 - digits;
            for e in [exp10, exp10 + 1, exp10 - 1] {
                if !(-EXACT_POW10..=EXACT_POW10).contains(&e) {
                    continue;
                }
                let m = libm::round(if e >= 0 {
                    mag / pow10(e)
                } else {
                    mag * pow10(-e)
                });
                if !(0.0..1e15).contains(&m) {
                    continue;
                }
                let m = m as u64;
                if self.reads_back(scaled(m, e)) {
                    return Some((m, e));
                }
            }
        }
        None
    }
}

impl fmt::Display for Exact {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.value;
        let Some((mut m, mut e)) = self.decimal() else {
            return write!(f, "0x{:016x}", x.to_bits());
        };
        // Trailing zeros of the mantissa go into the exponent.
        while m != 0 && m % 10 == 0 {
            m /= 10;
            e += 1;
        }
        // The digits of `m`, most significant first.
        let mut digits = [0u8; 16];
        let mut n = 0;
        loop {
            digits[n] = b'0' + (m % 10) as u8;
            m /= 10;
            n += 1;
            if m == 0 {
                break;
            }
        }
        digits[..n].reverse();
        // Written into one buffer: sign, integer part, point, fraction (at most 1 + 15 + 22
        // zeros + 1 + 22 bytes).
        let mut out = [0u8; 64];
        let mut len = 0;
        let mut put = |b: u8| {
            if let Some(slot) = out.get_mut(len) {
                *slot = b;
                len += 1;
            }
        };
        if x.is_sign_negative() && digits[..n] != [b'0'] {
            put(b'-');
        }
        let n = n as i32;
        if e >= 0 {
            digits[..n as usize].iter().for_each(|&d| put(d));
            (0..e).for_each(|_| put(b'0'));
        } else {
            // `n + e` digits before the point (none: a leading `0.` and zeros).
            let int = n + e;
            if int <= 0 {
                put(b'0');
                put(b'.');
                (0..-int).for_each(|_| put(b'0'));
                digits[..n as usize].iter().for_each(|&d| put(d));
            } else {
                digits[..int as usize].iter().for_each(|&d| put(d));
                put(b'.');
                digits[int as usize..n as usize]
                    .iter()
                    .for_each(|&d| put(d));
            }
        }
        // ASCII digits, sign and point only.
        f.write_str(core::str::from_utf8(&out[..len]).map_err(|_| fmt::Error)?)
    }
}

/// Reads what [`Exact`] writes: a plain decimal (`[+-]digits[.digits]`, at most
/// [`EXACT_DIGITS`] significant digits and 22 decimals), correctly rounded to `f64` (the same
/// bits as Rust's `str::parse` and a TOML file's value), or `0x` with 16 hex digits (the bits).
/// `None` for anything else (exponents, `nan`, `inf`, more digits, empty). The bits form takes
/// any value, NaN included: the caller validates.
pub fn parse_exact(s: &str) -> Option<f64> {
    if let Some(hex) = s.strip_prefix("0x") {
        if hex.len() != 16 {
            return None;
        }
        return u64::from_str_radix(hex, 16).ok().map(f64::from_bits);
    }
    let (neg, body) = match s.as_bytes().first()? {
        b'-' => (true, s.get(1..)?),
        b'+' => (false, s.get(1..)?),
        _ => (false, s),
    };
    let (int, frac) = body.split_once('.').unwrap_or((body, ""));
    if int.is_empty() && frac.is_empty() {
        return None;
    }
    let mut mantissa: u64 = 0;
    let mut digits = 0u32;
    // Trailing zeros of the integer part past the significant digits scale up instead.
    let mut zeros = 0i32;
    for (i, b) in int.bytes().chain(frac.bytes()).enumerate() {
        if !b.is_ascii_digit() {
            return None;
        }
        let in_int = i < int.len();
        if mantissa == 0 && b == b'0' {
            continue;
        }
        if digits == EXACT_DIGITS && b == b'0' && in_int {
            zeros += 1;
            continue;
        }
        digits += 1;
        if digits > EXACT_DIGITS {
            return None;
        }
        mantissa = mantissa * 10 + u64::from(b - b'0');
    }
    let frac_len = i32::try_from(frac.len()).ok()?;
    if frac_len > EXACT_POW10 || (zeros > 0 && frac.bytes().any(|b| b != b'0')) {
        return None;
    }
    let exp10 = if zeros > 0 { zeros } else { -frac_len };
    if exp10 > EXACT_POW10 {
        return None;
    }
    let v = scaled(mantissa, exp10);
    Some(if neg { -v } else { v })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::format;

    #[test]
    fn fixed_matches_core_formatting() {
        for (x, d) in [
            (3.6404f32, 4u8),
            (0.89, 3),
            (95.854, 1),
            (32.788, 2),
            (0.0, 0),
            (-7.25, 3),
        ] {
            assert_eq!(
                format!("{}", Decimal(x, d)),
                format!("{:.*}", usize::from(d), f64::from(x)),
                "{x} {d}"
            );
        }
        assert_eq!(format!("{}", Decimal(f32::NAN, 2)), "nan");
        assert_eq!(format!("{}", Decimal(-f32::INFINITY, 2)), "-inf");
        // Half away from zero (core rounds half to even: "12"), and no negative zero.
        assert_eq!(format!("{}", Decimal(12.5, 0)), "13");
        assert_eq!(format!("{}", Decimal(-0.001, 2)), "0.00");
    }

    #[test]
    fn parse_decimal_agrees_with_core() {
        for s in [
            "3.66", "0.3", "10", "+2.5", "-1", ".5", "5.", "0.000001", "3659.123", "007.25",
        ] {
            assert_eq!(parse_decimal(s), s.parse::<f32>().ok(), "{s}");
        }
        for s in [
            "",
            ".",
            "-",
            "1e3",
            "nan",
            "inf",
            "1.2.3",
            "3,5",
            "1234567890",
            " 1",
        ] {
            assert_eq!(parse_decimal(s), None, "{s}");
        }
    }

    #[test]
    fn exact_round_trips_and_reads_as_rust_does() {
        let values = [
            0.298,
            5.38,
            0.89e-3,
            9.81,
            0.075,
            5.5e6,
            1.2e3,
            2.1e8,
            1.6,
            0.317,
            0.004,
            0.0,
            -0.0075,
            1e15,
            123_456_789_012_345.0,
            0.1 + 0.2,
            1.0 / 3.0,
            5_462_345.123_456_789,
            1e-25,
            f64::MAX,
            f64::MIN_POSITIVE,
        ];
        for x in values {
            let text = format!("{}", Exact::f64(x));
            let back = parse_exact(&text).unwrap_or_else(|| panic!("{text}"));
            assert_eq!(back.to_bits(), x.to_bits(), "{x} → {text}");
            // A decimal reads as Rust reads it (and so as a TOML file's value).
            if !text.starts_with("0x") {
                assert_eq!(
                    text.parse::<f64>().unwrap().to_bits(),
                    x.to_bits(),
                    "{text}"
                );
            }
        }
        // Short values stay short; values without a 15-digit decimal go as bits.
        assert_eq!(format!("{}", Exact::f64(0.298)), "0.298");
        assert_eq!(format!("{}", Exact::f64(5.5e6)), "5500000");
        assert_eq!(format!("{}", Exact::f64(0.89e-3)), "0.00089");
        assert_eq!(format!("{}", Exact::f64(-0.0075)), "-0.0075");
        // An f32 is written as its own shortest decimal, negative ones too.
        assert_eq!(format!("{}", Exact::f32(-0.0075)), "-0.0075");
        assert_eq!(format!("{}", Exact::f32(0.298)), "0.298");
        for x in [-0.0038748f32, -1.5e-7, -310.0, -1234.5678] {
            let text = format!("{}", Exact::f32(x));
            assert!(!text.starts_with("0x"), "{text}");
            assert_eq!(
                (parse_exact(&text).unwrap() as f32).to_bits(),
                x.to_bits(),
                "{text}"
            );
        }
        assert_eq!(format!("{}", Exact::f64(0.1 + 0.2)), "0x3fd3333333333334");
        // What an operator types reads as Rust reads it.
        for s in [
            "0.31",
            "12",
            "0.0098",
            "4.5",
            "1e3x",
            "0.000000000000000000001",
        ] {
            assert_eq!(parse_exact(s), s.parse::<f64>().ok(), "{s}");
        }
        for s in [
            "",
            "-",
            "1e3",
            "nan",
            "inf",
            "0x12",
            "1234567890123456",
            "1.2.3",
        ] {
            assert_eq!(parse_exact(s), None, "{s}");
        }
        // An `f32` as short as it reads back as an `f32`: a TOML value's path.
        for x in [
            0.0098f32,
            0.2,
            3.3,
            280.0,
            1.0e-5,
            0.1 + 0.2,
            1.0 / 3.0,
            f32::MAX,
        ] {
            let text = format!("{}", Exact::f32(x));
            let back = parse_exact(&text).unwrap() as f32;
            assert_eq!(back.to_bits(), x.to_bits(), "{x} → {text}");
            if !text.starts_with("0x") {
                assert_eq!(text.parse::<f64>().unwrap() as f32, x, "{text}");
            }
        }
        assert_eq!(format!("{}", Exact::f32(0.0098)), "0.0098");
    }
}

//! Decimal numbers as the console writes and reads them: [`Decimal`] prints an `f32` with a
//! fixed number of decimals through integer formatting and [`parse_decimal`] reads a plain
//! decimal number (both avoid `core`'s float formatting and parsing machinery, tens of KiB of
//! flash on the MCU).

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
}

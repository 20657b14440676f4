//! Typed errors of the `shared` crate. No function of this crate panics on bad input:
//! it returns one of these, naming the field and the allowed range.

use core::fmt;

/// A parameter failed validation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParamError {
    /// The value is NaN or infinite.
    NotFinite {
        /// Field name as it appears in the parameter structs / TOML (`mass_kg`, ...).
        field: &'static str,
    },
    /// The value lies outside `[min, max]` (bounds in the field's own unit).
    OutOfRange {
        /// Field name.
        field: &'static str,
        /// Offending value.
        value: f64,
        /// Smallest allowed value.
        min: f64,
        /// Largest allowed value.
        max: f64,
    },
    /// The value lies outside the half-open `[min, max)` (bounds in the field's own unit).
    OutOfHalfOpenRange {
        /// Field name.
        field: &'static str,
        /// Offending value.
        value: f64,
        /// Smallest allowed value.
        min: f64,
        /// The bound the value must stay below.
        max: f64,
    },
    /// An integer setting outside `[min, max]`.
    CountOutOfRange {
        /// Field name.
        field: &'static str,
        /// Offending value.
        value: u32,
        /// Smallest allowed value.
        min: u32,
        /// Largest allowed value.
        max: u32,
    },
    /// A sweep/range given with `lo > hi`, a non-positive step, or too many points.
    BadRange {
        /// Field name.
        field: &'static str,
        /// What is wrong with it.
        reason: &'static str,
    },
}

impl ParamError {
    /// The field it names.
    pub fn field(&self) -> &'static str {
        match self {
            ParamError::NotFinite { field }
            | ParamError::OutOfRange { field, .. }
            | ParamError::OutOfHalfOpenRange { field, .. }
            | ParamError::CountOutOfRange { field, .. }
            | ParamError::BadRange { field, .. } => field,
        }
    }
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ParamError::NotFinite { field } => {
                write!(f, "`{field}` must be a finite number (got NaN or infinity)")
            }
            ParamError::OutOfRange {
                field,
                value,
                min,
                max,
            } => out_of_range(f, field, &Value(value), &Bound::min(min), &Bound::max(max)),
            ParamError::OutOfHalfOpenRange {
                field,
                value,
                min,
                max,
            } => write!(
                f,
                "`{field}` = {} is out of range: allowed {} ≤ {field} < {}",
                Value(value),
                Bound::min(min),
                Bound::max(max)
            ),
            ParamError::CountOutOfRange {
                field,
                value,
                min,
                max,
            } => out_of_range(f, field, &value, &min, &max),
            ParamError::BadRange { field, reason } => write!(f, "`{field}`: {reason}"),
        }
    }
}

impl core::error::Error for ParamError {}

/// The text of an out-of-range value (floats and counts alike).
fn out_of_range(
    f: &mut fmt::Formatter<'_>,
    field: &str,
    value: &dyn fmt::Display,
    min: &dyn fmt::Display,
    max: &dyn fmt::Display,
) -> fmt::Result {
    write!(
        f,
        "`{field}` = {value} is out of range: allowed {min} ..= {max}"
    )
}

/// An offending value as typed: in full (the shortest digits that give it back), or in
/// e-notation where that would run past 16 digits (`1e300`, `1e-300`, not 301 digits).
struct Value(f64);

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = libm::fabs(self.0);
        if a == 0.0 || (1e-6..1e16).contains(&a) {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

/// A bound of an allowed range as a reader takes it: as it is when 8 significant digits hold
/// it, else to 6 significant digits rounded into the range (a smallest value up, a largest
/// down: `91.01102550109582` shows as `91.011`), so that the number shown is allowed too.
struct Bound {
    value: f64,
    /// Whether this is the smallest allowed value (rounded up), else the largest (down).
    up: bool,
}

impl Bound {
    fn min(value: f64) -> Self {
        Bound { value, up: true }
    }
    fn max(value: f64) -> Self {
        Bound { value, up: false }
    }
}

impl fmt::Display for Bound {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.value;
        if !v.is_finite() || v == 0.0 {
            return write!(f, "{v}");
        }
        let exp = libm::floor(libm::log10(libm::fabs(v)));
        let at = |digits: f64, round: fn(f64) -> f64| {
            let scale = libm::pow(10.0, digits - 1.0 - exp);
            round(v * scale) / scale
        };
        if at(8.0, libm::round) == v {
            return write!(f, "{v}");
        }
        let shown = at(6.0, if self.up { libm::ceil } else { libm::floor });
        // (A subnormal bound's scale overflows: shown as it is.)
        write!(f, "{}", if shown.is_finite() { shown } else { v })
    }
}

/// Checks that `value` is finite and in `[min, max]`.
///
/// # Errors
/// [`ParamError::NotFinite`] or [`ParamError::OutOfRange`] naming `field`.
pub fn check_range(field: &'static str, value: f64, min: f64, max: f64) -> Result<f64, ParamError> {
    if !value.is_finite() {
        return Err(ParamError::NotFinite { field });
    }
    if value < min || value > max {
        return Err(ParamError::OutOfRange {
            field,
            value,
            min,
            max,
        });
    }
    Ok(value)
}

/// Checks that `value` is finite and in the half-open `[min, max)`.
///
/// # Errors
/// [`ParamError::NotFinite`] or [`ParamError::OutOfHalfOpenRange`] naming `field`.
pub fn check_half_open(
    field: &'static str,
    value: f64,
    min: f64,
    max: f64,
) -> Result<f64, ParamError> {
    if !value.is_finite() {
        return Err(ParamError::NotFinite { field });
    }
    if value < min || value >= max {
        return Err(ParamError::OutOfHalfOpenRange {
            field,
            value,
            min,
            max,
        });
    }
    Ok(value)
}

/// Checks an integer setting against `[min, max]`.
///
/// # Errors
/// [`ParamError::CountOutOfRange`] naming `field`.
pub fn check_count(field: &'static str, value: u32, min: u32, max: u32) -> Result<u32, ParamError> {
    if value < min || value > max {
        return Err(ParamError::CountOutOfRange {
            field,
            value,
            min,
            max,
        });
    }
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

    #[test]
    fn a_range_shows_its_bounds_as_a_reader_takes_them() {
        // A range worked out from the rig (Ω/ω 0.01–10 at f_n = 9.1011 Hz): six significant
        // digits, rounded into it.
        let e = ParamError::OutOfRange {
            field: "freq_hz",
            value: 1e9,
            min: 0.09101102550109583,
            max: 91.01102550109582,
        };
        assert_eq!(
            e.to_string(),
            "`freq_hz` = 1000000000 is out of range: allowed 0.0910111 ..= 91.011"
        );
        // Short bounds as they are, negative ones rounded into the range too.
        for (min, max, shown) in [
            (0.0, 18.75, "0 ..= 18.75"),
            (1e-6, 0.05, "0.000001 ..= 0.05"),
            (-core::f64::consts::PI, 1.2345678, "-3.14159 ..= 1.2345678"),
            (0.1, 12345678.0, "0.1 ..= 12345678"),
        ] {
            let e = ParamError::OutOfRange {
                field: "x",
                value: f64::MAX,
                min,
                max,
            };
            let text = e.to_string();
            assert!(text.ends_with(shown), "{text}");
        }
        // An offending value as typed, in e-notation only where it would be long.
        for (value, shown) in [
            (1e300, "`x` = 1e300 is"),
            (-2.5e-300, "`x` = -2.5e-300 is"),
            (1e9, "`x` = 1000000000 is"),
            (-0.000032, "`x` = -0.000032 is"),
            (1.5e16, "`x` = 1.5e16 is"),
        ] {
            for e in [
                check_range("x", value, 0.0, 1.0),
                check_half_open("x", value, 0.0, 1.0),
            ] {
                let e = e.expect_err("out of range");
                assert!(e.to_string().starts_with(shown), "{e}");
            }
        }
        // The bounds shown lie in the range.
        let pi = core::f64::consts::PI;
        for k in -12..12 {
            let (min, max) = (pi * 10f64.powi(k), core::f64::consts::E * 10f64.powi(k + 1));
            let e = ParamError::OutOfHalfOpenRange {
                field: "x",
                value: -1.0,
                min,
                max,
            };
            let text = e.to_string();
            let (lo, hi) = text
                .rsplit_once("allowed ")
                .and_then(|(_, r)| r.split_once(" ≤ x < "))
                .expect("both bounds");
            let (lo, hi): (f64, f64) = (lo.parse().expect("lo"), hi.parse().expect("hi"));
            assert!(lo >= min && lo <= min * (1.0 + 1e-5), "{text}");
            assert!(hi <= max && hi >= max * (1.0 - 1e-5), "{text}");
        }
    }
}

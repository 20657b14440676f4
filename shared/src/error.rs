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
            } => out_of_range(f, field, &value, &min, &max),
            ParamError::OutOfHalfOpenRange {
                field,
                value,
                min,
                max,
            } => write!(
                f,
                "`{field}` = {value} is out of range: allowed {min} ≤ {field} < {max}"
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

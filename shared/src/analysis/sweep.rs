//! An inclusive, evenly spaced sweep `lo:hi:step` whose points are `lo + i·step` from an integer
//! index (no accumulated rounding).

use serde::{Deserialize, Serialize};

use crate::error::ParamError;

/// Largest number of points in one sweep.
pub const MAX_SWEEP_POINTS: u32 = 10_000_000;

/// `lo, lo + step, …, ≤ hi` (the last point within `1e-9·step` of `hi` counts). Read from a
/// file it is validated as [`Sweep::new`] does.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SweepFields")]
pub struct Sweep {
    /// First value.
    pub lo: f64,
    /// Last value (inclusive).
    pub hi: f64,
    /// Spacing, > 0.
    pub step: f64,
}

/// A sweep as a file states it, before [`Sweep::new`]'s checks.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepFields {
    lo: f64,
    hi: f64,
    step: f64,
}

impl TryFrom<SweepFields> for Sweep {
    type Error = ParamError;
    fn try_from(f: SweepFields) -> Result<Self, ParamError> {
        Sweep::new("sweep", f.lo, f.hi, f.step)
    }
}

impl Sweep {
    /// A validated sweep.
    ///
    /// # Errors
    /// [`ParamError::NotFinite`] for NaN/inf, [`ParamError::BadRange`] for `lo > hi`,
    /// `step ≤ 0` or more than [`MAX_SWEEP_POINTS`] points; `field` names the sweep.
    pub fn new(field: &'static str, lo: f64, hi: f64, step: f64) -> Result<Self, ParamError> {
        if !(lo.is_finite() && hi.is_finite() && step.is_finite()) {
            return Err(ParamError::NotFinite { field });
        }
        if lo > hi {
            return Err(ParamError::BadRange {
                field,
                reason: "empty range: the start is above the end (write lo:hi:step with lo ≤ hi)",
            });
        }
        if step <= 0.0 {
            return Err(ParamError::BadRange {
                field,
                reason: "the step must be > 0",
            });
        }
        let s = Sweep { lo, hi, step };
        if (hi - lo) / step >= f64::from(MAX_SWEEP_POINTS) {
            return Err(ParamError::BadRange {
                field,
                reason: "too many points (at most 10,000,000)",
            });
        }
        Ok(s)
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        // `as` saturates (a sweep not made by `new` cannot overflow the count).
        (libm::floor((self.hi - self.lo) / self.step + 1e-9) as usize).saturating_add(1)
    }

    /// Never empty (a valid sweep has at least `lo`).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The `i`-th value.
    pub fn value(&self, i: usize) -> f64 {
        self.lo + i as f64 * self.step
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sweep read from a file goes through `new`'s checks; one built by hand with a zero
    /// step counts `usize::MAX` points instead of overflowing.
    #[test]
    fn a_read_sweep_is_checked_and_a_hand_made_one_cannot_overflow() {
        let read = |lo, hi, step| Sweep::try_from(SweepFields { lo, hi, step });
        assert_eq!(read(0.5, 5.0, 0.5).map(|s| s.len()), Ok(10));
        assert!(read(0.5, 5.0, 0.0).is_err());
        assert!(read(f64::NAN, 5.0, 0.1).is_err());
        assert!(read(5.0, 0.5, 0.1).is_err());
        let zero_step = Sweep {
            lo: 0.5,
            hi: 5.0,
            step: 0.0,
        };
        assert_eq!(zero_step.len(), usize::MAX);
    }

    #[test]
    fn counts_inclusive_points() {
        let s = Sweep::new("omega_ratio", 0.5, 5.0, 0.02).unwrap();
        assert_eq!(s.len(), 226);
        assert!((s.value(225) - 5.0).abs() < 1e-12);
        // The thesis' grids: 343 gaps 0.00–3.42 mm, 612 frequencies 1.00–7.11 Hz.
        assert_eq!(Sweep::new("gap", 0.0, 3.42, 0.01).unwrap().len(), 343);
        assert_eq!(Sweep::new("freq", 1.0, 7.11, 0.01).unwrap().len(), 612);
        assert_eq!(Sweep::new("x", 1.0, 1.0, 0.1).unwrap().len(), 1);
        assert!(Sweep::new("x", 2.0, 1.0, 0.1).is_err());
        assert!(Sweep::new("x", 1.0, 2.0, 0.0).is_err());
        assert!(Sweep::new("x", f64::NAN, 2.0, 0.1).is_err());
    }
}

//! Recurrence on the stroboscopic map against a catalogue of known attractors (the method of
//! Datseris & Wagemakers, "Effortless estimation of basins of attraction", Chaos 32, 023104,
//! 2022, on the Poincaré section of docs/model.md): a trajectory whose Poincaré points fall,
//! `confirm` periods in a row, within `tol` of the points of one catalogued attractor is
//! assigned to it and its run can stop ([`Observer::stop`]); a trajectory that reaches no
//! known attractor runs the whole canonical protocol, whose steady-state test (the section
//! repeating with a period `q`) is its own recurrence, and the caller catalogues what it found.
//!
//! Distances are the protocol's scaled distance `max(|Δu|/A0, |Δu̇|/(A0 Ω))`
//! ([`StroboPoint::distance`]). The catalogue is the caller's ([`AttractorCatalogue`]): on the
//! host, one shared by every thread of a run.

use serde::{Deserialize, Serialize};

use super::poincare::StroboPoint;
use super::protocol::Observer;
use crate::error::{ParamError, check_count, check_range};
use crate::real::Real;

/// Known attractors, looked up by Poincaré point.
pub trait AttractorCatalogue {
    /// The id of a catalogued attractor with a Poincaré point within the scaled distance `tol`
    /// of `(u, u̇)` (`u` in m, `u̇` in m/s), if any.
    fn lookup(&self, u_m: f64, du_m_s: f64, tol: f64) -> Option<u32>;
}

impl<C: AttractorCatalogue + ?Sized> AttractorCatalogue for &C {
    fn lookup(&self, u_m: f64, du_m_s: f64, tol: f64) -> Option<u32> {
        (**self).lookup(u_m, du_m_s, tol)
    }
}

/// How a trajectory is matched to the catalogue.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RecurrenceSettings {
    /// Scaled distance within which a Poincaré point belongs to a known attractor
    /// (`1e-9 ..= 1`).
    pub tol: f64,
    /// Consecutive periods within `tol` of one attractor's points that assign the trajectory
    /// to it (`1 ..= 10000`).
    pub confirm: u32,
}

impl Default for RecurrenceSettings {
    /// `tol` 1e-2 (9 µm and 0.1 mm/s on the wire rig at Ω/ω = 2), `confirm` 16.
    fn default() -> Self {
        RecurrenceSettings {
            tol: 1e-2,
            confirm: 16,
        }
    }
}

impl RecurrenceSettings {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`ParamError`] naming `tol` (`1e-9 ..= 1`) or `confirm` (`1 ..= 10000`).
    pub fn validate(&self) -> Result<(), ParamError> {
        check_range("tol", self.tol, 1e-9, 1.0)?;
        check_count("confirm", self.confirm, 1, 10_000)?;
        Ok(())
    }
}

/// An [`Observer`] that watches the Poincaré points of a run for a known attractor and stops
/// the run once the trajectory has stayed on one for `confirm` periods. `C` is the catalogue or
/// a view of it (a reference, or a filter such as "found by an earlier initial condition").
#[derive(Debug, Clone, Copy)]
pub struct RecurrenceWatch<C> {
    catalogue: C,
    settings: RecurrenceSettings,
    current: Option<u32>,
    hits: u32,
    assigned: Option<u32>,
}

impl<C: AttractorCatalogue> RecurrenceWatch<C> {
    /// A watch against `catalogue`. `settings` must be valid ([`RecurrenceSettings::validate`]).
    pub fn new(catalogue: C, settings: RecurrenceSettings) -> Self {
        RecurrenceWatch {
            catalogue,
            settings,
            current: None,
            hits: 0,
            assigned: None,
        }
    }

    /// Feeds one Poincaré point (`u` in m, `u̇` in m/s; the catalogue applies the scales).
    /// Returns the attractor the trajectory is assigned to, once it is.
    pub fn feed(&mut self, u_m: f64, du_m_s: f64) -> Option<u32> {
        if self.assigned.is_some() {
            return self.assigned;
        }
        let id = self.catalogue.lookup(u_m, du_m_s, self.settings.tol);
        if id.is_some() && id == self.current {
            self.hits += 1;
        } else {
            self.current = id;
            self.hits = u32::from(id.is_some());
        }
        if self.hits >= self.settings.confirm {
            self.assigned = self.current;
        }
        self.assigned
    }

    /// The attractor the trajectory was assigned to, if any.
    pub fn assigned(&self) -> Option<u32> {
        self.assigned
    }
}

impl<T: Real, C: AttractorCatalogue> Observer<T> for RecurrenceWatch<C> {
    const SAMPLES: bool = false;
    fn strobe(&mut self, p: &StroboPoint<T>, _window: bool) {
        self.feed(p.u.to_f64(), p.du.to_f64());
    }
    fn stop(&self) -> bool {
        self.assigned.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One attractor: the period-2 cycle {(0, 0), (1e-3, 0)} (m, m/s), scales 1e-3 m, 1 m/s.
    struct Two;
    impl AttractorCatalogue for Two {
        fn lookup(&self, u: f64, du: f64, tol: f64) -> Option<u32> {
            [(0.0, 0.0), (1e-3, 0.0)]
                .iter()
                .any(|&(a, b)| ((u - a).abs() / 1e-3).max((du - b).abs()) <= tol)
                .then_some(7)
        }
    }

    #[test]
    fn assigns_after_confirm_consecutive_hits_only() {
        let s = RecurrenceSettings {
            tol: 1e-2,
            confirm: 3,
        };
        let mut w = RecurrenceWatch::new(&Two, s);
        // Two hits, a miss (resets), then three hits on alternating points of the cycle.
        assert_eq!(w.feed(0.0, 0.0), None);
        assert_eq!(w.feed(1e-3, 0.0), None);
        assert_eq!(w.feed(5e-4, 0.0), None);
        assert_eq!(w.feed(0.0, 0.005), None);
        assert_eq!(w.feed(1.005e-3, 0.0), None);
        assert_eq!(w.feed(0.0, 0.0), Some(7));
        assert!(Observer::<f64>::stop(&w));
        // Once assigned, it stays.
        assert_eq!(w.feed(1.0, 1.0), Some(7));
    }

    #[test]
    fn settings_are_checked() {
        assert!(RecurrenceSettings::default().validate().is_ok());
        for bad in [
            RecurrenceSettings {
                tol: 0.0,
                confirm: 3,
            },
            RecurrenceSettings {
                tol: f64::NAN,
                confirm: 3,
            },
            RecurrenceSettings {
                tol: 0.1,
                confirm: 0,
            },
        ] {
            assert!(bad.validate().is_err());
        }
    }
}

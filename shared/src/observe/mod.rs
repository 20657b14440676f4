//! Observables of a simulation: impacts and their peak forces, the stroboscopic Poincaré
//! section, the smallest repeating period, the impact regime `z = p/q`, and the canonical
//! protocol that produces them (docs/model.md, "Observables" and "Canonical protocol").

pub mod impact;
pub mod period;
pub mod poincare;
pub mod protocol;
pub mod recurrence;
pub mod regime;

pub use impact::{DEFAULT_SEPARATION_M, ImpactEvent, ImpactTracker};
pub use poincare::StroboPoint;
pub use protocol::{Observer, PointResult, Protocol, ProtocolRun, run_protocol};
pub use recurrence::{AttractorCatalogue, RecurrenceSettings, RecurrenceWatch};
pub use regime::Regime;

//! Periodic orbits of the stroboscopic map and their stability, on the same simulator the
//! analyses and the MCU run (no second model): the map and its derivative ([`map`]: dual
//! numbers through the simulator), Floquet multipliers and bifurcation test functions
//! ([`floquet`]), shooting ([`shooting`]), pseudo-arclength continuation with located
//! bifurcations ([`continuation`]), the largest Lyapunov exponent ([`lyapunov`]) and what it
//! adds to a regime label ([`mod@label`]).

pub mod continuation;
pub mod curve;
pub mod edges;
pub mod floquet;
pub mod label;
pub mod lyapunov;
pub mod map;
pub mod shooting;
pub mod start;

pub use continuation::{
    BifEvent, BranchEnd, BranchPoint, ContinuationSettings, EventKind, MIN_TURN_COSINE,
    SignChanges, StepSizes, continue_branch, doubling_start,
};
pub use curve::{CurveEnd, CurvePoint, CurveSettings, continue_curve};
pub use edges::{Edge, band_edges};
pub use floquet::{Floquet, Multiplier};
pub use label::{Label, LabelSettings, label};
pub use lyapunov::{
    Exponent, exponent_along_with, largest_exponent, largest_exponent_with, orbit_exponent,
};
pub use map::{Image, MAX_Q, MapPoint, Param, Trace, iterate, samples, tangent};
pub use shooting::{Orbit, OrbitError, ShootSettings, Stability, shoot};
pub use start::{minimal_period, orbit_from, relative, settle, state_of};

//! The switch-model integrator: fixed-step RK4 with an integer number of steps per excitation
//! period and deterministic sub-steps in and near contact.
//!
//! - [`rk4`]: one classical Runge–Kutta step on a 2-state vector.
//! - `dense`: the step's cubic Hermite dense output, event location on it, minima between samples.
//! - [`stepper`]: the period-locked driver ([`Simulator`]).
//! - [`lanes`]: whole free-flight steps of several simulators in lockstep (host grids).

pub(crate) mod dense;
pub mod lanes;
pub mod rk4;
pub mod stepper;

pub use stepper::{Simulator, StepSample, StepSettings};

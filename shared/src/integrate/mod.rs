//! The switch-model integrator: fixed-step RK4 with an integer number of steps per excitation
//! period and deterministic sub-steps in and near contact.
//!
//! - [`rk4`]: one classical Runge–Kutta step on a 2-state vector.
//! - [`stepper`]: the period-locked driver ([`Simulator`]).
//! - [`lanes`]: whole free-flight steps of several simulators in lockstep (host grids).

pub mod lanes;
pub mod rk4;
pub mod stepper;

pub use stepper::{Simulator, StepSample, StepSettings};

//! The switch-model integrator: fixed-step RK4 with an integer number of steps per excitation
//! period and deterministic sub-steps in and near contact.
//!
//! - [`plan`]: the step settings, the excitation phase on the step grid ([`PhaseTable`],
//!   shared) and one simulator's step lengths ([`StepPlan`]).
//! - [`rk4`]: one classical Runge–Kutta step on a 2-state vector.
//! - `free`: one whole free-flight step and its acceptance test (the stepper's and the lanes'
//!   kernel).
//! - `bracket`: the bracketing root finder; `dense`: the step's cubic Hermite dense output,
//!   event location on it, minima between samples; `near`: where a free-flight trial that
//!   came near the surface is split (on the host its points in vector lanes).
//! - [`stepper`]: the period-locked driver ([`Simulator`]).
//! - `lane_field`: what a suspension's coefficients are to the vector lanes (the lane traits,
//!   below every kind of lane and the near search).
//! - [`lanes`]: whole free-flight steps of several simulators in lockstep (host grids);
//!   `contact_lanes`: their ordinary contact sub-steps, several at once; `switch_lanes`: the
//!   switching events inside those sub-steps, several located at once; `isa`: the vector
//!   instructions those kernels run, chosen at run time ([`kernel_isa`]; on the host
//!   `ISA_VAR` narrows them).

pub(crate) mod bracket;
pub(crate) mod contact_lanes;
pub(crate) mod dense;
pub(crate) mod free;
pub(crate) mod isa;
pub(crate) mod lane_field;
pub mod lanes;
pub(crate) mod near;
pub mod plan;
pub mod rk4;
pub mod stepper;
pub(crate) mod switch_lanes;

pub use isa::kernel_isa;
#[cfg(feature = "std")]
pub use isa::{ISA_VAR, IsaVarError, check_isa_var};
pub use plan::{MAX_STEPS_PER_PERIOD, PhaseTable, StepPlan, StepSettings, resting_substeps};
pub use stepper::{Simulator, StepCounts, StepSample};

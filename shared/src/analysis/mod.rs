//! Analyses built on the protocol: one operating point, frequency responses over a sweep, and
//! the operating-frequency selection; the drop test of the contact-law identification.

pub mod batch;
pub mod drop;
pub mod response;
pub mod selection;
pub mod sweep;

pub use batch::{
    DEFAULT_LANES, LaneStats, Started, WIDE_LANES, evaluate_interleaved,
    evaluate_interleaved_native, lanes_per_core, run_interleaved, run_interleaved_native,
};
pub use response::{
    ResponseSample, SimSettings, evaluate_point, evaluate_point_observed, evaluate_point_on,
    simulator_at,
};
pub use selection::{
    Candidate, Selection, SelectionError, SelectionSpec, perturbed_gaps, robustness_window, select,
    select_sequential,
};
pub use sweep::Sweep;

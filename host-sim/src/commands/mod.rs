//! One module per command: each parses its arguments, calls the library, writes its outputs
//! and prints.

use anyhow::Result;
use shared::analysis::Sweep;
use shared::analysis::response::OMEGA_RATIO_RANGE;

use crate::config::parse_sweep;

pub mod basins;
pub mod bifurcation;
pub mod compare;
pub mod drop;
pub mod hil;
pub mod identify;
pub mod merge;
pub mod peterka;
pub mod points;
pub mod response;
pub mod rig;
pub mod select;
pub mod simulate;

/// Parses `--omega-ratio START:END:STEP` within the analyses' `Ω/ω` range.
///
/// # Errors
/// Malformed or out-of-range sweep (the flag and the range named).
pub fn omega_sweep(text: &str) -> Result<Sweep> {
    parse_sweep(
        "--omega-ratio",
        text,
        OMEGA_RATIO_RANGE.0,
        OMEGA_RATIO_RANGE.1,
    )
}

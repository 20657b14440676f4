//! One module per command.

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

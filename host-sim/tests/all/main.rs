//! host-sim's integration tests but the paced virtual rig's (`tests/rig.rs`, a binary of its
//! own so that no other test takes its cores), one binary (each file a module, one concept per
//! file): host-sim and the physics' generic code are compiled and linked once for all of them.
//!
//! `cargo test -p host-sim --test all identify_cli::` runs one file's tests.

#[path = "../common/mod.rs"]
mod common;
#[path = "../common/coverage.rs"]
mod coverage;

mod attractors;
mod cli;
mod commission;
mod convergence;
mod grid;
mod hil;
mod identify;
mod identify_cli;
mod onboard_identify;
mod rig_hostile;
mod series;
mod slurm;
mod uncertainty;

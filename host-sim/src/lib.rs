//! Desktop side of the vibro-impact hammer project: the analysis commands (`select`,
//! `response`, `simulate`, `points`, `bifurcation`, `peterka`, `basins`, `merge`, `identify`, `drop`, `compare`), their CSV and PNG outputs, and the parallel runner.
//! All physics comes from the `shared` crate, the same code the firmware runs.

pub mod cli;
pub mod client;
pub mod commands;
pub mod comparison;
pub mod config;
pub mod grid;
pub mod identify;
pub mod interrupt;
pub mod maps;
pub mod output;
pub mod plot;
pub mod plot_identify;
pub mod precision;
pub mod propagate;
pub mod response;
pub mod rig;
pub mod runner;
pub mod selection;
pub mod series;
pub mod shard;
pub mod trace;

//! The desktop side of the vibro-impact hammer project. All physics comes from `shared`, the
//! same code the firmware runs; this crate adds what a desktop needs around it.
//!
//! Data flows one way, and every dependency between these modules points down this list (a
//! test, `tests/tests/all/layers.rs`, holds it):
//!
//! 1. rig parameters: [`config`] (presets, `--config` TOML, validation) → a [`config::Setup`];
//!    [`precision`]; [`trace`] (measured traces);
//! 2. the computations over `shared`'s integrator and observers: [`runner`] (the batch size,
//!    parallel interleaved evaluation, progress), [`response`], [`selection`] (the main job),
//!    [`series`] (time series), [`attractors`] (the attractors of many initial conditions, basin
//!    fractions), [`grid`] (Peterka maps, basins, basin fractions, bifurcation; shards in
//!    [`shard`]), [`propagate`] (the selection under parameter uncertainty), [`identify`]
//!    (parameters from drop tests and free decays), [`comparison`] (model against a measured
//!    response or time series), [`orbits`] (periodic orbits, their branches and bifurcations);
//! 3. the rig: [`rig_link`] (the real rig's serial console, from the desktop) and
//!    [`virtual_rig`] (the firmware's controller against a simulated plant through mock
//!    hardware, and its pseudo-terminal);
//! 4. the outputs: CSV through [`output`] (written whole or not at all) and the figures in
//!    [`figures`], which read the results of the layers above and are never read by them;
//! 5. the commands in [`commands`] (parsed by [`cli`]), each with its entry point `run`: parse,
//!    call the library, write, print. [`interrupt`] (Ctrl-C) and [`stats`] (the 95 % quantile,
//!    Wilson's interval) serve every layer.

pub mod attractors;
pub mod cli;
pub mod commands;
pub mod comparison;
pub mod config;
pub mod figures;
pub mod grid;
pub mod identify;
pub mod interrupt;
pub mod orbits;
pub mod output;
pub mod precision;
pub mod progress;
pub mod propagate;
pub mod response;
pub mod rig_link;
pub mod runner;
pub mod selection;
pub mod series;
pub mod shard;
pub mod stats;
pub mod trace;
pub mod virtual_rig;

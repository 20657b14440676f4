//! The desktop side of the vibro-impact hammer project. All physics comes from `shared`, the
//! same code the firmware runs; this crate adds what a desktop needs around it.
//!
//! Data flows one way:
//!
//! - rig parameters: [`config`] (presets, `--config` TOML, validation) → a [`config::Setup`];
//! - the analyses over `shared`'s integrator and observers: [`runner`] (parallel, batched,
//!   interleaved evaluation), [`response`], [`selection`] (the main job), [`series`] (time
//!   series), [`grid`] (Peterka maps, basins, bifurcation; shards in [`shard`]), [`propagate`]
//!   (the selection under parameter uncertainty), [`identify`] (parameters from drop tests and
//!   free decays, read by [`trace`]), [`comparison`] (model against a measured response);
//! - the outputs: CSV through [`output`] (written whole or not at all), figures in [`plot`],
//!   [`maps`], [`plot_identify`];
//! - the commands in [`commands`] (parsed by [`cli`]): parse, call the library, write, print;
//! - the rig itself: [`client`] (its serial console from the desktop) and [`rig`] (the virtual
//!   rig: the firmware's controller against a simulated plant through mock hardware).

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

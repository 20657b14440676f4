//! The shared crate's integration tests, one binary (each file a module, one concept per file):
//! the physics' generic code is compiled and linked once for all of them.
//!
//! `cargo test -p vibro-shared --test all orbit::` runs one file's tests.

mod analytic;
mod capture_dma;
mod console_fuzz;
mod controller;
mod damping;
mod lyapunov;
mod orbit;
mod protocol;
mod robustness;
mod store;

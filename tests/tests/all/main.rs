//! The end-to-end tests but the QEMU runs (`emulator.rs` and `qemu.rs`, binaries of their own:
//! QEMU runs its CPU flat out, one emulation at a time), one binary (each file a module).
//!
//! `cargo test -p e2e-tests --test all docs::` runs one file's tests.

mod docs;
mod firmware_image;
mod layers;
mod register_trace;
mod selection;

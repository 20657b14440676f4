//! What the firmware's images share and that carries no interrupt handler: the power-up
//! configuration ([`config`]), the rig board's clock tree and the register values derived from
//! it, checked at compile time against RM0090's limits ([`clock_tree`]), and on the MCU the
//! stack measurement (`stack`) and what both boards do alike (`board_common`: the parts'
//! shape, the console's USART2, the 64-bit µs count). The images are the binaries of this
//! package: `firmware` (the rig board, `src/main.rs`), `firmware-qemu` (the same RTIC app on
//! QEMU, `src/emulator.rs`) and `qemu-check` (the `shared` computations on an emulated
//! Cortex-M4F, `src/bin/qemu_check.rs`). Each image brings its own board module (its
//! peripherals and interrupt stand-ins), so the app (`src/app.rs`) and the boards
//! (`src/board_rig.rs`, `src/board_emu.rs`) are modules of the binaries, not of this library.
#![cfg_attr(target_os = "none", no_std)]

pub mod clock_tree;
pub mod config;

#[cfg(target_os = "none")]
pub mod board_common;
#[cfg(target_os = "none")]
pub mod stack;

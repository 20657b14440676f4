//! Firmware of the vibro-impact rig: an RTIC 2 application for the STM32F407 (Cortex-M4F,
//! 168 MHz), thin glue around `shared::control` (the controller, the console service, the
//! capture): the tasks are in `app.rs`, the peripherals in `board_rig.rs` (what it shares with
//! the emulator image's board in `board_common.rs`).
//!
//! Data flows one way: the ADC's force samples (TIM2 trigger, 10 kHz, the `sample` task on
//! the end-of-conversion interrupt) → `shared::control::Controller` (drive cycles, impacts,
//! regime, faults) → the DAC's drive command. At lower priorities: `model` runs
//! `shared::control::predict` (rig parameters → switch-model integrator → regime and operating
//! frequency); `console` (USART2) and `serve` answer the console and send telemetry; `capture`
//! takes the drop-test force by DMA; `report` logs with defmt once a second and feeds the
//! watchdog after its health check.
//!
//! This binary is the rig image (`cargo fw-build`, flashed with `cargo fw`); the emulator image
//! (`src/emulator.rs`) runs the same app on QEMU's `netduinoplus2`. On the host this
//! crate compiles to a stub so that `cargo build --workspace` works.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board_rig;
#[cfg(target_os = "none")]
use board_rig as board;

#[cfg(target_os = "none")]
mod app;

#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "firmware for {} at {} mm gap: build it for the MCU with `cargo fw-build` (thumbv7em-none-eabihf)",
        rig_firmware::config::RIG,
        rig_firmware::config::GAP_MM
    );
}

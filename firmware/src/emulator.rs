//! The emulator image: the rig image's RTIC app (`src/app.rs`) on QEMU's `netduinoplus2`
//! (STM32F405, the F407's memory map), with the board of `src/board_emu.rs` standing in for
//! what QEMU lacks. Run by `tests/tests/emulator.rs`:
//! `qemu-system-arm -machine netduinoplus2 -nographic -serial null -serial pty -monitor none
//! -semihosting-config enable=on,target=native -icount shift=3,sleep=off -kernel
//! target/thumbv7em-none-eabihf/release/firmware-qemu` (USART2 on the pty).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board_emu;
#[cfg(target_os = "none")]
use board_emu as board;

#[cfg(target_os = "none")]
mod app;

#[cfg(not(target_os = "none"))]
fn main() {
    println!("firmware-qemu runs on QEMU's netduinoplus2: see tests/tests/emulator.rs");
}

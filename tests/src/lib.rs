//! End-to-end tests across the workspace crates live in `tests/`: the firmware's on-target
//! selection path (`shared`, sequential, no allocation) against the desktop's parallel one
//! (`host-sim`), and the thesis' reported behaviour at the main job's operating point.
//!
//! The library holds what the tests share: where the firmware images are and whether the
//! tools to run them are there. The tests that need the images and a tool (QEMU, LLVM's
//! binary tools, python's unicorn) are `#[ignore]`d with the tool named: `cargo test
//! --workspace` counts them as ignored where nothing says the tools are there, and
//! `--include-ignored` (as in `.ci/run`) runs them, where a missing tool fails.

use std::path::PathBuf;
use std::process::Command;

/// The release firmware binary `name` built for the target
/// (`$CARGO_TARGET_DIR/thumbv7em-none-eabihf/release/NAME`; by `cargo fw-build`).
#[must_use]
pub fn firmware_image(name: &str) -> PathBuf {
    let target_dir = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target"));
    target_dir.join("thumbv7em-none-eabihf/release").join(name)
}

/// The firmware image `name` (`cargo fw-build`), after checking that it and `qemu-system-arm`
/// are there.
///
/// # Panics
/// When either is missing, saying which (the tests that call it are ignored unless asked for).
#[must_use]
pub fn qemu_image(name: &str) -> PathBuf {
    let elf = firmware_image(name);
    let qemu_ok = Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .is_ok();
    assert!(
        elf.exists() && qemu_ok,
        "the test needs {} (cargo fw-build) and qemu-system-arm (apt-get install \
         qemu-system-arm) (found: image {}, qemu {qemu_ok})",
        elf.display(),
        elf.exists(),
    );
    elf
}

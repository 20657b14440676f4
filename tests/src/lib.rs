//! End-to-end tests across the workspace crates live in `tests/`: the firmware's on-target
//! selection path (`shared`, sequential, no allocation) against the desktop's parallel one
//! (`host-sim`), and the thesis' reported behaviour at the main job's operating point.
//!
//! The library holds what the tests share: where the firmware images are and whether the
//! tools to run them are there.

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

/// The firmware image `name` when it and `qemu-system-arm` are there. Otherwise `None` after a
/// note on stderr (the test is skipped), except under CI (`CI` set), where it panics.
///
/// # Panics
/// Under CI, when the image or QEMU is missing.
#[must_use]
pub fn qemu_image(name: &str) -> Option<PathBuf> {
    let elf = firmware_image(name);
    let qemu_ok = Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .is_ok();
    if elf.exists() && qemu_ok {
        return Some(elf);
    }
    let why = format!(
        "the test needs {} (cargo fw-build) and qemu-system-arm (found: image {}, qemu {qemu_ok})",
        elf.display(),
        elf.exists(),
    );
    assert!(std::env::var_os("CI").is_none(), "{why}");
    eprintln!("skipped: {why}");
    None
}

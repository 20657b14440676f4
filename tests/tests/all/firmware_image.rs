//! The rig image as linked (`cargo fw-build`), read with `llvm-nm` and `llvm-size`:
//! - flash within its budget (192 KiB of the F407VG's 1 MiB: the code from sector 3 on, after
//!   the vector table's sector 0 and the settings store's sectors 1–2, `memory.x`);
//! - flip-link's layout: the stack below the static data, so an overflow runs into the
//!   unmapped space below RAM and faults (the emulator test provokes one) instead of
//!   overwriting statics;
//! - hardware-timed sampling: the ADC's end-of-conversion interrupt runs the sampling task and
//!   TIM2 has no handler (it only triggers the conversions through its TRGO), so the sampling
//!   instant does not move with interrupt latency.
//!
//! Needs the images and LLVM's tools (`apt-get install llvm`): ignored unless asked for
//! (`cargo test -p e2e-tests -- --include-ignored`; `.ci/run`), where a missing tool fails.

use std::collections::HashMap;
use std::process::Command;

/// The output of LLVM's `tool` on the image `name`.
///
/// # Panics
/// Without the image or the tool, saying which.
fn llvm(tool: &str, args: &[&str], name: &str) -> String {
    let elf = e2e_tests::firmware_image(name);
    let out = Command::new(tool).args(args).arg(&elf).output();
    let ok = elf.exists() && out.as_ref().is_ok_and(|o| o.status.success());
    assert!(
        ok,
        "needs {} (cargo fw-build) and {tool} (apt-get install llvm): {}",
        elf.display(),
        match &out {
            Ok(o) => String::from_utf8_lossy(&o.stderr).into_owned(),
            Err(e) => e.to_string(),
        }
    );
    String::from_utf8(out.unwrap().stdout).unwrap()
}

/// Symbol → address of the image `name`.
fn symbols(name: &str) -> HashMap<String, u64> {
    llvm("llvm-nm", &[], name)
        .lines()
        .filter_map(|l| {
            let mut w = l.split_whitespace();
            let addr = u64::from_str_radix(w.next()?, 16).ok()?;
            let _kind = w.next()?;
            Some((w.next()?.to_string(), addr))
        })
        .collect()
}

#[test]
#[ignore = "needs llvm-nm (apt install llvm) and the firmware images (cargo fw-build)"]
fn the_stack_sits_below_the_static_data_in_every_image() {
    for name in ["firmware", "firmware-qemu", "qemu-check"] {
        let s = symbols(name);
        let (stack_top, data) = (s["_stack_start"], s["__sdata"]);
        assert!(
            stack_top <= data && s["_stack_end"] == 0x2000_0000,
            "{name}: stack top 0x{stack_top:x}, static data from 0x{data:x}: not flip-link's layout"
        );
    }
}

#[test]
#[ignore = "needs llvm-nm (apt install llvm) and the firmware images (cargo fw-build)"]
fn sampling_is_triggered_by_hardware_on_the_rig() {
    let s = symbols("firmware");
    let default = s["DefaultHandler"];
    assert_ne!(s["ADC"], default, "no ADC end-of-conversion handler");
    assert_eq!(
        s["TIM2"], default,
        "TIM2 has a handler: is the conversion started in software again?"
    );
    assert_ne!(s["USART2"], default);
}

#[test]
#[ignore = "needs llvm-size (apt install llvm) and the firmware images (cargo fw-build)"]
fn the_rig_image_fits_its_flash_budget() {
    let text = llvm("llvm-size", &["-A"], "firmware");
    let size = |sec: &str| -> u64 {
        text.lines()
            .find(|l| l.split_whitespace().next() == Some(sec))
            .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
            .unwrap_or(0)
    };
    assert!(
        size(".text") > 0,
        "no .text in the llvm-size output:\n{text}"
    );
    let flash = size(".vector_table") + size(".text") + size(".rodata") + size(".data");
    eprintln!(
        "rig image: flash {flash} B ({:.1} KiB)",
        flash as f64 / 1024.0
    );
    assert!(flash <= 192 * 1024, "flash {flash} B");
}

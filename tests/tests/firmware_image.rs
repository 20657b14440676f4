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
//! Skipped with a note without the image or LLVM's tools, except under CI.

use std::collections::HashMap;
use std::process::Command;

/// Symbol → address, or `None` (skipped) without the image or llvm-nm.
fn symbols(name: &str) -> Option<HashMap<String, u64>> {
    let elf = e2e_tests::firmware_image(name);
    let out = Command::new("llvm-nm").arg(&elf).output();
    let ok = elf.exists() && out.as_ref().is_ok_and(|o| o.status.success());
    if !ok {
        let why = format!(
            "needs {} (cargo fw-build) and llvm-nm (apt-get install llvm)",
            elf.display()
        );
        assert!(std::env::var_os("CI").is_none(), "{why}");
        eprintln!("skipped: {why}");
        return None;
    }
    let text = String::from_utf8(out.unwrap().stdout).unwrap();
    Some(
        text.lines()
            .filter_map(|l| {
                let mut w = l.split_whitespace();
                let addr = u64::from_str_radix(w.next()?, 16).ok()?;
                let _kind = w.next()?;
                Some((w.next()?.to_string(), addr))
            })
            .collect(),
    )
}

#[test]
fn the_stack_sits_below_the_static_data_in_every_image() {
    for name in ["firmware", "firmware-qemu", "qemu-check"] {
        let Some(s) = symbols(name) else { return };
        let (stack_top, data) = (s["_stack_start"], s["__sdata"]);
        assert!(
            stack_top <= data && s["_stack_end"] == 0x2000_0000,
            "{name}: stack top 0x{stack_top:x}, static data from 0x{data:x}: not flip-link's layout"
        );
    }
}

#[test]
fn sampling_is_triggered_by_hardware_on_the_rig() {
    let Some(s) = symbols("firmware") else { return };
    let default = s["DefaultHandler"];
    assert_ne!(s["ADC"], default, "no ADC end-of-conversion handler");
    assert_eq!(
        s["TIM2"], default,
        "TIM2 has a handler: is the conversion started in software again?"
    );
    assert_ne!(s["USART2"], default);
}

#[test]
fn the_rig_image_fits_its_flash_budget() {
    let elf = e2e_tests::firmware_image("firmware");
    let Ok(out) = Command::new("llvm-size").args(["-A"]).arg(&elf).output() else {
        assert!(std::env::var_os("CI").is_none(), "llvm-size missing");
        return;
    };
    if !out.status.success() {
        assert!(
            std::env::var_os("CI").is_none(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        return;
    }
    let text = String::from_utf8(out.stdout).unwrap();
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

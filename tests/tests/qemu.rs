//! The `shared` computations on an emulated Cortex-M4F: runs the firmware crate's `qemu-check`
//! image under `qemu-system-arm -machine netduinoplus2 -icount shift=0` and checks that
//! - the operating frequency (and band and F_i/mg) computed on target equals the host's f32
//!   `shared::control::predict` bit for bit,
//! - one full target-frequency computation takes ≤ 84 M instructions (0.5 s at 168 MHz) and one
//!   sampling-task call, streaming telemetry, ≤ 1,500 instructions (the program's exit code
//!   says the same).
//!
//! Needs the image (`cargo fw-build`, which builds both firmware binaries) and QEMU
//! (`apt-get install qemu-system-arm`); `.ci/run` provides both and runs it. Ignored unless
//! asked for (`cargo test -p e2e-tests -- --include-ignored`), where a missing tool fails it.

use std::process::Command;

use shared::control::{SensorChain, predict};
use shared::identify::{DropIdentification, DropLaw, RecordedDrop, identify_drop};
use shared::model::{ModelEdit, ModelField, RigId, params_hash};

/// Instructions the Hunt–Crossley drop identification may take on the recorded 22-impact drop
/// (0.25 s at 168 MHz: the console service waits for it, the sampling does not).
const HC_IDENTIFY_BUDGET: u64 = 42_000_000;

fn field(out: &str, key: &str) -> String {
    out.split_whitespace()
        .find_map(|w| w.strip_prefix(&format!("{key}=")))
        .unwrap_or_else(|| panic!("`{key}=` missing in the QEMU output:\n{out}"))
        .to_string()
}

/// The host's identification of a recorded drop in `firmware/data/` (what `qemu-check` replays
/// on the emulated board), with `rig`'s hammer mass.
fn replay(file: &str, rig: RigId) -> DropIdentification {
    let path = format!("{}/../firmware/data/{file}", env!("CARGO_MANIFEST_DIR"));
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut rec = RecordedDrop::parse(&bytes, SensorChain::default()).unwrap();
    identify_drop(&mut rec, rig.preset().mass_kg as f32, 0.0).unwrap()
}

fn hex(s: &str) -> u32 {
    u32::from_str_radix(s.trim_start_matches("0x"), 16).unwrap()
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware images (cargo fw-build)"]
fn on_target_selection_matches_the_host_and_meets_the_budgets() {
    let elf = e2e_tests::qemu_image("qemu-check");
    let run = Command::new("timeout")
        .args([
            "300",
            "qemu-system-arm",
            "-machine",
            "netduinoplus2",
            "-nographic",
        ])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=0,sleep=off", "-kernel"])
        .arg(&elf)
        .output()
        .expect("run qemu-system-arm");
    let out = String::from_utf8_lossy(&run.stdout).into_owned();
    eprintln!("{out}");
    assert!(
        run.status.success(),
        "qemu-check failed ({}):\n{out}",
        run.status
    );

    // Same inputs on the host, same f32 code: identical bits.
    let host = predict(&RigId::Wires.preset(), 0.0).unwrap();
    let hint = "(a stale image? rebuild with `cargo fw-build`)";
    assert_eq!(
        hex(&field(&out, "bits")),
        host.target_hz.to_bits(),
        "target_hz {hint}"
    );
    assert_eq!(
        hex(&field(&out, "band_lo_bits")),
        host.band_hz[0].to_bits(),
        "{hint}"
    );
    assert_eq!(
        hex(&field(&out, "band_hi_bits")),
        host.band_hz[1].to_bits(),
        "{hint}"
    );
    assert_eq!(
        hex(&field(&out, "force_mg_bits")),
        host.impact_force_mg.to_bits(),
        "{hint}"
    );

    // A model that is no preset (stored by a rig engineer): the wire rig damped, a heavier
    // hammer, a contact of its own; the same bits on the host.
    let stored = [
        ModelEdit::Set(ModelField::StiffnessNM, 5_016_300.0),
        ModelEdit::Set(ModelField::DampingNSM, 1_133.7),
        ModelEdit::Set(ModelField::DampingRatio, 0.01),
        ModelEdit::Set(ModelField::MassKg, 0.31),
    ]
    .into_iter()
    .try_fold(RigId::Wires.preset(), |p, e| p.edited(e))
    .unwrap();
    let host = predict(&stored, 0.0).unwrap();
    let line = out
        .lines()
        .find(|l| l.starts_with("stored "))
        .unwrap_or_else(|| panic!("no `stored` line in:\n{out}"));
    assert_eq!(
        hex(&field(line, "model_hash")),
        params_hash(&stored),
        "{hint}"
    );
    for (key, bits) in [
        ("target_bits", host.target_hz.to_bits()),
        ("band_lo_bits", host.band_hz[0].to_bits()),
        ("band_hi_bits", host.band_hz[1].to_bits()),
        ("force_mg_bits", host.impact_force_mg.to_bits()),
    ] {
        assert_eq!(hex(&field(line, key)), bits, "stored model's {key} {hint}");
    }

    // The board's drop identification of the recorded capture: the host's bits.
    let id = replay("drop-wires-k2.bin", RigId::Wires);
    let sus = id.suspension.unwrap();
    let line = out
        .lines()
        .find(|l| l.starts_with("identify "))
        .unwrap_or_else(|| panic!("no `identify` line in:\n{out}"));
    let DropLaw::SpringDashpot {
        stiffness_n_m,
        damping_n_s_m,
        ..
    } = id.law
    else {
        panic!("the recorded drop's law: {:?}", id.law)
    };
    for (key, bits) in [
        ("k_bits", stiffness_n_m.to_bits()),
        ("c_bits", damping_n_s_m.to_bits()),
        ("f_n_bits", sus.natural_freq_hz.to_bits()),
        ("zeta_bits", sus.damping_ratio.to_bits()),
        ("fit_bits", id.fit_ratio.to_bits()),
    ] {
        assert_eq!(hex(&field(line, key)), bits, "identify's {key} {hint}");
    }

    // The Hunt–Crossley drop: the host's bits too.
    let id = replay("drop-beam150-hc.bin", RigId::Beam150);
    let sus = id.suspension.unwrap();
    let DropLaw::HuntCrossley {
        stiffness,
        exponent,
        lambda_s_m,
        ..
    } = id.law
    else {
        panic!("the recorded Hunt–Crossley drop's law: {:?}", id.law)
    };
    let line = out
        .lines()
        .find(|l| l.starts_with("identify_hc "))
        .unwrap_or_else(|| panic!("no `identify_hc` line in:\n{out}"));
    for (key, bits) in [
        ("k_bits", stiffness.to_bits()),
        ("n_bits", exponent.to_bits()),
        ("lambda_bits", lambda_s_m.to_bits()),
        ("f_n_bits", sus.natural_freq_hz.to_bits()),
        ("zeta_bits", sus.damping_ratio.to_bits()),
        ("fit_bits", id.fit_ratio.to_bits()),
    ] {
        assert_eq!(hex(&field(line, key)), bits, "identify_hc's {key} {hint}");
    }

    let n = |k: &str| field(&out, k).parse::<u64>().unwrap();
    assert!(
        n("identify") <= 4_200_000,
        "drop identification: {} instructions",
        n("identify")
    );
    assert!(
        n("identify_hc") <= HC_IDENTIFY_BUDGET,
        "Hunt–Crossley drop identification: {} instructions",
        n("identify_hc")
    );
    for key in ["predict", "predict_stored"] {
        assert!(
            n(key) <= 84_000_000,
            "target computation ({key}): {} instructions",
            n(key)
        );
    }
    assert!(
        n("sample_max") <= 1_500,
        "sampling task: {} instructions",
        n("sample_max")
    );
    assert!(n("step_mean") > 0 && n("sample_mean") > 0);
    // The stack must fit the 128 KiB SRAM with room for the interrupt tasks on top (and the
    // painting must see the model task's depth: tens of KiB).
    let stack = n("stack_high_water_bytes");
    assert!((10 * 1024..96 * 1024).contains(&stack), "stack {stack} B");
    assert_eq!(field(&out, "state"), "track");
    assert_eq!(field(&out, "fault"), "none");

    // sin/cos on the target (docs/model.md, "Dependencies"): the model's polynomial is as
    // accurate as libm's and no dearer than micromath, whose 1e-3 error is why it is not used.
    let math = |name: &str| -> (u64, f64) {
        let line = out
            .lines()
            .find(|l| l.starts_with(&format!("math sin_cos {name} ")))
            .unwrap_or_else(|| panic!("no `math sin_cos {name}` line in:\n{out}"));
        (
            field(line, "insns").parse().unwrap(),
            field(line, "max_err").parse().unwrap(),
        )
    };
    let (model, micro, libm) = (math("model"), math("micromath"), math("libm"));
    assert!(model.1 < 1e-7 && libm.1 < 1e-7, "{model:?} {libm:?}");
    assert!(micro.1 > 1e-4, "micromath {micro:?}");
    assert!(
        model.0 <= micro.0 && model.0 * 10 < libm.0,
        "{model:?} {micro:?} {libm:?}"
    );
}

//! Writes the recorded drop that the emulated board's budget check replays
//! (`firmware/data/drop-wires-k2.bin`): `cargo run --release -p host-sim --example record_drop
//! [-- PATH]`. `host-sim/tests/all/onboard_identify.rs` checks that the committed file is what this
//! makes. Prints the board's `capture identify` and `capture adopt` answers to it.

use anyhow::Result;
use host_sim::virtual_rig::recording::{capture_drop, recorded_bytes, reference_scenario};
use shared::console::Line;
use shared::model::RigId;

fn main() -> Result<()> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "firmware/data/drop-wires-k2.bin".into());
    let (_, scenario) = reference_scenario(1);
    let mut session = capture_drop(RigId::Wires, scenario, 2.5)?;
    let bytes = recorded_bytes(&session)?;
    std::fs::write(&path, &bytes)?;
    println!("wrote {path} ({} bytes)", bytes.len());
    let answer = session.answer(Line::Text("capture identify")).answer;
    println!("> capture identify\n{answer}");
    let answer = session.answer(Line::Text("capture adopt")).answer;
    println!("> capture adopt\n{answer}");
    Ok(())
}

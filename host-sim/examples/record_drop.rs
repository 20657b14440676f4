//! Writes the recorded drops that the emulated board's budget check replays:
//! `firmware/data/drop-wires-k2.bin` (the wire rig, a spring–dashpot contact of its own) and
//! `firmware/data/drop-beam150-hc.bin` (the 150 mm beam, Fig. 3.3's Hunt–Crossley contact):
//! `cargo run --release -p host-sim --example record_drop [-- DIR]` (DIR: `firmware/data` by
//! default). `host-sim/tests/all/onboard_identify.rs` checks that the committed files are what
//! this makes. Prints the board's `capture identify` and `capture adopt` answers to each.

use anyhow::Result;
use host_sim::virtual_rig::recording::{
    capture_drop, hunt_crossley_scenario, recorded_bytes, reference_scenario,
};
use shared::console::Line;
use shared::model::RigId;

fn main() -> Result<()> {
    let dir = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "firmware/data".into());
    for (name, rig, (_, scenario)) in [
        ("drop-wires-k2.bin", RigId::Wires, reference_scenario(1)),
        (
            "drop-beam150-hc.bin",
            RigId::Beam150,
            hunt_crossley_scenario(1),
        ),
    ] {
        let path = std::path::Path::new(&dir).join(name);
        let mut session = capture_drop(rig, scenario, 2.5)?;
        let bytes = recorded_bytes(&session)?;
        std::fs::write(&path, &bytes)?;
        println!("wrote {} ({} bytes)", path.display(), bytes.len());
        let answer = session.answer(Line::Text("capture identify")).answer;
        println!("> capture identify\n{answer}");
        let answer = session.answer(Line::Text("capture adopt")).answer;
        println!("> capture adopt\n{answer}");
    }
    Ok(())
}

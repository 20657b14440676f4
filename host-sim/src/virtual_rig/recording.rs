//! A drop test on the virtual rig, as its console records it: the scenario's plant released
//! while a capture runs (`capture arm`), the segments kept ([`shared::identify::RecordedDrop`]'s
//! bytes). The emulated board's budget check replays one such recording
//! (`firmware/data/drop-wires-k2.bin`, written by `cargo run -p host-sim --example record_drop`).

use anyhow::{Context, Result, bail, ensure};
use shared::console::{Answer, Line};
use shared::identify::RecordedDrop;
use shared::model::RigId;

use super::chains::SensorChainSim;
use super::scenario::{PlantSection, Scenario, TimedDrop};
use super::session::{HilSetup, Session};

/// The recorded drop of the firmware's budget check: the wire rig whose contact is twice as
/// stiff as Table 3.1's with 0.6 of its damping and whose natural frequency is 8 % higher,
/// released from 8 mm at gap 0, the default sensor chain with noise seed 1, a 2.5 s capture.
pub fn reference_scenario(seed: u64) -> (PlantSection, Scenario) {
    let plant = PlantSection {
        contact_stiffness_factor: 2.0,
        contact_damping_factor: 0.6 / 2f64.sqrt(),
        natural_freq_factor: 1.08,
        ..PlantSection::default()
    };
    (plant, drop_scenario(plant, seed))
}

/// The recorded Hunt–Crossley drop of the firmware's budget check: the 150 mm beam with Fig.
/// 3.3's contact (`k_i` 2.1e8 N/m^1.6, `n` 1.6, `λ_i` 0.6 s/m), released from 8 mm at gap 0,
/// the default sensor chain with noise seed `seed`, a 2.5 s capture (`RigId::Beam150`).
pub fn hunt_crossley_scenario(seed: u64) -> (PlantSection, Scenario) {
    let plant = PlantSection {
        contact: Some(shared::model::ContactLaw::HuntCrossley {
            stiffness: 2.1e8,
            exponent: 1.6,
            lambda_s_m: 0.6,
        }),
        ..PlantSection::default()
    };
    (plant, drop_scenario(plant, seed))
}

/// A scenario of the plant `plant` released from 8 mm at 0.2 s, no console lines, the default
/// sensor chain with noise seed `seed`.
pub fn drop_scenario(plant: PlantSection, seed: u64) -> Scenario {
    Scenario {
        plant,
        sensor: SensorChainSim {
            seed,
            ..SensorChainSim::default()
        },
        commands: Vec::new(),
        drops: vec![TimedDrop {
            at_s: 0.2,
            release_mm: 8.0,
        }],
        ..Scenario::default()
    }
}

/// Runs `scenario` on `rig` at gap 0 with a capture of `seconds` armed at the start (trigger
/// 1 N), and returns the session when the capture is done.
///
/// # Errors
/// The scenario does not run, or the capture is refused.
pub fn capture_drop(rig: RigId, scenario: Scenario, seconds: f64) -> Result<Session> {
    let mut s = Session::new(&HilSetup {
        rig,
        gap_mm: 0.0,
        actual_gap_mm: 0.0,
        seconds: seconds + 1.0,
        scenario,
    })?;
    let arm = format!("capture arm 1 {seconds}");
    match s.answer(Line::Text(&arm)).answer {
        Answer::Capture(_) => {}
        other => bail!("`{arm}` answered `{other}`"),
    }
    while s.t_s() < seconds + 0.1 {
        s.begin_sample().context("the virtual rig")?;
        s.end_sample();
    }
    Ok(s)
}

/// The bytes of the capture of `session` (done).
///
/// # Errors
/// The capture is still recording.
pub fn recorded_bytes(session: &Session) -> Result<Vec<u8>> {
    let cap = session.capture();
    ensure!(!cap.active(), "the capture is still recording");
    let mut out = Vec::new();
    RecordedDrop::encode(cap, &mut out);
    Ok(out)
}

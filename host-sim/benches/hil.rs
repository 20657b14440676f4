//! Speed of the virtual rig (`host-sim hil`): rig time over wall time on one core, for the wire
//! rig at 0.0 mm tracking for 60 s (default scenario), best of three runs.
//!
//! `cargo bench -p host-sim --bench hil`

use host_sim::virtual_rig::scenario::Scenario;
use host_sim::virtual_rig::{HilSetup, run};
use shared::model::RigId;

fn main() {
    let setup = HilSetup {
        rig: RigId::Wires,
        gap_mm: 0.0,
        actual_gap_mm: 0.0,
        seconds: 60.0,
        scenario: Scenario::default(),
    };
    let mut best = 0.0f64;
    for i in 0..3 {
        let r = run(&setup).expect("virtual rig");
        let us_per_sample = r.wall_s * 1e6 / r.samples as f64;
        println!(
            "run {i}: 60 s of rig time in {:.3} s wall: {:.1}× real time ({us_per_sample:.2} µs per 100 µs sample: controller + 10 plant RK4 steps)",
            r.wall_s,
            r.speedup()
        );
        best = best.max(r.speedup());
    }
    println!("hil speed: {best:.1}× real time on one core (target ≥ 50×)");
}

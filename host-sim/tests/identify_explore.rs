use host_sim::identify::contact::*;
use host_sim::identify::synth::*;
use shared::analysis::drop::DropSpec;
use shared::model::{ContactLaw, RigId};
use std::time::Instant;

#[test]
fn explore() {
    let mut p = RigId::Wires.preset();
    let laws = [
        ContactLaw::SpringDashpot { stiffness_n_m: 4.0e6, damping_n_s_m: 900.0 },
        ContactLaw::Hertz { stiffness: 1.0e9, exponent: 1.5 },
        ContactLaw::HuntCrossley { stiffness: 1.0e9, exponent: 1.5, lambda_s_m: 10.0 },
        ContactLaw::LankaraniNikravesh { stiffness: 1.0e9, exponent: 1.5, restitution: 0.5 },
    ];
    for law in laws {
        p.contact = law;
        let spec = DropSpec { gap_m: 0.0, release_m: 3e-3, duration_s: 2.0, max_impacts: 0 };
        let t = Instant::now();
        let tr = synthetic_drop(&p, &spec, &TRUTH_STEPS, &Sensor { sample_rate_hz: 50e3, noise_pct: 1.0, offset_n: 0.5, seed: 7 }).unwrap();
        let data = analyse_drop(&tr, 8).unwrap();
        println!("{law:?}: synth {:?}, offset {:.3} noise {:.3}", t.elapsed(), data.offset_n, data.noise_n);
        for i in &data.impacts { println!("   {:?}", i); }
        let setup = DropSetup { params: p, gap_m: 0.0, release_m: 3e-3, steps: FIT_STEPS };
        for (name, w) in [("peaks", Weights { time: 1.0, profile: 0.0 }), ("profile", Weights { time: 1.0, profile: 1.0 })] {
            let t = Instant::now();
            let truth = residual_of(&setup, &data, &law, w).unwrap();
            let fit = fit_law(&setup, &data, law.kind(), w, 400).unwrap();
            println!("  {name}: {:?} in {:?} ({} evals): {:?}\n     truth residual {:?}", fit.law, t.elapsed(), fit.evaluations, fit.residual, truth);
        }
    }
}

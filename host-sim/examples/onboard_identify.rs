//! The board's drop identification (`capture identify`, `shared::identify`) on the virtual
//! rig's plants that differ from the preset, an 8 mm drop at 0.0 mm gap: the errors against the
//! plant's own parameters for noise seeds 1–3, then the damping ratio's error over seeds 1–N
//! (docs/identification.md, "On the board").
//! `cargo run --release -p host-sim --example onboard_identify [N]` (N = 3 by default; 0.6 s
//! once built, 20 seeds 4 s).

use anyhow::Result;
use host_sim::virtual_rig::recording::{capture_drop, drop_scenario};
use host_sim::virtual_rig::scenario::PlantSection;
use shared::control::SensorChain;
use shared::identify::{CaptureOnChain, DropLaw, identify_drop};
use shared::model::{ContactLaw, RigId};

/// Fig. 3.3's Hunt–Crossley contact (the thesis' fit of the 150 mm beam's drop).
const HUNT_CROSSLEY: ContactLaw = ContactLaw::HuntCrossley {
    stiffness: 2.1e8,
    exponent: 1.6,
    lambda_s_m: 0.6,
};

fn main() -> Result<()> {
    let seeds: u64 = match std::env::args().nth(1) {
        None => 3,
        Some(a) => a
            .parse()
            .ok()
            .filter(|&n| (3..=1000).contains(&n))
            .ok_or_else(|| {
                anyhow::anyhow!("N (noise seeds) must be an integer in 3..=1000, got {a:?}")
            })?,
    };
    let plants: [(&str, RigId, PlantSection); 6] = [
        ("wire rig, Table 3.1", RigId::Wires, PlantSection::default()),
        (
            "k_i ×2, c_i ×0.6",
            RigId::Wires,
            PlantSection {
                contact_stiffness_factor: 2.0,
                contact_damping_factor: 0.6 / 2f64.sqrt(),
                ..PlantSection::default()
            },
        ),
        (
            "ω +8 %",
            RigId::Wires,
            PlantSection {
                natural_freq_factor: 1.08,
                ..PlantSection::default()
            },
        ),
        (
            "pendulum ζ = 0.01",
            RigId::Wires,
            PlantSection {
                damping_ratio: Some(0.01),
                ..PlantSection::default()
            },
        ),
        (
            "170 mm beam (ζ = 0.004)",
            RigId::Beam170,
            PlantSection::default(),
        ),
        (
            "150 mm beam, Hunt–Crossley (Fig. 3.3)",
            RigId::Beam150,
            PlantSection {
                contact: Some(HUNT_CROSSLEY),
                ..PlantSection::default()
            },
        ),
    ];
    println!(
        "| plant | impacts | law | k_i error | c_i or λ_i error | n error | f_n error | ζ (truth) | fit_ratio |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    let mut zeta_rows = Vec::new();
    for (name, rig, plant) in plants {
        let truth = plant.params(&rig.preset())?;
        // The plant's (k_i, c_i or λ_i, n).
        let (k, c, n) = match truth.contact {
            ContactLaw::SpringDashpot {
                stiffness_n_m,
                damping_n_s_m,
            } => (stiffness_n_m, damping_n_s_m, None),
            ContactLaw::HuntCrossley {
                stiffness,
                exponent,
                lambda_s_m,
            } => (stiffness, lambda_s_m, Some(exponent)),
            other => anyhow::bail!("{name}: no board identification for {other:?}"),
        };
        let zeta = truth.damping_ratio();
        let mut cells: [Vec<String>; 8] = Default::default();
        let mut zeta_errors = Vec::new();
        for seed in 1..=seeds {
            let session = capture_drop(rig, drop_scenario(plant, seed), 2.5)?;
            let sensor = SensorChain::default();
            let id = identify_drop(
                &mut CaptureOnChain {
                    capture: session.capture(),
                    sensor: &sensor,
                },
                truth.mass_kg as f32,
                0.0,
            )
            .map_err(|e| anyhow::anyhow!("{name}, seed {seed}: refused: {e:?}"))?;
            let s = id.suspension.expect("gap 0");
            zeta_errors.push(f64::from(s.damping_ratio) - zeta);
            if seed > 3 {
                continue;
            }
            let pct = |x: f32, t: f64| format!("{:+.2}", 100.0 * (f64::from(x) / t - 1.0));
            let (law, id_k, id_c, id_n) = match id.law {
                DropLaw::SpringDashpot {
                    stiffness_n_m,
                    damping_n_s_m,
                    ..
                } => ("spring–dashpot", stiffness_n_m, damping_n_s_m, None),
                DropLaw::HuntCrossley {
                    stiffness,
                    exponent,
                    lambda_s_m,
                    ..
                } => ("Hunt–Crossley", stiffness, lambda_s_m, Some(exponent)),
            };
            cells[0].push(id.impacts.to_string());
            cells[1].push(law.to_string());
            cells[2].push(pct(id_k, k));
            cells[3].push(pct(id_c, c));
            cells[4].push(match (id_n, n) {
                (Some(x), Some(t)) => format!("{:+.4}", f64::from(x) - t),
                _ => "–".to_string(),
            });
            cells[5].push(pct(s.natural_freq_hz, truth.natural_freq_hz()));
            cells[6].push(format!("{:.4}", s.damping_ratio));
            cells[7].push(format!("{:.2}", id.fit_ratio));
        }
        cells[1].dedup();
        println!(
            "| {name} | {} | {} | {} % | {} % | {} | {} % | {} ({zeta}) | {} |",
            cells[0].join(", "),
            cells[1].join(", "),
            cells[2].join(", "),
            cells[3].join(", "),
            cells[4].join(", "),
            cells[5].join(", "),
            cells[6].join(", "),
            cells[7].join(", ")
        );
        zeta_rows.push((name, zeta, zeta_errors));
    }
    println!("\n| plant | ζ | ζ error over {seeds} seeds: mean | standard deviation | largest |");
    println!("|---|---|---|---|---|");
    for (name, zeta, e) in zeta_rows {
        let n = e.len() as f64;
        let mean = e.iter().sum::<f64>() / n;
        let sd = (e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let largest = e.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        println!("| {name} | {zeta} | {mean:+.4} | {sd:.4} | {largest:.4} |");
    }
    Ok(())
}

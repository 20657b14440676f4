//! The identified parameters' uncertainty, checked against known truth:
//! - coverage, on noise seed 1 of a synthetic drop test (the plant simulation at finer
//!   steps than the fit's, 1 % noise, 0.5 N offset): the 95 % intervals contain the true value
//!   of every parameter and the lack-of-fit note stays silent — spring–dashpot (Table 3.1) and
//!   Hunt–Crossley (Fig. 3.3), peaks and profile errors; the same for the free decay's `f_n`
//!   and `ζ` (the analytic oscillator, and a simulated decay of the damped wire pendulum). Over
//!   seeds 1–40, where the intervals must hold the truth in 85–100 % of the seeds and the note
//!   stay silent on 95 %, with the wrong law's spread below: `cargo run --release -p host-sim
//!   --example coverage` (the same checks, `tests/common/coverage.rs`; docs/identification.md);
//! - the wrong law (Hunt–Crossley data fitted with the spring–dashpot law, 3 mm and 1 mm,
//!   seed 1): the lack-of-fit note fires;
//! - the identifiability notes say what docs/identification.md says: Hertz `(k, n)` and the
//!   power laws' `k_i` are not fixed by one release height, spring–dashpot is by two;
//! - propagation to the main job: ±5 % on Table 3.1's `k_i` and `c_i` gives a 95 % range of
//!   the operating frequency that contains `select`'s nominal answer.

use crate::coverage::{self, truth_of};
use host_sim::config::{Setup, UncertaintyTable, coordinate_names};
use host_sim::identify::cost::{DropTest, Weights};
use host_sim::identify::fit::{Fit, fit_law, fit_law_joint};
use host_sim::identify::synth::LabDrop;
use host_sim::propagate::propagate;
use host_sim::selection::compute;
use host_sim::stats::Z95;
use shared::model::{ContactLaw, ContactLawKind, RigId};

const PEAKS: Weights = Weights::PEAKS;
const PROFILE: Weights = Weights::PROFILE;
/// The noise seed of the suite's coverage cases: a representative case of the statistical
/// sweep over seeds 1–40 that `examples/coverage.rs` runs (each interval holds the truth and the
/// note fires as on 85–100 % of those seeds).
const SEEDS: std::ops::RangeInclusive<u64> = 1..=1;

#[test]
fn spring_dashpot_intervals_cover_the_truth() {
    for (weights, what) in [(PEAKS, "peaks"), (PROFILE, "profile")] {
        coverage::assert_coverage(ContactLaw::identified(), weights, what, SEEDS);
    }
}

#[test]
fn hunt_crossley_intervals_cover_the_truth() {
    let truth = ContactLaw::preset(ContactLawKind::HuntCrossley);
    coverage::assert_coverage(truth, PEAKS, "peaks", SEEDS);
    // The profile with the impact times: over seeds 1–40, 35, 35 and 36 of 40 (k_i, n, λ_i).
    // With the first 100 noise redraws alone, 33, 33 and 35: that set of redraws gives n a
    // spread of 0.00326 where 2,000 give 0.00395, and every fit shares it
    // (docs/identification.md).
    coverage::assert_coverage(truth, PROFILE, "profile", SEEDS);
}

#[test]
fn the_wrong_law_is_flagged() {
    for release_mm in [3.0, 1.0] {
        coverage::assert_wrong_law(release_mm, SEEDS, false);
    }
}

#[test]
fn free_decay_intervals_cover_the_truth() {
    coverage::assert_free_decay_coverage(SEEDS);
}

#[test]
fn wire_rig_free_decay_intervals_cover_the_damped_pendulum() {
    coverage::assert_wire_rig_free_decay_coverage(SEEDS);
}

/// The [`LabDrop`] of `law` released `release_mm`, measured with noise seed `seed`.
fn lab_test(law: ContactLaw, release_mm: f64, seed: u64) -> DropTest {
    let lab = LabDrop { law, release_mm };
    lab.measured(&lab.clean().unwrap(), seed).unwrap()
}

/// A fit of one 3 mm drop test of `truth` (noise seed 1).
fn one_height(truth: ContactLaw, weights: Weights) -> Fit {
    let lab = LabDrop {
        law: truth,
        release_mm: 3.0,
    };
    let t = lab.measured(&lab.clean().unwrap(), 1).unwrap();
    fit_law(&t.setup, &t.data, truth.kind(), weights, 400).unwrap()
}

#[test]
fn notes_say_what_one_height_does_not_fix() {
    // Hertz from the peaks: every peak of one drop is the same function of (k, n), so the two
    // trade off along a valley.
    let hertz = one_height(ContactLaw::preset(ContactLawKind::Hertz), PEAKS);
    let u = hertz.uncertainty.unwrap();
    let k = &u.params[0];
    assert_eq!(k.key, "stiffness");
    assert!(k.rel_half_width() > 0.10, "{k:?}");
    let notes = u.notes.join("\n");
    assert!(notes.contains("k_i") && notes.contains(" n"), "{notes}");
    // Hunt–Crossley from the peaks of one height: k_i is tied to n (Δk/k ≈ |ln δ| Δn); the
    // notes say so, and that a second release height fixes it.
    let hc = ContactLaw::preset(ContactLawKind::HuntCrossley);
    let u = one_height(hc, PEAKS).uncertainty.unwrap();
    assert!(u.params[0].rel_half_width() > 0.10, "{:?}", u.params[0]);
    let notes = u.notes.join("\n");
    assert!(
        notes.contains("k_i") && notes.contains("trade off") && notes.contains("height"),
        "{notes}"
    );
    // With the profile (16 samples per contact) one height fixes k_i to about ±8 %: no note
    // on k_i, but an interval still wider than a second height gives.
    let one = one_height(hc, PROFILE).uncertainty.unwrap();
    let tests: Vec<DropTest> = [(0.25, 11), (3.0, 10)]
        .iter()
        .map(|&(release_mm, seed)| lab_test(hc, release_mm, seed))
        .collect();
    let two = fit_law_joint(&tests, hc.kind(), PROFILE, 400)
        .unwrap()
        .uncertainty
        .unwrap();
    assert!(
        two.params[0].rel_half_width() < 0.5 * one.params[0].rel_half_width(),
        "k_i: one height {:?}, two {:?}",
        one.params[0],
        two.params[0]
    );
}

#[test]
fn notes_are_silent_where_two_heights_fix_the_law() {
    let truth = ContactLaw::identified();
    let tests: Vec<DropTest> = [(0.25, 11), (3.0, 10)]
        .iter()
        .map(|&(release_mm, seed)| lab_test(truth, release_mm, seed))
        .collect();
    for weights in [PEAKS, PROFILE] {
        let f = fit_law_joint(&tests, truth.kind(), weights, 400).unwrap();
        let u = f.uncertainty.unwrap();
        assert!(u.identifiable);
        assert!(u.notes.is_empty(), "{:?}", u.notes);
        for p in &u.params {
            assert!(p.rel_half_width() < 0.10, "{p:?}");
            let v = truth_of(&truth, p.key);
            assert!(p.ci95[0] <= v && v <= p.ci95[1], "{p:?}");
        }
    }
}

#[test]
fn five_percent_on_table_3_1_keeps_the_nominal_frequency_in_range() {
    let setup = Setup::preset(RigId::Wires).unwrap();
    let (nominal, _) = compute(&setup, 0.0).unwrap();
    let ContactLaw::SpringDashpot {
        stiffness_n_m,
        damping_n_s_m,
    } = setup.params.contact
    else {
        panic!("the wire rig's law is Table 3.1's")
    };
    // ±5 % as a 95 % interval: σ of ln k and ln c = ln(1.05)/1.96 (uncorrelated).
    let var = (1.05f64.ln() / Z95).powi(2);
    let table = UncertaintyTable {
        law: ContactLawKind::SpringDashpot,
        coordinates: coordinate_names(ContactLawKind::SpringDashpot)
            .iter()
            .map(|c| c.to_string())
            .collect(),
        mean: vec![stiffness_n_m.ln(), damping_n_s_m.ln()],
        covariance: vec![vec![var, 0.0], vec![0.0, var]],
        method: None,
        lack_of_fit: None,
    };
    table.validate(&setup.params).unwrap();
    let p = propagate(&setup, 0.0, &table, &nominal, 64, 1).unwrap();
    assert_eq!(p.draws, 64);
    assert!(
        p.freq_hz.lo95 <= nominal.freq_hz && nominal.freq_hz <= p.freq_hz.hi95,
        "nominal {} Hz outside {:?}",
        nominal.freq_hz,
        p.freq_hz
    );
    // The nominal answer is 1/1 in most draws, and the robust point is 1/1 in all of them.
    assert!(p.nominal_one_one_share >= 0.9, "{p:?}");
    let robust = p.robust.expect("a frequency 1/1 in every draw");
    let at = p
        .band
        .iter()
        .find(|b| (b.freq_hz - robust.freq_hz).abs() < 1e-9)
        .unwrap();
    assert_eq!(at.one_one_share, 1.0);
    assert_eq!(p.band.len(), setup.selection.omega_ratio.len());
}

/// A distribution of one law (no variance: every draw is the mean) propagates to that law's
/// own answers, computed here without the propagation: the operating frequency and its force
/// (median and 95 % range) are `select`'s, the nominal frequency is 1/1 in every draw, and the
/// robust point is the strongest 1/1 point of the law's response at the nominal gap.
#[test]
fn a_distribution_of_one_law_propagates_to_that_laws_answers() {
    let setup = Setup::preset(RigId::Wires).unwrap();
    let (nominal, _) = compute(&setup, 0.0).unwrap();
    let ContactLaw::SpringDashpot {
        stiffness_n_m,
        damping_n_s_m,
    } = setup.params.contact
    else {
        panic!("the wire rig's law is Table 3.1's")
    };
    let mean = vec![stiffness_n_m.ln(), damping_n_s_m.ln()];
    let table = UncertaintyTable {
        law: ContactLawKind::SpringDashpot,
        coordinates: coordinate_names(ContactLawKind::SpringDashpot)
            .iter()
            .map(|c| c.to_string())
            .collect(),
        mean: mean.clone(),
        covariance: vec![vec![0.0; 2]; 2],
        method: None,
        lack_of_fit: None,
    };
    table.validate(&setup.params).unwrap();
    let p = propagate(&setup, 0.0, &table, &nominal, 8, 1).unwrap();
    // The one law drawn, and its answers.
    let mut drawn = setup.clone();
    drawn.params.contact = ContactLaw::SpringDashpot {
        stiffness_n_m: mean[0].exp(),
        damping_n_s_m: mean[1].exp(),
    };
    let (answer, response) = compute(&drawn, 0.0).unwrap();
    assert_eq!((p.draws, p.no_selection), (8, 0));
    for (spread, value) in [
        (p.freq_hz, answer.freq_hz),
        (p.impact_force_mg, answer.impact_force_mg),
    ] {
        assert_eq!(
            [spread.lo95, spread.median, spread.hi95],
            [value; 3],
            "{spread:?}"
        );
    }
    assert_eq!(p.nominal_one_one_share, 1.0);
    let strongest = response
        .iter()
        .enumerate()
        .filter(|(_, r)| r.regime == shared::observe::Regime::ONE_ONE)
        .reduce(|a, b| {
            if b.1.impact_force_mg > a.1.impact_force_mg {
                b
            } else {
                a
            }
        })
        .unwrap();
    let robust = p.robust.expect("a frequency 1/1 in every draw");
    let ratio = setup.selection.omega_ratio.value(strongest.0);
    assert_eq!(robust.omega_ratio, ratio);
    assert_eq!(robust.worst_impact_force_mg, strongest.1.impact_force_mg);
    assert_eq!(robust.median_impact_force_mg, strongest.1.impact_force_mg);
}

//! The identified parameters' uncertainty, checked against known truth:
//! - coverage: over 40 noise seeds of a synthetic drop test (the plant simulation at finer
//!   steps than the fit's, 1 % noise, 0.5 N offset), the 95 % intervals contain the true value
//!   of every parameter in 85–100 % of the seeds — spring–dashpot (Table 3.1) and Hunt–Crossley
//!   (Fig. 3.3), peaks and profile errors; the same for the free decay's `f_n` and `ζ` (the analytic
//!   oscillator, and a simulated decay of the damped wire pendulum); and the
//!   lack-of-fit note stays silent on at least 95 % of those seeds;
//! - the wrong law (Hunt–Crossley data fitted with the spring–dashpot law, 3 mm and 1 mm, 40
//!   seeds each): the lack-of-fit note fires on every seed, and the intervals hold the centre
//!   of the estimates' spread over the seeds in at least 85 % of them (the noise-only ones do
//!   not at 1 mm);
//! - the identifiability notes say what docs/identification.md says: Hertz `(k, n)` and the
//!   power laws' `k_i` are not fixed by one release height, spring–dashpot is by two;
//! - propagation to the main job: ±5 % on Table 3.1's `k_i` and `c_i` gives a 95 % range of
//!   the operating frequency that contains `select`'s nominal answer.

use host_sim::config::{Setup, UncertaintyTable, coordinate_names};
use host_sim::identify::cost::{DropTest, Weights};
use host_sim::identify::fit::{Fit, fit_law, fit_law_joint};
use host_sim::identify::free::identify_free;
use host_sim::identify::synth::{
    LabDrop, Recorded, TRUTH_STEPS, clean_record, record_displacement,
};
use host_sim::identify::uncertainty::IntervalMethod;
use host_sim::propagate::propagate;
use host_sim::selection::compute;
use host_sim::stats::Z95;
use host_sim::trace::Trace;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use shared::analysis::drop::DropSpec;
use shared::model::{ContactLaw, ContactLawKind, RigId};

const PEAKS: Weights = Weights::PEAKS;
const PROFILE: Weights = Weights::PROFILE;
/// Noise seeds of the coverage tests.
const SEEDS: std::ops::RangeInclusive<u64> = 1..=40;

/// The [`LabDrop`] of `law` released `release_mm`, measured with noise seed `seed`.
fn lab_test(law: ContactLaw, release_mm: f64, seed: u64) -> DropTest {
    let lab = LabDrop { law, release_mm };
    lab.measured(&lab.clean().unwrap(), seed).unwrap()
}

/// The true value of the parameter `key` (a [`ContactLaw`] field name) of `law`.
fn truth_of(law: &ContactLaw, key: &str) -> f64 {
    match (*law, key) {
        (ContactLaw::SpringDashpot { stiffness_n_m, .. }, "stiffness_n_m") => stiffness_n_m,
        (ContactLaw::SpringDashpot { damping_n_s_m, .. }, "damping_n_s_m") => damping_n_s_m,
        (
            ContactLaw::Hertz { stiffness, .. }
            | ContactLaw::HuntCrossley { stiffness, .. }
            | ContactLaw::LankaraniNikravesh { stiffness, .. },
            "stiffness",
        ) => stiffness,
        (
            ContactLaw::Hertz { exponent, .. }
            | ContactLaw::HuntCrossley { exponent, .. }
            | ContactLaw::LankaraniNikravesh { exponent, .. },
            "exponent",
        ) => exponent,
        (ContactLaw::HuntCrossley { lambda_s_m, .. }, "lambda_s_m") => lambda_s_m,
        (ContactLaw::LankaraniNikravesh { restitution, .. }, "restitution") => restitution,
        _ => panic!("{law:?} has no parameter {key}"),
    }
}

/// The fits of `law` to the drops of `truth` released `release_mm` with noise seeds `seeds`.
fn fits(
    truth: ContactLaw,
    law: ContactLawKind,
    release_mm: f64,
    weights: Weights,
    seeds: std::ops::RangeInclusive<u64>,
) -> Vec<Fit> {
    let lab = LabDrop {
        law: truth,
        release_mm,
    };
    let trace = lab.clean().unwrap();
    seeds
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&seed| {
            let t = lab.measured(&trace, seed).unwrap();
            fit_law(&t.setup, &t.data, law, weights, 400).unwrap()
        })
        .collect()
}

/// Per parameter key: in how many of `fits` the 95 % interval contains `value(key)`.
fn hits(fits: &[Fit], value: impl Fn(&str) -> f64) -> Vec<(&'static str, usize)> {
    let u0 = fits[0].uncertainty.as_ref().unwrap();
    u0.params
        .iter()
        .enumerate()
        .map(|(i, p0)| {
            let v = value(p0.key);
            let n = fits
                .iter()
                .filter(|f| {
                    let p = &f.uncertainty.as_ref().unwrap().params[i];
                    p.ci95[0] <= v && v <= p.ci95[1]
                })
                .count();
            (p0.key, n)
        })
        .collect()
}

/// Coverage of the truth in 85–100 % of the one-height (3 mm) fits of `truth` with `weights`
/// over `seeds`, and the lack-of-fit note silent on at least 95 % of them.
fn assert_coverage(
    truth: ContactLaw,
    weights: Weights,
    what: &str,
    seeds: std::ops::RangeInclusive<u64>,
) {
    let fits = fits(truth, truth.kind(), 3.0, weights, seeds);
    let n = fits.len();
    let c = hits(&fits, |key| truth_of(&truth, key));
    assert_eq!(c.len(), coordinate_names(truth.kind()).len());
    for (key, hits) in c {
        // 85–100 %: at least 34 of 40.
        assert!(
            hits * 100 >= 85 * n,
            "{what}: the 95 % interval of {key} holds the truth in {hits} of {n} seeds"
        );
    }
    let flagged: Vec<f64> = fits
        .iter()
        .map(|f| &f.uncertainty.as_ref().unwrap().fit_check)
        .filter(|c| c.misses)
        .filter_map(|c| c.headline_ratio())
        .collect();
    assert!(
        flagged.len() * 100 <= 5 * n,
        "{what}: the right law flagged for lack of fit on {} of {n} seeds ({flagged:?})",
        flagged.len()
    );
}

#[test]
fn spring_dashpot_intervals_cover_the_truth() {
    for (weights, what) in [(PEAKS, "peaks"), (PROFILE, "profile")] {
        assert_coverage(ContactLaw::identified(), weights, what, SEEDS);
    }
}

#[test]
fn hunt_crossley_intervals_cover_the_truth() {
    let truth = ContactLaw::preset(ContactLawKind::HuntCrossley);
    assert_coverage(truth, PEAKS, "peaks", SEEDS);
    // The profile with the impact times: 35, 35 and 36 of 40 (k_i, n, λ_i). With the first 100
    // noise redraws alone, 33, 33 and 35: that set of redraws gives n a spread of 0.00326 where
    // 2,000 give 0.00395, and every fit shares it (docs/identification.md).
    assert_coverage(truth, PROFILE, "profile", SEEDS);
}

#[test]
fn the_wrong_law_is_flagged_and_its_intervals_cover_how_the_fit_moves() {
    // Hunt–Crossley data (Fig. 3.3) fitted with the spring–dashpot law: the fit misses the
    // pulses' shape (residual ~13× the noise); its parameters depend on the drop (k_i 4.9e5 at
    // 3 mm, 3.0e5 at 1 mm), and over the noise seeds they spread by more than the noise alone
    // explains.
    let truth = ContactLaw::preset(ContactLawKind::HuntCrossley);
    for release_mm in [3.0, 1.0] {
        let fits = fits(
            truth,
            ContactLawKind::SpringDashpot,
            release_mm,
            PROFILE,
            SEEDS,
        );
        let n = fits.len();
        for f in &fits {
            let u = f.uncertainty.as_ref().unwrap();
            assert!(u.fit_check.misses, "{release_mm} mm: {:?}", u.fit_check);
            assert!(
                u.notes[0].contains("does not fit these data"),
                "{:?}",
                u.notes
            );
            assert!(u.fit_check.ratio > 5.0, "{:?}", u.fit_check);
        }
        // The centre of the estimates' spread over the seeds.
        let median = |key: &str| {
            let mut v: Vec<f64> = fits
                .iter()
                .map(|f| match f.law {
                    ContactLaw::SpringDashpot {
                        stiffness_n_m,
                        damping_n_s_m,
                    } => {
                        if key == "stiffness_n_m" {
                            stiffness_n_m
                        } else {
                            damping_n_s_m
                        }
                    }
                    _ => unreachable!(),
                })
                .collect();
            v.sort_by(f64::total_cmp);
            v[n / 2]
        };
        let scaled = hits(&fits, median);
        let noise_only: Vec<Fit> = fits
            .iter()
            .map(|f| {
                let mut g = f.clone();
                g.uncertainty = Ok(f
                    .uncertainty
                    .as_ref()
                    .unwrap()
                    .with_intervals(IntervalMethod::Noise));
                g
            })
            .collect();
        let noise = hits(&noise_only, median);
        for ((key, h), (_, h_noise)) in scaled.iter().zip(&noise) {
            assert!(
                h * 100 >= 85 * n,
                "{release_mm} mm: {key} centre in {h} of {n} intervals (noise only {h_noise})"
            );
            assert!(h >= h_noise, "{release_mm} mm: {key} {h} vs {h_noise}");
        }
        if release_mm == 1.0 {
            // The noise alone explains too little of how k_i moves: 24 of 40.
            assert!(noise[0].1 * 100 < 85 * n, "{noise:?}");
        }
    }
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

/// Free decay `A e^{-ζωt} cos(ω_d t)` (displacement).
fn damped(t: f64, fn_hz: f64, zeta: f64, amp: f64) -> f64 {
    let wn = 2.0 * std::f64::consts::PI * fn_hz;
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    amp * (-zeta * wn * t).exp() * (wd * t).cos()
}

#[test]
fn free_decay_intervals_cover_the_truth() {
    let (fn_hz, zeta, amp) = (4.5, 0.004, 1e-3);
    let t_s: Vec<f64> = (0..20_000).map(|i| i as f64 / 1000.0).collect();
    let clean: Vec<f64> = t_s.iter().map(|&t| damped(t, fn_hz, zeta, amp)).collect();
    let hits: Vec<(bool, bool)> = SEEDS
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&seed| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let noise = Normal::new(0.0, 0.01 * amp).unwrap();
            let value = clean
                .iter()
                .map(|x| x + 0.05 * amp + noise.sample(&mut rng))
                .collect();
            let d = identify_free(&Trace {
                t_s: t_s.clone(),
                value,
            })
            .unwrap();
            let [f0, f1] = d.natural_freq_ci95_hz;
            let [z0, z1] = d.damping_ratio_ci95;
            // The intervals are the estimate ± 1.96 σ, not wider than the estimate allows.
            assert!(f0 < d.natural_freq_hz && d.natural_freq_hz < f1, "{d:?}");
            assert!(z0 < d.damping_ratio && d.damping_ratio < z1, "{d:?}");
            assert!((f1 - f0) / fn_hz < 1e-3, "{d:?}");
            ((f0..=f1).contains(&fn_hz), (z0..=z1).contains(&zeta))
        })
        .collect();
    let n = hits.len();
    let f_hits = hits.iter().filter(|h| h.0).count();
    let z_hits = hits.iter().filter(|h| h.1).count();
    assert!(f_hits * 100 >= 85 * n, "f_n: {f_hits} of {n}");
    assert!(z_hits * 100 >= 85 * n, "ζ: {z_hits} of {n}");
}

#[test]
fn wire_rig_free_decay_intervals_cover_the_damped_pendulum() {
    // The damped wire rig (ζ = 0.003, the project's viscous term) released at rest 0.15 mm
    // (θ0 = 0.002 rad) from its rest position with the surface 10 mm away: a free decay of the
    // model (the drop test's integrator at the synthetic records' 512 steps per period, no
    // closed form), u(t) at 1 kHz for 20 s, then 1 % noise and a 0.01 mm offset per seed. The
    // small-angle truth is f_n = sqrt(g/l)/2π and ζ; the pendulum's amplitude-dependent
    // frequency (−θ0²/16 = −2.5e-7 relative) stays well inside the f_n interval (±3e-6).
    let zeta = 0.003;
    let params = RigId::Wires.preset().with_damping_ratio(zeta);
    let spec = DropSpec {
        gap_m: 10e-3,
        release_m: 10.15e-3,
        duration_s: 20.0,
        max_impacts: 0,
    };
    let clean = clean_record(&params, &spec, &TRUTH_STEPS, 1000.0, Recorded::Displacement).unwrap();
    let fn_hz = params.natural_freq_hz();
    let hits: Vec<(bool, bool)> = SEEDS
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&seed| {
            let trace = record_displacement(&clean, 1.0, 1e-5, seed).unwrap();
            let d = identify_free(&trace).unwrap();
            let [f0, f1] = d.natural_freq_ci95_hz;
            let [z0, z1] = d.damping_ratio_ci95;
            assert!(z0 < d.damping_ratio && d.damping_ratio < z1, "{d:?}");
            // ζ to a few percent, f_n to 1e-5, the length l = g/ω² to 2e-5.
            assert!((d.damping_ratio / zeta - 1.0).abs() < 0.05, "{d:?}");
            assert!((d.natural_freq_hz / fn_hz - 1.0).abs() < 1e-5, "{d:?}");
            assert!((d.pendulum_length_m(params.gravity_m_s2) / 0.075 - 1.0).abs() < 2e-5);
            ((f0..=f1).contains(&fn_hz), (z0..=z1).contains(&zeta))
        })
        .collect();
    let n = hits.len();
    let f_hits = hits.iter().filter(|h| h.0).count();
    let z_hits = hits.iter().filter(|h| h.1).count();
    println!("wires ζ {zeta}: f_n covered {f_hits} of {n}, ζ {z_hits} of {n}");
    assert!(f_hits * 100 >= 85 * n, "f_n: {f_hits} of {n}");
    assert!(z_hits * 100 >= 85 * n, "ζ: {z_hits} of {n}");
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
    assert!(p.freq_hz.lo95 <= p.freq_hz.median && p.freq_hz.median <= p.freq_hz.hi95);
    // The nominal answer is 1/1 in most draws, and the robust point is 1/1 in all of them
    // with a worst case no better than the nominal F_i/mg.
    assert!(p.nominal_one_one_share >= 0.9, "{p:?}");
    let robust = p.robust.expect("a frequency 1/1 in every draw");
    assert!(robust.worst_impact_force_mg <= robust.median_impact_force_mg);
    let at = p
        .band
        .iter()
        .find(|b| (b.freq_hz - robust.freq_hz).abs() < 1e-9)
        .unwrap();
    assert_eq!(at.one_one_share, 1.0);
    assert_eq!(p.band.len(), setup.selection.omega_ratio.len());
}

//! The identified parameters' coverage over noise seeds, shared by the suite
//! (`tests/uncertainty.rs`, a few seeds: each seed's intervals) and the full sweep over seeds
//! 1–40 (`examples/coverage.rs`): the 95 % intervals hold the truth in 85–100 % of the seeds.

#![allow(dead_code)]

use std::ops::RangeInclusive;

use host_sim::config::coordinate_names;
use host_sim::identify::cost::Weights;
use host_sim::identify::fit::{Fit, fit_law};
use host_sim::identify::free::identify_free;
use host_sim::identify::synth::{
    LabDrop, Recorded, TRUTH_STEPS, clean_record, record_displacement,
};
use host_sim::identify::uncertainty::IntervalMethod;
use host_sim::trace::Trace;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use shared::analysis::drop::DropSpec;
use shared::model::{ContactLaw, ContactLawKind, RigId};

/// The noise seeds of the full sweep.
pub const ALL_SEEDS: RangeInclusive<u64> = 1..=40;

/// Whether 95 % intervals that hold the truth in `hits` of `n` seeds cover it: in 85–100 % of
/// them (at least 34 of 40); of a few seeds (fewer than 20), in all but one (an interval misses
/// about one seed in twenty, Hunt–Crossley's profile one in eight); of the suite's one seed, in
/// that seed.
pub fn covers(hits: usize, n: usize) -> bool {
    match n {
        20.. => hits * 100 >= 85 * n,
        2.. => hits + 1 >= n,
        _ => hits == n,
    }
}

/// The true value of the parameter `key` (a [`ContactLaw`] field name) of `law`.
pub fn truth_of(law: &ContactLaw, key: &str) -> f64 {
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
pub fn fits(
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
pub fn hits(fits: &[Fit], value: impl Fn(&str) -> f64) -> Vec<(&'static str, usize)> {
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
/// over `seeds` (of fewer than 20 seeds, in all but one), and the lack-of-fit note silent on
/// at least 95 % of them.
pub fn assert_coverage(
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
        assert!(
            covers(hits, n),
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

/// Hunt–Crossley data (Fig. 3.3) released `release_mm` fitted with the spring–dashpot law over
/// `seeds`: the fit misses the pulses' shape (residual ~13× the noise) and says so on every
/// seed. With `spread` (many seeds): its parameters depend on the drop (`k_i` 4.9e5 at 3 mm,
/// 3.0e5 at 1 mm) and over the seeds they spread by more than the noise alone explains, which
/// the intervals (scaled by the misfit) cover: they hold the centre of the estimates' spread in
/// 85–100 % of the seeds, at least as often as the noise-only ones, which at 1 mm hold it in
/// fewer than 85 % for `k_i`.
pub fn assert_wrong_law(release_mm: f64, seeds: RangeInclusive<u64>, spread: bool) {
    let truth = ContactLaw::preset(ContactLawKind::HuntCrossley);
    let fits = fits(
        truth,
        ContactLawKind::SpringDashpot,
        release_mm,
        Weights::PROFILE,
        seeds,
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
    if !spread {
        return;
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
                other => panic!("not a spring–dashpot fit: {other:?}"),
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

/// Free decay `A e^{-ζωt} cos(ω_d t)` (displacement).
fn damped(t: f64, fn_hz: f64, zeta: f64, amp: f64) -> f64 {
    let wn = 2.0 * std::f64::consts::PI * fn_hz;
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    amp * (-zeta * wn * t).exp() * (wd * t).cos()
}

/// The free decay of an analytic oscillator (`f_n` 4.5 Hz, `ζ` 0.004, 20 s at 1 kHz, 1 %
/// noise and a 5 % offset per seed): over `seeds`, the 95 % intervals of `f_n` and `ζ` hold
/// the truth in 85–100 % of them.
pub fn assert_free_decay_coverage(seeds: RangeInclusive<u64>) {
    let (fn_hz, zeta, amp) = (4.5, 0.004, 1e-3);
    let t_s: Vec<f64> = (0..20_000).map(|i| i as f64 / 1000.0).collect();
    let clean: Vec<f64> = t_s.iter().map(|&t| damped(t, fn_hz, zeta, amp)).collect();
    let hits: Vec<(bool, bool)> = seeds
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
    assert!(covers(f_hits, n), "f_n: {f_hits} of {n}");
    assert!(covers(z_hits, n), "ζ: {z_hits} of {n}");
}

/// The free decay of the damped wire rig's model (below): over `seeds`, the 95 % intervals of
/// `f_n` and `ζ` hold the truth in 85–100 % of them.
pub fn assert_wire_rig_free_decay_coverage(seeds: RangeInclusive<u64>) {
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
    let hits: Vec<(bool, bool)> = seeds
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
    assert!(covers(f_hits, n), "f_n: {f_hits} of {n}");
    assert!(covers(z_hits, n), "ζ: {z_hits} of {n}");
}

//! What a drop test identifies, measured: synthetic drop tests of known laws (the plant
//! simulation at finer steps than the fit's, 1.2 s at 50 kHz, 1 % noise, 0.5 N offset, wire rig)
//! fitted by `identify contact`'s code.
//!
//! - Recovery: the worst relative error over noise seeds 1–16 of each parameter, one release
//!   height (3 mm) and two (0.25 mm and 3 mm, fitted jointly), peaks and profile errors.
//! - Coverage: in how many of noise seeds 1–40 the 95 % interval holds the truth (one 3 mm drop),
//!   and on how many the lack-of-fit note fires.
//! - The wrong law: Hunt–Crossley drops fitted with the spring–dashpot law, 3, 1 and 0.25 mm:
//!   the lack-of-fit note, and how often the intervals hold the centre of the estimates' spread.
//!
//! `cargo run --release -p host-sim --example recovery` (about 15 minutes on 2 cores); the tables
//! of docs/identification.md. `-- recovery`, `-- coverage` or `-- wrong-law` runs one part.

use host_sim::identify::cost::{DropTest, Weights};
use host_sim::identify::fit::{Fit, fit_law_joint};
use host_sim::identify::synth::LabDrop;
use host_sim::identify::uncertainty::IntervalMethod;
use host_sim::trace::Trace;
use rayon::prelude::*;
use shared::model::{ContactLaw, ContactLawKind};

const PEAKS: Weights = Weights::PEAKS;
const PROFILE: Weights = Weights::PROFILE;
/// Reference penetration of the power laws' force `k δ_ref^n`, m.
const DELTA_REF_M: f64 = 1e-5;

/// The [`LabDrop`] of `law` released `release_mm`.
fn lab(law: ContactLaw, release_mm: f64) -> LabDrop {
    LabDrop { law, release_mm }
}

/// The law's parameters by name, plus `k δ_ref^n` for the power laws.
fn params(law: &ContactLaw) -> Vec<(&'static str, f64)> {
    match *law {
        ContactLaw::SpringDashpot {
            stiffness_n_m,
            damping_n_s_m,
        } => vec![("k_i", stiffness_n_m), ("c_i", damping_n_s_m)],
        ContactLaw::Hertz {
            stiffness,
            exponent,
        } => vec![
            ("k_i", stiffness),
            ("n", exponent),
            ("k_i δ_ref^n", stiffness * DELTA_REF_M.powf(exponent)),
        ],
        ContactLaw::HuntCrossley {
            stiffness,
            exponent,
            lambda_s_m,
        } => vec![
            ("k_i", stiffness),
            ("n", exponent),
            ("k_i δ_ref^n", stiffness * DELTA_REF_M.powf(exponent)),
            ("λ_i", lambda_s_m),
        ],
        ContactLaw::LankaraniNikravesh {
            stiffness,
            exponent,
            restitution,
        } => vec![
            ("k_i", stiffness),
            ("n", exponent),
            ("k_i δ_ref^n", stiffness * DELTA_REF_M.powf(exponent)),
            ("e", restitution),
        ],
    }
}

/// The fit of `truth` to `traces` (release mm, clean trace) with noise seed `seed` (one
/// trace) or `10 seed + 1`, `10 seed` (two: 0.25 mm, then 3 mm: the seeds of the tests in
/// `host-sim/tests/all/identify.rs`).
fn fit(truth: ContactLaw, traces: &[(f64, &Trace)], seed: u64, weights: Weights) -> Fit {
    let tests: Vec<DropTest> = traces
        .iter()
        .map(|(h, c)| {
            let s = match (traces.len(), *h == 3.0) {
                (1, _) => seed,
                (_, true) => 10 * seed,
                (_, false) => 10 * seed + 1,
            };
            lab(truth, *h).measured(c, s).expect("impacts")
        })
        .collect();
    fit_law_joint(&tests, truth.kind(), weights, 400).expect("fit")
}

/// Worst relative error of each parameter over seeds 1–16.
fn worst(truth: ContactLaw, traces: &[(f64, &Trace)], weights: Weights) -> String {
    let errors: Vec<Vec<f64>> = (1..=16u64)
        .into_par_iter()
        .map(|seed| {
            let f = fit(truth, traces, seed, weights);
            params(&f.law)
                .iter()
                .zip(params(&truth))
                .map(|(a, b)| (a.1 / b.1 - 1.0).abs())
                .collect()
        })
        .collect();
    params(&truth)
        .iter()
        .enumerate()
        .map(|(i, (name, _))| {
            let w = errors.iter().map(|e| e[i]).fold(0.0, f64::max);
            format!("`{name}` {:.1} %", 100.0 * w)
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// One seed's fit in [`coverage`]: per parameter whether its interval holds the truth, whether
/// the lack-of-fit note fires, and the reduced χ² of the error as fitted.
struct SeedOutcome {
    holds: Vec<(&'static str, bool)>,
    misses: bool,
    ratio: f64,
}

/// In how many of seeds `seeds` each parameter's 95 % interval holds the truth, on how many
/// seeds the lack-of-fit note fires, and the range of the reduced χ² of the error as fitted.
fn coverage(
    truth: ContactLaw,
    trace: &Trace,
    weights: Weights,
    seeds: std::ops::RangeInclusive<u64>,
) -> String {
    let n = seeds.clone().count();
    let hits: Vec<SeedOutcome> = seeds
        .into_par_iter()
        .map(|seed| {
            let t = lab(truth, 3.0).measured(trace, seed).expect("impacts");
            let f =
                fit_law_joint(std::slice::from_ref(&t), truth.kind(), weights, 400).expect("fit");
            let u = f.uncertainty.expect("uncertainty");
            let p = params(&truth);
            let h = u
                .params
                .iter()
                .map(|q| {
                    let v = p.iter().find(|x| x.0 == q.name).expect("parameter").1;
                    (q.name, q.ci95[0] <= v && v <= q.ci95[1])
                })
                .collect();
            SeedOutcome {
                holds: h,
                misses: u.fit_check.misses,
                ratio: u.fit_check.ratio,
            }
        })
        .collect();
    let mut out: Vec<String> = (0..hits[0].holds.len())
        .map(|i| {
            let k = hits.iter().filter(|h| h.holds[i].1).count();
            format!("`{}` {k}/{n}", hits[0].holds[i].0)
        })
        .collect();
    let ratios = hits.iter().map(|h| h.ratio);
    out.push(format!(
        "lack of fit {}/{n} (reduced χ² {:.2}–{:.2})",
        hits.iter().filter(|h| h.misses).count(),
        ratios.clone().fold(f64::INFINITY, f64::min),
        ratios.fold(0.0, f64::max)
    ));
    out.join(", ")
}

/// Hunt–Crossley drops (Fig. 3.3) released `release_mm` fitted with the spring–dashpot law over
/// seeds 1–40: the flagged seeds, the reduced χ² range, and for `k_i`, `c_i` the spread over the
/// seeds and in how many seeds the scaled (and the noise-only) interval holds the median.
fn wrong_law(release_mm: f64, weights: Weights) -> String {
    let truth = ContactLaw::preset(ContactLawKind::HuntCrossley);
    let clean = lab(truth, release_mm).clean().expect("valid drop");
    let fits: Vec<Fit> = (1..=40u64)
        .into_par_iter()
        .map(|seed| {
            let t = lab(truth, release_mm)
                .measured(&clean, seed)
                .expect("impacts");
            fit_law_joint(
                std::slice::from_ref(&t),
                ContactLawKind::SpringDashpot,
                weights,
                400,
            )
            .expect("fit")
        })
        .collect();
    let ratios: Vec<f64> = fits
        .iter()
        .map(|f| f.uncertainty.as_ref().expect("uncertainty").fit_check.ratio)
        .collect();
    let flagged = fits
        .iter()
        .filter(|f| {
            f.uncertainty
                .as_ref()
                .expect("uncertainty")
                .fit_check
                .misses
        })
        .count();
    let mut s = format!(
        "| {release_mm} mm | {flagged}/40 | {:.1}–{:.1} |",
        ratios.iter().copied().fold(f64::INFINITY, f64::min),
        ratios.iter().copied().fold(0.0, f64::max)
    );
    for (i, name) in ["k_i", "c_i"].iter().enumerate() {
        let mut v: Vec<f64> = fits.iter().map(|f| params(&f.law)[i].1).collect();
        v.sort_by(f64::total_cmp);
        let centre = v[v.len() / 2];
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt();
        let holds = |method| {
            fits.iter()
                .filter(|f| {
                    let u = f
                        .uncertainty
                        .as_ref()
                        .expect("uncertainty")
                        .with_intervals(method);
                    u.params[i].ci95[0] <= centre && centre <= u.params[i].ci95[1]
                })
                .count()
        };
        // The intervals' median half-width, % of the value.
        let width = |method| {
            let mut w: Vec<f64> = fits
                .iter()
                .map(|f| {
                    let u = f.uncertainty.as_ref().expect("uncertainty");
                    u.with_intervals(method).params[i].rel_half_width()
                })
                .collect();
            w.sort_by(f64::total_cmp);
            100.0 * w[w.len() / 2]
        };
        s.push_str(&format!(
            " `{name}` {centre:.4e}, spread {:.2} %: {}/40 (±{:.2} %) (noise only {}/40, ±{:.2} %) |",
            100.0 * sd / mean,
            holds(IntervalMethod::Scaled),
            width(IntervalMethod::Scaled),
            holds(IntervalMethod::Noise),
            width(IntervalMethod::Noise)
        ));
    }
    s
}

/// A row group of the recovery table: name, true law, the errors fitted.
type Case = (&'static str, ContactLaw, Vec<(&'static str, Weights)>);

fn main() {
    // `recovery`, `coverage` or `wrong-law` runs that part alone; no argument, all three.
    const PARTS: [&str; 3] = ["recovery", "coverage", "wrong-law"];
    let part = std::env::args().nth(1);
    if let Some(p) = part.as_deref().filter(|p| !PARTS.contains(p)) {
        eprintln!("error: unknown part `{p}`: allowed {}", PARTS.join(", "));
        std::process::exit(2);
    }
    let runs = |name: &str| part.as_deref().is_none_or(|p| p == name);
    // The table's rows, law by law (the spring–dashpot first, then `ContactLawKind::ALL`'s
    // order): a law added there needs its cases here.
    let mut kinds = ContactLawKind::ALL;
    kinds.sort_by_key(|k| *k != ContactLawKind::SpringDashpot);
    let cases: Vec<Case> = kinds.into_iter().flat_map(cases_of).collect();
    if runs("recovery") {
        recovery(&cases);
    }
    if runs("coverage") {
        coverages();
    }
    if runs("wrong-law") {
        println!(
            "The wrong law: Hunt–Crossley (Fig. 3.3) drops fitted with the spring–dashpot law"
        );
        println!("| release | flagged | reduced χ² | `k_i` | `c_i` |");
        println!("|---|---|---|---|---|");
        for release_mm in [3.0, 1.0, 0.25] {
            println!("{}", wrong_law(release_mm, PROFILE));
        }
    }
}

/// The recovery table's cases of one law: name, true law, the errors fitted.
fn cases_of(kind: ContactLawKind) -> Vec<Case> {
    let both = || vec![("peaks", PEAKS), ("profile", PROFILE)];
    match kind {
        ContactLawKind::SpringDashpot => vec![
            (
                "spring–dashpot, Table 3.1 (5.5e6, 1.2e3)",
                ContactLaw::identified(),
                both(),
            ),
            (
                "spring–dashpot (4.0e6, 900)",
                ContactLaw::SpringDashpot {
                    stiffness_n_m: 4.0e6,
                    damping_n_s_m: 900.0,
                },
                both(),
            ),
        ],
        ContactLawKind::Hertz => vec![(
            "Hertz (1e9, n = 1.5)",
            ContactLaw::Hertz {
                stiffness: 1e9,
                exponent: 1.5,
            },
            vec![("profile", PROFILE)],
        )],
        ContactLawKind::HuntCrossley => vec![(
            "Hunt–Crossley (1e9, 1.5, λ = 10 s/m)",
            ContactLaw::HuntCrossley {
                stiffness: 1e9,
                exponent: 1.5,
                lambda_s_m: 10.0,
            },
            both(),
        )],
        ContactLawKind::LankaraniNikravesh => vec![(
            "Lankarani–Nikravesh (1e9, 1.5, e = 0.5)",
            ContactLaw::LankaraniNikravesh {
                stiffness: 1e9,
                exponent: 1.5,
                restitution: 0.5,
            },
            both(),
        )],
    }
}

/// The recovery table: worst relative errors over seeds 1–16.
fn recovery(cases: &[Case]) {
    println!("Recovery: worst relative error over noise seeds 1–16");
    println!("| law (truth) | error | one height (3 mm) | two heights (0.25 + 3 mm, joint) |");
    println!("|---|---|---|---|");
    for (name, law, errors) in cases {
        let c3 = lab(*law, 3.0).clean().expect("valid drop");
        let c025 = lab(*law, 0.25).clean().expect("valid drop");
        for (i, (error, w)) in errors.iter().enumerate() {
            println!(
                "| {} | {error} | {} | {} |",
                if i == 0 { *name } else { "" },
                worst(*law, &[(3.0, &c3)], *w),
                worst(*law, &[(0.25, &c025), (3.0, &c3)], *w)
            );
        }
    }
    println!();
}

/// The coverage table: seeds 1–40, and Hunt–Crossley's profile over 160.
fn coverages() {
    println!("Coverage of the 95 % intervals over noise seeds 1–40 (one 3 mm drop)");
    println!("| law (truth) | peaks | profile |");
    println!("|---|---|---|");
    for (name, law) in [
        ("spring–dashpot, Table 3.1", ContactLaw::identified()),
        (
            "Hunt–Crossley, Fig. 3.3 (2.1e8, 1.6, λ = 0.6 s/m)",
            ContactLaw::preset(ContactLawKind::HuntCrossley),
        ),
    ] {
        let c3 = lab(law, 3.0).clean().expect("valid drop");
        println!(
            "| {name} | {} | {} |",
            coverage(law, &c3, PEAKS, 1..=40),
            coverage(law, &c3, PROFILE, 1..=40)
        );
    }
    let hc = ContactLaw::preset(ContactLawKind::HuntCrossley);
    let c3 = lab(hc, 3.0).clean().expect("valid drop");
    println!(
        "Hunt–Crossley, profile, seeds 1–160: {}",
        coverage(hc, &c3, PROFILE, 1..=160)
    );
    println!();
}

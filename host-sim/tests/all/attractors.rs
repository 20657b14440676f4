//! Attractors, basins and basin fractions (`basins`, `fractions`, `select`'s basin check)
//! against independent computations: the beam rig's hysteresis at 3.0 mm (two coexisting
//! attractors exactly where sweeps from the previous state say both branches exist), two seeds,
//! the grid basin against random sampling, the start-up basin of the main job; bad input
//! rejected with its field and range, nothing written.
//!
//! `cargo test --release -p host-sim --test all attractors:: -- --nocapture` prints the measured values.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::Vector2;
use shared::analysis::SimSettings;
use shared::model::RigId;
use shared::orbit::{MapPoint, Param, ShootSettings, iterate, orbit_from};

use crate::common;

use common::{Outputs, line, ok, rejected, said};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// One row of a fractions CSV.
#[derive(Debug, Clone, serde::Deserialize)]
struct Row {
    omega_ratio: f64,
    attractor: String,
    regime: String,
    fraction: f64,
    ci95_lo: f64,
    ci95_hi: f64,
}

fn read(path: &Path) -> Vec<Row> {
    csv::Reader::from_path(path)
        .unwrap()
        .deserialize()
        .map(Result::unwrap)
        .collect()
}

/// The attractors (not the group without one) at each `Ω/ω`, keyed by Ω/ω in thousandths.
fn by_point(rows: &[Row]) -> BTreeMap<i64, Vec<Row>> {
    let mut m: BTreeMap<i64, Vec<Row>> = BTreeMap::new();
    for r in rows.iter().filter(|r| r.attractor != "-") {
        m.entry((r.omega_ratio * 1e3).round() as i64)
            .or_default()
            .push(r.clone());
    }
    m
}

const BOX: [&str; 4] = ["--u0-mm", "-6:3", "--v0-mm-s", "-300:300"];

/// `fractions` on the beam rig (170 mm) at 3.0 mm over `omega` in the box [`BOX`].
fn fractions(dir: &Path, name: &str, omega: &str, samples: u32, seed: u64) -> Vec<Row> {
    let out = dir.join(format!("{name}.csv"));
    let mut args = line(&format!(
        "fractions --rig beam-170 --gap-mm 3.0 --omega-ratio {omega} --samples {samples} \
         --seed {seed} --max-periods 1500 --out {}",
        s(&out)
    ));
    args.extend(BOX.iter().map(|a| a.to_string()));
    ok(&args);
    read(&out)
}

/// `periods` iterations of the map from `x`: whether every period had `p` impacts, and the
/// state reached.
fn run_map(at: &MapPoint, x: Vector2<f32>, periods: u32, p: u32) -> (bool, Vector2<f32>) {
    let mut x = x;
    for _ in 0..periods {
        let img = iterate::<f32>(at, 1, x).unwrap();
        if img.trace.impacts != p {
            return (false, img.x);
        }
        x = img.x;
    }
    (true, x)
}

/// A sweep of `Ω/ω` over `values` (each starting where the previous one ended) from the orbit
/// the protocol settles on from rest at `values[0]`: the last value whose `periods` periods all
/// had `p` impacts.
fn sweep_end(at: &MapPoint, values: &[f64], periods: u32, p: u32) -> f64 {
    let first = at.with(Param::OmegaRatio, values[0]);
    let (_, orbit) =
        orbit_from::<f32>(&first, 0.0, 0.0, None, &ShootSettings::for_type::<f32>()).unwrap();
    let mut x = orbit.x;
    let mut last = f64::NAN;
    for &v in values {
        let (same, nx) = run_map(&at.with(Param::OmegaRatio, v), x, periods, p);
        if !same {
            return last;
        }
        last = v;
        x = nx;
    }
    last
}

#[test]
fn beam_hysteresis_has_two_attractors_inside_one_outside_with_the_sweeps_ends() {
    let dir = tempfile::tempdir().unwrap();
    let rows = fractions(dir.path(), "f", "1.15:1.55:0.01", 4000, 1);
    let points = by_point(&rows);
    assert_eq!(points.len(), 41);
    let mut two = Vec::new();
    for (k, list) in &points {
        let regimes: Vec<&str> = list.iter().map(|r| r.regime.as_str()).collect();
        println!(
            "Ω/ω {:.2}: {}",
            *k as f64 / 1e3,
            list.iter()
                .map(|r| format!("{} {} {:.4}", r.attractor, r.regime, r.fraction))
                .collect::<Vec<_>>()
                .join(", ")
        );
        if list.len() >= 2 {
            // Inside: exactly the impacting 1/1 orbit and the non-impacting one (a start caught
            // by the fold's slow passage may add a rare third: not at these points).
            assert_eq!(list.len(), 2, "Ω/ω {k}: {regimes:?}");
            assert!(
                regimes.contains(&"1/1") && regimes.contains(&"no impact"),
                "{regimes:?}"
            );
            for r in list {
                assert!(r.fraction > 0.0 && r.fraction < 1.0, "{r:?}");
            }
            two.push(*k as f64 / 1e3);
        } else {
            assert_eq!(list.len(), 1, "Ω/ω {k}");
        }
    }
    // One coexistence interval, and each attractor keeps its id along it.
    let (lo, hi) = (two[0], *two.last().unwrap());
    assert_eq!(
        two.len(),
        ((hi - lo) / 0.01).round() as usize + 1,
        "{two:?}"
    );
    for regime in ["1/1", "no impact"] {
        let ids: std::collections::BTreeSet<&str> = rows
            .iter()
            .filter(|r| r.regime == regime && (lo - 1e-9..=hi + 1e-9).contains(&r.omega_ratio))
            .map(|r| r.attractor.as_str())
            .collect();
        assert_eq!(ids.len(), 1, "{regime}: {ids:?}");
    }

    // Independent: sweeps of the stroboscopic map from the previous state, step 0.01 — up
    // from the 1/1 orbit at 1.35 (1000 periods per value: the passage past the fold's ghost is
    // slow), down from the non-impacting orbit at 1.70.
    let at = MapPoint {
        params: RigId::Beam170.preset(),
        settings: SimSettings::default(),
        gap_m: 3.0e-3,
        omega_ratio: 1.35,
    };
    let up: Vec<f64> = (0..=25).map(|k| 1.35 + 0.01 * f64::from(k)).collect();
    let down: Vec<f64> = (0..=55).map(|k| 1.70 - 0.01 * f64::from(k)).collect();
    let last_up = sweep_end(&at, &up, 1000, 1);
    let last_down = sweep_end(&at, &down, 300, 0);
    println!(
        "coexistence from the fractions {lo:.2} – {hi:.2}; sweeps: 1/1 up to {last_up:.2}, \
         no impact down to {last_down:.2}"
    );
    assert!((lo - last_down).abs() <= 0.01 + 1e-9, "{lo} vs {last_down}");
    assert!((hi - last_up).abs() <= 0.01 + 1e-9, "{hi} vs {last_up}");
}

#[test]
fn two_seeds_and_the_grid_basin_agree_within_the_intervals() {
    let dir = tempfile::tempdir().unwrap();
    let a = fractions(dir.path(), "a", "1.44", 2000, 1);
    let b = fractions(dir.path(), "b", "1.44", 2000, 2);
    // The grid basin over the same box, its fractions from the catalogue.
    let cat = dir.path().join("cat.csv");
    let args = line(&format!(
        "basins --rig beam-170 --gap-mm 3.0 --omega-ratio 1.44 --u0-mm -6:3:60 \
         --v0-mm-s -300:300:60 --max-periods 1500 --out {} --attractors-out {}",
        s(&dir.path().join("b.csv")),
        s(&cat)
    ));
    ok(&args);
    #[derive(serde::Deserialize)]
    struct Cat {
        regime: String,
        fraction: f64,
    }
    let mut grid: BTreeMap<String, f64> = BTreeMap::new();
    for c in csv::Reader::from_path(&cat).unwrap().deserialize::<Cat>() {
        let c = c.unwrap();
        grid.insert(c.regime, c.fraction);
    }
    assert_eq!(a.len(), 2);
    assert_eq!(b.len(), 2);
    for ra in &a {
        let rb = b.iter().find(|r| r.regime == ra.regime).unwrap();
        let g = grid[&ra.regime];
        println!(
            "{}: seed 1 {:.4} [{:.4}, {:.4}], seed 2 {:.4} [{:.4}, {:.4}], grid 60 × 60 {g:.4}",
            ra.regime, ra.fraction, ra.ci95_lo, ra.ci95_hi, rb.fraction, rb.ci95_lo, rb.ci95_hi
        );
        assert!(ra.fraction > 0.05 && ra.fraction < 0.95);
        // The two seeds' intervals overlap.
        assert!(ra.ci95_lo <= rb.ci95_hi && rb.ci95_lo <= ra.ci95_hi);
        // The grid's fraction lies inside the random sample's interval.
        assert!((ra.ci95_lo..=ra.ci95_hi).contains(&g), "{g} vs {ra:?}");
    }
}

#[test]
fn select_states_the_start_up_basin_and_flags_a_small_one() {
    // The main job: from every start-up condition the hammer ends on the chosen 1/1 orbit.
    let out = ok(&line(
        "select --rig wires --gap-mm 0 --json --no-orbit-check",
    ));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let b = &v["basin_check"];
    assert_eq!(b["from_rest"], "1/1 A");
    assert_eq!(b["chosen"], "A");
    assert_eq!(b["fraction"], 1.0);
    assert_eq!(b["samples"], 1000);
    assert_eq!(b["flagged"], false);
    // The box: u0 from −A0 (0.89 mm) up to the surface, u̇0 up to ± A0 Ω.
    let u0 = b["u0_mm"].as_array().unwrap();
    assert!((u0[0].as_f64().unwrap() + 0.89).abs() < 0.01 && u0[1] == 0.0);
    let a0_omega = 0.89
        * v["omega_ratio"].as_f64().unwrap()
        * 2.0
        * std::f64::consts::PI
        * v["natural_freq_hz"].as_f64().unwrap();
    assert!((b["v0_mm_s"][1].as_f64().unwrap() - a0_omega).abs() < 0.02 * a0_omega);

    // Inside the beam rig's hysteresis the non-impacting orbit competes; a threshold above the
    // 1/1 fraction flags it.
    let text = ok(&line(
        "select --rig beam-170 --gap-mm 3.0 --omega-ratio 1.44:1.50:0.01 --freq-margin-pct 0.5 \
         --gap-margin-mm 0.01 --no-orbit-check --basin-threshold 0.95",
    ));
    println!("{text}");
    assert!(text.contains("start-up basin:"), "{text}");
    assert!(
        text.contains("largest competing attractor: no impact"),
        "{text}"
    );
    assert!(text.contains("below the threshold"), "{text}");
    assert!(
        text.contains("warning: the chosen 1/1 orbit is reached from only"),
        "{text}"
    );
    let json = ok(&line(
        "select --rig beam-170 --gap-mm 3.0 --omega-ratio 1.44:1.50:0.01 --freq-margin-pct 0.5 \
         --gap-margin-mm 0.01 --no-orbit-check --json",
    ));
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let b = &v["basin_check"];
    let f = b["fraction"].as_f64().unwrap();
    assert!(f > 0.5 && f < 0.95, "{b}");
    assert_eq!(b["competitor"]["regime"], "no impact");
    let c = b["competitor"]["fraction"].as_f64().unwrap();
    assert!((f + c - 1.0).abs() < 0.01, "{b}");
    assert_eq!(b["flagged"], false);
    // Without the check: no key.
    let json = ok(&line(
        "select --rig wires --gap-mm 0 --json --no-orbit-check --no-basin-check",
    ));
    assert!(!json.contains("basin_check"));
}

/// The basin check's transient without `--basin-max-periods`: 2000 periods (the main job, the
/// beam rig with Table 3.3's ζ = 0.004 at its answer Ω/ω 1.38: 759 would do), or as long as a
/// lighter damping's free oscillation takes to shrink by 1e-6 at the chosen Ω/ω: ζ = 0.001,
/// `ln(1e6) · 1.38 / (2π · 0.001)` = 3034.4 → 3035 periods, within which the starts that 2000
/// periods left without an attractor reach the non-impacting orbit (and no other start changes
/// its attractor).
#[test]
fn the_basin_checks_transient_outlasts_a_light_dampings_free_oscillation() {
    let basin = |extra: &str| {
        let json = ok(&line(&format!(
            "select --rig beam-170 --gap-mm 3.0 --no-orbit-check --json {extra}"
        )));
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(v["omega_ratio"], 1.38, "{v}");
        v["basin_check"].clone()
    };
    // The periods the free oscillation takes to shrink by 1e-6: ln(1e6) Ω/ω / (2π ζ).
    let decay = |zeta: f64| (1e6f64.ln() * 1.38 / (2.0 * std::f64::consts::PI * zeta)).ceil();
    assert!(decay(0.004) < 2000.0);
    assert_eq!(basin("")["max_transient_periods"], 2000);
    let long = basin("--damping-ratio 0.001");
    assert_eq!(long["max_transient_periods"], decay(0.001) as u64, "{long}");
    assert_eq!(long["competitor"]["regime"], "no impact", "{long}");
    // Every start reaches an attractor: the chosen orbit or the competitor.
    let no_attractor = |b: &serde_json::Value| -> f64 {
        b["attractors"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|a| a["id"] == "-")
            .map(|a| a["fraction"].as_f64().unwrap())
            .sum()
    };
    let fraction = |b: &serde_json::Value, key: &str| b[key]["fraction"].as_f64().unwrap();
    let chosen = long["fraction"].as_f64().unwrap();
    assert_eq!(no_attractor(&long), 0.0, "{long}");
    assert!(
        (chosen + fraction(&long, "competitor") - 1.0).abs() < 1e-12,
        "{long}"
    );
    // 2000 periods leave some starts without an attractor: those, and only those, are the
    // ones the longer transient takes to the non-impacting orbit.
    let short = basin("--damping-ratio 0.001 --basin-max-periods 2000");
    assert!(short["competitor"].is_null(), "{short}");
    assert_eq!(short["fraction"].as_f64().unwrap(), chosen, "{short}");
    assert!(no_attractor(&short) > 0.0, "{short}");
    assert!(
        (no_attractor(&short) - fraction(&long, "competitor")).abs() < 1e-12,
        "{short}\n{long}"
    );
}

#[test]
fn a_run_without_recurrence_says_so_with_the_counts() {
    // The undamped wire rig far from the surface: the motions never impact and never settle
    // (neutral beats): no attractor, said with the count.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("n.csv");
    let (_, err) = said(&line(&format!(
        "fractions --rig wires --gap-mm 10 --omega-ratio 0.5 --u0-mm -1:0 --v0-mm-s -5:5 \
         --samples 50 --out {}",
        s(&out)
    )));
    println!("{err}");
    assert!(
        err.contains("no attractor: 50 initial conditions of 50"),
        "{err}"
    );
    let rows = read(&out);
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].attractor, "-");
    assert_eq!(rows[0].fraction, 1.0);
    // With a small damping the same starts settle on the non-impacting orbit.
    let out = dir.path().join("d.csv");
    ok(&line(&format!(
        "fractions --rig wires --damping-ratio 0.05 --gap-mm 10 --omega-ratio 0.5 --u0-mm -1:0 \
         --v0-mm-s -5:5 --samples 50 --max-periods 1000 --out {}",
        s(&out)
    )));
    let rows = read(&out);
    assert_eq!(rows.len(), 1, "{rows:?}");
    assert_eq!(rows[0].regime, "no impact");
    assert_eq!(rows[0].fraction, 1.0);
}

/// Without `--max-periods`, a damped suspension's transient lasts as long as its free
/// oscillation takes to shrink by `--steady-tol`: `ln(1e6) · 1.6 / (2π · 0.004)` = 879.5 →
/// 880 periods for the beam rig (ζ = 0.004, Table 3.3) up to Ω/ω 1.6. Above the 3.0 mm
/// hysteresis the non-impacting orbit is the one attractor (the sweeps of
/// `beam_hysteresis_has_two_attractors_inside_one_outside_with_the_sweeps_ends`); with the protocol's 200 periods no start
/// settles on it and every one counts as no attractor.
#[test]
fn a_damped_suspensions_transient_lasts_until_its_free_oscillation_has_decayed() {
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &str| {
        let out = dir.path().join("f.csv");
        let (_, err) = said(&line(&format!(
            "fractions --rig beam-170 --gap-mm 3.0 --omega-ratio 1.55:1.6:0.05 \
             --samples 100 --out {} {extra}",
            s(&out)
        )));
        (read(&out), err)
    };
    let (rows, err) = run("");
    println!("{err}");
    // ln(1e6) Ω/ω / (2π ζ) at Ω/ω 1.6 with ζ = 0.004.
    let n = (1e6f64.ln() * 1.6 / (2.0 * std::f64::consts::PI * 0.004)).ceil();
    assert_eq!(n, 880.0);
    assert!(
        err.contains(&format!("transient up to {n} periods"))
            && err.contains(&format!("in {n} periods at Ω/ω 1.6")),
        "{err}"
    );
    assert_eq!(rows.len(), 2, "{rows:?}");
    for r in &rows {
        assert_eq!((r.regime.as_str(), r.fraction), ("no impact", 1.0), "{r:?}");
    }
    let (rows, err) = run("--max-periods 200");
    assert!(!err.contains("transient up to"), "{err}");
    assert_eq!(rows.len(), 2, "{rows:?}");
    for r in &rows {
        assert_eq!((r.attractor.as_str(), r.fraction), ("-", 1.0), "{r:?}");
    }
}

/// The impact view (`--color-by impact`, the thesis' Figs. 3.36–3.38) counts each run's own
/// last window. At Fig. 3.37a's point (undamped wires, Ω/ω = 1.75, gap/A0 = 2.50): starts near
/// the linear forced response `u_p = A0 r²/(1 − r²) sin Ωt` (analytic; at t = 0 the Poincaré
/// point `(0, A0 r² Ω/(1 − r²))`) beat with a free oscillation too small to reach the surface,
/// so none impacts; over the thesis' box most runs impact in their window, far more than the
/// impacting attractors' share (undamped: most impacting runs never recur).
#[test]
fn the_impact_view_counts_each_runs_window_and_the_forced_response_island_never_impacts() {
    let dir = tempfile::tempdir().unwrap();
    let (a0_mm, r) = (0.89f64, 1.75f64);
    let gap = 2.5 * a0_mm;
    let omega_n = (9.81f64 / 0.075).sqrt();
    let omega = r * omega_n;
    let amp = a0_mm * r * r / (1.0 - r * r);
    let v_p = amp * omega;
    // Free oscillation at most 0.2 mm and 2 mm/s off: |u| ≤ |u_p| + √(δu² + (δu̇/ω)²) < gap.
    let (du, dv) = (0.2, 2.0);
    assert!(amp.abs() + (du * du + (dv / omega_n).powi(2)).sqrt() < gap - 0.2);
    let run = |u0: String, v0: String, name: &str| {
        let out = dir.path().join(format!("{name}.csv"));
        let (_, err) = said(&line(&format!(
            "basins --rig wires --gap-mm {gap} --omega-ratio {r} --u0-mm {u0} \
             --v0-mm-s {v0} --color-by impact --out {} --plot {}",
            s(&out),
            s(&dir.path().join(format!("{name}.png")))
        )));
        let mut rdr = csv::Reader::from_path(&out).unwrap();
        let rows: Vec<csv::StringRecord> = rdr.records().map(Result::unwrap).collect();
        (rows, err)
    };
    let (island, _) = run(
        format!("{}:{}:9", -du, du),
        format!("{}:{}:9", v_p - dv, v_p + dv),
        "island",
    );
    assert_eq!(island.len(), 81);
    assert!(island.iter().all(|r| &r[3] == "false"), "{island:?}");
    let (rows, err) = run(format!("-4:{gap}:40"), "-100:100:40".into(), "box");
    let impacting = rows.iter().filter(|r| &r[3] == "true").count();
    let on_impacting_attractor = rows
        .iter()
        .filter(|r| &r[3] == "true" && &r[5] != "-")
        .count();
    let share = 100.0 * impacting as f64 / rows.len() as f64;
    assert!(
        err.contains(&format!(
            "impacting in the last window: {share:.2} % of starts"
        )),
        "{share} {err}"
    );
    assert!(share > 30.0, "{share}");
    assert!(
        impacting > 3 * on_impacting_attractor,
        "{impacting} {on_impacting_attractor}"
    );
}

#[test]
fn bad_attractor_input_is_rejected_with_the_field_named_and_nothing_written() {
    let outputs = Outputs::new();
    let (o, p) = (outputs.csv(), outputs.png());
    let fr = |extra: &str| {
        format!(
            "fractions --rig beam-170 --gap-mm 3.0 --omega-ratio 1.4 --out {o} --plot {p} {extra}"
        )
    };
    let cases: [(String, &[&str]); 11] = [
        (
            fr("--u0-mm -1:4 --v0-mm-s -1:1"),
            &["--u0-mm", "beyond the impact surface", "u0 ≤ gap"],
        ),
        (fr("--samples 0"), &["--samples", "allowed 1"]),
        (
            fr("--samples 100 --width 0.01"),
            &["--width", "cannot be met", "--samples ≥"],
        ),
        (fr("--width 1.5"), &["--width", "(0, 1)"]),
        (fr("--confirm 0"), &["error: --confirm: `confirm`"]),
        (
            fr("--recurrence-tol NaN"),
            &["error: --recurrence-tol: `tol`"],
        ),
        (fr("--match-tol 0"), &["--match-tol", "allowed"]),
        (
            fr("--damping-ratio 1.0"),
            &["damping_ratio", "allowed 0 ≤ damping_ratio < 1"],
        ),
        (fr("--damping-ratio -0.1"), &["damping_ratio"]),
        (
            format!("fractions --gap-mm 1:2:0.5 --omega-ratio 1:2:0.5 --out {o}"),
            &["--gap-mm and --omega-ratio", "one of them"],
        ),
        (
            format!("fractions --gap-mm 0 --omega-ratio 1.5 --out {o} --width 0.1 --shard 0/2"),
            &["--width", "shard"],
        ),
    ];
    outputs.rejected(&cases);
    rejected(
        &line("select --rig wires --gap-mm 0 --basin-samples 0 --json --no-orbit-check"),
        &["--basin-samples", "allowed 1"],
        &[],
    );
    rejected(
        &line("select --rig wires --gap-mm 0 --basin-threshold 1.5 --no-orbit-check"),
        &["--basin-threshold", "allowed 0 ..= 1"],
        &[],
    );
}

/// The fractions figure draws each band's 95 % interval whole, over the bands: at the beam
/// rig's hysteresis (3.0 mm, Ω/ω 1.5: no impact, A, below `1/1`, B) the bar on the lower band's
/// top edge reaches into the band above it and into its own as far as the CSV's interval says
/// (it was drawn with its band, so the band above covered its upper half), the bands in the
/// no-impact grey and the `1/1` red of every figure.
#[test]
fn fractions_draw_each_interval_whole_over_the_bands() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, png) = (dir.path().join("fr.csv"), dir.path().join("fr.png"));
    ok(&line(&format!(
        "fractions --rig beam-170 --gap-mm 3.0 --omega-ratio 1.5 --u0-mm -6:3 \
         --v0-mm-s -300:300 --samples 200 --max-periods 1500 --out {} --plot {}",
        s(&csv),
        s(&png)
    )));
    let rows = read(&csv);
    let regimes: Vec<(&str, &str)> = rows
        .iter()
        .map(|r| (r.attractor.as_str(), r.regime.as_str()))
        .collect();
    assert_eq!(regimes, [("A", "no impact"), ("B", "1/1")]);
    let low = &rows[0];
    let img = image::open(&png).unwrap().to_rgb8();
    let (red, grey, black) = ([215, 25, 28], [190, 190, 190], [0, 0, 0]);
    let banded = |x: u32, y: u32| [red, grey].contains(&img.get_pixel(x, y).0);
    // The bar: the column with the most black pixels among the bands' (beside it, clear of
    // its white edge, the bands).
    let bar = |x: u32| -> Vec<u32> {
        (0..img.height())
            .filter(|&y| banded(x + 6, y) && img.get_pixel(x, y).0 == black)
            .collect()
    };
    let x = (0..img.width() - 6).max_by_key(|&x| bar(x).len()).unwrap();
    let run = bar(x);
    let (top, bottom) = (run[0], run[run.len() - 1]);
    assert_eq!(run.len() as u32, bottom - top + 1, "one bar");
    // Where the grey band meets the red one above it.
    let edge = (1..img.height())
        .find(|&y| img.get_pixel(x + 6, y - 1).0 == red && img.get_pixel(x + 6, y).0 == grey)
        .unwrap();
    let (above, below) = (f64::from(edge - top), f64::from(bottom - edge));
    let want = (low.ci95_hi - low.fraction) / (low.fraction - low.ci95_lo);
    println!("bar {top}..{bottom}, edge {edge}: {above} px above, {below} below; CSV {low:?}");
    assert!(above > 10.0 && below > 10.0);
    assert!(
        (above / below - want).abs() < 0.15,
        "{} vs {want}",
        above / below
    );
    // Its length is the interval's share of the bands' height.
    let height = (0..img.height()).filter(|&y| banded(x + 6, y)).count() as f64;
    let len = (above + below) / height;
    assert!(
        (len - (low.ci95_hi - low.ci95_lo)).abs() < 0.01,
        "{len} vs {}",
        low.ci95_hi - low.ci95_lo
    );
}

/// The basin fractions of one operating point are drawn as a bar a fifth of the axis wide, not
/// a block filling the plot (which read as fractions over the whole axis): the attractor's
/// colour covers about a fifth of the plot, against two thirds of the image before.
#[test]
fn one_points_fractions_are_a_bar_not_the_whole_plot() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("one.png");
    ok(&line(&format!(
        "fractions --rig wires --gap-mm 0 --omega-ratio 2.0 --u0-mm -3:0 --v0-mm-s -50:50 \
         --samples 40 --out {} --plot {}",
        s(&dir.path().join("one.csv")),
        s(&png)
    )));
    let img = image::open(&png).unwrap().to_rgb8();
    // The only attractor here, the 1/1 orbit: in the 1/1 regime's red, as every figure has it.
    let red = [215, 25, 28];
    let bar = img.pixels().filter(|p| p.0 == red).count();
    let share = bar as f64 / (img.width() * img.height()) as f64;
    assert!((0.05..0.2).contains(&share), "{share}");
    // Centred on Ω/ω 2.0: the bar's columns are the plot's middle fifth.
    let cols: Vec<u32> = (0..img.width())
        .filter(|&x| img.get_pixel(x, img.height() / 2).0 == red)
        .collect();
    let (first, last) = (cols[0], cols[cols.len() - 1]);
    assert_eq!(cols.len() as u32, last - first + 1, "one bar");
    let mid = 0.5 * (first + last) as f64 / img.width() as f64;
    assert!((0.35..0.5).contains(&mid), "{mid}");
}

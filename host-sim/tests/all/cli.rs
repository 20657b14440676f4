//! The command-line contract: outputs, columns, and rejection of bad input with a named field,
//! a non-zero exit and no output file left behind.

use std::fs;

use crate::common;

use common::{host_sim, line, ok, rejected, rejected_files, said, spawn_first_line, write_file};

#[test]
fn select_json_reports_the_operating_point() {
    let out = ok(&line(
        "select --rig wires --gap-mm 0 --json --omega-ratio 0.5:5.0:0.02",
    ));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    for key in [
        "rig",
        "gap_mm",
        "freq_hz",
        "omega_ratio",
        "regime",
        "impact_force_mg",
        "band_hz",
        "margin_freq_pct",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["rig"], "wires");
    assert_eq!(v["regime"], "1/1");
    let f = v["freq_hz"].as_f64().unwrap();
    let ratio = v["omega_ratio"].as_f64().unwrap();
    // freq_hz = Ω/ω · sqrt(g/l)/2π.
    assert!((f - ratio * (9.81f64 / 0.075).sqrt() / (2.0 * std::f64::consts::PI)).abs() < 1e-9);
    let band = v["band_hz"].as_array().unwrap();
    let (lo, hi) = (band[0].as_f64().unwrap(), band[1].as_f64().unwrap());
    assert!(lo < f && f < hi);
    // The margin is measured to the band's edges located on the orbit's branch: a grazing
    // below, a period doubling above; the sweep's margin stays as the cross-check.
    let check = &v["band_check"];
    assert_eq!(check["lower"]["kind"], "grazing");
    assert_eq!(check["upper"]["kind"], "period-doubling");
    let (elo, ehi) = (
        check["lower"]["freq_hz"].as_f64().unwrap(),
        check["upper"]["freq_hz"].as_f64().unwrap(),
    );
    let margin = v["margin_freq_pct"].as_f64().unwrap();
    assert!(margin >= 5.0, "margin {margin}");
    assert!((margin - ((f - elo).min(ehi - f) / f * 100.0)).abs() < 1e-9);
    let sweep_margin = check["sweep_margin_freq_pct"].as_f64().unwrap();
    assert!((sweep_margin - ((f - lo).min(hi - f) / f * 100.0)).abs() < 1e-9);
    // The located edges lie within a sweep step of the sweep's edges (midway between the
    // last 1/1 point and the next: 1.5 steps of 0.02 × 1.82 Hz from the last 1/1 point).
    assert!((elo - lo).abs() < 0.03 * 1.82 && (ehi - hi).abs() < 0.03 * 1.82);
    assert!(check["lower"]["agrees"] == true && check["upper"]["agrees"] == true);
    // The grazing is extrapolated past the branch's last orbit (Newton stalls before it, inside
    // the band), whose multiplier the edge gives and names; the doubling is located by
    // bisection, its multiplier its own.
    let (graze, at) = (
        check["lower"]["omega_ratio"].as_f64().unwrap(),
        check["lower"]["multiplier_at"].as_f64().unwrap(),
    );
    assert!(at > graze && at - graze < 0.01, "{graze} {at}");
    assert!(check["upper"].get("multiplier_at").is_none());
    // The orbit is stable, its multipliers inside the unit circle.
    let mu = check["orbit"]["max_abs_multiplier"].as_f64().unwrap();
    assert!(mu > 0.0 && mu < 1.0 && check["orbit"]["stable"] == true);
}

/// A gap off zero is checked at itself and ±0.1 mm: the report lists the gaps in order, the
/// JSON with the nominal first.
#[test]
fn select_lists_the_gaps_it_checked() {
    let args = "select --rig wires --gap-mm 0.05 --no-orbit-check --no-basin-check";
    let text = ok(&line(args));
    assert!(
        text.contains("gap checked at [0.0, 0.05, 0.15] mm (±0.1 mm)"),
        "{text}"
    );
    let v: serde_json::Value = serde_json::from_str(&ok(&line(&format!("{args} --json")))).unwrap();
    let gaps: Vec<f64> = v["gaps_checked_mm"]
        .as_array()
        .unwrap()
        .iter()
        .map(|g| g.as_f64().unwrap())
        .collect();
    assert_eq!(gaps.len(), 3);
    assert!((gaps[0] - 0.05).abs() < 1e-12 && gaps[1] == 0.0 && (gaps[2] - 0.15).abs() < 1e-12);
}

/// Where the continuation cannot follow the chosen orbit's branch (the Hunt–Crossley law on the
/// wire rig: Newton stalls a step away), no edge is claimed: the side is `stalled`, the sweep's
/// edge stands there, the margin is the sweep's, and a warning says why.
#[test]
fn select_says_when_the_branch_could_not_be_followed() {
    let out = ok(&line("select --law hunt-crossley --no-basin-check --json"));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let check = &v["band_check"];
    for side in ["lower", "upper"] {
        let e = &check[side];
        assert_eq!(e["kind"], "stalled", "{side}: {e}");
        assert!(e["stalled_at"].as_f64().is_some());
        assert_eq!(e["omega_ratio"], e["sweep_omega_ratio"]);
    }
    let margin = v["margin_freq_pct"].as_f64().unwrap();
    let sweep_margin = check["sweep_margin_freq_pct"].as_f64().unwrap();
    assert!(
        (margin - sweep_margin).abs() < 1e-9,
        "{margin} vs {sweep_margin}"
    );
    let warnings = v["warnings"].to_string();
    assert!(
        warnings.contains("no edge is located on this side"),
        "{warnings}"
    );
    // The report claims no located edge, nor a margin to one.
    let text = ok(&line("select --law hunt-crossley --no-basin-check"));
    assert!(
        text.contains("no edge located (the orbit's branch was not followed):")
            && text.contains("to the nearer band edge (the sweep's: no edge located)")
            && !text.contains("located on the orbit's branch"),
        "{text}"
    );
    // Where the sweep's edge stands, the point beyond it is said to be unsettled if it is: the
    // response there (the same sweep's points, computed alone) ended its transient unsettled,
    // in the regime the warning names.
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("r.csv");
    for (side, step) in [("lower", -0.01), ("upper", 0.01)] {
        let edge = check[side]["sweep_omega_ratio"].as_f64().unwrap();
        let beyond = edge + step;
        ok(&line(&format!(
            "response --law hunt-crossley --gap-mm 0 --omega-ratio {beyond:.2}:{beyond:.2}:0.01 \
             --no-lyapunov --out {}",
            csv.display()
        )));
        let text = fs::read_to_string(&csv).unwrap();
        let row: Vec<&str> = text.lines().nth(1).unwrap().split(',').collect();
        assert_eq!(row[6], "false", "{text}");
        let needle = format!(
            "the sweep's point beyond its {side} 1/1 point {edge:.4}, Ω/ω {beyond:.4}, ended its \
             transient of 200 periods unsettled ({})",
            row[3]
        );
        assert!(warnings.contains(&needle), "{warnings} lacks {needle}");
    }
}

/// Without the orbit check the sweep's edges stand, and the main job's upper one is followed
/// by a point still alternating after 200 periods (Ω/ω 2.66, read as `2/2`; the located period
/// doubling is at 2.66035, beyond it): the warning says so. With the check, no warning.
#[test]
fn select_warns_of_an_unsettled_point_beyond_a_sweep_edge() {
    let out = ok(&line("select --no-basin-check --no-orbit-check --json"));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let warnings = v["warnings"].to_string();
    assert!(
        warnings.contains(
            "the sweep's point beyond its upper 1/1 point 2.6500, Ω/ω 2.6600, ended its \
             transient of 200 periods unsettled (2/2)"
        ),
        "{warnings}"
    );
    assert!(!warnings.contains("lower 1/1 point"), "{warnings}");
    let checked = ok(&line("select --no-basin-check --json"));
    assert!(!checked.contains("warnings"), "{checked}");
}

/// Runs `host-sim args`, asserts it fails and returns its stderr.
fn failure(args: &str) -> String {
    let out = host_sim().args(line(args)).output().unwrap();
    assert!(!out.status.success(), "{args} succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The `1/1` runs of a response CSV (`Ω/ω` of each run's first and last point), read by the
/// protocol's own label (`window_regime` where the exponent relabelled a point).
fn one_one_runs(csv: &str) -> Vec<(f64, f64)> {
    let mut rdr = csv::Reader::from_reader(csv.as_bytes());
    let head = rdr.headers().unwrap().clone();
    let col = |n: &str| head.iter().position(|h| h == n).unwrap();
    let (r, reg, win) = (col("omega_ratio"), col("regime"), col("window_regime"));
    let mut runs: Vec<(f64, f64)> = Vec::new();
    let mut open = false;
    for rec in rdr.records().map(Result::unwrap) {
        let label = if rec[win].is_empty() {
            &rec[reg]
        } else {
            &rec[win]
        };
        let x: f64 = rec[r].parse().unwrap();
        match (label == "1/1", open) {
            (true, true) => runs.last_mut().unwrap().1 = x,
            (true, false) => runs.push((x, x)),
            _ => {}
        }
        open = label == "1/1";
    }
    runs
}

/// Where `select` finds no robust `1/1` point it says why from what its responses show, not
/// the contact law alone (which is Table 3.1's here, so it is not named): at 10 mm on the wire
/// rig the widest `1/1` band (the `response` command's, over the same sweep) spans ±5.3 %, too
/// little for a ±5 % window on the sweep's 0.01 grid, and the advice holds (a finer sweep finds
/// a robust point); with a gap margin of 8 mm the upper gap has no impact where the band is; a
/// 5-period transient leaves most points unsettled, as many as `response` counts.
#[test]
fn select_says_from_its_responses_why_no_point_is_robust() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("r.csv");
    let csv = csv.to_str().unwrap();

    let err = failure("select --gap-mm 10");
    ok(&line(&format!(
        "response --gap-mm 10 --omega-ratio 0.5:5:0.01 --no-lyapunov --out {csv}"
    )));
    let runs = one_one_runs(&fs::read_to_string(csv).unwrap());
    let &(lo, hi) = runs
        .iter()
        .max_by(|a, b| ((a.1 - a.0) / (a.1 + a.0)).total_cmp(&((b.1 - b.0) / (b.1 + b.0))))
        .unwrap();
    let pct = (hi - lo) / (hi + lo) * 100.0;
    assert!((5.0..5.5).contains(&pct), "{runs:?}");
    for needle in [
        format!("why: the widest 1/1 band at 10 mm, Ω/ω {lo:.3}–{hi:.3}"),
        format!("spans ±{pct:.1} % about its centre: no 1/1 point has its ±5 % window"),
        "a finer or wider --omega-ratio may find one".to_string(),
    ] {
        assert!(err.contains(&needle), "`{err}` lacks `{needle}`");
    }
    assert!(!err.contains("rebounds at"), "{err}");
    let fine = ok(&line(
        "select --gap-mm 10 --omega-ratio 0.8:1.3:0.002 --no-basin-check --json",
    ));
    let v: serde_json::Value = serde_json::from_str(&fine).unwrap();
    let chosen = v["omega_ratio"].as_f64().unwrap();
    assert!(lo <= chosen && chosen <= hi, "{chosen} outside {lo}–{hi}");

    let err = failure("select --gap-mm 0 --gap-margin-mm 8");
    assert!(
        err.contains("but the gap margin (±8 mm) breaks each: at 8 mm "),
        "{err}"
    );
    let (_, at) = err.split_once("at 8 mm ").unwrap();
    let (_, first) = at.split_once("(Ω/ω ").unwrap();
    let (r, regime) = first.split_once(": ").unwrap();
    let regime = regime.split(')').next().unwrap();
    ok(&line(&format!(
        "response --gap-mm 8 --omega-ratio {r}:{r}:0.01 --no-lyapunov --out {csv}"
    )));
    let text = fs::read_to_string(csv).unwrap();
    assert!(
        text.lines()
            .nth(1)
            .unwrap()
            .contains(&format!(",{regime},")),
        "{regime}: {text}"
    );

    let cfg = write_file(
        dir.path(),
        "t5.toml",
        "[settings.protocol]\nmax_transient_periods = 5\n",
    );
    let cfg = cfg.to_str().unwrap();
    let err = failure(&format!("select --gap-mm 0 --config {cfg}"));
    ok(&line(&format!(
        "response --gap-mm 0 --omega-ratio 0.5:5:0.01 --no-lyapunov --config {cfg} --out {csv}"
    )));
    let mut rdr = csv::Reader::from_path(csv).unwrap();
    let unsettled = rdr
        .deserialize::<std::collections::HashMap<String, String>>()
        .map(Result::unwrap)
        .filter(|r| r["settled"] == "false" && r["regime"] != "no impact")
        .count();
    assert!(unsettled > 226, "{unsettled}");
    let needle = format!(
        "why: {unsettled} of the 451 points ended their transient of 5 periods (the canonical \
         protocol's: 200) unsettled while impacting"
    );
    assert!(err.contains(&needle), "`{err}` lacks `{needle}`");
}

/// A period doubling across a jump of the discretised map bounds the band: with
/// Lankarani–Nikravesh at 1.0 mm the `1/1` orbit's multiplier passes −1 by a jump near Ω/ω 2.195
/// (the test's change located where `μ` is −0.60 ± 0.38i). `continue` tells it, flagged
/// `at_jump`, and `select` takes it as the upper edge (before: no event, the edge a grazing at
/// 3.0137 on the unstable branch, 59 % of margin); the edge in the main job's JSON has no
/// `at_jump` key.
#[test]
fn a_doubling_across_a_jump_is_told_and_bounds_the_band() {
    let ln = "--rig wires --law lankarani-nikravesh --gap-mm 1.0";
    let b = continue_branches(&format!(
        "{ln} --omega-ratio 2.0 --range 1:2.3 --direction up"
    ))
    .swap_remove(0);
    let events = b["events"].as_array().unwrap();
    assert_eq!(events.len(), 1, "{}", b["events"]);
    let e = &events[0];
    let value = e["value"].as_f64().unwrap();
    assert!(
        e["kind"] == "period-doubling" && e["at_jump"] == true && (2.1925..2.2044).contains(&value),
        "{e}"
    );
    let text = ok(&line(&format!(
        "continue {ln} --omega-ratio 2.0 --range 1:2.3 --direction up"
    )));
    assert!(
        text.contains("across a jump of the discretised map"),
        "{text}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&ok(&line(&format!("select {ln} --no-basin-check --json")))).unwrap();
    let upper = &v["band_check"]["upper"];
    let at = upper["omega_ratio"].as_f64().unwrap();
    assert!(
        upper["kind"] == "period-doubling"
            && upper["at_jump"] == true
            && (2.1925..2.2044).contains(&at),
        "{upper}"
    );
    let main: serde_json::Value =
        serde_json::from_str(&ok(&line("select --no-basin-check --json"))).unwrap();
    for side in ["lower", "upper"] {
        assert!(main["band_check"][side].get("at_jump").is_none(), "{side}");
    }
}

/// `VIBRO_ISA` narrows the lane kernels' vector instructions and changes no bit of a Peterka
/// grid whose runs go through every kind of lane (free flight, contact, switching events, near
/// searches): the widest variant's grid and the narrower ones' are each the points computed
/// one at a time by the stepper, without lanes (so the check holds on a CPU with one variant
/// too); a value naming no variant this CPU runs is refused by name, before any output.
#[test]
fn the_isa_variable_changes_no_bit_and_refuses_what_the_cpu_lacks() {
    use shared::analysis::{SimSettings, evaluate_point};
    use shared::model::RigId;
    let dir = tempfile::tempdir().unwrap();
    let grid = |name: &str, isa: Option<&str>| {
        let out = dir.path().join(name);
        let mut c = host_sim();
        c.args(line(&format!(
            "peterka --rig wires --gap-mm 0:1.0:0.5 --freq-hz 1:7:0.25 --out {}",
            out.display()
        )));
        if let Some(isa) = isa {
            c.env("VIBRO_ISA", isa);
        }
        (c.output().unwrap(), out)
    };
    let (o, widest) = grid("widest.csv", None);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let widest = fs::read(widest).unwrap();
    // Each row (index, gap_mm, gap_ratio, omega_ratio, freq_hz, regime, impacts,
    // impact_force_mg, transient_periods, settled, …) is the stepper's point, alone.
    let text = String::from_utf8(widest.clone()).unwrap();
    let params = RigId::Wires.preset();
    let mut points = 0;
    for row in text.lines().skip(1) {
        let c: Vec<&str> = row.split(',').collect();
        let (gap_mm, omega_ratio): (f64, f64) = (c[1].parse().unwrap(), c[3].parse().unwrap());
        let r = evaluate_point::<f32>(&params, gap_mm * 1e-3, omega_ratio, &SimSettings::default())
            .unwrap();
        let force: f64 = c[7].parse().unwrap();
        assert_eq!(
            (
                c[5].to_string(),
                c[6].parse::<u32>().unwrap(),
                force.to_bits(),
                c[8].parse::<u32>().unwrap(),
                c[9].parse::<bool>().unwrap()
            ),
            (
                r.regime.to_string(),
                r.impacts,
                r.impact_force_mg.to_bits(),
                r.transient_periods,
                r.settled
            ),
            "{row}"
        );
        points += 1;
    }
    assert_eq!(points, 3 * 25);
    let mut variants = vec!["portable"];
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        variants.push("avx2");
    }
    for isa in variants {
        let (o, out) = grid(&format!("{isa}.csv"), Some(isa));
        assert!(
            o.status.success(),
            "{isa}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(fs::read(out).unwrap() == widest, "{isa}: the grid differs");
    }
    for bad in ["sse9", "AVX2"] {
        let (o, out) = grid("bad.csv", Some(bad));
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{bad} accepted");
        assert!(
            stderr.contains(&format!("VIBRO_ISA=\"{bad}\"")) && stderr.contains("portable"),
            "{stderr}"
        );
        assert!(!out.exists(), "{bad}: output written");
    }
}

#[test]
fn response_writes_csv_and_png() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("fr.csv");
    let png = dir.path().join("fr.png");
    let (_, err) = said(&line(&format!(
        "response --rig beam-150 --gap-mm 1 --omega-ratio 1.0:2.0:0.25 --out {} --plot {}",
        csv.display(),
        png.display()
    )));
    // What it wrote, as the grid commands say it.
    assert_eq!(err, format!("response: 5 points → {}\n", csv.display()));
    let one = dir.path().join("one.csv");
    let (_, err) = said(&line(&format!(
        "response --rig beam-150 --gap-mm 1 --omega-ratio 1.5:1.5:0.25 --out {}",
        one.display()
    )));
    assert_eq!(err, format!("response: 1 point → {}\n", one.display()));
    let text = fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "omega_ratio,freq_hz,impact_force_mg,regime,impacts,transient_periods,settled,\
         lyapunov_per_period,lyapunov_uncertainty,window_regime,extra_periods,\
         chaotic_transient_periods"
    );
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 5);
    // freq_hz = Ω/ω × 5.25 Hz for the 150 mm beam rig.
    let first: Vec<&str> = rows[0].split(',').collect();
    assert_eq!(first[0], "1.0");
    assert!((first[1].parse::<f64>().unwrap() - 5.25).abs() < 1e-12);
    assert_eq!(&fs::read(&png).unwrap()[..8], b"\x89PNG\r\n\x1a\n");
}

/// A motion whose first window after the protocol has a positive exponent but which then
/// settles (wire rig, 1.0 mm, Ω/ω 4.28: a stable 12/26 orbit, shared's
/// `transient_chaos_is_labelled_by_the_orbit_it_settles_on`) is labelled by its orbit, the
/// chaotic transient's length in the CSV's column and in the text.
#[test]
fn response_names_a_chaotic_transient_and_the_orbit_after_it() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("fr.csv");
    let (_, err) = said(&line(&format!(
        "response --rig wires --gap-mm 1.0 --omega-ratio 4.28:4.28:0.01 --out {}",
        csv.display()
    )));
    let mut rdr = csv::Reader::from_path(&csv).unwrap();
    let head = rdr.headers().unwrap().clone();
    let rec = rdr.records().next().unwrap().unwrap();
    let cell = |name: &str| rec[head.iter().position(|h| h == name).unwrap()].to_string();
    assert_eq!(cell("regime"), "12/26");
    assert_eq!(cell("window_regime"), "irregular");
    // The transient's length (checked against the map's iterates in shared's test), the same
    // in the column and the text below.
    let n: u32 = cell("chaotic_transient_periods").parse().unwrap();
    assert!(cell("extra_periods").parse::<u32>().unwrap() > 0);
    assert!(cell("lyapunov_per_period").parse::<f64>().unwrap() < 0.0);
    assert_eq!(
        err,
        format!(
            "response: 1 point → {}\nlabels: 0 chaotic (a positive exponent over the \
             confirmation run), 0 irregular, 1 settled after a chaotic transient (Ω/ω 4.2800: \
             12/26 after {n} periods)\n",
            csv.display()
        )
    );
}

#[test]
fn simulate_writes_time_series_with_poincare_rows() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("ts.csv");
    let said = ok(&line(&format!(
        "simulate --rig wires --gap-mm 0 --omega-ratio 2.0 --periods 10 --out {}",
        csv.display()
    )));
    let mut rdr = csv::Reader::from_path(&csv).unwrap();
    let headers = rdr.headers().unwrap().clone();
    assert_eq!(
        headers.iter().collect::<Vec<_>>(),
        [
            "t_s",
            "u_mm",
            "du_mm_s",
            "x_mm",
            "impact_force_n",
            "impact_force_mg",
            "region",
            "poincare",
            "lyapunov_per_period"
        ]
    );
    let recs: Vec<csv::StringRecord> = rdr.records().map(Result::unwrap).collect();
    let strobes: Vec<&csv::StringRecord> = recs.iter().filter(|r| &r[7] == "true").collect();
    assert_eq!(strobes.len(), 11, "t = 0 and the end of each of 10 periods");
    // Poincaré instants fall at t = kT exactly (T = 1/(2 · 1.82025 Hz)).
    let period = 1.0 / (2.0 * (9.81f64 / 0.075).sqrt() / (2.0 * std::f64::consts::PI));
    for (k, r) in strobes.iter().enumerate() {
        let t: f64 = r[0].parse().unwrap();
        assert!((t - k as f64 * period).abs() < 1e-9, "strobe {k} at {t}");
    }
    // At the Poincaré instants sin Ωt = 0, so x = u (Eq. 3-18).
    for r in &strobes {
        let (u, x): (f64, f64) = (r[1].parse().unwrap(), r[3].parse().unwrap());
        assert!((u - x).abs() < 1e-6);
    }
    // The running Lyapunov estimate at every Poincaré row after the first, none elsewhere;
    // the run settles on the stable 1/1 orbit, so it is negative.
    assert!(strobes[0][8].is_empty());
    for r in &strobes[1..] {
        let l: f64 = r[8].parse().unwrap();
        assert!(l < 0.0, "{l}");
    }
    assert!(
        recs.iter()
            .filter(|r| &r[7] != "true")
            .all(|r| r[8].is_empty())
    );
    // The summary's exponent is the last running estimate; its sign is called undecided
    // exactly where the uncertainty is not below its size (over 3 periods, not over 10).
    let exponent = |said: &str| -> (f64, f64, bool) {
        let tail = said.split("largest Lyapunov exponent ").nth(1).unwrap();
        let mut words = tail.split_whitespace();
        let l = words.next().unwrap().parse().unwrap();
        assert_eq!(words.next(), Some("±"));
        let u = words.next().unwrap().parse().unwrap();
        (l, u, tail.contains("its sign undecided over this run"))
    };
    let (l, u, undecided) = exponent(&said);
    let last: f64 = strobes.last().unwrap()[8].parse().unwrap();
    assert!((l - last).abs() < 1e-4, "{said}");
    assert!(u < l.abs() && !undecided, "{said}");
    let said = ok(&line(
        "simulate --rig wires --gap-mm 0 --omega-ratio 2.0 --periods 3",
    ));
    let (l, u, undecided) = exponent(&said);
    assert!(u >= l.abs() && undecided, "{said}");
}

#[test]
fn points_evaluates_a_batch() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("pts.csv");
    let output = dir.path().join("res.csv");
    // `points --rig wires [extra] --input pts.csv` with `rows` as the input: the output's text.
    let points = |rows: &str, extra: &[&str]| {
        fs::write(&input, rows).unwrap();
        host_sim()
            .args(["points", "--rig", "wires"])
            .args(extra)
            .arg("--input")
            .arg(&input)
            .arg("--out")
            .arg(&output)
            .assert()
            .success();
        fs::read_to_string(&output).unwrap()
    };
    let text = points(
        "gap_mm,omega_ratio,note\n0,2.0,a\n1.0,1.5,b\n2.4,0.6,c\n",
        &[],
    );
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        "gap_mm,omega_ratio,freq_hz,regime,impacts,impact_force_mg,lyapunov_per_period,\
         lyapunov_uncertainty,window_regime,extra_periods,chaotic_transient_periods"
    );
    assert_eq!(lines.len(), 4);
    assert!(lines[1].starts_with("0.0,2.0,"));
    assert!(lines[1].contains(",1/1,64,"), "{}", lines[1]);
    // Far below resonance with a 2.4 mm gap the pendulum never reaches the surface.
    assert!(lines[3].contains(",no impact,0,0.0"), "{}", lines[3]);
    // Without --lyapunov the exponent's columns are empty.
    assert!(lines[1..].iter().all(|l| l.ends_with(",,,,,")), "{text}");

    // A spreadsheet's export: a comment, `;` and spaces round the cells, the columns in
    // another order: the same points, the same rows.
    let export = points(
        "# operating points\nnote ; omega_ratio ; gap_mm\na ; 2.0 ; 0\nb ; 1.5 ; 1.0\nc ; 0.6 ; 2.4\n",
        &[],
    );
    assert_eq!(export, text);

    // With it: the 1.0 mm response's point Ω/ω 2.33, `irregular` by the protocol's window,
    // is chaotic (exponent positive beyond three standard errors over the confirmation run's
    // 2,048 periods, no period found); the 1/1 orbit keeps its label with a negative exponent
    // (its multipliers').
    points("gap_mm,omega_ratio\n0,2.0\n1.0,2.33\n", &["--lyapunov"]);
    let mut rdr = csv::Reader::from_path(&output).unwrap();
    let rows: Vec<csv::StringRecord> = rdr.records().map(|r| r.unwrap()).collect();
    assert_eq!(rows.len(), 2);
    let num = |r: &csv::StringRecord, k: usize| r[k].parse::<f64>().unwrap();
    assert_eq!(&rows[0][3], "1/1");
    assert!(num(&rows[0], 6) < -0.1, "{:?}", rows[0]);
    assert_eq!(&rows[0][8], "");
    assert_eq!(&rows[1][3], "chaotic");
    assert_eq!(&rows[1][8], "irregular");
    assert!(num(&rows[1], 6) > 3.0 * num(&rows[1], 7), "{:?}", rows[1]);
    assert_eq!(&rows[1][9], "2048");
    assert_eq!(&rows[1][10], "");
}

#[test]
fn bad_input_is_rejected_with_the_field_named_and_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fr.csv");
    let png = dir.path().join("fr.png");
    let o = out.to_str().unwrap();
    let p = png.to_str().unwrap();
    rejected(
        &line(&format!("response --gap-mm -1 --out {} --plot {}", o, p)),
        &["gap_mm"],
        &[&out, &png],
    );
    rejected(
        &line(&format!("response --gap-mm NaN --out {}", o)),
        &["gap_mm"],
        &[&out],
    );
    rejected(
        &line(&format!(
            "response --gap-mm 0 --omega-ratio 5:0.5:0.1 --out {}",
            o
        )),
        &["--omega-ratio"],
        &[&out],
    );
    rejected(
        &line(&format!(
            "response --gap-mm 0 --omega-ratio 0.5:5:0 --out {}",
            o
        )),
        &["step"],
        &[&out],
    );
    rejected(
        &line(&format!(
            "response --gap-mm 0 --omega-ratio 0.001:1:0.1 --out {}",
            o
        )),
        &["allowed"],
        &[&out],
    );
    rejected(
        &line(&format!("simulate --gap-mm 0 --freq-hz -3 --out {}", o)),
        &["freq_hz"],
        &[&out],
    );
    rejected(&["select", "--rig", "beam-171"], &["unknown rig"], &[]);
    // Checked when the command line is read, before any work: a figure not named .png or .svg,
    // an output in a missing folder (the CSV is not written either).
    let missing = dir.path().join("no-such-folder").join("p.png");
    for (plot, says) in [
        (dir.path().join("fr.pdf"), "ending in .png or .svg"),
        (missing.clone(), "no-such-folder"),
    ] {
        rejected(
            &line(&format!(
                "peterka --gap-mm 0:1:0.5 --freq-hz 1:7:0.5 --out {o} --plot {}",
                plot.display()
            )),
            &["--plot", says],
            &[&out],
        );
    }
    rejected(
        &line(&format!(
            "basins --gap-mm 1 --omega-ratio 2 --u0-mm -1:1:4 --v0-mm-s -1:1:4 --out {o} \
             --attractors-out {}",
            missing.with_extension("csv").display()
        )),
        &["--attractors-out", "no-such-folder"],
        &[&out],
    );
    // The gap against the rig's own range (the wire pendulum's l/4 = 18.75 mm), named as the
    // flag, on a value and on a grid's axis.
    rejected(
        &line(&format!("response --gap-mm 20 --out {o}")),
        &["--gap-mm", "18.75"],
        &[&out],
    );
    rejected(
        &line(&format!(
            "peterka --gap-mm 0:30:0.5 --freq-hz 1:7:0.5 --out {o}"
        )),
        &["--gap-mm", "18.75"],
        &[&out],
    );
    rejected(
        &line(&format!(
            "drop --rig wires --gap-mm 30 --release-mm 40 --out {o}"
        )),
        &["--gap-mm", "wires rig's range", "0 ..= 18.75"],
        &[&out],
    );
    // Each sensor flag named alone, in both records.
    for (args, flag) in [
        ("--sample-rate-hz 0", "--sample-rate-hz:"),
        ("--noise-pct -1", "--noise-pct:"),
        ("--offset-n inf", "--offset-n:"),
        (
            "--record displacement --sample-rate-hz 0.5",
            "--sample-rate-hz:",
        ),
        ("--record displacement --noise-pct 101", "--noise-pct:"),
    ] {
        let stderr_starts = format!("error: {flag} `");
        rejected(
            &line(&format!("drop {args} --out {o}")),
            &[stderr_starts.as_str()],
            &[&out],
        );
    }
    let far = dir.path().join("far.csv");
    std::fs::write(&far, "gap_mm,omega_ratio\n1,1.0\n30,1.0\n").unwrap();
    rejected(
        &line(&format!(
            "points --rig wires --input {} --out {o}",
            far.display()
        )),
        &["line 3", "gap_mm", "0 ..= 18.75"],
        &[&out],
    );
    // A start pressed into the surface; a transient limit of no periods.
    rejected(
        &line(&format!(
            "simulate --gap-mm 0 --omega-ratio 2 --u0-mm 0.2 --out {o}"
        )),
        &["--u0-mm", "beyond the impact surface"],
        &[&out],
    );
    rejected(
        &line("orbit --gap-mm 0.5 --omega-ratio 2 --u0-mm 1"),
        &["--u0-mm", "beyond the impact surface"],
        &[],
    );
    rejected(
        &line(&format!(
            "fractions --rig beam-170 --gap-mm 3 --omega-ratio 1.3 --samples 50 --max-periods 0 \
             --out {o}"
        )),
        &["--max-periods", "1 ..= 1000000"],
        &[&out],
    );
    rejected(
        &line("select --basin-max-periods 0"),
        &["--basin-max-periods"],
        &[],
    );

    // Bad input files: a config and an operating-point list.
    let cfg = dir.path().join("bad.toml");
    let input = dir.path().join("pts.csv");
    let config = format!("response --gap-mm 0 --config {} --out {o}", cfg.display());
    let points = format!("points --input {} --out {o}", input.display());
    rejected_files(
        &[
            (&cfg, &config, "[rig]\nmass_kg = -0.3\n", "mass_kg"),
            (&cfg, &config, "[rig]\nmas_kg = 0.3\n", "mas_kg"),
            (&cfg, &config, "[rig\nmass_kg = 0.3\n", "malformed"),
            // An enum's table without its variant: the variants named, and what was found.
            (
                &cfg,
                &config,
                "[rig.contact]\nstiffness_n_m = 5e6\n",
                "rig.contact: name one contact law as a table of its own, `[rig.contact.NAME]` \
                 with its fields, NAME one of hertz, spring-dashpot, hunt-crossley, \
                 lankarani-nikravesh (found: stiffness_n_m)",
            ),
            (
                &cfg,
                &config,
                "[rig]\ncontact = \"hertz\"\n",
                "(found: \"hertz\")",
            ),
            (
                &cfg,
                &config,
                "[rig.contact.hertz]\nstiffness = 1e8\nexponent = 1.5\n\
                 [rig.contact.hunt-crossley]\nstiffness = 1e8\n",
                "(found: hertz, hunt-crossley)",
            ),
            (
                &cfg,
                &config,
                "[rig.suspension]\nlength_m = 0.1\n",
                "rig.suspension: name one suspension as a table of its own, \
                 `[rig.suspension.NAME]` with its fields, NAME one of wires, beam (found: \
                 length_m)",
            ),
            // A field's own error keeps its words.
            (
                &cfg,
                &config,
                "[rig.contact.spring-dashpot]\nstiffness_n_m = \"x\"\n",
                "rig.contact.spring-dashpot.stiffness_n_m: invalid type: string \"x\"",
            ),
            (
                &input,
                &points,
                "gap_mm,omega_ratio\n0,2.0\nx,1.0\n",
                "line 3",
            ),
            (&input, &points, "gap_mm,omega_ratio\n-0.5,2.0\n", "gap_mm"),
            (
                &input,
                &points,
                "gap_mm,omega_ratio\n0,2.0\n0,2.0,1\n",
                "line 3: 3 cells, more than the first line's 2",
            ),
            (
                &input,
                &points,
                "0,2.0\n",
                "no header line: the file needs a header `gap_mm,omega_ratio`",
            ),
            (
                &input,
                &points,
                "gap,ratio\n0,2.0\n",
                "the header `gap,ratio` lacks the columns gap_mm, omega_ratio",
            ),
            (
                &input,
                &points,
                "gap_mm omega_ratio\n0 2,0\n",
                "line 2, column `omega_ratio` (Ω/ω): `2,0` is not a number",
            ),
            (
                &input,
                &points,
                "omega_ratio,gap\n2.0,0\n",
                "the header `omega_ratio,gap` lacks the column gap_mm (",
            ),
        ],
        &[&out],
    );
}

/// No command writes over a file it reads or over another of its outputs: each is refused
/// before any work, the file it names as both, and the file left as it was.
#[test]
fn no_output_replaces_an_input_or_another_output() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_file(dir.path(), "c.toml", "[rig]\nmass_kg = 0.298\n");
    let csv = write_file(dir.path(), "in.csv", "gap_mm,omega_ratio\n0,2\n");
    let scenario = write_file(
        dir.path(),
        "s.toml",
        "[[commands]]\nat_s = 1.0\nline = \"start\"\n",
    );
    let (c, i, s) = (config.display(), csv.display(), scenario.display());
    let png = dir.path().join("a.png");
    let p = png.display();
    for (args, flags) in [
        (
            format!("simulate --config {c} --gap-mm 0 --omega-ratio 2 --out {c}"),
            "--out {c} is also --config",
        ),
        (
            format!("response --config {c} --gap-mm 0 --omega-ratio 1:2:0.5 --out {c}"),
            "--out {c} is also --config",
        ),
        (
            format!("select --config {c} --out {c}"),
            "--out {c} is also --config",
        ),
        (
            format!("continue --config {c} --omega-ratio 2 --range 1:3 --out {c}"),
            "--out {c} is also --config",
        ),
        (
            format!("drop --config {c} --out {c}"),
            "--out {c} is also --config",
        ),
        (
            format!("points --input {i} --out {i}"),
            "--out {i} is also --input",
        ),
        (
            format!("hil --scenario {s} --out {s}"),
            "--out {s} is also --scenario",
        ),
        (
            format!("simulate --gap-mm 0 --omega-ratio 2 --out {p} --plot {p}"),
            "--plot {p} is also --out",
        ),
    ] {
        let before: Vec<Vec<u8>> = [&config, &csv, &scenario]
            .iter()
            .map(|f| fs::read(f).unwrap())
            .collect();
        let flags = flags
            .replace("{c}", &c.to_string())
            .replace("{i}", &i.to_string())
            .replace("{s}", &s.to_string())
            .replace("{p}", &p.to_string());
        rejected(&line(&args), &[&flags], &[&png]);
        let after: Vec<Vec<u8>> = [&config, &csv, &scenario]
            .iter()
            .map(|f| fs::read(f).unwrap())
            .collect();
        assert_eq!(before, after, "{args}: an input was changed");
    }
}

/// A config file's values replace the preset's, those and nothing else: the setup read is the
/// preset with `A0` and the observation window set, and `response` with the file computes what
/// the library computes with that setup (its window of 32 periods holding 32 impacts of the
/// `1/1` orbit, where the preset's 64 hold 64).
#[test]
fn config_file_overrides_parameters() {
    use host_sim::cli::RigOpts;
    use host_sim::config::Setup;
    use host_sim::runner::{OperatingPoint, evaluate_all};
    use shared::model::RigId;

    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("c.toml");
    fs::write(
        &cfg,
        "[rig]\namplitude_m = 1.78e-3\n[settings.protocol]\nobserve_periods = 32\n",
    )
    .unwrap();
    let preset = Setup::preset(RigId::Wires).unwrap();
    let read = Setup::from_opts(&RigOpts {
        config: Some(cfg.clone()),
        ..RigOpts::preset(RigId::Wires)
    })
    .unwrap();
    let mut expect = preset.clone();
    expect.params.amplitude_m = 1.78e-3;
    expect.settings.protocol.observe_periods = 32;
    assert_eq!(read.params, expect.params);
    assert_eq!(read.settings, expect.settings);
    assert_ne!(read.params, preset.params);

    // (impact_force_mg, impacts) of `response` at Ω/ω 2.0, and the library's with `setup`.
    let command = |extra: &str| -> (f64, u32) {
        let out = dir.path().join("r.csv");
        ok(&line(&format!(
            "response --rig wires --gap-mm 0 --omega-ratio 2.0:2.0:0.1 --out {} {extra}",
            out.display()
        )));
        let text = fs::read_to_string(&out).unwrap();
        let row: Vec<&str> = text.lines().nth(1).unwrap().split(',').collect();
        (row[2].parse().unwrap(), row[4].parse().unwrap())
    };
    let library = |setup: &Setup| -> (f64, u32) {
        let point = OperatingPoint {
            gap_m: 0.0,
            omega_ratio: 2.0,
        };
        let r = evaluate_all(setup, &[point], "test").unwrap()[0];
        (r.impact_force_mg, r.impacts)
    };
    let over = command(&format!("--config {}", cfg.display()));
    assert_eq!(over, library(&expect));
    assert_eq!(over.1, 32);
    let base = command("");
    assert_eq!(base, library(&preset));
    assert_eq!(base.1, 64);
}

/// The run's log is one timeline: commands, state changes and faults in the order of rig
/// time (the sensor-open scenario: a fault at 15 s between two starts, docs/virtual-rig.md).
#[test]
fn hil_logs_commands_states_and_faults_in_the_order_of_rig_time() {
    let scenario = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../docs/scenarios/sensor-open.toml"
    );
    let stdout = ok(&line(&format!(
        "hil --rig wires --gap-mm 0 --seconds 30 --scenario {scenario}"
    )));
    let log: Vec<(f64, &str)> = stdout
        .lines()
        .filter_map(|l| {
            let (t, rest) = l.strip_prefix('[')?.split_once(" s] ")?;
            Some((t.trim().parse().unwrap(), rest))
        })
        .collect();
    let events: Vec<&str> = log.iter().map(|e| e.1).collect();
    assert_eq!(
        events,
        [
            "state idle",
            "> start",
            "state ramp",
            "state track",
            "state fault",
            "FAULT sensor-open",
            "> clear",
            "state idle",
            "> start",
            "state ramp",
            "state track"
        ],
        "{stdout}"
    );
    assert!(log.windows(2).all(|w| w[0].0 <= w[1].0), "{stdout}");
    assert_eq!((log[1].0, log[5].0 > 15.0, log[6].0), (1.0, true, 25.0));
}

#[test]
fn hil_writes_its_log_and_figure_and_rejects_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    let png = dir.path().join("run.png");
    let (c, p) = (csv.to_str().unwrap(), png.to_str().unwrap());
    let stdout = ok(&line(&format!(
        "hil --rig wires --gap-mm 0 --seconds 6 --out {c} --plot {p}"
    )));
    assert!(stdout.contains("state track"), "{stdout}");
    let text = fs::read_to_string(&csv).unwrap();
    assert!(text.starts_with(
        "t_s,state,freq_hz,amp_cmd_mm,cart_amp_mm,measured_impacts,measured_peak_n,true_impacts,true_peak_n,measured_regime,fault,lost_cycles,force_vs_model_pct"
    ));
    assert!(fs::metadata(&png).unwrap().len() > 10_000);
    fs::remove_file(&csv).unwrap();
    fs::remove_file(&png).unwrap();

    let outs = [csv.as_path(), png.as_path()];
    for (args, flag) in [
        (format!("--gap-mm -1 --out {c} --plot {p}"), "--gap-mm"),
        (format!("--gap-mm NaN --out {c}"), "--gap-mm"),
        (format!("--actual-gap-mm 11 --out {c}"), "--actual-gap-mm"),
        (format!("--seconds 0 --out {c}"), "--seconds"),
        // --speed paces the served console; without it the run would ignore it.
        (format!("--speed 10 --out {c}"), "--serve-pty"),
    ] {
        rejected(&line(&format!("hil {args}")), &[flag], &outs);
    }
    let bad = dir.path().join("bad.toml");
    let args = format!("hil --scenario {} --out {c}", bad.display());
    rejected_files(
        &[
            (
                &bad,
                &args,
                "[[faults]]\nkind = \"sensor-melted\"\nat_s = 1.0\n",
                "malformed --scenario",
            ),
            (
                &bad,
                &args,
                "[[faults]]\nkind = \"gain\"\nat_s = -2.0\nfactor = 1.0\n",
                "faults.at_s",
            ),
            (
                &bad,
                &args,
                "[controller.limits]\nfreq_max_hz = 0.5\n",
                "freq_max_hz",
            ),
        ],
        &outs,
    );
}

#[test]
fn a_reader_that_stops_early_ends_the_command_quietly() {
    // `host-sim response … | head -1`: 4,501 CSV rows on stdout, the reader takes the header
    // and closes the pipe. The command ends by SIGPIPE, as Unix tools do, without a panic or
    // an error message. (The protocol's labels alone: the rows, not their labels, are what
    // the pipe carries.)
    use std::os::unix::process::ExitStatusExt;
    let (child, first) = spawn_first_line(
        &line("response --rig wires --gap-mm 0 --omega-ratio 0.5:5.0:0.001 --no-lyapunov"),
        std::process::Stdio::piped(),
    );
    assert!(first.starts_with("omega_ratio,freq_hz"), "{first}");
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.signal(), Some(13), "{:?}: {stderr}", out.status);
    // Nothing but the progress lines a run past 2 s writes to a stderr that is not a terminal.
    let other: Vec<&str> = stderr
        .lines()
        .filter(|l| !(l.contains(" % (") && l.contains(" points/s, about ")))
        .collect();
    assert!(other.is_empty(), "{stderr}");
}

/// `orbit` warns where the monodromy is not the map's slope over ±1e-4 of the scales: at the
/// wire rig's `1/1` orbit at Ω/ω 1.15172, 3e-5 above the band's lower grazing (1.151689 in
/// f32), the secant crosses the grazing; at the main job's orbit, at the `3/1` orbit at 0.9
/// (slow arrivals, where the split near the surface is located to round-off), and at two
/// smooth f32 orbits whose secants in f32 came out above 0.05 by f32's own rounding (the
/// 170 mm beam rig at 3.0 mm, Ω/ω 1.45; Hunt–Crossley at the main job's point) it does not.
/// `--json` carries the mismatch as `slope_mismatch`.
#[test]
fn orbit_warns_where_the_map_is_not_smooth() {
    let run = |args: &str| said(&line(&format!("orbit {args}"))).1;
    let warned = run("--rig wires --gap-mm 0 --omega-ratio 1.15172");
    let by: f64 = warned
        .split("differs from its monodromy by ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{warned}"));
    // Measured: 37.021.
    assert!(by > 1.0, "{warned}");
    assert!(warned.contains("within that of a grazing"), "{warned}");
    for quiet in [
        "--rig wires --gap-mm 0 --omega-ratio 0.9",
        "--rig wires --gap-mm 0 --omega-ratio 2.0",
        "--rig beam-170 --gap-mm 3 --omega-ratio 1.45",
        "--rig wires --law hunt-crossley --gap-mm 0 --omega-ratio 2.0",
    ] {
        let out = run(quiet);
        assert!(out.is_empty(), "{quiet}: {out}");
    }
    // `--json` gives the mismatch as a number: the warning's, and below 0.05 where quiet.
    let mismatch = |ratio: &str| {
        let v: serde_json::Value = serde_json::from_str(&ok(&line(&format!(
            "orbit --rig wires --gap-mm 0 --omega-ratio {ratio} --json"
        ))))
        .unwrap();
        v["slope_mismatch"].as_f64().unwrap()
    };
    let m = mismatch("1.15172");
    assert!((m - by).abs() <= 0.0005 + 1e-9, "{m} vs the warning's {by}");
    let m = mismatch("2.0");
    assert!((0.0..0.05).contains(&m), "{m}");
}

#[test]
fn orbit_reports_the_orbit_its_multipliers_and_its_minimal_period() {
    let v: serde_json::Value = serde_json::from_str(&ok(&line(
        "orbit --rig wires --gap-mm 0 --omega-ratio 2.0 --precision f64 --json",
    )))
    .unwrap();
    let o = &v["orbit"];
    assert_eq!(o["regime"], "1/1");
    // The orbit's multipliers are a complex pair of modulus 0.3169 (f64); the exponent of a
    // periodic orbit is ln max|μ| / q, the margin 1 − max|μ|.
    let mu = o["max_abs_multiplier"].as_f64().unwrap();
    assert!((mu - 0.3169).abs() < 2e-3, "max|μ| {mu}");
    let m = o["multipliers"].as_array().unwrap();
    let (re, im) = (m[0][0].as_f64().unwrap(), m[0][1].as_f64().unwrap());
    assert!((re.hypot(im) - mu).abs() < 1e-12 && im != 0.0);
    assert!((o["lyapunov_per_period"].as_f64().unwrap() - mu.ln()).abs() < 1e-12);
    assert!((o["margin"].as_f64().unwrap() - (1.0 - mu)).abs() < 1e-12);
    assert_eq!(o["stable"], true);
    // Asked at q = 3, the fixed point of P³ is the same orbit: reported at its minimal period.
    let v3: serde_json::Value = serde_json::from_str(&ok(&line(
        "orbit --rig wires --gap-mm 0 --omega-ratio 2.0 --precision f64 --q 3 --json",
    )))
    .unwrap();
    assert_eq!(v3["orbit"]["regime"], "1/1");
    for k in 0..2 {
        let (a, b) = (
            v3["orbit"]["section"][0][k].as_f64().unwrap(),
            o["section"][0][k].as_f64().unwrap(),
        );
        assert!((a - b).abs() < 1e-9 * b.abs(), "{a} vs {b}");
    }
    // Just before the doubling the protocol's window still alternates; the orbit its fixed
    // point of P² is lies within its error of the 1/1 orbit, and is reported as that.
    let text = ok(&line(
        "orbit --rig wires --gap-mm 0 --omega-ratio 2.66 --precision f64",
    ));
    assert!(text.contains("settled on 2/2"), "{text}");
    assert!(
        text.contains("the fixed point of P^2 found is this orbit of minimal period 1"),
        "{text}"
    );
    assert!(
        text.contains("orbit 1/1 at") && text.contains("μ1 = -0.99799"),
        "{text}"
    );
    // In f32 the same search converges onto a 2/2 orbit whose points lie 0.016 mm apart, with
    // μ ≈ +0.996 (the double, born at the doubling with μ = +1): the report says f32 cannot
    // tell the two apart there and gives f64's 1/1 orbit (the run above) beside it.
    let (text, v) = (
        ok(&line("orbit --rig wires --gap-mm 0 --omega-ratio 2.66")),
        serde_json::from_str::<serde_json::Value>(&ok(&line(
            "orbit --rig wires --gap-mm 0 --omega-ratio 2.66 --json",
        )))
        .unwrap(),
    );
    assert!(text.contains("orbit 2/2 at"), "{text}");
    assert!(
        text.contains("near a period doubling (μ = +0.99")
            && text.contains("in f64 the same search finds the 1/1 orbit (max |μ| = 0.99799")
            && text.contains("`--precision f64`"),
        "{text}"
    );
    let near = &v["near_doubling"];
    assert_eq!(near["f64_orbit"]["regime"], "1/1", "{v}");
    assert!((near["mu"].as_f64().unwrap() - 1.0).abs() < 0.01, "{v}");
    assert!(
        (near["f64_orbit"]["multipliers"][0][0].as_f64().unwrap() + 0.99799).abs() < 1e-5,
        "{v}"
    );
    // Away from a doubling (Ω/ω 2.0, max |μ| well inside the circle) nothing is added.
    let far: serde_json::Value = serde_json::from_str(&ok(&line(
        "orbit --rig wires --gap-mm 0 --omega-ratio 2.0 --json",
    )))
    .unwrap();
    assert!(far.get("near_doubling").is_none(), "{far}");
    // The report names a given start as typed (not its round trip through metres).
    let text = ok(&line(
        "orbit --rig wires --gap-mm 0 --omega-ratio 2.0 --u0-mm -3.2e-05 --v0-mm-s 0.1",
    ));
    assert!(
        text.contains("the protocol from u0 = -0.000032 mm, u̇0 = 0.1 mm/s settled on 1/1"),
        "{text}"
    );
    assert_eq!(o["stability"], "stable");
    // Without impacts the undamped pendulum's orbit is neutral (det M = 1: the map preserves
    // area), whatever the rounding of its computed |μ|; damped, the same orbit is stable. The
    // gap reads as typed (0.018 m back in mm is 18.000000000000004).
    let at_18 = |extra: &str| -> serde_json::Value {
        let args = format!("orbit --rig wires --gap-mm 18 --omega-ratio 2.0 --json{extra}");
        serde_json::from_str(&ok(&line(&args))).unwrap()
    };
    let (undamped, damped) = (at_18(""), at_18(" --damping-ratio 0.003"));
    let (u, d) = (&undamped["orbit"], &damped["orbit"]);
    assert_eq!(u["regime"], "no impact");
    assert_eq!(u["gap_mm"], 18.0);
    assert_eq!(
        (&u["stability"], &u["stable"]),
        (&"neutral".into(), &false.into())
    );
    assert!((u["max_abs_multiplier"].as_f64().unwrap() - 1.0).abs() < 1e-5);
    assert_eq!(
        (&d["stability"], &d["stable"]),
        (&"stable".into(), &true.into())
    );
    let text = ok(&line("orbit --rig wires --gap-mm 18 --omega-ratio 2.0"));
    assert!(text.contains("gap 18 mm\n"), "{text}");
    assert!(
        text.contains(": neutral (no impact on an undamped suspension"),
        "{text}"
    );
}

/// In the wire rig's chaotic band (1.0 mm, Ω/ω 2.6: the response's exponent +0.35 per period)
/// the protocol settles on no period: `orbit` says how to ask for one, and asked for two
/// periods finds the unstable `2/2` orbit embedded in the chaos.
#[test]
fn orbit_in_chaos_asks_for_the_period_and_finds_an_unstable_orbit_with_it() {
    let at = "orbit --rig wires --gap-mm 1.0 --omega-ratio 2.6";
    rejected(
        &line(at),
        &["settled on no period (regime irregular)", "`--q Q`"],
        &[],
    );
    let v: serde_json::Value =
        serde_json::from_str(&ok(&line(&format!("{at} --q 2 --json")))).unwrap();
    let o = &v["orbit"];
    assert_eq!((&o["regime"], &o["stable"]), (&"2/2".into(), &false.into()));
    // Unstable by a flip (μ < −1), its exponent ln max|μ| / 2 positive like the attractor's.
    let mu = o["multipliers"][0][0].as_f64().unwrap();
    assert!(mu < -1.5, "{mu}");
    let lyap = o["lyapunov_per_period"].as_f64().unwrap();
    assert!(
        (lyap - mu.abs().ln() / 2.0).abs() < 1e-9 && lyap > 0.2,
        "{lyap}"
    );
}

/// `orbit --out --plot` writes the orbit over its q periods as `simulate` writes a run, from
/// its first Poincaré point: the wire rig's stable `2/2` at Ω/ω 2.8 (f64) closes after two
/// periods, passes through its second Poincaré point after one, and has its two impacts, the
/// larger the report's peak.
#[test]
fn orbit_writes_its_time_series_over_its_period() {
    let dir = tempfile::tempdir().unwrap();
    let (csv_path, png) = (dir.path().join("o.csv"), dir.path().join("o.png"));
    let v: serde_json::Value = serde_json::from_str(&ok(&line(&format!(
        "orbit --rig wires --gap-mm 0 --omega-ratio 2.8 --q 2 --precision f64 --json \
         --out {} --plot {}",
        csv_path.display(),
        png.display()
    ))))
    .unwrap();
    let o = &v["orbit"];
    assert_eq!(o["regime"], "2/2");
    let num = |x: &serde_json::Value| x.as_f64().unwrap();
    let period_s = 1.0 / num(&o["freq_hz"]);
    let rows: Vec<std::collections::HashMap<String, String>> = csv::Reader::from_path(&csv_path)
        .unwrap()
        .deserialize()
        .map(Result::unwrap)
        .collect();
    let f =
        |r: &std::collections::HashMap<String, String>, k: &str| -> f64 { r[k].parse().unwrap() };
    let section: Vec<_> = rows.iter().filter(|r| r["poincare"] == "true").collect();
    assert_eq!(section.len(), 3);
    for (k, r) in section.iter().enumerate() {
        assert!((f(r, "t_s") - k as f64 * period_s).abs() < 1e-9);
        let point = &o["section"][k % 2];
        assert!((f(r, "u_mm") - num(&point[0])).abs() < 1e-5, "u at {k}T");
        assert!((f(r, "du_mm_s") - num(&point[1])).abs() < 1e-4, "u̇ at {k}T");
    }
    assert!((f(section[0], "u_mm") - f(section[1], "u_mm")).abs() > 1.0);
    assert!((f(&rows[rows.len() - 1], "t_s") - 2.0 * period_s).abs() < 1e-9);
    // The impacts: contact episodes, and the largest peak.
    let contacts = rows
        .windows(2)
        .filter(|w| w[0]["region"] != "contact" && w[1]["region"] == "contact")
        .count();
    assert_eq!(contacts, 2);
    let peak = rows
        .iter()
        .map(|r| f(r, "impact_force_mg"))
        .fold(0.0, f64::max);
    assert!(
        (peak - num(&o["impact_force_mg"])).abs() < 1e-3 * peak,
        "{peak}"
    );
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (1000, 1100));
}

/// The branches `continue {args} --json` prints.
fn continue_branches(args: &str) -> Vec<serde_json::Value> {
    let v: serde_json::Value =
        serde_json::from_str(&ok(&line(&format!("continue {args} --json")))).unwrap();
    v.as_array().unwrap().clone()
}

/// The events of `kind` located on `branch` (one of [`continue_branches`]).
fn events_of<'b>(branch: &'b serde_json::Value, kind: &str) -> Vec<&'b serde_json::Value> {
    branch["events"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["kind"] == kind)
        .collect()
}

/// The values of the events of `kind` located on `branch` (one of [`continue_branches`]).
fn event_values(branch: &serde_json::Value, kind: &str) -> Vec<f64> {
    events_of(branch, kind)
        .iter()
        .map(|e| e["value"].as_f64().unwrap())
        .collect()
}

/// A branch that turns back without a fold says so: with Hunt–Crossley in f64 the wire rig's
/// `1/1` branch from Ω/ω 2.0 down turns at 1.96988 where its fold test keeps its sign (a kink
/// of the discretised map; no fold is told) and stalls on the way back at 1.97081; branches that
/// turn at a fold (the beam's at 1.500572, the wire rig's `3/1` at 0.946869, located 9e-5
/// beyond the branch's farthest point) name no such turn.
#[test]
fn continue_says_where_a_branch_turned_back_without_a_fold() {
    let branch = |args: &str| continue_branches(args).swap_remove(0);
    let hc = "--rig wires --law hunt-crossley --gap-mm 0 --omega-ratio 2.0 --range 1.9:2.1 \
              --direction down --precision f64";
    let b = branch(hc);
    let turned = b["turned_back"].as_f64().unwrap();
    assert!((turned - 1.96988).abs() < 1e-4, "{turned}");
    assert_eq!(b["events"], serde_json::json!([]), "{}", b["events"]);
    let end = b["end"].as_str().unwrap();
    assert!(
        end.starts_with("a step below the minimum at Ω/ω 1.9708"),
        "{end}"
    );
    let text = ok(&line(&format!("continue {hc}")));
    assert!(
        text.contains("turned back at Ω/ω 1.9698") && text.contains("without a fold"),
        "{text}"
    );
    for (args, fold) in [
        (
            "--rig beam-170 --gap-mm 3.0 --omega-ratio 1.35 --range 1.0:2.0 --precision f64",
            1.500572,
        ),
        (
            "--rig wires --gap-mm 0 --omega-ratio 0.9 --range 0.6:1.4",
            0.946869,
        ),
    ] {
        let b = branch(&format!("{args} --direction up"));
        let folds = event_values(&b, "fold");
        assert!(
            folds.len() == 1 && (folds[0] - fold).abs() < 1e-4,
            "{folds:?}"
        );
        assert_eq!(b["turned_back"], serde_json::Value::Null, "{args}");
    }
}

/// A fold over kinks of the discretised map is told once, where the branch turns farthest,
/// with the changes of its test it stands for: the 170 mm beam rig's `1/1` branch at 3.0 mm
/// with Lankarani–Nikravesh (f32) zig-zags round its fold at Ω/ω 1.72998 and its fold test
/// changes sign at 13 located folds over 1.72905–1.72998 (each told as a fold before); the
/// same branch with the spring–dashpot law turns cleanly at 1.500573 (no `crossings`).
#[test]
fn continue_tells_a_fold_over_kinks_once_with_its_changes() {
    let args = "--rig beam-170 --gap-mm 3.0 --omega-ratio 1.35 --range 1.0:2.0 --direction up";
    let ln = format!("{args} --law lankarani-nikravesh");
    let b = continue_branches(&ln).swap_remove(0);
    let folds = events_of(&b, "fold");
    assert_eq!(folds.len(), 1, "{}", b["events"]);
    let (value, c) = (folds[0]["value"].as_f64().unwrap(), &folds[0]["crossings"]);
    assert!((value - 1.72998).abs() < 1e-4, "{value}");
    assert!(c["count"].as_u64().unwrap() > 1, "{c}");
    assert_eq!(c["span"][1].as_f64(), Some(value), "{c}");
    assert!(c["span"][0].as_f64().unwrap() < value - 5e-4, "{c}");
    assert_eq!(c["step"], serde_json::Value::Null, "{c}");
    let text = ok(&line(&format!("continue {ln}")));
    assert!(
        text.contains("located folds between Ω/ω 1.729") && text.contains("turns farthest"),
        "{text}"
    );
    let b = continue_branches(args).swap_remove(0);
    let folds = events_of(&b, "fold");
    assert_eq!(folds.len(), 1, "{}", b["events"]);
    assert_eq!(
        folds[0]["crossings"],
        serde_json::Value::Null,
        "{}",
        folds[0]
    );
}

/// The report's branch line gives the span of a branch that turned (its ends alone hide it),
/// and a grazing extrapolated where Newton stalled names the last orbit it comes from: the
/// 170 mm beam's `1/1` branch at 3.0 mm (f32) from Ω/ω 1.35 up turns at its fold (1.50057) and
/// stalls at 1.198 before the grazing it extrapolates at 1.1965 (0.0041 from f64's, which the
/// error it gives contains); down, it runs straight to the
/// range's end (no span said). The wire rig's `2/2` at 1.0 mm from 2.6 meets its grazing within
/// a step, located there by bisection with its own orbit (no extrapolation said).
#[test]
fn continue_reports_a_branch_span_and_an_extrapolated_grazing() {
    let args = "--rig beam-170 --gap-mm 3.0 --omega-ratio 1.35 --range 1.0:2.0";
    let branches = continue_branches(args);
    let ratios = |b: &serde_json::Value| -> Vec<f64> {
        b["points"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["orbit"]["omega_ratio"].as_f64().unwrap())
            .collect()
    };
    let (up, down) = (ratios(&branches[0]), ratios(&branches[1]));
    let (lo, hi) = up
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    let fold = event_values(&branches[0], "fold");
    assert!(
        fold.len() == 1 && (hi - fold[0]).abs() < 1e-3,
        "{fold:?} {hi}"
    );
    let last = *up.last().unwrap();
    assert_eq!(lo, last);
    let graze = events_of(&branches[0], "grazing");
    assert_eq!(graze.len(), 1, "{}", branches[0]["events"]);
    let at = graze[0]["value"].as_f64().unwrap();
    assert_eq!(graze[0]["orbit"]["omega_ratio"].as_f64(), Some(last));
    assert_eq!(graze[0]["extrapolated"], true);
    assert!(at < last && last - at < 0.01, "{at} {last}");
    // Its error: 4× the extrapolation's 0.0016, which contains f64's grazing (1.1923766,
    // docs/accuracy.md, 0.0041 away): not placed to 1e-3, and said so.
    let x = &graze[0]["extrapolation"];
    let (d, bound) = (
        x["distance"].as_f64().unwrap(),
        x["error_bound"].as_f64().unwrap(),
    );
    assert_eq!(d, (at - last).abs());
    assert_eq!(bound, 4.0 * d);
    assert!((at - 1.1923766).abs() <= bound, "{at} ± {bound}");
    assert!(
        (at - 1.1923766).abs() > 1e-3,
        "{at}: f32 within 1e-3 of f64"
    );
    assert_eq!(x["placed"], false);
    let text = ok(&line(&format!("continue {args}")));
    assert!(
        text.contains(&format!(
            "{} orbits from Ω/ω 1.35000000 to Ω/ω {last:.8}, over Ω/ω {lo:.8} – Ω/ω {hi:.8}\n",
            up.len()
        )),
        "{text}"
    );
    let said = text
        .lines()
        .find(|l| l.contains(&format!("grazing at Ω/ω {at:.8}")))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(
        said.ends_with(&format!(
            "beyond (extrapolated {d:.4} from the branch's last orbit, at Ω/ω {last:.8}, whose \
             multiplier this is; error ≲ {bound:.4}: not placed to 0.001)"
        )),
        "{said}"
    );
    assert!(
        text.contains(
            "note: a grazing extrapolated in f32 past where Newton stalled is not placed to 0.001"
        ),
        "{text}"
    );
    assert!(
        text.contains(&format!(
            "{} orbits from Ω/ω 1.35000000 to Ω/ω {:.8}\n",
            down.len(),
            down.last().unwrap()
        )),
        "{text}"
    );
    let wires = "--rig wires --gap-mm 1.0 --omega-ratio 2.6 --q 2 --range 2.4:2.8";
    let text = ok(&line(&format!("continue {wires}")));
    assert!(
        text.contains("grazing at Ω/ω 2.5781")
            && !text.contains("extrapolated")
            && !text.contains("not placed"),
        "{text}"
    );
    let bracketed = continue_branches(wires)
        .iter()
        .flat_map(|b| events_of(b, "grazing"))
        .map(|e| {
            assert!(e.get("extrapolation").is_none(), "{e}");
            e["extrapolated"].clone()
        })
        .collect::<Vec<_>>();
    assert!(
        !bracketed.is_empty() && bracketed.iter().all(|x| x == false),
        "{bracketed:?}"
    );
}

/// Where Newton cannot follow a branch across a jump of the discretised map, `continue` steps
/// over it and goes on: the wire rig's `1/1` branch with Lankarani–Nikravesh in f64 from Ω/ω
/// 1.99 stalls at 1.99552 (the orbit's state and force jump there as the contact's sub-steps
/// change), is taken up again at 1.99602, and reaches the doubling that the f32 branch from 2.3
/// locates at 2.63604; the smooth spring–dashpot branch steps over nothing.
#[test]
fn continue_steps_over_a_jump_of_the_discretised_map() {
    let branch = |args: &str| {
        continue_branches(&format!("--rig wires --gap-mm 0 {args} --direction up")).swap_remove(0)
    };
    let args = "--law lankarani-nikravesh --precision f64 --omega-ratio 1.99 --range 1.9:2.8";
    let b = branch(args);
    let bridges = b["bridges"].as_array().unwrap();
    assert_eq!(bridges.len(), 1, "{bridges:?}");
    let [from, to] = [0, 1].map(|i| bridges[0][i].as_f64().unwrap());
    assert!(
        (from - 1.99552).abs() < 1e-4 && (to - from - 5e-4).abs() < 1e-9,
        "{from} {to}"
    );
    let pd = event_values(&b, "period-doubling");
    assert_eq!(pd.len(), 1, "{pd:?}");
    assert!((pd[0] - 2.63604).abs() < 1e-3, "{pd:?}");
    let text = ok(&line(&format!(
        "continue --rig wires --gap-mm 0 {args} --direction up"
    )));
    assert!(
        text.contains("stepped over 1 jump of the discretised map")
            && text.contains("Ω/ω 1.995520"),
        "{text}"
    );
    let smooth = branch("--omega-ratio 2.0 --range 2.0:2.8");
    assert_eq!(smooth["bridges"], serde_json::json!([]), "{smooth}");
    // Up to Ω/ω 50, the parameter's limit: the last step is shortened to end on it, so the
    // branch ends at the range's end, on its edge, not at a stall or a grazing.
    for precision in ["f64", "f32"] {
        let b = branch(&format!("--omega-ratio 2.0 --precision {precision}"));
        let end = b["end"].as_str().unwrap();
        assert_eq!(end, "the end of the range at Ω/ω 50.000000");
        let kinds: Vec<&str> = b["events"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["kind"].as_str().unwrap())
            .collect();
        assert!(!kinds.contains(&"grazing"), "{kinds:?}");
    }
}

/// A located doubling's test function probed along its branch: on the wire rig's `1/1` branch
/// (spring–dashpot) it changes sign once, at the doubling; with Lankarani–Nikravesh the
/// multiplier moves in jumps of the discretised map as large as its own motion, and the test
/// changes sign several times in a span that holds the doublings located from either start
/// (2.63604 from 2.3, 2.64222 from 1.99), which the reports of `continue` and `select` say.
#[test]
fn continue_says_where_a_doubling_is_smeared_by_kinks_of_the_map() {
    let doublings = |args: &str| -> Vec<serde_json::Value> {
        continue_branches(&format!("--rig wires --gap-mm 0 {args}"))
            .iter()
            .flat_map(|b| b["events"].as_array().unwrap().clone())
            .filter(|e| e["kind"] == "period-doubling")
            .collect()
    };
    let smooth = doublings("--omega-ratio 2.0 --range 2.0:2.8 --direction up");
    assert_eq!(smooth.len(), 1, "{smooth:?}");
    let c = &smooth[0]["crossings"];
    assert_eq!(c["count"], 1, "{c}");
    let value = smooth[0]["value"].as_f64().unwrap();
    let span = [
        c["span"][0].as_f64().unwrap(),
        c["span"][1].as_f64().unwrap(),
    ];
    assert!(
        span[0] < value && value < span[1] && span[1] - span[0] < 1.5e-3,
        "{c}"
    );

    let args = "--law lankarani-nikravesh --omega-ratio 2.3 --range 2.2:2.8 --direction up";
    let kinked = doublings(args);
    assert_eq!(kinked.len(), 1, "{kinked:?}");
    let c = &kinked[0]["crossings"];
    assert!(c["count"].as_u64().unwrap() >= 3, "{c}");
    let span = [
        c["span"][0].as_f64().unwrap(),
        c["span"][1].as_f64().unwrap(),
    ];
    for located in [2.63604, 2.64222] {
        assert!(span[0] < located && located < span[1], "{located}: {c}");
    }
    // `select` says so of the band edges it measures its margin to; the main job's edges (a
    // grazing and the smooth doubling) carry no such note.
    let select = |law: &str| -> serde_json::Value {
        serde_json::from_str(&ok(&line(&format!(
            "select --law {law} --gap-mm 0 --no-basin-check --json"
        ))))
        .unwrap()
    };
    let v = select("lankarani-nikravesh");
    let upper = &v["band_check"]["upper"];
    assert!(upper["smeared"]["count"].as_u64().unwrap() >= 3, "{upper}");
    let warnings = v["warnings"].to_string();
    assert!(
        warnings.contains("its test function changes sign"),
        "{warnings}"
    );
    let v = select("spring-dashpot");
    for side in ["lower", "upper"] {
        assert!(v["band_check"][side].get("smeared").is_none(), "{v}");
    }
    let text = ok(&line(&format!("continue --rig wires --gap-mm 0 {args}")));
    assert!(
        text.contains("its test function changes sign")
            && text.contains("kinks of the discretised map"),
        "{text}"
    );
}

#[test]
fn continue_writes_the_branch_with_located_events_and_rejects_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("c.csv");
    let png = dir.path().join("c.png");
    let args = format!(
        "continue --rig wires --gap-mm 0 --omega-ratio 2.0 --range 1.0:3.0 --follow-doublings 1 \
         --background-points 40 --out {} --plot {}",
        csv.display(),
        png.display()
    );
    let text = ok(&line(&args));
    assert!(text.contains("period-doubling at Ω/ω 2.660"), "{text}");
    assert!(text.contains("grazing at Ω/ω 1.1516"), "{text}");
    let body = fs::read_to_string(&csv).unwrap();
    let mut rows = body.lines();
    assert_eq!(
        rows.next().unwrap(),
        "branch,parent,direction,omega_ratio,freq_hz,gap_mm,u_mm,du_mm_s,regime,\
         impact_force_mg,mu1_re,mu1_im,mu2_re,mu2_im,max_abs_mu,stable,stability,event"
    );
    let events: Vec<Vec<&str>> = rows
        .map(|r| r.split(',').collect::<Vec<_>>())
        .filter(|c| !c[17].is_empty())
        .collect();
    let find = |kind: &str, regime: &str| {
        events
            .iter()
            .find(|c| c[17] == kind && c[8] == regime)
            .unwrap_or_else(|| panic!("no {kind} of {regime} in {events:?}"))
    };
    // The 1/1 band's upper edge: a period doubling at Ω/ω 2.66035 (f32; 2.66036 in f64), the
    // critical multiplier −1; its lower edge: a grazing at 1.15169.
    let pd = find("period-doubling", "1/1");
    let value = pd[3].parse::<f64>().unwrap();
    assert!((value - 2.66035).abs() < 1e-3, "{value}");
    assert!((pd[10].parse::<f64>().unwrap() + 1.0).abs() < 0.01);
    let graze = find("grazing", "1/1");
    assert!((graze[3].parse::<f64>().unwrap() - 1.15169).abs() < 1e-3);
    // The doubled branch (parent 0) doubles again at 2.82918.
    let pd2 = find("period-doubling", "2/2");
    assert_eq!(pd2[1], "0");
    assert!((pd2[3].parse::<f64>().unwrap() - 2.82918).abs() < 1e-3);
    assert!(fs::metadata(&png).unwrap().len() > 10_000);

    let out = dir.path().join("bad.csv");
    rejected(
        &line(&format!(
            "continue --rig wires --omega-ratio 2.0 --range 3:1 --out {}",
            out.display()
        )),
        &["--range"],
        &[&out],
    );
    rejected(
        &line(&format!(
            "continue --rig wires --omega-ratio 2.0 --range 1:nan --out {}",
            out.display()
        )),
        &["--range", "finite"],
        &[&out],
    );
    rejected(
        &line(&format!(
            "continue --rig wires --gap-mm -1 --omega-ratio 2.0 --range 1:3 --out {}",
            out.display()
        )),
        &["gap_mm", "0 ..= 18.75"],
        &[&out],
    );
    // No orbit at the start: the protocol from rest sees no period (the 1.0 mm response's
    // chaotic point) and none was given.
    rejected(
        &line(&format!(
            "continue --rig wires --gap-mm 1.0 --omega-ratio 2.33 --range 2:3 --out {}",
            out.display()
        )),
        &["no periodic orbit at Ω/ω 2.33"],
        &[&out],
    );
}

#[test]
fn damping_ratio_is_set_by_option_or_config_and_checked() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.csv");
    let o = out.to_str().unwrap();
    // --damping-ratio outside [0, 1) or not finite: the field and its range named, exit ≠ 0,
    // nothing written (wires and beams alike).
    for (rig, zeta, needle) in [
        ("wires", "1", "0 ≤ damping_ratio < 1"),
        ("wires", "-0.1", "0 ≤ damping_ratio < 1"),
        ("wires", "NaN", "finite"),
        ("beam-170", "1", "0 ≤ damping_ratio < 1"),
    ] {
        rejected(
            &line(&format!(
                "simulate --rig {rig} --gap-mm 0 --omega-ratio 2.0 --periods 2 \
                 --damping-ratio={zeta} --out {o}"
            )),
            &["--damping-ratio", "`damping_ratio`", needle],
            &[&out],
        );
    }
    // The config's field: the same range, named with its table.
    let cfg = dir.path().join("z.toml");
    let config = format!(
        "simulate --rig wires --gap-mm 0 --omega-ratio 2.0 --periods 2 --config {} --out {o}",
        cfg.display()
    );
    rejected_files(
        &[
            (
                &cfg,
                &config,
                "[rig.suspension.wires]\nlength_m = 0.075\ndamping_ratio = 1.0\n",
                "suspension.wires.damping_ratio",
            ),
            (
                &cfg,
                &config,
                "[rig.suspension.wires]\nlength_m = 0.075\ndamping_ratio = -0.1\n",
                "suspension.wires.damping_ratio",
            ),
        ],
        &[&out],
    );
    // A config without the field (written before it existed) is the undamped pendulum; the
    // option and the config's field give the same damped run, which differs from it.
    let run = |extra: &str| {
        ok(&line(&format!(
            "simulate --rig wires --gap-mm 0 --omega-ratio 2.0 --periods 30 {extra}"
        )))
    };
    fs::write(&cfg, "[rig.suspension.wires]\nlength_m = 0.075\n").unwrap();
    let undamped = run("");
    assert_eq!(run(&format!("--config {}", cfg.display())), undamped);
    fs::write(
        &cfg,
        "[rig.suspension.wires]\nlength_m = 0.075\ndamping_ratio = 0.003\n",
    )
    .unwrap();
    let damped = run(&format!("--config {}", cfg.display()));
    assert_ne!(damped, undamped);
    assert_eq!(run("--damping-ratio 0.003"), damped);
    // The option overrides the config.
    assert_eq!(
        run(&format!("--config {} --damping-ratio 0", cfg.display())),
        undamped
    );
}

/// The elements `<tag …/>` of an SVG document, each as its attributes `(name, value)`.
fn svg_elements<'a>(svg: &'a str, tag: &str) -> Vec<Vec<(&'a str, &'a str)>> {
    svg.split(&format!("<{tag} "))
        .skip(1)
        .map(|rest| {
            let body = &rest[..rest.find('>').unwrap()];
            body.split('"')
                .collect::<Vec<_>>()
                .chunks_exact(2)
                .map(|kv| (kv[0].trim().trim_end_matches('='), kv[1]))
                .collect()
        })
        .collect()
}

/// The value of attribute `name` of an element of [`svg_elements`].
fn attr<'a>(el: &[(&str, &'a str)], name: &str) -> &'a str {
    el.iter().find(|(k, _)| *k == name).unwrap().1
}

/// A figure named `.svg` is an SVG document of the figure its `.png` name draws: the response's
/// points as circles (one per CSV row, in its regime's colour, the largest force topmost), the
/// regimes' legend as text; a map's raster as one embedded PNG image whose pixels are the PNG
/// figure's over the same rectangle (not an element per pixel), its legend as text.
#[test]
fn a_figure_named_svg_is_a_vector_document_of_the_same_figure() {
    use base64::Engine;
    use host_sim::figures::{regime_class, regime_color};
    use shared::observe::Regime;

    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).display().to_string();
    // `cmd --out CSV --plot FIGURE` in the folder.
    let draw = |cmd: &str, csv: &str, figure: &str| {
        ok(&line(&format!(
            "{cmd} --out {} --plot {}",
            p(csv),
            p(figure)
        )))
    };
    draw(
        "response --rig wires --gap-mm 1.0 --omega-ratio 0.5:5.0:0.05",
        "r.csv",
        "r.svg",
    );
    let svg = fs::read_to_string(p("r.svg")).unwrap();
    assert!(
        svg.starts_with("<svg width=\"1000\" height=\"620\""),
        "{}",
        &svg[..80]
    );
    assert!(svg.trim_end().ends_with("</svg>"));
    let mut csv = csv::Reader::from_path(p("r.csv")).unwrap();
    let rows: Vec<(Regime, f64)> = csv
        .deserialize::<std::collections::HashMap<String, String>>()
        .map(|r| {
            let r = r.unwrap();
            (
                r["regime"].parse().unwrap(),
                r["impact_force_mg"].parse().unwrap(),
            )
        })
        .collect();
    assert_eq!(rows.len(), 91);
    let hex = |r: Regime| {
        let c = regime_color(r);
        format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
    };
    let dots: Vec<_> = svg_elements(&svg, "circle")
        .into_iter()
        .filter(|c| attr(c, "r") == "3")
        .collect();
    let mut fills: Vec<&str> = dots.iter().map(|c| attr(c, "fill")).collect();
    let mut expected: Vec<String> = rows.iter().map(|&(r, _)| hex(r)).collect();
    fills.sort_unstable();
    expected.sort_unstable();
    assert_eq!(fills, expected);
    let top = dots
        .iter()
        .min_by_key(|c| attr(c, "cy").parse::<i32>().unwrap())
        .unwrap();
    let strongest = rows.iter().max_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
    assert_eq!(attr(top, "fill"), hex(strongest.0));
    // Every regime of the CSV has its legend entry, a text element of its own.
    let legend_names = |svg: &str, regimes: &mut dyn Iterator<Item = Regime>| {
        for r in regimes {
            let name = regime_class(r).1;
            assert!(
                svg.contains(&format!("\n{name}\n</text>")),
                "legend: {name}"
            );
        }
    };
    legend_names(&svg, &mut rows.iter().map(|r| r.0));
    // Its text names the font its layout is measured with, then the viewer's sans-serif.
    let texts = svg.matches("<text ").count();
    assert!(texts > rows.len().min(5), "{texts} text elements");
    assert_eq!(
        svg.matches("font-family=\"DejaVu Sans, sans-serif\"")
            .count(),
        texts
    );

    // A map: one embedded PNG, the PNG figure's pixels.
    let grid = "peterka --rig wires --gap-mm 0:3.42:0.38 --freq-hz 1:7.11:0.1";
    for figure in ["p.png", "p.svg"] {
        draw(grid, "p.csv", figure);
    }
    let svg = fs::read_to_string(p("p.svg")).unwrap();
    let images = svg_elements(&svg, "image");
    assert_eq!(images.len(), 1);
    assert!(svg.len() < 200_000, "{} bytes", svg.len());
    let im = &images[0];
    let data = attr(im, "href")
        .strip_prefix("data:image/png;base64,")
        .unwrap();
    let bytes = base64::engine::general_purpose::STANDARD
        .decode(data)
        .unwrap();
    let raster = image::load_from_memory(&bytes).unwrap().to_rgb8();
    let at = |k| attr(im, k).parse::<u32>().unwrap();
    let (x, y, w, h) = (at("x"), at("y"), at("width"), at("height"));
    assert_eq!((raster.width(), raster.height()), (w, h));
    let png = image::open(p("p.png")).unwrap().to_rgb8();
    let differ = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .filter(|&(i, j)| raster.get_pixel(i, j) != png.get_pixel(x + i, y + j))
        .count();
    assert_eq!(differ, 0, "of {w} × {h}");
    let mut regimes = csv::Reader::from_path(p("p.csv"))
        .unwrap()
        .into_deserialize::<std::collections::HashMap<String, String>>()
        .map(|r| r.unwrap()["regime"].parse::<Regime>().unwrap());
    legend_names(&svg, &mut regimes);
}

/// Far from the surface the 170 mm beam is a damped linear oscillator: its largest exponent
/// is the free oscillation's decay, `−2πζ/(Ω/ω)` per excitation period (ζ = 0.004). At Ω/ω
/// 0.05 the default 64 steps per period are 3.2 per natural period, and RK4's numerical damping
/// makes it −17.7: the command warns, naming where the steps run short and how to resolve it;
/// with 512 steps per period (its advice) no warning, and the exponent is the model's.
#[test]
fn too_few_steps_per_natural_period_are_warned_and_more_resolve_them() {
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &str| -> (String, Vec<(f64, f64)>) {
        let out = dir.path().join("low.csv");
        let (_, err) = said(&line(&format!(
            "response --rig beam-170 --gap-mm 50 --omega-ratio 0.05:0.25:0.2 --out {} {extra}",
            out.display()
        )));
        let mut rdr = csv::Reader::from_path(&out).unwrap();
        let h = rdr.headers().unwrap().clone();
        let col = |name: &str| h.iter().position(|c| c == name).unwrap();
        let (r, l) = (col("omega_ratio"), col("lyapunov_per_period"));
        let rows = rdr
            .records()
            .map(|x| {
                let x = x.unwrap();
                (x[r].parse().unwrap(), x[l].parse().unwrap())
            })
            .collect();
        (err, rows)
    };
    let model = |ratio: f64| -2.0 * std::f64::consts::PI * 0.004 / ratio;
    let (warned, coarse) = run("");
    assert!(
        warned
            .contains("! warning: at Ω/ω 0.050 the suspension's natural period has 3.2 RK4 steps")
            && warned.contains("below Ω/ω 0.250 are approximate"),
        "{warned}"
    );
    assert!(coarse[0].1 < 10.0 * model(0.05), "{coarse:?}");
    let config = write_file(
        dir.path(),
        "fine.toml",
        "[settings.steps]\nsteps_per_period = 512\n",
    );
    let (quiet, fine) = run(&format!("--config {}", config.display()));
    assert!(!quiet.contains("warning"), "{quiet}");
    for (ratio, l) in fine {
        assert!(
            (l / model(ratio) - 1.0).abs() < 5e-3,
            "Ω/ω {ratio}: {l} vs {}",
            model(ratio)
        );
    }
}

/// A grid whose stderr is a pipe (no terminal: a script, a cluster job) reports its progress in
/// lines once it has run 2 s — percent, counts, rate and time left, the counts true — and a run
/// shorter than that writes none. One rayon thread, so that the run is long enough on this
/// machine while costing one core; the test judges by the run's measured time.
#[test]
fn a_long_grid_without_a_terminal_writes_progress_lines() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.csv");
    let started = std::time::Instant::now();
    let o = host_sim()
        .env("RAYON_NUM_THREADS", "1")
        .args(line("peterka --gap-mm 0:3:0.1 --freq-hz 1:7:0.015 --out"))
        .arg(&out)
        .output()
        .unwrap();
    let took = started.elapsed().as_secs_f64();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| l.contains(" % (")).collect();
    // 31 gaps × 401 frequencies.
    let len = 31 * 401;
    for l in &lines {
        let (pct, rest) = l
            .strip_prefix("peterka: ")
            .and_then(|r| r.split_once(" % ("))
            .unwrap_or_else(|| panic!("{l}"));
        let (done, rest) = rest.split_once(" of ").unwrap();
        let done: u64 = done.replace(',', "").parse().unwrap();
        assert!(rest.starts_with("12,431 points) in "), "{l}");
        assert_eq!(pct.parse::<u64>().unwrap(), 100 * done / len, "{l}");
        assert!(
            l.contains(" points/s, about ") && l.ends_with(" left"),
            "{l}"
        );
    }
    if took > 2.5 {
        assert!(
            !lines.is_empty(),
            "{took:.1} s and no progress line:\n{stderr}"
        );
    } else if took < 1.9 {
        assert!(
            lines.is_empty(),
            "{took:.1} s and progress lines:\n{stderr}"
        );
    }
}

//! The grid commands (`peterka`, `basins`, `bifurcation`) and `merge`: shards merged equal a
//! single run byte for byte, physics checks that can fail, bad input rejected with the flag and
//! its range named, a non-zero exit and nothing written, and Ctrl-C leaving nothing behind.

use std::fs;
use std::path::{Path, PathBuf};

use crate::common;

use common::{BEAM_HYSTERESIS_FRACTIONS, Outputs, host_sim, leftovers, line, ok, rejected};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs `cmd` once, then as 3 shards, merges them, and checks the CSVs and figures are equal
/// byte for byte.
fn shards_equal_one_run(dir: &Path, name: &str, cmd: &[&str], plots: &[&str]) {
    let one = dir.join(format!("{name}-one.csv"));
    let mut args: Vec<String> = cmd.iter().map(|a| a.to_string()).collect();
    args.extend(["--out".into(), s(&one).into()]);
    for flag in plots {
        args.extend([
            flag.to_string(),
            s(&dir.join(format!("{name}-one{flag}.png"))).into(),
        ]);
    }
    ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let mut shards: Vec<PathBuf> = Vec::new();
    for i in 0..3 {
        let p = dir.join(format!("{name}-shard{i}.csv"));
        let mut a: Vec<String> = cmd.iter().map(|a| a.to_string()).collect();
        a.extend([
            "--out".into(),
            s(&p).into(),
            "--shard".into(),
            format!("{i}/3"),
        ]);
        ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(
            fs::read_to_string(&p)
                .unwrap()
                .starts_with("# host-sim-shard {")
        );
        shards.push(p);
    }
    let merged = dir.join(format!("{name}-merged.csv"));
    let mut m: Vec<String> = vec!["merge".into(), "--out".into(), s(&merged).into()];
    for flag in plots {
        m.extend([
            flag.to_string(),
            s(&dir.join(format!("{name}-merged{flag}.png"))).into(),
        ]);
    }
    // Shards in any order.
    for i in [2, 0, 1] {
        m.push(s(&shards[i]).into());
    }
    ok(&m.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(
        fs::read(&one).unwrap(),
        fs::read(&merged).unwrap(),
        "{name}: merged CSV differs from the one-run CSV"
    );
    for flag in plots {
        let a = fs::read(dir.join(format!("{name}-one{flag}.png"))).unwrap();
        let b = fs::read(dir.join(format!("{name}-merged{flag}.png"))).unwrap();
        if *flag == "--attractors-out" {
            assert!(a.starts_with(b"attractor,regime,"));
        } else {
            assert_eq!(&a[..8], b"\x89PNG\r\n\x1a\n");
        }
        assert!(a == b, "{name}: merged {flag} output differs");
    }
}

#[test]
fn peterka_shards_merge_to_the_one_run_bytes() {
    let dir = tempfile::tempdir().unwrap();
    shards_equal_one_run(
        dir.path(),
        "peterka",
        &[
            "peterka",
            "--rig",
            "wires",
            "--gap-mm",
            "0:0.3:0.1",
            "--omega-ratio",
            "1.2:2.8:0.4",
        ],
        &["--plot", "--force-plot"],
    );
    let text = fs::read_to_string(dir.path().join("peterka-one.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        "index,gap_mm,gap_ratio,omega_ratio,freq_hz,regime,impacts,impact_force_mg,\
         transient_periods,settled,lyapunov_per_period"
    );
    assert_eq!(lines.len(), 1 + 4 * 5);
    // Gap outer, frequency inner; index in order.
    for (i, l) in lines[1..].iter().enumerate() {
        assert!(l.starts_with(&format!("{i},")), "{l}");
    }
    assert!(lines[6].starts_with("5,0.1,"), "{}", lines[6]);
}

/// A SLURM array of many tasks makes more shards than a shell's usual soft limit of open files
/// allows at once (1,024): `merge`, which holds them all open, raises its soft limit as far as
/// the hard one allows. Here 40 shards under a soft limit of 32.
#[test]
fn merge_takes_more_shards_than_the_soft_limit_of_open_files() {
    let dir = tempfile::tempdir().unwrap();
    let grid = "peterka --rig wires --gap-mm 0:0.3:0.1 --omega-ratio 1.2:3.0:0.2";
    let one = dir.path().join("one.csv");
    ok(&line(&format!("{grid} --out {}", s(&one))));
    let shards: Vec<String> = (0..40)
        .map(|i| {
            let p = dir.path().join(format!("shard{i}.csv"));
            ok(&line(&format!("{grid} --shard {i}/40 --out {}", s(&p))));
            s(&p).to_string()
        })
        .collect();
    let merged = dir.path().join("merged.csv");
    let status = std::process::Command::new("sh")
        .arg("-c")
        .arg("ulimit -Sn 32 && exec \"$0\" \"$@\"")
        .arg(assert_cmd::cargo::cargo_bin("host-sim"))
        .args(["merge", "--out", s(&merged)])
        .args(&shards)
        .status()
        .unwrap();
    assert!(status.success(), "merge under ulimit -Sn 32: {status}");
    assert_eq!(fs::read(&one).unwrap(), fs::read(&merged).unwrap());
}

#[test]
fn basins_fractions_and_bifurcation_shards_merge_to_the_one_run_bytes() {
    let dir = tempfile::tempdir().unwrap();
    shards_equal_one_run(
        dir.path(),
        "basins",
        &[
            "basins",
            "--rig",
            "wires",
            "--gap-mm",
            "0",
            "--omega-ratio",
            "1.5",
            "--u0-mm",
            "-1:0:4",
            "--v0-mm-s",
            "-10:10:5",
        ],
        &["--plot", "--attractors-out"],
    );
    // Fractions continued over Ω/ω: ids matched across the points of every shard alike.
    shards_equal_one_run(
        dir.path(),
        "fractions",
        &[
            &["fractions"],
            BEAM_HYSTERESIS_FRACTIONS,
            &["--samples", "60", "--max-periods", "1500"],
        ]
        .concat(),
        &["--plot"],
    );
    // Values whose decimal text needs 17 digits (1.1 + 3 × 0.01 = 1.1300000000000001) pass
    // through the shards' metadata exactly.
    shards_equal_one_run(
        dir.path(),
        "fractions17",
        &[
            "fractions",
            "--rig",
            "beam-170",
            "--gap-mm",
            "3.0",
            "--omega-ratio",
            "1.10:1.14:0.01",
            "--samples",
            "12",
        ],
        &[],
    );
    shards_equal_one_run(
        dir.path(),
        "bif",
        &[
            "bifurcation",
            "--rig",
            "wires",
            "--gap-mm",
            "0",
            "--omega-ratio",
            "1.4:2.2:0.2",
        ],
        &["--plot"],
    );
}

#[test]
fn slurm_variables_select_the_shard() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.csv");
    let b = dir.path().join("b.csv");
    let cmd = [
        "peterka",
        "--gap-mm",
        "0:0.1:0.1",
        "--omega-ratio",
        "1.5:1.7:0.2",
    ];
    ok(&[&cmd[..], &["--shard", "1/2", "--out", s(&a)]].concat());
    let out = host_sim()
        .args(cmd)
        .args(["--out", s(&b)])
        .env("SLURM_ARRAY_TASK_ID", "1")
        .env("SLURM_ARRAY_TASK_COUNT", "2")
        .env("SLURM_ARRAY_TASK_MIN", "0")
        .env("SLURM_ARRAY_TASK_STEP", "1")
        .output()
        .unwrap();
    assert!(out.status.success());
    assert_eq!(fs::read(&a).unwrap(), fs::read(&b).unwrap());
    // An array 1-2 (or with a step): its task 1 is in range, and refused all the same, as
    // every task of it is.
    for (min, step) in [("1", "1"), ("0", "2")] {
        let out = host_sim()
            .args(cmd)
            .args(["--out", s(&b)])
            .env("SLURM_ARRAY_TASK_ID", "1")
            .env("SLURM_ARRAY_TASK_COUNT", "2")
            .env("SLURM_ARRAY_TASK_MIN", min)
            .env("SLURM_ARRAY_TASK_STEP", step)
            .output()
            .unwrap();
        assert!(!out.status.success());
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(e.contains("--array=0-1"), "{e}");
    }
    let out = host_sim()
        .args(cmd)
        .args(["--out", s(&b)])
        .env("SLURM_ARRAY_TASK_ID", "2")
        .env("SLURM_ARRAY_TASK_COUNT", "2")
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("SLURM_ARRAY_TASK_ID"));
}

fn read_rows(path: &Path) -> Vec<csv::StringRecord> {
    let mut r = csv::Reader::from_path(path).unwrap();
    r.records().map(Result::unwrap).collect()
}

/// Runs `host-sim {args} --out <a CSV in a temporary folder>` and reads the CSV's rows.
fn rows_of(args: &str) -> Vec<csv::StringRecord> {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.csv");
    ok(&line(&format!("{args} --out {}", s(&out))));
    read_rows(&out)
}

#[test]
fn peterka_wire_rig_at_gap_zero_is_one_one_up_to_the_force_peak() {
    // The thesis (docs/model.md, "What the thesis reports"): wires, gap 0: a z = 1/1 band (Ω/ω ≈ 1.16–2.64) whose maximum force,
    // F_i/mg ≈ 32.9 near Ω/ω = 2.0, is about 3× the force at Ω = ω.
    let rows = rows_of("peterka --rig wires --gap-ratio 0:0:0.1 --omega-ratio 1.5:2.1:0.1");
    assert_eq!(rows.len(), 7);
    let mut best = (0.0, 0.0);
    for r in &rows {
        assert_eq!(&r[5], "1/1", "Ω/ω {}", &r[3]);
        assert_eq!(&r[6], "64");
        let f: f64 = r[7].parse().unwrap();
        if f > best.1 {
            best = (r[3].parse().unwrap(), f);
        }
    }
    assert!((best.0 - 2.0f64).abs() < 0.15, "peak at {}", best.0);
    assert!((30.0..36.0).contains(&best.1), "peak F_i/mg {}", best.1);
}

#[test]
fn basins_with_a_unique_attractor_give_one_attractor_everywhere() {
    let rows = rows_of(
        "basins --rig wires --gap-mm 0 --omega-ratio 1.5 --u0-mm -1:0:3 --v0-mm-s -10:10:3",
    );
    assert_eq!(rows.len(), 9);
    let first = &rows[0];
    for r in &rows {
        assert_eq!(&r[3], "true");
        assert_eq!(&r[4], "1/1");
        assert_eq!(&r[5], "A");
        assert_eq!(&r[6], &first[6]);
        assert_eq!(&r[7], &first[7]);
    }
    // The attractor's Poincaré point is the from-rest steady state (bifurcation, same point).
    let u: f64 = rows_of("bifurcation --gap-mm 0 --omega-ratio 1.5:1.5:0.1")[0][7]
        .parse()
        .unwrap();
    let ua: f64 = first[6].parse().unwrap();
    assert!((u - ua).abs() < 0.01 * 0.89, "{u} vs {ua}");
}

#[test]
fn bifurcation_from_rest_at_gap_zero_is_period_one_with_one_impact_per_period() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("f.png");
    let rows = rows_of(&format!(
        "bifurcation --rig wires --gap-mm 0 --omega-ratio 1.5:1.5:0.1 --plot {}",
        s(&png)
    ));
    assert!(fs::metadata(&png).unwrap().len() > 10_000);
    let strobes: Vec<f64> = rows
        .iter()
        .filter(|r| &r[5] == "strobe")
        .map(|r| r[7].parse().unwrap())
        .collect();
    assert_eq!(strobes.len(), 64);
    for u in &strobes {
        assert!((u - strobes[0]).abs() < 1e-6, "{u} vs {}", strobes[0]);
    }
    let mut per_period = [0u32; 64];
    for r in rows.iter().filter(|r| &r[5] == "impact") {
        assert_eq!(&r[4], "1/1");
        per_period[r[6].parse::<usize>().unwrap()] += 1;
    }
    assert_eq!(per_period, [1; 64]);
}

#[test]
fn bifurcation_continuation_writes_two_branches() {
    let rows = rows_of("bifurcation --gap-mm 0 --omega-ratio 1.5:1.9:0.2 --continuation both");
    let order: Vec<(String, String)> = rows
        .iter()
        .filter(|r| &r[5] == "strobe" && &r[6] == "0")
        .map(|r| (r[1].to_string(), r[0].to_string()))
        .collect();
    let expect: Vec<(String, String)> = [
        ("up", "0"),
        ("up", "1"),
        ("up", "2"),
        ("down", "2"),
        ("down", "1"),
        ("down", "0"),
    ]
    .iter()
    .map(|(a, b)| (a.to_string(), b.to_string()))
    .collect();
    assert_eq!(order, expect);
    // A 1/1 state is unique here: both branches settle on the same orbit at every frequency,
    // their 64 Poincaré points each within 1e-4 of the cart's amplitude A0 (u) and of its
    // velocity amplitude A0 Ω (u̇) of the other branch's.
    let a0_mm = shared::model::RigId::Wires.preset().amplitude_m * 1e3;
    for index in ["0", "1", "2"] {
        let points = |branch: &str| -> Vec<[f64; 3]> {
            rows.iter()
                .filter(|r| &r[0] == index && &r[1] == branch && &r[5] == "strobe")
                .map(|r| {
                    assert_eq!(&r[4], "1/1");
                    [3, 7, 8].map(|c| r[c].parse().unwrap())
                })
                .collect()
        };
        let (up, down) = (points("up"), points("down"));
        assert_eq!((up.len(), down.len()), (64, 64), "index {index}");
        let omega = 2.0 * std::f64::consts::PI * up[0][0];
        for a in &up {
            for b in &down {
                assert!(
                    (a[1] - b[1]).abs() < 1e-4 * a0_mm
                        && (a[2] - b[2]).abs() < 1e-4 * a0_mm * omega,
                    "index {index}: up {a:?}, down {b:?}"
                );
            }
        }
    }
}

#[test]
fn bad_grid_input_is_rejected_with_the_flag_named_and_nothing_written() {
    let outputs = Outputs::new();
    let (o, p) = (outputs.csv(), outputs.png());
    let peterka = |gap: &str, freq: &str| {
        format!("peterka --gap-mm {gap} --freq-hz {freq} --out {o} --plot {p}")
    };
    let basins = |gap: &str, u0: &str, v0: &str| {
        format!(
            "basins --gap-mm {gap} --omega-ratio 1.5 --u0-mm {u0} --v0-mm-s {v0} --out {o} --plot {p}"
        )
    };
    let sharded = |shard: &str| {
        format!("peterka --gap-mm 0:1:0.1 --freq-hz 2:3:0.1 --out {o} --shard {shard}")
    };
    // (command line, what stderr names)
    let cases: [(String, &[&str]); 16] = [
        (peterka("NaN:1:0.1", "2:3:0.1"), &["--gap-mm", "finite"]),
        (
            peterka("-0.5:1:0.1", "2:3:0.1"),
            &["--gap-mm", "allowed 0 ..= 18.75"],
        ),
        (peterka("0:1:0.1", "0.01:3:0.1"), &["--freq-hz", "allowed"]),
        (peterka("0:1:0.1", "2:200:0.1"), &["--freq-hz", "allowed"]),
        (
            format!("peterka --gap-mm 0:1:0.1 --gap-ratio 0:1:0.1 --freq-hz 2:3:0.1 --out {o}"),
            &["--gap-ratio", "cannot be used with"],
        ),
        (
            format!("peterka --gap-mm 0:1:0.1 --out {o}"),
            &["--freq-hz", "--omega-ratio"],
        ),
        (sharded("3/3"), &["--shard", "allowed 0 ..= 2"]),
        (sharded("0/0"), &["--shard", "N ≥ 1"]),
        (sharded("x"), &["--shard", "expected I/N"]),
        (
            basins("0", "-1:0:0", "-1:1:3"),
            &["--u0-mm", "COUNT = 0", "allowed 1 ..= 4096"],
        ),
        (basins("0", "-1:0:3", "-1:1:0"), &["--v0-mm-s", "COUNT = 0"]),
        (
            basins("0", "0:0:3", "-1:1:3"),
            &["--u0-mm 0:0:3", "COUNT times the same point"],
        ),
        (basins("-1", "-1:0:3", "-1:1:3"), &["--gap-mm", "gap_mm"]),
        (basins("NaN", "-1:0:3", "-1:1:3"), &["--gap-mm", "finite"]),
        (basins("0", "-1:1:3", "-1:1:3"), &["--u0-mm", "u0 ≤ gap"]),
        (
            format!(
                "bifurcation --gap-mm 0 --omega-ratio 1:2:0.5 --continuation up --shard 0/2 --out {o}"
            ),
            &["--shard", "continuation"],
        ),
    ];
    outputs.rejected(&cases);
    outputs.rejected(&[(
        format!("bifurcation --gap-mm 0 --omega-ratio 0.001:2:0.5 --out {o}"),
        &["--omega-ratio", "allowed"],
    )]);
}

#[test]
fn merge_rejects_bad_shards_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("m.csv");
    let png = d.join("m.png");
    let o = s(&out);
    let p = s(&png);
    let shard = |name: &str, gaps: &str, i: u32, n: u32| -> PathBuf {
        let path = d.join(name);
        ok(&line(&format!(
            "peterka --gap-mm {gaps} --omega-ratio 1.5:1.7:0.2 --out {} --shard {i}/{n}",
            s(&path)
        )));
        path
    };
    let a0 = shard("a0.csv", "0:0.1:0.1", 0, 2);
    let a1 = shard("a1.csv", "0:0.1:0.1", 1, 2);
    let b1 = shard("b1.csv", "0:0.2:0.1", 1, 2);
    // Missing index (shard 1 absent).
    rejected(
        &line(&format!("merge --out {} --plot {} {}", o, p, s(&a0))),
        &["point index 1 is missing"],
        &[&out, &png],
    );
    // Same shard twice.
    rejected(
        &line(&format!(
            "merge --out {} {} {} {}",
            o,
            s(&a0),
            s(&a1),
            s(&a1)
        )),
        &["appears twice"],
        &[&out],
    );
    // Another grid.
    rejected(
        &line(&format!("merge --out {} {} {}", o, s(&a0), s(&b1))),
        &["do not belong to the same run", "grid"],
        &[&out],
    );
    // Wrong kind.
    rejected(
        &line(&format!(
            "merge --kind basins --out {} {} {}",
            o,
            s(&a0),
            s(&a1)
        )),
        &["--kind basins", "peterka"],
        &[&out],
    );
    // Not a shard (a one-run CSV has no metadata line).
    let plain = d.join("plain.csv");
    ok(&line(&format!(
        "peterka --gap-mm 0:0.1:0.1 --omega-ratio 1.5:1.7:0.2 --out {}",
        s(&plain)
    )));
    rejected(
        &line(&format!("merge --out {} {}", o, s(&plain))),
        &["not a host-sim shard"],
        &[&out],
    );
    // Malformed row.
    let bad = d.join("bad.csv");
    let text = fs::read_to_string(&a1).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    lines[2] = lines[2].replacen(",1/1,", ",one,", 1);
    fs::write(&bad, lines.join("\n") + "\n").unwrap();
    rejected(
        &line(&format!("merge --out {} {} {}", o, s(&a0), s(&bad))),
        &["bad.csv line 3", "malformed"],
        &[&out],
    );
    // Truncated shard: a row missing.
    let trunc = d.join("trunc.csv");
    let good: Vec<&str> = text.lines().collect();
    fs::write(&trunc, good[..good.len() - 1].join("\n") + "\n").unwrap();
    rejected(
        &line(&format!("merge --out {} {} {}", o, s(&a0), s(&trunc))),
        &["missing"],
        &[&out],
    );
    // Edited metadata.
    let meta = d.join("meta.csv");
    fs::write(
        &meta,
        text.replacen("\"precision\":\"f32\"", "\"precision\":\"f64\"", 1),
    )
    .unwrap();
    rejected(
        &line(&format!("merge --out {} {} {}", o, s(&a0), s(&meta))),
        &["precision"],
        &[&out],
    );
    // A row edited: a coordinate that is not its index's, a force that is not a number; a
    // file cut in its last line (the value still reads, the line end is gone).
    let edit = |name: &str, field: usize, value: &str| -> PathBuf {
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let mut cells: Vec<&str> = lines[2].split(',').collect();
        cells[field] = value;
        lines[2] = cells.join(",");
        let path = d.join(name);
        fs::write(&path, lines.join("\n") + "\n").unwrap();
        path
    };
    for (path, says) in [
        (edit("gap.csv", 1, "0.5"), "gap_mm = 0.5 is not the grid's"),
        (edit("nan.csv", 7, "NaN"), "impact_force_mg = NaN"),
    ] {
        rejected(
            &line(&format!("merge --out {} {} {}", o, s(&a0), s(&path))),
            &["line 3", says],
            &[&out],
        );
    }
    let cut = d.join("cut.csv");
    fs::write(&cut, &text[..text.len() - 3]).unwrap();
    rejected(
        &line(&format!("merge --out {} {} {}", o, s(&a0), s(&cut))),
        &["cut.csv", "no line end"],
        &[&out],
    );
    // Outputs onto an input, onto each other, or onto a folder.
    rejected(
        &line(&format!("merge --out {} {} {}", s(&a1), s(&a0), s(&a1))),
        &["is also a shard"],
        &[],
    );
    assert_eq!(fs::read_to_string(&a1).unwrap(), text);
    rejected(
        &line(&format!(
            "merge --out {o} --plot {p} --force-plot {p} {} {}",
            s(&a0),
            s(&a1)
        )),
        &["--force-plot", "is also --plot"],
        &[&out, &png],
    );
    rejected(
        &line(&format!("merge --out {} {} {}", s(d), s(&a0), s(&a1))),
        &["not a file name"],
        &[],
    );
    // The good pair merges.
    ok(&line(&format!("merge --out {} {} {}", o, s(&a0), s(&a1))));
    assert_eq!(read_rows(&out).len(), 4);
}

#[cfg(unix)]
#[test]
fn ctrl_c_stops_and_leaves_no_file() {
    let peterka = [
        "peterka",
        "--gap-mm",
        "0:3.42:0.01",
        "--freq-hz",
        "1:7.11:0.01",
    ];
    interrupt_leaves_nothing(&peterka, &["-INT"]);
    // Two signals at once (the second exits at once): the temporary files go too.
    interrupt_leaves_nothing(&peterka, &["-INT", "-TERM"]);
    // SIGTERM delivered twice at once (`timeout` signals a process and its group): one
    // request; the run stops after its step and says which signal.
    interrupt_leaves_nothing(&peterka, &["-TERM", "-TERM"]);
    // Adaptive fractions over a continuation (rounds of 256 starts at each point).
    interrupt_leaves_nothing(
        &[
            &["fractions"],
            BEAM_HYSTERESIS_FRACTIONS,
            &["--samples", "200000", "--width", "0.005"],
        ]
        .concat(),
        &["-INT"],
    );
}

/// Starts `host-sim cmd --out big.csv --plot big.png`, interrupts it once its temporary CSV
/// exists with `signals` sent together (`kill`'s flags), and checks it stops within 15 s with
/// status 130, writing nothing; unless two different signals made it exit at once, it says it
/// was interrupted, naming the signal.
#[cfg(unix)]
fn interrupt_leaves_nothing(cmd: &[&str], signals: &[&str]) {
    use std::process::Stdio;
    use std::time::{Duration, Instant};
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("big.csv");
    let png = dir.path().join("big.png");
    let bin = assert_cmd::cargo::cargo_bin("host-sim");
    let child = std::process::Command::new(bin)
        .args(cmd)
        .args(["--out", s(&out), "--plot", s(&png)])
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("SLURM_ARRAY_TASK_COUNT")
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until the temporary CSV exists (the run has started), then interrupt.
    let t0 = Instant::now();
    while leftovers(dir.path()).is_empty() && t0.elapsed() < Duration::from_secs(20) {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    for signal in signals {
        let status = std::process::Command::new("kill")
            .args([*signal, &child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
    }
    let t1 = Instant::now();
    let output = child.wait_with_output().unwrap();
    assert!(
        t1.elapsed() < Duration::from_secs(15),
        "{cmd:?}: slow to stop"
    );
    assert_eq!(output.status.code(), Some(130), "{cmd:?}");
    let said = String::from_utf8_lossy(&output.stderr);
    let at_once = signals.windows(2).any(|w| w[0] != w[1]);
    let name = if signals[0] == "-INT" {
        "SIGINT"
    } else {
        "SIGTERM"
    };
    assert!(
        at_once || said.contains(&format!("interrupted by {name}")),
        "{cmd:?} {signals:?}: {said}"
    );
    assert!(!out.exists() && !png.exists(), "{cmd:?}");
    assert!(
        leftovers(dir.path()).is_empty(),
        "{cmd:?}: temporary files left"
    );
}

#[test]
fn peterka_boundary_curves_start_at_the_located_edges_and_merge_from_shards() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let grid = "peterka --rig wires --gap-mm 0:0.6:0.2 --omega-ratio 1.0:3.0:0.1";
    let one = d.join("b-one.csv");
    ok(&line(&format!(
        "{grid} --out {} --boundaries-out {}",
        s(&d.join("one.csv")),
        s(&one)
    )));
    let rows = read_rows(&one);
    // Each curve, from its point at gap 0: the 1/1 band's period doubling at Ω/ω 2.66037 and
    // grazing at 1.15170 (f64; f32 within 1e-3), both going on into the gap.
    let curve = |kind: &str| -> Vec<(f64, f64)> {
        rows.iter()
            .filter(|r| &r[1] == kind && &r[2] == "1/1")
            .map(|r| (r[3].parse().unwrap(), r[4].parse().unwrap()))
            .collect()
    };
    for (kind, at_zero) in [("period-doubling", 2.66037), ("grazing", 1.15170)] {
        let c = curve(kind);
        let start = c
            .iter()
            .find(|p| p.1 == 0.0)
            .unwrap_or_else(|| panic!("no {kind} point at gap 0 in {c:?}"));
        assert!(
            (start.0 - at_zero).abs() < 1e-3,
            "{kind} at gap 0: {start:?}"
        );
        // Both curves lean to lower Ω/ω as the gap grows (the map's 1/1 region narrows
        // from the right and moves left at its lower edge); the grazing leaves the box at its
        // left edge (Ω/ω 1.0, gap 0.15 mm).
        let top = c.iter().max_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
        assert!(top.1 > 0.1, "{kind} stays at gap 0: {c:?}");
        assert!(top.0 < start.0 - 0.1, "{kind}: {top:?} vs {start:?}");
    }
    // Shards run with --boundaries, merged with --boundaries-out: the same curves.
    let mut shards = Vec::new();
    for i in 0..2 {
        let p = d.join(format!("s{i}.csv"));
        ok(&line(&format!(
            "{grid} --boundaries --out {} --shard {i}/2",
            s(&p)
        )));
        shards.push(p);
    }
    let merged = d.join("b-merged.csv");
    ok(&line(&format!(
        "merge --out {} --boundaries-out {} {} {}",
        s(&d.join("m.csv")),
        s(&merged),
        s(&shards[1]),
        s(&shards[0])
    )));
    assert_eq!(fs::read(&one).unwrap(), fs::read(&merged).unwrap());
    // A shard cannot write them (its rows are a part of the grid).
    let out = d.join("x.csv");
    let bout = d.join("xb.csv");
    rejected(
        &line(&format!(
            "{grid} --out {} --shard 0/2 --boundaries-out {}",
            s(&out),
            s(&bout)
        )),
        &["--boundaries-out"],
        &[&out, &bout],
    );
}

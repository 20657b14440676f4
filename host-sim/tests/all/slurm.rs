//! The big grids on a real SLURM: the job-array and merge scripts of `docs/cluster/` submitted
//! to the one-node cluster of `docs/cluster/local-slurm.sh` (which `.ci/run` starts):
//! - a reduced Peterka map with its `1/1` region's boundaries (3,171 points, 4 array tasks, the
//!   merge held by `afterok`), a basin (1,600 initial conditions, 4 tasks), basin fractions
//!   (4 × 200 starts, 4 tasks) and a bifurcation diagram (51 frequencies, 4 tasks): the merged
//!   CSV, boundaries, catalogue and figures are byte for byte those of a single-process run;
//! - one task of a larger map killed with `scancel` while it computes: the merge never starts,
//!   no partial shard is left, and rerunning that array index, then the merge, completes the map
//!   (again byte-identical).
//!
//! Needs a SLURM node up: ignored unless asked for (`cargo test -p host-sim --test all slurm:: --
//! --include-ignored`; `.ci/run` starts the node and runs it), where no node up fails it.
//! `submit.sh`'s refusals (before anything is submitted) are tested everywhere.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use crate::common;

use common::BEAM_HYSTERESIS_FRACTIONS;

fn host_sim() -> PathBuf {
    assert_cmd::cargo::cargo_bin("host-sim")
}

fn scripts() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../docs/cluster")
}

/// Asserts that a SLURM node is up to take jobs.
fn assert_slurm_up() {
    let up = Command::new("sinfo")
        .args(["-h", "-o", "%t"])
        .output()
        .is_ok_and(|o| {
            o.status.success()
                && String::from_utf8_lossy(&o.stdout)
                    .lines()
                    .any(|l| matches!(l.trim(), "idle" | "mix" | "alloc"))
        });
    assert!(
        up,
        "no SLURM node is up (start one: sudo docs/cluster/local-slurm.sh start)"
    );
}

fn run(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?}: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// `(array task id or "-", state, reason)` of every job of `id` (an array job lists each task).
fn states(id: &str) -> Vec<(String, String, String)> {
    let text = run(Command::new("scontrol").args(["-o", "show", "job", id]));
    text.lines()
        .map(|l| {
            let f = |k: &str| {
                l.split_whitespace()
                    .find_map(|w| w.strip_prefix(k))
                    .unwrap_or("-")
                    .to_string()
            };
            (f("ArrayTaskId="), f("JobState="), f("Reason="))
        })
        .collect()
}

fn wait_for(what: &str, timeout: Duration, mut done: impl FnMut() -> bool) {
    let end = Instant::now() + timeout;
    while !done() {
        assert!(Instant::now() < end, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// Whether a process whose command line names `target` (a path ending so) holds a temporary
/// output (`.host-sim-…`) open: it has reserved its output and is computing into it.
fn computing_into(target: &str) -> bool {
    let Ok(procs) = std::fs::read_dir("/proc") else {
        return false;
    };
    procs.flatten().any(|p| {
        let writes = std::fs::read(p.path().join("cmdline"))
            .is_ok_and(|c| c.split(|&b| b == 0).any(|a| a.ends_with(target.as_bytes())));
        writes
            && std::fs::read_dir(p.path().join("fd")).is_ok_and(|fds| {
                fds.flatten().any(|fd| {
                    std::fs::read_link(fd.path()).is_ok_and(|l| {
                        l.file_name()
                            .is_some_and(|n| n.to_string_lossy().starts_with(".host-sim-"))
                    })
                })
            })
    })
}

fn terminal(state: &str) -> bool {
    matches!(
        state,
        "COMPLETED" | "FAILED" | "CANCELLED" | "TIMEOUT" | "NODE_FAIL" | "OUT_OF_MEMORY"
    )
}

/// Waits until every task of `id` has ended; all must have `COMPLETED`.
fn wait_completed(id: &str, run_dir: &Path) {
    wait_for(&format!("job {id}"), Duration::from_secs(600), || {
        states(id).iter().all(|(_, s, _)| terminal(s))
    });
    let st = states(id);
    assert!(
        st.iter().all(|(_, s, _)| s == "COMPLETED"),
        "job {id}: {st:?}\n{}",
        logs(run_dir)
    );
}

fn logs(run_dir: &Path) -> String {
    let mut out = String::new();
    if let Ok(dir) = std::fs::read_dir(run_dir.join("logs")) {
        for e in dir.filter_map(Result::ok) {
            out += &format!(
                "--- {}\n{}",
                e.path().display(),
                std::fs::read_to_string(e.path()).unwrap_or_default()
            );
        }
    }
    out
}

/// `submit.sh KIND SHARDS RUN GRID...` → (array job, merge job).
fn submit(kind: &str, shards: u32, run_dir: &Path, grid: &[&str]) -> (String, String) {
    let out = run(Command::new(scripts().join("submit.sh"))
        .env("HOST_SIM", host_sim())
        .arg(kind)
        .arg(shards.to_string())
        .arg(run_dir)
        .args(grid));
    let w: Vec<&str> = out.split_whitespace().collect();
    assert_eq!((w[0], w[2]), ("array", "merge"), "{out}");
    (w[1].to_string(), w[3].to_string())
}

/// The same command in one process: its CSV and figures into `dir`.
fn single(kind: &str, grid: &[&str], dir: &Path) {
    let mut cmd = Command::new(host_sim());
    cmd.arg(kind)
        .args(grid)
        .arg("--out")
        .arg(dir.join(format!("{kind}.csv")));
    match kind {
        "peterka" => {
            if grid.contains(&"--boundaries") {
                cmd.arg("--boundaries-out")
                    .arg(dir.join("peterka-boundaries.csv"));
            }
            cmd.arg("--plot")
                .arg(dir.join("peterka.png"))
                .arg("--force-plot")
                .arg(dir.join("peterka-f11.png"))
        }
        "basins" => cmd
            .arg("--plot")
            .arg(dir.join("basins.png"))
            .arg("--attractors-out")
            .arg(dir.join("basins-attractors.csv")),
        _ => cmd.arg("--plot").arg(dir.join(format!("{kind}.png"))),
    };
    run(&mut cmd);
}

/// Every file of `kind`'s run with `grid` (the scripts' names) is the same in `a` and `b`.
fn assert_same_files(kind: &str, grid: &[&str], a: &Path, b: &Path) {
    let mut names = vec![format!("{kind}.csv"), format!("{kind}.png")];
    match kind {
        "peterka" => {
            names.push("peterka-f11.png".into());
            if grid.contains(&"--boundaries") {
                names.push("peterka-boundaries.csv".into());
            }
        }
        "basins" => names.push("basins-attractors.csv".into()),
        _ => {}
    }
    for name in &names {
        let (x, y) = (std::fs::read(a.join(name)), std::fs::read(b.join(name)));
        assert!(
            x.as_ref().ok() == y.as_ref().ok() && x.is_ok(),
            "{name} differs between the array's merge and a single run"
        );
    }
}

/// A Peterka map with the curves bounding its `1/1` region.
const PETERKA_BOUNDARIES: &[&str] = &[
    "--rig",
    "wires",
    "--gap-mm",
    "0:1.0:0.05",
    "--freq-hz",
    "1:4:0.02",
    "--boundaries",
];
const BIFURCATION: &[&str] = &[
    "--rig",
    "wires",
    "--gap-mm",
    "0",
    "--omega-ratio",
    "0.5:3:0.05",
];
const BASINS: &[&str] = &[
    "--rig",
    "wires",
    "--gap-mm",
    "1.335",
    "--omega-ratio",
    "2.0",
    "--u0-mm",
    "-4:1.335:40",
    "--v0-mm-s",
    "-100:100:40",
];
/// A map whose shards take several seconds each on one core.
const PETERKA_LONG: &[&str] = &[
    "--rig",
    "wires",
    "--gap-mm",
    "0:3.42:0.05",
    "--freq-hz",
    "1:7.11:0.01",
];

#[test]
#[ignore = "needs a SLURM node up (docs/cluster/local-slurm.sh start)"]
fn job_arrays_merge_into_a_single_runs_files_and_a_cancelled_task_holds_the_merge() {
    assert_slurm_up();
    let started = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let fractions = [BEAM_HYSTERESIS_FRACTIONS, &["--samples", "200"]].concat();
    // 1. A Peterka map with its 1/1 region's boundaries, a basin, basin fractions and a
    // bifurcation diagram: array + merge against one process. The four arrays are submitted
    // at once (the node runs their tasks as its cores free), the single runs made meanwhile.
    let kinds = [
        ("peterka", PETERKA_BOUNDARIES),
        ("basins", BASINS),
        ("fractions", &fractions),
        ("bifurcation", BIFURCATION),
    ];
    let submitted: Vec<_> = kinds
        .iter()
        .map(|&(kind, grid)| {
            let run_dir = dir.path().join(format!("{kind}-array"));
            let jobs = submit(kind, 4, &run_dir, grid);
            (run_dir, jobs)
        })
        .collect();
    for (&(kind, grid), (run_dir, (array, merge))) in kinds.iter().zip(&submitted) {
        let one = dir.path().join(format!("{kind}-single"));
        std::fs::create_dir_all(&one).unwrap();
        single(kind, grid, &one);
        wait_completed(array, run_dir);
        wait_completed(merge, run_dir);
        assert_same_files(kind, grid, &one, run_dir);
    }

    // 2. A task cancelled while it computes.
    let run_dir = dir.path().join("long-array");
    let (array, merge) = submit("peterka", 4, &run_dir, PETERKA_LONG);
    let task1 = format!("{array}_1");
    wait_for("task 1 to run", Duration::from_secs(300), || {
        states(&task1).iter().any(|(_, s, _)| s == "RUNNING")
    });
    // Cancelled once it computes: its process holds its temporary output open (about 3 s of
    // computing follow: 10.5k points on one core). Its shard must not exist yet.
    wait_for(
        "task 1 to compute into its temporary output",
        Duration::from_secs(120),
        || computing_into("long-array/shards/peterka_1.csv"),
    );
    assert!(
        !run_dir.join("shards/peterka_1.csv").exists(),
        "task 1 finished before it could be cancelled: use a larger PETERKA_LONG"
    );
    run(Command::new("scancel").arg(&task1));
    wait_for("the other tasks", Duration::from_secs(600), || {
        states(&array).iter().all(|(_, s, _)| terminal(s))
    });
    let st = states(&array);
    for (task, state, _) in &st {
        let expected = if task == "1" {
            "CANCELLED"
        } else {
            "COMPLETED"
        };
        assert_eq!(state, expected, "task {task}: {st:?}\n{}", logs(&run_dir));
    }
    // The merge waits on a dependency that can no longer be met: it never starts (the
    // controller re-evaluates dependencies periodically, so the reason may take a while).
    wait_for(
        "the merge's reason DependencyNeverSatisfied",
        Duration::from_secs(120),
        || {
            let m = states(&merge);
            assert!(m.iter().all(|(_, s, _)| s == "PENDING"), "{m:?}");
            m.iter().all(|(_, _, r)| r == "DependencyNeverSatisfied")
        },
    );
    run(Command::new("scancel").arg(&merge));
    assert!(!run_dir.join("merged.csv").exists() && !run_dir.join("peterka.csv").exists());
    // No partial shard: task 1's file never appeared, nor any temporary file.
    let shards: Vec<String> = std::fs::read_dir(run_dir.join("shards"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(!shards.contains(&"peterka_1.csv".to_string()), "{shards:?}");
    assert!(
        shards.iter().all(|s| !s.starts_with(".host-sim-")),
        "{shards:?}"
    );
    assert_eq!(shards.len(), 3, "{shards:?}");
    // Rerun index 1, then the merge: the map is complete and a single run's.
    let export = format!(
        "ALL,KIND=peterka,N=4,OUTDIR={}",
        run_dir.canonicalize().unwrap().display()
    );
    let rerun = run(Command::new("sbatch")
        .env("HOST_SIM", host_sim())
        .args(["--parsable", &format!("--export={export}"), "--array=1"])
        .arg(format!(
            "--output={}/logs/rerun_%A_%a.out",
            run_dir.display()
        ))
        .arg(scripts().join("grid-array.sbatch"))
        .args(PETERKA_LONG));
    // The single run computes while the rerun waits for its slot.
    let one = dir.path().join("long-single");
    std::fs::create_dir_all(&one).unwrap();
    single("peterka", PETERKA_LONG, &one);
    wait_completed(rerun.trim(), &run_dir);
    let merge2 = run(Command::new("sbatch")
        .env("HOST_SIM", host_sim())
        .args(["--parsable", &format!("--export={export}")])
        .arg(format!("--output={}/logs/merge2_%j.out", run_dir.display()))
        .arg(scripts().join("grid-merge.sbatch")));
    wait_completed(merge2.trim(), &run_dir);
    assert_same_files("peterka", PETERKA_LONG, &one, &run_dir);
    eprintln!(
        "SLURM test: {:.1} s (two arrays and merges, a cancelled task, its rerun)",
        started.elapsed().as_secs_f64()
    );
}

/// `submit.sh` refuses, before it creates the run's folder or submits anything, a grid option
/// that would make every task fail once it starts (an output the scripts name, `--shard`, a
/// bifurcation's `--continuation`) and a kind it has no merge for; no SLURM is needed.
#[test]
fn submit_refuses_options_every_task_would_fail_on_before_submitting() {
    let dir = tempfile::tempdir().unwrap();
    let run_dir = dir.path().join("run");
    let cases: &[(&str, &[&str], &str)] = &[
        (
            "peterka",
            &["--rig", "wires", "--out", "x.csv"],
            "--out: the scripts write",
        ),
        ("peterka", &["--plot=p.png"], "--plot: the scripts write"),
        (
            "peterka",
            &["--boundaries-out", "b.csv"],
            "--boundaries-out: the scripts",
        ),
        (
            "basins",
            &["--attractors-out", "a.csv"],
            "--attractors-out: the scripts",
        ),
        ("fractions", &["--shard", "0/2"], "--shard: the scripts"),
        (
            "bifurcation",
            &["--gap-mm", "0", "--continuation", "up"],
            "--continuation: a continuation is sequential",
        ),
        (
            "response",
            &["--gap-mm", "0"],
            "KIND must be peterka, basins, fractions or bifurcation",
        ),
    ];
    for (kind, grid, needle) in cases {
        let out = Command::new(scripts().join("submit.sh"))
            .env("HOST_SIM", host_sim())
            .args([kind, "4"])
            .arg(&run_dir)
            .args(*grid)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{kind} {grid:?}: {err}");
        assert!(err.contains(needle), "{kind} {grid:?}: {err}");
        assert!(
            !run_dir.exists(),
            "{kind} {grid:?}: the run's folder was made"
        );
    }
}

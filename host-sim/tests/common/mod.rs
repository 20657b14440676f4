//! What the command-line tests share: run `host-sim`, expect success, or expect a rejection
//! that names the field and leaves nothing behind.

#![allow(dead_code)]

use std::ffi::OsStr;
use std::fmt::Debug;
use std::fs;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};

use assert_cmd::Command;

/// `host-sim` without the SLURM array variables (so a test's grid is never a shard by chance).
pub fn host_sim() -> Command {
    let mut c = Command::cargo_bin("host-sim").unwrap();
    c.env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("SLURM_ARRAY_TASK_COUNT")
        .env_remove("VIBRO_ISA");
    c
}

/// Starts `host-sim args` (stderr to `stderr`), reads the first line of its stdout and closes
/// the pipe: the process and that line.
pub fn spawn_first_line<S: AsRef<OsStr>>(args: &[S], stderr: Stdio) -> (Child, String) {
    let mut child = std::process::Command::new(assert_cmd::cargo::cargo_bin("host-sim"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(stderr)
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    (child, first)
}

/// The arguments of a command line written as one string (split at whitespace; the tests'
/// paths have none).
pub fn line(s: &str) -> Vec<String> {
    s.split_whitespace().map(str::to_owned).collect()
}

/// Runs `host-sim args`, asserts it succeeds and returns its stdout.
pub fn ok<S: AsRef<OsStr> + Debug>(args: &[S]) -> String {
    said(args).0
}

/// Runs `host-sim args`, asserts it succeeds and returns its stdout and its stderr.
pub fn said<S: AsRef<OsStr> + Debug>(args: &[S]) -> (String, String) {
    let out = host_sim().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{args:?}: {err}");
    (String::from_utf8_lossy(&out.stdout).into_owned(), err)
}

/// Writes `text` to the file `name` in `dir` and returns its path.
pub fn write_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    fs::write(&path, text).unwrap();
    path
}

/// The names of the temporary output files (`.host-sim-*`) left in `dir`.
pub fn leftovers(dir: &Path) -> Vec<String> {
    fs::read_dir(dir)
        .unwrap()
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".host-sim-"))
        .collect()
}

/// Runs `host-sim args` and asserts it fails, its stderr contains every needle, and none of
/// `outputs` nor a temporary file beside them exists.
pub fn rejected<S: AsRef<OsStr> + Debug>(args: &[S], needles: &[&str], outputs: &[&Path]) {
    rejected_stderr(args, needles, outputs);
}

/// [`rejected`], returning the stderr.
pub fn rejected_stderr<S: AsRef<OsStr> + Debug>(
    args: &[S],
    needles: &[&str],
    outputs: &[&Path],
) -> String {
    let out = host_sim().args(args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded");
    // Refused before it says anything else (no progress, no note on what it would run).
    assert!(stderr.starts_with("error: "), "{args:?}: stderr `{stderr}`");
    for n in needles {
        assert!(
            stderr.contains(n),
            "{args:?}: stderr `{stderr}` lacks `{n}`"
        );
    }
    for p in outputs {
        assert!(!p.exists(), "{} was left behind", p.display());
        let left = leftovers(p.parent().unwrap());
        assert!(left.is_empty(), "temporary files left: {left:?}");
    }
    stderr.into_owned()
}

/// A temporary folder and the paths of a command's CSV (`o.csv`) and figure (`o.png`) in it,
/// for the rejection tests: [`Outputs::rejected`] asserts that neither is written.
pub struct Outputs {
    /// The folder (removed when dropped).
    pub dir: tempfile::TempDir,
    /// The CSV's path.
    pub csv: PathBuf,
    /// The figure's path.
    pub png: PathBuf,
}

impl Outputs {
    /// A new temporary folder.
    pub fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("o.csv");
        let png = dir.path().join("o.png");
        Self { dir, csv, png }
    }

    /// The CSV's path as text.
    pub fn csv(&self) -> &str {
        self.csv.to_str().unwrap()
    }

    /// The figure's path as text.
    pub fn png(&self) -> &str {
        self.png.to_str().unwrap()
    }

    /// Asserts that every `(command line, needles)` is [`rejected`] naming its needles, with
    /// neither output written.
    pub fn rejected(&self, cases: &[(String, &[&str])]) {
        for (cmd, needles) in cases {
            rejected(&line(cmd), needles, &[&self.csv, &self.png]);
        }
    }
}

/// Bad input files: for each `(file, args, text, needle)`, writes `text` to `file`, runs the
/// command line `args` (which reads `file`) and asserts it is [`rejected`] naming `needle`
/// with none of `outputs` written.
pub fn rejected_files(cases: &[(&Path, &str, &str, &str)], outputs: &[&Path]) {
    for (file, args, text, needle) in cases {
        fs::write(file, text).unwrap();
        rejected(&line(args), &[needle], outputs);
    }
}

/// Basin fractions across the beam rig's hysteresis (170 mm, gap 3.0 mm, Ω/ω 1.40–1.52 in
/// steps of 0.04) from the box `u0` −6–3 mm, `u̇0` ±300 mm/s: the `fractions` options without
/// the sample count.
pub const BEAM_HYSTERESIS_FRACTIONS: &[&str] = &[
    "--rig",
    "beam-170",
    "--gap-mm",
    "3.0",
    "--omega-ratio",
    "1.40:1.52:0.04",
    "--u0-mm",
    "-6:3",
    "--v0-mm-s",
    "-300:300",
];

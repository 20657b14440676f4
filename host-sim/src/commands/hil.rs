//! `host-sim hil`: the firmware's controller in closed loop with a simulated rig (no hardware).

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;
use shared::control::Target;
use shared::model::RigId;

use std::io::Write as _;

use shared::console::Token;

use crate::figures::rig_log;
use crate::output::{Outputs, distinct_files, given, write_csv};
use crate::virtual_rig::pty::{ServeOptions, serve};
use crate::virtual_rig::scenario::Scenario;
use crate::virtual_rig::{self, HilRun, HilSetup};

/// Arguments of `hil`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct HilArgs {
    /// Rig (the controller's model and the plant start from its preset).
    #[arg(long, value_parser = crate::config::rig_parser(), default_value = "wires")]
    pub rig: RigId,
    /// Gap the controller is configured with, mm (0 ..= 10).
    #[arg(long, default_value_t = 0.0)]
    pub gap_mm: f64,
    /// Gap of the simulated rig, mm (default: the configured one).
    #[arg(long)]
    pub actual_gap_mm: Option<f64>,
    /// Scenario TOML: chains, controller configuration, timed commands and faults
    /// (default: `start` at 1 s, no faults).
    #[arg(long, value_name = "FILE.toml")]
    pub scenario: Option<PathBuf>,
    /// Rig time to simulate, s (0 < s ≤ 86400; default 60, or until Ctrl-C with --serve-pty).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Serve the rig's console on a pseudo-terminal instead of running the scenario's timed
    /// lines: prints `pty: /dev/pts/N` as its first line, then runs until --seconds of rig time
    /// or Ctrl-C/SIGTERM, and writes --out/--plot then.
    #[arg(long)]
    pub serve_pty: bool,
    /// With --serve-pty: rig time runs this many times faster than the wall clock (1: real
    /// time; 0 < X ≤ 1000; `max`: as fast as the machine allows).
    #[arg(long, default_value = "1", value_parser = parse_speed, requires = "serve_pty")]
    pub speed: f64,
    /// CSV log, one row per drive cycle: t_s, state, freq_hz, amp_cmd_mm, cart_amp_mm,
    /// measured_impacts, measured_peak_n, true_impacts, true_peak_n, measured_regime, fault,
    /// lost_cycles, force_vs_model_pct (true_: the plant's contacts with a peak of 1 mN or
    /// more).
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: Option<PathBuf>,
    /// PNG or SVG: frequency, force and state against time.
    #[arg(long, value_parser = crate::output::figure_target)]
    pub plot: Option<PathBuf>,
}

fn parse_speed(s: &str) -> Result<f64, String> {
    if s == "max" {
        return Ok(f64::INFINITY);
    }
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v <= 1000.0 => Ok(v),
        _ => Err(format!("`{s}`: allowed 0 < X ≤ 1000 or `max`")),
    }
}

/// Runs the command.
///
/// # Errors
/// Bad arguments or scenario (named, checked by [`run`]), or an output that cannot be written
/// (nothing is left).
pub fn run(a: &HilArgs) -> Result<()> {
    distinct_files(
        &given(&[("--scenario", a.scenario.as_deref())]),
        &given(&[("--out", a.out.as_deref()), ("--plot", a.plot.as_deref())]),
    )?;
    let actual = a.actual_gap_mm.unwrap_or(a.gap_mm);
    let mut scenario = match &a.scenario {
        Some(p) => Scenario::from_file(p)?,
        None => Scenario::default(),
    };
    if a.serve_pty {
        // The console is on the pty: the scenario's timed lines (and the default `start`) are
        // not run.
        scenario.commands.clear();
    }
    let force_limit = f64::from(scenario.controller.limits.force_limit_n);
    let setup = HilSetup {
        rig: a.rig,
        gap_mm: a.gap_mm as f32,
        actual_gap_mm: actual,
        seconds: a.seconds.unwrap_or(60.0),
        scenario,
    };
    let mut outputs = Outputs::new();
    let csv = a.out.as_ref().map(|p| outputs.reserve(p)).transpose()?;
    let png = a.plot.as_ref().map(|p| outputs.reserve(p)).transpose()?;
    let r = if a.serve_pty {
        let opts = ServeOptions {
            speed: a.speed,
            seconds: a.seconds,
        };
        let (r, stats) = serve(&setup, &opts, |path| {
            println!("pty: {}", path.display());
            let _ = std::io::stdout().flush();
        })?;
        // Stdout carries only the `pty:` line: whoever started the server may have stopped
        // reading it. The summary goes to stderr, after the files.
        write_outputs(a, &r, actual, force_limit, csv.as_deref(), png.as_deref())?;
        outputs.commit()?;
        eprintln!(
            "virtual rig stopped after {:.3} s of rig time ({:.2} s wall); {} bytes received ({} dropped: the receive FIFO was full), {} bytes not taken by the client",
            r.samples as f64 / 1e4,
            r.wall_s,
            stats.rx_bytes,
            stats.rx_dropped_bytes,
            stats.tx_lost_bytes
        );
        return Ok(());
    } else {
        let r = virtual_rig::run(&setup)?;
        println!(
            "virtual rig: {} configured at {:.2} mm, real gap {:.2} mm, {:.1} s of rig time in {:.2} s wall ({:.0}× real time, one core)",
            a.rig,
            a.gap_mm,
            actual,
            setup.seconds,
            r.wall_s,
            r.speedup()
        );
        r
    };
    if let Some(p) = &r.prediction {
        println!(
            "model: target {:.4} Hz, 1/1 band {:.3} – {:.3} Hz, predicted F_i/mg {:.2} ({:.1} N)",
            p.target_hz, p.band_hz[0], p.band_hz[1], p.impact_force_mg, p.impact_force_n
        );
    }
    // One timeline: the commands with their replies, the state changes and the faults in the
    // order of rig time (a sort that keeps that order among records at one time).
    let mut log: Vec<(f64, String)> = r
        .console
        .iter()
        .map(|c| (c.t_s, format!("> {}\n             {}", c.line, c.reply)))
        .chain(
            r.states
                .iter()
                .map(|(t, s)| (*t, format!("state {}", s.token()))),
        )
        .chain(
            r.faults
                .iter()
                .map(|(t, f)| (*t, format!("FAULT {}", f.token()))),
        )
        .collect();
    log.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (t, line) in &log {
        println!("[{t:8.3} s] {line}");
    }
    println!("final: {}", r.status);
    write_outputs(a, &r, actual, force_limit, csv.as_deref(), png.as_deref())?;
    outputs.commit()
}

fn write_outputs(
    a: &HilArgs,
    r: &HilRun,
    actual: f64,
    force_limit: f64,
    csv: Option<&Path>,
    png: Option<&Path>,
) -> Result<()> {
    if let Some(path) = csv {
        write_csv(path, &r.rows)?;
    }
    if let Some(path) = png {
        let title = format!(
            "virtual rig: {} (configured gap {:.2} mm, real {:.2} mm)",
            a.rig, a.gap_mm, actual
        );
        let model = r.prediction.as_ref().map(Target::from);
        rig_log::draw(path, &title, &r.rows, model.as_ref(), force_limit)?;
    }
    Ok(())
}

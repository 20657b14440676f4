//! `host-sim rig --port PATH …`: the rig as an instrument the desktop drives, over its serial
//! console (the board over USB-serial, the firmware under QEMU, or `hil --serve-pty`).

use std::io::BufRead as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result, bail, ensure};
use clap::{Args, Subcommand};
use shared::console::{Answer, Token};
use shared::control::{Command, ModelStatus};

use crate::figures::response::{MEAN_PEAK_FORCE, ResponsePoint, response};
use crate::figures::rig_log;
use crate::output::{Outputs, distinct_files, given, write_csv, write_whole};
use crate::rig_link::capture::{capture, write_trace};
use crate::rig_link::log::{Log, record};
use crate::rig_link::sweep::{SweepEnd, check};
use crate::rig_link::sweep::{
    SweepOutcome, SweepPoint, SweepSpec, parse_range, partial_path, sweep,
};
use crate::rig_link::{DEFAULT_LINK_TIMEOUT_S, LinkOptions, RigPort, check_reply, model};
use crate::virtual_rig::CycleRow;
use crate::virtual_rig::scenario::Scenario;
use shared::console::Request;
use shared::model::params_hash;

/// Arguments of `rig`.
#[derive(Debug, Args)]
pub struct RigArgs {
    /// The rig's console: a serial device (USB-serial adapter, `/dev/ttyACM0`), QEMU's pty or
    /// `hil --serve-pty`'s (`/dev/pts/N`).
    #[arg(long, value_name = "PATH")]
    pub port: PathBuf,
    /// Baud rate of the console (8N1).
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// How long to wait for a reply, s (0.1 ..= 60).
    #[arg(long, default_value_t = 2.0)]
    pub timeout_s: f64,
    /// The rig's link-loss watchdog while this command runs, s (0: off, else 1 ..= 3600): the
    /// rig stops its drive when no line comes for this long (this program sends a keep-alive
    /// every quarter of it), so a desktop that dies never leaves the shaker running.
    #[arg(long, default_value_t = f64::from(DEFAULT_LINK_TIMEOUT_S))]
    pub link_timeout_s: f64,
    /// What to do.
    #[command(subcommand)]
    pub what: RigCommand,
}

/// The `rig` subcommands.
#[derive(Debug, Subcommand)]
pub enum RigCommand {
    /// Send console lines, print each reply; stop with a non-zero exit at the first
    /// `error: …` reply.
    Send(SendArgs),
    /// Interactive: lines from stdin, replies (and asynchronous lines) to stdout.
    Console(ConsoleArgs),
    /// Run the timed `[[commands]]` of a virtual-rig scenario on the rig (times are rig time,
    /// by the rig's own clock).
    Run(RunArgs),
    /// Record the per-cycle telemetry for a span of rig time: CSV (the `hil` log's columns for
    /// what the rig measures) and figure.
    Log(LogArgs),
    /// Record a drop test with the rig's force capture: a `t_s,force_n` trace for
    /// `identify contact --trace`.
    Capture(CaptureArgs),
    /// Measure a frequency response: dwell at each frequency, record the mean peak force
    /// (F_i/mg) and the regime; a file `compare --experiment` reads.
    Sweep(SweepArgs),
    /// The rig's own model and calibration: show them, pull them into a TOML file, or push one
    /// (the TOML `identify` writes and `select --config` reads) as one change, verified.
    Model(ModelArgs),
    /// The board commissions itself: sensor check at rest, a drop test (release the hammer
    /// when told) identified on the board, its selection on the identified model, a verification
    /// at the target; then the model is stored if accepted. One line per step.
    Commission(CommissionArgs),
}

/// `rig commission`.
#[derive(Debug, Args)]
pub struct CommissionArgs {
    /// Store the model when its verification passes, without asking.
    #[arg(long, conflicts_with = "decline")]
    pub accept: bool,
    /// Keep the model the rig ran before whatever the verification says (a dry run).
    #[arg(long)]
    pub decline: bool,
}

/// `rig model`.
#[derive(Debug, Args)]
pub struct ModelArgs {
    /// What to do.
    #[command(subcommand)]
    pub what: ModelCommand,
}

/// `rig model` subcommands.
#[derive(Debug, Subcommand)]
pub enum ModelCommand {
    /// The active model, calibration and store, as the rig says them.
    Show,
    /// The active model and calibration into a TOML file (`[rig]` with every field,
    /// `[calibration]`): what `select --config` and `rig model push --config` read.
    Pull {
        /// The TOML file.
        #[arg(long, value_parser = crate::output::out_target)]
        out: PathBuf,
    },
    /// A model (a preset with `--law`, `--damping-ratio` and `--config` over it, as `select`
    /// builds it) and the config's `[calibration]` (if it has one) to the rig, all fields or
    /// none, refused while the drive runs; verified by reading the model back.
    Push {
        /// The preset the model starts from.
        #[arg(long, value_parser = crate::config::rig_parser(), default_value = "wires")]
        rig: shared::model::RigId,
        /// The contact law (default: the preset's).
        #[arg(long, value_parser = crate::config::parse_law)]
        law: Option<shared::model::ContactLawKind>,
        /// TOML file: `[rig]` over the preset, `[calibration]` over the firmware's defaults.
        #[arg(long, value_name = "FILE.toml")]
        config: Option<PathBuf>,
        /// The suspension's damping ratio ζ, 0 ≤ ζ < 1 (over the preset's and `--config`'s).
        #[arg(long, value_name = "ZETA")]
        damping_ratio: Option<f64>,
        /// Then keep it in the rig's flash (`save`), so that it survives a reset.
        #[arg(long)]
        save: bool,
    },
}

/// `rig send`.
#[derive(Debug, Args)]
pub struct SendArgs {
    /// Console lines, sent in order (quote lines with spaces: "gap 0.5").
    #[arg(required = true, value_name = "LINE")]
    pub lines: Vec<String>,
    /// Print each reply as it came, unchecked (otherwise a reply that does not read, or is of
    /// another kind than its line gets, is an error naming the field).
    #[arg(long)]
    pub raw: bool,
}

/// `rig console`.
#[derive(Debug, Args)]
pub struct ConsoleArgs {
    /// Turn streaming on and print the telemetry and event lines as they arrive.
    #[arg(long)]
    pub telemetry: bool,
}

/// `rig run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Scenario TOML with `[[commands]]` only (every other table is the virtual rig's and is
    /// refused); a refused command ends the run and stops the drive.
    #[arg(long, value_name = "FILE.toml")]
    pub scenario: PathBuf,
}

/// `rig log`.
#[derive(Debug, Args)]
pub struct LogArgs {
    /// Rig time to record, s (0 < s ≤ 86400).
    #[arg(long)]
    pub seconds: f64,
    /// CSV, one row per drive cycle.
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: PathBuf,
    /// PNG or SVG: frequency, measured peak force and state against time.
    #[arg(long, value_parser = crate::output::figure_target)]
    pub plot: Option<PathBuf>,
}

/// `rig capture`.
#[derive(Debug, Args)]
pub struct CaptureArgs {
    /// The trace: `t_s,force_n` (N on the rig's calibration from `id`).
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: PathBuf,
    /// Trigger level, N (0.1 ..= 100).
    #[arg(long, default_value_t = 1.0)]
    pub level_n: f64,
    /// Capture time from arming, s of rig time (0.01 ..= 60): release the hammer within it.
    #[arg(long, default_value_t = 2.0)]
    pub seconds: f64,
}

/// `rig sweep`.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// Frequencies START:END:STEP, Hz (inside the rig's safe window, `id`'s freq_window_hz).
    #[arg(long, value_name = "A:B:STEP")]
    pub freq_hz: String,
    /// Cycles recorded per frequency (2 ..= 10000: the regime is read from two at least).
    #[arg(long, default_value_t = 16)]
    pub dwell_cycles: u32,
    /// Cycles skipped after each frequency change (the transient).
    #[arg(long, default_value_t = 10)]
    pub settle_cycles: u32,
    /// CSV: freq_hz, impact_force_mg, impact_force_n, regime, cycles, impact_cycles. A sweep
    /// ended by a fault writes what it measured to `<name>.partial.csv` instead.
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: PathBuf,
    /// PNG or SVG: F_i/mg against Ω/ω (ω of the rig's preset), coloured by regime.
    #[arg(long, value_parser = crate::output::figure_target)]
    pub plot: Option<PathBuf>,
}

/// Runs `rig`. Every subcommand arms the port's drive guard: an error, Ctrl-C, SIGTERM or
/// SIGHUP stops the drive (the outcome printed) before the command exits non-zero; a command
/// that ends as planned leaves the drive as it commanded it.
///
/// # Errors
/// Bad arguments, a link failure, a refused command, a sweep ended early, an interruption.
pub fn run(a: &RigArgs) -> Result<()> {
    check_link(a)?;
    match &a.what {
        RigCommand::Send(s) => send(a, s),
        RigCommand::Console(c) => console(a, c),
        RigCommand::Run(r) => run_commands(a, r),
        RigCommand::Log(l) => log(a, l),
        RigCommand::Capture(c) => capture_drop(a, c),
        RigCommand::Sweep(s) => measure_sweep(a, s),
        RigCommand::Model(m) => rig_model(a, &m.what),
        RigCommand::Commission(c) => run_commission(a, c),
    }
}

/// `rig commission`: the board's sequence, one line per record on stdout; without `--accept`
/// or `--decline` the operator is asked at the accept step (no terminal, or no answer within
/// the board's window: declined). Exits non-zero unless the model was stored or declined.
fn run_commission(a: &RigArgs, c: &CommissionArgs) -> Result<()> {
    use crate::rig_link::commission::{Decision, Outcome, commission, describe, summary};
    use std::io::IsTerminal as _;
    let decision = if c.accept {
        Decision::Accept
    } else if c.decline || !std::io::stdin().is_terminal() {
        Decision::Decline
    } else {
        Decision::Ask {
            wait: Duration::from_secs_f32(shared::commission::ACCEPT_WINDOW_S - 30.0),
        }
    };
    let mut port = connect(a)?;
    let outcome = commission(&mut port, decision, |n| {
        println!("commission: {}", describe(&n.progress));
    })?;
    port.release_drive();
    println!("{}", summary(&outcome));
    match outcome {
        Outcome::Stored { .. } => Ok(()),
        Outcome::Kept {
            reason: shared::commission::EndReason::Aborted,
            at: shared::commission::Step::Accept,
        } if !c.accept => Ok(()),
        _ => bail!("{}", summary(&outcome)),
    }
}

/// `rig model show|pull|push`.
fn rig_model(a: &RigArgs, what: &ModelCommand) -> Result<()> {
    match what {
        ModelCommand::Show => {
            let mut port = connect(a)?;
            for request in [Request::Model, Request::Calib, Request::Store] {
                let answer = port.request_ok(&request)?;
                println!("{answer}");
            }
            port.release_drive();
        }
        ModelCommand::Pull { out } => {
            distinct_files(&[("--port", a.port.as_path())], &[("--out", out.as_path())])?;
            let mut port = connect(a)?;
            let (params, source, calibration, gap_mm) = model::pull(&mut port)?;
            let comment = format!(
                "host-sim rig model pull: the rig's {} model (rig_hash {:08x}) and calibration\n\
                 at gap {gap_mm} mm; {}",
                source.token(),
                params_hash(&params),
                port.id_line()
            );
            let text = model::toml_text(&comment, &params, &calibration)?;
            write_whole(out, |tmp| {
                std::fs::write(tmp, &text).with_context(|| format!("writing {}", out.display()))
            })?;
            println!(
                "wrote {}: the rig's {} model, rig_hash {:08x}",
                out.display(),
                source.token(),
                params_hash(&params)
            );
            port.release_drive();
        }
        ModelCommand::Push {
            rig,
            law,
            config,
            damping_ratio,
            save,
        } => {
            let mut opts = crate::config::RigOpts::preset(*rig);
            opts.law = *law;
            opts.config.clone_from(config);
            opts.damping_ratio = *damping_ratio;
            let setup = crate::config::Setup::from_opts(&opts)?;
            let mut port = connect(a)?;
            // The rig would compute the same selection (the on-target profile): a model that
            // finds no operating point is refused here, before the rig's model changes.
            let gap_mm = port.status()?.gap_mm;
            if let Err(e) = shared::control::predict(&setup.params, gap_mm) {
                return Err(port.refuse(anyhow::anyhow!(
                    "the model finds no operating point at the rig's gap of {gap_mm} mm ({e}): \
                     not pushed, the rig's model is unchanged"
                )));
            }
            let pushed = model::push(&mut port, &setup.params, setup.calibration.as_ref(), *save)?;
            println!(
                "pushed the model (rig_hash {:08x}){}{}",
                pushed.hash,
                if setup.calibration.is_some() {
                    " and the calibration"
                } else {
                    ""
                },
                match pushed.saved {
                    Some(s) => format!("; saved (save {})", s.saves),
                    None => "; not saved (`rig send save` keeps it across a reset)".into(),
                }
            );
            port.release_drive();
        }
    }
    Ok(())
}

/// The link's flags, checked before anything else.
fn check_link(a: &RigArgs) -> Result<()> {
    ensure!(
        a.timeout_s.is_finite() && (0.1..=60.0).contains(&a.timeout_s),
        "--timeout-s = {} is out of range: allowed 0.1 ..= 60",
        a.timeout_s
    );
    ensure!(
        (300..=4_000_000).contains(&a.baud),
        "--baud = {} is out of range: allowed 300 ..= 4000000",
        a.baud
    );
    ensure!(
        a.link_timeout_s == 0.0
            || (a.link_timeout_s.is_finite() && (1.0..=3600.0).contains(&a.link_timeout_s)),
        "--link-timeout-s = {} is out of range: allowed 0 (off) or 1 ..= 3600",
        a.link_timeout_s
    );
    Ok(())
}

/// The port, connected, with its drive guard armed.
fn connect(a: &RigArgs) -> Result<RigPort> {
    let opts = LinkOptions {
        baud: a.baud,
        timeout: Duration::from_secs_f64(a.timeout_s),
        link_timeout_s: a.link_timeout_s as f32,
    };
    let mut port = RigPort::open(&a.port, opts)?;
    port.guard_drive();
    Ok(port)
}

/// The longest wait for the next telemetry line.
fn quiet(a: &RigArgs) -> Duration {
    Duration::from_secs_f64((5.0f64).max(3.0 * a.timeout_s))
}

/// Output files that must differ from the port and from each other.
fn check_outputs(a: &RigArgs, out: &Path, plot: Option<&Path>) -> Result<()> {
    distinct_files(
        &[("--port", a.port.as_path())],
        &given(&[("--out", Some(out)), ("--plot", plot)]),
    )
}

/// `rig send`: every reply checked ([`RigPort::send_checked`]) before it is printed, unless
/// `--raw`.
fn send(a: &RigArgs, s: &SendArgs) -> Result<()> {
    // Every line is one request, or none is sent.
    for line in &s.lines {
        crate::rig_link::request_line(line)?;
    }
    let mut port = connect(a)?;
    for line in &s.lines {
        let refused = if s.raw {
            let reply = port.send_line(line)?;
            println!("{reply}");
            reply.starts_with("error:")
        } else {
            let (reply, answer) = port
                .send_checked(line)
                .context("the reply is not printed (`--raw` prints it unchecked)")?;
            println!("{reply}");
            matches!(answer, Answer::Error(_))
        };
        if refused {
            // A refusal is the rig's answer, not a failure of the link: the drive stays as
            // the lines left it.
            port.release_drive();
            bail!("the rig refused `{line}`");
        }
    }
    port.release_drive();
    Ok(())
}

/// `rig run`: the scenario's commands at their rig times.
fn run_commands(a: &RigArgs, r: &RunArgs) -> Result<()> {
    let commands = scenario_commands(&r.scenario)?;
    let mut port = connect(a)?;
    run_scenario(&mut port, commands)?;
    port.release_drive();
    Ok(())
}

/// `rig log`: records, then writes its files (created only then: a run killed while it
/// records leaves none).
fn log(a: &RigArgs, l: &LogArgs) -> Result<()> {
    check_outputs(a, &l.out, l.plot.as_deref())?;
    ensure!(
        l.seconds.is_finite() && l.seconds > 0.0 && l.seconds <= 86_400.0,
        "--seconds = {} is out of range: allowed (0, 86400]",
        l.seconds
    );
    let mut port = connect(a)?;
    // The model's target and band, for the figure (as the status says them now).
    let model = match port.status()?.model {
        ModelStatus::Ready(t) => Some(t),
        ModelStatus::Pending | ModelStatus::Failed => None,
    };
    eprintln!(
        "recording {} s of rig time (the files are written at the end; Ctrl-C ends it \
         without them)",
        l.seconds
    );
    let log = record(&mut port, l.seconds, quiet(a))?;
    println!(
        "{} cycles over {:.1} s of rig time; {} telemetry/event lines received, {} lost, {} duplicated, {} that did not read",
        log.rows.len(),
        log.rows.last().map_or(0.0, |r| r.t_s) - log.rows.first().map_or(0.0, |r| r.t_s),
        log.seq.received,
        log.seq.lost,
        log.seq.duplicates,
        port.garbled()
    );
    for e in &log.events {
        println!("{}", e.text);
    }
    let mut outputs = Outputs::new();
    let csv = outputs.reserve(&l.out)?;
    let png = l.plot.as_ref().map(|p| outputs.reserve(p)).transpose()?;
    write_csv(&csv, &log.rows)?;
    if let Some(p) = &png {
        let id = port.id();
        let title = format!(
            "rig log: {} ({} board, firmware {}), gap {:.2} mm",
            id.rig,
            id.board.token(),
            id.firmware,
            id.gap_mm
        );
        rig_log::draw(
            p,
            &title,
            &figure_rows(&log),
            model.as_ref(),
            f64::from(id.force_limit_n),
        )?;
    }
    outputs.commit()?;
    port.release_drive();
    Ok(())
}

/// `rig capture`: a drop test's force trace, written once recorded.
fn capture_drop(a: &RigArgs, c: &CaptureArgs) -> Result<()> {
    distinct_files(
        &[("--port", a.port.as_path())],
        &[("--out", c.out.as_path())],
    )?;
    ensure!(
        c.level_n.is_finite() && (0.1..=100.0).contains(&c.level_n),
        "--level-n = {} is out of range: allowed 0.1 ..= 100",
        c.level_n
    );
    ensure!(
        c.seconds.is_finite() && (0.01..=60.0).contains(&c.seconds),
        "--seconds = {} is out of range: allowed 0.01 ..= 60",
        c.seconds
    );
    let mut port = connect(a)?;
    let mut last = usize::MAX;
    let trace = capture(&mut port, c.level_n, c.seconds, quiet(a), |n| {
        if n != last {
            eprintln!("capture: {n} segments");
            last = n;
        }
    })?;
    write_whole(&c.out, |tmp| {
        write_trace(tmp, &trace, port.id_line(), c.level_n)
    })?;
    println!(
        "wrote {}: {} segments, {} samples at {} Hz",
        c.out.display(),
        trace.segments,
        trace.t_s.len(),
        port.id().capture_rate_hz
    );
    port.release_drive();
    Ok(())
}

/// `rig sweep`: the measured frequency response; a sweep that ends early writes what it
/// measured to the partial file, with the cause and the state the rig reported.
fn measure_sweep(a: &RigArgs, s: &SweepArgs) -> Result<()> {
    check_outputs(a, &s.out, s.plot.as_deref())?;
    crate::rig_link::sweep::check_cycles(s.dwell_cycles, s.settle_cycles)?;
    let spec = SweepSpec {
        freqs_hz: parse_range(&s.freq_hz)?,
        dwell_cycles: s.dwell_cycles,
        settle_cycles: s.settle_cycles,
        quiet: quiet(a),
    };
    let mut port = connect(a)?;
    check(&mut port, &spec)?;
    // The model the rig runs: the figure's Ω/ω and the sweep's deadlines are its.
    let model = match port.model() {
        Ok(m) => m,
        Err(e) => return Err(port.refuse(e)),
    };
    let n = spec.freqs_hz.len();
    let outcome = sweep(&mut port, &spec, |p| {
        println!(
            "{:8.4} Hz  F_i/mg {:7.2}  regime {:>9}  ({} of {} cycles impacted)",
            p.freq_hz, p.impact_force_mg, p.regime, p.impact_cycles, p.cycles
        );
    });
    let (points, at_hz, why) = match outcome {
        SweepOutcome::Complete(points) => {
            write_sweep(&s.out, s.plot.as_deref(), &points, &port, &model, None)?;
            port.release_drive();
            return Ok(());
        }
        SweepOutcome::Ended { points, at_hz, why } => (points, at_hz, why),
    };
    let partial = partial_path(&s.out);
    let (cause, error, drive) = match why {
        SweepEnd::Fault(f) => {
            // The rig ramps its drive to zero itself.
            port.release_drive();
            (
                format!("the fault `{}`", f.token()),
                None,
                "the rig ramps its drive to zero itself".to_string(),
            )
        }
        // The guard's stop now, so that the file says what the rig reported.
        SweepEnd::Failed(e) => (
            format!("{e:#}"),
            Some(e),
            match port.stop_now() {
                Ok(state) => state,
                Err(why) => why,
            },
        ),
    };
    let note = format!(
        "partial sweep: ended by {cause} at {at_hz} Hz; {} of {n} points; {drive}",
        points.len()
    );
    // A file of no points would be a record of nothing (not even a header).
    let written = if points.is_empty() {
        "no point was measured: nothing written".to_string()
    } else {
        write_sweep(&partial, None, &points, &port, &model, Some(&note))?;
        format!("the points so far are in {}", partial.display())
    };
    Err(match error {
        // An interruption keeps its kind (exit status 130).
        Some(e) if e.is::<crate::interrupt::Interrupted>() => e.context(written),
        _ => anyhow::anyhow!("{note}; {written}"),
    })
}

fn write_sweep(
    out: &Path,
    plot_path: Option<&Path>,
    points: &[SweepPoint],
    port: &RigPort,
    model: &shared::model::RigParams,
    note: Option<&str>,
) -> Result<()> {
    use std::io::Write as _;
    let mut outputs = Outputs::new();
    let csv = outputs.reserve(out)?;
    let png = plot_path.map(|p| outputs.reserve(p)).transpose()?;
    {
        let f = std::fs::File::create(&csv)?;
        let mut w = std::io::BufWriter::new(f);
        if let Some(n) = note {
            writeln!(w, "# {n}")?;
        }
        writeln!(w, "# host-sim rig sweep: {}", port.id_line())?;
        let mut c = csv::Writer::from_writer(w);
        for p in points {
            c.serialize(p)?;
        }
        c.flush()?;
    }
    if let Some(p) = &png {
        let id = port.id();
        let params = *model;
        let pts: Vec<ResponsePoint> = points
            .iter()
            .map(|q| ResponsePoint {
                omega_ratio: params.ratio_from_freq_hz(q.freq_hz),
                impact_force_mg: q.impact_force_mg,
                regime: q
                    .regime
                    .parse()
                    .unwrap_or(shared::observe::Regime::Irregular),
            })
            .collect();
        let title = format!(
            "measured frequency response: {} at {:.2} mm (ω/2π = {:.3} Hz, the rig's model)",
            id.rig,
            id.gap_mm,
            params.natural_freq_hz()
        );
        response(p, &title, &pts, None, MEAN_PEAK_FORCE)?;
    }
    outputs.commit()
}

/// The scenario's commands, refusing what only the virtual rig can do, and a file without
/// commands (the virtual rig's default `start` is not sent to a rig).
fn scenario_commands(path: &Path) -> Result<Vec<(f64, String)>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read --scenario {}", path.display()))?;
    let table: toml::Table = toml::from_str(&text)
        .with_context(|| format!("malformed --scenario {}", path.display()))?;
    let virtual_only: Vec<&str> = table
        .keys()
        .map(String::as_str)
        .filter(|k| *k != "commands")
        .collect();
    ensure!(
        virtual_only.is_empty(),
        "--scenario {}: {} belong to the virtual rig (`host-sim hil --scenario`: its plant, \
         chains, controller, injected faults and drops); a rig runs only [[commands]]: remove \
         them to run the commands",
        path.display(),
        virtual_only.join(", ")
    );
    let s = Scenario::from_file(path)?;
    ensure!(
        table.contains_key("commands") && !s.commands.is_empty(),
        "--scenario {}: no [[commands]] to run",
        path.display()
    );
    let mut c: Vec<(f64, String)> = s.commands.into_iter().map(|c| (c.at_s, c.line)).collect();
    c.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(c)
}

/// Sends each command at its rig time; a refused one ends the run (the guard stops the drive:
/// the lines after it were planned on its success).
fn run_scenario(port: &mut RigPort, commands: Vec<(f64, String)>) -> Result<()> {
    let t0 = port.uptime_s()?;
    for (at, line) in commands {
        loop {
            let t = port.uptime_s()? - t0;
            if t >= at {
                break;
            }
            std::thread::sleep(Duration::from_secs_f64(((at - t) / 4.0).clamp(0.002, 0.05)));
        }
        let t = port.uptime_s()? - t0;
        let (reply, answer) = port.send_checked(&line)?;
        println!("[{t:8.3} s] > {line}\n             {reply}");
        ensure!(
            !matches!(answer, Answer::Error(_)),
            "the rig refused `{line}` at {t:.3} s: the scenario ends there"
        );
    }
    Ok(())
}

/// `rig console`: lines from stdin, each reply checked before it is printed (a reply that
/// fails the check is said on stderr and the console goes on).
fn console(a: &RigArgs, c: &ConsoleArgs) -> Result<()> {
    let mut port = connect(a)?;
    console_lines(&mut port, c.telemetry)?;
    port.release_drive();
    Ok(())
}

fn console_lines(port: &mut RigPort, telemetry: bool) -> Result<()> {
    let (tx, rx) = std::sync::mpsc::channel::<Option<String>>();
    std::thread::spawn(move || {
        let stdin = std::io::stdin();
        for line in stdin.lock().lines() {
            match line {
                Ok(l) => {
                    if tx.send(Some(l)).is_err() {
                        return;
                    }
                }
                Err(_) => break,
            }
        }
        let _ = tx.send(None);
    });
    if telemetry {
        port.command(Command::Stream(true))?;
    }
    loop {
        crate::interrupt::check()?;
        while let Some(r) = port.next_record(Duration::ZERO)? {
            if telemetry {
                println!("{r}");
            }
        }
        match rx.recv_timeout(Duration::from_millis(50)) {
            Ok(Some(line)) => {
                let line = line.trim().to_string();
                if line.is_empty() {
                    continue;
                }
                // A line the rig would split is refused here; the console goes on.
                if let Err(e) = crate::rig_link::request_line(&line) {
                    println!("error: {e}");
                    continue;
                }
                // The link failing ends the console; a reply that fails its check is said
                // instead of printed, and the operator goes on.
                let reply = port.send_line(&line)?;
                match check_reply(&line, &reply) {
                    Ok(_) => println!("{reply}"),
                    Err(e) => eprintln!("error: {e:#}"),
                }
            }
            Ok(None) | Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
        }
    }
    if telemetry {
        port.command(Command::Stream(false)).context("stream off")?;
    }
    Ok(())
}

/// A rig log's rows as the `hil` figure draws them (no plant truth on a rig).
fn figure_rows(log: &Log) -> Vec<CycleRow> {
    log.rows
        .iter()
        .map(|r| CycleRow {
            t_s: r.t_s,
            state: r.state,
            freq_hz: r.freq_hz,
            amp_cmd_mm: r.amp_cmd_mm,
            cart_amp_mm: 0.0,
            measured_impacts: r.measured_impacts,
            measured_peak_n: r.measured_peak_n,
            true_impacts: 0,
            true_peak_n: None,
            measured_regime: r.measured_regime.clone(),
            fault: r.fault,
            lost_cycles: r.lost_cycles,
            force_vs_model_pct: None,
        })
        .collect()
}

//! Command-line interface (clap). Every command shares [`RigOpts`].

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};
use shared::model::{ContactLawKind, RigId};

use crate::commands;

/// Float type of the simulation.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// Single precision: the MCU's arithmetic (default).
    #[default]
    F32,
    /// Double precision (reference).
    F64,
}

/// Numerical profile: the analysis defaults, or the cheaper settings the firmware's model task
/// runs on the MCU (`SimSettings::embedded`, `SelectionSpec::embedded`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default)]
pub enum Profile {
    /// Analysis defaults: N = 64, K = 16, 200-period transient, Ω/ω 0.5:5.0:0.01 for `select`.
    #[default]
    Host,
    /// The firmware's on-target model: N = 32, K = 8, 40-period transient, q ≤ 4, 8-period
    /// window, Ω/ω 1.0:3.6:0.1 for `select` (gives the firmware's target bit for bit).
    Embedded,
}

/// The vibro-impact hammer of the thesis on the desktop: operating-frequency selection,
/// frequency responses, time series and batch evaluation, from the same `shared` code as the
/// rig's firmware.
#[derive(Debug, Parser)]
#[command(name = "host-sim", version, about, long_about = None)]
pub struct Cli {
    /// The command to run.
    #[command(subcommand)]
    pub command: Command,
}

/// Options that pick the rig and the numerics.
#[derive(Debug, Clone, Args)]
pub struct RigOpts {
    /// Rig: hammer on wires, or on beam springs with 170/150/135 mm couplings distance.
    #[arg(long, value_parser = parse_rig, default_value = "wires")]
    pub rig: RigId,
    /// Contact law (default: the identified spring–dashpot of Table 3.1).
    #[arg(long, value_parser = parse_law)]
    pub law: Option<ContactLawKind>,
    /// TOML file overriding any parameter: tables [rig], [settings], [selection].
    #[arg(long, value_name = "FILE.toml")]
    pub config: Option<PathBuf>,
    /// Float type of the simulation.
    #[arg(long, value_enum, default_value_t = Precision::F32)]
    pub precision: Precision,
    /// Numerical profile (defaults that `--config` then overrides).
    #[arg(long, value_enum, default_value_t = Profile::Host)]
    pub profile: Profile,
}

fn parse_rig(s: &str) -> Result<RigId, String> {
    s.parse().map_err(|e| format!("{e}"))
}

fn parse_law(s: &str) -> Result<ContactLawKind, String> {
    s.parse().map_err(|e| format!("{e}"))
}

/// The commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Pick the shaker operating frequency: the strongest z = 1/1 point that stays 1/1 for
    /// ±5 % in frequency and ±0.1 mm in gap (the main job).
    Select(commands::select::SelectArgs),
    /// Frequency response: max F_i/mg and regime per frequency, from rest (canonical protocol).
    Response(commands::response::ResponseArgs),
    /// Time series of one operating point: u, u̇, absolute x, F_i, Poincaré points.
    Simulate(commands::simulate::SimulateArgs),
    /// Batch evaluation of (gap_mm, omega_ratio) points from a CSV, in parallel.
    Points(commands::points::PointsArgs),
    /// Bifurcation diagram: Poincaré u and impact peaks F_i/mg vs Ω/ω, from rest or by
    /// continuation (up/down/both).
    Bifurcation(commands::bifurcation::BifurcationArgs),
    /// Peterka map: the impact regime over a gap × frequency grid, and the z = 1/1 force map.
    Peterka(commands::peterka::PeterkaArgs),
    /// Basins of attraction over a grid of initial conditions (u0, u̇0).
    Basins(commands::basins::BasinsArgs),
    /// Virtual rig: the firmware's controller in closed loop with a simulated hammer (drive and
    /// sensor chains, injected faults, console commands), no hardware.
    Hil(commands::hil::HilArgs),
    /// The rig from the desktop, over its serial console: send lines, an interactive console,
    /// a scenario's commands, a telemetry log, a drop-test capture, a frequency sweep.
    Rig(commands::rig::RigArgs),
    /// Join the shard CSVs of a peterka/basins/bifurcation run (--shard I/N) into its CSV and
    /// figures.
    Merge(commands::merge::MergeArgs),
    /// Identify parameters from measurements: the contact law from a drop test, the
    /// suspension from a free decay.
    Identify(commands::identify::IdentifyArgs),
    /// A drop test of the simulation (the hammer released at rest near the surface, no
    /// excitation) recorded like a force sensor: t_s, force_n, with optional noise and offset.
    Drop(commands::drop::DropArgs),
    /// Overlay a measured frequency response (F_i/mg vs Ω/ω) or time series (displacement,
    /// phase plane, Poincaré points) on the simulation, with an error summary.
    Compare(commands::compare::CompareArgs),
}

/// Runs the CLI; errors are printed as `error: …` with a non-zero exit status (130 after
/// Ctrl-C).
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Select(a) => commands::select::run(&a),
        Command::Response(a) => commands::response::run(&a),
        Command::Simulate(a) => commands::simulate::run(&a),
        Command::Points(a) => commands::points::run(&a),
        Command::Bifurcation(a) => commands::bifurcation::run(&a),
        Command::Peterka(a) => commands::peterka::run(&a),
        Command::Basins(a) => commands::basins::run(&a),
        Command::Merge(a) => commands::merge::run(&a),
        Command::Hil(a) => commands::hil::run_cmd(&a),
        Command::Rig(a) => commands::rig::run(&a),
        Command::Identify(a) => commands::identify::run(&a),
        Command::Drop(a) => commands::drop::run(&a),
        Command::Compare(a) => commands::compare::run(&a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            if e.downcast_ref::<crate::interrupt::Interrupted>().is_some() {
                ExitCode::from(130)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

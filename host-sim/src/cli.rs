//! Command-line interface (clap): the commands and `main`. Most commands flatten [`RigOpts`].

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::commands;
pub use crate::config::{Profile, RigOpts};
pub use crate::precision::Precision;

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
    ///
    /// --out: one row per Poincaré point or impact: index, branch, omega_ratio, freq_hz, regime,
    /// kind (strobe|impact), k (period of the window), u_mm, du_mm_s (strobes),
    /// impact_force_mg (impacts), lyapunov_per_period (the frequency's largest exponent).
    ///
    /// --plot: Poincaré u (mm) and impact peaks F_i/mg vs Ω/ω, two panels.
    Bifurcation(commands::bifurcation::BifurcationArgs),
    /// Peterka map: the impact regime over a gap × frequency grid, and the z = 1/1 force map.
    ///
    /// --out: one row per grid point (gap outer, frequency inner): index, gap_mm, gap_ratio,
    /// omega_ratio, freq_hz, regime, impacts, impact_force_mg, transient_periods, settled,
    /// lyapunov_per_period (with --lyapunov).
    ///
    /// --plot: regime over Ω/ω (x) and gap/A0 (y), one colour per regime (Fig. 3.24).
    Peterka(commands::peterka::PeterkaArgs),
    /// Basins of attraction over a grid of initial conditions (u0, u̇0).
    ///
    /// --out: one row per initial condition (u0 fastest): index, u0_mm, v0_mm_s, impacting,
    /// regime, attractor, attractor_u_mm, attractor_v_mm_s, impacts, impact_force_mg, settled,
    /// recurrence (a shard writes the ungrouped rows; `merge` groups them).
    ///
    /// Attractors are found by recurrence on the stroboscopic map against a catalogue of
    /// known ones (a trajectory that never recurs is counted as such).
    ///
    /// --plot: u0 (x) × u̇0 (y) coloured by attractor (or --color-by regime / impact),
    /// attractor points marked.
    Basins(commands::basins::BasinsArgs),
    /// Basin fractions: the share of random initial conditions in a box ending on each
    /// attractor, with 95 % intervals, at one point or continued over Ω/ω or the gap.
    ///
    /// --plot: the fractions stacked against the parameter, one colour per attractor (kept
    /// along the parameter), with their 95 % intervals.
    Fractions(commands::fractions::FractionsArgs),
    /// The periodic orbit at one point: Newton's method (shooting) from where the protocol
    /// settles, with its Floquet multipliers, stability margin and Lyapunov exponent.
    Orbit(commands::orbit::OrbitArgs),
    /// Continue a branch of periodic orbits in Ω/ω or the gap from the orbit at a point (stable
    /// and unstable, round folds), locating its bifurcations: fold, period doubling,
    /// Neimark–Sacker, grazing; CSV, figure over the brute-force diagram, JSON.
    Continue(commands::continuation::ContinueArgs),
    /// Virtual rig: the firmware's controller in closed loop with a simulated hammer (drive and
    /// sensor chains, injected faults, console commands), no hardware.
    Hil(commands::hil::HilArgs),
    /// The rig from the desktop, over its serial console: send lines, an interactive console,
    /// a scenario's commands, a telemetry log, a drop-test capture, a frequency sweep.
    Rig(commands::rig::RigArgs),
    /// Join the shard CSVs of a peterka/basins/fractions/bifurcation run (--shard I/N) into its CSV and
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
    let cli = Cli::parse_from(negative_values_attached(std::env::args_os()));
    // A variable that asks for vector instructions this CPU lacks is refused, not ignored.
    if let Err(e) = shared::integrate::check_isa_var() {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Select(a) => commands::select::run(&a),
        Command::Response(a) => commands::response::run(&a),
        Command::Simulate(a) => commands::simulate::run(&a),
        Command::Points(a) => commands::points::run(&a),
        Command::Bifurcation(a) => commands::bifurcation::run(&a),
        Command::Peterka(a) => commands::peterka::run(&a),
        Command::Basins(a) => commands::basins::run(&a),
        Command::Fractions(a) => commands::fractions::run(&a),
        Command::Merge(a) => commands::merge::run(&a),
        Command::Orbit(a) => commands::orbit::run(&a),
        Command::Continue(a) => commands::continuation::run(&a),
        Command::Hil(a) => commands::hil::run(&a),
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

/// The command line with every value that starts like a negative number (`-3.2e-05`,
/// `-4:1.335:200`, `-.5`) attached to the long option before it (`--u0-mm=-3.2e-05`): clap
/// takes `-3.2` as a value but not `-3.2e-05`, which it reads as an unknown option.
pub fn negative_values_attached(
    args: impl IntoIterator<Item = std::ffi::OsString>,
) -> Vec<std::ffi::OsString> {
    let mut out: Vec<std::ffi::OsString> = Vec::new();
    for arg in args {
        let negative = arg.to_str().is_some_and(|s| {
            let mut c = s.chars();
            c.next() == Some('-') && c.next().is_some_and(|d| d.is_ascii_digit() || d == '.')
        });
        let after_option = out
            .last()
            .and_then(|p| p.to_str())
            .is_some_and(|p| p.starts_with("--") && p.len() > 2 && !p.contains('='));
        match (negative, after_option, out.last_mut()) {
            (true, true, Some(prev)) => {
                prev.push("=");
                prev.push(&arg);
            }
            _ => out.push(arg),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    use super::Cli;
    use crate::grid::{basins, bifurcation, peterka};
    use crate::shard::header;

    /// The CSV columns each grid command's `--help` lists are its row's fields, in order.
    #[test]
    fn grid_help_lists_the_csv_columns() {
        let cli = Cli::command();
        for (name, columns) in [
            ("peterka", header::<peterka::PeterkaRow>()),
            ("basins", header::<basins::BasinRow>()),
            ("bifurcation", header::<bifurcation::BifRow>()),
        ] {
            let about = cli
                .find_subcommand(name)
                .and_then(|c| c.get_long_about())
                .unwrap()
                .to_string();
            let words: Vec<&str> = about
                .split(|c: char| !(c.is_alphanumeric() || c == '_'))
                .filter(|w| !w.is_empty())
                .collect();
            let mut at = 0;
            for col in columns {
                let found = words[at..].iter().position(|w| w == col);
                assert!(
                    found.is_some(),
                    "{name}: `{col}` not listed in order in {about}"
                );
                at += found.unwrap_or(0) + 1;
            }
        }
    }

    #[test]
    fn negative_numbers_in_e_notation_are_values() {
        use clap::Parser;
        let words = |s: &str| super::negative_values_attached(s.split(' ').map(Into::into));
        let args = words(
            "host-sim simulate --gap-mm 1 --omega-ratio 2 --u0-mm -3.2e-05 --v0-mm-s -.5 --out x.csv",
        );
        let cli = Cli::try_parse_from(&args).unwrap();
        let super::Command::Simulate(a) = cli.command else {
            panic!("{args:?}")
        };
        assert_eq!((a.start.u0_mm, a.start.v0_mm_s), (-3.2e-5, -0.5));
        // A sweep starting below zero, and an option that already has its value.
        let args = words("host-sim basins --u0-mm -4e-1:1:3 --v0-mm-s=-1:1:3");
        assert_eq!(args[2], "--u0-mm=-4e-1:1:3");
        assert_eq!(args[3], "--v0-mm-s=-1:1:3");
    }
}

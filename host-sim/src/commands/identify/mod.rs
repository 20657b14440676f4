//! `host-sim identify contact|free`: the contact law from a drop test, the suspension from a
//! free decay (thesis §3.3.2, Eq. 3-34).

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, Subcommand};
use shared::model::{ContactLaw, ContactLawKind, RigId};

use super::TimeOpts;
use crate::identify::cost::FitError;
use crate::identify::uncertainty::IntervalMethod;
use crate::trace::{ForceUnit, MotionUnit};

mod contact;
mod free;

/// Arguments of `identify`.
#[derive(Debug, Args)]
pub struct IdentifyArgs {
    /// What to identify.
    #[command(subcommand)]
    pub what: IdentifyCommand,
}

/// The identifications.
#[derive(Debug, Subcommand)]
pub enum IdentifyCommand {
    /// Fit a contact law's parameters to a measured drop test (force–time trace, several
    /// impacts) by Nelder–Mead, like the thesis' fminsearch on the peak forces.
    Contact(ContactArgs),
    /// Natural frequency and damping ratio from a free-decay record → k = m ω² (Eq. 3-34),
    /// c = 2 ζ m ω.
    Free(FreeArgs),
}

/// `--law`: one law or `all`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LawChoice {
    /// One law.
    One(ContactLawKind),
    /// Every law, compared.
    All,
}

fn parse_law_choice(s: &str) -> Result<LawChoice, String> {
    if s == "all" {
        return Ok(LawChoice::All);
    }
    s.parse()
        .map(LawChoice::One)
        .map_err(|e| format!("{e}, or all"))
}

/// The names `--law` takes: every law's (`ContactLawKind::ALL`), then `all`.
fn law_choices() -> Vec<&'static str> {
    let mut names = crate::config::law_names();
    names.push("all");
    names
}

/// Arguments of `identify contact`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct ContactArgs {
    /// Measured drop test: CSV with a time column (or a sample rate) and a force column.
    /// Repeat for a joint fit of several drop tests (e.g. two release heights): one parameter
    /// set, the error summed over the traces.
    #[arg(long, value_name = "FILE.csv", required = true)]
    pub trace: Vec<PathBuf>,
    /// Hammer mass, kg (0 < m ≤ 1000).
    #[arg(long)]
    pub mass_kg: f64,
    /// Contact law to fit, or all (Lankarani–Nikravesh is valid near e = 1 only: it rebounds at
    /// 0.663 or more whatever its e).
    #[arg(long, value_parser = crate::config::NamedValues::new(parse_law_choice, law_choices))]
    pub law: LawChoice,
    /// Distance from the surface at which the hammer was released at rest, mm. One value for
    /// every trace, or one per --trace in the same order.
    #[arg(long, default_values_t = [3.0])]
    pub release_mm: Vec<f64>,
    /// Gap between the hammer's rest position and the surface during the test, mm.
    #[arg(long, default_value_t = 0.0)]
    pub gap_mm: f64,
    /// Write the fit even when a trace's first impulse contradicts its release, mass and force
    /// unit by more than 3× (`--mass-kg` in grams, a force in kN read as N): otherwise refused,
    /// nothing written.
    #[arg(long)]
    pub allow_contradiction: bool,
    /// Suspension of the hammer during the test (the free flight between impacts).
    #[arg(long, value_parser = crate::config::rig_parser(), default_value = "wires")]
    pub rig: RigId,
    /// TOML file overriding rig parameters (e.g. the output of `identify free`).
    #[arg(long, value_name = "FILE.toml")]
    pub config: Option<PathBuf>,
    /// The error to minimise: peaks (peak forces and impact times, the thesis'), profile (also
    /// the whole force profile of every impact), or auto: the profile where every trace
    /// resolves the contact (≥ 8 samples per contact), peaks otherwise.
    #[arg(long, value_enum, default_value = "auto")]
    pub error: FitError,
    /// How the 95 % intervals are made: scaled (the noise bootstrap widened by the reduced χ²
    /// when the law misses the data) or noise (the sensor noise alone, no model error).
    #[arg(long, value_enum, default_value = "scaled")]
    pub intervals: IntervalMethod,
    /// Weight of the impact-time term (0 ignores the times).
    #[arg(long, default_value_t = 1.0)]
    pub time_weight: f64,
    /// Use at most this many impacts of the trace (1..=50).
    #[arg(long, default_value_t = 6)]
    pub max_impacts: u32,
    /// Time column, unit or sample rate.
    #[command(flatten)]
    pub time: TimeOpts,
    /// Force column: header name or 1-based number.
    #[arg(long, default_value = "force_n")]
    pub force_col: String,
    /// Unit of the force column.
    #[arg(long, value_enum, default_value = "N")]
    pub force_unit: ForceUnit,
    /// Config file with the fitted law (the best one with --law all), for --config of the
    /// other commands.
    #[arg(value_parser = crate::output::out_target, long, value_name = "FILE.toml")]
    pub out: Option<PathBuf>,
    /// PNG or SVG: the measured trace and the fitted simulation(s), whole and impact by impact.
    #[arg(value_parser = crate::output::figure_target, long, value_name = "FILE.png|svg")]
    pub plot: Option<PathBuf>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `identify free`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct FreeArgs {
    /// Free-decay record: CSV with a time column (or a sample rate) and a displacement or
    /// acceleration column.
    #[arg(long, value_name = "FILE.csv")]
    pub trace: PathBuf,
    /// Hammer mass, kg (0 < m ≤ 1000).
    #[arg(long)]
    pub mass_kg: f64,
    /// Time column, unit or sample rate.
    #[command(flatten)]
    pub time: TimeOpts,
    /// Signal column: header name or 1-based number [default: 2, or the only column of a
    /// one-column file read with --sample-rate-hz or a stated rate].
    #[arg(long)]
    pub value_col: Option<String>,
    /// Unit of the signal column: a displacement (m, mm, um) or an acceleration (m/s2, g).
    #[arg(long, value_enum, default_value = "mm")]
    pub unit: MotionUnit,
    /// Rig whose suspension the config file sets: a beam preset (natural frequency and
    /// damping ratio) or wires (pendulum length g/ω² and the damping ratio ζ of the project's
    /// viscous term −2ζω θ̇; the `wires` preset is the thesis' undamped model).
    #[arg(long, value_parser = crate::config::rig_parser(), default_value = "beam-170")]
    pub rig: RigId,
    /// Config file with the mass and the identified suspension.
    #[arg(value_parser = crate::output::out_target, long, value_name = "FILE.toml")]
    pub out: Option<PathBuf>,
    /// Print one JSON object instead of the text.
    #[arg(long)]
    pub json: bool,
}

/// Runs `identify`.
///
/// # Errors
/// Bad input or I/O failure.
pub fn run(a: &IdentifyArgs) -> Result<()> {
    match &a.what {
        IdentifyCommand::Contact(c) => contact::run(c),
        IdentifyCommand::Free(f) => free::run(f),
    }
}

/// The fitted parameters of a law as text, with units.
pub fn describe_law(law: &ContactLaw) -> String {
    match *law {
        ContactLaw::SpringDashpot {
            stiffness_n_m,
            damping_n_s_m,
        } => format!("k_i = {stiffness_n_m:.4e} N/m, c_i = {damping_n_s_m:.4e} N s/m"),
        ContactLaw::Hertz {
            stiffness,
            exponent,
        } => format!("k_i = {stiffness:.4e} N/m^{exponent:.3}, n = {exponent:.4}"),
        ContactLaw::HuntCrossley {
            stiffness,
            exponent,
            lambda_s_m,
        } => format!(
            "k_i = {stiffness:.4e} N/m^{exponent:.3}, n = {exponent:.4}, λ_i = {lambda_s_m:.4} s/m"
        ),
        ContactLaw::LankaraniNikravesh {
            stiffness,
            exponent,
            restitution,
        } => format!(
            "k_i = {stiffness:.4e} N/m^{exponent:.3}, n = {exponent:.4}, e = {restitution:.4}"
        ),
    }
}

/// Bad pairing of the repeated `identify contact` options.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum PairingError {
    /// `--release-mm` given neither once nor once per `--trace`.
    #[error(
        "`release_mm`: {given} values for {traces} traces: give one (for every trace) or one \
         per --trace, in the same order"
    )]
    ReleaseCount {
        /// Number of `--release-mm` values.
        given: usize,
        /// Number of `--trace` files.
        traces: usize,
    },
}

/// The release distance of each of `traces` traces, mm: `release_mm` itself if it has one value
/// per trace, its single value repeated if it has one.
///
/// # Errors
/// [`PairingError::ReleaseCount`] for any other count.
pub fn pair_releases(release_mm: &[f64], traces: usize) -> Result<Vec<f64>, PairingError> {
    match release_mm.len() {
        1 => Ok(vec![release_mm[0]; traces]),
        n if n == traces => Ok(release_mm.to_vec()),
        given => Err(PairingError::ReleaseCount { given, traces }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn releases_pair_with_the_traces_in_order_or_one_for_all() {
        assert_eq!(pair_releases(&[3.0], 2), Ok(vec![3.0, 3.0]));
        assert_eq!(pair_releases(&[0.25, 3.0], 2), Ok(vec![0.25, 3.0]));
        assert_eq!(pair_releases(&[3.0], 1), Ok(vec![3.0]));
        let e = pair_releases(&[1.0, 2.0, 3.0], 2).unwrap_err();
        assert_eq!(
            e,
            PairingError::ReleaseCount {
                given: 3,
                traces: 2
            }
        );
        assert!(e.to_string().contains("release_mm"), "{e}");
    }
}

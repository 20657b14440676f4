//! `host-sim identify contact|free`: the contact law from a drop test, the suspension from a
//! free decay (thesis §3.3.2, Eq. 3-34).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use serde::Serialize;
use shared::error::check_range;
use shared::model::{ContactLaw, ContactLawKind, RigId};

use super::TimeOpts;
use crate::config::{MAX_GAP_MM, Setup, config_text};
use crate::identify::contact::{
    DropData, DropSetup, DropTest, FIT_STEPS, Fit, FitError, Residual, Weights, analyse_drop,
    best_by_aic, fit_laws,
};
use crate::identify::free::{FreeDecay, identify_free};
use crate::identify::uncertainty::{STRONG_CORRELATION, Uncertainty, WIDE_REL};
use crate::output::Outputs;
use crate::plot_identify;
use crate::trace::{ForceUnit, MotionUnit, read_trace};

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
    /// Contact law to fit: hertz, spring-dashpot, hunt-crossley, lankarani-nikravesh, or all.
    #[arg(long, value_parser = parse_law_choice)]
    pub law: LawChoice,
    /// Distance from the surface at which the hammer was released at rest, mm. One value for
    /// every trace, or one per --trace in the same order.
    #[arg(long, default_values_t = [3.0])]
    pub release_mm: Vec<f64>,
    /// Gap between the hammer's rest position and the surface during the test, mm.
    #[arg(long, default_value_t = 0.0)]
    pub gap_mm: f64,
    /// Suspension of the hammer during the test (the free flight between impacts).
    #[arg(long, value_parser = crate::config::parse_rig, default_value = "wires")]
    pub rig: RigId,
    /// TOML file overriding rig parameters (e.g. the output of `identify free`).
    #[arg(long, value_name = "FILE.toml")]
    pub config: Option<PathBuf>,
    /// The error to minimise: peaks (peak forces and impact times, the thesis'), profile (also
    /// the whole force profile of every impact), or auto: the profile where every trace
    /// resolves the contact (≥ 8 samples per contact), peaks otherwise.
    #[arg(long, value_enum, default_value = "auto")]
    pub error: FitError,
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
    #[arg(long, value_name = "FILE.toml")]
    pub out: Option<PathBuf>,
    /// PNG: the measured trace and the fitted simulation(s), whole and impact by impact.
    #[arg(long, value_name = "FILE.png")]
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
    /// Signal column: header name or 1-based number.
    #[arg(long, default_value = "2")]
    pub value_col: String,
    /// Unit of the signal column: a displacement (m, mm, um) or an acceleration (m/s2, g).
    #[arg(long, value_enum, default_value = "mm")]
    pub unit: MotionUnit,
    /// Rig whose suspension the config file sets: a beam preset (natural frequency and
    /// damping ratio) or wires (pendulum length g/ω², no damping in the model).
    #[arg(long, value_parser = crate::config::parse_rig, default_value = "beam-170")]
    pub rig: RigId,
    /// Config file with the mass and the identified suspension.
    #[arg(long, value_name = "FILE.toml")]
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
        IdentifyCommand::Contact(c) => run_contact(c),
        IdentifyCommand::Free(f) => run_free(f),
    }
}

/// The fitted parameters of a law as text, with units.
pub fn describe_law(law: &ContactLaw, mass_kg: f64) -> String {
    match *law {
        ContactLaw::SpringDashpot {
            stiffness_n_m,
            damping_n_s_m,
        } => {
            let mut s = format!("k_i = {stiffness_n_m:.4e} N/m, c_i = {damping_n_s_m:.4e} N s/m");
            if let Some((e, _)) = shared::model::contact::spring_dashpot_restitution(
                stiffness_n_m,
                damping_n_s_m,
                mass_kg,
            ) {
                let _ = write!(s, " (e = {e:.3})");
            }
            s
        }
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

#[derive(Serialize)]
struct LawReport {
    law: ContactLawKind,
    contact: ContactLaw,
    /// All traces together.
    residual: Residual,
    /// Per trace, in the order of `traces`.
    trace_residuals: Vec<Residual>,
    evaluations: u64,
    /// Akaike's information criterion on the error's terms, and its difference to the best.
    aic: f64,
    delta_aic: f64,
    /// 95 % intervals, correlations and identifiability notes (absent if not estimated).
    uncertainty: Option<Uncertainty>,
}

#[derive(Serialize)]
struct TraceReport {
    trace: String,
    release_mm: f64,
    samples: usize,
    offset_n: f64,
    noise_n: f64,
    impact_peaks_n: Vec<f64>,
}

#[derive(Serialize)]
struct ContactReport {
    /// The first trace's `samples`, `offset_n`, `noise_n`, `impact_peaks_n`.
    #[serde(flatten)]
    first: TraceReport,
    /// Every trace (the first one again).
    traces: Vec<TraceReport>,
    /// The error used (`auto` resolved).
    error: FitError,
    /// The error asked for.
    error_requested: FitError,
    /// The fewest samples per contact over the traces.
    samples_per_contact: f64,
    fits: Vec<LawReport>,
    best: ContactLawKind,
}

/// One `--trace` with its release distance and preprocessed data.
struct LoadedTrace {
    path: PathBuf,
    release_mm: f64,
    data: DropData,
}

impl LoadedTrace {
    fn report(&self) -> TraceReport {
        TraceReport {
            trace: self.path.display().to_string(),
            release_mm: self.release_mm,
            samples: self.data.t_s.len(),
            offset_n: self.data.offset_n,
            noise_n: self.data.noise_n,
            impact_peaks_n: self.data.impacts.iter().map(|i| i.peak_n).collect(),
        }
    }
}

fn run_contact(a: &ContactArgs) -> Result<()> {
    check_range("mass_kg", a.mass_kg, 1e-6, 1e3).context("--mass-kg")?;
    check_range("gap_mm", a.gap_mm, 0.0, MAX_GAP_MM).context("--gap-mm")?;
    let releases = pair_releases(&a.release_mm, a.trace.len()).context("--release-mm")?;
    for &r in &releases {
        check_range("release_mm", r, a.gap_mm + 1e-3, 100.0).context("--release-mm")?;
    }
    check_range("time_weight", a.time_weight, 0.0, 1e6).context("--time-weight")?;
    shared::error::check_count("max_impacts", a.max_impacts, 1, 50).context("--max-impacts")?;
    let setup = Setup::from_opts(&crate::config::RigOpts {
        rig: a.rig,
        law: None,
        config: a.config.clone(),
        precision: crate::precision::Precision::F64,
        profile: crate::config::Profile::Host,
    })?;
    let mut params = setup.params;
    params.mass_kg = a.mass_kg;
    params.validate().context("rig parameters")?;
    let mut loaded = Vec::with_capacity(a.trace.len());
    for (path, &release_mm) in a.trace.iter().zip(&releases) {
        let trace = read_trace(
            path,
            &a.time.format(&a.force_col, a.force_unit.to_n()),
            "force",
        )?;
        let data = analyse_drop(&trace, a.max_impacts as usize)
            .with_context(|| format!("trace {}", path.display()))?;
        loaded.push(LoadedTrace {
            path: path.clone(),
            release_mm,
            data,
        });
    }
    let tests: Vec<DropTest> = loaded
        .iter()
        .map(|l| DropTest {
            setup: DropSetup {
                params,
                gap_m: a.gap_mm * 1e-3,
                release_m: l.release_mm * 1e-3,
                steps: FIT_STEPS,
            },
            data: l.data.clone(),
        })
        .collect();
    let spc = loaded
        .iter()
        .map(|l| l.data.samples_per_contact())
        .fold(f64::INFINITY, f64::min);
    let error = a.error.resolve(spc);
    let weights = Weights {
        time: a.time_weight,
        profile: match error {
            FitError::Profile => 1.0,
            _ => 0.0,
        },
    };
    let laws: Vec<ContactLawKind> = match a.law {
        LawChoice::One(k) => vec![k],
        LawChoice::All => ContactLawKind::ALL.to_vec(),
    };
    let fits = fit_laws(&tests, &laws, weights, 400)?;
    let best = best_by_aic(&fits).context("no fit")?;
    let run = ContactRun {
        error,
        requested: a.error,
        samples_per_contact: spc,
    };
    let best_fit = &fits.iter().find(|f| f.0 == best).context("no fit")?.1;
    let files: Vec<String> = a.trace.iter().map(|p| p.display().to_string()).collect();
    let releases_text: Vec<String> = releases.iter().map(|r| r.to_string()).collect();
    let impacts: Vec<String> = loaded
        .iter()
        .map(|l| l.data.impacts.len().to_string())
        .collect();

    let mut outputs = Outputs::new();
    if let Some(p) = &a.out {
        let tmp = outputs.reserve(p)?;
        let mut out_params = params;
        out_params.contact = best_fit.law;
        let mut comment = format!(
            "host-sim identify contact: {} law fitted to {} ({} impacts, error: {}, release {} mm, \
             gap {} mm)\nresidual: peak rms {:.2} % of the {}largest peak, time rms {:.1} us, J = {:.3e}",
            best,
            files.join(" + "),
            impacts.join(" + "),
            error,
            releases_text.join(" + "),
            a.gap_mm,
            best_fit.residual.peak_rms_pct,
            if loaded.len() > 1 { "trace's " } else { "" },
            best_fit.residual.time_rms_us,
            best_fit.residual.cost
        );
        if let Ok(u) = &best_fit.uncertainty {
            for par in &u.params {
                let _ = write!(
                    comment,
                    "\n{} = {:.5e} {} (95 %: {:.5e} .. {:.5e})",
                    par.name, par.value, par.unit, par.ci95[0], par.ci95[1]
                );
            }
            for n in &u.notes {
                let _ = write!(comment, "\n{n}");
            }
        }
        let mut text = config_text(
            &comment,
            &out_params,
            &a.rig.preset(),
            &["mass_kg", "contact"],
        )?;
        if let Ok(u) = &best_fit.uncertainty {
            text.push('\n');
            text.push_str(&u.toml_table()?);
        }
        std::fs::write(&tmp, text).with_context(|| format!("writing {}", p.display()))?;
    }
    if let Some(p) = &a.plot {
        let tmp = outputs.reserve(p)?;
        let name = |p: &PathBuf| {
            p.file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
        };
        let names: Vec<String> = a.trace.iter().map(name).collect();
        let title = format!(
            "Drop test {} (release {} mm, {} rig): fitted contact laws",
            names.join(" + "),
            releases_text.join(" + "),
            a.rig
        );
        let panels: Vec<(String, &DropData)> = loaded
            .iter()
            .map(|l| {
                (
                    format!("{} (release {} mm)", name(&l.path), l.release_mm),
                    &l.data,
                )
            })
            .collect();
        let curves: Vec<(String, &Fit)> = fits.iter().map(|(k, f)| (k.to_string(), f)).collect();
        plot_identify::drop_fit(&tmp, &title, &panels, &curves)?;
    }
    outputs.commit()?;
    print_contact(a, &run, &loaded, &fits, best)
}

/// How the error was chosen.
struct ContactRun {
    /// The error used.
    error: FitError,
    /// The one asked for (`auto` or the same).
    requested: FitError,
    /// The fewest samples per contact over the traces.
    samples_per_contact: f64,
}

/// The intervals, correlations and identifiability notes of one fit, as printed.
fn print_uncertainty(label: &str, u: &Result<Uncertainty, String>) {
    let u = match u {
        Ok(u) => u,
        Err(why) => {
            println!("  {label}: no uncertainty estimate ({why})");
            return;
        }
    };
    println!(
        "  {label}: 95 % intervals ({}; sensor noise {} N):",
        u.method,
        u.noise_n
            .iter()
            .map(|n| format!("{n:.3}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    for p in &u.params {
        let width = if p.sd.is_finite() {
            format!("±{:.1} %", 100.0 * p.rel_half_width())
        } else {
            "not identifiable".to_string()
        };
        println!(
            "    {:<5} = {:<12} {:<10} [{:.4e}, {:.4e}]  {}",
            p.name,
            format!("{:.4e}", p.value),
            p.unit,
            p.ci95[0],
            p.ci95[1],
            width
        );
    }
    let k = u.params.len();
    let mut corr = Vec::new();
    for i in 0..k {
        for j in i + 1..k {
            corr.push(format!(
                "{}–{} {:+.3}",
                u.params[i].name, u.params[j].name, u.correlation[i][j]
            ));
        }
    }
    println!("    correlations: {}", corr.join(", "));
    if u.notes.is_empty() {
        println!(
            "    every parameter fixed to ±{:.0} % or better, no two correlated beyond {}",
            100.0 * WIDE_REL,
            STRONG_CORRELATION
        );
    }
    for n in &u.notes {
        println!("    ! {n}");
    }
}

fn print_contact(
    a: &ContactArgs,
    run: &ContactRun,
    loaded: &[LoadedTrace],
    fits: &[(ContactLawKind, Fit)],
    best: ContactLawKind,
) -> Result<()> {
    let best_aic = fits.iter().map(|f| f.1.aic()).fold(f64::INFINITY, f64::min);
    if a.json {
        let traces: Vec<TraceReport> = loaded.iter().map(LoadedTrace::report).collect();
        let report = ContactReport {
            first: loaded.first().context("no trace")?.report(),
            traces,
            error: run.error,
            error_requested: run.requested,
            samples_per_contact: run.samples_per_contact,
            fits: fits
                .iter()
                .map(|(k, f)| LawReport {
                    law: *k,
                    contact: f.law,
                    residual: f.residual,
                    trace_residuals: f.traces.iter().map(|t| t.residual).collect(),
                    evaluations: f.evaluations,
                    aic: f.aic(),
                    delta_aic: f.aic() - best_aic,
                    uncertainty: f.uncertainty.as_ref().ok().cloned(),
                })
                .collect(),
            best,
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    for l in loaded {
        let data = &l.data;
        // The sampling interval is the smallest step; larger steps are gaps between the
        // segments of a segmented capture (`rig capture`).
        let dt = data
            .t_s
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        let segments = 1 + data
            .t_s
            .windows(2)
            .filter(|w| w[1] - w[0] > 1.5 * dt)
            .count();
        let segments = if segments > 1 {
            format!(" in {segments} segments")
        } else {
            String::new()
        };
        let peaks: Vec<String> = data
            .impacts
            .iter()
            .map(|i| format!("{:.2}", i.peak_n))
            .collect();
        println!(
            "Drop test {}: {} samples{} at {:.1} kHz, offset {:.3} N removed, noise {:.3} N; {} impacts, peaks {} N",
            l.path.display(),
            data.t_s.len(),
            segments,
            1e-3 / dt,
            data.offset_n,
            data.noise_n,
            data.impacts.len(),
            peaks.join(", ")
        );
    }
    let releases: Vec<String> = loaded.iter().map(|l| l.release_mm.to_string()).collect();
    println!(
        "{} ({} error{}{}), {} suspension, m = {} kg, released {} mm from the surface, gap {} mm:",
        if loaded.len() > 1 {
            format!("Joint fit of {} drop tests", loaded.len())
        } else {
            "Fit".to_string()
        },
        match run.error {
            FitError::Profile => "peak forces + force profile",
            _ => "peak forces",
        },
        if a.time_weight > 0.0 {
            " + impact times"
        } else {
            ""
        },
        if loaded.len() > 1 {
            ", summed over the traces"
        } else {
            ""
        },
        a.rig,
        a.mass_kg,
        releases.join(" and "),
        a.gap_mm
    );
    println!(
        "  error: {}{}",
        match run.error {
            FitError::Profile => "profile",
            _ => "peaks",
        },
        if run.requested == FitError::Auto {
            format!(
                " (auto: {:.1} samples per contact; the profile from {})",
                run.samples_per_contact,
                crate::identify::contact::PROFILE_MIN_SAMPLES
            )
        } else {
            String::new()
        }
    );
    println!(
        "  {:<20} {:<62} {:>9} {:>10} {:>11} {:>10} {:>7} {:>6}",
        "law", "parameters", "peak rms", "time rms", "profile rms", "J", "ΔAIC", "evals"
    );
    let row = |label: String, params: String, r: &Residual, aic: String, evals: String| {
        println!(
            "  {:<20} {:<62} {:>7.2} % {:>7.1} µs {:>9} {:>10.3e} {:>7} {:>6}",
            label,
            params,
            r.peak_rms_pct,
            r.time_rms_us,
            if run.error == FitError::Profile {
                format!("{:.2} %", r.profile_rms_pct)
            } else {
                "–".to_string()
            },
            r.cost,
            aic,
            evals
        );
    };
    let mut ranked: Vec<&(ContactLawKind, Fit)> = fits.iter().collect();
    ranked.sort_by(|x, y| x.1.aic().total_cmp(&y.1.aic()));
    for (k, f) in &ranked {
        row(
            k.to_string(),
            describe_law(&f.law, a.mass_kg),
            &f.residual,
            format!("{:.1}", f.aic() - best_aic),
            f.evaluations.to_string(),
        );
        if loaded.len() > 1 {
            for (l, t) in loaded.iter().zip(&f.traces) {
                row(
                    String::new(),
                    format!("  of which release {} mm", l.release_mm),
                    &t.residual,
                    String::new(),
                    String::new(),
                );
            }
        }
    }
    if fits.len() > 1 {
        let close: Vec<String> = ranked
            .iter()
            .skip(1)
            .filter(|f| f.1.aic() - best_aic < 2.0)
            .map(|f| f.0.to_string())
            .collect();
        println!(
            "  ranked by AIC (n ln(J/n) + 2p over the {} terms of the error): {best}{}",
            ranked[0].1.terms,
            if close.is_empty() {
                String::from(" is best by more than 2")
            } else {
                format!(
                    "; the data cannot tell it from {} (ΔAIC < 2)",
                    close.join(", ")
                )
            }
        );
    }
    for (k, f) in &ranked {
        print_uncertainty(&k.to_string(), &f.uncertainty);
    }
    if let Some(p) = &a.out {
        println!("  wrote {} ({best} law; use it with --config)", p.display());
    }
    Ok(())
}

#[derive(Serialize)]
struct FreeReport {
    #[serde(flatten)]
    decay: FreeDecay,
    mass_kg: f64,
    stiffness_n_m: f64,
    damping_n_s_m: f64,
    pendulum_length_m: f64,
}

fn run_free(a: &FreeArgs) -> Result<()> {
    check_range("mass_kg", a.mass_kg, 1e-6, 1e3).context("--mass-kg")?;
    let trace = read_trace(
        &a.trace,
        &a.time.format(&a.value_col, a.unit.to_si()),
        if a.unit.is_acceleration() {
            "acceleration"
        } else {
            "displacement"
        },
    )?;
    let decay =
        identify_free(&trace).with_context(|| format!("free decay {}", a.trace.display()))?;
    let mut params = a.rig.preset();
    params.mass_kg = a.mass_kg;
    params.suspension = decay.suspension(&params.suspension, params.gravity_m_s2);
    params
        .validate()
        .context("the identified suspension is out of range")?;
    let report = FreeReport {
        decay,
        mass_kg: a.mass_kg,
        stiffness_n_m: decay.stiffness_n_m(a.mass_kg),
        damping_n_s_m: decay.damping_n_s_m(a.mass_kg),
        pendulum_length_m: decay.pendulum_length_m(params.gravity_m_s2),
    };
    let mut outputs = Outputs::new();
    if let Some(p) = &a.out {
        let tmp = outputs.reserve(p)?;
        let comment = format!(
            "host-sim identify free: {} ({:.1} cycles): f_n = {:.5} Hz (95 %: {:.5} .. {:.5}), \
             zeta = {:.5} (95 %: {:.5} .. {:.5})\n\
             k = m w^2 = {:.5e} N/m (Eq. 3-34), c = 2 zeta m w = {:.5e} N s/m",
            a.trace.display(),
            decay.cycles,
            decay.natural_freq_hz,
            decay.natural_freq_ci95_hz[0],
            decay.natural_freq_ci95_hz[1],
            decay.damping_ratio,
            decay.damping_ratio_ci95[0],
            decay.damping_ratio_ci95[1],
            report.stiffness_n_m,
            report.damping_n_s_m
        );
        std::fs::write(
            &tmp,
            config_text(
                &comment,
                &params,
                &a.rig.preset(),
                &["mass_kg", "suspension"],
            )?,
        )
        .with_context(|| format!("writing {}", p.display()))?;
    }
    outputs.commit()?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "Free decay {}: {} samples, {:.1} cycles, fit residual {:.2} % of the signal rms",
        a.trace.display(),
        trace.t_s.len(),
        decay.cycles,
        100.0 * decay.residual_rel
    );
    println!(
        "  natural frequency ω/2π = {:.5} Hz (95 %: {:.5} – {:.5}; damped {:.5} Hz)",
        decay.natural_freq_hz,
        decay.natural_freq_ci95_hz[0],
        decay.natural_freq_ci95_hz[1],
        decay.damped_freq_hz
    );
    println!(
        "  damping ratio ζ = {:.5} (95 %: {:.5} – {:.5}); correlation with ω {:+.3}",
        decay.damping_ratio,
        decay.damping_ratio_ci95[0],
        decay.damping_ratio_ci95[1],
        decay.correlation_fn_zeta
    );
    println!(
        "  m = {} kg: k = m ω² = {:.5e} N/m (Eq. 3-34), c = 2ζmω = {:.5e} N s/m; as a pendulum l = g/ω² = {:.2} mm",
        a.mass_kg,
        report.stiffness_n_m,
        report.damping_n_s_m,
        report.pendulum_length_m * 1e3
    );
    if let Some(p) = &a.out {
        println!(
            "  wrote {} (suspension of the {} rig; use it with --rig {} --config)",
            p.display(),
            a.rig,
            a.rig
        );
    }
    Ok(())
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

//! `identify contact`: fit the contact law to drop tests, report it with its intervals, write
//! its config and figure.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail, ensure};
use serde::Serialize;
use shared::error::check_range;
use shared::model::{ContactLaw, ContactLawKind, RigParams, Suspension};

use super::{ContactArgs, LawChoice, describe_law, pair_releases};
use crate::config::{Setup, config_text};
use crate::identify::cost::{DropSetup, DropTest, FIT_STEPS, FitError, Residual, SimDrop, Weights};
use crate::identify::data::{DropData, NOISE_FLOOR, analyse_drop};
use crate::identify::fit::{Fit, best_by_aicc, by_aicc, fit_laws};
use crate::identify::uncertainty::{
    FitCheck, LACK_OF_FIT_FACTOR, STRONG_CORRELATION, Uncertainty, WIDE_REL, ratio_text,
};
use crate::output::{Outputs, distinct_files, given};
use crate::trace::read_trace;
use shared::model::rig::IMPACT_SPEEDS_M_S;

#[derive(Serialize)]
struct LawReport {
    law: ContactLawKind,
    contact: ContactLaw,
    /// All traces together.
    residual: Residual,
    /// Per trace, in the order of `traces`.
    trace_residuals: Vec<Residual>,
    evaluations: u64,
    /// Akaike's information criterion on the error's terms, its small-sample correction (the
    /// laws are ranked by it), and that one's difference to the best.
    aic: f64,
    aicc: f64,
    delta_aicc: f64,
    /// The effective coefficient of restitution of the fitted law.
    restitution: Restitution,
    /// Lack of fit, 95 % intervals, correlations and identifiability notes (absent if not
    /// estimated).
    uncertainty: Option<Uncertainty>,
}

/// A law's effective coefficient of restitution (one simulated impact of the hammer's mass,
/// `ContactLaw::restitution`).
#[derive(Serialize)]
struct Restitution {
    /// The first drop test's first impact speed (the fitted simulation's), m/s.
    first_impact_speed_m_s: f64,
    /// `e` at that speed.
    at_first_impact: Option<f64>,
    /// `(speed m/s, e)` at the rigs' impact speeds (`shared::model::rig::IMPACT_SPEEDS_M_S`).
    at_rig_speeds: Vec<(f64, Option<f64>)>,
}

impl Restitution {
    fn of(fit: &Fit, mass_kg: f64) -> Self {
        let v1 = fit
            .traces
            .first()
            .and_then(|t| t.sim.impacts.first())
            .map_or(f64::NAN, |i| i.approach_speed_m_s);
        Restitution {
            first_impact_speed_m_s: v1,
            at_first_impact: fit.law.restitution(mass_kg, v1),
            at_rig_speeds: IMPACT_SPEEDS_M_S
                .iter()
                .map(|&v| (v, fit.law.restitution(mass_kg, v)))
                .collect(),
        }
    }

    /// `"e = 0.987 at the first impact (34 mm/s); at 10, 30, 100, 300 mm/s: 0.996, …"`.
    fn describe(&self) -> String {
        let e = |x: Option<f64>| x.map_or_else(|| "–".to_string(), |e| format!("{e:.3}"));
        let speeds: Vec<String> = self
            .at_rig_speeds
            .iter()
            .map(|(v, _)| format!("{:.0}", 1e3 * v))
            .collect();
        let es: Vec<String> = self.at_rig_speeds.iter().map(|(_, x)| e(*x)).collect();
        format!(
            "e = {} at the first impact ({:.0} mm/s); at the rig's impact speeds {} mm/s: {}",
            e(self.at_first_impact),
            1e3 * self.first_impact_speed_m_s,
            speeds.join(", "),
            es.join(", ")
        )
    }
}

#[derive(Serialize)]
struct TraceReport {
    trace: String,
    release_mm: f64,
    samples: usize,
    offset_n: f64,
    noise_n: f64,
    /// Whether `noise_n` is the floor (the trace's own noise was below it).
    noise_floored: bool,
    impact_peaks_n: Vec<f64>,
    /// The peak of the first impact left out as too weak to time, N.
    too_weak_peak_n: Option<f64>,
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
            noise_floored: self.data.noise_floored,
            impact_peaks_n: self.data.impacts.iter().map(|i| i.peak_n).collect(),
            too_weak_peak_n: self.data.too_weak.map(|(p, _)| p),
        }
    }
}

pub(super) fn run(a: &ContactArgs) -> Result<()> {
    let (params, releases) = checked_setup(a)?;
    let loaded = load_traces(a, &params, &releases)?;
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
    let mut fits = fit_laws(&tests, &laws, weights, 400)?;
    for (_, f) in &mut fits {
        if let Ok(u) = &f.uncertainty {
            f.uncertainty = Ok(u.with_intervals(a.intervals));
        }
    }
    let best = best_by_aicc(&fits).context("no fit")?;
    let run = ContactRun {
        suspension: match params.suspension {
            Suspension::Wires { length_m, .. } => {
                format!("wires suspension (pendulum l = {:.2} mm)", length_m * 1e3)
            }
            Suspension::Beam {
                natural_freq_hz, ..
            } => format!("beam-spring suspension (f_n = {natural_freq_hz:.4} Hz)"),
        },
        error,
        requested: a.error,
        samples_per_contact: spc,
    };
    let best_fit = &fits.iter().find(|f| f.0 == best).context("no fit")?.1;

    let release_checks: Vec<ReleaseCheck> = loaded
        .iter()
        .zip(&best_fit.traces)
        .filter_map(|(l, t)| release_check(l, &t.sim, a.mass_kg, a.gap_mm))
        .collect();
    // A record that contradicts its options by far (a mass in grams, a force in kN read as N)
    // is not fitted into a config at all, unless asked.
    if !a.allow_contradiction
        && let Some(c) = release_checks
            .iter()
            .find(|c| c.factor > IMPLAUSIBLE_FACTOR)
    {
        bail!(
            "{}\nthe record contradicts the options by {:.0}× (more than {IMPLAUSIBLE_FACTOR}×): \
             nothing written; check --mass-kg (kg), --force-unit and --release-mm, or write the \
             fit anyway with --allow-contradiction",
            c.note,
            c.factor
        );
    }
    let release_notes: Vec<String> = release_checks.into_iter().map(|c| c.note).collect();
    // A fit whose misfit cannot be told from the sensor noise is not written as a config that
    // other commands would take on trust.
    let unchecked = best_fit.uncertainty.as_ref().err();
    let mut outputs = Outputs::new();
    if let (Some(p), None) = (&a.out, unchecked) {
        let tmp = outputs.reserve(p)?;
        let text = config_file(a, &run, &loaded, &params, best, best_fit)?;
        std::fs::write(&tmp, text).with_context(|| format!("writing {}", p.display()))?;
    }
    if let Some(p) = &a.plot {
        let tmp = outputs.reserve(p)?;
        draw_fits(a, &tmp, &loaded, &fits)?;
    }
    outputs.commit()?;
    let written = a.out.as_deref().filter(|_| unchecked.is_none());
    print_contact(a, &run, &loaded, &fits, best, written)?;
    if let Some(why) = unchecked {
        bail!(
            "the {best} fit cannot be checked against the sensor noise ({why}){}: the data may \
             not be what the options say; check the force and time units (--force-unit, \
             --time-unit), one --release-mm per trace, and the rig (--rig, --config){}",
            match &a.out {
                Some(p) => format!(
                    "; its parameters are printed above but not written to {}",
                    p.display()
                ),
                None => String::new(),
            },
            release_notes
                .iter()
                .map(|n| format!("\n{n}"))
                .collect::<String>()
        );
    }
    for note in &release_notes {
        eprintln!("! note: {note}");
    }
    Ok(())
}

/// The options checked: the rig's parameters with `--mass-kg` (from `--rig` and `--config`),
/// and the release of each trace (`--release-mm`, one for all or one per trace).
fn checked_setup(a: &ContactArgs) -> Result<(RigParams, Vec<f64>)> {
    let mut inputs: Vec<(&str, &Path)> = a.trace.iter().map(|t| ("--trace", t.as_path())).collect();
    inputs.extend(a.config.as_deref().map(|c| ("--config", c)));
    let outputs = given(&[("--out", a.out.as_deref()), ("--plot", a.plot.as_deref())]);
    distinct_files(&inputs, &outputs)?;
    check_range("mass_kg", a.mass_kg, 1e-6, 1e3).context("--mass-kg")?;
    check_range("time_weight", a.time_weight, 0.0, 1e6).context("--time-weight")?;
    shared::error::check_count("max_impacts", a.max_impacts, 1, 50).context("--max-impacts")?;
    let setup = Setup::from_opts(&crate::config::RigOpts {
        config: a.config.clone(),
        precision: crate::precision::Precision::F64,
        ..crate::config::RigOpts::preset(a.rig)
    })?;
    setup.gap_m("--gap-mm", a.gap_mm)?;
    let releases = pair_releases(&a.release_mm, a.trace.len()).context("--release-mm")?;
    for &r in &releases {
        check_range("release_mm", r, a.gap_mm + 1e-3, 100.0).context("--release-mm")?;
        // Released at rest `r` from the surface, the hammer swings at most `r − gap` past its
        // rest position: it reaches the surface only from beyond twice the gap.
        ensure!(
            r > 2.0 * a.gap_mm,
            "--release-mm {r}: released at rest {r} mm from the surface, the hammer swings at \
             most {:.3} mm past its rest position, short of the {} mm gap: allowed release > 2 × \
             gap = {} mm",
            r - a.gap_mm,
            a.gap_mm,
            2.0 * a.gap_mm
        );
    }
    let mut params = setup.params;
    params.mass_kg = a.mass_kg;
    params.validate().context("rig parameters")?;
    Ok((params, releases))
}

/// Each `--trace` read and its impacts found, with its release.
fn load_traces(a: &ContactArgs, params: &RigParams, releases: &[f64]) -> Result<Vec<LoadedTrace>> {
    let mut loaded = Vec::with_capacity(a.trace.len());
    for (path, &release_mm) in a.trace.iter().zip(releases) {
        let trace = read_trace(
            path,
            &a.time.format(Some(&a.force_col), a.force_unit.to_n()),
            "force",
        )?;
        let data = analyse_drop(&trace, a.max_impacts as usize)
            .and_then(|d| {
                d.check_spacing(1.0 / params.natural_freq_hz())?;
                Ok(d)
            })
            .with_context(|| format!("trace {}", path.display()))?;
        loaded.push(LoadedTrace {
            path: path.clone(),
            release_mm,
            data,
        });
    }
    Ok(loaded)
}

/// The `--out` config: the rig's parameters with the best law, its fit, restitution and
/// intervals as comments, and its `[uncertainty]` table where it has one.
fn config_file(
    a: &ContactArgs,
    run: &ContactRun,
    loaded: &[LoadedTrace],
    params: &RigParams,
    best: ContactLawKind,
    best_fit: &Fit,
) -> Result<String> {
    let files: Vec<String> = a.trace.iter().map(|p| p.display().to_string()).collect();
    let releases: Vec<String> = loaded.iter().map(|l| l.release_mm.to_string()).collect();
    let impacts: Vec<String> = loaded
        .iter()
        .map(|l| l.data.impacts.len().to_string())
        .collect();
    let mut out_params = *params;
    out_params.contact = best_fit.law;
    let mut comment = format!(
        "host-sim identify contact: {} law fitted to {} ({} impacts, error: {}, release {} mm, \
         gap {} mm)\nresidual: peak rms {:.2} % of the {}largest peak, time rms {:.1} us, J = {:.3e}",
        best,
        files.join(" + "),
        impacts.join(" + "),
        run.error,
        releases.join(" + "),
        a.gap_mm,
        best_fit.residual.peak_rms_pct,
        if loaded.len() > 1 { "trace's " } else { "" },
        best_fit.residual.time_rms_us,
        best_fit.residual.cost
    );
    let _ = write!(
        comment,
        "\n{}",
        Restitution::of(best_fit, a.mass_kg).describe()
    );
    if let Ok(u) = &best_fit.uncertainty {
        let _ = write!(comment, "\nintervals: {}", u.method);
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
        text.push_str(&u.table().to_toml()?);
    }
    Ok(text)
}

/// The `--plot` figure into `tmp`: each trace with every law's fitted simulation.
fn draw_fits(
    a: &ContactArgs,
    tmp: &Path,
    loaded: &[LoadedTrace],
    fits: &[(ContactLawKind, Fit)],
) -> Result<()> {
    let name = |p: &PathBuf| {
        p.file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
    };
    let names: Vec<String> = a.trace.iter().map(name).collect();
    let releases: Vec<String> = loaded.iter().map(|l| l.release_mm.to_string()).collect();
    let title = format!(
        "Drop test {} (release {} mm, {} rig): fitted contact laws",
        names.join(" + "),
        releases.join(" + "),
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
    crate::figures::identify::drop_fit(tmp, &title, &panels, &curves)
}

/// How far the arrival speed implied by a trace's first impulse may lie from the model's before
/// [`release_check`] says so (the impulse's trapezoids on a few samples per contact, the
/// suspension's own impulse during the contact, damping).
const IMPULSE_SPEED_MARGIN: f64 = 1.2;

/// How far outside the impulse's speed bounds the model's arrival may be before the record is
/// taken to contradict the options outright (a mass in grams is 1000×): refused unless
/// `--allow-contradiction`.
const IMPLAUSIBLE_FACTOR: f64 = 3.0;

/// A trace whose first impulse disagrees with its release: the note, and by how much (the
/// model's arrival speed over the nearest bound, ≥ 1).
struct ReleaseCheck {
    note: String,
    factor: f64,
}

/// Whether the first impact's impulse `J = m v (1 + e)` (any law: `0 ≤ e ≤ 1`, so an arrival
/// speed `v` within `[J/2m, J/m]`) agrees with the arrival speed of the model released from
/// `--release-mm` (`sim`, the fitted simulation of this trace; its free flight to the first
/// contact does not depend on the law): a note naming the releases that would, and the options
/// to check, where it does not by more than [`IMPULSE_SPEED_MARGIN`]. A wrong release, mass or
/// force unit leaves the law to absorb the difference, and the fit then says only that it does
/// not fit.
fn release_check(
    l: &LoadedTrace,
    sim: &SimDrop,
    mass_kg: f64,
    gap_mm: f64,
) -> Option<ReleaseCheck> {
    let j = l.data.impulse_n_s(0)?;
    let v = sim.impacts.first()?.approach_speed_m_s;
    let (lo, hi) = (j / (2.0 * mass_kg), j / mass_kg);
    if !(j > 0.0 && v > 0.0) || (lo / IMPULSE_SPEED_MARGIN..=hi * IMPULSE_SPEED_MARGIN).contains(&v)
    {
        return None;
    }
    let factor = (lo / v).max(v / hi);
    // The release that gives speed `w`: released `A` from rest (`A = release − gap`), the
    // hammer reaches the surface `gap` past rest at `ω √(A² − gap²)`, nearly (the model's own
    // speed scaled; the pendulum's arcs and damping aside).
    let amp = l.release_mm - gap_mm;
    let release_at = |w: f64| {
        gap_mm + (gap_mm * gap_mm + (amp * amp - gap_mm * gap_mm) * (w / v).powi(2)).sqrt()
    };
    let note = format!(
        "{}: the first impact's impulse, {j:.4e} N s, is an arrival at {:.1}–{:.1} mm/s for \
         m = {mass_kg} kg (J = m v (1 + e), e from 1 to 0, whatever the law); released {} mm \
         from the surface at gap {gap_mm} mm the model arrives at {:.1} mm/s, as if from about \
         {:.2}–{:.2} mm: check --release-mm, --mass-kg and --force-unit",
        l.path.display(),
        1e3 * lo,
        1e3 * hi,
        l.release_mm,
        1e3 * v,
        release_at(lo),
        release_at(hi),
    );
    Some(ReleaseCheck { note, factor })
}

/// How the error was chosen, and the suspension fitted with.
struct ContactRun {
    /// The suspension as the fit used it (`--rig`'s, or `--config`'s in its place), in words.
    suspension: String,
    /// The error used.
    error: FitError,
    /// The one asked for (`auto` or the same).
    requested: FitError,
    /// The fewest samples per contact over the traces.
    samples_per_contact: f64,
}

/// The intervals, correlations, restitution and notes of one fit, as printed.
fn print_uncertainty(label: &str, u: &Result<Uncertainty, String>, restitution: &Restitution) {
    let u = match u {
        Ok(u) => u,
        Err(why) => {
            println!("  {label}: no uncertainty estimate ({why})");
            println!("    restitution: {}", restitution.describe());
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
            format!("±{} %", ratio_text(100.0 * p.rel_half_width(), 1))
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
    println!("    restitution: {}", restitution.describe());
    if u.notes.is_empty() {
        println!(
            "    fits to the noise (reduced χ² {:.2}); every parameter fixed to ±{:.0} % or \
             better, no two correlated beyond {}",
            u.fit_check.ratio,
            100.0 * WIDE_REL,
            STRONG_CORRELATION
        );
    }
    for n in &u.notes {
        println!("    ! {n}");
    }
}

/// The report of `identify contact`: as JSON (`--json`), or as text: each trace, the fit, the
/// laws' table, their ranking, the lack of fit, each law's intervals, the file written.
fn print_contact(
    a: &ContactArgs,
    run: &ContactRun,
    loaded: &[LoadedTrace],
    fits: &[(ContactLawKind, Fit)],
    best: ContactLawKind,
    written: Option<&Path>,
) -> Result<()> {
    let best_aicc = fits
        .iter()
        .map(|f| f.1.aicc())
        .fold(f64::INFINITY, f64::min);
    if a.json {
        let report = contact_report(a, run, loaded, fits, best, best_aicc)?;
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    for l in loaded {
        println!("{}", trace_line(l));
    }
    print_fit_heading(a, run, loaded);
    let mut ranked: Vec<&(ContactLawKind, Fit)> = fits.iter().collect();
    ranked.sort_by(|x, y| by_aicc(&x.1, &y.1));
    print_table(a, run, loaded, &ranked, best_aicc);
    print_ranking(fits.len(), &ranked, best, best_aicc);
    print_lack_of_fit(fits.len(), &ranked);
    for (k, f) in &ranked {
        print_uncertainty(
            &k.to_string(),
            &f.uncertainty,
            &Restitution::of(f, a.mass_kg),
        );
    }
    if let Some(p) = written {
        println!("  wrote {} ({best} law; use it with --config)", p.display());
    }
    Ok(())
}

/// The `--json` report: the traces, the error, every law's fit.
fn contact_report(
    a: &ContactArgs,
    run: &ContactRun,
    loaded: &[LoadedTrace],
    fits: &[(ContactLawKind, Fit)],
    best: ContactLawKind,
    best_aicc: f64,
) -> Result<ContactReport> {
    Ok(ContactReport {
        first: loaded.first().context("no trace")?.report(),
        traces: loaded.iter().map(LoadedTrace::report).collect(),
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
                aicc: f.aicc(),
                delta_aicc: f.aicc() - best_aicc,
                restitution: Restitution::of(f, a.mass_kg),
                uncertainty: f.uncertainty.as_ref().ok().cloned(),
            })
            .collect(),
        best,
    })
}

/// A trace's line: its samples (and segments), rate, offset, noise, impacts and their peaks.
fn trace_line(l: &LoadedTrace) -> String {
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
    format!(
        "Drop test {}: {} samples{} at {:.1} kHz, offset {:.3} N removed, noise {:.3} N{}; {}, {} {} N{}{}",
        l.path.display(),
        data.t_s.len(),
        segments,
        1e-3 / dt,
        data.offset_n,
        data.noise_n,
        if data.noise_floored {
            format!(
                " (the floor, {} % of the largest force: the trace's own noise is below \
                 it; at this level the sampling limits the fit, by more than the intervals \
                 say below 100 kHz: docs/identification.md, \"A quiet sensor\")",
                100.0 * NOISE_FLOOR
            )
        } else {
            String::new()
        },
        crate::output::count(data.impacts.len() as u64, "impact"),
        if peaks.len() == 1 { "peak" } else { "peaks" },
        peaks.join(", "),
        data.too_weak.map_or(String::new(), |(p, thr)| format!(
            " (the next, {p:.2} N, is below twice the detection threshold {thr:.2} N: too \
             weak to time, left out)"
        )),
        data.spike_n.map_or(String::new(), |f| format!(
            "; a glitch of {f:.2} N (one or two samples) is not an impact"
        ))
    )
}

/// What was fitted: the error, the suspension, the mass, the releases and the gap.
fn print_fit_heading(a: &ContactArgs, run: &ContactRun, loaded: &[LoadedTrace]) {
    let releases: Vec<String> = loaded.iter().map(|l| l.release_mm.to_string()).collect();
    println!(
        "{} ({} error{}{}), {}, m = {} kg, released {} mm from the surface, gap {} mm:",
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
        run.suspension,
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
                crate::identify::cost::PROFILE_MIN_SAMPLES
            )
        } else {
            String::new()
        }
    );
}

/// The lack-of-fit check of a fit that has one.
fn fit_check(f: &Fit) -> Option<FitCheck> {
    f.uncertainty.as_ref().ok().map(|u| u.fit_check.clone())
}

/// The laws' table, best first: parameters, residuals, χ²/noise, restitution, ΔAICc,
/// evaluations (and each trace's residuals in a joint fit).
fn print_table(
    a: &ContactArgs,
    run: &ContactRun,
    loaded: &[LoadedTrace],
    ranked: &[&(ContactLawKind, Fit)],
    best_aicc: f64,
) {
    println!(
        "  {:<20} {:<50} {:>9} {:>10} {:>11} {:>10} {:>9} {:>6} {:>7} {:>6}",
        "law",
        "parameters",
        "peak rms",
        "time rms",
        "profile rms",
        "J",
        "χ²/noise",
        "e(v₁)",
        "ΔAICc",
        "evals"
    );
    struct Row<'r> {
        label: String,
        params: String,
        r: &'r Residual,
        chi2: String,
        e: String,
        aicc: String,
        evals: String,
    }
    let row = |w: Row<'_>| {
        println!(
            "  {:<20} {:<50} {:>7.2} % {:>7.1} µs {:>11} {:>10.3e} {:>9} {:>6} {:>7} {:>6}",
            w.label,
            w.params,
            w.r.peak_rms_pct,
            w.r.time_rms_us,
            if run.error == FitError::Profile {
                format!("{:.2} %", w.r.profile_rms_pct)
            } else {
                "–".to_string()
            },
            w.r.cost,
            w.chi2,
            w.e,
            w.aicc,
            w.evals
        );
    };
    for (k, f) in ranked {
        let e = Restitution::of(f, a.mass_kg).at_first_impact;
        row(Row {
            label: k.to_string(),
            params: describe_law(&f.law),
            r: &f.residual,
            chi2: fit_check(f)
                .and_then(|c| {
                    c.headline_ratio().map(|r| {
                        format!("{}{}", ratio_text(r, 1), if c.misses { " !" } else { "" })
                    })
                })
                .unwrap_or_else(|| "–".to_string()),
            e: e.map_or_else(|| "–".to_string(), |e| format!("{e:.3}")),
            aicc: if f.aicc().is_finite() {
                format!("{:.1}", f.aicc() - best_aicc)
            } else {
                "–".to_string()
            },
            evals: f.evaluations.to_string(),
        });
        if loaded.len() > 1 {
            for (l, t) in loaded.iter().zip(&f.traces) {
                row(Row {
                    label: String::new(),
                    params: format!("  of which release {} mm", l.release_mm),
                    r: &t.residual,
                    chi2: String::new(),
                    e: String::new(),
                    aicc: String::new(),
                    evals: String::new(),
                });
            }
        }
    }
}

/// The ranking by AICc of `laws` fits (`ranked`, best first): the laws it cannot rank, and
/// those it cannot tell from the best.
fn print_ranking(
    laws: usize,
    ranked: &[&(ContactLawKind, Fit)],
    best: ContactLawKind,
    best_aicc: f64,
) {
    let unranked: Vec<String> = ranked
        .iter()
        .filter(|f| !f.1.aicc().is_finite())
        .map(|f| format!("{} ({} parameters)", f.0, f.1.parameters()))
        .collect();
    if laws > 1 && !unranked.is_empty() {
        println!(
            "  ! not ranked by AICc: {} (AICc needs more terms than parameters + 1; the error has {}): \
             fit more impacts or a second trace, or keep the impact times or the profile in the error",
            unranked.join(", "),
            ranked[0].1.terms
        );
    }
    if laws > 1 && ranked[0].1.aicc().is_finite() {
        let close: Vec<String> = ranked
            .iter()
            .skip(1)
            .filter(|f| f.1.aicc() - best_aicc < 2.0)
            .map(|f| f.0.to_string())
            .collect();
        println!(
            "  ranked by AICc (n ln(J/n) + 2p + 2p(p+1)/(n−p−1) over the {} terms of the error): {best}{}",
            ranked[0].1.terms,
            if close.is_empty() {
                String::from(" is best by more than 2")
            } else {
                format!(
                    "; the data cannot tell it from {} (ΔAICc < 2)",
                    close.join(", ")
                )
            }
        );
    }
}

/// Lack of fit, said for every law of the `laws` fits (`ranked`): which miss the data, which
/// fit to the noise (those whose fitted error has no degrees of freedom are neither: their own
/// notes say so).
fn print_lack_of_fit(laws: usize, ranked: &[&(ContactLawKind, Fit)]) {
    let (miss, fit): (Vec<_>, Vec<_>) = ranked
        .iter()
        .filter_map(|(k, f)| fit_check(f).map(|c| (*k, c)))
        .partition(|(_, c)| c.misses);
    if miss.is_empty() {
        return;
    }
    let (fit, untested): (Vec<_>, Vec<_>) = fit
        .into_iter()
        .map(|(k, c)| (k, c.headline_ratio()))
        .partition(|(_, r)| r.is_some());
    let said: Vec<String> = miss
        .iter()
        .map(|(k, c)| {
            format!(
                "{k} (residual {}× the noise{})",
                ratio_text(c.headline_ratio().unwrap_or(f64::NAN), 1),
                c.worst_part().map_or_else(String::new, |p| format!(
                    ", its {} {}×",
                    p.part.name(),
                    ratio_text(p.ratio, 0)
                ))
            )
        })
        .collect();
    let fine: Vec<String> = fit
        .iter()
        .map(|(k, r)| format!("{k} ({}×)", ratio_text(r.unwrap_or(f64::NAN), 1)))
        .collect();
    let untested: Vec<String> = untested.iter().map(|(k, _)| k.to_string()).collect();
    println!(
        "  ! lack of fit (χ²/noise: the residual over what the sensor noise explains, 1 when a \
         law fits; ! beyond {LACK_OF_FIT_FACTOR}× and the noise's reach): {} {} not fit these data{}{}",
        said.join(", "),
        if miss.len() == 1 { "does" } else { "do" },
        if untested.is_empty() {
            String::new()
        } else {
            format!(
                "; {} cannot be tested (as many error terms as parameters)",
                untested.join(", ")
            )
        },
        if fine.is_empty() && laws > 1 {
            String::from("; no law fits to the noise")
        } else if fine.is_empty() {
            String::new()
        } else {
            format!(
                "; {} {} to the noise",
                fine.join(", "),
                if fine.len() == 1 { "fits" } else { "fit" }
            )
        }
    );
}

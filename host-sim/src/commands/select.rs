//! `host-sim select`: the operating frequency for a rig and gap (the main job).

use std::path::PathBuf;

use anyhow::{Result, anyhow};
use clap::Args;
use shared::analysis::SelectionError;
use shared::observe::PointResult;

use super::omega_sweep;
use crate::config::{RigOpts, Setup, UncertaintyTable};
use crate::figures::response::{Highlight, points, response_band};
use crate::output::Outputs;
use crate::propagate::{Propagation, propagate};
use crate::response;
use crate::selection::{
    BASIN_MAX_PERIODS, BASIN_SAMPLES, BASIN_THRESHOLD, BasinCheck, EdgeKind, check_band,
    check_basin, compute_parts, lack_of_fit_warning, no_robust_point_diagnosis, selection_failure,
    unsettled_beyond_edges,
};
pub use crate::selection::{OtherBest, SelectReport, compute};

/// Arguments of `select`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct SelectArgs {
    /// Rig and numerics.
    #[command(flatten)]
    pub rig: RigOpts,
    /// Gap between the hammer at rest and the impact surface, mm (≥ 0; field use: 0).
    #[arg(long, default_value_t = 0.0)]
    pub gap_mm: f64,
    /// Frequency-ratio sweep searched, START:END:STEP (default from `[selection]` or 0.5:5.0:0.01).
    #[arg(long)]
    pub omega_ratio: Option<String>,
    /// Required robustness in frequency, ± % (default 5).
    #[arg(long)]
    pub freq_margin_pct: Option<f64>,
    /// Required robustness in gap, ± mm (default 0.1; the lower side is clipped at 0).
    #[arg(long)]
    pub gap_margin_mm: Option<f64>,
    /// Print one JSON object instead of the report.
    #[arg(long)]
    pub json: bool,
    /// Skip the orbit check: the band's edges and the margin from the sweep's samples only
    /// (by default the chosen point's periodic orbit is found, its multipliers reported and
    /// its band's edges located on its branch).
    #[arg(long)]
    pub no_orbit_check: bool,
    /// Skip the basin check (by default: the chosen 1/1 orbit's basin fraction among random
    /// start-up conditions, u0 from −max(gap, A0) up to the surface and u̇0 up to ± the cart's
    /// velocity amplitude A0·Ω, with its 95 % interval and the largest competing attractor).
    #[arg(long)]
    pub no_basin_check: bool,
    /// Random start-up conditions of the basin check (1 ..= 1000000).
    #[arg(long, default_value_t = BASIN_SAMPLES)]
    pub basin_samples: u32,
    /// Seed of the basin check's start-up conditions.
    #[arg(long, default_value_t = 1)]
    pub basin_seed: u64,
    /// Flag the chosen point when its 1/1 basin fraction lies below this (0 ..= 1).
    #[arg(long, default_value_t = BASIN_THRESHOLD)]
    pub basin_threshold: f64,
    /// Transient limit of the basin check, excitation periods (1 ..= 1000000): a start that has
    /// not settled on an attractor by then counts as none (lightly damped non-impacting motions
    /// settle slowly). Default: 2000, or, on a damped suspension, the periods its free
    /// oscillation takes to shrink by 1e-6 at the chosen Ω/ω if more (at most 10000).
    #[arg(long)]
    pub basin_max_periods: Option<u32>,
    /// CSV of the nominal-gap response (columns as `response`).
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: Option<PathBuf>,
    /// PNG or SVG of the nominal-gap response with the band, window and chosen point (with
    /// --uncertainty: the response's 95 % range over the draws, and the robust point).
    #[arg(long, value_parser = crate::output::figure_target)]
    pub plot: Option<PathBuf>,
    /// Propagate the identified contact law's uncertainty (the `[uncertainty]` table of a
    /// `--config` written by `identify contact --out`): the selection for parameter sets drawn
    /// from it; the operating frequency and F_i/mg as median and 95 % range, the share of draws
    /// still 1/1 at the nominal answer, and a robust recommendation.
    #[arg(long)]
    pub uncertainty: bool,
    /// With --uncertainty: parameter sets drawn (8 ..= 100000).
    #[arg(long, default_value_t = 64, requires = "uncertainty")]
    pub draws: usize,
    /// With --uncertainty: seed of the draws.
    #[arg(long, default_value_t = 1, requires = "uncertainty")]
    pub seed: u64,
}

/// `select --json --uncertainty`: the report with the draws' spread.
#[derive(serde::Serialize)]
struct ReportWithUncertainty<'a> {
    #[serde(flatten)]
    report: &'a SelectReport,
    uncertainty: &'a Propagation,
}

/// Runs `select`.
///
/// # Errors
/// Bad input, no robust point, or I/O failure.
pub fn run(a: &SelectArgs) -> Result<()> {
    a.rig
        .check_outputs(&[("--out", a.out.as_deref()), ("--plot", a.plot.as_deref())])?;
    let setup = checked_setup(a)?;
    check_basin_args(a)?;
    let table = uncertainty_table(a, &setup)?;
    let config = a.config_name();
    let warning = lack_of_fit_warning(&setup, &config);
    let (selection, mut responses) = compute_parts(&setup, a.gap_mm, "select")?;
    let mut rep = selection.map_err(|e| {
        // Say what the responses show, and the identification's verdict.
        let mut text = selection_failure(&setup, a.gap_mm, &e);
        if matches!(
            e,
            SelectionError::NoOneToOneBand | SelectionError::NoRobustPoint { .. }
        ) {
            for why in no_robust_point_diagnosis(&setup, a.gap_mm, &responses) {
                text.push_str(&format!("\n  why: {why}"));
            }
        }
        if let Some(w) = &warning {
            text.push_str(&format!("\n  warning: {w}"));
        }
        anyhow!(text)
    })?;
    let nominal = responses.swap_remove(0);
    rep.warnings.extend(warning);
    if a.no_orbit_check {
        // The sweep's band and margin, as the report says.
    } else if let Err(e) = check_band(&setup, &mut rep) {
        rep.warnings.push(format!(
            "the chosen point's orbit could not be followed ({e:#}): the band's edges and the \
             margin are the sweep's samples"
        ));
    }
    band_warnings(&mut rep);
    let beyond = unsettled_beyond_edges(&setup, &rep, &nominal);
    rep.warnings.extend(beyond);
    if !a.no_basin_check {
        basin(a, &setup, &mut rep)?;
    }
    let spread = match &table {
        Some(t) => Some(propagate(&setup, a.gap_mm, t, &rep, a.draws, a.seed)?),
        None => None,
    };
    write_outputs(a, &setup, &rep, &nominal, spread.as_ref())?;
    if a.json {
        match &spread {
            Some(sp) => println!(
                "{}",
                serde_json::to_string_pretty(&ReportWithUncertainty {
                    report: &rep,
                    uncertainty: sp,
                })?
            ),
            None => println!("{}", serde_json::to_string_pretty(&rep)?),
        }
    } else {
        print_report(&rep);
        if let Some(b) = &rep.basin_check {
            print_basin(b);
        }
        if let Some(sp) = &spread {
            print_spread(&rep, sp, config, setup.uncertainty.as_ref());
        }
        for w in &rep.warnings {
            println!("  ! warning: {w}");
        }
    }
    Ok(())
}

/// The setup with `select`'s own options: the sweep, the margins, validated.
fn checked_setup(a: &SelectArgs) -> Result<Setup> {
    let mut setup = Setup::from_opts(&a.rig)?;
    if let Some(s) = &a.omega_ratio {
        setup.selection.omega_ratio = omega_sweep(s)?;
    }
    super::warn_coarse_steps(&setup, setup.selection.omega_ratio.lo);
    if let Some(p) = a.freq_margin_pct {
        setup.selection.freq_margin_pct = p;
    }
    if let Some(g) = a.gap_margin_mm {
        setup.selection.gap_margin_mm = g;
    }
    setup
        .selection
        .validate()
        .map_err(|e| anyhow!("{e} (--freq-margin-pct / --gap-margin-mm)"))?;
    Ok(setup)
}

/// The basin check's options, checked before the sweep, not after it.
fn check_basin_args(a: &SelectArgs) -> Result<()> {
    if a.no_basin_check {
        return Ok(());
    }
    anyhow::ensure!(
        (1..=1_000_000).contains(&a.basin_samples),
        "--basin-samples {}: out of range: allowed 1 ..= 1000000",
        a.basin_samples
    );
    anyhow::ensure!(
        (0.0..=1.0).contains(&a.basin_threshold),
        "--basin-threshold {}: out of range: allowed 0 ..= 1",
        a.basin_threshold
    );
    if let Some(n) = a.basin_max_periods {
        anyhow::ensure!(
            (1..=1_000_000).contains(&n),
            "--basin-max-periods {n}: out of range: allowed 1 ..= 1000000 (a start must \
             have periods to reach an attractor)"
        );
    }
    Ok(())
}

/// With `--uncertainty`: the config's `[uncertainty]` table, bounded, and `--draws` checked.
fn uncertainty_table(a: &SelectArgs, setup: &Setup) -> Result<Option<UncertaintyTable>> {
    if !a.uncertainty {
        return Ok(None);
    }
    let t = setup.uncertainty.clone().ok_or_else(|| {
        anyhow!(
            "--uncertainty needs a --config with an [uncertainty] table (identify contact \
             --out writes one)"
        )
    })?;
    t.check_bounded()?;
    anyhow::ensure!(
        (8..=100_000).contains(&a.draws),
        "--draws = {} is out of range: allowed 8 ..= 100000",
        a.draws
    );
    Ok(Some(t))
}

/// The band check's warnings: an edge the sweep disagrees with, an edge smeared over a span,
/// a margin to the located edges below the requirement.
fn band_warnings(rep: &mut SelectReport) {
    let Some(c) = &rep.band_check else {
        return;
    };
    let mut warnings = Vec::new();
    for e in [&c.lower, &c.upper] {
        if let Some(d) = &e.disagreement {
            warnings.push(format!("band edge: {d}"));
        }
        if let Some(s) = &e.smeared {
            warnings.push(format!(
                "band edge: the {} at Ω/ω {:.5}: {}; the margin measured to it is known to \
                 that span",
                e.kind,
                e.omega_ratio,
                s.describe("Ω/ω", "")
            ));
        }
    }
    // The sweep's margin met the requirement; the located edges may not.
    if rep.margin_freq_pct < rep.required_margin_freq_pct {
        warnings.push(format!(
            "the margin to the nearer band edge is {:.1} %, below the required ±{} %: the \
             point is less robust in frequency than the sweep showed",
            rep.margin_freq_pct, rep.required_margin_freq_pct
        ));
    }
    rep.warnings.extend(warnings);
}

/// The basin check of the chosen point (its transient as `--basin-max-periods` says, or from
/// the suspension's damping), flagged with a warning below the threshold.
fn basin(a: &SelectArgs, setup: &Setup, rep: &mut SelectReport) -> Result<()> {
    let mut basin_setup = setup.clone();
    let n = a.basin_max_periods.unwrap_or_else(|| {
        crate::attractors::transient_periods(
            &setup.params,
            BASIN_MAX_PERIODS,
            rep.omega_ratio,
            crate::attractors::ATTRACTOR_STEADY_TOL,
        )
    });
    basin_setup.settings.protocol.max_transient_periods = n;
    basin_setup.settings.protocol.steady_tol = crate::attractors::ATTRACTOR_STEADY_TOL;
    basin_setup
        .settings
        .protocol
        .validate()
        .map_err(|e| anyhow!("--basin-max-periods {n}: {e}"))?;
    let b = check_basin(
        &basin_setup,
        rep,
        a.basin_samples,
        a.basin_seed,
        a.basin_threshold,
    )?;
    if b.flagged {
        rep.warnings.push(format!(
            "the chosen 1/1 orbit is reached from only {:.1} % of the start-up conditions \
             (95 % interval {:.1}–{:.1} %; threshold {:.0} %){}",
            100.0 * b.fraction,
            100.0 * b.ci95[0],
            100.0 * b.ci95[1],
            100.0 * b.threshold,
            b.competitor.as_ref().map_or_else(String::new, |c| format!(
                "; the largest competing attractor is {} {} ({:.1} %, F_i/mg {:.2})",
                c.regime,
                c.id,
                100.0 * c.fraction,
                c.impact_force_mg
            ))
        ));
    }
    rep.basin_check = Some(b);
    Ok(())
}

/// `--out` and `--plot`: the nominal gap's response with the chosen point, band and window
/// (with `--uncertainty`, the figure of the draws' response band instead).
fn write_outputs(
    a: &SelectArgs,
    setup: &Setup,
    rep: &SelectReport,
    nominal: &[PointResult],
    spread: Option<&Propagation>,
) -> Result<()> {
    let mut outputs = Outputs::new();
    if a.out.is_none() && a.plot.is_none() {
        return outputs.commit();
    }
    let sweep = setup.selection.omega_ratio;
    let rows = response::rows(setup, &sweep, nominal, None);
    let points = points(&sweep, nominal);
    let p = setup.selection.freq_margin_pct / 100.0;
    let highlight = Highlight {
        chosen: (rep.omega_ratio, rep.impact_force_mg),
        band: rep.band_omega_ratio,
        window: [rep.omega_ratio * (1.0 - p), rep.omega_ratio * (1.0 + p)],
    };
    let title = format!(
        "{} rig, gap {:.2} mm: operating point {:.2} Hz (Ω/ω = {:.2})",
        setup.rig, a.gap_mm, rep.freq_hz, rep.omega_ratio
    );
    match spread {
        None => super::write_response(
            &mut outputs,
            a.out.as_deref(),
            a.plot.as_deref(),
            &title,
            &rows,
            &points,
            Some(highlight),
        )?,
        Some(sp) => {
            super::write_response(
                &mut outputs,
                a.out.as_deref(),
                None,
                &title,
                &rows,
                &points,
                Some(highlight),
            )?;
            if let Some(p) = &a.plot {
                let tmp = outputs.reserve(p)?;
                let title = format!(
                    "{} rig, gap {:.2} mm: response over {} draws of the identified law",
                    setup.rig, a.gap_mm, sp.draws
                );
                response_band(&tmp, &title, sp, &points, rep)?;
            }
        }
    }
    outputs.commit()
}

impl SelectArgs {
    fn config_name(&self) -> String {
        self.rig
            .config
            .as_ref()
            .map_or_else(String::new, |p| p.display().to_string())
    }
}

fn print_basin(b: &BasinCheck) {
    println!(
        "  start-up basin: {} of {} random starts (u0 {:.2} – {:.2} mm, u̇0 ±{:.0} mm/s, seed {}, \
         ≤ {} transient periods) reach the chosen orbit{}: {:.1} % (95 % interval {:.1} – {:.1} %){}",
        (b.fraction * f64::from(b.samples)).round(),
        b.samples,
        b.u0_mm[0],
        b.u0_mm[1],
        b.v0_mm_s[1],
        b.seed,
        b.max_transient_periods,
        b.chosen
            .as_ref()
            .map_or_else(String::new, |c| format!(" (attractor {c})")),
        100.0 * b.fraction,
        100.0 * b.ci95[0],
        100.0 * b.ci95[1],
        if b.flagged {
            " — below the threshold"
        } else {
            ""
        }
    );
    println!("    from rest: {}", b.from_rest);
    match &b.competitor {
        Some(c) => println!(
            "    largest competing attractor: {} {}, {:.1} % (95 % interval {:.1} – {:.1} %), F_i/mg {:.2}",
            c.regime,
            c.id,
            100.0 * c.fraction,
            100.0 * c.ci95[0],
            100.0 * c.ci95[1],
            c.impact_force_mg
        ),
        None => println!("    no competing attractor"),
    }
    if let Some(n) = b.attractors.iter().find(|a| a.id == "-") {
        println!(
            "    no attractor within the transient limit: {:.1} % (--basin-max-periods to wait longer)",
            100.0 * n.fraction
        );
    }
}

fn print_spread(
    r: &SelectReport,
    sp: &Propagation,
    config: String,
    table: Option<&crate::config::UncertaintyTable>,
) {
    println!(
        "  with the identified law's uncertainty ({} draws from {config}'s [uncertainty]{}, seed {}{}):",
        sp.draws,
        table
            .and_then(|t| t.method.as_deref())
            .map_or_else(String::new, |m| format!(" ({m})")),
        sp.seed,
        if sp.redrawn > 0 {
            format!(", {} invalid draws redrawn", sp.redrawn)
        } else {
            String::new()
        }
    );
    println!(
        "    operating frequency {:.3} Hz (median), 95 % range {:.3} – {:.3} Hz{}",
        sp.freq_hz.median,
        sp.freq_hz.lo95,
        sp.freq_hz.hi95,
        if sp.no_selection > 0 {
            format!(" ({} draws without a robust 1/1 point)", sp.no_selection)
        } else {
            String::new()
        }
    );
    println!(
        "    its F_i/mg {:.2} (median), 95 % range {:.2} – {:.2}",
        sp.impact_force_mg.median, sp.impact_force_mg.lo95, sp.impact_force_mg.hi95
    );
    println!(
        "    the nominal {:.3} Hz is z = 1/1 in {:.0} % of the draws",
        r.freq_hz,
        100.0 * sp.nominal_one_one_share
    );
    match &sp.robust {
        Some(b) => println!(
            "    robust recommendation: {:.3} Hz (Ω/ω = {:.2}): z = 1/1 in every draw, F_i/mg ≥ {:.2} (median {:.2})",
            b.freq_hz, b.omega_ratio, b.worst_impact_force_mg, b.median_impact_force_mg
        ),
        None => println!("    no frequency of the sweep is z = 1/1 in every draw"),
    }
}

fn print_report(r: &SelectReport) {
    println!(
        "Operating frequency for the {} rig at {:.2} mm gap ({} law, {:?}):",
        r.rig, r.gap_mm, r.law, r.precision
    );
    println!(
        "  run the shaker at {:.3} Hz  (Ω/ω = {:.3}, ω/2π = {:.3} Hz)",
        r.freq_hz, r.omega_ratio, r.natural_freq_hz
    );
    println!(
        "  regime z = {}, predicted impact force F_i/mg = {:.2}",
        r.regime, r.impact_force_mg
    );
    match &r.band_check {
        Some(c) => {
            let edge = |e: &crate::selection::EdgeReport| {
                format!(
                    "{} at {:.4} Hz (Ω/ω {:.5}{})",
                    match e.kind {
                        EdgeKind::Open => "no bifurcation before the sweep's end",
                        EdgeKind::Stalled => {
                            "no edge located (the branch was not followed); the sweep's"
                        }
                        k => k.name(),
                    },
                    e.freq_hz,
                    e.omega_ratio,
                    e.multiplier
                        .map(|m| if m[1] == 0.0 {
                            format!(", μ = {:+.4}", m[0])
                        } else {
                            format!(", |μ| = {:.4}", m[0].hypot(m[1]))
                        })
                        .unwrap_or_default()
                        + &e.multiplier_at
                            .map(|at| format!(" of the branch's last orbit, at Ω/ω {at:.5}"))
                            .unwrap_or_default(),
                ) + if e.at_jump {
                    ", across a jump of the discretised map: μ passes −1 by the jump"
                } else {
                    ""
                }
            };
            println!(
                "  z = 1/1 band {:.3} – {:.3} Hz, {}:",
                c.lower.freq_hz,
                c.upper.freq_hz,
                match located_edges(c) {
                    2 => "located on the orbit's branch",
                    1 => "one edge located on the orbit's branch",
                    _ => "no edge located (the orbit's branch was not followed)",
                }
            );
            println!("    lower edge: {}", edge(&c.lower));
            println!("    upper edge: {}", edge(&c.upper));
            println!(
                "    (the sweep's band: Ω/ω {:.2} – {:.2}, step {}; {})",
                r.band_omega_ratio[0],
                r.band_omega_ratio[1],
                c.sweep_step,
                if c.lower.agrees && c.upper.agrees {
                    "agrees within a step"
                } else {
                    "disagrees, see the warnings"
                }
            );
            let m = &c.orbit.multipliers;
            println!(
                "  orbit: Floquet multipliers {}, max |μ| = {:.4}: {}, stability margin 1 − max|μ| = {:.3}",
                if m[0][1] == 0.0 {
                    format!("{:+.4}, {:+.4}", m[0][0], m[1][0])
                } else {
                    format!("{:+.4} ± {:.4}i", m[0][0], m[0][1].abs())
                },
                c.orbit.max_abs_multiplier,
                c.orbit.stability.name(),
                c.orbit.margin
            );
        }
        None => println!(
            "  z = 1/1 band {:.3} – {:.3} Hz (Ω/ω {:.2} – {:.2}, the sweep's samples)",
            r.band_hz[0], r.band_hz[1], r.band_omega_ratio[0], r.band_omega_ratio[1]
        ),
    }
    // The gaps in order (the report holds the nominal first).
    let mut gaps: Vec<f64> = r
        .gaps_checked_mm
        .iter()
        .map(|g| (g * 1e3).round() / 1e3)
        .collect();
    gaps.sort_by(f64::total_cmp);
    println!(
        "  margins: {:.1} % to the nearer band edge{} (required ±{} %); gap checked at {:?} mm (±{} mm)",
        r.margin_freq_pct,
        match &r.band_check {
            Some(c) if located_edges(c) == 2 => {
                format!(" located ({:.1} % to the sweep's)", c.sweep_margin_freq_pct)
            }
            Some(c) if located_edges(c) == 1 => format!(
                " (one edge located, the other the sweep's; {:.1} % to the sweep's)",
                c.sweep_margin_freq_pct
            ),
            Some(_) => " (the sweep's: no edge located)".to_string(),
            None => String::new(),
        },
        r.required_margin_freq_pct,
        gaps,
        r.margin_gap_mm
    );
    println!(
        "  worst F_i/mg inside the robustness box: {:.2} ({} robust points)",
        r.worst_impact_force_mg, r.robust_points
    );
    if let Some(o) = &r.other_best {
        println!(
            "  for information, strongest other regime: z = {} at {:.3} Hz (Ω/ω = {:.2}), F_i/mg = {:.2}",
            o.regime, o.freq_hz, o.omega_ratio, o.impact_force_mg
        );
    }
}

/// How many of the band's two edges were located on the orbit's branch (the others are the
/// sweep's: the branch was not followed there).
fn located_edges(c: &crate::selection::BandCheck) -> usize {
    [&c.lower, &c.upper]
        .iter()
        .filter(|e| e.kind != EdgeKind::Stalled)
        .count()
}

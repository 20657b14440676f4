//! `host-sim compare`: a measured record against the simulation (thesis §3.3.4, §3.4.2).
//!
//! Two kinds of record, told apart by their header:
//! - **frequency response** (a `freq_hz` or `omega_ratio` column, and `impact_force_mg` or
//!   `impact_force_n`): the measured max `F_i/mg` per frequency over the simulated response
//!   (canonical protocol from rest at each frequency, as `response` does; Figs. 3.12–3.14).
//!   Error summary at the measured frequencies: bias, RMS and largest difference of `F_i/mg`.
//! - **time series** at one frequency (`--freq-hz`; a time column and the absolute hammer
//!   displacement `x`, Eq. 3-18, e.g. `x_mm`): the measured displacement, phase plane
//!   `(x, ẋ)` (`ẋ` by central differences) and Poincaré points (`t = kT`) over the simulated
//!   steady state (after `--transient-periods` from rest). The record's phase relative to the
//!   shaker is unknown, so the simulation is shifted by the `τ ∈ [0, T)` (256 trials) that
//!   minimises the RMS displacement difference; the error summary gives that RMS.

use std::path::PathBuf;

use anyhow::{Context, Result, bail, ensure};
use clap::Args;
use shared::analysis::response::OMEGA_RATIO_RANGE;
use shared::error::{check_count, check_range};
use shared::observe::Regime;

use crate::config::RigOpts;
use crate::config::{Setup, gap_m_from_mm};
use crate::output::Outputs;
use crate::plot_identify::{self, ResponseOverlay, TsOverlay};
use crate::runner::{OperatingPoint, evaluate_all};
use crate::series;
use crate::trace::{MotionUnit, TimeUnit, TraceFormat, read_trace};

/// Arguments of `compare`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct CompareArgs {
    /// Rig and numerics (use --config with the identified parameters).
    #[command(flatten)]
    pub rig: RigOpts,
    /// Measured record (CSV): a frequency response or a time series, see `--help`.
    #[arg(long, value_name = "FILE.csv")]
    pub experiment: PathBuf,
    /// Gap of the experiment, mm.
    #[arg(long)]
    pub gap_mm: f64,
    /// Excitation frequency of a time-series record, Hz.
    #[arg(long)]
    pub freq_hz: Option<f64>,
    /// Time-series record: time column (name or 1-based number).
    #[arg(long, default_value = "t_s")]
    pub time_col: String,
    /// Time-series record: unit of the time column.
    #[arg(long, value_enum, default_value = "s")]
    pub time_unit: TimeUnit,
    /// Time-series record: fixed sample rate, Hz (instead of a time column).
    #[arg(long)]
    pub sample_rate_hz: Option<f64>,
    /// Time-series record: absolute displacement column (name or 1-based number).
    #[arg(long, default_value = "x_mm")]
    pub disp_col: String,
    /// Time-series record: unit of the displacement column.
    #[arg(long, value_enum, default_value = "mm")]
    pub disp_unit: MotionUnit,
    /// Time series: periods simulated from rest before the comparison window (1..=10000).
    #[arg(long, default_value_t = 200)]
    pub transient_periods: u32,
    /// PNG with the overlay.
    #[arg(long, value_name = "FILE.png")]
    pub out: PathBuf,
}

/// Runs `compare`.
///
/// # Errors
/// Bad input or I/O failure.
pub fn run(a: &CompareArgs) -> Result<()> {
    let setup = Setup::from_opts(&a.rig)?;
    let gap_m = gap_m_from_mm("--gap-mm", a.gap_mm)?;
    let text = std::fs::read_to_string(&a.experiment)
        .with_context(|| format!("cannot read --experiment {}", a.experiment.display()))?;
    let header = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#') && !l.starts_with('%'))
        .unwrap_or("")
        .to_ascii_lowercase();
    if header.contains("freq_hz") || header.contains("omega_ratio") {
        compare_response(a, &setup, gap_m, &text)
    } else {
        compare_time_series(a, &setup, gap_m)
    }
}

/// One measured point of a frequency response.
#[derive(Debug, Clone, Copy)]
struct Measured {
    omega_ratio: f64,
    force_mg: f64,
}

fn parse_response(text: &str, setup: &Setup) -> Result<Vec<Measured>> {
    let mut rdr = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let headers = rdr.headers().context("header")?.clone();
    let find = |name: &str| headers.iter().position(|h| h.eq_ignore_ascii_case(name));
    let (x_col, x_is_ratio) = match (find("omega_ratio"), find("freq_hz")) {
        (Some(c), _) => (c, true),
        (None, Some(c)) => (c, false),
        _ => bail!("no `omega_ratio` or `freq_hz` column"),
    };
    let (y_col, y_is_mg) = match (find("impact_force_mg"), find("impact_force_n")) {
        (Some(c), _) => (c, true),
        (None, Some(c)) => (c, false),
        _ => bail!("no `impact_force_mg` or `impact_force_n` column"),
    };
    let mut out = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            anyhow::anyhow!("line {line}: {e}")
        })?;
        let line = rec.position().map_or(0, |p| p.line());
        let cell = |c: usize, name: &str| -> Result<f64> {
            let s = rec.get(c).unwrap_or("");
            let v: f64 = s.parse().map_err(|_| {
                anyhow::anyhow!("line {line}, column `{name}`: `{s}` is not a number")
            })?;
            ensure!(
                v.is_finite(),
                "line {line}, column `{name}`: `{s}` is not finite"
            );
            Ok(v)
        };
        let x = cell(x_col, &headers[x_col])?;
        let y = cell(y_col, &headers[y_col])?;
        let ratio = if x_is_ratio {
            x
        } else {
            setup.params.ratio_from_freq_hz(x)
        };
        check_range(
            "omega_ratio",
            ratio,
            OMEGA_RATIO_RANGE.0,
            OMEGA_RATIO_RANGE.1,
        )
        .with_context(|| format!("line {line}"))?;
        ensure!(y >= 0.0, "line {line}: the impact force {y} is negative");
        out.push(Measured {
            omega_ratio: ratio,
            force_mg: if y_is_mg {
                y
            } else {
                y / setup.params.weight_n()
            },
        });
    }
    ensure!(!out.is_empty(), "no data rows");
    Ok(out)
}

fn compare_response(a: &CompareArgs, setup: &Setup, gap_m: f64, text: &str) -> Result<()> {
    let meas = parse_response(text, setup)
        .with_context(|| format!("--experiment {}", a.experiment.display()))?;
    let lo = meas
        .iter()
        .map(|m| m.omega_ratio)
        .fold(f64::INFINITY, f64::min);
    let hi = meas.iter().map(|m| m.omega_ratio).fold(0.0, f64::max);
    let (lo, hi) = (
        (lo - 0.05).max(OMEGA_RATIO_RANGE.0),
        (hi + 0.05).min(OMEGA_RATIO_RANGE.1),
    );
    let n_line = (((hi - lo) / 0.01).round() as usize).clamp(2, 2000);
    let mut points: Vec<OperatingPoint> = (0..=n_line)
        .map(|i| OperatingPoint {
            gap_m,
            omega_ratio: lo + (hi - lo) * i as f64 / n_line as f64,
        })
        .collect();
    points.extend(meas.iter().map(|m| OperatingPoint {
        gap_m,
        omega_ratio: m.omega_ratio,
    }));
    let results = evaluate_all(setup, &points, "compare")?;
    let (line, at_meas) = results.split_at(n_line + 1);
    let diffs: Vec<f64> = at_meas
        .iter()
        .zip(&meas)
        .map(|(s, m)| s.impact_force_mg - m.force_mg)
        .collect();
    let n = diffs.len() as f64;
    let bias = diffs.iter().sum::<f64>() / n;
    let rms = (diffs.iter().map(|d| d * d).sum::<f64>() / n).sqrt();
    let (imax, dmax) = diffs
        .iter()
        .enumerate()
        .max_by(|x, y| x.1.abs().total_cmp(&y.1.abs()))
        .map(|(i, d)| (i, *d))
        .unwrap_or((0, 0.0));
    let both_impact = at_meas
        .iter()
        .zip(&meas)
        .filter(|(s, m)| (s.regime != Regime::NoImpact) == (m.force_mg > 0.0))
        .count();
    let summary = format!(
        "{} points: F_i/mg simulated − measured: bias {:+.2}, RMS {:.2}, largest {:+.2} at Ω/ω = {:.3}; \
         impact/no-impact agrees at {}/{}",
        meas.len(),
        bias,
        rms,
        dmax,
        meas[imax].omega_ratio,
        both_impact,
        meas.len()
    );
    let overlay = ResponseOverlay {
        sim: line
            .iter()
            .zip(&points)
            .map(|(r, p)| (p.omega_ratio, r.impact_force_mg, r.regime))
            .collect(),
        measured: meas.iter().map(|m| (m.omega_ratio, m.force_mg)).collect(),
    };
    let title = format!(
        "{} rig, gap {:.2} mm, {} law: measured vs simulated frequency response",
        setup.rig,
        a.gap_mm,
        setup.params.contact.kind()
    );
    let mut outputs = Outputs::new();
    let tmp = outputs.reserve(&a.out)?;
    plot_identify::response_compare(&tmp, &title, &summary, &overlay)?;
    outputs.commit()?;
    println!("{}: {summary}", a.experiment.display());
    Ok(())
}

fn compare_time_series(a: &CompareArgs, setup: &Setup, gap_m: f64) -> Result<()> {
    let Some(freq_hz) = a.freq_hz else {
        bail!(
            "--experiment {} is a time series (no freq_hz/omega_ratio column): give its \
             excitation frequency with --freq-hz",
            a.experiment.display()
        );
    };
    ensure!(
        !a.disp_unit.is_acceleration(),
        "--disp-unit must be a displacement unit (m, mm, um)"
    );
    let fn_hz = setup.params.natural_freq_hz();
    check_range(
        "freq_hz",
        freq_hz,
        OMEGA_RATIO_RANGE.0 * fn_hz,
        OMEGA_RATIO_RANGE.1 * fn_hz,
    )
    .context("--freq-hz")?;
    check_count("transient_periods", a.transient_periods, 1, 10_000)
        .context("--transient-periods")?;
    let trace = read_trace(
        &a.experiment,
        &TraceFormat {
            time_col: a.time_col.clone(),
            value_col: a.disp_col.clone(),
            time_to_s: a.time_unit.to_s(),
            value_to_si: a.disp_unit.to_si(),
            sample_rate_hz: a.sample_rate_hz,
        },
        "displacement",
    )?;
    let t0 = trace.t_s[0];
    let t_meas: Vec<f64> = trace.t_s.iter().map(|t| t - t0).collect();
    let x_meas: Vec<f64> = trace.value.iter().map(|x| x * 1e3).collect();
    let duration = t_meas[t_meas.len() - 1];
    let period = 1.0 / freq_hz;
    let record_periods = (duration / period).ceil() as u32 + 2;
    ensure!(
        record_periods <= 100_000,
        "the record spans {record_periods} excitation periods (at most 100000)"
    );
    let omega_exc = 2.0 * std::f64::consts::PI * freq_hz;
    let periods = a.transient_periods + record_periods;
    let (rows, _) = series::simulate(setup, gap_m, omega_exc, periods, 0.0, 0.0)?;
    let t_start = f64::from(a.transient_periods) * period;
    // Simulated absolute displacement and velocity after the transient, t from 0.
    let sim: Vec<(f64, f64, f64)> = rows
        .iter()
        .filter(|r| r.t_s >= t_start - 1e-12)
        .map(|r| {
            let t = r.t_s - t_start;
            let v =
                r.du_mm_s + setup.params.amplitude_m * 1e3 * omega_exc * (omega_exc * r.t_s).cos();
            (t, r.x_mm, v)
        })
        .collect();
    let interp = |t: f64| -> f64 {
        let i = sim.partition_point(|s| s.0 <= t).clamp(1, sim.len() - 1);
        let (ta, xa, _) = sim[i - 1];
        let (tb, xb, _) = sim[i];
        if tb > ta {
            xa + (xb - xa) * (t - ta) / (tb - ta)
        } else {
            xb
        }
    };
    // The phase shift τ: measured t ↔ simulated t + τ.
    let mut best = (0.0, f64::INFINITY);
    for k in 0..256 {
        let tau = period * f64::from(k) / 256.0;
        let ss: f64 = t_meas
            .iter()
            .zip(&x_meas)
            .map(|(&t, &x)| (interp(t + tau) - x).powi(2))
            .sum();
        if ss < best.1 {
            best = (tau, ss);
        }
    }
    let tau = best.0;
    let rms = (best.1 / t_meas.len() as f64).sqrt();
    let (xlo, xhi) = x_meas
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, &x| {
            (a.0.min(x), a.1.max(x))
        });
    // Measured velocity by central differences.
    let n = t_meas.len();
    let v_meas: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
            (x_meas[b] - x_meas[a]) / (t_meas[b] - t_meas[a])
        })
        .collect();
    // Poincaré points: measured samples nearest to t + τ = kT (simulated phase 0).
    let mut strobe_meas = Vec::new();
    let mut k = ((tau / period).ceil()) as i64;
    loop {
        let t = k as f64 * period - tau;
        if t > duration {
            break;
        }
        if t >= 0.0 {
            let i = t_meas.partition_point(|&s| s < t).min(n - 1);
            strobe_meas.push((x_meas[i], v_meas[i]));
        }
        k += 1;
    }
    let strobe_sim: Vec<(f64, f64)> = rows
        .iter()
        .filter(|r| r.poincare && r.t_s >= t_start - 1e-12)
        .map(|r| {
            let v =
                r.du_mm_s + setup.params.amplitude_m * 1e3 * omega_exc * (omega_exc * r.t_s).cos();
            (r.x_mm, v)
        })
        .collect();
    let summary = format!(
        "{} samples over {:.3} s at {:.3} Hz (Ω/ω = {:.3}): displacement RMS difference {:.4} mm \
         ({:.1} % of the measured peak-to-peak {:.3} mm), phase shift {:.1}°",
        n,
        duration,
        freq_hz,
        freq_hz / fn_hz,
        rms,
        100.0 * rms / (xhi - xlo).max(1e-12),
        xhi - xlo,
        360.0 * tau / period
    );
    let overlay = TsOverlay {
        measured: t_meas
            .iter()
            .zip(&x_meas)
            .zip(&v_meas)
            .map(|((&t, &x), &v)| (t, x, v))
            .collect(),
        sim: sim
            .iter()
            .filter(|s| s.0 >= tau && s.0 <= duration + tau)
            .map(|&(t, x, v)| (t - tau, x, v))
            .collect(),
        strobe_measured: strobe_meas,
        strobe_sim,
    };
    let title = format!(
        "{} rig, gap {:.2} mm, {:.3} Hz, {} law: measured vs simulated",
        setup.rig,
        a.gap_mm,
        freq_hz,
        setup.params.contact.kind()
    );
    let mut outputs = Outputs::new();
    let tmp = outputs.reserve(&a.out)?;
    plot_identify::time_series_compare(&tmp, &title, &summary, &overlay)?;
    outputs.commit()?;
    println!("{}: {summary}", a.experiment.display());
    Ok(())
}

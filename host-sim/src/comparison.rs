//! A measured record against the simulation (thesis §3.3.4, §3.4.2): a frequency response
//! (measured max `F_i/mg` per frequency over the simulated response from rest, Figs.
//! 3.12–3.14) or a time series at one frequency (the measured absolute displacement, phase
//! plane and Poincaré points over the simulated steady state, Figs. 3.16–3.23), each with an
//! error summary. The record is a lab file ([`LabTable`]).

use anyhow::{Context, Result, bail, ensure};
use shared::analysis::response::OMEGA_RATIO_RANGE;
use shared::error::check_range;
use shared::observe::Regime;

use crate::config::Setup;
use crate::runner::{OperatingPoint, evaluate_all};
use crate::series;
use crate::trace::{LabTable, Trace};

/// A simulated frequency response and the measured points, for the comparison figure.
#[derive(Debug, Clone, Default)]
pub struct ResponseOverlay {
    /// `(Ω/ω, F_i/mg, regime)` of the simulation.
    pub sim: Vec<(f64, f64, shared::observe::Regime)>,
    /// `(Ω/ω, F_i/mg)` measured.
    pub measured: Vec<(f64, f64)>,
}

/// A measured and a simulated time series, for the comparison figure.
#[derive(Debug, Clone, Default)]
pub struct TsOverlay {
    /// `(t s, x mm, ẋ mm/s)` measured.
    pub measured: Vec<(f64, f64, f64)>,
    /// `(t s, x mm, ẋ mm/s)` simulated, on the measured time axis.
    pub sim: Vec<(f64, f64, f64)>,
    /// Poincaré points `(x, ẋ)` measured.
    pub strobe_measured: Vec<(f64, f64)>,
    /// Poincaré points `(x, ẋ)` simulated.
    pub strobe_sim: Vec<(f64, f64)>,
}

/// The record's shortest repeat at the excitation period `T`: over `q = 1..=4` (those the
/// record spans twice), the smallest RMS of `x(t + qT) − x(t)` (mm; `x` linear between the
/// samples), with that `q`; `None` for a record shorter than `2T`. A steady periodic motion
/// (`p/q`, `q ≤ 4`) repeats to the noise; a transient, chaos, or a record taken at another
/// frequency than `T`'s does not.
pub fn repeat_rms(t: &[f64], x: &[f64], period: f64) -> Option<(u32, f64)> {
    let duration = t.last()? - t.first()?;
    let at = |s: f64| linear_at(t, x, s);
    (1..=4u32)
        .filter(|&q| 2.0 * f64::from(q) * period <= duration)
        .map(|q| {
            let shift = f64::from(q) * period;
            let (n, ss) = t
                .iter()
                .zip(x)
                .take_while(|(ti, _)| **ti + shift <= t[t.len() - 1])
                .fold((0usize, 0.0), |(n, ss), (&ti, &xi)| {
                    (n + 1, ss + (at(ti + shift) - xi).powi(2))
                });
            (q, (ss / n.max(1) as f64).sqrt())
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// `x` at `s`, linear between the samples `(t[i], x[i])` (`t` non-decreasing, at least two;
/// the end segments extended beyond the ends).
fn linear_at(t: &[f64], x: &[f64], s: f64) -> f64 {
    let i = t.partition_point(|&ti| ti <= s).clamp(1, t.len() - 1);
    let (ta, tb) = (t[i - 1], t[i]);
    if tb > ta {
        x[i - 1] + (x[i] - x[i - 1]) * (s - ta) / (tb - ta)
    } else {
        x[i]
    }
}

/// Above this share of the record's peak-to-peak, [`repeat_rms`] says the record is not a
/// steady periodic motion at the given frequency (`compare` warns).
pub const REPEAT_WARN: f64 = 0.05;

/// One measured point of a frequency response.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Max impact force, `F_i/mg` (≥ 0).
    pub force_mg: f64,
}

/// Whether a lab file holds a frequency response: a header column containing `freq_hz` or
/// `omega_ratio` (otherwise it is read as a time series).
pub fn is_response(table: &LabTable) -> bool {
    table.header.iter().flatten().any(|h| {
        let h = h.to_ascii_lowercase();
        h.contains("freq_hz") || h.contains("omega_ratio")
    })
}

/// The measured points of a frequency-response file: an `omega_ratio` or `freq_hz` column and
/// an `impact_force_mg` or `impact_force_n` column (ASCII case ignored), converted with the
/// setup's natural frequency and weight.
///
/// # Errors
/// Missing columns, malformed cells (line and column named), a frequency outside the analyses'
/// range, a negative force, or no data rows.
pub fn measured_response(table: &LabTable, setup: &Setup) -> Result<Vec<Measured>> {
    let (x_col, x_is_ratio) = match (table.find("omega_ratio"), table.find("freq_hz")) {
        (Some(c), _) => (c, true),
        (None, Some(c)) => (c, false),
        _ => bail!("no `omega_ratio` or `freq_hz` column"),
    };
    let (y_col, y_is_mg) = match (table.find("impact_force_mg"), table.find("impact_force_n")) {
        (Some(c), _) => (c, true),
        (None, Some(c)) => (c, false),
        _ => bail!("no `impact_force_mg` or `impact_force_n` column"),
    };
    let mut out = Vec::with_capacity(table.rows().len());
    for row in table.rows() {
        let line = row.line;
        let x = row.number(x_col, "frequency")?;
        let y = row.number(y_col, "impact force")?;
        let ratio = if x_is_ratio {
            check_range("omega_ratio", x, OMEGA_RATIO_RANGE.0, OMEGA_RATIO_RANGE.1)
                .with_context(|| format!("line {line}"))?
        } else {
            // Checked in the file's own unit: the range of Ω/ω in Hz on this rig.
            let fn_hz = setup.params.natural_freq_hz();
            check_range(
                "freq_hz",
                x,
                OMEGA_RATIO_RANGE.0 * fn_hz,
                OMEGA_RATIO_RANGE.1 * fn_hz,
            )
            .with_context(|| format!("line {line}"))?;
            setup.params.ratio_from_freq_hz(x)
        };
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

/// The simulated response at gap `gap_m` (m) from rest, on a line over the measured span
/// (±0.05 in `Ω/ω`, step 0.01) and at the measured frequencies; the overlay and the error
/// summary (bias, RMS and largest difference of `F_i/mg`, impact/no-impact agreement).
///
/// # Errors
/// An invalid point.
pub fn response(setup: &Setup, gap_m: f64, meas: &[Measured]) -> Result<(ResponseOverlay, String)> {
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
        .zip(meas)
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
        .zip(meas)
        .filter(|(s, m)| (s.regime != Regime::NoImpact) == (m.force_mg > 0.0))
        .count();
    let summary = format!(
        "{}: F_i/mg simulated − measured: bias {:+.2}, RMS {:.2}, largest {:+.2} at Ω/ω = {:.3}; \
         impact/no-impact agrees at {}/{}",
        crate::output::count(meas.len() as u64, "point"),
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
    Ok((overlay, summary))
}

/// The simulated steady state at gap `gap_m` (m) and `freq_hz` (after `transient_periods`
/// from rest) against a measured absolute displacement `trace` (m): the simulation shifted by
/// the phase `τ ∈ [0, T)` (256 trials) that minimises the RMS displacement difference; the
/// overlay (mm, mm/s; measured velocity by central differences), the error summary, and a
/// warning where the record does not repeat with the excitation ([`repeat_rms`]).
///
/// # Errors
/// A record longer than 100000 periods, or an invalid simulation.
pub fn time_series(
    setup: &Setup,
    gap_m: f64,
    freq_hz: f64,
    transient_periods: u32,
    trace: &Trace,
) -> Result<(TsOverlay, String, Option<String>)> {
    let fn_hz = setup.params.natural_freq_hz();
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
    let periods = transient_periods + record_periods;
    let (rows, _) = series::simulate(
        setup,
        &series::SeriesSpec {
            gap_m,
            omega_exc,
            periods,
            u0_m: 0.0,
            v0_m_s: 0.0,
        },
    )?;
    let t_start = f64::from(transient_periods) * period;
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
    let (sim_t, sim_x): (Vec<f64>, Vec<f64>) = sim.iter().map(|s| (s.0, s.1)).unzip();
    let interp = |t: f64| linear_at(&sim_t, &sim_x, t);
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
    let warning = repeat_rms(&t_meas, &x_meas, period)
        .filter(|&(_, r)| r > REPEAT_WARN * (xhi - xlo))
        .map(|(q, r)| {
            format!(
                "the record does not repeat with the excitation period T: the RMS of \
                 x(t + qT) − x(t) is {r:.3} mm at the best q of 1–4 (q = {q}), {:.0} % of its \
                 peak-to-peak: a transient, a motion that is not periodic (chaos), or a record at \
                 another frequency than {freq_hz} Hz; the comparison assumes a steady periodic \
                 motion",
                100.0 * r / (xhi - xlo).max(1e-12)
            )
        });
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
    Ok((overlay, summary, warning))
}

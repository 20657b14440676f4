//! `host-sim orbit`: the periodic orbit at one operating point, with its Floquet multipliers
//! (the computation: [`crate::orbits`]).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use shared::error::check_count;
use shared::observe::Regime;
use shared::orbit::{MAX_Q, MapPoint, Orbit, Stability};

use super::simulate::write_series;
use super::{ExcitationOpts, StartOpts};
use crate::config::{RigOpts, Setup};
use crate::orbits::{self, OrbitReport, Start};
use crate::series::{self, SeriesSpec};

/// Where an orbit is sought: the rig, the point, the start and the period.
#[derive(Debug, Args)]
pub struct PointArgs {
    /// Rig and numerics (`--precision f64` for the reference; f32 is the MCU's arithmetic).
    #[command(flatten)]
    pub rig: RigOpts,
    /// Gap, mm (≥ 0).
    #[arg(long, default_value_t = 0.0)]
    pub gap_mm: f64,
    #[command(flatten)]
    pub excitation: ExcitationOpts,
    /// Period q of the orbit sought, excitation periods (1..=256; default: the period the
    /// protocol settles on from the start).
    #[arg(long)]
    pub q: Option<u32>,
    /// The start of the protocol run the search starts from.
    #[command(flatten)]
    pub start: StartOpts,
}

impl PointArgs {
    /// The setup, the map point and the start, checked.
    ///
    /// # Errors
    /// Bad input (the flag and its range named).
    pub fn resolve(&self) -> Result<(Setup, MapPoint, Start)> {
        let setup = Setup::from_opts(&self.rig)?;
        let gap_m = setup.gap_m("--gap-mm", self.gap_mm)?;
        let ratio = self.excitation.ratio(&setup)?;
        if let Some(q) = self.q {
            check_count("q", q, 1, MAX_Q).context("--q")?;
        }
        let (u_m, du_m_s) = self.start.start_m(self.gap_mm)?;
        let start = if self.start.u0_mm == 0.0 && self.start.v0_mm_s == 0.0 {
            Start::Rest
        } else {
            Start::Relative { u_m, du_m_s }
        };
        let at = orbits::map_point(&setup, gap_m, ratio);
        Ok((setup, at, start))
    }
}

/// Arguments of `orbit`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct OrbitArgs {
    /// The point.
    #[command(flatten)]
    pub point: PointArgs,
    /// Print one JSON object instead of the report.
    #[arg(long)]
    pub json: bool,
    /// CSV of the orbit over its q periods from its first Poincaré point, `simulate`'s
    /// columns: t_s, u_mm, du_mm_s, x_mm, impact_force_n, impact_force_mg, region, poincare,
    /// lyapunov_per_period.
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: Option<PathBuf>,
    /// PNG or SVG: the orbit over its q periods (displacement, impact force, phase plane with
    /// its Poincaré points), its multipliers in the title.
    #[arg(long, value_parser = crate::output::figure_target)]
    pub plot: Option<PathBuf>,
}

/// The orbit found and what the protocol saw, for JSON.
#[derive(serde::Serialize)]
struct OrbitJson<'a> {
    rig: String,
    precision: &'static str,
    protocol_regime: String,
    orbit: &'a OrbitReport,
    /// The map's slope against its monodromy over ±1e-4 of the state's scales
    /// ([`Orbit::slope_mismatch`]; above [`orbits::SLOPE_MISMATCH_WARN`] the map is not smooth
    /// that close to the orbit, and a warning says so).
    slope_mismatch: f64,
    /// In f32, at an orbit near a period doubling: what the same search finds in f64.
    #[serde(skip_serializing_if = "Option::is_none")]
    near_doubling: Option<DoublingCheck>,
}

/// A real Floquet multiplier within this of −1 (or of +1 on an even period, where the doubled
/// orbit is born) puts the orbit at a period doubling, where f32's rounding may converge onto
/// the orbit's double instead of the orbit (or the reverse): the search is repeated in f64.
pub const NEAR_DOUBLING: f64 = 0.01;

/// The f64 search beside an f32 orbit near a period doubling.
#[derive(Debug, Clone, serde::Serialize)]
pub struct DoublingCheck {
    /// The f32 orbit's multiplier near ±1.
    pub mu: f64,
    /// The orbit the same search finds in f64, or `None` when it finds none (`f64_error`).
    pub f64_orbit: Option<OrbitReport>,
    /// Why f64 finds no orbit.
    pub f64_error: Option<String>,
}

/// The real multiplier of `o` near a period doubling ([`NEAR_DOUBLING`]), if any.
pub fn near_doubling(o: &OrbitReport) -> Option<f64> {
    o.multipliers
        .iter()
        .filter(|m| m[1] == 0.0)
        .map(|m| m[0])
        .find(|&mu| {
            (mu + 1.0).abs() < NEAR_DOUBLING
                || (o.q.is_multiple_of(2) && (mu - 1.0).abs() < NEAR_DOUBLING)
        })
}

/// The f64 search at `at` from `start` (period `q`) beside the f32 orbit `o`, when `o` is near a
/// period doubling.
fn doubling_check(
    o: &OrbitReport,
    at: &MapPoint,
    start: Start,
    q: Option<u32>,
) -> Option<DoublingCheck> {
    let mu = near_doubling(o)?;
    let found = orbits::find::<f64>(at, start, q).and_then(|(_, o64)| orbits::report(&o64));
    Some(match found {
        Ok(r) => DoublingCheck {
            mu,
            f64_orbit: Some(r),
            f64_error: None,
        },
        Err(e) => DoublingCheck {
            mu,
            f64_orbit: None,
            f64_error: Some(format!("{e:#}")),
        },
    })
}

/// The text of a [`DoublingCheck`] beside the f32 orbit `o`.
pub fn describe_doubling(o: &OrbitReport, c: &DoublingCheck) -> String {
    let head = format!(
        "  near a period doubling (μ = {:+.4}, within {NEAR_DOUBLING} of {}1): f32 may not tell \
         this orbit from its double;",
        c.mu,
        if c.mu < 0.0 { '−' } else { '+' }
    );
    match &c.f64_orbit {
        Some(r) if r.regime != o.regime => format!(
            "{head} in f64 the same search finds the {} orbit (max |μ| = {:.6}, μ = {:+.4}, \
             {:+.4}): `--precision f64`",
            r.regime, r.max_abs_multiplier, r.multipliers[0][0], r.multipliers[1][0]
        ),
        Some(r) => format!(
            "{head} f64 finds the same {} orbit (max |μ| = {:.6})",
            r.regime, r.max_abs_multiplier
        ),
        None => format!(
            "{head} f64 finds no orbit from this start: {}",
            c.f64_error.as_deref().unwrap_or("")
        ),
    }
}

/// `x`, or `+0` where it prints as zero at `decimals` places (no `-0.000000` for a value a
/// hair below zero).
fn unsigned_zero(x: f64, decimals: i32) -> f64 {
    if (x * 10f64.powi(decimals)).round() == 0.0 {
        0.0
    } else {
        x
    }
}

/// The report's text: the orbit, its multipliers and stability.
pub fn describe(o: &OrbitReport) -> String {
    let mu = |m: [f64; 2]| {
        if m[1] == 0.0 {
            format!("{:+.6}", unsigned_zero(m[0], 6))
        } else {
            format!(
                "{:+.6} {} {:.6}i",
                unsigned_zero(m[0], 6),
                if m[1] < 0.0 { '−' } else { '+' },
                m[1].abs()
            )
        }
    };
    let mut s = format!(
        "orbit {} at Ω/ω {:.6} ({:.4} Hz), gap {} mm\n",
        o.regime, o.omega_ratio, o.freq_hz, o.gap_mm
    );
    for (k, p) in o.section.iter().enumerate() {
        s += &format!(
            "  Poincaré point {}: u = {:+.6} mm, u̇ = {:+.4} mm/s\n",
            k + 1,
            unsigned_zero(p[0], 6),
            unsigned_zero(p[1], 4)
        );
    }
    s += &format!("  impact peak F_i/mg = {:.3}\n", o.impact_force_mg);
    s += &format!(
        "  Floquet multipliers μ1 = {}, μ2 = {}; max |μ| = {:.6}: {}, margin 1 − max|μ| = {:.4}\n",
        mu(o.multipliers[0]),
        mu(o.multipliers[1]),
        o.max_abs_multiplier,
        match o.stability {
            Stability::Neutral => {
                "neutral (no impact on an undamped suspension: the map preserves area, \
                 |μ| = 1 but for the integrator's error)"
            }
            other => other.name(),
        },
        o.margin
    );
    s += &format!(
        "  largest Lyapunov exponent ln max|μ| / q = {:.5} per period\n",
        o.lyapunov_per_period
    );
    s += &format!(
        "  Newton: {} iterations, scaled residual {:.2e}",
        o.iterations, o.residual
    );
    s
}

/// Runs `orbit`.
///
/// # Errors
/// Bad input, or no orbit at the point (the reason, with the point).
pub fn run(a: &OrbitArgs) -> Result<()> {
    a.point
        .rig
        .check_outputs(&[("--out", a.out.as_deref()), ("--plot", a.plot.as_deref())])?;
    let (setup, at, start) = a.point.resolve()?;
    let (protocol, (report, slope_mismatch)) = crate::with_precision!(setup.precision, T => {
        let (r, o): (_, Orbit<T>) = orbits::find::<T>(&at, start, a.point.q)?;
        let (mismatch, warning) = orbits::slope_check(&o)?;
        if let Some(w) = warning {
            eprintln!("{w}");
        }
        (r, (orbits::report(&o)?, mismatch))
    });
    let near = match setup.precision {
        crate::precision::Precision::F32 => doubling_check(&report, &at, start, a.point.q),
        crate::precision::Precision::F64 => None,
    };
    if a.json {
        let j = OrbitJson {
            rig: setup.rig.to_string(),
            precision: setup.precision.name(),
            protocol_regime: protocol.regime.to_string(),
            orbit: &report,
            slope_mismatch,
            near_doubling: near,
        };
        println!("{}", serde_json::to_string_pretty(&j)?);
    } else {
        println!(
            "{} rig, {}: the protocol from {} settled on {} ({})",
            setup.rig,
            setup.precision.name(),
            match start {
                Start::Rest => "rest".to_string(),
                // As given (the start in m, times 1e3, prints the conversion's rounding).
                Start::Relative { .. } => format!(
                    "u0 = {} mm, u̇0 = {} mm/s",
                    a.point.start.u0_mm, a.point.start.v0_mm_s
                ),
            },
            protocol.regime,
            crate::output::count(u64::from(protocol.transient_periods), "period")
        );
        if let Some(q) = a.point.q.filter(|&q| q != report.q) {
            println!(
                "  (asked q = {q}: the fixed point of P^{q} found is this orbit of minimal period {})",
                report.q
            );
        } else if let (None, Regime::Periodic { q, .. }) = (a.point.q, protocol.regime)
            && u32::from(q) != report.q
        {
            println!(
                "  (the protocol's window repeats every {q} periods, but the fixed point of P^{q} \
                 found is this orbit of minimal period {}: the window had not converged onto it)",
                report.q
            );
        }
        println!("{}", describe(&report));
        if let Some(c) = &near {
            println!("{}", describe_doubling(&report, c));
        }
    }
    if a.out.is_some() || a.plot.is_some() {
        write_orbit(&setup, &report, a)?;
    }
    Ok(())
}

/// The orbit's time series over its `q` periods, simulated from its first Poincaré point (the
/// section at `Ωt = 0`), written as `simulate` writes one (`--out`, `--plot`).
///
/// # Errors
/// File or drawing errors.
fn write_orbit(setup: &Setup, report: &OrbitReport, a: &OrbitArgs) -> Result<()> {
    let [u_mm, du_mm_s] = report.section[0];
    // The point as `simulate` reads it from the same flags.
    let gap_m = setup.gap_m("--gap-mm", a.point.gap_mm)?;
    let ratio = a.point.excitation.ratio(setup)?;
    let (rows, _) = series::simulate(
        setup,
        &SeriesSpec {
            gap_m,
            omega_exc: ratio * setup.params.omega_n(),
            periods: report.q,
            u0_m: u_mm * 1e-3,
            v0_m_s: du_mm_s * 1e-3,
        },
    )?;
    let title = format!(
        "{} rig, gap {:.2} mm, Ω/ω = {:.4}: orbit {}, {}, max |μ| = {:.4}",
        setup.rig,
        report.gap_mm,
        report.omega_ratio,
        report.regime,
        report.stability.name(),
        report.max_abs_multiplier
    );
    write_series(
        &rows,
        a.out.as_deref(),
        a.plot.as_deref(),
        &title,
        report.gap_mm,
    )
}

#[cfg(test)]
mod tests {
    use super::unsigned_zero;

    #[test]
    fn a_value_a_hair_below_zero_prints_as_plus_zero() {
        assert_eq!(format!("{:+.6}", unsigned_zero(-4e-7, 6)), "+0.000000");
        assert_eq!(format!("{:+.6}", unsigned_zero(-6e-7, 6)), "-0.000001");
        assert_eq!(format!("{:+.4}", unsigned_zero(-0.0, 4)), "+0.0000");
        assert_eq!(unsigned_zero(-2.5, 6), -2.5);
    }
}

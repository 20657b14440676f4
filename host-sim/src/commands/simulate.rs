//! `host-sim simulate`: the time series of one operating point.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use serde::Serialize;
use shared::Real;
use shared::analysis::response::OMEGA_RATIO_RANGE;
use shared::error::{check_count, check_range};
use shared::integrate::{PhaseTable, Simulator, StepSample};
use shared::observe::{ImpactEvent, ImpactTracker};

use crate::cli::{Precision, RigOpts};
use crate::config::{Setup, gap_m_from_mm};
use crate::output::{Outputs, write_csv};
use crate::plot::{self, TsPoint};

/// Arguments of `simulate`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct SimulateArgs {
    /// Rig and numerics.
    #[command(flatten)]
    pub rig: RigOpts,
    /// Gap, mm (≥ 0).
    #[arg(long)]
    pub gap_mm: f64,
    /// Excitation frequency as Ω/ω (give this or --freq-hz).
    #[arg(long, conflicts_with = "freq_hz")]
    pub omega_ratio: Option<f64>,
    /// Excitation frequency, Hz.
    #[arg(long)]
    pub freq_hz: Option<f64>,
    /// Excitation periods to simulate (1..=100000).
    #[arg(long, default_value_t = 20)]
    pub periods: u32,
    /// Initial relative displacement u0, mm (default: at rest, 0).
    #[arg(long, default_value_t = 0.0)]
    pub u0_mm: f64,
    /// Initial relative velocity u̇0, mm/s.
    #[arg(long, default_value_t = 0.0)]
    pub v0_mm_s: f64,
    /// CSV: t_s, u_mm, du_mm_s, x_mm, impact_force_n, impact_force_mg, region, poincare.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// PNG: displacement, impact force and phase plane with the Poincaré points.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// One CSV row (after every RK4 step or sub-step).
#[derive(Debug, Clone, Serialize)]
pub struct TsRow {
    /// Time since the start, s.
    pub t_s: f64,
    /// Relative displacement `u`, mm.
    pub u_mm: f64,
    /// Relative velocity `u̇`, mm/s.
    pub du_mm_s: f64,
    /// Absolute hammer displacement `x = u + A0 sin Ωt`, mm (Eq. 3-18).
    pub x_mm: f64,
    /// Contact force `F_i`, N.
    pub impact_force_n: f64,
    /// `F_i/mg`.
    pub impact_force_mg: f64,
    /// Switch-model region: free, contact, band-alpha, band-beta.
    pub region: &'static str,
    /// Whether the row is a Poincaré-section instant `t = kT`.
    pub poincare: bool,
}

/// Summary of a run.
#[derive(Debug, Clone, Copy, Default)]
pub struct TsSummary {
    /// Impacts (arrivals).
    pub impacts: u32,
    /// Largest episode peak, `F_i/mg`.
    pub max_force_mg: f64,
}

/// Simulates `periods` periods from `(u0, v0)` (m, m/s) at phase 0.
///
/// # Errors
/// Invalid parameters or initial state.
pub fn time_series<T: Real>(
    setup: &Setup,
    gap_m: f64,
    omega_exc: f64,
    periods: u32,
    u0_m: f64,
    v0_m_s: f64,
) -> Result<(Vec<TsRow>, TsSummary)> {
    let phases = PhaseTable::new(setup.settings.steps.steps_per_period)?;
    let mut sim = Simulator::<T>::new(
        &setup.params,
        gap_m,
        omega_exc,
        &setup.settings.bands,
        &setup.settings.steps,
        &phases,
    )?;
    sim.reset_relative(u0_m, v0_m_s)
        .context("initial state (--u0-mm, --v0-mm-s)")?;
    let hammer = *sim.hammer();
    let h_sub = sim.step_s();
    let a0 = setup.params.amplitude_m;
    let mg = setup.params.weight_n();
    let (d0, _) = hammer.penetration(&sim.state());
    let mut tracker = ImpactTracker::new(T::from_f64(setup.settings.protocol.separation_m), d0);
    let mut summary = TsSummary::default();
    let (u, du) = sim.relative();
    let mut rows = vec![TsRow {
        t_s: 0.0,
        u_mm: u.to_f64() * 1e3,
        du_mm_s: du.to_f64() * 1e3,
        x_mm: u.to_f64() * 1e3,
        impact_force_n: 0.0,
        impact_force_mg: 0.0,
        region: "free",
        poincare: true,
    }];
    for _ in 0..periods {
        sim.run_period(&mut |s: &StepSample<T>| {
            match tracker.update(s.delta, s.delta_min, s.force) {
                Some(ImpactEvent::Arrival) => summary.impacts += 1,
                Some(ImpactEvent::End { peak_n }) => {
                    summary.max_force_mg = summary.max_force_mg.max(peak_n.to_f64() / mg);
                }
                None => {}
            }
            let (u, du) = hammer.relative(&s.x);
            let t = s.time_s(h_sub);
            let u = u.to_f64();
            let f = s.force.to_f64();
            rows.push(TsRow {
                t_s: t,
                u_mm: u * 1e3,
                du_mm_s: du.to_f64() * 1e3,
                x_mm: (u + a0 * (omega_exc * t).sin()) * 1e3,
                impact_force_n: f,
                impact_force_mg: f / mg,
                region: match s.region {
                    shared::model::Region::Free => "free",
                    shared::model::Region::Contact => "contact",
                    shared::model::Region::BandAlpha => "band-alpha",
                    shared::model::Region::BandBeta => "band-beta",
                },
                poincare: s.period_end,
            });
        });
    }
    if let Some(p) = tracker.current_peak() {
        summary.max_force_mg = summary.max_force_mg.max(p.to_f64() / mg);
    }
    Ok((rows, summary))
}

/// Runs `simulate`.
///
/// # Errors
/// Bad input or I/O failure.
pub fn run(a: &SimulateArgs) -> Result<()> {
    let setup = Setup::from_opts(&a.rig)?;
    let gap_m = gap_m_from_mm("--gap-mm", a.gap_mm)?;
    let fn_hz = setup.params.natural_freq_hz();
    let ratio = match (a.omega_ratio, a.freq_hz) {
        (Some(r), None) => r,
        (None, Some(f)) => {
            check_range(
                "freq_hz",
                f,
                OMEGA_RATIO_RANGE.0 * fn_hz,
                OMEGA_RATIO_RANGE.1 * fn_hz,
            )
            .context("--freq-hz")?;
            f / fn_hz
        }
        _ => bail!("give the excitation frequency with --omega-ratio or --freq-hz"),
    };
    check_range(
        "omega_ratio",
        ratio,
        OMEGA_RATIO_RANGE.0,
        OMEGA_RATIO_RANGE.1,
    )
    .context("--omega-ratio")?;
    check_count("periods", a.periods, 1, 100_000).context("--periods")?;
    check_range("u0_mm", a.u0_mm, -20.0, 20.0).context("--u0-mm")?;
    check_range("v0_mm_s", a.v0_mm_s, -1e4, 1e4).context("--v0-mm-s")?;
    let omega_exc = ratio * setup.params.omega_n();
    let (rows, summary) = match setup.precision {
        Precision::F32 => time_series::<f32>(
            &setup,
            gap_m,
            omega_exc,
            a.periods,
            a.u0_mm * 1e-3,
            a.v0_mm_s * 1e-3,
        )?,
        Precision::F64 => time_series::<f64>(
            &setup,
            gap_m,
            omega_exc,
            a.periods,
            a.u0_mm * 1e-3,
            a.v0_mm_s * 1e-3,
        )?,
    };
    let mut outputs = Outputs::new();
    if let Some(p) = &a.out {
        let tmp = outputs.reserve(p)?;
        write_csv(&tmp, &rows)?;
    }
    if let Some(p) = &a.plot {
        let tmp = outputs.reserve(p)?;
        let ts: Vec<TsPoint> = rows
            .iter()
            .map(|r| TsPoint {
                t_s: r.t_s,
                u_mm: r.u_mm,
                du_mm_s: r.du_mm_s,
                x_mm: r.x_mm,
                force_mg: r.impact_force_mg,
            })
            .collect();
        let strobes: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.poincare)
            .map(|r| (r.u_mm, r.du_mm_s))
            .collect();
        let title = format!(
            "{} rig, gap {:.2} mm, Ω/ω = {:.3} ({:.3} Hz), {} periods",
            setup.rig,
            a.gap_mm,
            ratio,
            ratio * fn_hz,
            a.periods
        );
        plot::time_series(&tmp, &title, &ts, &strobes, a.gap_mm)?;
    }
    outputs.commit()?;
    println!(
        "{} periods at Ω/ω = {:.4} ({:.4} Hz): {} impacts, max F_i/mg = {:.3}, {} samples",
        a.periods,
        ratio,
        ratio * fn_hz,
        summary.impacts,
        summary.max_force_mg,
        rows.len()
    );
    Ok(())
}

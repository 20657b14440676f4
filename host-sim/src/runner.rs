//! Parallel evaluation of operating points (rayon over both cores) with a progress bar on a
//! terminal (indicatif draws nothing when stderr is not a terminal).

use anyhow::{Result, anyhow};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use shared::Real;
use shared::analysis::{DEFAULT_LANES, evaluate_interleaved, evaluate_point};
use shared::observe::PointResult;

use crate::cli::Precision;
use crate::config::Setup;

/// One operating point: gap (m) and `Ω/ω`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatingPoint {
    /// Gap, m.
    pub gap_m: f64,
    /// `Ω/ω`.
    pub omega_ratio: f64,
}

/// Runs the canonical protocol at one point in the setup's precision.
///
/// # Errors
/// Invalid point (named field and range).
pub fn evaluate(setup: &Setup, p: OperatingPoint) -> Result<PointResult> {
    let r = match setup.precision {
        Precision::F32 => {
            evaluate_point::<f32>(&setup.params, p.gap_m, p.omega_ratio, &setup.settings)
        }
        Precision::F64 => {
            evaluate_point::<f64>(&setup.params, p.gap_m, p.omega_ratio, &setup.settings)
        }
    };
    r.map_err(|e| anyhow!("gap {:.4} mm, Ω/ω {:.4}: {e}", p.gap_m * 1e3, p.omega_ratio))
}

/// Runs the canonical protocol at every point of `points` on the calling thread,
/// [`DEFAULT_LANES`] interleaved (results identical to [`evaluate`], in order).
pub fn evaluate_batch(setup: &Setup, points: &[OperatingPoint]) -> Vec<Result<PointResult>> {
    fn go<T: Real>(setup: &Setup, points: &[OperatingPoint]) -> Vec<Result<PointResult>> {
        let mut out: Vec<Option<Result<PointResult>>> = points.iter().map(|_| None).collect();
        evaluate_interleaved::<T, DEFAULT_LANES, _, _>(
            &setup.params,
            &setup.settings,
            points.iter().map(|p| (p.gap_m, p.omega_ratio)),
            |i, r| {
                let p = points[i];
                out[i] = Some(r.map_err(|e| {
                    anyhow!("gap {:.4} mm, Ω/ω {:.4}: {e}", p.gap_m * 1e3, p.omega_ratio)
                }));
            },
        );
        out.into_iter()
            .map(|r| r.unwrap_or_else(|| Err(anyhow!("internal: point not evaluated"))))
            .collect()
    }
    match setup.precision {
        Precision::F32 => go::<f32>(setup, points),
        Precision::F64 => go::<f64>(setup, points),
    }
}

/// A progress bar for `len` items on stderr, with rate and ETA.
pub fn progress(len: usize, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len as u64);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} points, {per_sec}, ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// Evaluates every point in parallel, in order.
///
/// # Errors
/// The first invalid point.
pub fn evaluate_all(
    setup: &Setup,
    points: &[OperatingPoint],
    what: &str,
) -> Result<Vec<PointResult>> {
    let bar = progress(points.len(), what);
    let out: Result<Vec<_>> = points
        .par_iter()
        .map(|&p| {
            let r = evaluate(setup, p);
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    out
}

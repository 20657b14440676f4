//! The batch runner every parallel computation shares: the batch size, parallel evaluation of
//! operating points (rayon over both cores) and the progress bar on a terminal (indicatif draws
//! nothing when stderr is not a terminal).

use anyhow::{Result, anyhow};
use indicatif::{ProgressBar, ProgressStyle};
use nalgebra::Vector2;
use rayon::prelude::*;
use shared::Real;
use shared::analysis::evaluate_interleaved_native;
use shared::error::ParamError;
use shared::observe::{Observer, PointResult, StroboPoint};
use shared::orbit::{Label, LabelSettings, MapPoint, label};

use crate::config::Setup;

/// Points per parallel task (a task interleaves its points on one core,
/// [`shared::analysis::run_interleaved`]): the unit of every parallel evaluation. Four times
/// the runs a core keeps in flight with AVX-512 (32), so that finished runs' places are
/// refilled, not left to drain (measured on AVX2, one core, the 4,284-point grid: 1.16–1.21 s
/// with 64 or 128 against 1.20–1.24 s with 32).
pub const BATCH: usize = 128;

/// One operating point: gap (m) and `Ω/ω`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatingPoint {
    /// Gap, m.
    pub gap_m: f64,
    /// `Ω/ω`.
    pub omega_ratio: f64,
}

/// Collects the out-of-order `emit(i, result)` calls of an interleaved run into a vector in
/// item order: `run(emit)` must emit every index below `len` once.
pub fn in_order<R>(
    len: usize,
    run: impl FnOnce(&mut dyn FnMut(usize, Result<R>)),
) -> Vec<Result<R>> {
    let mut out: Vec<Option<Result<R>>> = (0..len).map(|_| None).collect();
    run(&mut |i, r| out[i] = Some(r));
    out.into_iter()
        .map(|r| r.unwrap_or_else(|| Err(anyhow!("internal: point not evaluated"))))
        .collect()
}

/// Runs the canonical protocol at every point of `points` on the calling thread,
/// [`shared::analysis::lanes_per_core`] interleaved, in `T`, and ends each run with
/// `finish(result, x_end)` (`x_end`: the state it ended on); results in order, an error naming
/// its point.
fn interleaved<T: Real, R>(
    setup: &Setup,
    points: &[OperatingPoint],
    mut finish: impl FnMut(&OperatingPoint, PointResult, Vector2<T>) -> Result<R, ParamError>,
) -> Vec<Result<R>> {
    in_order(points.len(), |emit| {
        evaluate_interleaved_native::<T, _, _>(
            &setup.params,
            &setup.settings,
            points.iter().map(|p| (p.gap_m, p.omega_ratio)),
            |i, r| {
                let p = points[i];
                let finished = r.and_then(|(result, x)| finish(&p, result, x));
                emit(
                    i,
                    finished.map_err(|e| {
                        anyhow!("gap {:.4} mm, Ω/ω {:.4}: {e}", p.gap_m * 1e3, p.omega_ratio)
                    }),
                );
            },
        );
    })
}

/// Runs the canonical protocol at every point of `points` on the calling thread,
/// [`shared::analysis::lanes_per_core`] interleaved, in the setup's precision; results in
/// order, identical to one-at-a-time [`shared::analysis::evaluate_point`].
pub fn evaluate_batch(setup: &Setup, points: &[OperatingPoint]) -> Vec<Result<PointResult>> {
    crate::with_precision!(setup.precision, T => {
        interleaved::<T, _>(setup, points, |_, result, _| Ok(result))
    })
}

/// A progress bar for `len` items on stderr, with rate and ETA (hidden when `what` is empty,
/// e.g. for one computation of many that have their own bar).
pub fn progress(len: usize, what: &str) -> ProgressBar {
    if what.is_empty() {
        return ProgressBar::hidden();
    }
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
    in_parallel(points, what, |batch| evaluate_batch(setup, batch))
}

/// `run` over every [`BATCH`] of `points` in parallel with a progress bar (`what`,
/// [`progress`]); the results in order.
///
/// # Errors
/// The first invalid point.
fn in_parallel<R: Send>(
    points: &[OperatingPoint],
    what: &str,
    run: impl Fn(&[OperatingPoint]) -> Vec<Result<R>> + Sync,
) -> Result<Vec<R>> {
    let bar = progress(points.len(), what);
    let out: Result<Vec<_>> = points
        .par_chunks(BATCH)
        .flat_map_iter(|batch| {
            let r = run(batch);
            bar.inc(batch.len() as u64);
            r
        })
        .collect();
    bar.finish_and_clear();
    out
}

/// [`evaluate_batch`], each result with its label refined by the largest Lyapunov exponent
/// over a window after the protocol (`shared::orbit::label`: `chaotic`, or the period an
/// extended run finds).
pub fn evaluate_batch_labelled(
    setup: &Setup,
    points: &[OperatingPoint],
    settings: &LabelSettings,
) -> Vec<Result<(PointResult, Label)>> {
    crate::with_precision!(setup.precision, T => {
        interleaved::<T, _>(setup, points, |p, result, x| {
            let at = MapPoint {
                params: setup.params,
                settings: setup.settings,
                gap_m: p.gap_m,
                omega_ratio: p.omega_ratio,
            };
            label::<T>(&at, &result, x, settings).map(|l| (result, l))
        })
    })
}

/// [`evaluate_all`] with [`evaluate_batch_labelled`].
///
/// # Errors
/// The first invalid point.
pub fn evaluate_all_labelled(
    setup: &Setup,
    points: &[OperatingPoint],
    what: &str,
    settings: &LabelSettings,
) -> Result<Vec<(PointResult, Label)>> {
    in_parallel(points, what, |batch| {
        evaluate_batch_labelled(setup, batch, settings)
    })
}

/// The window's Poincaré points (m, m/s) and impacts (period, peak N).
#[derive(Debug, Default)]
pub struct WindowSamples {
    /// Poincaré points, in order.
    pub strobes: Vec<(f64, f64)>,
    /// Impacts: period of the window in which each ended, and its peak force (N).
    pub impacts: Vec<(u32, f64)>,
}

impl<T: Real> Observer<T> for WindowSamples {
    const SAMPLES: bool = false;
    fn strobe(&mut self, p: &StroboPoint<T>, window: bool) {
        if window {
            self.strobes.push((p.u.to_f64(), p.du.to_f64()));
        }
    }
    fn impact(&mut self, peak_n: T, window: bool) {
        if window {
            self.impacts
                .push((self.strobes.len() as u32, peak_n.to_f64()));
        }
    }
}

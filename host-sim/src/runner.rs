//! The batch runner every parallel computation shares: the batch size, parallel evaluation of
//! operating points (rayon over both cores), with their progress on stderr ([`crate::progress`]).

use anyhow::{Result, anyhow};
use nalgebra::Vector2;
use rayon::prelude::*;
use shared::Real;
use shared::analysis::evaluate_interleaved_native;
use shared::error::ParamError;
use shared::observe::{Observer, PointResult, StroboPoint};
use shared::orbit::{Label, LabelSettings, MapPoint, label};
use std::cell::RefCell;
use std::collections::HashMap;
use std::sync::{Mutex, PoisonError};

use crate::config::Setup;
use crate::progress::progress;

/// The smallest batch of points a core takes ([`guided`]): a batch interleaves its points on
/// one core ([`shared::analysis::run_interleaved`]), the unit of every parallel evaluation.
/// Twice the runs a core keeps in flight with AVX-512 (64), four times those with AVX2 (32),
/// so that finished runs' places are refilled, not left to drain.
pub const BATCH: usize = 128;

/// The stack of a thread that runs protocol runs interleaved, bytes. A core's driver keeps its
/// runs on the stack, four per lane ([`shared::analysis::run_interleaved`]): in the release
/// build with 8 lanes, `basins --precision f64` and `peterka --precision f64 --lyapunov` need
/// 512–640 KiB (measured by running them with `RUST_MIN_STACK` set lower), and 16 lanes
/// (AVX-512) keep twice the runs, against the 2 MiB a thread gets by default. Only the pages
/// a thread touches are committed.
pub const WORKER_STACK_BYTES: usize = 8 << 20;

/// Gives the rayon pool's threads [`WORKER_STACK_BYTES`] of stack (`host-sim`'s `main`, before
/// the pool's first use; a pool built already is left as it is).
pub fn init_pool() {
    let _ = rayon::ThreadPoolBuilder::new()
        .stack_size(WORKER_STACK_BYTES)
        .build_global();
}

/// `run` over consecutive batches of `items` on every core of the rayon pool; each batch's
/// result in item order.
///
/// The batches are guided: a core takes a `1 / (2 · cores)` share of what is left, at least
/// [`BATCH`] items (all if fewer are left). A batch ends with its lanes draining while its
/// last runs finish, so long batches while much is left waste less; short ones at the end keep
/// a core from waiting long for the other's last batch (on the 4,284-point grid, one AVX-512 core:
/// 84 % of the free-flight lane slots busy against 78 % with batches of [`BATCH`]).
pub fn guided<X: Sync, R: Send>(items: &[X], run: impl Fn(&[X]) -> R + Sync) -> Vec<R> {
    let cores = rayon::current_num_threads().max(1);
    let next = Mutex::new(0usize);
    let take = || {
        let mut at = next.lock().unwrap_or_else(PoisonError::into_inner);
        let start = *at;
        let left = items.len() - start;
        let n = (left / (2 * cores)).max(BATCH).min(left);
        *at += n;
        (n > 0).then_some(start..start + n)
    };
    let mut parts: Vec<(usize, R)> = (0..cores)
        .into_par_iter()
        .flat_map_iter(|_| {
            let mut out = Vec::new();
            while let Some(batch) = take() {
                out.push((batch.start, run(&items[batch])));
            }
            out
        })
        .collect();
    parts.sort_unstable_by_key(|&(start, _)| start);
    parts.into_iter().map(|(_, r)| r).collect()
}

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

/// Runs the canonical protocol at every point `points` yields (with a key) on the calling
/// thread, [`shared::analysis::lanes_per_core`] interleaved, in `T`, taken as the lanes free up,
/// and ends each run with `finish(point, result, x_end)` (`x_end`: the state it ended on):
/// `emit(key, result)` as soon as a point is done (so not in order), an error naming its
/// point. `points` may end for a while (`None`) and go on later: a place left idle is filled
/// when a run ends after it goes on.
fn interleaved_keyed<T: Real, K: Copy, R>(
    setup: &Setup,
    points: impl Iterator<Item = (K, OperatingPoint)>,
    mut finish: impl FnMut(&OperatingPoint, PointResult, Vector2<T>) -> Result<R, ParamError>,
    emit: &mut dyn FnMut(K, Result<R>),
) {
    // The points in flight by their place in the sequence (`run_interleaved` emits places).
    let in_flight: RefCell<HashMap<usize, (K, OperatingPoint)>> = RefCell::default();
    let mut taken = 0usize;
    let items = points.map(|(key, p)| {
        in_flight.borrow_mut().insert(taken, (key, p));
        taken += 1;
        (p.gap_m, p.omega_ratio)
    });
    evaluate_interleaved_native::<T, _, _>(&setup.params, &setup.settings, items, |i, r| {
        let Some((key, p)) = in_flight.borrow_mut().remove(&i) else {
            return;
        };
        let finished = r.and_then(|(result, x)| finish(&p, result, x));
        emit(
            key,
            finished
                .map_err(|e| anyhow!("gap {:.4} mm, Ω/ω {:.4}: {e}", p.gap_m * 1e3, p.omega_ratio)),
        );
    });
}

/// Runs the canonical protocol at every point of `points` on the calling thread,
/// [`shared::analysis::lanes_per_core`] interleaved, in the setup's precision; results in
/// order, identical to one-at-a-time [`shared::analysis::evaluate_point`].
pub fn evaluate_batch(setup: &Setup, points: &[OperatingPoint]) -> Vec<Result<PointResult>> {
    in_order(points.len(), |emit| {
        evaluate_keyed(setup, points.iter().copied().enumerate(), emit);
    })
}

/// [`evaluate_batch`] over the keyed points `points` yields, taken as the lanes free up
/// (`points` may end for a while and go on later): `emit(key, result)` as each is done, not in
/// order, an error naming its point.
pub fn evaluate_keyed<K: Copy>(
    setup: &Setup,
    points: impl Iterator<Item = (K, OperatingPoint)>,
    emit: &mut dyn FnMut(K, Result<PointResult>),
) {
    crate::with_precision!(setup.precision, T => {
        interleaved_keyed::<T, K, _>(setup, points, |_, result, _| Ok(result), emit)
    })
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

/// `run` over the [`guided`] batches of `points` in parallel with a progress bar (`what`,
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
    let out: Result<Vec<_>> = guided(points, |batch| {
        let r = run(batch);
        bar.inc(batch.len() as u64);
        r
    })
    .into_iter()
    .flatten()
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
    in_order(points.len(), |emit| {
        evaluate_keyed_labelled(setup, points.iter().copied().enumerate(), settings, emit);
    })
}

/// [`evaluate_batch_labelled`] over the keyed points `points` yields, as [`evaluate_keyed`].
pub fn evaluate_keyed_labelled<K: Copy>(
    setup: &Setup,
    points: impl Iterator<Item = (K, OperatingPoint)>,
    settings: &LabelSettings,
    emit: &mut dyn FnMut(K, Result<(PointResult, Label)>),
) {
    crate::with_precision!(setup.precision, T => {
        interleaved_keyed::<T, K, _>(
            setup,
            points,
            |p, result, x| {
                let at = MapPoint {
                    params: setup.params,
                    settings: setup.settings,
                    gap_m: p.gap_m,
                    omega_ratio: p.omega_ratio,
                };
                label::<T>(&at, &result, x, settings).map(|l| (result, l))
            },
            emit,
        )
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The batches `guided` takes on `cores` threads over `len` items: their lengths in item
    /// order, and the items seen in that order.
    fn batches(len: usize, cores: usize) -> (Vec<usize>, Vec<usize>) {
        let items: Vec<usize> = (0..len).collect();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(cores)
            .build()
            .expect("a thread pool");
        let parts = pool.install(|| guided(&items, |b| b.to_vec()));
        let lens = parts.iter().map(Vec::len).collect();
        (lens, parts.concat())
    }

    #[test]
    fn guided_batches_cover_the_items_in_order_and_shrink_to_the_minimum() {
        for cores in [1, 2, 3] {
            let (lens, seen) = batches(16_384, cores);
            assert_eq!(seen, (0..16_384).collect::<Vec<_>>(), "{cores} cores");
            // The first batch: 1 / (2 · cores) of everything (2,730 of 16,384 on 3 cores).
            assert_eq!(lens[0], 16_384 / (2 * cores), "{cores} cores");
            // Batches never grow, and all but the last hold at least BATCH items.
            assert!(lens.windows(2).all(|w| w[1] <= w[0]), "{lens:?}");
            assert!(
                lens[..lens.len() - 1].iter().all(|&n| n >= BATCH),
                "{lens:?}"
            );
            // Two cores: a quarter of what is left each time (4,096, 3,072, 2,304, …, 130),
            // then BATCH three times and the last 6.
            if cores == 2 {
                assert_eq!(lens[..3], [4096, 3072, 2304]);
                assert_eq!(lens[12..], [130, 128, 128, 128, 6], "{lens:?}");
            }
        }
        // Fewer items than a batch: one batch; none: no batch.
        assert_eq!(batches(100, 2).0, vec![100]);
        assert_eq!(batches(0, 2).0, Vec::<usize>::new());
    }
}

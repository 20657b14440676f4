//! A grid's points streamed through every core's interleaved lanes ([`run_streamed`]), for
//! the grids whose points are independent of each other (the Peterka map).
//!
//! [`super::run_chunked`] evaluates a chunk of points in batches and waits for the chunk's last
//! batch before it writes the chunk and starts the next: every batch ends with its lanes
//! draining while its last runs finish, and every chunk with one core waiting for the other.
//! Here each core runs one interleaved evaluation that takes the next point whenever a run
//! ends, from one queue over the whole grid; the rows go to the sink in index order as they
//! complete (a reorder window of at most [`WINDOW`] points, so memory stays flat), written by
//! the calling thread while the cores compute. The lanes drain once, at the grid's end.

use std::cell::RefCell;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Condvar, Mutex, PoisonError};
use std::time::Duration;

use anyhow::{Context, Result, anyhow};

use super::CHUNK;
use crate::interrupt;
use crate::progress::progress;
use crate::runner::WORKER_STACK_BYTES;

/// Points the cores may take beyond the first one not yet written: the rows held in memory at
/// most (as many as a chunk of [`super::run_chunked`]).
pub const WINDOW: usize = CHUNK;

/// Points a core takes from the queue at once (one lock for them).
const TAKE: usize = 8;

/// Rows a core hands the writer at once (the writer wakes once for them; a core's last rows
/// go when its evaluation ends).
const SEND: usize = 256;

/// How long the writer and a core whose queue is held by the window wait at most before they
/// look again (Ctrl-C, a stopped run).
const POLL: Duration = Duration::from_millis(20);

/// How a grid's rows are computed: in batches ([`Batches`], [`super::run_chunked`]) or
/// streamed ([`Streamed`], [`run_streamed`]).
pub trait GridCompute<R: Send>: Sync {
    /// The rows of every index of `indices` (ascending; `len` of them) to `sink`, in index
    /// order, with a progress bar labelled `what`.
    ///
    /// # Errors
    /// The first failing point or sink call (in index order), or
    /// [`Interrupted`](crate::interrupt::Interrupted).
    fn evaluate(
        &self,
        indices: impl Iterator<Item = usize> + Send,
        len: usize,
        what: &str,
        sink: impl FnMut(usize, R) -> Result<()>,
    ) -> Result<()>;
}

/// A computation in batches ([`batches`]): the rows of a batch of indices, in order.
pub struct Batches<F>(F);

/// `compute(batch)`, the rows of the indices of `batch` in order, as a [`GridCompute`]
/// ([`super::run_chunked`]).
pub fn batches<R, F: Fn(&[usize]) -> Vec<Result<R>> + Sync>(compute: F) -> Batches<F> {
    Batches(compute)
}

impl<R: Send, F: Fn(&[usize]) -> Vec<Result<R>> + Sync> GridCompute<R> for Batches<F> {
    fn evaluate(
        &self,
        indices: impl Iterator<Item = usize> + Send,
        len: usize,
        what: &str,
        sink: impl FnMut(usize, R) -> Result<()>,
    ) -> Result<()> {
        super::run_chunked(indices, len, what, &self.0, sink)
    }
}

/// A streamed computation ([`streamed`], [`run_streamed`]).
pub struct Streamed<G>(G);

/// `compute(source, emit)` as a [`GridCompute`] ([`run_streamed`]): it evaluates on the
/// calling thread the points `source` gives (grid indices, taken as its lanes free up;
/// `source` may end for a while and go on later) and calls `emit(index, row)` for each as soon
/// as it is done, in any order.
pub fn streamed<R, G>(compute: G) -> Streamed<G>
where
    G: Fn(&mut dyn Iterator<Item = usize>, &mut dyn FnMut(usize, Result<R>)) + Sync,
{
    Streamed(compute)
}

impl<R, G> GridCompute<R> for Streamed<G>
where
    R: Send,
    G: Fn(&mut dyn Iterator<Item = usize>, &mut dyn FnMut(usize, Result<R>)) + Sync,
{
    fn evaluate(
        &self,
        indices: impl Iterator<Item = usize> + Send,
        len: usize,
        what: &str,
        sink: impl FnMut(usize, R) -> Result<()>,
    ) -> Result<()> {
        run_streamed(indices, len, what, &self.0, sink)
    }
}

/// The queue of points every core takes from.
struct Queue<I> {
    indices: I,
    /// Points taken so far (the next one's place in the sequence).
    taken: usize,
    /// Whether `indices` is exhausted.
    done: bool,
}

/// Evaluates every index of `indices` (ascending; `len` of them) with `compute` on every core
/// of the rayon pool's size at once ([`streamed`]), and passes each row to `sink` in index
/// order from the calling thread. A core takes a point only while it lies fewer than
/// [`WINDOW`] places beyond the first not yet written; when the window holds it, its
/// evaluation ends once its runs are done and it waits for the writer.
///
/// # Errors
/// The first failing point or sink call (in index order; the cores stop taking points and end
/// their runs), or [`Interrupted`](crate::interrupt::Interrupted) after Ctrl-C (the same).
pub fn run_streamed<R: Send>(
    indices: impl Iterator<Item = usize> + Send,
    len: usize,
    what: &str,
    compute: &(impl Fn(&mut dyn Iterator<Item = usize>, &mut dyn FnMut(usize, Result<R>)) + Sync),
    mut sink: impl FnMut(usize, R) -> Result<()>,
) -> Result<()> {
    interrupt::install();
    let bar = progress(len, what);
    let cores = rayon::current_num_threads().max(1);
    let queue = Mutex::new(Queue {
        indices,
        taken: 0,
        done: false,
    });
    let moved = Condvar::new();
    let written = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let (tx, rx) = mpsc::channel::<Vec<(usize, usize, Result<R>)>>();
    let mut spawn_error = None;
    let outcome = std::thread::scope(|scope| {
        for _ in 0..cores {
            let tx = tx.clone();
            let (queue, moved, written, stop) = (&queue, &moved, &written, &stop);
            let core = std::thread::Builder::new().stack_size(WORKER_STACK_BYTES);
            let spawned = core.spawn_scoped(scope, move || {
                // Each point's place in the sequence, while it is in flight here; points
                // taken from the queue and not yet given to `compute`.
                let places: RefCell<HashMap<usize, usize>> = RefCell::default();
                let mut ready: VecDeque<(usize, usize)> = VecDeque::with_capacity(TAKE);
                loop {
                    let mut source = std::iter::from_fn(|| {
                        if stop.load(Ordering::Relaxed) || interrupt::requested() {
                            return None;
                        }
                        if ready.is_empty() {
                            let mut q = queue.lock().unwrap_or_else(PoisonError::into_inner);
                            let open = (written.load(Ordering::Acquire) + WINDOW)
                                .saturating_sub(q.taken)
                                .min(TAKE);
                            for _ in 0..open {
                                let Some(i) = q.indices.next() else {
                                    q.done = true;
                                    break;
                                };
                                ready.push_back((q.taken, i));
                                q.taken += 1;
                            }
                        }
                        let (place, i) = ready.pop_front()?;
                        places.borrow_mut().insert(i, place);
                        Some(i)
                    });
                    let mut done: Vec<(usize, usize, Result<R>)> = Vec::with_capacity(SEND);
                    compute(&mut source, &mut |i, row| {
                        let place = places.borrow_mut().remove(&i);
                        // (A point emitted twice, or never taken, is the writer's error.)
                        if let Some(place) = place {
                            done.push((place, i, row));
                        }
                        if done.len() >= SEND {
                            let _ = tx.send(std::mem::replace(&mut done, Vec::with_capacity(SEND)));
                        }
                    });
                    if !done.is_empty() {
                        let _ = tx.send(done);
                    }
                    let q = queue.lock().unwrap_or_else(PoisonError::into_inner);
                    if q.done || stop.load(Ordering::Relaxed) || interrupt::requested() {
                        return;
                    }
                    // The window held this core: wait for the writer to move on.
                    let _ = moved.wait_timeout(q, POLL);
                }
            });
            // (The cores started take every point; with none, the writer says so.)
            if let Err(e) = spawned {
                spawn_error.get_or_insert(e);
            }
        }
        drop(tx);
        let outcome = write_in_order(&rx, len, &mut sink, &bar, &written, &moved);
        if outcome.is_err() {
            stop.store(true, Ordering::Relaxed);
            moved.notify_all();
        }
        outcome
    });
    match outcome {
        Ok(()) => bar.finish_and_clear(),
        Err(_) => bar.abandon(),
    }
    match spawn_error {
        Some(e) => outcome.with_context(|| format!("starting a worker thread: {e}")),
        None => outcome,
    }
}

/// The writer of [`run_streamed`]: the rows received on `rx` to `sink` in their order, all
/// `len` of them; `written` and `moved` tell the cores how far it got.
fn write_in_order<R>(
    rx: &mpsc::Receiver<Vec<(usize, usize, Result<R>)>>,
    len: usize,
    sink: &mut impl FnMut(usize, R) -> Result<()>,
    bar: &indicatif::ProgressBar,
    written: &AtomicUsize,
    moved: &Condvar,
) -> Result<()> {
    let mut ahead: BTreeMap<usize, (usize, Result<R>)> = BTreeMap::new();
    let mut next = 0usize;
    while next < len {
        interrupt::check()?;
        match rx.recv_timeout(POLL) {
            Ok(rows) => {
                ahead.extend(rows.into_iter().map(|(place, i, row)| (place, (i, row))));
            }
            Err(RecvTimeoutError::Timeout) => continue,
            Err(RecvTimeoutError::Disconnected) => {
                interrupt::check()?;
                return Err(anyhow!(
                    "internal: {} of {len} points not evaluated",
                    len - next
                ));
            }
        }
        let before = next;
        while let Some((i, row)) = ahead.remove(&next) {
            sink(i, row?)?;
            next += 1;
        }
        if next > before {
            written.store(next, Ordering::Release);
            moved.notify_all();
            bar.inc((next - before) as u64);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A computation that takes every point it can before it emits any, then emits them in
    /// reverse (the most out of order an interleaved evaluation could be): the sink still sees
    /// every index once, in order, and the window holds the cores at `WINDOW` points ahead.
    #[test]
    fn streamed_rows_reach_the_sink_in_index_order() {
        for (total, step) in [(10_000usize, 3usize), (2 * WINDOW + 1000, 1)] {
            let calls = AtomicUsize::new(0);
            let most = AtomicUsize::new(0);
            let compute = |source: &mut dyn Iterator<Item = usize>,
                           emit: &mut dyn FnMut(usize, Result<usize>)| {
                calls.fetch_add(1, Ordering::Relaxed);
                let taken: Vec<usize> = source.collect();
                most.fetch_max(taken.len(), Ordering::Relaxed);
                for &i in taken.iter().rev() {
                    emit(i, Ok(i * 2));
                }
            };
            let mut seen = Vec::new();
            let indices = (0..total).step_by(step);
            let len = indices.len();
            run_streamed(indices, len, "", &compute, |i, r| {
                assert_eq!(r, i * 2);
                seen.push(i);
                Ok(())
            })
            .unwrap();
            assert_eq!(seen, (0..total).step_by(step).collect::<Vec<_>>());
            // No evaluation held more than the window; the long grid needed several.
            assert!(most.load(Ordering::Relaxed) <= WINDOW);
            if len > WINDOW {
                assert!(calls.load(Ordering::Relaxed) > 2, "{calls:?}");
            }
        }
    }

    /// The first failing point in index order is the error, after the rows before it and
    /// none after; a sink error stops the run the same way.
    #[test]
    fn the_first_failing_point_in_index_order_stops_the_run() {
        let compute = |source: &mut dyn Iterator<Item = usize>,
                       emit: &mut dyn FnMut(usize, Result<usize>)| {
            let taken: Vec<usize> = source.collect();
            for &i in taken.iter().rev() {
                if i == 700 || i == 5_000 {
                    emit(i, Err(anyhow!("point {i} failed")));
                } else {
                    emit(i, Ok(i));
                }
            }
        };
        let mut seen = Vec::new();
        let err = run_streamed(0..20_000, 20_000, "", &compute, |i, _| {
            seen.push(i);
            Ok(())
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "point 700 failed");
        assert_eq!(seen, (0..700).collect::<Vec<_>>());
        let err = run_streamed(0..20_000, 20_000, "", &compute, |i, _| {
            if i == 42 {
                return Err(anyhow!("disk full at {i}"));
            }
            Ok(())
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "disk full at 42");
    }

    /// A computation that drops a point is an internal error naming how many are missing,
    /// not a hang.
    #[test]
    fn a_point_never_emitted_is_an_error() {
        let compute = |source: &mut dyn Iterator<Item = usize>,
                       emit: &mut dyn FnMut(usize, Result<usize>)| {
            for i in source {
                if i != 17 {
                    emit(i, Ok(i));
                }
            }
        };
        let err = run_streamed(0..100, 100, "", &compute, |_, _| Ok(())).unwrap_err();
        assert_eq!(err.to_string(), "internal: 83 of 100 points not evaluated");
    }
}

//! Ctrl-C for long runs: the first SIGINT, SIGTERM or SIGHUP sets a flag; grid runs stop after
//! the current chunk (points not yet started are skipped), every temporary file is removed as
//! the error unwinds, the error names the signal, and the process exits with status 130; the
//! virtual rig's pty server stops, writes its log and exits 0. A second signal exits at once,
//! status 130, after removing the temporary files made so far ([`temporary`]) — but the same
//! signal again within [`SAME_DELIVERY`] is the same request (`timeout` signals a process and
//! its group: two deliveries), so the run still ends with its message.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{Mutex, Once};
use std::time::{Duration, Instant};

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};

static REQUESTED: AtomicBool = AtomicBool::new(false);
/// The first signal received (0: none).
static SIGNAL: AtomicI32 = AtomicI32::new(0);

/// A signal repeated within this time is the same request, not a second one.
pub const SAME_DELIVERY: Duration = Duration::from_millis(200);

/// A signal's name.
fn name(signal: i32) -> &'static str {
    match signal {
        SIGINT => "SIGINT (Ctrl-C)",
        SIGTERM => "SIGTERM",
        SIGHUP => "SIGHUP",
        _ => "a signal",
    }
}

/// The temporary files made so far (output.rs `scratch`): removed by the exit at once. A path
/// already renamed onto its target, or removed, no longer exists and is left alone.
static TEMPORARY: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Notes a temporary file, for the exit at once to remove.
pub fn temporary(path: PathBuf) {
    if let Ok(mut t) = TEMPORARY.lock() {
        t.push(path);
    }
}

/// Removes the temporary files noted (those still there), without waiting for a lock held
/// elsewhere.
fn remove_temporaries() {
    for _ in 0..100 {
        if let Ok(t) = TEMPORARY.try_lock() {
            for p in t.iter() {
                let _ = std::fs::remove_file(p);
            }
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
}

/// The run was interrupted (Ctrl-C, SIGTERM or SIGHUP: its message names which); its temporary
/// files are removed as the error unwinds (what a command keeps, such as a sweep's partial
/// file, its message says).
#[derive(Debug, thiserror::Error)]
#[error(
    "interrupted by {}: stopped after the current step, temporary files removed",
    name(SIGNAL.load(Ordering::Relaxed))
)]
pub struct Interrupted;

/// Installs the handler (once per process; later calls do nothing): a thread that waits for the
/// signals. If the platform refuses, the default behaviour (immediate termination) stays.
pub fn install() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
            return;
        };
        std::thread::spawn(move || {
            let mut first: Option<(i32, Instant)> = None;
            for signal in signals.forever() {
                match first {
                    None => {
                        first = Some((signal, Instant::now()));
                        SIGNAL.store(signal, Ordering::SeqCst);
                        REQUESTED.store(true, Ordering::SeqCst);
                        eprintln!(
                            "\ninterrupt: {} received: stopping after the current step (again to \
                             quit at once)",
                            name(signal)
                        );
                    }
                    // One request delivered twice (to the process and its group).
                    Some((s, at)) if s == signal && at.elapsed() < SAME_DELIVERY => {}
                    Some(_) => {
                        remove_temporaries();
                        std::process::exit(130);
                    }
                }
            }
        });
    });
}

/// Whether Ctrl-C was pressed.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}

/// `Err(Interrupted)` once Ctrl-C was pressed.
///
/// # Errors
/// [`Interrupted`].
pub fn check() -> Result<(), Interrupted> {
    if requested() {
        Err(Interrupted)
    } else {
        Ok(())
    }
}

//! Ctrl-C for long runs: the first SIGINT/SIGTERM sets a flag; grid runs stop after the current
//! chunk (points not yet started are skipped), every temporary file is removed as the error
//! unwinds, and the process exits with status 130; the virtual rig's pty server stops, writes
//! its log and exits 0. A second Ctrl-C (or a signal delivered twice, as `timeout` does to a
//! process and its group) exits at once, status 130, after removing the temporary files made so
//! far ([`temporary`]).

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, Once};

static REQUESTED: AtomicBool = AtomicBool::new(false);

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

/// The run was interrupted (Ctrl-C, SIGTERM or SIGHUP); its temporary files are removed as the
/// error unwinds (what a command keeps, such as a sweep's partial file, its message says).
#[derive(Debug, thiserror::Error)]
#[error(
    "interrupted (Ctrl-C or a termination signal): stopped after the current step, temporary \
     files removed"
)]
pub struct Interrupted;

/// Installs the handler (once per process; later calls do nothing). If the platform refuses, the
/// default Ctrl-C behaviour (immediate termination) stays.
pub fn install() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = ctrlc::set_handler(|| {
            if REQUESTED.swap(true, Ordering::SeqCst) {
                remove_temporaries();
                std::process::exit(130);
            }
            eprintln!(
                "\ninterrupt: stopping after the current step (Ctrl-C again to quit at once)"
            );
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

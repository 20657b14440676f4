//! Ctrl-C for long runs: the first SIGINT/SIGTERM sets a flag; grid runs stop after the current
//! chunk (points not yet started are skipped), every temporary file is removed as the error
//! unwinds, and the process exits with status 130; the virtual rig's pty server stops, writes
//! its log and exits 0. A second Ctrl-C exits at once (status 130; hidden `.host-sim-*`
//! temporary files may then remain in the output folder).

use std::sync::Once;
use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

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

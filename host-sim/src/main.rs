//! `host-sim`: the vibro-impact hammer on the desktop. See `host-sim --help`.
use std::process::ExitCode;

use nix::sys::signal::{SigHandler, Signal, signal};

fn main() -> ExitCode {
    // End quietly when the reader of stdout goes away (`host-sim response … | head`), as Unix
    // tools do: Rust ignores SIGPIPE, which turns the next print into a panic.
    // SAFETY: the first statement of `main`, before any other thread exists; the default
    // disposition installs no handler.
    let _ = unsafe { signal(Signal::SIGPIPE, SigHandler::SigDfl) };
    host_sim::runner::init_pool();
    host_sim::cli::main()
}

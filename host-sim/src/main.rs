//! `host-sim`: the vibro-impact hammer on the desktop. See `host-sim --help`.
use std::process::ExitCode;

fn main() -> ExitCode {
    host_sim::cli::main()
}

//! host-sim as a virtual rig: the firmware's controller (`shared::control`) in closed loop with
//! a simulated hammer, no hardware. [`plant`] is the hammer and the drive chain in f64,
//! [`chains`] the mocks of the firmware's hardware traits (ADC with the sensing chain, DAC,
//! clock), [`scenario`] the TOML of faults, drops and commands, [`session`] the loop, [`pty`]
//! the loop with its console on a pseudo-terminal.

pub mod chains;
pub mod plant;
pub mod pty;
pub mod recording;
pub mod scenario;
pub mod session;

pub use session::{CycleRow, HilRun, HilSetup, Session, run, virtual_board};

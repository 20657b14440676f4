//! What the controller is told ([`Command`]) and what it answers ([`Reply`], [`CommandError`]),
//! as types (the console's text for them is [`crate::console`]'s).

use super::faults::Fault;
use super::status::Status;
use crate::model::RigId;

/// A command for the controller ([`super::Controller::execute`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// The status snapshot.
    Status,
    /// Select the rig (only while idle).
    Rig(RigId),
    /// Set the gap, mm (only while idle).
    Gap(f32),
    /// Ramp up and track the target (or dwell at the manual frequency).
    Start,
    /// Ramp down to idle.
    Stop,
    /// Recompute the target frequency with the model.
    Tune,
    /// Dwell at this frequency, Hz.
    Freq(f32),
    /// Clear a latched fault.
    Clear,
    /// Per-cycle telemetry and event records on (`true`) or off.
    Stream(bool),
    /// The link-loss watchdog: stop a running drive ([`Fault::LinkLost`]) when no line arrives
    /// for this long, s (0: off).
    LinkTimeout(f32),
}

/// Why a command was refused (nothing changed), or the fault it tripped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CommandError {
    /// `start` tripped this fault (the start frequency or the rig's amplitude is outside the
    /// configured limits): the drive stays off and the fault is latched.
    Tripped(Fault),
    /// `rig`, `gap` and `start` only while idle; the state the drive is in.
    NotIdle(super::State),
    /// A fault is latched: `clear` first.
    FaultLatched,
    /// `start` without a target: the model is still computing.
    ModelPending,
    /// `start` without a target: the model found none (use `freq`).
    NoTarget,
    /// `gap` or `link-timeout` with a value outside its range (not finite, negative, beyond
    /// the largest, or a link timeout between 0 and [`super::MIN_LINK_TIMEOUT_S`]).
    OutOfRange {
        /// Smallest, in the command's unit.
        min: f32,
        /// Largest.
        max: f32,
    },
    /// `freq` outside the safe window.
    FreqOutOfWindow {
        /// Lowest, Hz.
        min: f32,
        /// Highest, Hz.
        max: f32,
    },
}

/// The reply to a command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reply {
    /// Done.
    Ok,
    /// The status snapshot.
    Status(Status),
}

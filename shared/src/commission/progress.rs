//! What the sequence reports, as types: one [`Progress`] record per step's prompt and verdict
//! (the console's `!C` lines, [`crate::console::commission`]).

use super::sensor::SensorCheck;
use crate::control::{Fault, Target};
use crate::identify::{DropIdentification, DropRefusal};
use crate::observe::Regime;
use crate::store::SaveError;

/// The steps, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// The force at rest.
    Sensor,
    /// The drop test and its identification.
    Drop,
    /// The board's selection on the identified model.
    Select,
    /// The drive at the target, measured against the prediction.
    Verify,
    /// The operator's decision.
    Accept,
}

impl Step {
    /// Every step, in order.
    pub const ALL: [Step; 5] = [
        Step::Sensor,
        Step::Drop,
        Step::Select,
        Step::Verify,
        Step::Accept,
    ];
}

/// What a step waits for (its prompt).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WaitFor {
    /// The hammer still, drive off, for `seconds`.
    Rest {
        /// How long, s.
        seconds: f32,
    },
    /// The operator releases the hammer from `release_mm` within `window_s`.
    Release {
        /// Height, mm.
        release_mm: f32,
        /// Window, s.
        window_s: f32,
    },
    /// The board computes the target of the identified model.
    Model,
    /// The drive ramps to `target_hz` and tracks.
    Drive {
        /// Start frequency, Hz.
        target_hz: f32,
    },
    /// The operator's `commission accept` within `window_s`.
    Accept {
        /// Window, s.
        window_s: f32,
    },
}

impl WaitFor {
    /// The step it belongs to.
    pub fn step(&self) -> Step {
        match self {
            WaitFor::Rest { .. } => Step::Sensor,
            WaitFor::Release { .. } => Step::Drop,
            WaitFor::Model => Step::Select,
            WaitFor::Drive { .. } => Step::Verify,
            WaitFor::Accept { .. } => Step::Accept,
        }
    }
}

/// The selection step's outcome: the identified model's target beside the target of the
/// model the rig ran before (`None`: it had none, or it was still computing), and the verdict.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectOutcome {
    /// The identified model's target (`None`: it has no robust `1/1` point).
    pub target: Option<Target>,
    /// The previous model's.
    pub before: Option<Target>,
    /// Why the step failed; `None`: passed.
    pub failure: Option<SelectFailure>,
}

/// Why the selection step failed: the drive is not started on a target it cannot hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SelectFailure {
    /// No robust `1/1` point.
    NoTarget,
    /// The target is outside the drive's frequency window.
    Window,
    /// The predicted impact force exceeds the controller's force limit (the verification would
    /// trip `over-force`).
    ForceLimit,
}

/// The verification's measurement and verdict.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VerifyOutcome {
    /// Drive frequency at the measurement, Hz.
    pub freq_hz: f32,
    /// Measured regime.
    pub regime: Option<Regime>,
    /// Measured mean peak force, N.
    pub peak_n: Option<f32>,
    /// Peak force against the prediction, %.
    pub force_vs_model_pct: Option<f32>,
    /// Why it failed; `None`: passed.
    pub failure: Option<VerifyFailure>,
}

/// Why the verification failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VerifyFailure {
    /// The regime is not `1/1`.
    Regime,
    /// The peak force is further than [`super::VERIFY_FORCE_PCT`] from the prediction (or
    /// not measured).
    Force,
    /// The drive left its ramp or tracking (an operator's `stop`).
    Stopped,
    /// A fault tripped.
    Fault(Fault),
    /// No tracking within [`super::VERIFY_TIMEOUT_S`].
    Timeout,
}

/// Why the sequence ended without storing anything.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EndReason {
    /// The step's own line said why.
    Failed,
    /// `commission abort`.
    Aborted,
    /// A fault tripped (its name).
    Fault(Fault),
    /// The step overran its bound.
    Timeout,
    /// The store refused the save.
    SaveFailed(SaveError),
}

/// One record of the sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum Progress {
    /// A step waits (the operator's prompt).
    Wait(WaitFor),
    /// The sensor check's verdict.
    Sensor(SensorCheck),
    /// The drop's identification (a misfit fails the step, as a refusal does).
    Drop(Result<DropIdentification, DropRefusal>),
    /// The selection's verdict.
    Select(SelectOutcome),
    /// The verification's verdict.
    Verify(VerifyOutcome),
    /// Accepted: the model stored (`saves`, the stored model's hash).
    Stored {
        /// The save's number.
        saves: u32,
        /// The stored model's hash.
        hash: u32,
    },
    /// Ended at `at` without storing: the settings the rig ran before are back.
    Kept {
        /// The step it ended at.
        at: Step,
        /// Why.
        reason: EndReason,
    },
}

impl Progress {
    /// The step it reports on (`None`: the sequence's end).
    pub fn step(&self) -> Option<Step> {
        Some(match self {
            Progress::Wait(w) => w.step(),
            Progress::Sensor(_) => Step::Sensor,
            Progress::Drop(_) => Step::Drop,
            Progress::Select(_) => Step::Select,
            Progress::Verify(_) => Step::Verify,
            Progress::Stored { .. } | Progress::Kept { .. } => return None,
        })
    }

    /// Whether it is the sequence's last record.
    pub fn ends(&self) -> bool {
        self.step().is_none()
    }
}

/// A record with its number (every record the sequence made since power-up counts, so that
/// a lost one shows as a gap) and the sample it was made at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Numbered {
    /// Sequence number.
    pub seq: u32,
    /// Controller samples since start-up.
    pub sample: u64,
    /// The record.
    pub progress: Progress,
}

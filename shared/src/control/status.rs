//! What the controller reports, as types: its states, the status snapshot, its events and the
//! asynchronous records it queues while streaming (their text is the console's,
//! [`crate::console`]).

use super::faults::Fault;
use super::model_id::ModelId;
use super::prediction::Prediction;
use crate::model::RigParams;
use crate::observe::Regime;

/// Controller states.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum State {
    /// Drive off.
    Idle,
    /// Soft start: amplitude ramping up at the start frequency.
    Ramp,
    /// Holding a manual frequency (`freq`), measuring.
    Dwell,
    /// Holding `1/1` and climbing to the force maximum.
    Track,
    /// Soft stop: amplitude ramping down.
    Stopping,
    /// Aborted: drive ramped to zero, latched until `clear`.
    Fault,
}

impl State {
    /// Every state, in the order of the state machine.
    pub const ALL: [State; 6] = [
        State::Idle,
        State::Ramp,
        State::Dwell,
        State::Track,
        State::Stopping,
        State::Fault,
    ];
}

/// What the console shows of a prediction: the target, its `1/1` band and the predicted force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// Target (operating) frequency, Hz.
    pub target_hz: f32,
    /// The `1/1` band holding the target, Hz.
    pub band_hz: [f32; 2],
    /// Predicted maximum impact force at the target, `F_i/mg`.
    pub impact_force_mg: f32,
}

impl From<&Prediction> for Target {
    fn from(p: &Prediction) -> Self {
        Target {
            target_hz: p.target_hz,
            band_hz: p.band_hz,
            impact_force_mg: p.impact_force_mg,
        }
    }
}

/// The model's status.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ModelStatus {
    /// A computation is requested or running.
    Pending,
    /// The latest prediction's target.
    Ready(Target),
    /// The latest computation found no robust `1/1` point (or failed).
    Failed,
}

/// A computation for the model task.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelRequest {
    /// The rig model.
    pub params: RigParams,
    /// Its hash ([`crate::model::params_hash`]), handed back in the prediction.
    pub model_hash: u32,
    /// Gap, mm.
    pub gap_mm: f32,
    /// Tag to hand back with the result; stale results are dropped.
    pub generation: u32,
}

/// Something worth a log line (and, while streaming, an event line on the console).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    /// The state changed.
    State {
        /// Old state.
        from: State,
        /// New state.
        to: State,
    },
    /// A fault tripped.
    Fault(Fault),
    /// A prediction arrived.
    ModelReady(Target),
    /// The model found no target.
    ModelFailed,
    /// The health check found the sampling slower than it should be (the watchdog is not fed).
    SamplingStalled {
        /// Samples taken in the last check window.
        samples: u32,
        /// Samples expected in that window at [`super::SAMPLE_RATE_HZ`].
        expected: u32,
    },
}

/// One finished drive cycle, as streamed (`!T` lines).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleTelemetry {
    /// State at the end of the cycle.
    pub state: State,
    /// Drive frequency now, Hz.
    pub freq_hz: f32,
    /// Drive amplitude now, mm.
    pub amplitude_mm: f32,
    /// Impacts detected in the cycle.
    pub impacts: u8,
    /// Their largest peak, N (0 without impacts).
    pub peak_n: f32,
    /// Sum of their impulses, N·s.
    pub impulse_n_s: f32,
    /// Measured regime of the last evaluation.
    pub regime: Option<Regime>,
    /// Latched fault.
    pub fault: Option<Fault>,
    /// Cycles lost from `1/1` while tracking, so far.
    pub lost_cycles: u32,
}

/// What an asynchronous line carries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AsyncKind {
    /// A drive cycle (`!T`).
    Cycle(CycleTelemetry),
    /// An event (`!E`).
    Event(Event),
}

/// An asynchronous record, produced while streaming: one per drive cycle or per event, with a
/// sequence number that counts every record produced, so that the desktop sees any record lost
/// on the way as a gap (the `!T`/`!E` lines of [`crate::console`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AsyncRecord {
    /// Sequence number (every line produced counts, sent or dropped).
    pub seq: u32,
    /// Samples since start-up when it was produced.
    pub sample: u64,
    /// What it says.
    pub kind: AsyncKind,
}

/// Largest [`Status::force_vs_model_pct`], % (a peak 10,000 times the prediction): a larger
/// discrepancy reads as this, within what the status line's reader accepts.
pub const MAX_FORCE_VS_MODEL_PCT: f32 = 1e6;

/// A snapshot for the console's `status` and the periodic log line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Status {
    /// State.
    pub state: State,
    /// The active rig model: where it came from, and its hash.
    pub rig: ModelId,
    /// Gap, mm.
    pub gap_mm: f32,
    /// Drive frequency now, Hz.
    pub freq_hz: f32,
    /// Drive amplitude now, mm.
    pub amplitude_mm: f32,
    /// Measured regime of the last evaluation.
    pub regime: Option<Regime>,
    /// Measured mean peak force of the last evaluation.
    pub peak: Option<PeakForce>,
    /// Model status.
    pub model: ModelStatus,
    /// Measured peak force against the model's prediction, % (`(measured − predicted) /
    /// predicted`, at most [`MAX_FORCE_VS_MODEL_PCT`]): the discrepancy a wrong gap or a
    /// drifted rig shows.
    pub force_vs_model_pct: Option<f32>,
    /// Latched fault.
    pub fault: Option<Fault>,
    /// Impacts detected since start-up.
    pub impacts: u32,
    /// Cycles in `Track` (after settling) whose impact count was not 1.
    pub lost_cycles: u32,
}

/// A measured mean peak force, in N and over the hammer's weight `m g`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeakForce {
    /// N.
    pub n: f32,
    /// Over `m g`.
    pub mg: f32,
}

//! What the controller says: its state names, events, the status line, the console replies and
//! refusals, and the asynchronous `!T`/`!E` lines while streaming (their text is the console
//! protocol, docs/operator.md).

use core::fmt;

use super::console::HELP;
use super::faults::Fault;
use super::fixed::Fixed;
use super::prediction::Prediction;
use crate::model::RigId;
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
    /// Short name for logs and the console.
    pub fn as_str(self) -> &'static str {
        match self {
            State::Idle => "idle",
            State::Ramp => "ramp",
            State::Dwell => "dwell",
            State::Track => "track",
            State::Stopping => "stopping",
            State::Fault => "fault",
        }
    }

    /// The state of a name from [`State::as_str`].
    pub fn from_name(name: &str) -> Option<State> {
        [
            State::Idle,
            State::Ramp,
            State::Dwell,
            State::Track,
            State::Stopping,
            State::Fault,
        ]
        .into_iter()
        .find(|s| s.as_str() == name)
    }
}

/// The model's status.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ModelStatus {
    /// A computation is requested or running.
    Pending,
    /// The latest prediction.
    Ready(Prediction),
    /// The latest computation found no robust `1/1` point (or failed).
    Failed,
}

/// A computation for the model task.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelRequest {
    /// Rig.
    pub rig: RigId,
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
    ModelReady(Prediction),
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

/// An asynchronous console line, produced while streaming: `!T` (one per drive cycle) or `!E`
/// (one per event), with a sequence number that counts every line produced, so that the
/// desktop sees any line lost on the way as a gap. Its text ([`fmt::Display`]):
///
/// ```text
/// !T seq=41 t_s=12.3456 state=track freq_hz=3.7000 amp_mm=0.890 impacts=1 peak_n=95.4 impulse_n_s=0.02851 regime=1/1 fault=none lost_cycles=0
/// !E seq=42 t_s=12.3457 event=state from=ramp to=track
/// !E seq=43 t_s=15.1550 event=fault fault=sensor-open
/// !E seq=44 t_s=0.5000 event=model-ready target_hz=3.6404 target_bits=0x4068fcfc band_hz=2.107..4.720 predicted_mg=32.76
/// !E seq=45 t_s=0.5000 event=model-failed
/// !E seq=46 t_s=20.0000 event=stalled samples=5000 expected=10000
/// ```
///
/// `t_s` is the controller's sample count over [`super::SAMPLE_RATE_HZ`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AsyncRecord {
    /// Sequence number (every line produced counts, sent or dropped).
    pub seq: u32,
    /// Samples since start-up when it was produced.
    pub sample: u64,
    /// What it says.
    pub kind: AsyncKind,
}

/// Samples as seconds with four decimals, in integers (exact at 10 kHz).
struct SampleTime(u64);

impl fmt::Display for SampleTime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rate = u64::from(super::SAMPLE_RATE_HZ);
        let frac = (self.0 % rate) * 10_000 / rate;
        write!(f, "{}.{:04}", self.0 / rate, frac)
    }
}

/// A measured regime as the console writes it: `p/q`, `none`, `irregular`, or `-` (not yet).
fn write_regime(f: &mut fmt::Formatter<'_>, regime: Option<Regime>) -> fmt::Result {
    match regime {
        Some(r @ Regime::Periodic { .. }) => write!(f, "{r}"),
        Some(Regime::NoImpact) => f.write_str("none"),
        Some(Regime::Irregular) => f.write_str("irregular"),
        None => f.write_str("-"),
    }
}

impl fmt::Display for AsyncRecord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let tag = match self.kind {
            AsyncKind::Cycle(_) => "!T",
            AsyncKind::Event(_) => "!E",
        };
        write!(f, "{tag} seq={} t_s={}", self.seq, SampleTime(self.sample))?;
        match self.kind {
            AsyncKind::Cycle(c) => {
                write!(
                    f,
                    " state={} freq_hz={} amp_mm={} impacts={}",
                    c.state.as_str(),
                    Fixed(c.freq_hz, 4),
                    Fixed(c.amplitude_mm, 3),
                    c.impacts
                )?;
                if c.impacts > 0 {
                    write!(
                        f,
                        " peak_n={} impulse_n_s={}",
                        Fixed(c.peak_n, 1),
                        Fixed(c.impulse_n_s, 5)
                    )?;
                } else {
                    f.write_str(" peak_n=- impulse_n_s=-")?;
                }
                f.write_str(" regime=")?;
                write_regime(f, c.regime)?;
                write!(
                    f,
                    " fault={} lost_cycles={}",
                    c.fault.map_or("none", Fault::as_str),
                    c.lost_cycles
                )
            }
            AsyncKind::Event(e) => match e {
                Event::State { from, to } => {
                    write!(f, " event=state from={} to={}", from.as_str(), to.as_str())
                }
                Event::Fault(fault) => write!(f, " event=fault fault={}", fault.as_str()),
                Event::ModelReady(p) => write!(
                    f,
                    " event=model-ready target_hz={} target_bits={:#010x} band_hz={}..{} predicted_mg={}",
                    Fixed(p.target_hz, 4),
                    p.target_hz.to_bits(),
                    Fixed(p.band_hz[0], 3),
                    Fixed(p.band_hz[1], 3),
                    Fixed(p.impact_force_mg, 2)
                ),
                Event::ModelFailed => f.write_str(" event=model-failed"),
                Event::SamplingStalled { samples, expected } => {
                    write!(f, " event=stalled samples={samples} expected={expected}")
                }
            },
        }
    }
}

/// Why a console command was refused (nothing changed), or the fault it tripped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CommandError {
    /// `start` tripped this fault (the start frequency or the rig's amplitude is outside the
    /// configured limits): the drive stays off and the fault is latched.
    Tripped(Fault),
    /// `rig`/`gap` only while idle.
    NotIdle,
    /// A fault is latched: `clear` first.
    FaultLatched,
    /// `start` without a target: the model is still computing.
    ModelPending,
    /// `start` without a target: the model found none (use `freq`).
    NoTarget,
    /// `freq` outside the safe window.
    FreqOutOfWindow {
        /// Lowest, Hz.
        min: f32,
        /// Highest, Hz.
        max: f32,
    },
}

impl fmt::Display for CommandError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CommandError::Tripped(fault) => write!(
                f,
                "start tripped fault {}: frequency or amplitude outside the limits (clear first)",
                fault.as_str()
            ),
            CommandError::NotIdle => f.write_str("only while idle: stop first"),
            CommandError::FaultLatched => f.write_str("fault latched: clear first"),
            CommandError::ModelPending => {
                f.write_str("model still computing the target: wait or use freq <Hz>")
            }
            CommandError::NoTarget => {
                f.write_str("the model found no robust 1/1 target: use freq <Hz>")
            }
            CommandError::FreqOutOfWindow { min, max } => write!(
                f,
                "frequency out of the safe window: allowed {} ..= {} Hz",
                Fixed(*min, 2),
                Fixed(*max, 2)
            ),
        }
    }
}

/// The reply to a console command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reply {
    /// Done.
    Ok,
    /// The status line.
    Status(Status),
    /// The help line.
    Help,
}

impl fmt::Display for Reply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Reply::Ok => f.write_str("ok"),
            Reply::Status(s) => write!(f, "{s}"),
            Reply::Help => f.write_str(HELP),
        }
    }
}

/// A snapshot for the console's `status` and the periodic log line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Status {
    /// State.
    pub state: State,
    /// Rig.
    pub rig: RigId,
    /// Gap, mm.
    pub gap_mm: f32,
    /// Drive frequency now, Hz.
    pub freq_hz: f32,
    /// Drive amplitude now, mm.
    pub amplitude_mm: f32,
    /// Measured regime of the last evaluation.
    pub regime: Option<Regime>,
    /// Measured mean peak force of the last evaluation, N.
    pub peak_n: Option<f32>,
    /// The same over `m g`.
    pub peak_mg: Option<f32>,
    /// Model status.
    pub model: ModelStatus,
    /// Measured peak force against the model's prediction, % (`(measured − predicted) /
    /// predicted`): the discrepancy a wrong gap or a drifted rig shows.
    pub force_vs_model_pct: Option<f32>,
    /// Latched fault.
    pub fault: Option<Fault>,
    /// Impacts detected since start-up.
    pub impacts: u32,
    /// Cycles in `Track` (after settling) whose impact count was not 1.
    pub lost_cycles: u32,
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "state={} rig={} gap_mm={} freq_hz={} amp_mm={} regime=",
            self.state.as_str(),
            self.rig.name(),
            Fixed(self.gap_mm, 2),
            Fixed(self.freq_hz, 4),
            Fixed(self.amplitude_mm, 3)
        )?;
        write_regime(f, self.regime)?;
        match (self.peak_n, self.peak_mg) {
            (Some(n), Some(mg)) => write!(f, " peak_n={} peak_mg={}", Fixed(n, 1), Fixed(mg, 2))?,
            _ => f.write_str(" peak_n=- peak_mg=-")?,
        }
        match self.model {
            ModelStatus::Ready(p) => write!(
                f,
                " model=ready target_hz={} band_hz={}..{} predicted_mg={}",
                Fixed(p.target_hz, 4),
                Fixed(p.band_hz[0], 3),
                Fixed(p.band_hz[1], 3),
                Fixed(p.impact_force_mg, 2)
            )?,
            ModelStatus::Pending => f.write_str(" model=pending")?,
            ModelStatus::Failed => f.write_str(" model=failed")?,
        }
        if let Some(pct) = self.force_vs_model_pct {
            write!(f, " force_vs_model_pct={}", Fixed(pct, 1))?;
        }
        write!(
            f,
            " fault={} impacts={} lost_cycles={}",
            self.fault.map_or("none", Fault::as_str),
            self.impacts,
            self.lost_cycles
        )
    }
}

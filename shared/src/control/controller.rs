//! The rig controller: the state machine `Idle → Ramp → Dwell/Track → Stopping → Idle`, with
//! `Fault` from anywhere, driven by one call per force sample ([`Controller::on_sample`], the
//! sampling task) and one call per console line ([`Controller::execute`]). The model runs
//! elsewhere (the firmware's low-priority task): the controller hands out requests
//! ([`Controller::take_model_request`]) and accepts their results
//! ([`Controller::set_prediction`]).
//!
//! Hardware-free: the firmware feeds ADC codes and writes the returned DAC code; host-sim does
//! the same against a simulated plant.

use core::fmt;

use heapless::Deque;

use super::config::ControllerConfig;
use super::console::{Command, HELP};
use super::detector::ImpactDetector;
use super::faults::{Fault, SensorMonitor};
use super::fixed::Fixed;
use super::meter::RegimeMeter;
use super::model::Prediction;
use super::sine::SineGenerator;
use super::tracker::HillClimber;
use crate::analysis::SelectionError;
use crate::error::ParamError;
use crate::hal::SampleError;
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

/// Why a console command was refused (nothing changed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CommandError {
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
        match self.regime {
            Some(r @ Regime::Periodic { .. }) => write!(f, "{r}")?,
            Some(Regime::NoImpact) => f.write_str("none")?,
            Some(Regime::Irregular) => f.write_str("irregular")?,
            None => f.write_str("-")?,
        }
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

/// Events kept for the logger.
pub const EVENT_QUEUE: usize = 8;
/// Asynchronous lines kept for the console service while streaming.
pub const OUTBOX: usize = 8;

/// The controller.
#[derive(Debug, Clone)]
pub struct Controller {
    config: ControllerConfig,
    rig: RigId,
    gap_mm: f32,
    state: State,
    fault: Option<Fault>,
    manual_hz: Option<f32>,
    model: ModelStatus,
    generation: u32,
    request_open: bool,
    generator: SineGenerator,
    detector: ImpactDetector,
    meter: RegimeMeter,
    monitor: SensorMonitor,
    climber: Option<HillClimber>,
    sample: u64,
    last_us: Option<u64>,
    /// Drive cycles completed.
    cycles: u32,
    /// Sample index where the current drive cycle began.
    cycle_start_sample: u64,
    /// Longest impact-free stretch the measured regime allows, samples (updated per cycle).
    regime_gap_samples: u32,
    cycles_at_freq: u32,
    regime: Option<Regime>,
    peak_n: Option<f32>,
    impacts: u32,
    lost_cycles: u32,
    events: Deque<Event, EVENT_QUEUE>,
    streaming: bool,
    seq: u32,
    outbox: Deque<AsyncRecord, OUTBOX>,
}

impl Controller {
    /// A controller in `Idle` for `rig` at `gap_mm`, with a model request open.
    ///
    /// # Errors
    /// [`ParamError`] naming the bad configuration field, or `gap_mm` outside `0 ..= 10`.
    pub fn new(config: ControllerConfig, rig: RigId, gap_mm: f32) -> Result<Self, ParamError> {
        config.validate()?;
        crate::error::check_range(
            "gap_mm",
            f64::from(gap_mm),
            0.0,
            f64::from(super::console::MAX_GAP_MM),
        )?;
        Ok(Controller {
            generator: SineGenerator::new(&config.limits, &config.drive),
            detector: ImpactDetector::new(&config.detector),
            meter: RegimeMeter::new(),
            monitor: SensorMonitor::new(&config.faults),
            config,
            rig,
            gap_mm,
            state: State::Idle,
            fault: None,
            manual_hz: None,
            model: ModelStatus::Pending,
            generation: 0,
            request_open: true,
            climber: None,
            sample: 0,
            last_us: None,
            cycles: 0,
            cycle_start_sample: 0,
            regime_gap_samples: 0,
            cycles_at_freq: 0,
            regime: None,
            peak_n: None,
            impacts: 0,
            lost_cycles: 0,
            events: Deque::new(),
            streaming: false,
            seq: 0,
            outbox: Deque::new(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// State.
    pub fn state(&self) -> State {
        self.state
    }

    /// Latched fault.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }

    /// Samples processed.
    pub fn samples(&self) -> u64 {
        self.sample
    }

    /// Drive cycles completed (the phase accumulator wrapped), since start-up.
    pub fn cycles(&self) -> u32 {
        self.cycles
    }

    /// The drive generator (frequency and amplitude now).
    pub fn generator(&self) -> &SineGenerator {
        &self.generator
    }

    /// The last finished excitation cycle as the regime meter recorded it (impacts, peak).
    pub fn last_cycle(&self) -> Option<super::meter::CycleRecord> {
        self.meter.cycle(0)
    }

    /// The status snapshot.
    pub fn status(&self) -> Status {
        let weight = self.rig.preset().weight_n() as f32;
        Status {
            state: self.state,
            rig: self.rig,
            gap_mm: self.gap_mm,
            freq_hz: self.generator.freq_hz(),
            amplitude_mm: self.generator.amplitude_mm(),
            regime: self.regime,
            peak_n: self.peak_n,
            peak_mg: self.peak_n.map(|n| n / weight),
            model: self.model,
            force_vs_model_pct: match (self.peak_n, self.model) {
                (Some(n), ModelStatus::Ready(p)) if p.impact_force_n > 0.0 => {
                    Some((n / p.impact_force_n - 1.0) * 100.0)
                }
                _ => None,
            },
            fault: self.fault,
            impacts: self.impacts,
            lost_cycles: self.lost_cycles,
        }
    }

    /// The oldest unlogged event.
    pub fn pop_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// Whether per-cycle telemetry and event lines are produced (`stream on`).
    pub fn streaming(&self) -> bool {
        self.streaming
    }

    /// The oldest asynchronous line not yet handed to the console.
    pub fn pop_async(&mut self) -> Option<AsyncRecord> {
        self.outbox.pop_front()
    }

    /// Whether asynchronous lines wait for the console.
    pub fn async_pending(&self) -> bool {
        !self.outbox.is_empty()
    }

    /// Records the health check's finding that sampling is slower than it should be: `samples`
    /// taken where `expected` were due (an [`Event::SamplingStalled`]).
    pub fn report_stall(&mut self, samples: u32, expected: u32) {
        self.push(Event::SamplingStalled { samples, expected });
    }

    /// Whether a model computation is waiting to be taken.
    pub fn model_request_open(&self) -> bool {
        self.request_open
    }

    /// Takes the open model request, if any (the model task then computes it).
    pub fn take_model_request(&mut self) -> Option<ModelRequest> {
        if !core::mem::take(&mut self.request_open) {
            return None;
        }
        Some(ModelRequest {
            rig: self.rig,
            gap_mm: self.gap_mm,
            generation: self.generation,
        })
    }

    /// Hands back the result of request `generation`; stale results are ignored. A new target
    /// while tracking moves the drive toward it; while dwelling after `tune`, tracking resumes.
    pub fn set_prediction(&mut self, generation: u32, result: Result<Prediction, SelectionError>) {
        if generation != self.generation {
            return;
        }
        match result {
            Ok(p) => {
                self.model = ModelStatus::Ready(p);
                self.push(Event::ModelReady(p));
                if matches!(self.state, State::Track | State::Dwell) && self.manual_hz.is_none() {
                    if self.target_in_window(&p) {
                        self.begin_tracking(&p);
                        self.set_state(State::Track);
                    } else {
                        self.trip(Fault::BadConfig);
                    }
                }
            }
            Err(_) => {
                self.model = ModelStatus::Failed;
                self.push(Event::ModelFailed);
            }
        }
    }

    /// Runs one console command.
    ///
    /// # Errors
    /// [`CommandError`]: the command was refused and nothing changed.
    pub fn execute(&mut self, cmd: Command) -> Result<Reply, CommandError> {
        match cmd {
            Command::Status => return Ok(Reply::Status(self.status())),
            Command::Help => return Ok(Reply::Help),
            Command::Stream(on) => self.streaming = on,
            Command::Rig(rig) => {
                self.require_idle()?;
                self.rig = rig;
                self.request_model();
            }
            Command::Gap(gap_mm) => {
                self.require_idle()?;
                self.gap_mm = gap_mm;
                self.request_model();
            }
            Command::Tune => {
                self.manual_hz = None;
                self.request_model();
            }
            Command::Start => {
                match self.state {
                    State::Idle => {}
                    State::Fault => return Err(CommandError::FaultLatched),
                    _ => return Ok(Reply::Ok), // already running
                }
                let start_hz = match (self.manual_hz, self.model) {
                    (Some(f), _) => f,
                    (None, ModelStatus::Ready(p)) => p.target_hz,
                    (None, ModelStatus::Pending) => return Err(CommandError::ModelPending),
                    (None, ModelStatus::Failed) => return Err(CommandError::NoTarget),
                };
                let amplitude = (self.rig.preset().amplitude_m * 1e3) as f32;
                let l = self.config.limits;
                if amplitude > l.amplitude_max_mm
                    || !(l.freq_min_hz..=l.freq_max_hz).contains(&start_hz)
                {
                    self.trip(Fault::BadConfig);
                    return Ok(Reply::Ok);
                }
                self.generator.jump_freq_hz(start_hz);
                self.generator.set_amplitude_mm(amplitude);
                self.reset_measurement();
                self.set_state(State::Ramp);
            }
            Command::Stop => {
                if matches!(self.state, State::Ramp | State::Dwell | State::Track) {
                    self.generator.set_amplitude_mm(0.0);
                    self.set_state(State::Stopping);
                }
            }
            Command::Freq(freq_hz) => {
                let l = self.config.limits;
                if !(l.freq_min_hz..=l.freq_max_hz).contains(&freq_hz) {
                    return Err(CommandError::FreqOutOfWindow {
                        min: l.freq_min_hz,
                        max: l.freq_max_hz,
                    });
                }
                match self.state {
                    State::Fault => return Err(CommandError::FaultLatched),
                    State::Stopping => return Err(CommandError::NotIdle),
                    State::Idle => {}
                    State::Ramp | State::Dwell | State::Track => {
                        self.generator.set_freq_hz(freq_hz);
                        self.reset_measurement();
                        if self.state != State::Ramp {
                            self.set_state(State::Dwell);
                        }
                    }
                }
                self.manual_hz = Some(freq_hz);
            }
            Command::Clear => {
                if self.state == State::Fault {
                    self.fault = None;
                    self.detector.reset();
                    self.monitor.disarm();
                    let next = if self.generator.amplitude_mm() > 0.0 {
                        State::Stopping
                    } else {
                        State::Idle
                    };
                    self.generator.set_amplitude_mm(0.0);
                    self.set_state(next);
                }
            }
        }
        Ok(Reply::Ok)
    }

    /// The sampling task: one ADC result in (`now_us` from the time base), one DAC code out.
    pub fn on_sample(&mut self, code: Result<u16, SampleError>, now_us: u64) -> u16 {
        self.sample = self.sample.wrapping_add(1);
        if let Some(last) = self.last_us.replace(now_us)
            && now_us.wrapping_sub(last) > u64::from(self.config.faults.deadline_us)
        {
            self.trip(Fault::MissedDeadline);
        }
        let (force_n, code) = match code {
            Ok(c) => (self.config.sensor.force_n(c), Some(c)),
            Err(_) => {
                self.trip(Fault::AdcOverrun);
                (0.0, None)
            }
        };
        // Over-force aborts a drive; with the drive off there is nothing to abort (a drop test
        // or a hand on the hammer is not a fault).
        if force_n > self.config.limits.force_limit_n && self.state != State::Idle {
            self.trip(Fault::OverForce);
        }
        let rail = code.is_some_and(|c| self.monitor.at_rail(c));
        let impact = self.detector.update(self.sample, force_n, rail);
        if let Some(imp) = impact {
            self.impacts = self.impacts.wrapping_add(1);
            self.meter.on_impact(imp.peak_n, imp.impulse_ns);
        }
        if let Some(c) = code {
            let driving = self.generator.amplitude_mm() > 0.0;
            let full = matches!(self.state, State::Dwell | State::Track);
            let gap = self.regime_gap_samples;
            if let Some(f) = self.monitor.check(c, driving, full, impact.is_some(), gap) {
                self.trip(f);
            }
        }
        let out = self.generator.next_sample();
        if out.cycle_start {
            self.on_cycle();
            if self.streaming {
                self.queue_cycle();
            }
        }
        match self.state {
            State::Ramp if self.generator.settled() => {
                self.reset_measurement();
                if self.manual_hz.is_some() {
                    self.set_state(State::Dwell);
                } else if let ModelStatus::Ready(p) = self.model {
                    self.begin_tracking(&p);
                    self.set_state(State::Track);
                } else {
                    self.set_state(State::Dwell);
                }
            }
            State::Stopping if self.generator.amplitude_mm() == 0.0 => {
                self.set_state(State::Idle);
            }
            _ => {}
        }
        out.code
    }

    fn on_cycle(&mut self) {
        self.meter.on_cycle_end();
        self.cycles = self.cycles.wrapping_add(1);
        // The longest impact-free stretch the measured regime allows: q drive periods, the
        // period counted in samples (no division in the sampling path).
        let period = self.sample.wrapping_sub(self.cycle_start_sample);
        self.cycle_start_sample = self.sample;
        let q = match self.regime {
            Some(Regime::Periodic { q, .. }) => u64::from(q),
            _ => 1,
        };
        self.regime_gap_samples = u32::try_from(period.saturating_mul(q)).unwrap_or(u32::MAX);
        if !matches!(self.state, State::Dwell | State::Track) {
            return;
        }
        self.cycles_at_freq = self.cycles_at_freq.saturating_add(1);
        let t = self.config.track;
        let settle = u32::from(t.settle_cycles);
        if self.state == State::Track
            && self.cycles_at_freq > settle
            && self.meter.cycle(0).is_some_and(|c| c.impacts != 1)
        {
            self.lost_cycles = self.lost_cycles.saturating_add(1);
        }
        if self.cycles_at_freq < settle + u32::from(t.measure_cycles) {
            return;
        }
        let window = usize::from(t.measure_cycles);
        let Some(regime) = self.meter.regime(window) else {
            return;
        };
        let peak = self.meter.peak_force_n(window).map(|(mean, _)| mean);
        // The climb follows the mean impulse per cycle: it grows with the approach speed as the
        // peak force does, and does not carry the peak's sampling-phase bias (up to 4 %).
        let impulse = self.meter.impulse_ns(window);
        self.regime = Some(regime);
        self.peak_n = peak;
        match (self.state, self.climber.as_mut()) {
            (State::Track, Some(climber)) => {
                let f = self.generator.target_freq_hz();
                let next = climber.next_freq_hz(f, regime, impulse);
                if next != f {
                    self.generator.set_freq_hz(next);
                    self.cycles_at_freq = 0;
                } else {
                    self.cycles_at_freq = settle;
                }
            }
            // Dwell: keep measuring in consecutive windows.
            _ => self.cycles_at_freq = settle,
        }
    }

    fn queue_cycle(&mut self) {
        let last = self.meter.cycle(0).unwrap_or_default();
        let c = CycleTelemetry {
            state: self.state,
            freq_hz: self.generator.freq_hz(),
            amplitude_mm: self.generator.amplitude_mm(),
            impacts: last.impacts,
            peak_n: last.peak_n,
            impulse_n_s: last.impulse_ns,
            regime: self.regime,
            fault: self.fault,
            lost_cycles: self.lost_cycles,
        };
        self.queue_async(AsyncKind::Cycle(c));
    }

    /// Queues an asynchronous line; a full outbox drops it (its sequence number is spent, so
    /// the desktop counts it as lost).
    fn queue_async(&mut self, kind: AsyncKind) {
        let record = AsyncRecord {
            seq: self.seq,
            sample: self.sample,
            kind,
        };
        self.seq = self.seq.wrapping_add(1);
        let _ = self.outbox.push_back(record);
    }

    fn begin_tracking(&mut self, p: &Prediction) {
        let l = self.config.limits;
        let band = [
            p.band_hz[0].max(l.freq_min_hz),
            p.band_hz[1].min(l.freq_max_hz),
        ];
        self.climber = Some(HillClimber::new(&self.config.track, band, p.target_hz));
        self.generator.set_freq_hz(p.target_hz);
        self.cycles_at_freq = 0;
    }

    fn target_in_window(&self, p: &Prediction) -> bool {
        let l = self.config.limits;
        (l.freq_min_hz..=l.freq_max_hz).contains(&p.target_hz)
    }

    fn reset_measurement(&mut self) {
        self.meter.reset();
        self.cycles_at_freq = 0;
        self.regime = None;
        self.peak_n = None;
        self.monitor.disarm();
    }

    fn require_idle(&self) -> Result<(), CommandError> {
        match self.state {
            State::Idle => Ok(()),
            State::Fault => Err(CommandError::FaultLatched),
            _ => Err(CommandError::NotIdle),
        }
    }

    fn request_model(&mut self) {
        self.generation = self.generation.wrapping_add(1);
        self.model = ModelStatus::Pending;
        self.request_open = true;
    }

    fn trip(&mut self, fault: Fault) {
        if self.state == State::Fault {
            return;
        }
        self.fault = Some(fault);
        self.generator.abort();
        self.climber = None;
        self.push(Event::Fault(fault));
        self.set_state(State::Fault);
    }

    fn set_state(&mut self, to: State) {
        if to != self.state {
            let from = core::mem::replace(&mut self.state, to);
            self.push(Event::State { from, to });
        }
    }

    fn push(&mut self, e: Event) {
        if self.events.is_full() {
            let _ = self.events.pop_front();
        }
        let _ = self.events.push_back(e);
        if self.streaming {
            self.queue_async(AsyncKind::Event(e));
        }
    }
}

//! The rig controller: the state machine `Idle → Ramp → Dwell/Track → Stopping → Idle`, with
//! `Fault` from anywhere, driven by one call per force sample ([`Controller::on_sample`], the
//! sampling task) and one call per console line ([`Controller::execute`]). The model runs
//! elsewhere (the firmware's low-priority task): the controller hands out requests
//! ([`Controller::take_model_request`]) and accepts their results
//! ([`Controller::set_prediction`]).
//!
//! Hardware-free: the firmware feeds ADC codes and writes the returned DAC code; host-sim does
//! the same against a simulated plant.

use heapless::Deque;

use super::calibration::{CalibField, Calibration};
use super::command::{Command, CommandError, Reply};
use super::config::ControllerConfig;
use super::detector::ImpactDetector;
use super::faults::{Fault, SensorMonitor};
use super::meter::RegimeMeter;
use super::model_id::{ModelId, ModelSource};
use super::prediction::Prediction;
use super::rest_probe::{RestProbe, RestStats};
use super::settings::{Draft, Settings, SettingsError};
use super::sine::SineGenerator;
use super::status::{
    AsyncKind, AsyncRecord, CycleTelemetry, Event, MAX_FORCE_VS_MODEL_PCT, ModelRequest,
    ModelStatus, PeakForce, State, Status, Target,
};
use super::tracker::HillClimber;
use crate::analysis::SelectionError;
use crate::error::ParamError;
use crate::hal::SampleError;
use crate::model::{ModelEdit, RigId, RigParams};
use crate::observe::Regime;

/// Events kept for the logger.
pub const EVENT_QUEUE: usize = 8;
/// Asynchronous records kept for the console service while streaming.
pub const OUTBOX: usize = 8;

/// Where a measurement at one drive frequency stands, in drive cycles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Measurement {
    /// Cycles since the frequency changed, while the response settles (`0 ..= settle`).
    Settling(u32),
    /// Cycles into the current measurement window (counted after settling).
    Measuring(u32),
}

impl Measurement {
    /// After one more cycle, with `settle` settling cycles.
    fn advance(self, settle: u32) -> Self {
        match self {
            Measurement::Settling(c) if c.saturating_add(1) > settle => {
                Measurement::Measuring(c.saturating_add(1) - settle)
            }
            Measurement::Settling(c) => Measurement::Settling(c + 1),
            Measurement::Measuring(w) => Measurement::Measuring(w.saturating_add(1)),
        }
    }
}

/// The model's latest answer, as the controller keeps it.
#[derive(Debug, Clone, Copy)]
enum Model {
    Pending,
    Ready(Prediction),
    Failed,
}

/// What the controller is doing, with the data that means something only there.
#[derive(Debug, Clone, Copy)]
enum Mode {
    Idle,
    Ramp,
    Dwell(Measurement),
    Track {
        climber: HillClimber,
        measurement: Measurement,
    },
    Stopping,
    /// Latched until `clear`.
    Fault(Fault),
}

impl Mode {
    fn state(&self) -> State {
        match self {
            Mode::Idle => State::Idle,
            Mode::Ramp => State::Ramp,
            Mode::Dwell(_) => State::Dwell,
            Mode::Track { .. } => State::Track,
            Mode::Stopping => State::Stopping,
            Mode::Fault(_) => State::Fault,
        }
    }

    /// Whether the drive was started and not yet stopped (ramping up, dwelling or tracking).
    fn driving(&self) -> bool {
        matches!(self, Mode::Ramp | Mode::Dwell(_) | Mode::Track { .. })
    }

    /// Whether the drive runs at its full amplitude and the response is measured.
    fn measuring(&self) -> bool {
        matches!(self, Mode::Dwell(_) | Mode::Track { .. })
    }
}

/// The controller.
#[derive(Debug, Clone)]
// `repr(C)`, the fields in this order: what the sampling task touches at every sample first, so
// that its loads and stores reach them at short offsets from the controller's address (the
// Cortex-M4's floating-point loads take offsets up to 1020 bytes); the large buffers last.
#[repr(C)]
pub struct Controller {
    sample: u64,
    last_us: Option<u64>,
    /// The sample after which a running drive is stopped for want of a line (`u64::MAX`: off).
    link_deadline: u64,
    /// Sample index where the current drive cycle began.
    cycle_start_sample: u64,
    mode: Mode,
    generator: SineGenerator,
    detector: ImpactDetector,
    monitor: SensorMonitor,
    /// Drive cycles completed.
    cycles: u32,
    /// Longest impact-free stretch the measured regime allows, samples (updated per cycle).
    regime_gap_samples: u32,
    regime: Option<Regime>,
    peak_n: Option<f32>,
    impacts: u32,
    lost_cycles: u32,
    streaming: bool,
    seq: u32,
    /// The link-loss watchdog: samples without a received line after which a running drive is
    /// stopped ([`Fault::LinkLost`]); 0: off.
    link_timeout: u32,
    manual_hz: Option<f32>,
    generation: u32,
    request_open: bool,
    /// A flash write is under way (`save`): sampling pauses while the CPU stalls on flash, and
    /// the late samples and ADC overruns that follow are counted, not faults.
    paused: bool,
    /// Samples that came late or overran during flash writes, since start-up.
    paused_samples: u32,
    /// The sensor at rest being measured (the commissioning's sensor check).
    probe: Option<RestProbe>,
    gap_mm: f32,
    config: ControllerConfig,
    /// The rig model.
    params: RigParams,
    /// Where it came from, and its hash.
    model_id: ModelId,
    /// Staged edits (`draft begin`).
    draft: Option<Draft>,
    model: Model,
    meter: RegimeMeter,
    events: Deque<Event, EVENT_QUEUE>,
    outbox: Deque<AsyncRecord, OUTBOX>,
}

impl Controller {
    /// A controller in `Idle` for the preset `rig` at `gap_mm`, with a model request open.
    ///
    /// # Errors
    /// [`ParamError`] naming the bad configuration field, or `gap_mm` outside `0 ..= 10`.
    pub fn new(config: ControllerConfig, rig: RigId, gap_mm: f32) -> Result<Self, ParamError> {
        Controller::with_model(config, rig.preset(), ModelSource::Preset(rig), gap_mm)
    }

    /// A controller in `Idle` for the model `params` (from `source`) at `gap_mm`, with a model
    /// request open.
    ///
    /// # Errors
    /// [`ParamError`] naming the bad configuration or model field, or `gap_mm` outside
    /// `0 ..= 10`.
    pub fn with_model(
        config: ControllerConfig,
        params: RigParams,
        source: ModelSource,
        gap_mm: f32,
    ) -> Result<Self, ParamError> {
        config.validate()?;
        params.validate()?;
        crate::error::check_range(
            "gap_mm",
            f64::from(gap_mm),
            0.0,
            f64::from(super::MAX_GAP_MM),
        )?;
        Ok(Controller {
            generator: SineGenerator::new(&config.limits, &config.drive),
            detector: ImpactDetector::new(&config.detector),
            meter: RegimeMeter::new(),
            monitor: SensorMonitor::new(&config.faults),
            config,
            model_id: ModelId::of(&params, source),
            params,
            draft: None,
            paused: false,
            paused_samples: 0,
            probe: None,
            gap_mm,
            mode: Mode::Idle,
            manual_hz: None,
            model: Model::Pending,
            generation: 0,
            request_open: true,
            sample: 0,
            last_us: None,
            cycles: 0,
            cycle_start_sample: 0,
            regime_gap_samples: 0,
            regime: None,
            peak_n: None,
            impacts: 0,
            lost_cycles: 0,
            events: Deque::new(),
            link_timeout: 0,
            link_deadline: u64::MAX,
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
        self.mode.state()
    }

    /// Latched fault.
    pub fn fault(&self) -> Option<Fault> {
        match self.mode {
            Mode::Fault(f) => Some(f),
            _ => None,
        }
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
        let weight = self.params.weight_n() as f32;
        Status {
            state: self.state(),
            rig: self.model_id,
            gap_mm: self.gap_mm,
            freq_hz: self.generator.freq_hz(),
            amplitude_mm: self.generator.amplitude_mm(),
            regime: self.regime,
            peak: self.peak_n.map(|n| PeakForce { n, mg: n / weight }),
            model: match &self.model {
                Model::Pending => ModelStatus::Pending,
                Model::Ready(p) => ModelStatus::Ready(Target::from(p)),
                Model::Failed => ModelStatus::Failed,
            },
            force_vs_model_pct: match (self.peak_n, self.model) {
                (Some(n), Model::Ready(p)) if p.impact_force_n > 0.0 => {
                    Some(((n / p.impact_force_n - 1.0) * 100.0).min(MAX_FORCE_VS_MODEL_PCT))
                }
                _ => None,
            },
            fault: self.fault(),
            impacts: self.impacts,
            lost_cycles: self.lost_cycles,
        }
    }

    /// A line (or a keep-alive: an empty line) arrived on the console: the link-loss watchdog
    /// starts counting afresh.
    pub fn link_alive(&mut self) {
        self.link_deadline = match self.link_timeout {
            0 => u64::MAX,
            t => self.sample.saturating_add(u64::from(t)),
        };
    }

    /// The link-loss watchdog's time, samples (0: off).
    pub fn link_timeout_samples(&self) -> u32 {
        self.link_timeout
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
            params: self.params,
            model_hash: self.model_id.hash,
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
                self.model = Model::Ready(p);
                self.push(Event::ModelReady(Target::from(&p)));
                if self.mode.measuring() && self.manual_hz.is_none() {
                    if self.target_in_window(&p) {
                        let mode = self.begin_tracking(&p);
                        self.set_mode(mode);
                    } else {
                        self.trip(Fault::BadConfig);
                    }
                }
            }
            Err(_) => {
                self.model = Model::Failed;
                self.push(Event::ModelFailed);
            }
        }
    }

    /// Runs one console command.
    ///
    /// # Errors
    /// [`CommandError`]: the command was refused and nothing changed, except
    /// [`CommandError::Tripped`]: `start` latched that fault (the controller is in `Fault`).
    pub fn execute(&mut self, cmd: Command) -> Result<Reply, CommandError> {
        match cmd {
            Command::Status => return Ok(Reply::Status(self.status())),
            Command::Stream(on) => self.streaming = on,
            Command::Rig(rig) => {
                self.require_idle()?;
                self.draft = None;
                self.set_model(rig.preset(), ModelSource::Preset(rig));
            }
            Command::Gap(gap_mm) => {
                if !(0.0..=super::MAX_GAP_MM).contains(&gap_mm) {
                    return Err(CommandError::OutOfRange {
                        min: 0.0,
                        max: super::MAX_GAP_MM,
                    });
                }
                self.require_idle()?;
                self.gap_mm = gap_mm;
                self.reset_measurement();
                self.request_model();
            }
            Command::LinkTimeout(seconds) => {
                if seconds != 0.0
                    && !(super::MIN_LINK_TIMEOUT_S..=super::MAX_LINK_TIMEOUT_S).contains(&seconds)
                {
                    return Err(CommandError::OutOfRange {
                        min: super::MIN_LINK_TIMEOUT_S,
                        max: super::MAX_LINK_TIMEOUT_S,
                    });
                }
                self.link_timeout = super::config::samples(seconds, 0);
                self.link_alive();
            }
            Command::Tune => {
                self.manual_hz = None;
                self.request_model();
            }
            Command::Start => {
                self.require_idle()?;
                let start_hz = match (self.manual_hz, self.model) {
                    (Some(f), _) => f,
                    (None, Model::Ready(p)) => p.target_hz,
                    (None, Model::Pending) => return Err(CommandError::ModelPending),
                    (None, Model::Failed) => return Err(CommandError::NoTarget),
                };
                let amplitude = (self.params.amplitude_m * 1e3) as f32;
                let l = self.config.limits;
                if amplitude > l.amplitude_max_mm
                    || !(l.freq_min_hz..=l.freq_max_hz).contains(&start_hz)
                {
                    self.trip(Fault::BadConfig);
                    return Err(CommandError::Tripped(Fault::BadConfig));
                }
                self.generator.jump_freq_hz(start_hz);
                self.generator.set_amplitude_mm(amplitude);
                self.reset_measurement();
                self.set_mode(Mode::Ramp);
            }
            Command::Stop => {
                // What was measured is no longer current, whatever the state.
                self.reset_measurement();
                if self.mode.driving() {
                    self.generator.set_amplitude_mm(0.0);
                    self.set_mode(Mode::Stopping);
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
                match self.mode {
                    Mode::Fault(_) => return Err(CommandError::FaultLatched),
                    // For the next start, as while idle.
                    Mode::Stopping | Mode::Idle => {}
                    Mode::Ramp => {
                        self.generator.set_freq_hz(freq_hz);
                        self.reset_measurement();
                    }
                    Mode::Dwell(_) | Mode::Track { .. } => {
                        self.generator.set_freq_hz(freq_hz);
                        self.reset_measurement();
                        self.set_mode(Mode::Dwell(Measurement::Settling(0)));
                    }
                }
                self.manual_hz = Some(freq_hz);
            }
            Command::Clear => {
                if let Mode::Fault(_) = self.mode {
                    self.detector.reset();
                    // What was measured before the fault is no longer current.
                    self.reset_measurement();
                    let next = if self.generator.amplitude_mm() > 0.0 {
                        Mode::Stopping
                    } else {
                        Mode::Idle
                    };
                    self.generator.set_amplitude_mm(0.0);
                    self.set_mode(next);
                }
            }
        }
        Ok(Reply::Ok)
    }

    /// The active rig model, and which it is.
    pub fn model(&self) -> (&RigParams, ModelId) {
        (&self.params, self.model_id)
    }

    /// The gap, mm.
    pub fn gap_mm(&self) -> f32 {
        self.gap_mm
    }

    /// The active calibration.
    pub fn calibration(&self) -> Calibration {
        Calibration::of(&self.config)
    }

    /// The staged edits, if a draft is open.
    pub fn draft(&self) -> Option<&Draft> {
        self.draft.as_ref()
    }

    /// What a `save` keeps: the active model, gap and calibration.
    pub fn settings(&self) -> Settings {
        Settings {
            params: self.params,
            gap_mm: self.gap_mm,
            calibration: self.calibration(),
        }
    }

    /// Makes `params` (from `source`) the active model: measurements reset, the model
    /// recomputed.
    fn set_model(&mut self, params: RigParams, source: ModelSource) {
        self.params = params;
        self.model_id = ModelId::of(&params, source);
        self.reset_measurement();
        self.request_model();
    }

    /// Edits the model: the draft's if one is open, else the active one (then `Edited`, and
    /// recomputed). Idle only.
    ///
    /// # Errors
    /// [`SettingsError`]: not idle, the field not of this model, the result out of range.
    pub fn edit_model(&mut self, edit: ModelEdit) -> Result<(), SettingsError> {
        self.require_idle().map_err(SettingsError::Command)?;
        match &mut self.draft {
            Some(d) => d.params = super::settings::edit_model(&d.params, edit)?,
            None => {
                let p = super::settings::edit_model(&self.params, edit)?;
                self.set_model(p, ModelSource::Edited);
            }
        }
        Ok(())
    }

    /// Edits one calibration field: the draft's if one is open, else the active calibration
    /// (the model's force in `F_i/mg` is unchanged; measurements reset). Idle only.
    ///
    /// # Errors
    /// [`SettingsError`]: not idle, the calibration refused as a whole (the field and range).
    pub fn edit_calibration(&mut self, field: CalibField, value: f32) -> Result<(), SettingsError> {
        self.require_idle().map_err(SettingsError::Command)?;
        let cal = self.draft.map_or(self.calibration(), |d| d.calibration);
        let cal = super::settings::edit_calibration(&cal, &self.config, field, value)?;
        match &mut self.draft {
            Some(d) => d.calibration = cal,
            None => self.set_calibration(&cal)?,
        }
        Ok(())
    }

    /// Makes `cal` the active calibration (validated against the whole configuration).
    fn set_calibration(&mut self, cal: &Calibration) -> Result<(), SettingsError> {
        let config = cal
            .applied_to(&self.config)
            .map_err(SettingsError::Calibration)?;
        // The drive is silent (idle): a generator of the new window and chain, at the same
        // frequency (clamped into the new window).
        let freq_hz = self.generator.freq_hz();
        self.config = config;
        self.generator = SineGenerator::new(&config.limits, &config.drive);
        self.generator.jump_freq_hz(freq_hz);
        self.reset_measurement();
        Ok(())
    }

    /// Opens a draft (a copy of the active model and calibration), replacing any open one.
    /// Idle only.
    ///
    /// # Errors
    /// [`SettingsError::Command`]: not idle.
    pub fn begin_draft(&mut self) -> Result<(), SettingsError> {
        self.require_idle().map_err(SettingsError::Command)?;
        self.draft = Some(Draft {
            params: self.params,
            calibration: self.calibration(),
        });
        Ok(())
    }

    /// Opens a draft (replacing any open one) holding the model `params` and the active
    /// calibration: what `capture adopt` proposes. Idle only.
    ///
    /// # Errors
    /// [`SettingsError`]: not idle, `params` out of range.
    pub fn draft_model(&mut self, params: RigParams) -> Result<(), SettingsError> {
        self.require_idle().map_err(SettingsError::Command)?;
        params.validate().map_err(SettingsError::Invalid)?;
        self.draft = Some(Draft {
            params,
            calibration: self.calibration(),
        });
        Ok(())
    }

    /// Applies the draft whole: its calibration and its model (`Edited` if it differs from the
    /// active one), then closes it. Idle only.
    ///
    /// # Errors
    /// [`SettingsError`]: not idle, no draft, the draft invalid as a whole (nothing applied).
    pub fn apply_draft(&mut self) -> Result<(), SettingsError> {
        self.require_idle().map_err(SettingsError::Command)?;
        let Some(d) = self.draft else {
            return Err(SettingsError::NoDraft);
        };
        d.params.validate().map_err(SettingsError::Invalid)?;
        d.calibration
            .applied_to(&self.config)
            .map_err(SettingsError::Calibration)?;
        self.draft = None;
        if d.calibration != self.calibration() {
            self.set_calibration(&d.calibration)?;
        }
        if d.params != self.params {
            self.set_model(d.params, ModelSource::Edited);
        }
        Ok(())
    }

    /// Closes the draft without applying it.
    ///
    /// # Errors
    /// [`SettingsError::NoDraft`].
    pub fn discard_draft(&mut self) -> Result<(), SettingsError> {
        self.draft.take().map(|_| ()).ok_or(SettingsError::NoDraft)
    }

    /// Loads settings (power-up, `revert`): the model from `source`, the gap, the calibration,
    /// all validated first (nothing changes on a refusal); closes any draft. Idle only.
    ///
    /// # Errors
    /// [`SettingsError`]: not idle, a field out of range.
    pub fn load_settings(
        &mut self,
        s: &Settings,
        source: ModelSource,
    ) -> Result<(), SettingsError> {
        self.require_idle().map_err(SettingsError::Command)?;
        s.params.validate().map_err(SettingsError::Invalid)?;
        crate::error::check_range(
            "gap_mm",
            f64::from(s.gap_mm),
            0.0,
            f64::from(super::MAX_GAP_MM),
        )
        .map_err(SettingsError::Invalid)?;
        s.calibration
            .applied_to(&self.config)
            .map_err(SettingsError::Calibration)?;
        self.draft = None;
        self.set_calibration(&s.calibration)?;
        self.gap_mm = s.gap_mm;
        self.set_model(s.params, source);
        Ok(())
    }

    /// The active model now comes from the store (it was just saved).
    pub fn mark_stored(&mut self) {
        self.model_id.source = ModelSource::Stored;
    }

    /// A flash write begins (`save`): until [`Controller::resume_sampling`], a late sample or
    /// an ADC overrun is counted ([`Controller::paused_samples`]), not a fault. Only with the
    /// drive idle (the caller checks).
    pub fn pause_sampling(&mut self) {
        self.paused = true;
    }

    /// The flash write ended: late samples are faults again, after the first sample (whose gap
    /// spans the pause).
    pub fn resume_sampling(&mut self) {
        self.paused = false;
        self.last_us = None;
    }

    /// Samples that came late or overran during flash writes, since start-up.
    pub fn paused_samples(&self) -> u32 {
        self.paused_samples
    }

    /// Starts measuring the sensor over the next `samples` samples ([`RestProbe`]), replacing
    /// any probe under way.
    pub fn begin_rest_probe(&mut self, samples: u32) {
        self.probe = Some(RestProbe::new(samples));
    }

    /// The probe's statistics once it has its samples (`None` before, or without a probe).
    pub fn rest_stats(&self) -> Option<RestStats> {
        self.probe.as_ref().and_then(RestProbe::done)
    }

    /// Ends the probe.
    pub fn end_rest_probe(&mut self) {
        self.probe = None;
    }

    /// The sampling task: one ADC result in (`now_us` from the time base), one DAC code out.
    pub fn on_sample(&mut self, code: Result<u16, SampleError>, now_us: u64) -> u16 {
        self.sample = self.sample.wrapping_add(1);
        if self.sample > self.link_deadline && self.mode.driving() {
            self.trip(Fault::LinkLost);
        }
        if let Some(last) = self.last_us.replace(now_us)
            && now_us.wrapping_sub(last) > u64::from(self.config.faults.deadline_us)
        {
            if self.paused {
                self.paused_samples = self.paused_samples.saturating_add(1);
            } else {
                self.trip(Fault::MissedDeadline);
            }
        }
        let (force_n, code) = match code {
            Ok(c) => (self.config.sensor.force_n(c), Some(c)),
            Err(_) if self.paused => {
                self.paused_samples = self.paused_samples.saturating_add(1);
                (0.0, None)
            }
            Err(_) => {
                self.trip(Fault::AdcOverrun);
                (0.0, None)
            }
        };
        // Over-force aborts a drive; with the drive off there is nothing to abort (a drop test
        // or a hand on the hammer is not a fault).
        if force_n > self.config.limits.force_limit_n && !matches!(self.mode, Mode::Idle) {
            self.trip(Fault::OverForce);
        }
        if let Some(p) = &mut self.probe {
            p.push(code, now_us);
        }
        let rail = code.is_some_and(|c| self.monitor.at_rail(c));
        let impact = self.detector.update(self.sample, force_n, rail);
        if let Some(imp) = impact {
            self.impacts = self.impacts.wrapping_add(1);
            self.meter.on_impact(imp.peak_n, imp.impulse_n_s);
        }
        if let Some(c) = code {
            let driving = self.generator.amplitude_mm() > 0.0;
            let full = self.mode.measuring();
            let gap = self.regime_gap_samples;
            // Within ± IMPACTS_EXPECTED_PCT of the model's target (asked only when it decides).
            let (model, generator) = (&self.model, &self.generator);
            let expected = || match model {
                Model::Ready(p) => {
                    let half = p.target_hz * (super::faults::IMPACTS_EXPECTED_PCT / 100.0);
                    (generator.freq_hz() - p.target_hz).abs() <= half
                }
                _ => false,
            };
            if let Some(f) = self
                .monitor
                .check(c, driving, full, impact.is_some(), gap, expected)
            {
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
        match self.mode {
            Mode::Ramp if self.generator.settled() => {
                self.reset_measurement();
                match (self.manual_hz, self.model) {
                    // A target that arrived during the ramp is checked as at `start`.
                    (None, Model::Ready(p)) if !self.target_in_window(&p) => {
                        self.trip(Fault::BadConfig);
                    }
                    (None, Model::Ready(p)) => {
                        let mode = self.begin_tracking(&p);
                        self.set_mode(mode);
                    }
                    _ => self.set_mode(Mode::Dwell(Measurement::Settling(0))),
                }
            }
            Mode::Stopping if self.generator.amplitude_mm() == 0.0 => {
                self.set_mode(Mode::Idle);
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
        let t = self.config.track;
        let settle = u32::from(t.settle_cycles);
        let measurement = match &mut self.mode {
            Mode::Dwell(m) | Mode::Track { measurement: m, .. } => {
                *m = m.advance(settle);
                *m
            }
            _ => return,
        };
        let Measurement::Measuring(done) = measurement else {
            return;
        };
        let tracking = matches!(self.mode, Mode::Track { .. });
        if tracking && self.meter.cycle(0).is_some_and(|c| c.impacts != 1) {
            self.lost_cycles = self.lost_cycles.saturating_add(1);
        }
        if done < u32::from(t.measure_cycles) {
            return;
        }
        let window = usize::from(t.measure_cycles);
        let Some(regime) = self.meter.regime(window) else {
            return;
        };
        // The climb follows the window's mean peak force: the tracker spreads the impacts over
        // the sampling phases (`phase_spread_freq_hz`), so the peaks' sampling error (up to
        // 4 % on one impact) cancels in the mean.
        let peak = self.meter.peak_force_n(window).map(|(mean, _)| mean);
        self.regime = Some(regime);
        self.peak_n = peak;
        let f = self.generator.target_freq_hz();
        // The next window: at a new frequency after settling, else straight on.
        let next = match &mut self.mode {
            Mode::Track {
                climber,
                measurement,
            } => {
                let next_hz = climber.next_freq_hz(f, regime, peak);
                *measurement = if next_hz != f {
                    Measurement::Settling(0)
                } else {
                    Measurement::Measuring(0)
                };
                (next_hz != f).then_some(next_hz)
            }
            Mode::Dwell(measurement) => {
                *measurement = Measurement::Measuring(0);
                None
            }
            _ => None,
        };
        if let Some(hz) = next {
            self.generator.set_freq_hz(hz);
        }
    }

    fn queue_cycle(&mut self) {
        let last = self.meter.cycle(0).unwrap_or_default();
        let c = CycleTelemetry {
            state: self.state(),
            freq_hz: self.generator.freq_hz(),
            amplitude_mm: self.generator.amplitude_mm(),
            impacts: last.impacts,
            peak_n: last.peak_n,
            impulse_n_s: last.impulse_n_s,
            regime: self.regime,
            fault: self.fault(),
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

    /// Moves the drive to the prediction's target and returns the tracking mode that climbs
    /// from there within its `1/1` band (clipped to the limits).
    #[inline(never)] // a transition: one copy (flash), not one per caller
    fn begin_tracking(&mut self, p: &Prediction) -> Mode {
        let l = self.config.limits;
        let band = [
            p.band_hz[0].max(l.freq_min_hz),
            p.band_hz[1].min(l.freq_max_hz),
        ];
        let mut climber = HillClimber::new(&self.config.track, band, p.target_hz);
        self.generator.set_freq_hz(climber.start_hz());
        Mode::Track {
            climber,
            measurement: Measurement::Settling(0),
        }
    }

    fn target_in_window(&self, p: &Prediction) -> bool {
        let l = self.config.limits;
        (l.freq_min_hz..=l.freq_max_hz).contains(&p.target_hz)
    }

    #[inline(never)] // called from several commands and transitions: one copy (flash)
    fn reset_measurement(&mut self) {
        self.meter.reset();
        if let Mode::Dwell(m) | Mode::Track { measurement: m, .. } = &mut self.mode {
            *m = Measurement::Settling(0);
        }
        self.regime = None;
        self.peak_n = None;
        self.monitor.disarm();
    }

    fn require_idle(&self) -> Result<(), CommandError> {
        match self.mode {
            Mode::Idle => Ok(()),
            Mode::Fault(_) => Err(CommandError::FaultLatched),
            _ => Err(CommandError::NotIdle(self.mode.state())),
        }
    }

    fn request_model(&mut self) {
        self.generation = self.generation.wrapping_add(1);
        self.model = Model::Pending;
        self.request_open = true;
    }

    #[inline(never)] // a transition: one copy (flash), not one per caller
    fn trip(&mut self, fault: Fault) {
        if let Mode::Fault(_) = self.mode {
            return;
        }
        self.generator.abort();
        self.push(Event::Fault(fault));
        self.set_mode(Mode::Fault(fault));
    }

    #[inline(never)] // a transition: one copy (flash), not one per caller
    fn set_mode(&mut self, mode: Mode) {
        let from = self.mode.state();
        self.mode = mode;
        let to = self.mode.state();
        if to != from {
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

//! The closed loop: the firmware's controller (`shared::control::Controller`, exactly as the
//! MCU runs it) against the plant through the mock ADC, DAC and clock, one sample at a time, with
//! the scenario's console commands and faults. The controller never sees the plant except
//! through the sensor chain.

use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;
use shared::analysis::SelectionError;
use shared::capture::{CAPTURE_RATE_HZ, Capture};
use shared::commission::{Commission, Numbered, Progress, WaitFor};
use shared::console::serve::{
    ReplyText, Response, next_commission_line, poll_commission, sent_commission_line,
};
use shared::console::{Board, BoardInfo, Direct, Line, Link, Token, Version, answer};
use shared::control::{
    Controller, Event, Fault, ModelRequest, Prediction, SAMPLE_RATE_HZ, State, Status, predict,
};
use shared::hal::{DriveOutput, ForceSource, TimeBase};
use shared::model::{RigId, RigParams};
use shared::store::ram_flash::RamFlash;
use shared::store::{STORE_BYTES, Store, start_up};

use super::chains::{MockAdc, MockClock, MockDac, SensorChainSim, SensorState};
use super::plant::Plant;
use super::scenario::{Scenario, TimedDrop, TimedFault};

/// What to run.
#[derive(Debug, Clone)]
pub struct HilSetup {
    /// The rig (preset parameters for both the controller's model and the plant).
    pub rig: RigId,
    /// Gap the controller is configured with, mm.
    pub gap_mm: f32,
    /// Gap of the plant, mm (the real rig).
    pub actual_gap_mm: f64,
    /// Rig time to simulate, s.
    pub seconds: f64,
    /// Chains, faults, commands.
    pub scenario: Scenario,
}

/// The least peak force of a contact episode of the plant counted as an impact, N: lighter
/// ones are the hammer resting on the surface as its motion dies out (at 0.0 mm gap, peaks
/// falling to 1e-300 N); 1 mN is an eightieth of the sensor chain's least step (0.081 N).
pub const TRUE_IMPACT_MIN_N: f64 = 1e-3;

/// One excitation cycle of the drive, as logged.
#[derive(Debug, Clone, Serialize)]
pub struct CycleRow {
    /// Rig time at the end of the cycle, s.
    pub t_s: f64,
    /// Controller state.
    pub state: &'static str,
    /// Drive frequency, Hz.
    pub freq_hz: f64,
    /// Commanded cart amplitude (generator), mm.
    pub amp_cmd_mm: f64,
    /// The plant's cart amplitude over the cycle (max |y|), mm.
    pub cart_amp_mm: f64,
    /// Impacts the controller detected in the cycle.
    pub measured_impacts: u32,
    /// Their largest peak, N (empty without impacts).
    pub measured_peak_n: Option<f64>,
    /// Impacts of the plant in the cycle: its contact episodes whose peak reaches
    /// [`TRUE_IMPACT_MIN_N`].
    pub true_impacts: u32,
    /// Their largest true peak, N.
    pub true_peak_n: Option<f64>,
    /// The controller's measured regime (last evaluation).
    pub measured_regime: String,
    /// Latched fault.
    pub fault: &'static str,
    /// Cycles lost from `1/1` while tracking, so far.
    pub lost_cycles: u32,
    /// Measured force vs the model's prediction, %.
    pub force_vs_model_pct: Option<f64>,
}

/// A console exchange.
#[derive(Debug, Clone, PartialEq)]
pub struct ConsoleLine {
    /// Rig time, s.
    pub t_s: f64,
    /// The line sent.
    pub line: String,
    /// The reply.
    pub reply: String,
}

/// The outcome of a run.
#[derive(Debug, Clone)]
pub struct HilRun {
    /// One row per drive cycle.
    pub rows: Vec<CycleRow>,
    /// Console exchanges.
    pub console: Vec<ConsoleLine>,
    /// State changes `(t_s, state)`.
    pub states: Vec<(f64, State)>,
    /// Faults `(t_s, fault)`.
    pub faults: Vec<(f64, Fault)>,
    /// The model's prediction (when it arrived).
    pub prediction: Option<Prediction>,
    /// The commissioning's records, as the board made them.
    pub commission: Vec<Numbered>,
    /// The controller's final status.
    pub status: Status,
    /// Samples run.
    pub samples: u64,
    /// Wall time, s.
    pub wall_s: f64,
}

impl HilRun {
    /// Rig time over wall time.
    pub fn speedup(&self) -> f64 {
        self.samples as f64 / f64::from(SAMPLE_RATE_HZ) / self.wall_s.max(1e-9)
    }

    /// First time the controller entered `state`, s.
    pub fn first(&self, state: State) -> Option<f64> {
        self.states
            .iter()
            .find(|(_, s)| *s == state)
            .map(|(t, _)| *t)
    }
}

/// Sample rate of the capture ADC in the virtual rig: the plant's steps, `CAPTURE_RATE_HZ /
/// SAMPLE_RATE_HZ` per control sample.
const CAPTURE_PER_SAMPLE: usize = (CAPTURE_RATE_HZ / SAMPLE_RATE_HZ) as usize;

/// The board as the virtual rig reports it (`id`, `diag`).
pub fn virtual_board(uptime_ms: u64) -> BoardInfo {
    BoardInfo {
        firmware: Version::of(env!("CARGO_PKG_VERSION")),
        board: Board::Virtual,
        uptime_ms,
        stack_hwm_bytes: 0,
        stack_size_bytes: 0,
        sample_gap_max_us: 0,
    }
}

/// The virtual rig, one control sample at a time: the plant, the mocks of the firmware's
/// hardware, the controller and the capture, with the scenario's faults, drifts and drops
/// applied on time. Console lines come from outside (the scenario's timed commands in
/// [`run`], a pseudo-terminal in [`super::pty`]) between [`Session::begin_sample`] and
/// [`Session::end_sample`].
pub struct Session {
    sc: Scenario,
    /// The rig and gap the controller falls back to at a start-up without stored settings.
    fallback: (RigId, f32),
    controller: Controller,
    /// The settings store: a NOR flash in RAM with the board's geometry, kept across `reset`.
    store: Store<RamFlash<Vec<u8>>>,
    capture: Capture,
    /// The console service's commissioning sequence.
    commission: Commission,
    /// Its drop prompts seen, and the operator's drops they scheduled `(t_s, release_mm)`.
    prompts_seen: u32,
    prompted_due: Vec<(f64, f64)>,
    /// Its records logged so far (its `records()` count).
    commission_logged: u32,
    /// The console's link (the pty server feeds it; scenario lines bypass it).
    link: Link,
    plant: Plant,
    base: RigParams,
    adc: MockAdc,
    capture_adc: MockAdc,
    dac: MockDac,
    clock: MockClock,
    faults_due: Vec<TimedFault>,
    next_fault: usize,
    drops_due: Vec<TimedDrop>,
    next_drop: usize,
    /// (start, duration, natural frequency %, contact stiffness %).
    drifts: Vec<(f64, f64, f64, f64)>,
    model_due: Option<(f64, ModelRequest, Result<Prediction, SelectionError>)>,
    /// A `reset` was accepted: the pty server restarts the board once its reply is out.
    restart_pending: bool,
    k: u64,
    cart_max: f64,
    true_n: u32,
    true_peak: Option<f64>,
    out: HilRun,
    wall: Instant,
    forces: Vec<f64>,
    codes: Vec<u16>,
}

impl Session {
    /// A rig at rest, drive off, model request open.
    ///
    /// # Errors
    /// Invalid setup (gap, scenario).
    pub fn new(setup: &HilSetup) -> Result<Self> {
        let sc = setup.scenario.clone();
        sc.validate()?;
        let gap = f64::from(setup.gap_mm);
        anyhow::ensure!(
            gap.is_finite() && (0.0..=10.0).contains(&gap),
            "--gap-mm = {gap} is out of range: allowed 0 ..= 10 mm"
        );
        anyhow::ensure!(
            setup.actual_gap_mm.is_finite() && (0.0..=10.0).contains(&setup.actual_gap_mm),
            "--actual-gap-mm = {} is out of range: allowed 0 ..= 10 mm",
            setup.actual_gap_mm
        );
        for d in &sc.drops {
            anyhow::ensure!(
                d.release_mm > setup.actual_gap_mm,
                "drops.release_mm = {} must exceed the rig's gap ({} mm)",
                d.release_mm,
                setup.actual_gap_mm
            );
        }
        let controller = Controller::new(sc.controller, setup.rig, setup.gap_mm)
            .map_err(|e| anyhow::anyhow!("--gap-mm / [controller]: {e}"))?;
        let store = Store::new(
            RamFlash::erased(vec![0u8; STORE_BYTES as usize]),
            0..STORE_BYTES,
        )
        .map_err(|_| anyhow::anyhow!("the virtual rig's store range"))?;
        let base = sc.plant.params(&setup.rig.preset())?;
        let plant = Plant::new(
            &base,
            setup.actual_gap_mm * 1e-3,
            sc.drive,
            sc.plant.settings(),
        )
        .context("--actual-gap-mm")?;
        let adc = MockAdc::new(sc.sensor)?;
        let capture_adc = MockAdc::new(SensorChainSim {
            seed: sc.sensor.seed.wrapping_add(1),
            ..sc.sensor
        })?;
        let mut faults_due: Vec<TimedFault> = sc.faults.clone();
        faults_due.sort_by(|a, b| a.at_s().total_cmp(&b.at_s()));
        let mut drops_due = sc.drops.clone();
        drops_due.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
        let status = controller.status();
        Ok(Session {
            sc,
            fallback: (setup.rig, setup.gap_mm),
            controller,
            store,
            capture: Capture::new(),
            commission: Commission::new(),
            prompts_seen: 0,
            prompted_due: Vec::new(),
            commission_logged: 0,
            link: Link::new(),
            plant,
            base,
            adc,
            capture_adc,
            dac: MockDac::default(),
            clock: MockClock::default(),
            faults_due,
            next_fault: 0,
            drops_due,
            next_drop: 0,
            drifts: Vec::new(),
            model_due: None,
            restart_pending: false,
            k: 0,
            cart_max: 0.0,
            true_n: 0,
            true_peak: None,
            out: HilRun {
                rows: Vec::new(),
                console: Vec::new(),
                states: vec![(0.0, State::Idle)],
                faults: Vec::new(),
                prediction: None,
                commission: Vec::new(),
                status,
                samples: 0,
                wall_s: 0.0,
            },
            wall: Instant::now(),
            forces: Vec::with_capacity(CAPTURE_PER_SAMPLE),
            codes: Vec::with_capacity(CAPTURE_PER_SAMPLE),
        })
    }

    /// Rig time at the start of the next sample, s.
    pub fn t_s(&self) -> f64 {
        self.k as f64 / f64::from(SAMPLE_RATE_HZ)
    }

    /// Rig time at the end of the sample being run, s: the sample count's, not the plant's
    /// sum of steps (which drifts in the last digits: 0.9999999999999062 for 1 s).
    fn sample_end_s(&self) -> f64 {
        (self.k + 1) as f64 / f64::from(SAMPLE_RATE_HZ)
    }

    /// Samples run.
    pub fn samples(&self) -> u64 {
        self.k
    }

    /// The controller (the pty server takes its asynchronous lines).
    pub fn controller_mut(&mut self) -> &mut Controller {
        &mut self.controller
    }

    /// The plant.
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The rows logged so far (one per drive cycle).
    pub fn rows(&self) -> &[CycleRow] {
        &self.out.rows
    }

    /// The console's link.
    pub fn link_mut(&mut self) -> &mut Link {
        &mut self.link
    }

    /// Answers a console line now (through the same service as the firmware's). A `reset`
    /// restarts the rig's board after its reply ([`Session::restart`]).
    pub fn answer(&mut self, line: Line<'_>) -> Response {
        let mut access = self.access();
        let response = answer(&mut access, line);
        if access.reset {
            self.restart_pending = true;
        }
        self.log_commission();
        response
    }

    /// The console service's view of the rig.
    fn access(&mut self) -> Direct<'_> {
        Direct {
            controller: &mut self.controller,
            capture: &mut self.capture,
            board: virtual_board(self.k / 10),
            link: &mut self.link,
            store: &mut self.store,
            commission: &mut self.commission,
            reset: false,
        }
    }

    /// The commissioning sequence advanced, as the console service does when it wakes.
    fn poll_commission(&mut self) {
        if !self.commission.busy() {
            return;
        }
        poll_commission(&mut self.access());
        self.log_commission();
    }

    /// The sequence's new records into the run's log; a new drop prompt schedules the
    /// scenario's operator drops.
    fn log_commission(&mut self) {
        let made = self.commission.records();
        let from = self.commission_logged;
        if made != from {
            // The outbox keeps the newest records: those not logged yet are among them.
            self.out.commission.extend(
                self.commission
                    .unsent()
                    .filter(|n| n.seq.wrapping_sub(from) < made.wrapping_sub(from)),
            );
            self.commission_logged = made;
        }
        if self.commission.prompts() != self.prompts_seen {
            self.prompts_seen = self.commission.prompts();
            let t = self.t_s();
            let asked = self
                .out
                .commission
                .iter()
                .rev()
                .find_map(|n| match n.progress {
                    Progress::Wait(WaitFor::Release { release_mm, .. }) => {
                        Some(f64::from(release_mm))
                    }
                    _ => None,
                });
            self.prompted_due.extend(
                self.sc
                    .prompted_drops
                    .iter()
                    .map(|d| (t + d.after_s, d.release_mm.or(asked).unwrap_or(8.0))),
            );
        }
    }

    /// The commissioning's `!C` lines into the link, as many as have room (the pty server).
    pub fn send_commission_lines(&mut self) {
        let mut text = ReplyText::new();
        let mut access = self.access();
        while next_commission_line(&mut access, &mut text) {
            access.link.push_bytes(text.as_bytes());
            access.link.push_bytes(b"\r\n");
            sent_commission_line(&mut access);
        }
    }

    /// The commissioning sequence.
    pub fn commission(&self) -> &Commission {
        &self.commission
    }

    /// The commissioning's records so far.
    pub fn commission_log(&self) -> &[Numbered] {
        &self.out.commission
    }

    /// The settings store's status (what `store` answers).
    pub fn store_status(&self) -> shared::store::StoreStatus {
        use shared::store::SettingsStore as _;
        self.store.status()
    }

    /// The capture (its segments, for a recording).
    pub fn capture(&self) -> &Capture {
        &self.capture
    }

    /// Whether a `reset` was accepted and waits for its reply to go out.
    pub fn restart_pending(&self) -> bool {
        self.restart_pending
    }

    /// The board restarts (`reset`): a new controller from the store, as the firmware starts
    /// ([`start_up`]), or from the fallback preset; the capture and the model's work start
    /// afresh, the link's queues are emptied. The plant and the store are the hardware's and
    /// stay.
    ///
    /// # Errors
    /// The fallback configuration refused (it was accepted at the session's start: never).
    pub fn restart(&mut self) -> Result<()> {
        let (rig, gap_mm) = self.fallback;
        let mut controller = Controller::new(self.sc.controller, rig, gap_mm)
            .map_err(|e| anyhow::anyhow!("restart: {e}"))?;
        start_up(&mut self.store, &mut controller);
        self.controller = controller;
        self.capture = Capture::new();
        self.commission = Commission::new();
        self.commission_logged = 0;
        self.prompts_seen = 0;
        self.link = Link::new();
        self.model_due = None;
        self.restart_pending = false;
        Ok(())
    }

    /// Runs a timed console line and records the exchange.
    pub fn say(&mut self, line: &str) {
        let a = self.answer(Line::Text(line));
        self.out.console.push(ConsoleLine {
            t_s: self.t_s(),
            line: line.to_string(),
            reply: a.to_string(),
        });
        if self.restart_pending {
            // The fallback was accepted when the session was made: it is again.
            let _ = self.restart();
        }
    }

    /// The first half of a sample: the scenario's faults, drifts and drops due by now.
    ///
    /// # Errors
    /// Drifted parameters the plant rejects, a drop the suspension cannot start from.
    pub fn begin_sample(&mut self) -> Result<()> {
        let t = self.t_s();
        while let Some(f) = self
            .faults_due
            .get(self.next_fault)
            .filter(|f| f.at_s() <= t)
        {
            let adc = &mut self.adc;
            match *f {
                TimedFault::SensorOpen { .. } => adc.state = SensorState::Open,
                TimedFault::SensorStuckHigh { .. } => adc.state = SensorState::Stuck(true),
                TimedFault::SensorStuckLow { .. } => adc.state = SensorState::Stuck(false),
                TimedFault::SensorOk { .. } => adc.state = SensorState::Ok,
                TimedFault::Gain { factor, .. } => adc.gain_factor = factor,
                TimedFault::Drift {
                    at_s,
                    duration_s,
                    natural_freq_pct,
                    contact_stiffness_pct,
                } => self
                    .drifts
                    .push((at_s, duration_s, natural_freq_pct, contact_stiffness_pct)),
            }
            // The capture ADC reads the same sensor.
            self.capture_adc.state = self.adc.state;
            self.capture_adc.gain_factor = self.adc.gain_factor;
            self.next_fault += 1;
        }
        while let Some(d) = self.drops_due.get(self.next_drop).filter(|d| d.at_s <= t) {
            self.plant
                .release(d.release_mm * 1e-3)
                .with_context(|| format!("drop at {} s", d.at_s))?;
            self.next_drop += 1;
        }
        while let Some(i) = self.prompted_due.iter().position(|d| d.0 <= t) {
            let (at, release_mm) = self.prompted_due.remove(i);
            self.plant
                .release(release_mm * 1e-3)
                .with_context(|| format!("prompted drop at {at} s"))?;
        }
        if !self.drifts.is_empty() && self.k.is_multiple_of(100) {
            // Every 10 ms: the plant's parameters on the linear drift paths.
            let (mut nat, mut stiff) = (1.0, 1.0);
            for &(t0, dur, np, sp) in &self.drifts {
                let x = if dur > 0.0 {
                    ((t - t0) / dur).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                nat *= 1.0 + np / 100.0 * x;
                stiff *= 1.0 + sp / 100.0 * x;
            }
            let p = self
                .base
                .with_natural_freq_scaled(nat)
                .with_contact_scaled(stiff);
            self.plant.set_params(&p)?;
        }
        Ok(())
    }

    /// The second half of a sample: the model task, the control loop (ADC → controller → DAC),
    /// the plant over one sample interval, the capture, and the cycle log.
    pub fn end_sample(&mut self) {
        let t = self.t_s();
        // The console service's commissioning, every millisecond.
        if self.k.is_multiple_of(10) {
            self.poll_commission();
        }
        // The model task: computed at once here, delivered after the MCU's computation time.
        if let Some(req) = self.controller.take_model_request() {
            self.model_due = Some((
                t + self.sc.model_delay_s,
                req,
                predict(&req.params, req.gap_mm),
            ));
        }
        if self.model_due.as_ref().is_some_and(|(due, _, _)| *due <= t)
            && let Some((_, req, result)) = self.model_due.take()
        {
            if let Ok(p) = &result {
                self.out.prediction = Some(*p);
            }
            self.controller.set_prediction(req.generation, result);
        }

        self.adc.input_n = self.plant.force_n();
        self.clock.samples = self.k;
        let code = self.adc.read_code();
        let cycles = self.controller.cycles();
        let drive = self.controller.on_sample(code, self.clock.now_us());
        self.dac.write_code(drive);
        self.plant.advance(self.dac.code);
        if self.capture.active() {
            self.plant
                .forces_within_sample(CAPTURE_PER_SAMPLE, &mut self.forces);
            self.codes.clear();
            for &f in &self.forces {
                self.capture_adc.input_n = f;
                self.codes.push(self.capture_adc.read_code().unwrap_or(0));
            }
            self.capture.push_block(&self.codes);
        }

        self.cart_max = self.cart_max.max(self.plant.cart_m().abs());
        let impacts = self.plant.take_impacts();
        for imp in impacts.iter().filter(|i| i.peak_n >= TRUE_IMPACT_MIN_N) {
            self.true_n += 1;
            self.true_peak = Some(
                self.true_peak
                    .map_or(imp.peak_n, |p: f64| p.max(imp.peak_n)),
            );
        }
        while let Some(e) = self.controller.pop_event() {
            match e {
                Event::State { to, .. } => self.out.states.push((self.sample_end_s(), to)),
                Event::Fault(f) => self.out.faults.push((self.sample_end_s(), f)),
                Event::ModelReady(_) | Event::ModelFailed | Event::SamplingStalled { .. } => {}
            }
        }
        if self.controller.cycles() != cycles {
            let s = self.controller.status();
            let last = self.controller.last_cycle();
            self.out.rows.push(CycleRow {
                t_s: self.sample_end_s(),
                state: s.state.token(),
                freq_hz: shortest(s.freq_hz),
                amp_cmd_mm: shortest(s.amplitude_mm),
                cart_amp_mm: self.cart_max * 1e3,
                measured_impacts: last.map_or(0, |c| u32::from(c.impacts)),
                measured_peak_n: last.filter(|c| c.impacts > 0).map(|c| shortest(c.peak_n)),
                true_impacts: self.true_n,
                true_peak_n: self.true_peak,
                measured_regime: s.regime.map_or("-".into(), |r| r.to_string()),
                fault: s.fault.map_or("none", Fault::token),
                lost_cycles: s.lost_cycles,
                force_vs_model_pct: s.force_vs_model_pct.map(shortest),
            });
            (self.cart_max, self.true_n, self.true_peak) = (0.0, 0, None);
        }
        self.k += 1;
    }

    /// The run's record.
    pub fn finish(mut self) -> HilRun {
        self.out.samples = self.k;
        self.out.status = self.controller.status();
        self.out.wall_s = self.wall.elapsed().as_secs_f64();
        self.out
    }
}

/// Runs the closed loop for `setup.seconds` with the scenario's timed console lines.
///
/// # Errors
/// Invalid setup (gap, scenario, duration).
pub fn run(setup: &HilSetup) -> Result<HilRun> {
    anyhow::ensure!(
        setup.seconds.is_finite() && setup.seconds > 0.0 && setup.seconds <= 86_400.0,
        "--seconds = {} is out of range: allowed (0, 86400]",
        setup.seconds
    );
    let mut session = Session::new(setup)?;
    let mut commands = setup.scenario.commands.clone();
    commands.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
    let mut next_cmd = 0;
    let n = (setup.seconds * f64::from(SAMPLE_RATE_HZ)).round() as u64;
    for _ in 0..n {
        session.begin_sample()?;
        let t = session.t_s();
        while let Some(c) = commands.get(next_cmd).filter(|c| c.at_s <= t) {
            session.say(&c.line);
            next_cmd += 1;
        }
        session.end_sample();
    }
    Ok(session.finish())
}

/// `x` as the `f64` of its shortest decimal (`1.0000006`, not `1.0000005960464478`): the
/// controller's `f32` values as the log shows them.
fn shortest(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

//! The closed loop: the firmware's controller (`shared::control::Controller`, exactly as the
//! MCU runs it) against the plant through the mock ADC, DAC and clock, one sample at a time, with
//! the scenario's console commands and faults. The controller never sees the plant except
//! through the sensor chain.

use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;
use shared::analysis::SelectionError;
use shared::control::{
    Controller, Event, Fault, Line, ModelRequest, Prediction, SAMPLE_RATE_HZ, State, Status,
    predict, respond,
};
use shared::hal::{DriveOutput, ForceSource, TimeBase};
use shared::model::{ContactLaw, RigId, RigParams, Suspension};

use super::chains::{MockAdc, MockClock, MockDac, SensorState};
use super::plant::Plant;
use super::scenario::{Scenario, TimedFault};

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
    /// Contact episodes of the plant in the cycle.
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

/// `params` with the contact stiffness scaled by `factor` (spring–dashpot damping by
/// `sqrt(factor)`, which keeps its restitution).
pub fn scale_contact(params: &RigParams, factor: f64) -> RigParams {
    let mut p = *params;
    p.contact = match p.contact {
        ContactLaw::SpringDashpot {
            stiffness_n_m,
            damping_n_s_m,
        } => ContactLaw::SpringDashpot {
            stiffness_n_m: stiffness_n_m * factor,
            damping_n_s_m: damping_n_s_m * factor.sqrt(),
        },
        ContactLaw::Hertz {
            stiffness,
            exponent,
        } => ContactLaw::Hertz {
            stiffness: stiffness * factor,
            exponent,
        },
        ContactLaw::HuntCrossley {
            stiffness,
            exponent,
            lambda_s_m,
        } => ContactLaw::HuntCrossley {
            stiffness: stiffness * factor,
            exponent,
            lambda_s_m,
        },
        ContactLaw::LankaraniNikravesh {
            stiffness,
            exponent,
            restitution,
        } => ContactLaw::LankaraniNikravesh {
            stiffness: stiffness * factor,
            exponent,
            restitution,
        },
    };
    p
}

/// `params` with the natural frequency scaled by `factor` (wires: the pendulum length by
/// `1/factor²`; beams: `natural_freq_hz`).
pub fn scale_natural_freq(params: &RigParams, factor: f64) -> RigParams {
    let mut p = *params;
    p.suspension = match p.suspension {
        Suspension::Wires { length_m } => Suspension::Wires {
            length_m: length_m / (factor * factor),
        },
        Suspension::Beam {
            natural_freq_hz,
            damping_ratio,
        } => Suspension::Beam {
            natural_freq_hz: natural_freq_hz * factor,
            damping_ratio,
        },
    };
    p
}

/// Runs the closed loop.
///
/// # Errors
/// Invalid setup (gap, scenario).
pub fn run(setup: &HilSetup) -> Result<HilRun> {
    let sc = &setup.scenario;
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
    anyhow::ensure!(
        setup.seconds.is_finite() && setup.seconds > 0.0 && setup.seconds <= 86_400.0,
        "--seconds = {} is out of range: allowed (0, 86400]",
        setup.seconds
    );
    let mut controller = Controller::new(sc.controller, setup.rig, setup.gap_mm)
        .map_err(|e| anyhow::anyhow!("--gap-mm / [controller]: {e}"))?;
    let base = scale_contact(&setup.rig.preset(), sc.plant.contact_stiffness_factor);
    let mut plant = Plant::new(
        &base,
        setup.actual_gap_mm * 1e-3,
        sc.drive,
        sc.plant.settings(),
    )
    .context("--actual-gap-mm")?;
    let mut adc = MockAdc::new(sc.sensor)?;
    let mut dac = MockDac::default();
    let mut clock = MockClock::default();

    let mut faults_due: Vec<TimedFault> = sc.faults.clone();
    faults_due.sort_by(|a, b| a.at_s().total_cmp(&b.at_s()));
    let mut commands = sc.commands.clone();
    commands.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
    let (mut next_fault, mut next_cmd) = (0, 0);
    let mut drifts: Vec<(f64, f64, f64, f64)> = Vec::new(); // (start, duration, nat %, stiff %)
    let mut model_due: Option<(f64, ModelRequest, Result<Prediction, SelectionError>)> = None;

    let mut out = HilRun {
        rows: Vec::new(),
        console: Vec::new(),
        states: vec![(0.0, State::Idle)],
        faults: Vec::new(),
        prediction: None,
        status: controller.status(),
        samples: 0,
        wall_s: 0.0,
    };
    let wall = Instant::now();
    let fs = f64::from(SAMPLE_RATE_HZ);
    let n = (setup.seconds * fs).round() as u64;
    let (mut cart_max, mut true_n, mut true_peak): (f64, u32, Option<f64>) = (0.0, 0, None);
    for k in 0..n {
        let t = k as f64 / fs;
        while let Some(f) = faults_due.get(next_fault).filter(|f| f.at_s() <= t) {
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
                } => drifts.push((at_s, duration_s, natural_freq_pct, contact_stiffness_pct)),
            }
            next_fault += 1;
        }
        if !drifts.is_empty() && k % 100 == 0 {
            // Every 10 ms: the plant's parameters on the linear drift paths.
            let (mut nat, mut stiff) = (1.0, 1.0);
            for &(t0, dur, np, sp) in &drifts {
                let x = if dur > 0.0 {
                    ((t - t0) / dur).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                nat *= 1.0 + np / 100.0 * x;
                stiff *= 1.0 + sp / 100.0 * x;
            }
            let p = scale_contact(&scale_natural_freq(&base, nat), stiff);
            plant.set_params(&p)?;
        }
        while let Some(c) = commands.get(next_cmd).filter(|c| c.at_s <= t) {
            let mut reply = String::new();
            respond(&mut controller, Line::Text(&c.line), &mut reply)
                .context("formatting a console reply")?;
            out.console.push(ConsoleLine {
                t_s: t,
                line: c.line.clone(),
                reply,
            });
            next_cmd += 1;
        }
        // The model task: computed at once here, delivered after the MCU's computation time.
        if let Some(req) = controller.take_model_request() {
            model_due = Some((t + sc.model_delay_s, req, predict(req.rig, req.gap_mm)));
        }
        if model_due.as_ref().is_some_and(|(due, _, _)| *due <= t)
            && let Some((_, req, result)) = model_due.take()
        {
            if let Ok(p) = &result {
                out.prediction = Some(*p);
            }
            controller.set_prediction(req.generation, result);
        }

        adc.input_n = plant.force_n();
        clock.samples = k;
        let code = adc.read_code();
        let cycles = controller.cycles();
        let drive = controller.on_sample(code, clock.now_us());
        dac.write_code(drive);
        plant.advance(dac.code);

        cart_max = cart_max.max(plant.cart_m().abs());
        for imp in plant.take_impacts() {
            true_n += 1;
            true_peak = Some(true_peak.map_or(imp.peak_n, |p: f64| p.max(imp.peak_n)));
        }
        while let Some(e) = controller.pop_event() {
            match e {
                Event::State { to, .. } => out.states.push((plant.t_s(), to)),
                Event::Fault(f) => out.faults.push((plant.t_s(), f)),
                Event::ModelReady(_) | Event::ModelFailed => {}
            }
        }
        if controller.cycles() != cycles {
            let s = controller.status();
            let last = controller.last_cycle();
            out.rows.push(CycleRow {
                t_s: plant.t_s(),
                state: s.state.as_str(),
                freq_hz: f64::from(s.freq_hz),
                amp_cmd_mm: f64::from(s.amplitude_mm),
                cart_amp_mm: cart_max * 1e3,
                measured_impacts: last.map_or(0, |c| u32::from(c.impacts)),
                measured_peak_n: last.filter(|c| c.impacts > 0).map(|c| f64::from(c.peak_n)),
                true_impacts: true_n,
                true_peak_n: true_peak,
                measured_regime: s.regime.map_or("-".into(), |r| r.to_string()),
                fault: s.fault.map_or("none", Fault::as_str),
                lost_cycles: s.lost_cycles,
                force_vs_model_pct: s.force_vs_model_pct.map(f64::from),
            });
            (cart_max, true_n, true_peak) = (0.0, 0, None);
        }
    }
    out.samples = n;
    out.status = controller.status();
    out.wall_s = wall.elapsed().as_secs_f64();
    Ok(out)
}

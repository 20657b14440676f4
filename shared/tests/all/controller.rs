//! The controller's state machine, tracking and faults against a toy rig: one half-sine impact
//! per drive cycle whose peak follows a known force-vs-frequency hill (the closed loop with the
//! real hammer plant is host-sim's `hil`). Values asserted come from the toy's own formula.

use proptest::prelude::*;
use shared::analysis::SelectionError;
use shared::console::{Line, LineBuffer, Request, parse};
use shared::control::{
    Command, CommandError, Controller, ControllerConfig, Fault, ModelStatus, Prediction,
    SAMPLE_PERIOD_US, SAMPLE_RATE_HZ, State,
};
use shared::hal::SampleError;
use shared::model::RigId;
use shared::observe::Regime;

/// Peak force (N) of the toy rig at full amplitude: maximum 96 N at 3.70 Hz.
fn hill(f: f32) -> f32 {
    96.0 - 40.0 * (f - 3.70) * (f - 3.70)
}

/// What the toy's sensor does.
#[derive(Clone, Copy, PartialEq)]
enum Sensor {
    Ok,
    Open,
    StuckHigh,
    Overrun,
}

struct Rig {
    c: Controller,
    t_us: u64,
    /// Samples since the current cycle began.
    in_cycle: u32,
    peak_scale: f32,
    sensor: Sensor,
}

impl Rig {
    fn new() -> Self {
        let mut c = Controller::new(ControllerConfig::default(), RigId::Wires, 0.0).unwrap();
        let req = c.take_model_request().unwrap();
        c.set_prediction(req.generation, Ok(prediction(3.60)));
        Rig {
            c,
            t_us: 0,
            in_cycle: 0,
            peak_scale: 1.0,
            sensor: Sensor::Ok,
        }
    }

    /// Runs `seconds` of samples.
    fn run(&mut self, seconds: f32) {
        let n = (seconds * SAMPLE_RATE_HZ as f32) as u32;
        for _ in 0..n {
            self.tick();
        }
    }

    fn tick(&mut self) {
        let g = self.c.generator();
        let (f, a) = (g.freq_hz(), g.amplitude_mm());
        // A 1.2 ms half-sine impact starting 30 ms into each cycle, scaled with amplitude.
        let t_in = self.in_cycle as f32 / SAMPLE_RATE_HZ as f32 - 0.030;
        let force = if a > 0.05 && (0.0..=0.0012).contains(&t_in) {
            self.peak_scale * hill(f) * (a / 0.89) * (core::f32::consts::PI * t_in / 0.0012).sin()
        } else {
            0.0
        };
        let sensor = self.c.config().sensor;
        let code = match self.sensor {
            Sensor::Ok => Ok((sensor.code_of(force).round().clamp(0.0, 4095.0)) as u16),
            Sensor::Open => Ok(sensor.code_of(0.0).round() as u16),
            Sensor::StuckHigh => Ok(4095),
            Sensor::Overrun => Err(SampleError::Overrun),
        };
        self.t_us += u64::from(SAMPLE_PERIOD_US);
        let before = self.c.cycles();
        self.c.on_sample(code, self.t_us);
        if self.c.cycles() != before {
            self.in_cycle = 0;
        } else {
            self.in_cycle += 1;
        }
    }
}

fn prediction(target_hz: f32) -> Prediction {
    Prediction {
        model_hash: shared::model::params_hash(&RigId::Wires.preset()),
        gap_mm: 0.0,
        target_hz,
        band_hz: [2.2, 4.7],
        impact_force_mg: 32.0,
        impact_force_n: 93.4,
        amplitude_mm: 0.89,
        weight_n: 2.923,
        natural_freq_hz: 1.82,
    }
}

/// A model whose predicted force is tiny against the measured one: the discrepancy is capped at
/// `MAX_FORCE_VS_MODEL_PCT`, so that the status line stays within what its reader accepts.
#[test]
fn the_force_discrepancy_is_capped_within_the_status_lines_range() {
    let mut rig = Rig::new();
    let mut c = Controller::new(ControllerConfig::default(), RigId::Wires, 0.0).unwrap();
    let req = c.take_model_request().unwrap();
    c.set_prediction(
        req.generation,
        Ok(Prediction {
            impact_force_n: 1e-3,
            ..prediction(3.60)
        }),
    );
    rig.c = c;
    assert_eq!(
        rig.c.execute(Command::Start),
        Ok(shared::control::Reply::Ok)
    );
    rig.run(20.0);
    let s = rig.c.status();
    // 96 N measured against 1 mN predicted: 9.6e6 %, capped.
    assert!(s.peak.unwrap().n > 50.0, "{s:?}");
    assert_eq!(
        s.force_vs_model_pct,
        Some(shared::control::MAX_FORCE_VS_MODEL_PCT)
    );
    let text = shared::console::Answer::Reply(shared::control::Reply::Status(s)).to_string();
    match text.parse::<shared::console::Answer>() {
        Ok(shared::console::Answer::Reply(shared::control::Reply::Status(read))) => {
            assert_eq!(read.force_vs_model_pct, s.force_vs_model_pct, "{text}");
        }
        other => panic!("{text}: {other:?}"),
    }
}

#[test]
fn start_ramps_then_tracks_to_the_force_maximum() {
    let mut rig = Rig::new();
    assert_eq!(
        rig.c.execute(Command::Start),
        Ok(shared::control::Reply::Ok)
    );
    assert_eq!(rig.c.state(), State::Ramp);
    // 0.89 mm at 0.5 mm/s: 1.78 s of ramp.
    rig.run(1.77);
    assert_eq!(rig.c.state(), State::Ramp);
    rig.run(0.02);
    assert_eq!(rig.c.state(), State::Track);
    rig.run(60.0);
    let s = rig.c.status();
    assert_eq!(s.regime, Some(Regime::ONE_ONE));
    // Within 0.5 % of the toy's maximum (96 N at 3.70 Hz), measured force equal to the toy's
    // force at the drive frequency to within the sampling of the half-sine (10 kHz over 1.2 ms).
    let f = s.freq_hz;
    assert!(hill(f) >= 0.995 * 96.0, "{f}");
    let peak = s.peak.unwrap().n;
    assert!(
        (peak - hill(f)).abs() < 0.02 * hill(f),
        "{peak} vs {}",
        hill(f)
    );
    assert!((s.peak.unwrap().mg - peak / 2.9234).abs() < 0.01);
    assert_eq!(s.lost_cycles, 0);
    assert_eq!(rig.c.fault(), None);
    // Stop ramps down to idle.
    rig.c.execute(Command::Stop).unwrap();
    rig.run(1.9);
    assert_eq!(rig.c.state(), State::Idle);
    assert_eq!(rig.c.generator().amplitude_mm(), 0.0);
}

fn assert_fault_ramps_down_and_latches(rig: &mut Rig, fault: Fault, within_s: f32) {
    let mut t = 0.0;
    while rig.c.state() != State::Fault {
        rig.run(0.001);
        t += 0.001;
        assert!(t <= within_s, "no {fault:?} within {within_s} s");
    }
    assert_eq!(rig.c.fault(), Some(fault));
    // Abort ramp 4 mm/s: 0.89 mm in 0.22 s.
    rig.run(0.25);
    assert_eq!(rig.c.generator().amplitude_mm(), 0.0);
    rig.sensor = Sensor::Ok;
    rig.run(5.0);
    assert_eq!(rig.c.state(), State::Fault);
    assert_eq!(rig.c.generator().amplitude_mm(), 0.0);
    assert_eq!(
        rig.c.execute(Command::Start),
        Err(CommandError::FaultLatched)
    );
    // The fault keeps the last measurement before it; clearing it drops that measurement.
    let measured = rig.c.status();
    rig.c.execute(Command::Clear).unwrap();
    assert_eq!(rig.c.state(), State::Idle);
    assert_eq!(rig.c.fault(), None);
    let s = rig.c.status();
    assert_eq!(
        (s.regime, s.peak, s.force_vs_model_pct),
        (None, None, None),
        "before the clear: {measured:?}"
    );
}

fn tracking_rig() -> Rig {
    let mut rig = Rig::new();
    rig.c.execute(Command::Start).unwrap();
    rig.run(10.0);
    assert_eq!(rig.c.state(), State::Track);
    rig
}

/// A tracking rig whose sensor turns `sensor` trips `fault` within `within_s` (s), then
/// behaves as [`assert_fault_ramps_down_and_latches`] requires.
fn assert_sensor_fault(sensor: Sensor, fault: Fault, within_s: f32) {
    let mut rig = tracking_rig();
    rig.sensor = sensor;
    assert_fault_ramps_down_and_latches(&mut rig, fault, within_s);
}

#[test]
fn sensor_open_trips_within_half_a_second() {
    assert_sensor_fault(Sensor::Open, Fault::SensorOpen, 0.5);
}

#[test]
fn sensor_stuck_at_a_rail_trips() {
    // 20 ms at the rail (4095 is also above the force limit: 310 N > 280 N, the first sample
    // trips over-force).
    assert_sensor_fault(Sensor::StuckHigh, Fault::OverForce, 0.001);
    // Stuck at the lower rail: not a force, so it must be the rail check.
    let mut c = Controller::new(ControllerConfig::default(), RigId::Wires, 0.0).unwrap();
    let req = c.take_model_request().unwrap();
    c.set_prediction(req.generation, Ok(prediction(3.6)));
    c.execute(Command::Start).unwrap();
    let mut t = 0;
    for i in 0..2_000u64 {
        c.on_sample(Ok(0), (i + 1) * 100);
        if c.state() == State::Fault {
            t = i + 1;
            break;
        }
    }
    assert_eq!(c.fault(), Some(Fault::SensorStuck));
    // The drive is on from the first sample's output: 200 rail samples (20 ms) after it.
    assert_eq!(t, 201);
}

#[test]
fn over_force_trips_on_the_first_sample_above_the_limit() {
    let mut rig = tracking_rig();
    rig.peak_scale = 3.2; // ≈ 300 N > 280 N
    assert_fault_ramps_down_and_latches(&mut rig, Fault::OverForce, 0.6);
}

#[test]
fn adc_overrun_and_missed_deadline_trip() {
    assert_sensor_fault(Sensor::Overrun, Fault::AdcOverrun, 0.001);
    let mut rig = tracking_rig();
    rig.t_us += 200; // this sample comes 300 µs after the previous one (limit 250)
    rig.tick();
    assert_eq!(rig.c.fault(), Some(Fault::MissedDeadline));
}

/// A `freq` re-arms nothing the no-signal check needs near the model's target: the sensor
/// opening with the command still trips `sensor-open`, as does a `start` with the sensor
/// already open (where no impact is ever seen). Away from the target (where a regime without
/// impacts is legitimate) the check still waits for a first impact.
#[test]
fn sensor_open_trips_across_a_freq_change_and_from_a_start() {
    // Opened together with a `freq` inside ±5 % of the 3.60 Hz target.
    let mut rig = tracking_rig();
    rig.sensor = Sensor::Open;
    rig.c.execute(Command::Freq(3.70)).unwrap();
    assert_fault_ramps_down_and_latches(&mut rig, Fault::SensorOpen, 1.0);
    // Started with the sensor open: the ramp (1.78 s), then the check's 0.4 s.
    let mut rig = Rig::new();
    rig.sensor = Sensor::Open;
    rig.c.execute(Command::Start).unwrap();
    assert_fault_ramps_down_and_latches(&mut rig, Fault::SensorOpen, 2.5);
    // Started at 3.0 Hz, 17 % below the target, without a first impact: no fault (the regime
    // may be one without impacts there).
    let mut rig = Rig::new();
    rig.sensor = Sensor::Open;
    rig.c.execute(Command::Freq(3.0)).unwrap();
    rig.c.execute(Command::Start).unwrap();
    rig.run(10.0);
    assert_eq!(rig.c.fault(), None);
    assert_eq!(rig.c.state(), State::Dwell);
}

/// Values the console's parser would refuse are refused by the controller too (it is a public
/// API): a gap or link timeout that is not finite or out of range, and a positive link timeout
/// shorter than one sample, which would read as off.
#[test]
fn out_of_range_values_are_refused_by_the_controller_too() {
    let mut rig = Rig::new();
    let before = rig.c.status();
    for g in [f32::NAN, -5.0, 10.5, f32::INFINITY] {
        assert_eq!(
            rig.c.execute(Command::Gap(g)),
            Err(CommandError::OutOfRange {
                min: 0.0,
                max: 10.0
            }),
            "{g}"
        );
    }
    for s in [f32::NAN, -1.0, 0.00004, 0.009, 3600.5] {
        assert_eq!(
            rig.c.execute(Command::LinkTimeout(s)),
            Err(CommandError::OutOfRange {
                min: 0.01,
                max: 3600.0
            }),
            "{s}"
        );
    }
    assert_eq!(rig.c.status(), before);
    assert_eq!(rig.c.link_timeout_samples(), 0);
    // The console line reads the reply back.
    let line = CommandError::OutOfRange {
        min: 0.01,
        max: 3600.0,
    }
    .to_string();
    assert_eq!(
        line,
        "value out of range: allowed 0.01 ..= 3600.00 (0: off for link-timeout)"
    );
    assert_eq!(
        line.parse::<CommandError>(),
        Ok(CommandError::OutOfRange {
            min: 0.01,
            max: 3600.0
        })
    );
    rig.c.execute(Command::LinkTimeout(0.01)).unwrap();
    assert_eq!(rig.c.link_timeout_samples(), 100);
}

/// A target that arrives during the ramp is checked against the frequency window as one
/// present at `start` is: outside it, `bad-config` trips instead of tracking a clamped target.
#[test]
fn a_target_outside_the_window_that_arrives_during_the_ramp_trips() {
    let mut config = ControllerConfig::default();
    config.limits.freq_min_hz = 1.0;
    config.limits.freq_max_hz = 3.0;
    let mut c = Controller::new(config, RigId::Wires, 0.0).unwrap();
    c.execute(Command::Freq(2.0)).unwrap();
    c.execute(Command::Start).unwrap();
    assert_eq!(c.state(), State::Ramp);
    c.execute(Command::Tune).unwrap();
    let req = c.take_model_request().unwrap();
    c.set_prediction(req.generation, Ok(prediction(3.64)));
    let mut t_us = 0;
    for _ in 0..3 * SAMPLE_RATE_HZ {
        t_us += u64::from(SAMPLE_PERIOD_US);
        c.on_sample(Ok(2048), t_us);
        if c.state() != State::Ramp {
            break;
        }
    }
    assert_eq!(c.fault(), Some(Fault::BadConfig));
}

#[test]
fn bad_commands_change_nothing() {
    let mut rig = tracking_rig();
    let before = rig.c.status();
    assert_eq!(
        rig.c.execute(Command::Rig(RigId::Beam170)),
        Err(CommandError::NotIdle(State::Track))
    );
    assert_eq!(
        rig.c.execute(Command::Gap(1.0)),
        Err(CommandError::NotIdle(State::Track))
    );
    assert_eq!(
        rig.c.execute(Command::Freq(40.0)),
        Err(CommandError::FreqOutOfWindow {
            min: 1.0,
            max: 30.0
        })
    );
    assert_eq!(rig.c.status(), before);
    // A stale model result is ignored.
    rig.c
        .set_prediction(99, Err(SelectionError::NoOneToOneBand));
    assert_eq!(rig.c.status(), before);
    assert!(matches!(before.model, ModelStatus::Ready(_)));
}

#[test]
fn freq_dwells_and_tune_returns_to_tracking() {
    let mut rig = tracking_rig();
    rig.c.execute(Command::Freq(3.0)).unwrap();
    assert_eq!(rig.c.state(), State::Dwell);
    rig.run(20.0);
    let s = rig.c.status();
    assert!((s.freq_hz - 3.0).abs() < 1e-4);
    assert!((s.peak.unwrap().n - hill(3.0)).abs() < 0.02 * hill(3.0));
    rig.c.execute(Command::Tune).unwrap();
    assert_eq!(rig.c.status().model, ModelStatus::Pending);
    let req = rig.c.take_model_request().unwrap();
    assert!(rig.c.take_model_request().is_none(), "taken once");
    rig.c.set_prediction(req.generation, Ok(prediction(3.5)));
    assert_eq!(rig.c.state(), State::Track);
    rig.run(40.0);
    assert!(hill(rig.c.status().freq_hz) >= 0.994 * 96.0);
}

#[test]
fn start_needs_a_target_and_rig_changes_request_the_model() {
    let mut c = Controller::new(ControllerConfig::default(), RigId::Wires, 0.0).unwrap();
    assert_eq!(c.execute(Command::Start), Err(CommandError::ModelPending));
    let req = c.take_model_request().unwrap();
    c.set_prediction(req.generation, Err(SelectionError::NoOneToOneBand));
    assert_eq!(c.execute(Command::Start), Err(CommandError::NoTarget));
    c.execute(Command::Rig(RigId::Beam170)).unwrap();
    c.execute(Command::Gap(3.0)).unwrap();
    let req = c.take_model_request().unwrap();
    assert_eq!((req.params, req.gap_mm), (RigId::Beam170.preset(), 3.0));
    assert_eq!(
        req.model_hash,
        shared::model::params_hash(&RigId::Beam170.preset())
    );
    // A manual frequency starts without the model: ramp, then dwell.
    c.execute(Command::Freq(9.0)).unwrap();
    c.execute(Command::Start).unwrap();
    for i in 0..20_000u64 {
        c.on_sample(Ok(248), (i + 1) * 100);
    }
    assert_eq!(c.state(), State::Dwell);
    assert!((c.generator().freq_hz() - 9.0).abs() < 1e-4);
    assert!(Controller::new(ControllerConfig::default(), RigId::Wires, -1.0).is_err());
    assert!(Controller::new(ControllerConfig::default(), RigId::Wires, f32::NAN).is_err());
}

#[test]
fn a_start_that_trips_says_so() {
    // The model's target is outside the safe window (1 ..= 30 Hz): `start` trips bad-config,
    // answers with the fault instead of `ok`, and the drive stays off.
    let mut c = Controller::new(ControllerConfig::default(), RigId::Wires, 0.0).unwrap();
    let req = c.take_model_request().unwrap();
    c.set_prediction(req.generation, Ok(prediction(42.0)));
    let reply = c.execute(Command::Start);
    assert_eq!(reply, Err(CommandError::Tripped(Fault::BadConfig)));
    assert_eq!(
        reply.unwrap_err().to_string(),
        "start tripped fault bad-config: frequency or amplitude outside the limits (clear first)"
    );
    assert_eq!(
        (c.state(), c.fault()),
        (State::Fault, Some(Fault::BadConfig))
    );
    assert_eq!(c.generator().amplitude_mm(), 0.0);
    // Latched: another start is refused until `clear`.
    assert_eq!(c.execute(Command::Start), Err(CommandError::FaultLatched));
    c.execute(Command::Clear).unwrap();
    assert_eq!((c.state(), c.fault()), (State::Idle, None));
}

#[test]
fn status_line_names_every_field() {
    let rig = tracking_rig();
    let line = std::format!("{}", rig.c.status());
    for key in [
        "state=track",
        "rig=wires",
        "gap_mm=0.00",
        "freq_hz=",
        "amp_mm=0.890",
        "regime=1/1",
        "peak_n=",
        "peak_mg=",
        "model=ready",
        "target_hz=3.6 ",
        "fault=none",
        "impacts=",
        "lost_cycles=0",
    ] {
        assert!(line.contains(key), "{key} missing in {line}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// Fuzz: any text parses or is rejected, never panics; accepted numbers are in range.
    #[test]
    fn parser_never_panics(line in ".{0,80}") {
        match parse(&line) {
            Ok(Request::Control(Command::Gap(g))) => prop_assert!((0.0..=10.0).contains(&g)),
            Ok(Request::Control(Command::Freq(f))) => prop_assert!(f.is_finite() && f >= 0.0),
            _ => {}
        }
    }

    /// Fuzz: command words with random arguments and case.
    #[test]
    fn parser_on_command_shaped_lines(
        word in "(?i)(status|rig|gap|start|stop|tune|freq|clear|help|x)",
        arg in proptest::option::of("[-+0-9.eEnaifwrsbm]{0,12}"),
    ) {
        let line = match &arg { Some(a) => std::format!("{word} {a}"), None => word.clone() };
        let r = parse(&line);
        if let Ok(Request::Control(Command::Freq(f) | Command::Gap(f))) = r {
            prop_assert!(f.is_finite());
        }
        if word.eq_ignore_ascii_case("start") {
            prop_assert_eq!(r.is_ok(), arg.as_deref().is_none_or(|a| a.is_empty()));
        }
    }

    /// Fuzz: random bytes through the line buffer, then the parser, then the controller: no
    /// panic, lines never longer than the buffer, and a rejected line changes nothing.
    #[test]
    fn console_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        let mut b = LineBuffer::default();
        let mut c = Controller::new(ControllerConfig::default(), RigId::Wires, 0.0).unwrap();
        for byte in bytes {
            if let Some(Line::Text(s)) = b.push(byte) {
                prop_assert!(s.len() <= shared::console::MAX_LINE);
                let before = c.status();
                match parse(s) {
                    Ok(Request::Control(cmd)) => {
                        if c.execute(cmd).is_err() {
                            prop_assert_eq!(c.status(), before);
                        }
                    }
                    Ok(_) => {}
                    Err(_) => prop_assert_eq!(c.status(), before),
                }
            }
        }
    }
}

/// A controller of the toy rig brought into `state`.
fn rig_in(state: State) -> Rig {
    let mut rig = Rig::new();
    match state {
        State::Idle => {}
        State::Ramp => {
            rig.c.execute(Command::Start).unwrap();
            rig.run(0.5);
        }
        State::Dwell => {
            rig.c.execute(Command::Freq(3.0)).unwrap();
            rig.c.execute(Command::Start).unwrap();
            rig.run(5.0);
        }
        State::Track => rig = tracking_rig(),
        State::Stopping => {
            rig = tracking_rig();
            rig.c.execute(Command::Stop).unwrap();
            rig.run(0.2);
        }
        State::Fault => {
            rig = tracking_rig();
            rig.sensor = Sensor::StuckHigh;
            rig.run(0.1);
            rig.sensor = Sensor::Ok;
        }
    }
    assert_eq!(rig.c.state(), state);
    rig
}

/// Every (state, command) pair: an `ok` comes only with the command's effect; a refusal changes
/// nothing (the controller's whole state, compared by its debug text), except a `start` that
/// trips a fault, which latches it.
#[test]
fn no_ok_without_its_effect_in_any_state() {
    let commands = [
        Command::Status,
        Command::Rig(RigId::Beam170),
        Command::Gap(1.5),
        Command::Start,
        Command::Stop,
        Command::Tune,
        Command::Freq(3.3),
        Command::Freq(40.0),
        Command::Clear,
        Command::Stream(true),
        Command::LinkTimeout(2.5),
    ];
    let mut refusals = 0;
    for state in State::ALL {
        for cmd in commands {
            let mut rig = rig_in(state);
            let before = std::format!("{:?}", rig.c);
            let was = rig.c.status();
            let reply = rig.c.execute(cmd);
            let now = rig.c.status();
            let ctx = std::format!("{state:?} + {cmd:?} → {reply:?}");
            match reply {
                Err(CommandError::Tripped(f)) => {
                    assert_eq!((cmd, rig.c.fault()), (Command::Start, Some(f)), "{ctx}")
                }
                Err(e) => {
                    refusals += 1;
                    assert_eq!(std::format!("{:?}", rig.c), before, "{ctx}: changed");
                    match e {
                        CommandError::NotIdle(s) => assert_eq!(s, state, "{ctx}"),
                        CommandError::FaultLatched => assert_eq!(state, State::Fault, "{ctx}"),
                        _ => {}
                    }
                }
                Ok(_) => match cmd {
                    Command::Status => {
                        assert_eq!(std::format!("{:?}", rig.c), before, "{ctx}")
                    }
                    Command::Rig(r) => {
                        assert_eq!(
                            now.rig.source,
                            shared::control::ModelSource::Preset(r),
                            "{ctx}"
                        );
                        assert_eq!(now.model, ModelStatus::Pending, "{ctx}");
                        assert!(now.regime.is_none() && now.peak.is_none(), "{ctx}: stale");
                    }
                    Command::Gap(g) => {
                        assert_eq!(now.gap_mm, g, "{ctx}");
                        assert!(now.regime.is_none() && now.peak.is_none(), "{ctx}: stale");
                    }
                    Command::Start => {
                        assert_eq!((was.state, now.state), (State::Idle, State::Ramp), "{ctx}");
                        assert!(rig.c.generator().target_amplitude_mm() > 0.0, "{ctx}");
                    }
                    Command::Stop => {
                        // The drive is going to zero (or is there) and nothing measured stays.
                        assert_eq!(rig.c.generator().target_amplitude_mm(), 0.0, "{ctx}");
                        assert!(
                            matches!(now.state, State::Idle | State::Stopping | State::Fault),
                            "{ctx}"
                        );
                        assert!(now.regime.is_none() && now.peak.is_none(), "{ctx}: stale");
                    }
                    Command::Tune => assert_eq!(now.model, ModelStatus::Pending, "{ctx}"),
                    Command::Freq(f) => {
                        if matches!(state, State::Idle | State::Stopping) {
                            // The next start dwells there.
                            rig.run(3.0);
                            assert_eq!(rig.c.state(), State::Idle, "{ctx}");
                            rig.c.execute(Command::Start).unwrap();
                            rig.run(5.0);
                            assert_eq!(rig.c.state(), State::Dwell, "{ctx}");
                        }
                        // The generator's frequency step (its phase increment) is 2.3e-6 Hz.
                        let target = rig.c.generator().target_freq_hz();
                        assert!((target - f).abs() < 1e-5, "{ctx}: {target}");
                    }
                    Command::Clear => assert_eq!(rig.c.fault(), None, "{ctx}"),
                    Command::Stream(on) => assert_eq!(rig.c.streaming(), on, "{ctx}"),
                    Command::LinkTimeout(s) => assert_eq!(
                        rig.c.link_timeout_samples(),
                        (s * SAMPLE_RATE_HZ as f32) as u32,
                        "{ctx}"
                    ),
                },
            }
        }
    }
    // The table holds refusals of every kind, not only successes.
    assert!(refusals >= 15, "{refusals}");
}

#[test]
fn a_silent_link_stops_a_running_drive_and_only_then() {
    let mut rig = tracking_rig();
    rig.c.execute(Command::LinkTimeout(2.0)).unwrap();
    // Lines (or keep-alives) every second keep it running.
    for _ in 0..5 {
        rig.run(1.0);
        rig.c.link_alive();
    }
    assert_eq!(rig.c.state(), State::Track);
    // Then silence: the drive is aborted 2 s after the last line.
    rig.run(1.99);
    assert_eq!(rig.c.state(), State::Track);
    rig.run(0.02);
    assert_eq!(rig.c.fault(), Some(Fault::LinkLost));
    rig.run(0.3);
    assert_eq!(rig.c.generator().amplitude_mm(), 0.0);
    // Idle, a silent link trips nothing; off, nothing either.
    let mut rig = Rig::new();
    rig.c.execute(Command::LinkTimeout(0.5)).unwrap();
    rig.run(3.0);
    assert_eq!(rig.c.state(), State::Idle);
    let mut rig = tracking_rig();
    rig.c.execute(Command::LinkTimeout(0.0)).unwrap();
    rig.run(5.0);
    assert_eq!(rig.c.state(), State::Track);
}

//! The board's commissioning sequence (`shared::commission`) on the virtual rig: plants that
//! are not the controller's model, commissioned from the console with no desktop model; bad
//! captures refused; interruptions that leave the drive at zero and the store untouched.

use host_sim::config::Setup;
use host_sim::selection::compute;
use host_sim::virtual_rig::recording::reference_scenario;
use host_sim::virtual_rig::scenario::{
    PlantSection, PromptedDrop, Scenario, TimedCommand, TimedFault,
};
use host_sim::virtual_rig::{CycleRow, HilSetup, Session, run};
use shared::commission::{
    EndReason, Numbered, Progress, SelectFailure, SensorFailure, Step, VerifyFailure, WaitFor,
};
use shared::console::{Answer, Line};
use shared::control::{Fault, ModelSource, State};
use shared::identify::DropRefusal;
use shared::model::{RigId, RigParams, params_hash};
use shared::store::StoreState;

/// A virtual rig at gap 0 whose controller holds the wire preset, its plant `plant`, no timed
/// lines or drops (the operator drops when prompted: the scenario's default).
fn rig(plant: PlantSection, seed: u64) -> Session {
    let (_, mut scenario) = reference_scenario(seed);
    scenario.plant = plant;
    scenario.drops.clear();
    scenario.commands.clear();
    rig_of(scenario)
}

fn rig_of(scenario: Scenario) -> Session {
    rig_on(RigId::Wires, scenario)
}

/// The virtual rig of `preset` at gap 0 running `scenario`.
fn rig_on(preset: RigId, scenario: Scenario) -> Session {
    Session::new(&HilSetup {
        rig: preset,
        gap_mm: 0.0,
        actual_gap_mm: 0.0,
        seconds: 1e6,
        scenario,
    })
    .unwrap()
}

fn say(rig: &mut Session, line: &str) -> Answer {
    rig.answer(Line::Text(line)).answer
}

fn run_until(rig: &mut Session, t: f64) {
    while rig.t_s() < t {
        rig.begin_sample().unwrap();
        rig.end_sample();
    }
}

/// Runs until a record satisfies `what` (at most `within` s of rig time); that record.
fn run_until_record(rig: &mut Session, within: f64, what: impl Fn(&Progress) -> bool) -> Numbered {
    let end = rig.t_s() + within;
    loop {
        if let Some(n) = rig.commission_log().iter().find(|n| what(&n.progress)) {
            return *n;
        }
        assert!(
            rig.t_s() < end,
            "no such record within {within} s: {:#?}",
            rig.commission_log()
        );
        rig.begin_sample().unwrap();
        rig.end_sample();
    }
}

/// Starts the sequence at 1 s (the preset's target is ready by then).
fn start(rig: &mut Session) {
    run_until(rig, 1.0);
    assert!(
        matches!(say(rig, "commission start"), Answer::Commission(_)),
        "commission start refused"
    );
}

fn ends(p: &Progress) -> bool {
    p.ends()
}

fn spring_dashpot(p: &RigParams) -> (f64, f64) {
    match p.contact {
        shared::model::ContactLaw::SpringDashpot {
            stiffness_n_m,
            damping_n_s_m,
        } => (stiffness_n_m, damping_n_s_m),
        other => panic!("not the thesis' law: {other:?}"),
    }
}

/// Target of `host-sim select` on the plant's true parameters, Hz.
fn select_on(truth: &RigParams) -> f64 {
    let mut setup = Setup::preset(RigId::Wires).unwrap();
    setup.params = *truth;
    compute(&setup, 0.0).unwrap().0.freq_hz
}

/// The mean true peak force of the last five drive cycles, N.
fn mean_tail(rows: &[CycleRow]) -> f64 {
    rows.iter()
        .rev()
        .take(5)
        .filter_map(|r| r.true_peak_n)
        .sum::<f64>()
        / 5.0
}

/// From power-up with no desktop model, the board commissions a rig whose contact and
/// suspension differ from its model's (the plant's contact twice as stiff with 0.6 of the
/// damping, its natural frequency 8 % higher): the sensor check passes; the drop fixes
/// `k_i`, `c_i` within 5 % and `f_n` within 1 % of the plant's; the board's target is within
/// 0.5 % of `host-sim select` on the plant's true parameters (the issue asks 1 %); the verification passes (`1/1`,
/// the force within 10 % of the prediction); `commission accept` stores the model, which a
/// reset loads. Tracking on it for 30 s, the plant's force is within 2 % of the best it gives
/// at five dwell frequencies around the target. The preset model's target on the same plant
/// is printed (how far off the uncommissioned rig is).
#[test]
fn the_board_commissions_a_rig_that_is_not_its_model_and_then_runs_within_2_pct_of_its_best() {
    let (plant, scenario) = reference_scenario(1);
    let truth = plant.params(&RigId::Wires.preset()).unwrap();
    let select_hz = select_on(&truth);
    let mut rig = rig(plant, 1);
    start(&mut rig);
    let accept = run_until_record(&mut rig, 120.0, |p| {
        matches!(
            p,
            Progress::Wait(WaitFor::Accept { .. }) | Progress::Kept { .. }
        )
    });
    let log = rig.commission_log().to_vec();
    for n in &log {
        eprintln!("{}", shared::console::commission::CommissionLine(*n));
    }
    assert!(
        matches!(accept.progress, Progress::Wait(WaitFor::Accept { .. })),
        "{log:#?}"
    );
    // Every step passed, in order, and numbered without a gap.
    let seqs: Vec<u32> = log.iter().map(|n| n.seq).collect();
    assert_eq!(seqs, (0..log.len() as u32).collect::<Vec<_>>());
    let steps: Vec<Option<Step>> = log.iter().map(|n| n.progress.step()).collect();
    use Step::*;
    assert_eq!(
        steps,
        [
            Sensor, Sensor, Drop, Drop, Select, Select, Verify, Verify, Accept
        ]
        .map(Some)
    );
    let Progress::Sensor(check) = log[1].progress else {
        panic!()
    };
    assert_eq!(check.failure, None);
    // The default chain: 0.2 N of noise, no offset the calibration does not know.
    assert!((check.noise_n - 0.2).abs() < 0.02, "{check:?}");
    assert!(check.offset_n.abs() < 0.05, "{check:?}");
    let Progress::Drop(Ok(id)) = log[3].progress else {
        panic!("{:?}", log[3])
    };
    let (model, _) = rig.controller_mut().model();
    let model = *model;
    let (k, c) = spring_dashpot(&truth);
    let (km, cm) = spring_dashpot(&model);
    assert!((km / k - 1.0).abs() < 0.05, "k_i {km} vs {k}");
    assert!((cm / c - 1.0).abs() < 0.05, "c_i {cm} vs {c}");
    let fn_pct = (model.natural_freq_hz() / truth.natural_freq_hz() - 1.0) * 100.0;
    assert!(fn_pct.abs() < 1.0, "f_n off by {fn_pct} %");
    assert!(id.law_fits());
    let Progress::Select(sel) = log[5].progress else {
        panic!()
    };
    let board_hz = f64::from(sel.target.unwrap().target_hz);
    assert!(
        (board_hz / select_hz - 1.0).abs() < 0.005,
        "board {board_hz} Hz vs select on the plant {select_hz} Hz"
    );
    let before = sel.before.expect("the preset's target beside");
    let preset = shared::control::predict(&RigId::Wires.preset(), 0.0).unwrap();
    assert_eq!(before.target_hz, preset.target_hz);
    let Progress::Verify(v) = log[7].progress else {
        panic!()
    };
    assert_eq!(v.failure, None, "{v:?}");
    assert_eq!(rig.controller_mut().state(), State::Idle);
    // Nothing stored before `accept`.
    assert_eq!(rig.store_status().state, StoreState::Empty);
    let Answer::Store(store) = say(&mut rig, "commission accept") else {
        panic!("accept")
    };
    assert_eq!(store.hash, Some(params_hash(&model)));
    let stored = *rig.commission_log().last().unwrap();
    eprintln!("{}", shared::console::commission::CommissionLine(stored));
    assert!(matches!(stored.progress, Progress::Stored { saves: 1, .. }));
    assert_eq!(rig.controller_mut().model().1.source, ModelSource::Stored);

    // Accepted: tracking on the commissioned model.
    let t = rig.t_s() + 1.0;
    run_until(&mut rig, t);
    rig.say("start");
    let t = rig.t_s() + 30.0;
    run_until(&mut rig, t);
    assert_eq!(rig.controller_mut().state(), State::Track);
    let end = mean_tail(rig.rows());
    let dwell = |freq_hz: f64| {
        let sc = Scenario {
            commands: vec![
                TimedCommand {
                    at_s: 0.8,
                    line: format!("freq {freq_hz:.3}"),
                },
                TimedCommand {
                    at_s: 1.0,
                    line: "start".into(),
                },
            ],
            drops: Vec::new(),
            ..scenario.clone()
        };
        let r = run(&HilSetup {
            rig: RigId::Wires,
            gap_mm: 0.0,
            actual_gap_mm: 0.0,
            seconds: 15.0,
            scenario: sc,
        })
        .unwrap();
        mean_tail(&r.rows)
    };
    let best = [0.97, 0.985, 1.0, 1.015, 1.03]
        .into_iter()
        .map(|x| dwell(select_hz * x))
        .fold(0.0, f64::max);
    assert!(end > 0.98 * best, "{end} N tracked vs {best} N at best");
    // A reset loads the accepted model.
    rig.say("stop");
    let t = rig.t_s() + 5.0;
    run_until(&mut rig, t);
    assert!(matches!(say(&mut rig, "reset"), Answer::Reply(_)));
    rig.restart().unwrap();
    assert_eq!(
        rig.controller_mut().model().1,
        shared::control::ModelId::of(&model, ModelSource::Stored)
    );
    eprintln!(
        "plant's select {select_hz:.4} Hz; commissioned board {board_hz:.4} Hz; preset model {:.4} Hz ({:+.1} %); verify {:?}; tracked {end:.1} N, best dwell {best:.1} N",
        preset.target_hz,
        100.0 * (f64::from(preset.target_hz) / select_hz - 1.0),
        v
    );
}

/// The same sequence on two more plants the wire preset does not describe — natural frequency
/// +8 % alone, and a damped pendulum (ζ = 0.01) — and on the 170 mm beam rig (its controller
/// holding the beam's preset, the plant's natural frequency +8 %): each identified within 5 %
/// (contact) and 1 % (natural frequency), its target within 0.5 % of `select` on the plant
/// (the issue asks 1 %), verified.
#[test]
fn other_plants_commission_within_the_same_bounds() {
    let cases = [
        (
            RigId::Wires,
            PlantSection {
                natural_freq_factor: 1.08,
                ..PlantSection::default()
            },
        ),
        (
            RigId::Wires,
            PlantSection {
                damping_ratio: Some(0.01),
                ..PlantSection::default()
            },
        ),
        (
            RigId::Beam170,
            PlantSection {
                natural_freq_factor: 1.08,
                ..PlantSection::default()
            },
        ),
    ];
    for (preset, plant) in cases {
        let truth = plant.params(&preset.preset()).unwrap();
        let (_, mut scenario) = reference_scenario(2);
        scenario.plant = plant;
        scenario.drops.clear();
        scenario.commands.clear();
        let mut rig = rig_on(preset, scenario);
        start(&mut rig);
        let last = run_until_record(&mut rig, 120.0, |p| {
            matches!(p, Progress::Wait(WaitFor::Accept { .. })) || p.ends()
        });
        assert!(
            matches!(last.progress, Progress::Wait(WaitFor::Accept { .. })),
            "{preset:?} {plant:?}: {:#?}",
            rig.commission_log()
        );
        let model = *rig.controller_mut().model().0;
        let (k, c) = spring_dashpot(&truth);
        let (km, cm) = spring_dashpot(&model);
        let fn_pct = (model.natural_freq_hz() / truth.natural_freq_hz() - 1.0) * 100.0;
        let mut setup = Setup::preset(preset).unwrap();
        setup.params = truth;
        let select_hz = compute(&setup, 0.0).unwrap().0.freq_hz;
        let board_hz = rig
            .commission_log()
            .iter()
            .find_map(|n| match n.progress {
                Progress::Select(s) => s.target.map(|t| f64::from(t.target_hz)),
                _ => None,
            })
            .unwrap();
        eprintln!(
            "{preset:?} {plant:?}: k_i {:+.2} %, c_i {:+.2} %, f_n {fn_pct:+.3} %, target {board_hz:.4} vs select {select_hz:.4} Hz",
            (km / k - 1.0) * 100.0,
            (cm / c - 1.0) * 100.0
        );
        assert!((km / k - 1.0).abs() < 0.05, "k_i {km} vs {k}");
        assert!((cm / c - 1.0).abs() < 0.05, "c_i {cm} vs {c}");
        assert!(fn_pct.abs() < 1.0, "f_n off by {fn_pct} %");
        assert!(
            (board_hz / select_hz - 1.0).abs() < 0.005,
            "board {board_hz} Hz vs select on the plant {select_hz} Hz"
        );
    }
}

/// The 150 mm beam rig whose contact is Fig. 3.3's Hunt–Crossley law (`k_i` 2.1e8 N/m^1.6,
/// `n` 1.6, `λ_i` 0.6 s/m), its controller holding the beam's preset (Table 3.1's
/// spring–dashpot law): the drop's spring–dashpot fit does not fit, the board fits the
/// Hunt–Crossley law within 5 % of each parameter and `f_n` within 1 %. Its selection then
/// finds no target the board may run (`host-sim select` on the plant: 10.395 Hz at 172 mg,
/// 504 N, beyond the sensor's 310 N and the 280 N force limit; the board's embedded profile
/// finds no robust `1/1` point on so elastic a contact): the sequence ends at `select`
/// with its reason, the drive never ran and nothing is stored.
#[test]
fn a_hunt_crossley_beam_is_identified_and_its_selection_refused_with_the_reason() {
    let (plant, _) = host_sim::virtual_rig::recording::hunt_crossley_scenario(1);
    let preset = RigId::Beam150;
    let truth = plant.params(&preset.preset()).unwrap();
    let (_, mut scenario) = reference_scenario(1);
    scenario.plant = plant;
    scenario.drops.clear();
    scenario.commands.clear();
    let mut rig = rig_on(preset, scenario);
    start(&mut rig);
    let last = run_until_record(&mut rig, 120.0, ends);
    let log = rig.commission_log().to_vec();
    for n in &log {
        eprintln!("{}", shared::console::commission::CommissionLine(*n));
    }
    assert!(
        matches!(
            last.progress,
            Progress::Kept {
                at: Step::Select,
                reason: EndReason::Failed
            }
        ),
        "{log:#?}"
    );
    let id = log
        .iter()
        .find_map(|n| match n.progress {
            Progress::Drop(Ok(id)) => Some(id),
            _ => None,
        })
        .expect("the drop was identified");
    let model = id.applied_to(&preset.preset()).unwrap();
    let shared::model::ContactLaw::HuntCrossley {
        stiffness,
        exponent,
        lambda_s_m,
    } = model.contact
    else {
        panic!("not a Hunt–Crossley model: {model:?}")
    };
    assert!(id.law_fits(), "{id:?}");
    assert!((stiffness / 2.1e8 - 1.0).abs() < 0.05, "k_i {stiffness}");
    assert!((exponent / 1.6 - 1.0).abs() < 0.05, "n {exponent}");
    assert!((lambda_s_m / 0.6 - 1.0).abs() < 0.05, "λ_i {lambda_s_m}");
    let fn_pct = (model.natural_freq_hz() / truth.natural_freq_hz() - 1.0) * 100.0;
    assert!(fn_pct.abs() < 1.0, "f_n off by {fn_pct} %");
    assert!(log.iter().any(|n| matches!(
        n.progress,
        Progress::Select(s) if s.failure == Some(SelectFailure::NoTarget)
    )));
    // The drive never ran; the controller keeps the preset; nothing stored.
    assert!(
        rig.rows().iter().all(|r| r.amp_cmd_mm == 0.0),
        "the drive ran"
    );
    assert_eq!(
        rig.controller_mut().model().1.source,
        ModelSource::Preset(preset)
    );
    assert_eq!(rig.store_status().state, StoreState::Empty);
}

/// Captures that cannot fix the model — no drop, a drop from too high (the sensor saturates),
/// two drops, the sensor open mid-drop — each end the sequence at the drop step with the
/// identification's reason; the drive never ran, the model is the preset's again, nothing is
/// stored.
#[test]
fn bad_drops_are_refused_with_their_reason_and_nothing_changes() {
    let drop_at = |after_s: f64, release_mm: f64| PromptedDrop {
        after_s,
        release_mm: Some(release_mm),
    };
    let base = || {
        let (_, mut sc) = reference_scenario(3);
        sc.drops.clear();
        sc.commands.clear();
        sc
    };
    let preset =
        shared::control::ModelId::of(&RigId::Wires.preset(), ModelSource::Preset(RigId::Wires));
    let cases: Vec<(&str, Scenario, Want)> = vec![
        (
            "no drop",
            Scenario {
                prompted_drops: Vec::new(),
                ..base()
            },
            |r| matches!(r, DropRefusal::NoImpacts),
        ),
        (
            "from 30 mm",
            Scenario {
                prompted_drops: vec![drop_at(0.5, 30.0)],
                ..base()
            },
            |r| matches!(r, DropRefusal::Saturated { impact: 0 }),
        ),
        (
            "two drops",
            Scenario {
                prompted_drops: vec![drop_at(0.5, 8.0), drop_at(1.5, 8.0)],
                ..base()
            },
            |r| {
                matches!(
                    r,
                    DropRefusal::SecondTrain { .. } | DropRefusal::IrregularSpacing { .. }
                )
            },
        ),
        (
            "sensor open mid-drop",
            Scenario {
                // The prompt comes at 1.5 s, the drop at 2.0 s; the cable opens at 2.6 s.
                faults: vec![TimedFault::SensorOpen { at_s: 2.6 }],
                ..base()
            },
            |r| {
                matches!(
                    r,
                    DropRefusal::TooFewImpacts { .. }
                        | DropRefusal::TrainStopped { .. }
                        | DropRefusal::Saturated { .. }
                )
            },
        ),
    ];
    for (what, scenario, want) in cases {
        let mut rig = rig_of(scenario);
        start(&mut rig);
        let end = run_until_record(&mut rig, 30.0, ends);
        let log = rig.commission_log();
        let refusal = log.iter().find_map(|n| match n.progress {
            Progress::Drop(Err(r)) => Some(r),
            _ => None,
        });
        assert!(refusal.as_ref().is_some_and(want), "{what}: {log:#?}");
        assert_eq!(
            end.progress,
            Progress::Kept {
                at: Step::Drop,
                reason: EndReason::Failed
            },
            "{what}"
        );
        eprintln!("{what}: {refusal:?}");
        assert_eq!(rig.controller_mut().model().1, preset, "{what}");
        assert_eq!(rig.store_status().state, StoreState::Empty, "{what}");
        assert!(
            rig.rows().iter().all(|r| r.amp_cmd_mm == 0.0),
            "{what}: the drive ran"
        );
    }
}

/// The 170 mm beam whose contact is twice as stiff as its model's: identified, but its target's
/// predicted impact force is beyond the controller's force limit (280 N), so the selection step
/// fails before the drive starts (the verification would trip `over-force`); nothing changes.
#[test]
fn a_target_beyond_the_force_limit_is_refused_before_the_drive_starts() {
    let (_, mut scenario) = reference_scenario(1);
    scenario.drops.clear();
    scenario.commands.clear();
    let mut rig = rig_on(RigId::Beam170, scenario);
    start(&mut rig);
    let end = run_until_record(&mut rig, 60.0, ends);
    let sel = rig
        .commission_log()
        .iter()
        .find_map(|n| match n.progress {
            Progress::Select(s) => Some(s),
            _ => None,
        })
        .expect("a select record");
    assert_eq!(sel.failure, Some(SelectFailure::ForceLimit), "{sel:?}");
    let weight = RigId::Beam170.preset().weight_n();
    let force = f64::from(sel.target.unwrap().impact_force_mg) * weight;
    assert!(force > 280.0, "{force} N");
    assert_eq!(
        end.progress,
        Progress::Kept {
            at: Step::Select,
            reason: EndReason::Failed
        }
    );
    assert!(rig.rows().iter().all(|r| r.amp_cmd_mm == 0.0));
    assert_eq!(
        rig.controller_mut().model().1.source,
        ModelSource::Preset(RigId::Beam170)
    );
    assert_eq!(rig.store_status().state, StoreState::Empty);
}

/// How a refused capture is recognised.
type Want = fn(&DropRefusal) -> bool;

/// Runs until the drive is at zero and idle (at most `within` s).
fn run_until_idle(rig: &mut Session, within: f64) {
    let end = rig.t_s() + within;
    while !(rig.controller_mut().state() == State::Idle
        && rig.controller_mut().generator().amplitude_mm() == 0.0)
    {
        assert!(rig.t_s() < end, "{:?}", rig.controller_mut().status());
        rig.begin_sample().unwrap();
        rig.end_sample();
    }
}

/// The reference plant at the verification step (the drive ramping at the target).
fn at_verification(rig: &mut Session) {
    start(rig);
    run_until_record(rig, 60.0, |p| {
        matches!(p, Progress::Wait(WaitFor::Drive { .. }))
    });
    let t = rig.t_s() + 3.0;
    run_until(rig, t);
}

fn preset_id() -> shared::control::ModelId {
    shared::control::ModelId::of(&RigId::Wires.preset(), ModelSource::Preset(RigId::Wires))
}

/// A commissioning interrupted anywhere leaves the drive at zero and the store as it was, and
/// the rig on the model it ran before: `commission abort` during the verification; the link
/// lost during it (the link-loss watchdog trips, the sequence ends once the fault is cleared);
/// a sensor that fails during it; a `reset` during the selection.
#[test]
fn an_interrupted_commissioning_leaves_the_drive_at_zero_and_the_store_unchanged() {
    let (plant, _) = reference_scenario(1);
    // `commission abort` while the drive ramps.
    let mut rig = rig(plant, 1);
    at_verification(&mut rig);
    assert!(rig.controller_mut().generator().amplitude_mm() > 0.0);
    let Answer::Commission(v) = say(&mut rig, "commission abort") else {
        panic!("abort")
    };
    assert!(v.ending && v.step == Some(Step::Verify), "{v:?}");
    let end = run_until_record(&mut rig, 30.0, ends);
    assert_eq!(
        end.progress,
        Progress::Kept {
            at: Step::Verify,
            reason: EndReason::Aborted
        }
    );
    run_until_idle(&mut rig, 1.0);
    assert_eq!(rig.controller_mut().model().1, preset_id());
    assert_eq!(rig.store_status().state, StoreState::Empty);

    // The link lost (a 1 s watchdog, no line after it): `link-lost` trips at the ramp; the
    // verification fails with it; the drive ramps to zero; the old model is back after `clear`.
    let mut rig = self::rig(plant, 1);
    rig.say("link-timeout 1");
    at_verification(&mut rig);
    let failed = rig.commission_log().iter().find_map(|n| match n.progress {
        Progress::Verify(v) => v.failure,
        _ => None,
    });
    assert_eq!(failed, Some(VerifyFailure::Fault(Fault::LinkLost)));
    let t = rig.t_s() + 10.0;
    run_until(&mut rig, t);
    assert_eq!(rig.controller_mut().generator().amplitude_mm(), 0.0);
    assert_eq!(rig.controller_mut().state(), State::Fault);
    assert!(rig.commission().busy(), "ends after `clear`");
    // Meanwhile only what is safe is taken.
    assert!(matches!(
        say(&mut rig, "start"),
        Answer::Error(shared::console::AnswerError::Commission(
            shared::commission::CommissionRefusal::Busy(Step::Verify)
        ))
    ));
    rig.say("clear");
    let end = run_until_record(&mut rig, 5.0, ends);
    assert_eq!(
        end.progress,
        Progress::Kept {
            at: Step::Verify,
            reason: EndReason::Fault(Fault::LinkLost)
        }
    );
    run_until_idle(&mut rig, 1.0);
    assert_eq!(rig.controller_mut().model().1, preset_id());
    assert_eq!(rig.store_status().state, StoreState::Empty);

    // The sensor fails open mid-verification.
    let (_, mut scenario) = reference_scenario(1);
    scenario.drops.clear();
    scenario.commands.clear();
    scenario.faults = vec![TimedFault::SensorOpen { at_s: 9.0 }];
    let mut rig = rig_of(scenario);
    start(&mut rig);
    let verdict = run_until_record(&mut rig, 60.0, |p| matches!(p, Progress::Verify(_)));
    let Progress::Verify(v) = verdict.progress else {
        panic!()
    };
    assert!(
        matches!(
            v.failure,
            Some(VerifyFailure::Fault(Fault::SensorOpen | Fault::SensorStuck))
        ),
        "{v:?}"
    );
    let t = rig.t_s() + 10.0;
    run_until(&mut rig, t);
    assert_eq!(rig.controller_mut().generator().amplitude_mm(), 0.0);
    assert_eq!(rig.store_status().state, StoreState::Empty);

    // A reset while the board computes the identified model's target (the identified model
    // active, not stored): the board starts afresh on its stored settings (none).
    let mut rig = self::rig(plant, 1);
    start(&mut rig);
    run_until_record(&mut rig, 30.0, |p| {
        matches!(p, Progress::Wait(WaitFor::Model))
    });
    assert_eq!(rig.controller_mut().model().1.source, ModelSource::Edited);
    assert!(matches!(say(&mut rig, "reset"), Answer::Reply(_)));
    rig.restart().unwrap();
    assert!(!rig.commission().busy());
    assert_eq!(rig.controller_mut().model().1, preset_id());
    assert_eq!(rig.store_status().state, StoreState::Empty);
}

/// The sensor check fails on a sensor stuck from the start (its samples on the rail),
/// before anything moves; while a sequence runs the console refuses what would disturb it, and
/// `commission accept` before a verification passed is refused.
#[test]
fn a_failed_sensor_check_ends_the_sequence_and_a_running_one_guards_the_console() {
    use shared::commission::CommissionRefusal;
    use shared::console::AnswerError;
    let (_, mut scenario) = reference_scenario(1);
    scenario.drops.clear();
    scenario.commands.clear();
    scenario.faults = vec![TimedFault::SensorStuckHigh { at_s: 0.5 }];
    let mut rig = rig_of(scenario);
    start(&mut rig);
    let end = run_until_record(&mut rig, 5.0, ends);
    let Progress::Sensor(check) = rig.commission_log()[1].progress else {
        panic!("{:?}", rig.commission_log())
    };
    assert_eq!(check.failure, Some(SensorFailure::Rail), "{check:?}");
    assert_eq!(
        end.progress,
        Progress::Kept {
            at: Step::Sensor,
            reason: EndReason::Failed
        }
    );
    assert_eq!(rig.controller_mut().model().1, preset_id());

    let (plant, _) = reference_scenario(1);
    let mut rig = self::rig(plant, 1);
    start(&mut rig);
    let refused = |a: Answer| match a {
        Answer::Error(AnswerError::Commission(r)) => r,
        other => panic!("not refused: {other}"),
    };
    assert_eq!(
        refused(say(&mut rig, "commission accept")),
        CommissionRefusal::NothingToAccept
    );
    assert_eq!(
        refused(say(&mut rig, "commission start")),
        CommissionRefusal::Running(Step::Sensor)
    );
    for line in [
        "start",
        "save",
        "gap 0.5",
        "capture arm",
        "draft begin",
        "freq 3",
    ] {
        assert_eq!(
            refused(say(&mut rig, line)),
            CommissionRefusal::Busy(Step::Sensor),
            "{line}"
        );
    }
    for line in ["status", "id", "model", "store", "stop", "capture"] {
        assert!(!matches!(say(&mut rig, line), Answer::Error(_)), "{line}");
    }
    assert_eq!(rig.store_status().state, StoreState::Empty);
}

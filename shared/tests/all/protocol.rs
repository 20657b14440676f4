//! The console protocol's round trip: for every reply, record and request type,
//! `parse(format(x)) == x` over generated values (at the resolution the wire carries: the
//! decimals each field is written with), and what the parsers refuse at the edge.

use proptest::prelude::*;
use shared::capture::Capture;
use shared::capture::{CAPTURE_RATE_HZ, CaptureCommand};
use shared::capture::{CaptureState, CaptureStatus, SEGMENT_LEN, SEGMENTS, SegmentView};
use shared::commission::{Commission, CommissionRefusal, Step};
use shared::console::IdentifyLine;
use shared::console::commission::CommissionView;
use shared::console::link::LinkStats;
use shared::console::request::CommissionCommand;
use shared::console::serve::Response;
use shared::console::{self, BoardInfo, Direct, Line, Link};
use shared::console::{
    Answer, AnswerError, Arg, Board, CaptureError, DiagInfo, IdInfo, ParseError, Request, Version,
    WireError, parse,
};
use shared::console::{
    CalibView, DraftCommand, FieldProblem, ModelOf, ModelView, SettingsRefusal, StoreRefusal,
    StoreView, Token,
};
use shared::control::{
    AsyncKind, AsyncRecord, Command, CommandError, CycleTelemetry, Event, Fault, ModelStatus,
    PeakForce, Reply, SAMPLE_RATE_HZ, SensorChain, State, Status, Target,
};
use shared::control::{CalibField, Calibration, ModelId, ModelSource};
use shared::control::{Controller, ControllerConfig};
use shared::identify::spacing::SuspensionId;
use shared::identify::{DropIdentification, DropLaw, DropRefusal};
use shared::model::{ContactLawKind, ModelEdit, ModelField, RigId, RigParams, SuspensionKind};
use shared::observe::Regime;
use shared::store::ram_flash::{PAGE_BYTES, RamFlash};
use shared::store::{SaveError, Store, StoreState};

/// A decimal with `d` decimals in `lo ..= hi` (at most 7 significant digits: what the wire
/// writes and reads exactly).
fn dec(d: u32, lo: f64, hi: f64) -> impl Strategy<Value = f32> {
    let s = 10f64.powi(d as i32);
    let (a, b) = ((lo * s).ceil() as i64, (hi * s).floor() as i64);
    assert!(
        b.abs() < 10_000_000 && a.abs() < 10_000_000,
        "{lo} {hi} {d}"
    );
    (a..=b).prop_map(move |k| k as f32 / s as f32)
}

fn state() -> impl Strategy<Value = State> {
    proptest::sample::select(State::ALL.to_vec())
}

fn rig() -> impl Strategy<Value = RigId> {
    proptest::sample::select(RigId::ALL.to_vec())
}

fn fault() -> impl Strategy<Value = Option<Fault>> {
    proptest::option::of(proptest::sample::select(Fault::ALL.to_vec()))
}

fn regime() -> impl Strategy<Value = Option<Regime>> {
    prop_oneof![
        Just(None),
        Just(Some(Regime::NoImpact)),
        Just(Some(Regime::Irregular)),
        (1u16..200, 1u16..200).prop_map(|(p, q)| Some(Regime::Periodic { p, q })),
    ]
}

fn target() -> impl Strategy<Value = Target> {
    (
        dec(4, 0.0, 999.9),
        dec(3, 0.0, 999.9),
        dec(3, 0.0, 999.9),
        dec(2, 0.0, 99_999.0),
    )
        .prop_map(|(t, a, b, mg)| Target {
            target_hz: t,
            band_hz: [a.min(b), a.max(b)],
            impact_force_mg: mg,
        })
}

fn model_id() -> impl Strategy<Value = ModelId> {
    (
        proptest::sample::select(<ModelSource as Token>::ALL.to_vec()),
        any::<u32>(),
    )
        .prop_map(|(source, hash)| ModelId { source, hash })
}

fn store_state() -> impl Strategy<Value = StoreState> {
    proptest::sample::select(StoreState::ALL.to_vec())
}

/// A valid rig model: a preset with any law and suspension, every field it has scaled by a
/// factor in 0.7 ..= 1.3 (full-precision values: the exact form's bits as well as its decimals).
fn rig_params() -> impl Strategy<Value = RigParams> {
    (
        rig(),
        proptest::sample::select(ContactLawKind::ALL.to_vec()),
        proptest::sample::select(SuspensionKind::ALL.to_vec()),
        proptest::collection::vec(0.7f64..1.3, ModelField::ALL.len()),
        any::<bool>(),
    )
        .prop_map(|(rig, law, suspension, factors, round)| {
            let mut p = rig
                .preset()
                .edited(ModelEdit::Law(law))
                .and_then(|p| p.edited(ModelEdit::Suspension(suspension)))
                .unwrap();
            for (field, k) in ModelField::ALL.into_iter().zip(factors) {
                if let Some(v) = p.value(field) {
                    // Half the values as an operator types them (3 significant digits).
                    let w = if round {
                        format!("{:.3e}", v * k).parse().unwrap()
                    } else {
                        v * k
                    };
                    p = p.edited(ModelEdit::Set(field, w)).unwrap();
                }
            }
            p
        })
}

/// A valid calibration: the default's fields scaled a little (within the limits' checks).
fn calibration() -> impl Strategy<Value = Calibration> {
    proptest::collection::vec(0.97f32..1.0, CalibField::ALL.len()).prop_map(|factors| {
        let mut c = Calibration::default();
        for (field, k) in CalibField::ALL.into_iter().zip(factors) {
            c = c.with(field, c.value(field) * k);
        }
        c
    })
}

fn status() -> impl Strategy<Value = Status> {
    (
        (
            state(),
            model_id(),
            dec(2, 0.0, 10.0),
            dec(4, 0.0, 999.9),
            dec(3, 0.0, 99.999),
        ),
        (
            regime(),
            proptest::option::of((dec(1, 0.0, 999_999.0), dec(2, 0.0, 99_999.0))),
            prop_oneof![
                Just(ModelStatus::Pending),
                Just(ModelStatus::Failed),
                target().prop_map(ModelStatus::Ready)
            ],
            proptest::option::of(dec(1, -99_999.0, 99_999.0)),
            fault(),
            any::<u32>(),
            any::<u32>(),
        ),
    )
        .prop_map(
            |(
                (state, rig, gap_mm, freq_hz, amplitude_mm),
                (regime, peak, model, pct, fault, impacts, lost),
            )| Status {
                state,
                rig,
                gap_mm,
                freq_hz,
                amplitude_mm,
                regime,
                peak: peak.map(|(n, mg)| PeakForce { n, mg }),
                model,
                force_vs_model_pct: pct,
                fault,
                impacts,
                lost_cycles: lost,
            },
        )
}

fn id() -> impl Strategy<Value = IdInfo> {
    (
        (any::<u16>(), any::<u16>(), any::<u16>()),
        proptest::sample::select(vec![Board::Rig, Board::Emulator, Board::Virtual]),
        (model_id(), store_state()),
        dec(2, 0.0, 10.0),
        (1e-5f32..1.0, 0.0f32..1.65, 0.5f32..10.0),
        1e-3f32..999.0,
        (dec(2, 0.0, 999.99), dec(2, 0.0, 999.99)),
        (
            dec(3, 0.001, 999.0),
            dec(3, 0.001, 99.0),
            dec(1, 0.1, 999_999.0),
        ),
    )
        .prop_map(
            |(
                v,
                board,
                (rig, store),
                gap_mm,
                (vpn, off, fs),
                mass_kg,
                (a, b),
                (slew, ramp, lim),
            )| IdInfo {
                firmware: Version {
                    major: v.0,
                    minor: v.1,
                    patch: v.2,
                },
                board,
                rig,
                store,
                gap_mm,
                sample_rate_hz: SAMPLE_RATE_HZ,
                capture_rate_hz: CAPTURE_RATE_HZ,
                sensor: SensorChain {
                    volts_per_n: vpn,
                    offset_v: off,
                    adc_full_scale_v: fs,
                },
                mass_kg,
                freq_window_hz: [a.min(b), a.max(b)],
                slew_hz_per_s: slew,
                ramp_mm_per_s: ramp,
                force_limit_n: lim,
            },
        )
}

fn diag() -> impl Strategy<Value = DiagInfo> {
    (any::<[u64; 2]>(), any::<[u32; 9]>()).prop_map(|(a, b)| DiagInfo {
        samples: a[0],
        uptime_ms: a[1],
        sample_gap_max_us: b[0],
        link: LinkStats {
            rx_errors: b[1],
            lines_lost: b[2],
            async_sent: b[3],
            async_dropped: b[4],
        },
        lost_cycles: b[5],
        stack_hwm_bytes: b[6],
        stack_size_bytes: b[7],
        link_timeout_ms: b[8],
    })
}

fn capture_status() -> impl Strategy<Value = CaptureStatus> {
    (
        proptest::sample::select(vec![
            CaptureState::Off,
            CaptureState::Armed,
            CaptureState::Done,
        ]),
        0..=SEGMENTS as u16,
        any::<u32>(),
        dec(2, 0.0, 99_999.0),
    )
        .prop_map(|(state, segments, samples, level_n)| CaptureStatus {
            state,
            segments,
            samples,
            level_n,
        })
}

fn segment() -> impl Strategy<Value = SegmentView> {
    (
        0..SEGMENTS as u16,
        any::<u32>(),
        proptest::collection::vec(0u16..=4095, SEGMENT_LEN),
    )
        .prop_map(|(k, start, codes)| SegmentView {
            k,
            start,
            codes: codes.try_into().unwrap(),
        })
}

/// Any `f32` the identification can give: finite, of any size.
fn finite_f32() -> impl Strategy<Value = f32> {
    any::<f32>().prop_filter("finite", |v| v.is_finite())
}

fn identify_line() -> impl Strategy<Value = IdentifyLine> {
    let x = finite_f32;
    let law = prop_oneof![
        (x(), x(), x(), x()).prop_map(|(k, k_pm, c, c_pm)| DropLaw::SpringDashpot {
            stiffness_n_m: k,
            stiffness_pm_pct: k_pm,
            damping_n_s_m: c,
            damping_pm_pct: c_pm,
        }),
        (x(), x(), x(), x(), x(), x()).prop_map(|(k, k_pm, n, n_pm, l, l_pm)| {
            DropLaw::HuntCrossley {
                stiffness: k,
                stiffness_pm_pct: k_pm,
                exponent: n,
                exponent_pm: n_pm,
                lambda_s_m: l,
                lambda_pm_pct: l_pm,
            }
        }),
    ];
    let identified = (
        (any::<u16>(), x(), x(), x(), x(), x()),
        (law, x()),
        proptest::option::of((x(), x(), x(), any::<u16>())),
    )
        .prop_map(
            |(
                (impacts, offset_n, noise_n, first_peak_n, approach_speed_m_s, restitution),
                (law, fit_ratio),
                s,
            )| {
                DropIdentification {
                    impacts,
                    offset_n,
                    noise_n,
                    first_peak_n,
                    approach_speed_m_s,
                    restitution,
                    law,
                    fit_ratio,
                    suspension: s.map(|(natural_freq_hz, spread_pct, damping_ratio, halves)| {
                        SuspensionId {
                            natural_freq_hz,
                            spread_pct,
                            damping_ratio,
                            halves,
                        }
                    }),
                }
            },
        );
    let k = any::<u16>;
    let refused = prop_oneof![
        Just(DropRefusal::NoImpacts),
        k().prop_map(|found| DropRefusal::TooFewImpacts { found }),
        any::<u32>().prop_map(|lost| DropRefusal::LostSamples { lost }),
        k().prop_map(|impact| DropRefusal::Saturated { impact }),
        k().prop_map(|impact| DropRefusal::Clipped { impact }),
        (k(), k()).prop_map(|(impact, samples)| DropRefusal::ShortPulse { impact, samples }),
        (k(), x(), x()).prop_map(
            |(impact, noise_n, typical_n)| DropRefusal::RestlessBaseline {
                impact,
                noise_n,
                typical_n
            }
        ),
        (k(), x(), x()).prop_map(|(impact, spacing_ms, expected_ms)| {
            DropRefusal::IrregularSpacing {
                impact,
                spacing_ms,
                expected_ms,
            }
        }),
        (k(), x()).prop_map(|(impacts, expected_n)| DropRefusal::TrainStopped {
            impacts,
            expected_n
        }),
        (k(), x()).prop_map(|(impact, peak_n)| DropRefusal::SecondTrain { impact, peak_n }),
        Just(DropRefusal::NotIdentifiable),
        Just(DropRefusal::BadMass),
    ];
    prop_oneof![identified.prop_map(Ok), refused.prop_map(Err)].prop_map(IdentifyLine)
}

fn parse_error() -> impl Strategy<Value = ParseError> {
    let arg = proptest::sample::select(Arg::ALL.to_vec());
    prop_oneof![
        Just(ParseError::Empty),
        Just(ParseError::TooLong),
        Just(ParseError::UnknownCommand),
        Just(ParseError::UnexpectedArgument),
        Just(ParseError::UnknownRig),
        Just(ParseError::OnOff),
        Just(ParseError::UnknownCapture),
        Just(ParseError::BadTag),
        arg.clone().prop_map(ParseError::MissingArgument),
        arg.clone().prop_map(ParseError::BadNumber),
        (arg, dec(2, -9999.0, 9999.0), dec(2, -9999.0, 9999.0))
            .prop_map(|(field, min, max)| ParseError::OutOfRange { field, min, max }),
    ]
}

fn answer_error() -> impl Strategy<Value = AnswerError> {
    prop_oneof![
        Just(AnswerError::Lost),
        Just(AnswerError::Bad),
        parse_error().prop_map(AnswerError::Parse),
        prop_oneof![
            proptest::sample::select(Fault::ALL.to_vec()).prop_map(CommandError::Tripped),
            state().prop_map(CommandError::NotIdle),
            Just(CommandError::FaultLatched),
            Just(CommandError::ModelPending),
            Just(CommandError::NoTarget),
            (dec(2, 0.0, 999.0), dec(2, 0.0, 999.0))
                .prop_map(|(min, max)| CommandError::FreqOutOfWindow { min, max }),
            (dec(2, 0.0, 999.0), dec(2, 0.0, 3600.0))
                .prop_map(|(min, max)| CommandError::OutOfRange { min, max }),
        ]
        .prop_map(AnswerError::Command),
        prop_oneof![
            Just(CaptureError::NotIdle),
            Just(CaptureError::Running),
            (any::<u16>(), any::<u16>())
                .prop_map(|(k, recorded)| CaptureError::NoSegment { k, recorded }),
        ]
        .prop_map(AnswerError::Capture),
        settings_refusal().prop_map(AnswerError::Settings),
        prop_oneof![
            proptest::sample::select(vec![
                SaveError::Flash,
                SaveError::Storage,
                SaveError::TooBig
            ])
            .prop_map(StoreRefusal::SaveFailed),
            store_state().prop_map(StoreRefusal::NothingToRevert),
        ]
        .prop_map(AnswerError::Store),
        commission_refusal().prop_map(AnswerError::Commission),
    ]
}

fn commission_step() -> impl Strategy<Value = Step> {
    proptest::sample::select(Step::ALL.to_vec())
}

fn commission_refusal() -> impl Strategy<Value = CommissionRefusal> {
    prop_oneof![
        proptest::sample::select(vec![
            CommissionRefusal::FaultLatched,
            CommissionRefusal::CaptureRunning,
            CommissionRefusal::DraftOpen,
            CommissionRefusal::NothingToAccept,
            CommissionRefusal::NotRunning,
        ]),
        commission_step().prop_map(CommissionRefusal::Running),
        commission_step().prop_map(CommissionRefusal::Busy),
        state().prop_map(CommissionRefusal::NotIdle),
    ]
}

fn settings_refusal() -> impl Strategy<Value = SettingsRefusal> {
    let owners: Vec<&'static str> = ContactLawKind::ALL
        .into_iter()
        .map(ContactLawKind::name)
        .chain(SuspensionKind::ALL.into_iter().map(SuspensionKind::name))
        .collect();
    let value = || {
        prop_oneof![
            any::<f64>().prop_filter("finite", |v| v.is_finite()),
            -1e3f64..1e3
        ]
    };
    prop_oneof![
        Just(SettingsRefusal::NoDraft),
        (
            proptest::sample::select(ModelField::ALL.to_vec()),
            proptest::sample::select(owners)
        )
            .prop_map(|(field, model_has)| SettingsRefusal::NotOfThisModel { field, model_has }),
        (
            proptest::sample::select(vec![
                "mass_kg",
                "suspension.wires.damping_ratio",
                "contact.hunt-crossley.lambda_s_m",
                "volts_per_n",
                "force_limit_n",
                "threshold_n",
                "gap_mm",
            ]),
            prop_oneof![
                Just(FieldProblem::NotFinite),
                (value(), value(), value())
                    .prop_map(|(value, min, max)| FieldProblem::OutOfRange { value, min, max }),
                (value(), value(), value())
                    .prop_map(|(value, min, max)| FieldProblem::OutOfHalfOpen { value, min, max }),
            ]
        )
            .prop_map(|(field, problem)| SettingsRefusal::Invalid { field, problem }),
    ]
}

fn answer() -> impl Strategy<Value = Answer> {
    prop_oneof![
        Just(Answer::Reply(Reply::Ok)),
        Just(Answer::Help),
        status().prop_map(|s| Answer::Reply(Reply::Status(s))),
        id().prop_map(Answer::Id),
        diag().prop_map(Answer::Diag),
        capture_status().prop_map(Answer::Capture),
        segment().prop_map(Answer::Segment),
        identify_line().prop_map(Answer::Identify),
        (
            proptest::option::of(commission_step()),
            any::<bool>(),
            any::<u32>()
        )
            .prop_map(
                |(step, ending, records)| Answer::Commission(CommissionView {
                    step,
                    ending,
                    records
                })
            ),
        answer_error().prop_map(Answer::Error),
        (
            prop_oneof![
                Just(ModelOf::Draft),
                proptest::sample::select(<ModelSource as Token>::ALL.to_vec())
                    .prop_map(ModelOf::Active)
            ],
            rig_params()
        )
            .prop_map(|(of, params)| Answer::Model(ModelView { of, params })),
        (any::<bool>(), calibration())
            .prop_map(|(draft, calibration)| Answer::Calib(CalibView { draft, calibration })),
        (
            store_state(),
            any::<u32>(),
            proptest::option::of(any::<u32>())
        )
            .prop_map(|(state, saves, hash)| Answer::Store(StoreView {
                state,
                saves,
                hash
            })),
    ]
}

fn cycle() -> impl Strategy<Value = CycleTelemetry> {
    (
        (
            state(),
            dec(4, 0.0, 999.9),
            dec(3, 0.0, 9_999.0),
            any::<u8>(),
        ),
        (dec(1, 0.0, 999_999.0), dec(5, 0.0, 99.99999)),
        (regime(), fault(), any::<u32>()),
    )
        .prop_map(
            |((state, freq_hz, amplitude_mm, impacts), (peak, impulse), (regime, fault, lost))| {
                let hit = impacts > 0;
                CycleTelemetry {
                    state,
                    freq_hz,
                    amplitude_mm,
                    impacts,
                    peak_n: if hit { peak } else { 0.0 },
                    impulse_n_s: if hit { impulse } else { 0.0 },
                    regime,
                    fault,
                    lost_cycles: lost,
                }
            },
        )
}

fn event() -> impl Strategy<Value = Event> {
    prop_oneof![
        (state(), state()).prop_map(|(from, to)| Event::State { from, to }),
        proptest::sample::select(Fault::ALL.to_vec()).prop_map(Event::Fault),
        // The target travels as its bits: any frequency.
        (0.0f32..999.9, target()).prop_map(|(t, mut tg)| {
            tg.target_hz = t;
            Event::ModelReady(tg)
        }),
        Just(Event::ModelFailed),
        (any::<u32>(), any::<u32>())
            .prop_map(|(samples, expected)| Event::SamplingStalled { samples, expected }),
    ]
}

fn record() -> impl Strategy<Value = AsyncRecord> {
    (
        any::<u32>(),
        any::<u64>(),
        prop_oneof![
            cycle().prop_map(AsyncKind::Cycle),
            event().prop_map(AsyncKind::Event)
        ],
    )
        .prop_map(|(seq, sample, kind)| AsyncRecord { seq, sample, kind })
}

fn request() -> impl Strategy<Value = Request> {
    prop_oneof![
        Just(Request::Id),
        Just(Request::Diag),
        Just(Request::Help),
        any::<bool>().prop_map(Request::Echo),
        prop_oneof![
            Just(Command::Status),
            Just(Command::Start),
            Just(Command::Stop),
            Just(Command::Tune),
            Just(Command::Clear),
            any::<bool>().prop_map(Command::Stream),
            rig().prop_map(Command::Rig),
            (0u32..=10_000_000).prop_map(|k| Command::Gap(k as f32 / 1e6)),
            (0u32..=10_000_000).prop_map(|k| Command::Freq(k as f32 / 1e4)),
            (0u32..=3_600_000).prop_map(|k| Command::LinkTimeout(k as f32 / 1e3)),
        ]
        .prop_map(Request::Control),
        prop_oneof![
            Just(CaptureCommand::Status),
            Just(CaptureCommand::Stop),
            (0..SEGMENTS as u16).prop_map(CaptureCommand::Get),
            Just(CaptureCommand::Identify),
            Just(CaptureCommand::Adopt),
            (100u32..=100_000, 10u32..=60_000).prop_map(|(l, s)| CaptureCommand::Arm {
                level_n: l as f32 / 1e3,
                seconds: s as f32 / 1e3
            }),
        ]
        .prop_map(Request::Capture),
        Just(Request::Model),
        prop_oneof![
            (
                proptest::sample::select(ModelField::ALL.to_vec()),
                any::<f64>().prop_filter("finite", |v| v.is_finite())
            )
                .prop_map(|(f, v)| ModelEdit::Set(f, v)),
            proptest::sample::select(ContactLawKind::ALL.to_vec()).prop_map(ModelEdit::Law),
            proptest::sample::select(SuspensionKind::ALL.to_vec()).prop_map(ModelEdit::Suspension),
        ]
        .prop_map(Request::EditModel),
        Just(Request::Calib),
        (
            proptest::sample::select(CalibField::ALL.to_vec()),
            any::<f32>().prop_filter("finite", |v| v.is_finite())
        )
            .prop_map(|(f, v)| Request::EditCalib(f, v)),
        proptest::sample::select(DraftCommand::ALL.to_vec()).prop_map(Request::Draft),
        Just(Request::Save),
        Just(Request::Revert),
        Just(Request::Store),
        Just(Request::Reset),
        proptest::sample::select(vec![
            CommissionCommand::Status,
            CommissionCommand::Start,
            CommissionCommand::Accept,
            CommissionCommand::Abort,
        ])
        .prop_map(Request::Commission),
    ]
}

/// The kind of answer a request gets, as docs/operator.md's console table gives it.
fn kind_wanted(r: &Request) -> String {
    match r {
        Request::Control(Command::Status) => "status".into(),
        // Every command and request by name, no wildcard: a new one stops the build here.
        Request::Control(
            Command::Start
            | Command::Stop
            | Command::Tune
            | Command::Clear
            | Command::Stream(_)
            | Command::Rig(_)
            | Command::Gap(_)
            | Command::Freq(_)
            | Command::LinkTimeout(_),
        )
        | Request::Echo(_) => "ok".into(),
        Request::Id => "id".into(),
        Request::Diag => "diag".into(),
        Request::Help => "help".into(),
        Request::Capture(CaptureCommand::Get(k)) => format!("segment {k}"),
        Request::Capture(CaptureCommand::Identify) => "identify".into(),
        // The draft's model line; the identification itself when it is not adopted.
        Request::Capture(CaptureCommand::Adopt) => "model|identify".into(),
        Request::Model | Request::EditModel(_) | Request::Draft(_) | Request::Revert => {
            "model".into()
        }
        Request::Calib | Request::EditCalib(..) => "calib".into(),
        Request::Save | Request::Store => "store".into(),
        Request::Reset => "ok".into(),
        Request::Commission(CommissionCommand::Accept) => "store".into(),
        Request::Commission(
            CommissionCommand::Status | CommissionCommand::Start | CommissionCommand::Abort,
        ) => "commission".into(),
        Request::Capture(
            CaptureCommand::Status | CaptureCommand::Stop | CaptureCommand::Arm { .. },
        ) => "capture".into(),
    }
}

/// The kind of an answer (not an error), by its text's first word.
fn kind_of_answer(a: &Answer) -> String {
    match a {
        Answer::Reply(Reply::Status(_)) => "status".into(),
        Answer::Segment(s) => format!("segment {}", s.k),
        a => {
            let text = a.to_string();
            let word = text.split([' ', ':']).next().unwrap_or("");
            match word {
                "commands" => "help".into(),
                w => w.into(),
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    #[test]
    fn every_reply_reads_back(a in answer(), tag in proptest::option::of(0u32..1_000_000_000)) {
        let text = a.to_string();
        prop_assert_eq!(text.parse::<Answer>(), Ok(a), "{}", text);
        let r = Response { tag, answer: a };
        let text = r.to_string();
        prop_assert_eq!(text.parse::<Response>(), Ok(r), "{}", text);
    }

    #[test]
    fn every_record_reads_back(r in record()) {
        let text = r.to_string();
        prop_assert_eq!(text.parse::<AsyncRecord>(), Ok(r), "{}", text);
    }

    #[test]
    fn every_request_reads_back(r in request()) {
        let text = r.to_string();
        prop_assert_eq!(parse(&text), Ok(r), "{}", text);
    }

    /// No reply is the text of a request, and no request reads as a reply: an echo of a request
    /// can never be taken for its answer (the desktop skips a line equal to its request).
    #[test]
    fn replies_and_requests_never_read_as_each_other(a in answer(), r in request()) {
        let reply = a.to_string();
        prop_assert!(parse(&reply).is_err(), "the reply `{}` reads as a request", reply);
        let line = r.to_string();
        prop_assert!(line.parse::<Answer>().is_err(), "the request `{}` reads as a reply", line);
    }

    /// What the rig's own service answers every request is of the request's kind
    /// (`Answer::answers`), and the same answer to a request of another kind is not (unless it
    /// is an error, which any request may get).
    #[test]
    fn the_service_answers_every_request_with_its_kind(r in request(), other in request()) {
        let mut controller = Controller::new(ControllerConfig::default(), RigId::Wires, 0.0).unwrap();
        let mut capture = Capture::new();
        let mut link = Link::new();
        let mut mem = vec![0u8; 2 * PAGE_BYTES];
        let mut store = Store::new(RamFlash::erased(&mut mem), 0..(2 * PAGE_BYTES) as u32).unwrap();
        let mut rig = Direct {
            controller: &mut controller,
            capture: &mut capture,
            board: BoardInfo {
                firmware: Version::of("0.0.0"),
                board: Board::Virtual,
                uptime_ms: 0,
                stack_hwm_bytes: 0,
                stack_size_bytes: 0,
                sample_gap_max_us: 0,
            },
            link: &mut link,
            store: &mut store,
            commission: &mut Commission::new(),
            reset: false,
        };
        let line = r.to_string();
        let a = console::answer(&mut rig, Line::Text(&line)).answer;
        prop_assert!(a.answers(&r), "`{}` answered `{}`", line, a);
        if !matches!(a, Answer::Error(_)) {
            let wanted = kind_wanted(&other);
            let kind = kind_of_answer(&a);
            prop_assert_eq!(a.answers(&other), wanted.split('|').any(|k| k == kind), "`{}` for `{}`", a, other);
        }
    }

    /// Any text is a reply, an error, or refused; never a panic.
    #[test]
    fn any_text_reads_or_is_refused(s in ".{0,200}") {
        let _ = s.parse::<Answer>();
        let _ = s.parse::<AsyncRecord>();
    }
}

#[test]
fn bad_numbers_are_refused_at_the_edge_and_named() {
    let t = "!T seq=41 t_s=12.3456 state=track freq_hz=3.7000 amp_mm=0.890 impacts=1 peak_n=95.4 \
             impulse_n_s=0.02851 regime=1/1 fault=none lost_cycles=0";
    assert!(t.parse::<AsyncRecord>().is_ok());
    for (bad, field) in [
        ("t_s=12.3456", "t_s=nan"),
        ("freq_hz=3.7000", "freq_hz=inf"),
        ("peak_n=95.4", "peak_n=1e308"),
        ("peak_n=95.4", "peak_n=-5.0"),
        ("impacts=1", "impacts=-1"),
        ("seq=41", "seq=4294967296"),
    ] {
        let line = t.replace(bad, field);
        let key: &'static str = Box::leak(
            field
                .split('=')
                .next()
                .unwrap()
                .to_string()
                .into_boxed_str(),
        );
        assert_eq!(
            line.parse::<AsyncRecord>(),
            Err(WireError::Bad(key)),
            "{line}"
        );
    }
    // A model-ready event: the target's bits within the same range as its text, in hex digits.
    let target = |bits: &str, hz: &str| {
        format!(
            "!E seq=7 t_s=1.0000 event=model-ready target_hz={hz} target_bits={bits} \
             band_hz=2.10..4.84 predicted_mg=32.85"
        )
    };
    let good = f32::to_bits(3.64);
    assert!(
        target(&format!("0x{good:08x}"), "3.6400")
            .parse::<AsyncRecord>()
            .is_ok()
    );
    let negative = f32::to_bits(-4e-5);
    assert_eq!(
        target(&format!("0x{negative:08x}"), "0.0000").parse::<AsyncRecord>(),
        Err(WireError::Bad("target_bits"))
    );
    assert_eq!(
        target(&format!("0x+{good:08x}"), "3.6400").parse::<AsyncRecord>(),
        Err(WireError::Bad("target_bits"))
    );
    // Peak given without impacts, and impacts without a peak.
    assert_eq!(
        t.replace("impacts=1", "impacts=0").parse::<AsyncRecord>(),
        Err(WireError::Mismatch("impacts"))
    );
    assert!(
        t.replace(" lost_cycles=0", "")
            .parse::<AsyncRecord>()
            .is_err()
    );
    assert_eq!(
        format!("{t} extra=1").parse::<AsyncRecord>(),
        Err(WireError::Trailing)
    );
    let id = "id firmware=0.1.0 board=rig rig=wires rig_hash=36fccdc0 store=empty gap_mm=0.00 \
              sample_rate_hz=10000 capture_rate_hz=100000 volts_per_n=0.01 offset_v=0.2 \
              adc_full_scale_v=3.3 mass_kg=0.298 freq_window_hz=1..30 slew_hz_per_s=0.5 \
              ramp_mm_per_s=0.5 force_limit_n=280";
    assert!(id.parse::<IdInfo>().is_ok());
    // Each field set to a bad value: (field, value, the error).
    let bad = |key: &'static str| WireError::Bad(key);
    for (key, value, err) in [
        ("volts_per_n", "0", bad("volts_per_n")),
        ("volts_per_n", "nan", bad("volts_per_n")),
        ("mass_kg", "0", bad("mass_kg")),
        (
            "sample_rate_hz",
            "5000",
            WireError::Mismatch("sample_rate_hz"),
        ),
        ("freq_window_hz", "30.00..1.00", bad("freq_window_hz")),
        ("rig_hash", "36fccdc", bad("rig_hash")),
        ("store", "lost", bad("store")),
        ("rig", "custom", bad("rig")),
    ] {
        let to = format!("{key}={value}");
        let line: String = id
            .split(' ')
            .map(|w| {
                if w.starts_with(&format!("{key}=")) {
                    to.as_str()
                } else {
                    w
                }
            })
            .collect::<Vec<_>>()
            .join(" ");
        assert_eq!(line.parse::<IdInfo>(), Err(err), "{to}");
    }
    let cap = format!(
        "capture state=done segments=3 samples=1200000 level_n=1.00 rate_hz=100000 \
         segment_len={} pre_trigger=32 max_segments=32",
        shared::capture::SEGMENT_LEN
    );
    assert!(cap.parse::<CaptureStatus>().is_ok());
    assert_eq!(
        cap.replace(" segments=3 ", " segments=100000 ")
            .parse::<CaptureStatus>(),
        Err(WireError::Bad("segments"))
    );
    assert_eq!(
        cap.replace(" segments=3 ", " segments=40 ")
            .parse::<CaptureStatus>(),
        Err(WireError::Mismatch("segments"))
    );
    assert_eq!(
        cap.replace("rate_hz=100000", "rate_hz=0")
            .parse::<CaptureStatus>(),
        Err(WireError::Mismatch("rate_hz"))
    );
    let seg = SegmentView {
        k: 2,
        start: 5,
        codes: [0x7ff; SEGMENT_LEN],
    }
    .to_string();
    assert_eq!(
        seg.replacen("7ff", "", 1).parse::<SegmentView>(),
        Err(WireError::Mismatch("codes"))
    );
    assert_eq!(
        seg.replace(&format!("n={SEGMENT_LEN}"), "n=100")
            .parse::<SegmentView>(),
        Err(WireError::Mismatch("n"))
    );
    assert_eq!(
        seg.replacen("7ff", "7fg", 1).parse::<SegmentView>(),
        Err(WireError::Bad("codes"))
    );
    // A model-ready event whose bits and text disagree.
    let ev = "!E seq=44 t_s=0.5000 event=model-ready target_hz=3.6404 target_bits=0x4068fcfc \
              band_hz=2.107..4.720 predicted_mg=32.76";
    assert!(ev.parse::<AsyncRecord>().is_ok());
    assert_eq!(
        ev.replace("3.6404", "3.7404").parse::<AsyncRecord>(),
        Err(WireError::Mismatch("target_bits"))
    );
    assert_eq!("ok sure".parse::<Answer>(), Err(WireError::Kind));
}

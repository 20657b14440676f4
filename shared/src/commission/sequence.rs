//! The sequence's state machine ([`Commission`]): started, accepted and aborted from the
//! console, advanced by [`Commission::poll`].

use heapless::Deque;

use super::progress::{
    EndReason, Numbered, Progress, SelectFailure, SelectOutcome, Step, VerifyFailure,
    VerifyOutcome, WaitFor,
};
use super::sensor::SensorCheck;
use super::{
    ACCEPT_WINDOW_S, DROP_QUIET_S, DROP_WINDOW_S, REST_SAMPLES, RigPieces, SELECT_TIMEOUT_S,
    STOP_TIMEOUT_S, TRIGGER_SIGMAS, VERIFY_FORCE_PCT, VERIFY_TIMEOUT_S, VERIFY_TRACK_S,
    identify_capture, release_height_mm, samples_in, store_active,
};
use crate::capture::DEFAULT_LEVEL_N;
use crate::control::{
    Command, Controller, ModelSource, ModelStatus, SAMPLE_RATE_HZ, Settings, State, Target,
};
use crate::observe::Regime;
use crate::store::SaveError;

/// Records waiting for the console.
const OUTBOX: usize = 4;

/// Where the sequence is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Phase {
    /// Not running.
    Off,
    /// Measuring the force at rest.
    Sensor {
        /// Last sample of the step.
        deadline: u64,
    },
    /// The capture waits for the drop.
    Drop {
        /// Last sample of the step.
        deadline: u64,
        /// Segments recorded at the last look, and the sample they were first seen at.
        segments: u16,
        /// That sample.
        since: u64,
    },
    /// The model task computes the identified model's target.
    Select {
        /// Last sample of the step.
        deadline: u64,
    },
    /// The drive ramps and tracks.
    Verify {
        /// Last sample of the step.
        deadline: u64,
        /// The sample tracking began at.
        tracking_since: Option<u64>,
    },
    /// The drive ramps down after a verification that passed.
    Stopping {
        /// Last sample of the step.
        deadline: u64,
    },
    /// Waiting for `commission accept`.
    Accept {
        /// Last sample of the window.
        deadline: u64,
    },
    /// Ending without storing: waits for the drive to be idle (a latched fault: for `clear`),
    /// then restores the settings the rig ran before.
    Closing {
        /// The step it ended at.
        at: Step,
        /// Why.
        reason: EndReason,
    },
}

impl Phase {
    /// The step it belongs to (`None`: off).
    pub fn step(&self) -> Option<Step> {
        Some(match self {
            Phase::Off => return None,
            Phase::Sensor { .. } => Step::Sensor,
            Phase::Drop { .. } => Step::Drop,
            Phase::Select { .. } => Step::Select,
            Phase::Verify { .. } | Phase::Stopping { .. } => Step::Verify,
            Phase::Accept { .. } => Step::Accept,
            Phase::Closing { at, .. } => *at,
        })
    }
}

/// Why a `commission` command was refused (nothing changed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommissionRefusal {
    /// `commission start` while a sequence runs (its step).
    Running(Step),
    /// `commission start` with the drive not idle.
    NotIdle(State),
    /// `commission start` with a fault latched.
    FaultLatched,
    /// `commission start` while a capture records.
    CaptureRunning,
    /// `commission start` with a draft open.
    DraftOpen,
    /// `commission accept` outside the accept step.
    NothingToAccept,
    /// `commission abort` with no sequence running.
    NotRunning,
    /// Another command while a sequence runs (its step): only reading, `stop`, `clear`,
    /// `link-timeout`, `stream`, `reset` and `commission …` are taken.
    Busy(Step),
}

/// The commissioning sequence.
#[derive(Debug, Clone)]
pub struct Commission {
    phase: Phase,
    /// The settings and the model's source before the sequence: back unless accepted.
    before: Option<(Settings, ModelSource)>,
    /// The previous model's target, as last seen before the identified model replaced it.
    before_target: Option<Target>,
    outbox: Deque<Numbered, OUTBOX>,
    seq: u32,
    /// Drop prompts given since power-up (the virtual rig releases its hammer on each).
    prompts: u32,
}

impl Default for Commission {
    fn default() -> Self {
        Self::new()
    }
}

impl Commission {
    /// Not running.
    pub const fn new() -> Self {
        Commission {
            phase: Phase::Off,
            before: None,
            before_target: None,
            outbox: Deque::new(),
            seq: 0,
            prompts: 0,
        }
    }

    /// Where it is.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Whether a sequence runs (the console then refuses what would disturb it).
    pub fn busy(&self) -> bool {
        self.phase != Phase::Off
    }

    /// Records made since power-up.
    pub fn records(&self) -> u32 {
        self.seq
    }

    /// Drop prompts given since power-up.
    pub fn prompts(&self) -> u32 {
        self.prompts
    }

    /// The oldest record not yet sent.
    pub fn peek(&self) -> Option<&Numbered> {
        self.outbox.front()
    }

    /// The records not yet sent, oldest first.
    pub fn unsent(&self) -> impl Iterator<Item = &Numbered> {
        self.outbox.iter()
    }

    /// Takes the oldest record (it was sent).
    pub fn pop(&mut self) -> Option<Numbered> {
        self.outbox.pop_front()
    }

    /// `commission start`: the drive idle, no fault, no capture recording, no draft open.
    ///
    /// # Errors
    /// [`CommissionRefusal`]; nothing changed.
    pub fn start(&mut self, rig: &mut impl RigPieces) -> Result<(), CommissionRefusal> {
        if let Some(step) = self.phase.step() {
            return Err(CommissionRefusal::Running(step));
        }
        if rig.capture(|c| c.active()) {
            return Err(CommissionRefusal::CaptureRunning);
        }
        let now = rig.controller(|c| {
            match c.state() {
                State::Idle => {}
                State::Fault => return Err(CommissionRefusal::FaultLatched),
                s => return Err(CommissionRefusal::NotIdle(s)),
            }
            if c.draft().is_some() {
                return Err(CommissionRefusal::DraftOpen);
            }
            self.before = Some((c.settings(), c.model().1.source));
            c.begin_rest_probe(REST_SAMPLES);
            Ok(c.samples())
        })?;
        self.before_target = None;
        self.phase = Phase::Sensor {
            deadline: now + 4 * u64::from(REST_SAMPLES),
        };
        self.emit(
            now,
            Progress::Wait(WaitFor::Rest {
                seconds: REST_SAMPLES as f32 / SAMPLE_RATE_HZ as f32,
            }),
        );
        Ok(())
    }

    /// `commission accept`: the commissioned model stored in flash.
    ///
    /// # Errors
    /// [`CommissionRefusal::NothingToAccept`] outside the accept step (nothing changed); a
    /// failed save ends the sequence (the record says why) and is `Ok` with the error.
    pub fn accept(
        &mut self,
        rig: &mut impl RigPieces,
    ) -> Result<Result<u32, SaveError>, CommissionRefusal> {
        let Phase::Accept { .. } = self.phase else {
            return Err(CommissionRefusal::NothingToAccept);
        };
        let now = rig.controller(|c| c.samples());
        let saved = store_active(rig);
        match saved {
            Ok(saves) => {
                let hash = rig.controller(|c| c.model().1.hash);
                self.before = None;
                self.phase = Phase::Off;
                self.emit(now, Progress::Stored { saves, hash });
            }
            Err(e) => self.close(rig, Step::Accept, EndReason::SaveFailed(e)),
        }
        Ok(saved)
    }

    /// `commission abort`: the sequence ends at once (the drive ramps to zero), nothing stored.
    ///
    /// # Errors
    /// [`CommissionRefusal::NotRunning`].
    pub fn abort(&mut self, rig: &mut impl RigPieces) -> Result<(), CommissionRefusal> {
        match self.phase {
            Phase::Off => Err(CommissionRefusal::NotRunning),
            // Already ending: an abort changes nothing.
            Phase::Closing { .. } => Ok(()),
            p => {
                let at = p.step().unwrap_or(Step::Sensor);
                self.close(rig, at, EndReason::Aborted);
                Ok(())
            }
        }
    }

    /// Advances the sequence: checks the step under way, moves on when it is done.
    pub fn poll(&mut self, rig: &mut impl RigPieces) {
        let (now, state, fault, model) =
            rig.controller(|c| (c.samples(), c.state(), c.fault(), c.status().model));
        // A fault ends every step; the verification reports it in its own line.
        if let Some(f) = fault {
            match self.phase {
                Phase::Off | Phase::Closing { .. } => {}
                Phase::Verify { .. } | Phase::Stopping { .. } => {
                    let outcome = self.measure(rig, Some(VerifyFailure::Fault(f)));
                    self.emit(now, Progress::Verify(outcome));
                    self.close(rig, Step::Verify, EndReason::Fault(f));
                }
                p => self.close(rig, p.step().unwrap_or(Step::Sensor), EndReason::Fault(f)),
            }
        }
        if matches!(self.phase, Phase::Sensor { .. } | Phase::Drop { .. })
            && let ModelStatus::Ready(t) = model
        {
            self.before_target = Some(t);
        }
        match self.phase {
            Phase::Off => {}
            Phase::Sensor { deadline } => self.sensor(rig, now, deadline),
            Phase::Drop {
                deadline,
                segments,
                since,
            } => self.drop_test(rig, now, deadline, segments, since),
            Phase::Select { deadline } => self.select(rig, now, deadline, model),
            Phase::Verify {
                deadline,
                tracking_since,
            } => self.verify(rig, now, deadline, tracking_since, state),
            Phase::Stopping { deadline } => {
                if state == State::Idle {
                    self.phase = Phase::Accept {
                        deadline: now + samples_in(ACCEPT_WINDOW_S),
                    };
                    self.emit(
                        now,
                        Progress::Wait(WaitFor::Accept {
                            window_s: ACCEPT_WINDOW_S,
                        }),
                    );
                } else if now > deadline {
                    self.close(rig, Step::Verify, EndReason::Timeout);
                }
            }
            Phase::Accept { deadline } => {
                if now > deadline {
                    self.close(rig, Step::Accept, EndReason::Timeout);
                }
            }
            Phase::Closing { at, reason } => self.finish_closing(rig, now, at, reason),
        }
    }

    fn sensor(&mut self, rig: &mut impl RigPieces, now: u64, deadline: u64) {
        let Some(stats) = rig.controller(|c| c.rest_stats()) else {
            if now > deadline {
                self.close(rig, Step::Sensor, EndReason::Timeout);
            }
            return;
        };
        let (check, sensor) = rig.controller(|c| {
            c.end_rest_probe();
            let config = c.config();
            (
                SensorCheck::of(&stats, &config.sensor, &config.faults),
                config.sensor,
            )
        });
        self.emit(now, Progress::Sensor(check));
        if check.failure.is_some() {
            self.close(rig, Step::Sensor, EndReason::Failed);
            return;
        }
        let release_mm = rig.controller(|c| release_height_mm(c.model().0, sensor.max_force_n()));
        let level_n = (TRIGGER_SIGMAS * check.noise_n).max(DEFAULT_LEVEL_N);
        rig.capture(|c| c.arm(&sensor, level_n, DROP_WINDOW_S));
        self.prompts = self.prompts.wrapping_add(1);
        self.phase = Phase::Drop {
            deadline: now + samples_in(DROP_WINDOW_S + 5.0),
            segments: 0,
            since: now,
        };
        self.emit(
            now,
            Progress::Wait(WaitFor::Release {
                release_mm,
                window_s: DROP_WINDOW_S,
            }),
        );
    }

    fn drop_test(
        &mut self,
        rig: &mut impl RigPieces,
        now: u64,
        deadline: u64,
        segments: u16,
        since: u64,
    ) {
        let (active, recorded) = rig.capture(|c| (c.active(), c.status().segments));
        if active {
            if now > deadline {
                self.close(rig, Step::Drop, EndReason::Timeout);
                return;
            }
            if recorded != segments {
                self.phase = Phase::Drop {
                    deadline,
                    segments: recorded,
                    since: now,
                };
                return;
            }
            if recorded == 0 || now <= since + samples_in(DROP_QUIET_S) {
                return;
            }
            // The train is over: no impact for a while (the capture would run to the
            // window's end).
            rig.capture(|c| c.stop());
        }
        let id = identify_capture(rig);
        self.emit(now, Progress::Drop(id));
        let id = match id {
            Ok(id) if id.law_fits() => id,
            _ => {
                self.close(rig, Step::Drop, EndReason::Failed);
                return;
            }
        };
        // The identified model active; a manual frequency forgotten, so that `start` tracks
        // from the target.
        let applied = rig.controller(|c| {
            let params = id
                .applied_to(c.model().0)
                .map_err(crate::control::SettingsError::Invalid)?;
            c.draft_model(params)?;
            c.apply_draft()?;
            c.execute(Command::Tune)
                .map_err(crate::control::SettingsError::Command)?;
            Ok::<(), crate::control::SettingsError>(())
        });
        if applied.is_err() {
            self.close(rig, Step::Drop, EndReason::Failed);
            return;
        }
        self.phase = Phase::Select {
            deadline: now + samples_in(SELECT_TIMEOUT_S),
        };
        self.emit(now, Progress::Wait(WaitFor::Model));
    }

    fn select(&mut self, rig: &mut impl RigPieces, now: u64, deadline: u64, model: ModelStatus) {
        let target = match model {
            ModelStatus::Pending if now > deadline => {
                self.close(rig, Step::Select, EndReason::Timeout);
                return;
            }
            ModelStatus::Pending => return,
            ModelStatus::Failed => None,
            ModelStatus::Ready(t) => Some(t),
        };
        let (limits, weight_n) = rig.controller(|c| (c.config().limits, c.model().0.weight_n()));
        let failure = match target {
            None => Some(SelectFailure::NoTarget),
            Some(t) if !(limits.freq_min_hz..=limits.freq_max_hz).contains(&t.target_hz) => {
                Some(SelectFailure::Window)
            }
            Some(t)
                if f64::from(t.impact_force_mg) * weight_n > f64::from(limits.force_limit_n) =>
            {
                Some(SelectFailure::ForceLimit)
            }
            Some(_) => None,
        };
        self.emit(
            now,
            Progress::Select(SelectOutcome {
                target,
                before: self.before_target,
                failure,
            }),
        );
        let (Some(t), None) = (target, failure) else {
            self.close(rig, Step::Select, EndReason::Failed);
            return;
        };
        if rig.controller(|c| c.execute(Command::Start)).is_err() {
            // A fault it tripped is reported by the next poll.
            self.close(rig, Step::Select, EndReason::Failed);
            return;
        }
        self.phase = Phase::Verify {
            deadline: now + samples_in(VERIFY_TIMEOUT_S),
            tracking_since: None,
        };
        self.emit(
            now,
            Progress::Wait(WaitFor::Drive {
                target_hz: t.target_hz,
            }),
        );
    }

    fn verify(
        &mut self,
        rig: &mut impl RigPieces,
        now: u64,
        deadline: u64,
        tracking_since: Option<u64>,
        state: State,
    ) {
        let failure = match state {
            State::Ramp => None,
            State::Track => {
                let since = tracking_since.unwrap_or(now);
                self.phase = Phase::Verify {
                    deadline,
                    tracking_since: Some(since),
                };
                if now < since + samples_in(VERIFY_TRACK_S) {
                    None
                } else {
                    let m = self.measure(rig, None);
                    let failure = if m.regime != Some(Regime::ONE_ONE) {
                        Some(VerifyFailure::Regime)
                    } else if !m
                        .force_vs_model_pct
                        .is_some_and(|p| p.abs() <= VERIFY_FORCE_PCT)
                    {
                        Some(VerifyFailure::Force)
                    } else {
                        None
                    };
                    let outcome = VerifyOutcome { failure, ..m };
                    self.emit(now, Progress::Verify(outcome));
                    match failure {
                        None => {
                            let _ = rig.controller(|c| c.execute(Command::Stop));
                            self.phase = Phase::Stopping {
                                deadline: now + samples_in(STOP_TIMEOUT_S),
                            };
                        }
                        Some(_) => self.close(rig, Step::Verify, EndReason::Failed),
                    }
                    return;
                }
            }
            // Faults are handled before; anything else is the drive leaving the test.
            _ => Some(VerifyFailure::Stopped),
        };
        let failure = failure.or((now > deadline).then_some(VerifyFailure::Timeout));
        if let Some(f) = failure {
            let outcome = self.measure(rig, Some(f));
            self.emit(now, Progress::Verify(outcome));
            let reason = if f == VerifyFailure::Timeout {
                EndReason::Timeout
            } else {
                EndReason::Failed
            };
            self.close(rig, Step::Verify, reason);
        }
    }

    /// What the controller measures now, with `failure`.
    fn measure(&self, rig: &mut impl RigPieces, failure: Option<VerifyFailure>) -> VerifyOutcome {
        let s = rig.controller(|c| c.status());
        VerifyOutcome {
            freq_hz: s.freq_hz,
            regime: s.regime,
            peak_n: s.peak.map(|p| p.n),
            force_vs_model_pct: s.force_vs_model_pct,
            failure,
        }
    }

    /// Ends the sequence without storing: the capture stopped, the probe ended, the drive
    /// ramping to zero; the settings come back once it is idle.
    fn close(&mut self, rig: &mut impl RigPieces, at: Step, reason: EndReason) {
        rig.capture(|c| {
            if c.active() {
                c.stop();
            }
        });
        rig.controller(|c| {
            c.end_rest_probe();
            let _ = c.execute(Command::Stop);
        });
        self.phase = Phase::Closing { at, reason };
        let now = rig.controller(|c| c.samples());
        self.finish_closing(rig, now, at, reason);
    }

    fn finish_closing(&mut self, rig: &mut impl RigPieces, now: u64, at: Step, reason: EndReason) {
        let before = self.before;
        let restored = rig.controller(|c| match c.state() {
            State::Idle => {
                restore(c, before);
                true
            }
            // A latched fault waits for the operator's `clear`.
            State::Fault | State::Stopping => false,
            // The drive runs (the sequence had started it): it ramps down.
            _ => {
                let _ = c.execute(Command::Stop);
                false
            }
        });
        if restored {
            self.before = None;
            self.phase = Phase::Off;
            self.emit(now, Progress::Kept { at, reason });
        }
    }

    fn emit(&mut self, now: u64, progress: Progress) {
        let n = Numbered {
            seq: self.seq,
            sample: now,
            progress,
        };
        self.seq = self.seq.wrapping_add(1);
        if self.outbox.is_full() {
            // Nobody reads the console: the oldest goes (its number shows the gap).
            let _ = self.outbox.pop_front();
        }
        let _ = self.outbox.push_back(n);
    }
}

/// The settings the rig ran before, back (only if they changed: an unchanged model is not
/// recomputed).
fn restore(c: &mut Controller, before: Option<(Settings, ModelSource)>) {
    let Some((settings, source)) = before else {
        return;
    };
    if c.settings() != settings || c.model().1.source != source {
        // They were the controller's own: they load again.
        let _ = c.load_settings(&settings, source);
    }
}

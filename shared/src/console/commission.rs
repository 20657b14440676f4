//! The commissioning's text ([`crate::commission`]): its records (`!C` lines, sent as the
//! sequence goes), the `commission` reply and the refusals.
//!
//! `!C seq=<n> sample=<n> step=<step> verdict=<verdict> <fields>`, one per prompt and verdict:
//!
//! - `step=sensor verdict=wait seconds=0.5`, then `step=sensor verdict=pass|fail
//!   [reason=lost|rail|offset|noise|rate] offset_n=… noise_n=… min_n=… max_n=… rate_hz=… lost=…`
//! - `step=drop verdict=wait release_mm=8 window_s=10`, then `step=drop verdict=pass|fail
//!   identify …` (the `capture identify` line: pass when the law fits)
//! - `step=select verdict=wait`, then `step=select verdict=pass|fail
//!   [reason=no-target|window|force-limit] target_hz=… band_hz=…
//!   predicted_mg=… before_target_hz=… before_band_hz=… before_predicted_mg=…` (`-`: none)
//! - `step=verify verdict=wait target_hz=…`, then `step=verify verdict=pass|fail
//!   [reason=regime|force|stopped|fault|timeout] [fault=<name>] freq_hz=… regime=…
//!   peak_n=… force_vs_model_pct=…`
//! - `step=accept verdict=wait window_s=600`
//! - the last: `step=end verdict=stored saves=… hash=…` or `step=end verdict=kept at=<step>
//!   reason=failed|aborted|fault|timeout|save-failed [fault=<name>] [error=<flash|storage|too-big>]`
//!
//! Every number is exact ([`Exact`]). The reply to `commission`, `commission start` and
//! `commission abort`: `commission step=<off|sensor|drop|select|verify|accept> ending=<yes|no>
//! records=<n>`.

use core::fmt;
use core::str::FromStr;

use super::decimal::{Exact, parse_exact};
use super::drop_id::IdentifyLine;
use super::fields::{Fields, WireError, range};
use super::token::{Token, read_regime, write_regime};
use crate::commission::{
    CommissionRefusal, EndReason, Numbered, Phase, Progress, SelectFailure, SelectOutcome,
    SensorCheck, SensorFailure, Step, VerifyFailure, VerifyOutcome, WaitFor,
};
use crate::control::{Fault, State, Target};
use crate::store::SaveError;

impl Token for Step {
    const ALL: &'static [Step] = &Step::ALL;
    fn token(self) -> &'static str {
        match self {
            Step::Sensor => "sensor",
            Step::Drop => "drop",
            Step::Select => "select",
            Step::Verify => "verify",
            Step::Accept => "accept",
        }
    }
}

impl Token for SensorFailure {
    const ALL: &'static [SensorFailure] = &[
        SensorFailure::Lost,
        SensorFailure::Rail,
        SensorFailure::Offset,
        SensorFailure::Noise,
        SensorFailure::Rate,
    ];
    fn token(self) -> &'static str {
        match self {
            SensorFailure::Lost => "lost",
            SensorFailure::Rail => "rail",
            SensorFailure::Offset => "offset",
            SensorFailure::Noise => "noise",
            SensorFailure::Rate => "rate",
        }
    }
}

impl Token for SelectFailure {
    const ALL: &'static [SelectFailure] = &[
        SelectFailure::NoTarget,
        SelectFailure::Window,
        SelectFailure::ForceLimit,
    ];
    fn token(self) -> &'static str {
        match self {
            SelectFailure::NoTarget => "no-target",
            SelectFailure::Window => "window",
            SelectFailure::ForceLimit => "force-limit",
        }
    }
}

impl Token for SaveError {
    const ALL: &'static [SaveError] = &[SaveError::Flash, SaveError::Storage, SaveError::TooBig];
    fn token(self) -> &'static str {
        match self {
            SaveError::Flash => "flash",
            SaveError::Storage => "storage",
            SaveError::TooBig => "too-big",
        }
    }
}

/// A verification failure's word, and its fault.
fn verify_reason(v: VerifyFailure) -> (&'static str, Option<Fault>) {
    match v {
        VerifyFailure::Regime => ("regime", None),
        VerifyFailure::Force => ("force", None),
        VerifyFailure::Stopped => ("stopped", None),
        VerifyFailure::Fault(f) => ("fault", Some(f)),
        VerifyFailure::Timeout => ("timeout", None),
    }
}

/// An end's word, its fault and its store error.
fn end_reason(r: EndReason) -> (&'static str, Option<Fault>, Option<SaveError>) {
    match r {
        EndReason::Failed => ("failed", None, None),
        EndReason::Aborted => ("aborted", None, None),
        EndReason::Fault(f) => ("fault", Some(f), None),
        EndReason::Timeout => ("timeout", None, None),
        EndReason::SaveFailed(e) => ("save-failed", None, Some(e)),
    }
}

/// A `!C` line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommissionLine(pub Numbered);

/// The start of every `!C` line.
pub const PREFIX: &str = "!C ";

struct Opt(Option<f32>);

impl fmt::Display for Opt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(x) => write!(f, "{}", Exact::f32(x)),
            None => f.write_str("-"),
        }
    }
}

struct Band(Option<[f32; 2]>);

impl fmt::Display for Band {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some([a, b]) => write!(f, "{}..{}", Exact::f32(a), Exact::f32(b)),
            None => f.write_str("-"),
        }
    }
}

fn pass(ok: bool) -> &'static str {
    if ok { "pass" } else { "fail" }
}

fn write_target(f: &mut fmt::Formatter<'_>, prefix: &str, t: Option<Target>) -> fmt::Result {
    write!(
        f,
        " {prefix}target_hz={} {prefix}band_hz={} {prefix}predicted_mg={}",
        Opt(t.map(|t| t.target_hz)),
        Band(t.map(|t| t.band_hz)),
        Opt(t.map(|t| t.impact_force_mg)),
    )
}

impl fmt::Display for CommissionLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = &self.0;
        let x = Exact::f32;
        write!(f, "{PREFIX}seq={} sample={} step=", n.seq, n.sample)?;
        match n.progress {
            Progress::Wait(w) => {
                write!(f, "{} verdict=wait", w.step().token())?;
                match w {
                    WaitFor::Rest { seconds } => write!(f, " seconds={}", x(seconds)),
                    WaitFor::Release {
                        release_mm,
                        window_s,
                    } => write!(f, " release_mm={} window_s={}", x(release_mm), x(window_s)),
                    WaitFor::Model => Ok(()),
                    WaitFor::Drive { target_hz } => write!(f, " target_hz={}", x(target_hz)),
                    WaitFor::Accept { window_s } => write!(f, " window_s={}", x(window_s)),
                }
            }
            Progress::Sensor(c) => {
                write!(f, "sensor verdict={}", pass(c.failure.is_none()))?;
                if let Some(r) = c.failure {
                    write!(f, " reason={}", r.token())?;
                }
                write!(
                    f,
                    " offset_n={} noise_n={} min_n={} max_n={} rate_hz={} lost={}",
                    x(c.offset_n),
                    x(c.noise_n),
                    x(c.min_n),
                    x(c.max_n),
                    x(c.rate_hz),
                    c.lost
                )
            }
            Progress::Drop(id) => {
                let ok = id.as_ref().is_ok_and(|i| i.law_fits());
                write!(f, "drop verdict={} {}", pass(ok), IdentifyLine(id))
            }
            Progress::Select(s) => {
                write!(f, "select verdict={}", pass(s.failure.is_none()))?;
                if let Some(r) = s.failure {
                    write!(f, " reason={}", r.token())?;
                }
                write_target(f, "", s.target)?;
                write_target(f, "before_", s.before)
            }
            Progress::Verify(v) => {
                write!(f, "verify verdict={}", pass(v.failure.is_none()))?;
                if let Some(r) = v.failure {
                    let (word, fault) = verify_reason(r);
                    write!(f, " reason={word}")?;
                    if let Some(fault) = fault {
                        write!(f, " fault={}", fault.token())?;
                    }
                }
                write!(f, " freq_hz={} regime=", x(v.freq_hz))?;
                write_regime(f, v.regime)?;
                write!(
                    f,
                    " peak_n={} force_vs_model_pct={}",
                    Opt(v.peak_n),
                    Opt(v.force_vs_model_pct)
                )
            }
            Progress::Stored { saves, hash } => {
                write!(f, "end verdict=stored saves={saves} hash={hash:08x}")
            }
            Progress::Kept { at, reason } => {
                let (word, fault, error) = end_reason(reason);
                write!(f, "end verdict=kept at={} reason={word}", at.token())?;
                if let Some(fault) = fault {
                    write!(f, " fault={}", fault.token())?;
                }
                if let Some(e) = error {
                    write!(f, " error={}", e.token())?;
                }
                Ok(())
            }
        }
    }
}

/// `v` as an exact, finite `f32`.
fn finite(v: &str) -> Option<f32> {
    parse_exact(v).map(|x| x as f32).filter(|x| x.is_finite())
}

fn exact(w: &mut Fields<'_>, key: &'static str) -> Result<f32, WireError> {
    w.with(key, finite)
}

fn opt(w: &mut Fields<'_>, key: &'static str) -> Result<Option<f32>, WireError> {
    match w.raw(key)? {
        "-" => Ok(None),
        v => finite(v).map(Some).ok_or(WireError::Bad(key)),
    }
}

fn read_target(w: &mut Fields<'_>, keys: [&'static str; 3]) -> Result<Option<Target>, WireError> {
    let target_hz = opt(w, keys[0])?;
    let band = match w.raw(keys[1])? {
        "-" => None,
        v => Some(range(keys[1], v, f32::MIN, f32::MAX)?),
    };
    let mg = opt(w, keys[2])?;
    match (target_hz, band, mg) {
        (Some(target_hz), Some(band_hz), Some(impact_force_mg)) => Ok(Some(Target {
            target_hz,
            band_hz,
            impact_force_mg,
        })),
        (None, None, None) => Ok(None),
        _ => Err(WireError::Mismatch(keys[0])),
    }
}

impl FromStr for CommissionLine {
    type Err = WireError;

    /// Reads a `!C` line; its verdict must agree with its fields.
    fn from_str(s: &str) -> Result<Self, WireError> {
        let mut w = Fields::after(s, PREFIX)?;
        let seq = w.int("seq")?;
        let sample = w.int("sample")?;
        let step = w.raw("step")?;
        let progress = if step == "end" {
            read_end(&mut w)?
        } else {
            let step = Step::from_token(step).ok_or(WireError::Bad("step"))?;
            match w.raw("verdict")? {
                "wait" => Progress::Wait(read_wait(&mut w, step)?),
                "pass" => read_verdict(&mut w, step, s, true)?,
                "fail" => read_verdict(&mut w, step, s, false)?,
                _ => return Err(WireError::Bad("verdict")),
            }
        };
        if !matches!(progress, Progress::Drop(_)) {
            w.end()?;
        }
        Ok(CommissionLine(Numbered {
            seq,
            sample,
            progress,
        }))
    }
}

fn read_wait(w: &mut Fields<'_>, step: Step) -> Result<WaitFor, WireError> {
    Ok(match step {
        Step::Sensor => WaitFor::Rest {
            seconds: exact(w, "seconds")?,
        },
        Step::Drop => WaitFor::Release {
            release_mm: exact(w, "release_mm")?,
            window_s: exact(w, "window_s")?,
        },
        Step::Select => WaitFor::Model,
        Step::Verify => WaitFor::Drive {
            target_hz: exact(w, "target_hz")?,
        },
        Step::Accept => WaitFor::Accept {
            window_s: exact(w, "window_s")?,
        },
    })
}

fn read_verdict(
    w: &mut Fields<'_>,
    step: Step,
    line: &str,
    ok: bool,
) -> Result<Progress, WireError> {
    let progress = match step {
        Step::Sensor => {
            let failure = match w.optional("reason") {
                Some(r) => Some(SensorFailure::from_token(r).ok_or(WireError::Bad("reason"))?),
                None => None,
            };
            Progress::Sensor(SensorCheck {
                offset_n: exact(w, "offset_n")?,
                noise_n: exact(w, "noise_n")?,
                min_n: exact(w, "min_n")?,
                max_n: exact(w, "max_n")?,
                rate_hz: exact(w, "rate_hz")?,
                lost: w.int("lost")?,
                failure,
            })
        }
        Step::Drop => {
            // The rest of the line is the identify line.
            let at = line
                .find(" identify ")
                .ok_or(WireError::Missing("identify"))?;
            let id: IdentifyLine = line.get(at + 1..).unwrap_or("").parse()?;
            Progress::Drop(id.0)
        }
        Step::Select => Progress::Select(SelectOutcome {
            failure: match w.optional("reason") {
                Some(r) => Some(SelectFailure::from_token(r).ok_or(WireError::Bad("reason"))?),
                None => None,
            },
            target: read_target(w, ["target_hz", "band_hz", "predicted_mg"])?,
            before: read_target(
                w,
                ["before_target_hz", "before_band_hz", "before_predicted_mg"],
            )?,
        }),
        Step::Verify => {
            let failure = match w.optional("reason") {
                None => None,
                Some("regime") => Some(VerifyFailure::Regime),
                Some("force") => Some(VerifyFailure::Force),
                Some("stopped") => Some(VerifyFailure::Stopped),
                Some("timeout") => Some(VerifyFailure::Timeout),
                Some("fault") => Some(VerifyFailure::Fault(w.token("fault")?)),
                Some(_) => return Err(WireError::Bad("reason")),
            };
            Progress::Verify(VerifyOutcome {
                freq_hz: exact(w, "freq_hz")?,
                regime: w.with("regime", read_regime)?,
                peak_n: opt(w, "peak_n")?,
                force_vs_model_pct: opt(w, "force_vs_model_pct")?,
                failure,
            })
        }
        Step::Accept => return Err(WireError::Bad("verdict")),
    };
    let passed = match &progress {
        Progress::Sensor(c) => c.failure.is_none(),
        Progress::Drop(id) => id.as_ref().is_ok_and(|i| i.law_fits()),
        Progress::Select(s) => s.failure.is_none() && s.target.is_some(),
        Progress::Verify(v) => v.failure.is_none(),
        _ => ok,
    };
    if passed != ok {
        return Err(WireError::Mismatch("verdict"));
    }
    Ok(progress)
}

fn read_end(w: &mut Fields<'_>) -> Result<Progress, WireError> {
    match w.raw("verdict")? {
        "stored" => Ok(Progress::Stored {
            saves: w.int("saves")?,
            hash: w.with("hash", |h| {
                (h.len() == 8)
                    .then(|| u32::from_str_radix(h, 16).ok())
                    .flatten()
            })?,
        }),
        "kept" => {
            let at = w.token("at")?;
            let reason = match w.raw("reason")? {
                "failed" => EndReason::Failed,
                "aborted" => EndReason::Aborted,
                "timeout" => EndReason::Timeout,
                "fault" => EndReason::Fault(w.token("fault")?),
                "save-failed" => EndReason::SaveFailed(w.token("error")?),
                _ => return Err(WireError::Bad("reason")),
            };
            Ok(Progress::Kept { at, reason })
        }
        _ => Err(WireError::Bad("verdict")),
    }
}

/// The reply to `commission`, `commission start` and `commission abort`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CommissionView {
    /// The step under way (`None`: off).
    pub step: Option<Step>,
    /// Ending: the drive ramps down (or waits for `clear`) before the settings come back.
    pub ending: bool,
    /// Records made since power-up.
    pub records: u32,
}

impl CommissionView {
    /// The view of `phase` with `records` made.
    pub fn of(phase: Phase, records: u32) -> Self {
        CommissionView {
            step: phase.step(),
            ending: matches!(phase, Phase::Closing { .. }),
            records,
        }
    }
}

impl fmt::Display for CommissionView {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "commission step={} ending={} records={}",
            self.step.map_or("off", Step::token),
            if self.ending { "yes" } else { "no" },
            self.records
        )
    }
}

impl FromStr for CommissionView {
    type Err = WireError;
    fn from_str(s: &str) -> Result<Self, WireError> {
        let mut w = Fields::after(s, "commission ")?;
        let step = match w.raw("step")? {
            "off" => None,
            t => Some(Step::from_token(t).ok_or(WireError::Bad("step"))?),
        };
        let ending = match w.raw("ending")? {
            "yes" => true,
            "no" => false,
            _ => return Err(WireError::Bad("ending")),
        };
        let v = CommissionView {
            step,
            ending,
            records: w.int("records")?,
        };
        w.end()?;
        Ok(v)
    }
}

const RUNNING: &str = "commission: a sequence runs (step ";
const NOT_IDLE: &str = "commission: the drive must be idle (it is ";
const BUSY: &str = "commissioning (step ";
const BUSY_TAIL: &str = "): only reading, stop, clear, link-timeout, stream, reset and commission accept|abort are taken";
const FIXED: [(CommissionRefusal, &str); 5] = [
    (
        CommissionRefusal::FaultLatched,
        "commission: fault latched: clear first",
    ),
    (
        CommissionRefusal::CaptureRunning,
        "commission: a capture is recording: wait for it or `capture stop`",
    ),
    (
        CommissionRefusal::DraftOpen,
        "commission: a draft is open: `draft apply` or `draft discard` first",
    ),
    (
        CommissionRefusal::NothingToAccept,
        "commission: nothing to accept (the sequence has not passed its verification)",
    ),
    (
        CommissionRefusal::NotRunning,
        "commission: no sequence runs",
    ),
];

impl fmt::Display for CommissionRefusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CommissionRefusal::Running(s) => write!(f, "{RUNNING}{})", s.token()),
            CommissionRefusal::NotIdle(s) => write!(f, "{NOT_IDLE}{})", s.token()),
            CommissionRefusal::Busy(s) => write!(f, "{BUSY}{}{BUSY_TAIL}", s.token()),
            r => {
                let text = FIXED
                    .iter()
                    .find(|(k, _)| k == r)
                    .map_or("commission refused", |(_, t)| t);
                f.write_str(text)
            }
        }
    }
}

impl FromStr for CommissionRefusal {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        if let Some((r, _)) = FIXED.iter().find(|(_, t)| *t == s) {
            return Ok(*r);
        }
        if let Some(step) = s.strip_prefix(RUNNING).and_then(|r| r.strip_suffix(')')) {
            return Step::from_token(step)
                .map(CommissionRefusal::Running)
                .ok_or(());
        }
        if let Some(state) = s.strip_prefix(NOT_IDLE).and_then(|r| r.strip_suffix(')')) {
            return State::from_token(state)
                .map(CommissionRefusal::NotIdle)
                .ok_or(());
        }
        let step = s
            .strip_prefix(BUSY)
            .and_then(|r| r.strip_suffix(BUSY_TAIL))
            .ok_or(())?;
        Step::from_token(step)
            .map(CommissionRefusal::Busy)
            .ok_or(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::console::serve::ReplyText;
    use crate::identify::{DropIdentification, DropLaw, DropRefusal};
    use crate::observe::Regime;
    use std::string::ToString;

    fn id(fit_ratio: f32) -> DropIdentification {
        DropIdentification {
            impacts: 9,
            offset_n: -0.0123,
            noise_n: 0.19873,
            first_peak_n: 171.25,
            approach_speed_m_s: 0.3917,
            restitution: 0.71234,
            law: DropLaw::SpringDashpot {
                stiffness_n_m: 1.2345678e7,
                stiffness_pm_pct: 0.8123,
                damping_n_s_m: 123.45679,
                damping_pm_pct: 1.0712,
            },
            fit_ratio,
            suspension: Some(crate::identify::spacing::SuspensionId {
                natural_freq_hz: 2.2123456,
                spread_pct: 0.0123,
                damping_ratio: -0.0012345678,
                halves: 8,
            }),
        }
    }

    /// [`id`] with a Hunt–Crossley law (the longest `drop` line).
    fn id_power(fit_ratio: f32) -> DropIdentification {
        DropIdentification {
            law: DropLaw::HuntCrossley {
                stiffness: -2.1234567e-18,
                stiffness_pm_pct: 1.2345678e-12,
                exponent: 1.6006929,
                exponent_pm: 1.4104304e-13,
                lambda_s_m: 0.6002734,
                lambda_pm_pct: 4.9643776e-11,
            },
            ..id(fit_ratio)
        }
    }

    fn every_record() -> std::vec::Vec<Progress> {
        let target = Target {
            target_hz: 3.9314,
            band_hz: [2.1843, 4.7331],
            impact_force_mg: 68.12346,
        };
        let check = SensorCheck {
            offset_n: -0.0195,
            noise_n: 0.2013,
            min_n: -0.81,
            max_n: 0.77,
            rate_hz: 10_000.0,
            lost: 0,
            failure: None,
        };
        let verify = VerifyOutcome {
            freq_hz: 3.9733,
            regime: Some(Regime::ONE_ONE),
            peak_n: Some(201.03),
            force_vs_model_pct: Some(-2.4),
            failure: None,
        };
        let mut all = std::vec![
            Progress::Wait(WaitFor::Rest { seconds: 0.5 }),
            Progress::Wait(WaitFor::Release {
                release_mm: 8.0,
                window_s: 10.0
            }),
            Progress::Wait(WaitFor::Model),
            Progress::Wait(WaitFor::Drive { target_hz: 3.9314 }),
            Progress::Wait(WaitFor::Accept { window_s: 600.0 }),
            Progress::Sensor(check),
            Progress::Drop(Ok(id(0.9))),
            Progress::Drop(Ok(id(4.5))),
            Progress::Drop(Ok(id_power(1.0123457e-10))),
            Progress::Drop(Err(DropRefusal::NoImpacts)),
            Progress::Drop(Err(DropRefusal::Saturated { impact: 0 })),
            Progress::Select(SelectOutcome {
                target: Some(target),
                before: None,
                failure: None,
            }),
            Progress::Select(SelectOutcome {
                target: None,
                before: Some(target),
                failure: Some(SelectFailure::NoTarget),
            }),
            Progress::Select(SelectOutcome {
                target: Some(target),
                before: Some(target),
                failure: Some(SelectFailure::ForceLimit),
            }),
            Progress::Select(SelectOutcome {
                target: Some(target),
                before: Some(target),
                failure: Some(SelectFailure::Window),
            }),
            Progress::Verify(verify),
            Progress::Verify(VerifyOutcome {
                regime: None,
                peak_n: None,
                force_vs_model_pct: None,
                failure: Some(VerifyFailure::Fault(Fault::LinkLost)),
                ..verify
            }),
            Progress::Stored {
                saves: 3,
                hash: 0x0a1b_2c3d,
            },
        ];
        for failure in SensorFailure::ALL {
            all.push(Progress::Sensor(SensorCheck {
                failure: Some(*failure),
                ..check
            }));
        }
        for failure in [
            VerifyFailure::Regime,
            VerifyFailure::Force,
            VerifyFailure::Stopped,
            VerifyFailure::Timeout,
        ] {
            all.push(Progress::Verify(VerifyOutcome {
                failure: Some(failure),
                ..verify
            }));
        }
        for at in Step::ALL {
            for reason in [
                EndReason::Failed,
                EndReason::Aborted,
                EndReason::Timeout,
                EndReason::Fault(Fault::OverForce),
                EndReason::SaveFailed(SaveError::Flash),
            ] {
                all.push(Progress::Kept { at, reason });
            }
        }
        all
    }

    #[test]
    fn every_record_reads_back_and_fits_a_reply_line() {
        for (k, progress) in every_record().into_iter().enumerate() {
            let line = CommissionLine(Numbered {
                seq: u32::MAX - k as u32,
                sample: u64::MAX,
                progress,
            });
            let mut out = ReplyText::new();
            core::fmt::write(&mut out, format_args!("{line}"))
                .expect("fits a reply line (MAX_REPLY)");
            assert_eq!(out.parse::<CommissionLine>(), Ok(line), "{out}");
        }
        // A verdict that disagrees with its numbers does not read.
        let pass = CommissionLine(Numbered {
            seq: 1,
            sample: 2,
            progress: Progress::Drop(Ok(id(4.5))),
        })
        .to_string()
        .replace("verdict=fail identify", "verdict=pass identify");
        assert_eq!(
            pass.parse::<CommissionLine>(),
            Err(WireError::Mismatch("verdict"))
        );
        assert_eq!(
            "!C seq=1 sample=2 step=sensor verdict=wait seconds=0.5 x=1".parse::<CommissionLine>(),
            Err(WireError::Trailing)
        );
    }

    #[test]
    fn replies_and_refusals_read_back() {
        for step in [None, Some(Step::Verify)] {
            for ending in [false, true] {
                let v = CommissionView {
                    step,
                    ending,
                    records: 17,
                };
                assert_eq!(v.to_string().parse(), Ok(v));
            }
        }
        let mut all = std::vec![
            CommissionRefusal::FaultLatched,
            CommissionRefusal::CaptureRunning,
            CommissionRefusal::DraftOpen,
            CommissionRefusal::NothingToAccept,
            CommissionRefusal::NotRunning,
        ];
        for s in Step::ALL {
            all.push(CommissionRefusal::Running(s));
            all.push(CommissionRefusal::Busy(s));
        }
        for s in State::ALL {
            all.push(CommissionRefusal::NotIdle(s));
        }
        for r in all {
            assert_eq!(r.to_string().parse(), Ok(r), "{r}");
        }
        assert_eq!(
            CommissionRefusal::Busy(Step::Drop).to_string(),
            "commissioning (step drop): only reading, stop, clear, link-timeout, stream, reset and commission accept|abort are taken"
        );
    }
}

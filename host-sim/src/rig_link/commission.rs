//! `rig commission`: the board's own commissioning sequence run from the desktop — started,
//! followed record by record (one progress line per step's prompt and verdict), accepted or
//! declined. The sequence runs on the board (`shared::commission`); this side only talks.
//!
//! Interrupted (Ctrl-C, SIGTERM, a link error), the port sends `commission abort` as it closes,
//! then the drive guard's `stop`: the drive ramps to zero and the rig keeps the model it ran
//! before; nothing is stored unless accepted.

use std::time::Duration;

use anyhow::{Result, bail};
use shared::commission::{
    EndReason, Numbered, Progress, SelectFailure, SensorCheck, VerifyFailure, WaitFor,
};
use shared::console::commission::CommissionView;
use shared::console::{Answer, IdentifyLine, Token};
use shared::control::{Command, Target};
use shared::identify::DropLaw;

use super::{RigPort, escaped};

/// The longest silence between two records: the longest step's bound (the verification's
/// 120 s and its 60 s ramp down) and a margin.
pub const RECORD_WAIT: Duration = Duration::from_secs(240);

/// How the operator's decision is made at the accept step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// Accept (store) without asking.
    Accept,
    /// Keep the model the rig ran before, without asking.
    Decline,
    /// Ask on the terminal (`y` stores; anything else, or no answer within `wait`, keeps).
    Ask {
        /// How long the question waits.
        wait: Duration,
    },
}

/// How a commissioning ended: its last record, [`Progress::Stored`] or [`Progress::Kept`].
pub type Outcome = Progress;

/// Runs the sequence: `commission start`, each record to `on_record` as it comes, the accept
/// step decided by `decision`.
///
/// # Errors
/// `commission start` refused (the rig's reason), the link failed, a record did not come
/// within [`RECORD_WAIT`], a record lost on the way (its number skipped), Ctrl-C, or a fault
/// latched (the drive ramps to zero; the previous model comes back after `clear`).
pub fn commission(
    port: &mut RigPort,
    decision: Decision,
    mut on_record: impl FnMut(&Numbered),
) -> Result<Outcome> {
    // Telemetry on: the rig's own clock then keeps the link alive however fast it runs (a
    // virtual rig at 20× real time); the port turns it off as it closes.
    port.command(Command::Stream(true))?;
    let reply = port.send_line("commission start")?;
    match reply.parse::<Answer>() {
        Ok(Answer::Commission(CommissionView { step: Some(_), .. })) => {}
        _ => {
            return Err(port.refuse(anyhow::anyhow!(
                "the rig refused `commission start`: {}",
                escaped(&reply)
            )));
        }
    }
    port.abort_commission_on_close(true);
    let mut expected: Option<u32> = None;
    loop {
        let Some(n) = port.next_commission(RECORD_WAIT)? else {
            bail!(
                "no commissioning record for {} s: the rig stopped reporting",
                RECORD_WAIT.as_secs()
            );
        };
        if let Some(e) = expected
            && n.seq != e
        {
            bail!(
                "commissioning record {e} was lost on the way (record {} came): the sequence \
                 cannot be followed",
                n.seq
            );
        }
        expected = Some(n.seq.wrapping_add(1));
        on_record(&n);
        match n.progress {
            Progress::Wait(WaitFor::Accept { .. }) => {
                let yes = match decision {
                    Decision::Accept => true,
                    Decision::Decline => false,
                    Decision::Ask { wait } => ask(port, wait)?,
                };
                let line = if yes {
                    "commission accept"
                } else {
                    "commission abort"
                };
                let reply = port.send_line(line)?;
                if matches!(reply.parse::<Answer>(), Ok(Answer::Error(_)) | Err(_)) {
                    bail!("`{line}` answered `{}`", escaped(&reply));
                }
            }
            Progress::Verify(v) => {
                if let Some(VerifyFailure::Fault(f)) = v.failure {
                    // The sequence ends once the operator clears the fault.
                    port.abort_commission_on_close(false);
                    bail!(
                        "the rig latched fault `{}` during the verification: its drive ramps to \
                         zero; after `clear` (rig send clear) it runs the model it ran before",
                        f.token()
                    );
                }
            }
            Progress::Stored { .. } => {
                port.abort_commission_on_close(false);
                return Ok(n.progress);
            }
            Progress::Kept { at, reason } => {
                port.abort_commission_on_close(false);
                if let EndReason::Fault(f) = reason {
                    bail!(
                        "the rig latched fault `{}` at step {}: nothing stored; `clear` \
                         (rig send clear) before the next run",
                        f.token(),
                        at.token()
                    );
                }
                return Ok(n.progress);
            }
            _ => {}
        }
    }
}

/// The operator's answer on the terminal, waiting at most `wait` (the link kept alive).
fn ask(port: &mut RigPort, wait: Duration) -> Result<bool> {
    use std::io::BufRead as _;
    eprint!("store this model in the rig's flash? [y/N] ");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = std::io::stdin().lock().read_line(&mut line);
        let _ = tx.send(line);
    });
    let end = std::time::Instant::now() + wait;
    loop {
        // Keeps the link alive and sees Ctrl-C.
        if let Some(n) = port.next_commission(Duration::from_millis(100))? {
            bail!(
                "the rig sent a record while it waited for the answer: {}",
                describe(&n.progress)
            );
        }
        match rx.try_recv() {
            Ok(line) => return Ok(line.trim().eq_ignore_ascii_case("y")),
            Err(std::sync::mpsc::TryRecvError::Disconnected) => return Ok(false),
            Err(std::sync::mpsc::TryRecvError::Empty) => {}
        }
        if std::time::Instant::now() >= end {
            eprintln!("(no answer: keeping the model the rig ran before)");
            return Ok(false);
        }
    }
}

fn target(t: Option<Target>) -> String {
    t.map_or_else(
        || "none".to_string(),
        |t| {
            format!(
                "{:.4} Hz (1/1 band {:.3}..{:.3} Hz, F_i/mg {:.2})",
                t.target_hz, t.band_hz[0], t.band_hz[1], t.impact_force_mg
            )
        },
    )
}

fn sensor(c: &SensorCheck) -> String {
    format!(
        "offset {:+.3} N, noise {:.3} N, range {:.2}..{:.2} N, {:.1} Hz, {} lost",
        c.offset_n, c.noise_n, c.min_n, c.max_n, c.rate_hz, c.lost
    )
}

/// A record as the operator reads it (one line; the `!C` line has every number exact).
pub fn describe(p: &Progress) -> String {
    match p {
        Progress::Wait(w) => match w {
            WaitFor::Rest { seconds } => {
                format!(
                    "sensor: measuring the force at rest for {seconds} s: keep the hammer still"
                )
            }
            WaitFor::Release {
                release_mm,
                window_s,
            } => format!(
                "drop: RELEASE THE HAMMER from {release_mm} mm above the surface within {window_s} s"
            ),
            WaitFor::Model => "select: the board computes the identified model's target".into(),
            WaitFor::Drive { target_hz } => {
                format!("verify: the drive ramps up at {target_hz:.4} Hz and tracks")
            }
            WaitFor::Accept { window_s } => format!(
                "accept: `commission accept` stores the model (within {window_s} s); \
                 `commission abort` keeps the previous one"
            ),
        },
        Progress::Sensor(c) => match c.failure {
            None => format!("sensor: pass: {}", sensor(c)),
            Some(f) => format!("sensor: FAIL ({}): {}", f.token(), sensor(c)),
        },
        Progress::Drop(id) => {
            let line = IdentifyLine(*id).to_string();
            match id {
                Ok(i) => {
                    let s = i.suspension.map_or(String::new(), |s| {
                        format!(
                            ", f_n {:.4} Hz (spread {:.2} %), ζ {:.4}",
                            s.natural_freq_hz, s.spread_pct, s.damping_ratio
                        )
                    });
                    let law = match i.law {
                        DropLaw::SpringDashpot {
                            stiffness_n_m,
                            stiffness_pm_pct,
                            damping_n_s_m,
                            damping_pm_pct,
                        } => format!(
                            "spring–dashpot k_i {stiffness_n_m:.4e} N/m (±{stiffness_pm_pct:.1} %), \
                             c_i {damping_n_s_m:.4} N·s/m (±{damping_pm_pct:.1} %)"
                        ),
                        DropLaw::HuntCrossley {
                            stiffness,
                            stiffness_pm_pct,
                            exponent,
                            exponent_pm,
                            lambda_s_m,
                            lambda_pm_pct,
                        } => format!(
                            "Hunt–Crossley k_i {stiffness:.4e} N/m^n (±{stiffness_pm_pct:.1} %), \
                             n {exponent:.4} (±{exponent_pm:.4}), λ_i {lambda_s_m:.4} s/m \
                             (±{lambda_pm_pct:.1} %)"
                        ),
                    };
                    format!(
                        "drop: {}: {} impacts, {law}, fit ratio {:.2}{s}",
                        if i.law_fits() {
                            "pass"
                        } else {
                            "FAIL (misfit)"
                        },
                        i.impacts,
                        i.fit_ratio
                    )
                }
                Err(_) => format!("drop: FAIL: {line}"),
            }
        }
        Progress::Select(s) => format!(
            "select: {}: target {}; the model before: {}",
            match s.failure {
                None => "pass",
                Some(SelectFailure::NoTarget) => "FAIL (no robust 1/1 target)",
                Some(SelectFailure::Window) => "FAIL (the target is outside the drive's window)",
                Some(SelectFailure::ForceLimit) =>
                    "FAIL (the predicted impact force exceeds the force limit)",
            },
            target(s.target),
            target(s.before)
        ),
        Progress::Verify(v) => {
            let verdict = match v.failure {
                None => "pass".to_string(),
                Some(f) => format!(
                    "FAIL ({})",
                    match f {
                        VerifyFailure::Regime => "regime not 1/1".to_string(),
                        VerifyFailure::Force => "peak force off the prediction".to_string(),
                        VerifyFailure::Stopped => "the drive was stopped".to_string(),
                        VerifyFailure::Fault(f) => format!("fault {}", f.token()),
                        VerifyFailure::Timeout => "no tracking in time".to_string(),
                    }
                ),
            };
            format!(
                "verify: {verdict}: {} at {:.4} Hz, peak {}, {} vs the model",
                v.regime.map_or("-".to_string(), |r| r.to_string()),
                v.freq_hz,
                v.peak_n.map_or("-".to_string(), |n| format!("{n:.1} N")),
                v.force_vs_model_pct
                    .map_or("-".to_string(), |p| format!("{p:+.1} %"))
            )
        }
        Progress::Stored { saves, hash } => {
            format!("done: model {hash:08x} stored in the rig's flash (save {saves})")
        }
        Progress::Kept { at, reason } => format!(
            "done: nothing stored; the rig runs the model it ran before (ended at {}: {})",
            at.token(),
            why(*reason)
        ),
    }
}

/// Why a sequence ended without storing, in words.
fn why(reason: EndReason) -> String {
    match reason {
        EndReason::Failed => "the step failed".to_string(),
        EndReason::Aborted => "declined or aborted".to_string(),
        EndReason::Fault(f) => format!("fault {}", f.token()),
        EndReason::Timeout => "the step overran its bound".to_string(),
        EndReason::SaveFailed(e) => format!("the save failed ({})", e.token()),
    }
}

/// The outcome as the command's last line.
pub fn summary(o: &Outcome) -> String {
    match o {
        Progress::Stored { saves, hash } => {
            format!("commissioned: model {hash:08x} stored (save {saves})")
        }
        Progress::Kept { at, reason } => format!(
            "not commissioned: ended at {} ({})",
            at.token(),
            why(*reason)
        ),
        other => describe(other),
    }
}

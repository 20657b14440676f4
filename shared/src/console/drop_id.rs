//! The `identify` line: what the board's drop identification ([`crate::identify`]) made of
//! the last capture, or why it refused it. Every number is exact ([`Exact`]): the desktop reads
//! the board's `f32` bits.
//!
//! `identify verdict=fits|misfit impacts=… offset_n=… noise_n=… peak_n=… approach_m_s=…
//! restitution=… law=spring-dashpot k_i=… k_i_pm_pct=… c_i=… c_i_pm_pct=… fit_ratio=…
//! [f_n_hz=… f_n_spread_pct=… zeta=… halves=…]` (the suspension's fields at gap 0 only; for a
//! Hunt–Crossley law `law=hunt-crossley k_i=… k_i_pm_pct=… n=… n_pm=… lambda_i=…
//! lambda_i_pm_pct=…` in place of the spring–dashpot's four), or
//! `identify verdict=refused reason=<word> [its fields]`.

use core::fmt;
use core::str::FromStr;

use super::decimal::{Exact, parse_exact};
use super::fields::{Fields, WireError};
use crate::identify::spacing::SuspensionId;
use crate::identify::{DropIdentification, DropLaw, DropRefusal};
use crate::model::ContactLawKind;

/// The answer to `capture identify`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifyLine(pub Result<DropIdentification, DropRefusal>);

/// A refusal's word (`reason=`).
fn reason(r: &DropRefusal) -> &'static str {
    match r {
        DropRefusal::NoImpacts => "no-impacts",
        DropRefusal::TooFewImpacts { .. } => "too-few-impacts",
        DropRefusal::LostSamples { .. } => "lost-samples",
        DropRefusal::Saturated { .. } => "saturated",
        DropRefusal::Clipped { .. } => "clipped",
        DropRefusal::ShortPulse { .. } => "short-pulse",
        DropRefusal::RestlessBaseline { .. } => "restless-baseline",
        DropRefusal::IrregularSpacing { .. } => "irregular-spacing",
        DropRefusal::TrainStopped { .. } => "train-stopped",
        DropRefusal::SecondTrain { .. } => "second-train",
        DropRefusal::NotIdentifiable => "not-identifiable",
        DropRefusal::BadMass => "bad-mass",
    }
}

impl fmt::Display for IdentifyLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = Exact::f32;
        match &self.0 {
            Ok(id) => {
                write!(
                    f,
                    "identify verdict={} impacts={} offset_n={} noise_n={} peak_n={} \
                     approach_m_s={} restitution={} law={} ",
                    if id.law_fits() { "fits" } else { "misfit" },
                    id.impacts,
                    x(id.offset_n),
                    x(id.noise_n),
                    x(id.first_peak_n),
                    x(id.approach_speed_m_s),
                    x(id.restitution),
                    law_kind(&id.law).name(),
                )?;
                match id.law {
                    DropLaw::SpringDashpot {
                        stiffness_n_m,
                        stiffness_pm_pct,
                        damping_n_s_m,
                        damping_pm_pct,
                    } => write!(
                        f,
                        "k_i={} k_i_pm_pct={} c_i={} c_i_pm_pct={}",
                        x(stiffness_n_m),
                        x(stiffness_pm_pct),
                        x(damping_n_s_m),
                        x(damping_pm_pct),
                    )?,
                    DropLaw::HuntCrossley {
                        stiffness,
                        stiffness_pm_pct,
                        exponent,
                        exponent_pm,
                        lambda_s_m,
                        lambda_pm_pct,
                    } => write!(
                        f,
                        "k_i={} k_i_pm_pct={} n={} n_pm={} lambda_i={} lambda_i_pm_pct={}",
                        x(stiffness),
                        x(stiffness_pm_pct),
                        x(exponent),
                        x(exponent_pm),
                        x(lambda_s_m),
                        x(lambda_pm_pct),
                    )?,
                }
                write!(f, " fit_ratio={}", x(id.fit_ratio))?;
                if let Some(s) = id.suspension {
                    write!(
                        f,
                        " f_n_hz={} f_n_spread_pct={} zeta={} halves={}",
                        x(s.natural_freq_hz),
                        x(s.spread_pct),
                        x(s.damping_ratio),
                        s.halves
                    )?;
                }
                Ok(())
            }
            Err(r) => {
                write!(f, "identify verdict=refused reason={}", reason(r))?;
                match *r {
                    DropRefusal::NoImpacts
                    | DropRefusal::NotIdentifiable
                    | DropRefusal::BadMass => Ok(()),
                    DropRefusal::TooFewImpacts { found } => write!(f, " found={found}"),
                    DropRefusal::LostSamples { lost } => write!(f, " lost={lost}"),
                    DropRefusal::Saturated { impact } | DropRefusal::Clipped { impact } => {
                        write!(f, " impact={impact}")
                    }
                    DropRefusal::ShortPulse { impact, samples } => {
                        write!(f, " impact={impact} samples={samples}")
                    }
                    DropRefusal::RestlessBaseline {
                        impact,
                        noise_n,
                        typical_n,
                    } => write!(
                        f,
                        " impact={impact} noise_n={} typical_n={}",
                        x(noise_n),
                        x(typical_n)
                    ),
                    DropRefusal::IrregularSpacing {
                        impact,
                        spacing_ms,
                        expected_ms,
                    } => write!(
                        f,
                        " impact={impact} spacing_ms={} expected_ms={}",
                        x(spacing_ms),
                        x(expected_ms)
                    ),
                    DropRefusal::TrainStopped {
                        impacts,
                        expected_n,
                    } => write!(f, " impacts={impacts} expected_n={}", x(expected_n)),
                    DropRefusal::SecondTrain { impact, peak_n } => {
                        write!(f, " impact={impact} peak_n={}", x(peak_n))
                    }
                }
            }
        }
    }
}

/// `v` as an exact, finite `f32`.
fn finite(v: &str) -> Option<f32> {
    parse_exact(v).map(|x| x as f32).filter(|x| x.is_finite())
}

/// The next field `key` as an exact, finite `f32`.
fn exact(w: &mut Fields<'_>, key: &'static str) -> Result<f32, WireError> {
    w.with(key, finite)
}

impl FromStr for IdentifyLine {
    type Err = WireError;

    /// Reads an `identify` line; `verdict` must agree with the fit ratio.
    fn from_str(s: &str) -> Result<Self, WireError> {
        let mut w = Fields::after(s, "identify ")?;
        let verdict = w.raw("verdict")?;
        if verdict == "refused" {
            let r = refusal(&mut w)?;
            w.end()?;
            return Ok(IdentifyLine(Err(r)));
        }
        let mut id = DropIdentification {
            impacts: w.int("impacts")?,
            offset_n: exact(&mut w, "offset_n")?,
            noise_n: exact(&mut w, "noise_n")?,
            first_peak_n: exact(&mut w, "peak_n")?,
            approach_speed_m_s: exact(&mut w, "approach_m_s")?,
            restitution: exact(&mut w, "restitution")?,
            law: law(&mut w)?,
            fit_ratio: exact(&mut w, "fit_ratio")?,
            suspension: None,
        };
        if let Some(v) = w.optional("f_n_hz") {
            let natural_freq_hz = finite(v).ok_or(WireError::Bad("f_n_hz"))?;
            id.suspension = Some(SuspensionId {
                natural_freq_hz,
                spread_pct: exact(&mut w, "f_n_spread_pct")?,
                damping_ratio: exact(&mut w, "zeta")?,
                halves: w.int("halves")?,
            });
        }
        w.end()?;
        let want = if id.law_fits() { "fits" } else { "misfit" };
        if verdict != want {
            return Err(WireError::Mismatch("verdict"));
        }
        Ok(IdentifyLine(Ok(id)))
    }
}

/// The identified law's kind (its `law=` word).
fn law_kind(law: &DropLaw) -> ContactLawKind {
    match law {
        DropLaw::SpringDashpot { .. } => ContactLawKind::SpringDashpot,
        DropLaw::HuntCrossley { .. } => ContactLawKind::HuntCrossley,
    }
}

/// `law=<name>` and its parameters.
fn law(w: &mut Fields<'_>) -> Result<DropLaw, WireError> {
    let name = w.raw("law")?;
    Ok(if name == ContactLawKind::SpringDashpot.name() {
        DropLaw::SpringDashpot {
            stiffness_n_m: exact(w, "k_i")?,
            stiffness_pm_pct: exact(w, "k_i_pm_pct")?,
            damping_n_s_m: exact(w, "c_i")?,
            damping_pm_pct: exact(w, "c_i_pm_pct")?,
        }
    } else if name == ContactLawKind::HuntCrossley.name() {
        DropLaw::HuntCrossley {
            stiffness: exact(w, "k_i")?,
            stiffness_pm_pct: exact(w, "k_i_pm_pct")?,
            exponent: exact(w, "n")?,
            exponent_pm: exact(w, "n_pm")?,
            lambda_s_m: exact(w, "lambda_i")?,
            lambda_pm_pct: exact(w, "lambda_i_pm_pct")?,
        }
    } else {
        return Err(WireError::Bad("law"));
    })
}

fn refusal(w: &mut Fields<'_>) -> Result<DropRefusal, WireError> {
    Ok(match w.raw("reason")? {
        "no-impacts" => DropRefusal::NoImpacts,
        "too-few-impacts" => DropRefusal::TooFewImpacts {
            found: w.int("found")?,
        },
        "lost-samples" => DropRefusal::LostSamples {
            lost: w.int("lost")?,
        },
        "saturated" => DropRefusal::Saturated {
            impact: w.int("impact")?,
        },
        "clipped" => DropRefusal::Clipped {
            impact: w.int("impact")?,
        },
        "short-pulse" => DropRefusal::ShortPulse {
            impact: w.int("impact")?,
            samples: w.int("samples")?,
        },
        "restless-baseline" => DropRefusal::RestlessBaseline {
            impact: w.int("impact")?,
            noise_n: exact(w, "noise_n")?,
            typical_n: exact(w, "typical_n")?,
        },
        "irregular-spacing" => DropRefusal::IrregularSpacing {
            impact: w.int("impact")?,
            spacing_ms: exact(w, "spacing_ms")?,
            expected_ms: exact(w, "expected_ms")?,
        },
        "train-stopped" => DropRefusal::TrainStopped {
            impacts: w.int("impacts")?,
            expected_n: exact(w, "expected_n")?,
        },
        "second-train" => DropRefusal::SecondTrain {
            impact: w.int("impact")?,
            peak_n: exact(w, "peak_n")?,
        },
        "not-identifiable" => DropRefusal::NotIdentifiable,
        "bad-mass" => DropRefusal::BadMass,
        _ => return Err(WireError::Bad("reason")),
    })
}

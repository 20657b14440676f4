//! The asynchronous lines while streaming ([`AsyncRecord`]'s text and its reading): `!T` (one
//! per drive cycle) and `!E` (one per event), with a sequence number that counts every line
//! produced (a gap on the desktop is a line lost) and the board's time:
//!
//! ```text
//! !T seq=41 t_s=12.3456 state=track freq_hz=3.7000 amp_mm=0.890 impacts=1 peak_n=95.4 impulse_n_s=0.02851 regime=1/1 fault=none lost_cycles=0
//! !E seq=42 t_s=12.3457 event=state from=ramp to=track
//! !E seq=43 t_s=15.1550 event=fault fault=sensor-open
//! !E seq=44 t_s=0.5000 event=model-ready target_hz=3.6650 target_bits=0x406a8e8f band_hz=2.184..4.733 predicted_mg=32.79
//! !E seq=45 t_s=0.5000 event=model-failed
//! !E seq=46 t_s=20.0000 event=stalled samples=5000 expected=10000
//! ```
//!
//! `t_s` is the controller's sample count over [`SAMPLE_RATE_HZ`] (exact with four decimals at
//! 10 kHz).

use core::fmt;
use core::str::FromStr;

use super::decimal::{Decimal, Exact, parse_exact};
use super::fields::{Fields, WireError, decimal};
use super::request::MAX_FREQ_HZ;
use super::token::{Token, read_fault, read_regime, write_fault, write_regime};
use crate::control::{
    AsyncKind, AsyncRecord, CycleTelemetry, Event, SAMPLE_RATE_HZ, State, Target,
};

/// Largest force or amplitude a line may report (far above any rig's).
const MAX_VALUE: f32 = 1e6;

/// Samples as seconds with four decimals, in integers (exact at 10 kHz).
struct SampleTime(u64);

const TICKS_PER_S: u64 = 10_000;

impl fmt::Display for SampleTime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rate = u64::from(SAMPLE_RATE_HZ);
        let frac = (self.0 % rate) * TICKS_PER_S / rate;
        write!(f, "{}.{:04}", self.0 / rate, frac)
    }
}

/// Reads [`SampleTime`]'s text back into samples (exact: `s.ffff`, four decimals).
fn read_sample_time(v: &str) -> Option<u64> {
    let (s, frac) = v.split_once('.')?;
    if frac.len() != 4 || !frac.bytes().all(|b| b.is_ascii_digit()) || s.is_empty() {
        return None;
    }
    if !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let (s, frac): (u64, u64) = (s.parse().ok()?, frac.parse().ok()?);
    let rate = u64::from(SAMPLE_RATE_HZ);
    s.checked_mul(rate)?.checked_add(frac * rate / TICKS_PER_S)
}

impl fmt::Display for AsyncRecord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let tag = match self.kind {
            AsyncKind::Cycle(_) => "!T",
            AsyncKind::Event(_) => "!E",
        };
        write!(f, "{tag} seq={} t_s={}", self.seq, SampleTime(self.sample))?;
        match self.kind {
            AsyncKind::Cycle(c) => {
                write!(
                    f,
                    " state={} freq_hz={} amp_mm={} impacts={}",
                    c.state.token(),
                    Decimal(c.freq_hz, 4),
                    Decimal(c.amplitude_mm, 3),
                    c.impacts
                )?;
                if c.impacts > 0 {
                    write!(
                        f,
                        " peak_n={} impulse_n_s={}",
                        Decimal(c.peak_n, 1),
                        Decimal(c.impulse_n_s, 5)
                    )?;
                } else {
                    f.write_str(" peak_n=- impulse_n_s=-")?;
                }
                f.write_str(" regime=")?;
                write_regime(f, c.regime)?;
                f.write_str(" fault=")?;
                write_fault(f, c.fault)?;
                write!(f, " lost_cycles={}", c.lost_cycles)
            }
            AsyncKind::Event(e) => match e {
                Event::State { from, to } => {
                    write!(f, " event=state from={} to={}", from.token(), to.token())
                }
                Event::Fault(fault) => write!(f, " event=fault fault={}", fault.token()),
                Event::ModelReady(t) => write!(
                    f,
                    " event=model-ready target_hz={} target_bits={:#010x} band_hz={}..{} predicted_mg={}",
                    Decimal(t.target_hz, 4),
                    t.target_hz.to_bits(),
                    Exact::f32(t.band_hz[0]),
                    Exact::f32(t.band_hz[1]),
                    Exact::f32(t.impact_force_mg)
                ),
                Event::ModelFailed => f.write_str(" event=model-failed"),
                Event::SamplingStalled { samples, expected } => {
                    write!(f, " event=stalled samples={samples} expected={expected}")
                }
            },
        }
    }
}

impl FromStr for AsyncRecord {
    type Err = WireError;

    /// Reads a `!T` or `!E` line; every number must be finite and in range.
    fn from_str(s: &str) -> Result<Self, WireError> {
        let (cycle, rest) = if let Some(r) = s.strip_prefix("!T ") {
            (true, r)
        } else if let Some(r) = s.strip_prefix("!E ") {
            (false, r)
        } else {
            return Err(WireError::Kind);
        };
        let mut w = Fields::new(rest);
        let seq = w.int("seq")?;
        let sample = w.with("t_s", read_sample_time)?;
        let kind = if cycle {
            AsyncKind::Cycle(cycle_fields(&mut w)?)
        } else {
            AsyncKind::Event(event_fields(&mut w)?)
        };
        w.end()?;
        Ok(AsyncRecord { seq, sample, kind })
    }
}

fn cycle_fields(w: &mut Fields<'_>) -> Result<CycleTelemetry, WireError> {
    let state: State = w.token("state")?;
    let freq_hz = w.decimal("freq_hz", 0.0, MAX_FREQ_HZ)?;
    let amplitude_mm = w.decimal("amp_mm", 0.0, MAX_VALUE)?;
    let impacts: u8 = w.int("impacts")?;
    let peak_n = w.opt_decimal("peak_n", 0.0, MAX_VALUE)?;
    let impulse_n_s = w.opt_decimal("impulse_n_s", 0.0, MAX_VALUE)?;
    let (peak_n, impulse_n_s) = match (impacts, peak_n, impulse_n_s) {
        (0, None, None) => (0.0, 0.0),
        (1.., Some(p), Some(i)) => (p, i),
        _ => return Err(WireError::Mismatch("impacts")),
    };
    Ok(CycleTelemetry {
        state,
        freq_hz,
        amplitude_mm,
        impacts,
        peak_n,
        impulse_n_s,
        regime: w.with("regime", read_regime)?,
        fault: w.with("fault", read_fault)?,
        lost_cycles: w.int("lost_cycles")?,
    })
}

fn event_fields(w: &mut Fields<'_>) -> Result<Event, WireError> {
    Ok(match w.raw("event")? {
        "state" => Event::State {
            from: w.token("from")?,
            to: w.token("to")?,
        },
        "fault" => Event::Fault(w.token("fault")?),
        "model-ready" => {
            let shown = w.raw("target_hz")?;
            decimal("target_hz", shown, 0.0, MAX_FREQ_HZ)?;
            let bits = w.with("target_bits", |v| {
                let hex = v.strip_prefix("0x")?;
                // Hex digits only (`from_str_radix` would take a sign too).
                if !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
                    return None;
                }
                u32::from_str_radix(hex, 16).ok()
            })?;
            let target_hz = f32::from_bits(bits);
            // The bits are the target, in the same range; the rounded text must say the same.
            if !(0.0..=MAX_FREQ_HZ).contains(&target_hz) {
                return Err(WireError::Bad("target_bits"));
            }
            if !super::displays_as(&Decimal(target_hz, 4), shown) {
                return Err(WireError::Mismatch("target_bits"));
            }
            Event::ModelReady(Target {
                target_hz,
                band_hz: super::reply::exact_band(w)?,
                impact_force_mg: w.with("predicted_mg", |v| {
                    parse_exact(v)
                        .map(|x| x as f32)
                        .filter(|x| (0.0..=MAX_VALUE).contains(x))
                })?,
            })
        }
        "model-failed" => Event::ModelFailed,
        "stalled" => Event::SamplingStalled {
            samples: w.int("samples")?,
            expected: w.int("expected")?,
        },
        _ => return Err(WireError::Bad("event")),
    })
}

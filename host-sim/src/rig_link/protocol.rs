//! The console's lines as the desktop reads them: `key=value` fields, the `id` reply, and the
//! asynchronous `!T` (one per drive cycle) and `!E` (one per event) lines with their sequence
//! numbers (formats: `shared::control::serve` and `shared::control::AsyncRecord`).

use anyhow::{Context, Result, anyhow};
use shared::control::{Fault, SensorChain, State};
use shared::model::RigId as Rig;
use shared::observe::Regime;

/// The value of `key=` in a line of space-separated fields.
pub fn field<'a>(line: &'a str, key: &str) -> Option<&'a str> {
    line.split_ascii_whitespace()
        .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
}

fn num<T: std::str::FromStr>(line: &str, key: &str) -> Result<T> {
    let v = field(line, key).ok_or_else(|| anyhow!("`{key}=` missing in: {line}"))?;
    v.parse()
        .map_err(|_| anyhow!("`{key}={v}` is not a number in: {line}"))
}

/// What produced a log: the rig's `id` reply.
#[derive(Debug, Clone, PartialEq)]
pub struct RigIdentity {
    /// Firmware version.
    pub firmware: String,
    /// `rig`, `emulator` or `virtual`.
    pub board: String,
    /// Rig selected.
    pub rig: Rig,
    /// Gap set, mm.
    pub gap_mm: f64,
    /// Control sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Capture sample rate, Hz.
    pub capture_rate_hz: f64,
    /// The force sensor's calibration.
    pub sensor: SensorChain,
    /// Hammer mass, kg.
    pub mass_kg: f64,
    /// Safe drive-frequency window, Hz.
    pub freq_window_hz: [f64; 2],
    /// The reply as received.
    pub line: String,
}

impl Default for RigIdentity {
    fn default() -> Self {
        RigIdentity {
            firmware: String::new(),
            board: String::new(),
            rig: Rig::Wires,
            gap_mm: 0.0,
            sample_rate_hz: 10_000.0,
            capture_rate_hz: 100_000.0,
            sensor: SensorChain::default(),
            mass_kg: 0.298,
            freq_window_hz: [1.0, 30.0],
            line: String::new(),
        }
    }
}

impl RigIdentity {
    /// Hammer weight `m g`, N.
    pub fn weight_n(&self) -> f64 {
        self.mass_kg * shared::model::rig::GRAVITY_M_S2
    }

    /// Force (N) of an ADC code on the rig's calibration (the firmware's formula, in f64).
    pub fn force_n(&self, code: u16) -> f64 {
        let s = &self.sensor;
        (f64::from(code) * (f64::from(s.adc_full_scale_v) / 4096.0) - f64::from(s.offset_v))
            / f64::from(s.volts_per_n)
    }
}

/// Parses the `id` reply.
///
/// # Errors
/// A field missing or malformed (named).
pub fn parse_id(line: &str) -> Result<RigIdentity> {
    let rig: Rig = field(line, "rig")
        .ok_or_else(|| anyhow!("`rig=` missing in: {line}"))?
        .parse()
        .map_err(|e| anyhow!("{e} in: {line}"))?;
    let window = field(line, "freq_window_hz")
        .and_then(|w| w.split_once(".."))
        .and_then(|(a, b)| Some([a.parse().ok()?, b.parse().ok()?]))
        .unwrap_or([1.0, 30.0]);
    Ok::<RigIdentity, anyhow::Error>(RigIdentity {
        firmware: field(line, "firmware").unwrap_or("?").to_string(),
        board: field(line, "board").unwrap_or("?").to_string(),
        rig,
        gap_mm: num(line, "gap_mm")?,
        sample_rate_hz: num(line, "sample_rate_hz")?,
        capture_rate_hz: num(line, "capture_rate_hz")?,
        sensor: SensorChain {
            volts_per_n: num(line, "volts_per_n")?,
            offset_v: num(line, "offset_v")?,
            adc_full_scale_v: num(line, "adc_full_scale_v")?,
        },
        mass_kg: num(line, "mass_kg")?,
        freq_window_hz: window,
        line: line.to_string(),
    })
    .context("the rig's `id` reply")
}

/// One `!T` line: a finished drive cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleLine {
    /// Sequence number.
    pub seq: u32,
    /// Rig time, s.
    pub t_s: f64,
    /// Controller state.
    pub state: State,
    /// Drive frequency, Hz.
    pub freq_hz: f64,
    /// Drive amplitude, mm.
    pub amp_mm: f64,
    /// Impacts in the cycle.
    pub impacts: u32,
    /// Their largest peak, N.
    pub peak_n: Option<f64>,
    /// Their impulse, N·s.
    pub impulse_n_s: Option<f64>,
    /// Measured regime of the last evaluation (`None`: not yet measured).
    pub regime: Option<Regime>,
    /// The regime text as sent (`1/1`, `none`, `irregular`, `-`).
    pub regime_text: String,
    /// Latched fault.
    pub fault: Option<Fault>,
    /// Cycles lost from `1/1` while tracking.
    pub lost_cycles: u32,
}

/// One `!E` line: an event.
#[derive(Debug, Clone, PartialEq)]
pub struct EventLine {
    /// Sequence number.
    pub seq: u32,
    /// Rig time, s.
    pub t_s: f64,
    /// `state`, `fault`, `model-ready`, `model-failed`, `stalled`.
    pub event: String,
    /// The whole line.
    pub text: String,
}

/// An asynchronous line.
#[derive(Debug, Clone, PartialEq)]
pub enum AsyncLine {
    /// `!T`.
    Cycle(CycleLine),
    /// `!E`.
    Event(EventLine),
}

impl AsyncLine {
    /// Its sequence number.
    pub fn seq(&self) -> u32 {
        match self {
            AsyncLine::Cycle(c) => c.seq,
            AsyncLine::Event(e) => e.seq,
        }
    }
}

fn opt_num(line: &str, key: &str) -> Option<Option<f64>> {
    match field(line, key)? {
        "-" => Some(None),
        v => v.parse().ok().map(Some),
    }
}

/// Parses a `!T` or `!E` line; `None` if it is not one or is malformed.
pub fn parse_async(line: &str) -> Option<AsyncLine> {
    let seq = field(line, "seq")?.parse().ok()?;
    let t_s = field(line, "t_s")?.parse().ok()?;
    if line.starts_with("!T ") {
        let regime_text = field(line, "regime")?.to_string();
        let regime = match regime_text.as_str() {
            "none" => Some(Regime::NoImpact),
            "irregular" => Some(Regime::Irregular),
            "-" => None,
            r => Some(r.parse().ok()?),
        };
        let fault = match field(line, "fault")? {
            "none" => None,
            f => Some(Fault::from_name(f)?),
        };
        Some(AsyncLine::Cycle(CycleLine {
            seq,
            t_s,
            state: State::from_name(field(line, "state")?)?,
            freq_hz: field(line, "freq_hz")?.parse().ok()?,
            amp_mm: field(line, "amp_mm")?.parse().ok()?,
            impacts: field(line, "impacts")?.parse().ok()?,
            peak_n: opt_num(line, "peak_n")?,
            impulse_n_s: opt_num(line, "impulse_n_s")?,
            regime,
            regime_text,
            fault,
            lost_cycles: field(line, "lost_cycles")?.parse().ok()?,
        }))
    } else if line.starts_with("!E ") {
        Some(AsyncLine::Event(EventLine {
            seq,
            t_s,
            event: field(line, "event")?.to_string(),
            text: line.to_string(),
        }))
    } else {
        None
    }
}

/// Counts asynchronous lines lost on the way (gaps in the sequence numbers).
#[derive(Debug, Clone, Copy, Default)]
pub struct SeqCounter {
    next: Option<u32>,
    /// Lines received.
    pub received: u64,
    /// Lines missing between the first and the last received.
    pub lost: u64,
}

impl SeqCounter {
    /// Notes a received sequence number.
    pub fn see(&mut self, seq: u32) {
        if let Some(n) = self.next {
            self.lost += u64::from(seq.wrapping_sub(n));
        }
        self.received += 1;
        self.next = Some(seq.wrapping_add(1));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn telemetry_and_id_lines_parse() {
        let t = "!T seq=41 t_s=12.3456 state=track freq_hz=3.7000 amp_mm=0.890 impacts=1 \
                 peak_n=95.4 impulse_n_s=0.02851 regime=1/1 fault=none lost_cycles=0";
        let AsyncLine::Cycle(c) = parse_async(t).unwrap() else {
            panic!()
        };
        assert_eq!((c.seq, c.state, c.impacts), (41, State::Track, 1));
        assert_eq!(c.regime, Some(Regime::ONE_ONE));
        assert_eq!(c.peak_n, Some(95.4));
        let e = parse_async("!E seq=42 t_s=1.0000 event=fault fault=sensor-open").unwrap();
        assert_eq!(e.seq(), 42);
        assert!(parse_async("!T seq=1 t_s=x").is_none());
        assert!(parse_async("!X seq=1 t_s=1").is_none());
        let id = parse_id(
            "id firmware=0.1.0 board=virtual rig=beam-170 gap_mm=0.50 sample_rate_hz=10000 \
             capture_rate_hz=100000 volts_per_n=0.010000 offset_v=0.2000 adc_full_scale_v=3.3000 \
             mass_kg=0.2980 freq_window_hz=1.00..30.00",
        )
        .unwrap();
        assert_eq!(id.rig, Rig::Beam170);
        assert_eq!(id.freq_window_hz, [1.0, 30.0]);
        // The firmware's calibration, in f64: code 1440 is 0.96 V above the offset, 96 N.
        assert!((id.force_n(1440) - 96.0).abs() < 0.05);
        let mut s = SeqCounter::default();
        for q in [5, 6, 9, 10] {
            s.see(q);
        }
        assert_eq!((s.received, s.lost), (4, 2));
    }
}

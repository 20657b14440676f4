//! `rig log`: the rig's per-cycle telemetry recorded for a span of rig time.

use std::time::{Duration, Instant};

use anyhow::{Result, bail};
use serde::Serialize;
use shared::console::Token;
use shared::control::{AsyncKind, Command, Event};

use super::{RigPort, Seq, SeqCounter};

/// One logged drive cycle. The columns carry the `hil` log's names for what the rig measures
/// (`t_s`, `state`, `freq_hz`, `amp_cmd_mm`, `measured_*`, `fault`, `lost_cycles`), plus the
/// line's sequence number.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LogRow {
    /// Sequence number of the telemetry line.
    pub seq: u32,
    /// Rig time at the end of the cycle, s.
    pub t_s: f64,
    /// Controller state.
    pub state: &'static str,
    /// Drive frequency, Hz.
    pub freq_hz: f64,
    /// Commanded cart amplitude, mm.
    pub amp_cmd_mm: f64,
    /// Impacts detected in the cycle.
    pub measured_impacts: u32,
    /// Their largest peak, N (empty without impacts).
    pub measured_peak_n: Option<f64>,
    /// Their impulse, N·s.
    pub measured_impulse_n_s: Option<f64>,
    /// The controller's measured regime (last evaluation).
    pub measured_regime: String,
    /// Latched fault.
    pub fault: &'static str,
    /// Cycles lost from `1/1` while tracking, so far.
    pub lost_cycles: u32,
}

/// An event the rig reported while logging.
#[derive(Debug, Clone, PartialEq)]
pub struct LoggedEvent {
    /// Rig time, s.
    pub t_s: f64,
    /// The event.
    pub event: Event,
    /// Its line, as the rig writes it.
    pub text: String,
}

/// A recorded log.
#[derive(Debug, Clone, Default)]
pub struct Log {
    /// One row per drive cycle.
    pub rows: Vec<LogRow>,
    /// The events seen.
    pub events: Vec<LoggedEvent>,
    /// Received, lost and duplicated asynchronous lines.
    pub seq: SeqCounter,
}

/// The longest a log may take of wall time: ten times its rig time (a virtual rig may run
/// slower than real time) and a minute, then `quiet`.
pub fn wall_limit(seconds: f64, quiet: Duration) -> Duration {
    Duration::from_secs_f64((10.0 * seconds).max(60.0)) + quiet
}

/// Turns streaming on, records `seconds` of rig time (by the telemetry's own clock), turns it
/// off.
///
/// Bounds: no valid telemetry for `quiet` (the idle drive still reports once a second), the
/// rig's clock not advancing for `quiet`, and [`wall_limit`] in all. A duplicated line is
/// dropped and counted; a sequence number or a rig clock that goes back is an error (the rig
/// restarted, or the link replays old lines).
///
/// # Errors
/// The link failed, or one of the bounds above.
pub fn record(port: &mut RigPort, seconds: f64, quiet: Duration) -> Result<Log> {
    port.drain_records();
    port.command(Command::Stream(true))?;
    let mut log = Log::default();
    let started = Instant::now();
    let limit = wall_limit(seconds, quiet);
    let mut t0: Option<u64> = None;
    let mut last_sample: Option<u64> = None;
    let mut progress = Instant::now();
    let rate = f64::from(shared::control::SAMPLE_RATE_HZ);
    loop {
        if started.elapsed() > limit {
            bail!(
                "`rig log` took longer than {:.0} s of wall time for {seconds} s of rig time",
                limit.as_secs_f64()
            );
        }
        let rec = port.expect_record(quiet, "after `stream on`")?;
        if progress.elapsed() > quiet {
            bail!(
                "no new telemetry for {:.1} s (only duplicates, or a clock that does not advance)",
                quiet.as_secs_f64()
            );
        }
        match log.seq.see(rec.seq) {
            Seq::Next => {}
            Seq::Duplicate => continue,
            Seq::Back { last } => bail!(
                "the rig's sequence numbers went back from {last} to {} (did it restart?)",
                rec.seq
            ),
        }
        if let Some(prev) = last_sample
            && rec.sample < prev
        {
            bail!(
                "the rig's clock went back from {:.4} s to {:.4} s (did it restart?)",
                prev as f64 / rate,
                rec.sample as f64 / rate
            );
        }
        if last_sample.is_none_or(|prev| rec.sample > prev) {
            progress = Instant::now();
        }
        last_sample = Some(rec.sample);
        let t_s = rec.sample as f64 / rate;
        match rec.kind {
            AsyncKind::Cycle(c) => {
                let first = *t0.get_or_insert(rec.sample);
                let hit = c.impacts > 0;
                log.rows.push(LogRow {
                    seq: rec.seq,
                    t_s,
                    state: c.state.token(),
                    freq_hz: as_sent(c.freq_hz, 4),
                    amp_cmd_mm: as_sent(c.amplitude_mm, 3),
                    measured_impacts: u32::from(c.impacts),
                    measured_peak_n: hit.then_some(as_sent(c.peak_n, 1)),
                    measured_impulse_n_s: hit.then_some(as_sent(c.impulse_n_s, 5)),
                    measured_regime: c.regime.map_or("-".into(), |r| r.to_string()),
                    fault: c.fault.map_or("none", Token::token),
                    lost_cycles: c.lost_cycles,
                });
                if (rec.sample - first) as f64 / rate >= seconds {
                    break;
                }
            }
            AsyncKind::Event(event) => log.events.push(LoggedEvent {
                t_s,
                event,
                text: rec.to_string(),
            }),
        }
    }
    port.command(Command::Stream(false))?;
    Ok(log)
}

/// A value as the line carried it: `x` (the f32 read from the line) rounded to the `decimals`
/// it was written with, so that the CSV shows `0.89`, not `0.8899999856948853`.
pub fn as_sent(x: f32, decimals: i32) -> f64 {
    let scale = 10f64.powi(decimals);
    (f64::from(x) * scale).round() / scale
}

//! `rig log`: the rig's per-cycle telemetry recorded for a span of rig time.

use std::time::Duration;

use anyhow::{Result, bail};
use serde::Serialize;

use super::RigPort;
use super::protocol::{AsyncLine, EventLine, SeqCounter};

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

/// A recorded log.
#[derive(Debug, Clone, Default)]
pub struct Log {
    /// One row per drive cycle.
    pub rows: Vec<LogRow>,
    /// The events seen.
    pub events: Vec<EventLine>,
    /// Received and lost asynchronous lines.
    pub seq: SeqCounter,
}

/// Turns streaming on, records `seconds` of rig time (by the telemetry's own clock), turns it
/// off. `quiet` bounds the wait for the next line (the idle drive still reports once a second).
///
/// # Errors
/// The link failed, or no telemetry came for `quiet`.
pub fn record(port: &mut RigPort, seconds: f64, quiet: Duration) -> Result<Log> {
    port.drain_async();
    port.command_ok("stream on")?;
    let mut log = Log::default();
    let mut t0: Option<f64> = None;
    loop {
        let Some(line) = port.next_async(quiet)? else {
            bail!(
                "no telemetry for {:.1} s after `stream on` (the rig stopped sending)",
                quiet.as_secs_f64()
            );
        };
        log.seq.see(line.seq());
        match line {
            AsyncLine::Cycle(c) => {
                let t_first = *t0.get_or_insert(c.t_s);
                log.rows.push(LogRow {
                    seq: c.seq,
                    t_s: c.t_s,
                    state: c.state.as_str(),
                    freq_hz: c.freq_hz,
                    amp_cmd_mm: c.amp_mm,
                    measured_impacts: c.impacts,
                    measured_peak_n: c.peak_n,
                    measured_impulse_n_s: c.impulse_n_s,
                    measured_regime: c.regime_text.clone(),
                    fault: c.fault.map_or("none", shared::control::Fault::as_str),
                    lost_cycles: c.lost_cycles,
                });
                if c.t_s - t_first >= seconds {
                    break;
                }
            }
            AsyncLine::Event(e) => log.events.push(e),
        }
    }
    port.command_ok("stream off")?;
    Ok(log)
}

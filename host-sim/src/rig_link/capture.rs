//! `rig capture`: a drop test recorded by the rig's force capture (segments around each impact
//! at the capture rate) and turned into a `t_s,force_n` trace for `identify contact --trace`.

use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail, ensure};
use shared::control::capture::decode_codes;

use super::RigPort;
use super::protocol::field;

/// A drop test off the rig.
#[derive(Debug, Clone, Default)]
pub struct CaptureTrace {
    /// Sample times since arming, s (strictly increasing; gaps between segments).
    pub t_s: Vec<f64>,
    /// Force on the rig's calibration, N.
    pub force_n: Vec<f64>,
    /// Segments (impacts) recorded.
    pub segments: usize,
    /// Samples per segment.
    pub segment_len: usize,
}

/// Arms a capture (trigger `level_n`, `seconds` of rig time), waits until the rig reports it
/// done, and reads every segment. `on_progress` sees the segment count as it grows.
///
/// # Errors
/// The drive is not idle, the link failed, the capture stopped advancing for `stall`, a
/// malformed segment line, or no impact was recorded.
pub fn capture(
    port: &mut RigPort,
    level_n: f64,
    seconds: f64,
    stall: Duration,
    mut on_progress: impl FnMut(usize),
) -> Result<CaptureTrace> {
    let status = port.command_ok("status")?;
    let state = field(&status, "state").unwrap_or("?");
    ensure!(
        state == "idle",
        "capture needs the drive idle: the rig is in `{state}` (`rig send stop`, or `clear` after a fault)"
    );
    let armed = port.command_ok(&format!("capture arm {level_n:.3} {seconds:.3}"))?;
    ensure!(
        field(&armed, "state") == Some("armed"),
        "unexpected reply to capture arm: {armed}"
    );
    let rate: f64 = field(&armed, "rate_hz")
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| anyhow!("no rate_hz in: {armed}"))?;
    let mut last = (0u64, Instant::now());
    let mut segments;
    loop {
        std::thread::sleep(Duration::from_millis(50));
        let s = port.command_ok("capture")?;
        let samples: u64 = field(&s, "samples")
            .and_then(|v| v.parse().ok())
            .unwrap_or(0);
        segments = field(&s, "segments")
            .and_then(|v| v.parse().ok())
            .unwrap_or(0usize);
        on_progress(segments);
        if field(&s, "state") == Some("done") {
            break;
        }
        if samples != last.0 {
            last = (samples, Instant::now());
        } else if last.1.elapsed() > stall {
            bail!(
                "the capture stopped advancing ({samples} samples) for {:.1} s",
                stall.as_secs_f64()
            );
        }
    }
    ensure!(
        segments > 0,
        "no impact reached the trigger level of {level_n} N within {seconds} s of rig time"
    );
    let mut trace = CaptureTrace {
        segments,
        ..CaptureTrace::default()
    };
    for k in 0..segments {
        let line = port.command_ok(&format!("capture get {k}"))?;
        let bad = || anyhow!("malformed segment line for segment {k}: {line}");
        let start: u64 = field(&line, "start")
            .and_then(|v| v.parse().ok())
            .ok_or_else(bad)?;
        let codes = decode_codes(field(&line, "codes").ok_or_else(bad)?).ok_or_else(bad)?;
        trace.segment_len = codes.len();
        for (i, &c) in codes.iter().enumerate() {
            let t = (start + i as u64) as f64 / rate;
            if let Some(&prev) = trace.t_s.last() {
                ensure!(t > prev, "segment {k} overlaps the previous one");
            }
            trace.t_s.push(t);
            trace.force_n.push(port.id.force_n(c));
        }
    }
    Ok(trace)
}

/// Writes the trace as `identify contact --trace` reads it: `#` lines with the rig's identity,
/// then `t_s,force_n`.
///
/// # Errors
/// I/O.
pub fn write_trace(
    path: &std::path::Path,
    trace: &CaptureTrace,
    id_line: &str,
    level_n: f64,
) -> Result<()> {
    use std::io::Write as _;
    let f = std::fs::File::create(path).with_context(|| format!("writing {}", path.display()))?;
    let mut w = std::io::BufWriter::new(f);
    writeln!(w, "# host-sim rig capture: {id_line}")?;
    writeln!(
        w,
        "# {} segments of {} samples around impacts (trigger {level_n} N); time since arming",
        trace.segments, trace.segment_len
    )?;
    writeln!(w, "t_s,force_n")?;
    for (t, f) in trace.t_s.iter().zip(&trace.force_n) {
        writeln!(w, "{t:.7},{f:.4}")?;
    }
    w.flush()?;
    Ok(())
}

//! `rig capture`: a drop test recorded by the rig's force capture (segments around each impact
//! at the capture rate) and turned into a `t_s,force_n` trace for `identify contact --trace`.

use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail, ensure};
use shared::capture::{CaptureCommand, CaptureState, SEGMENTS};
use shared::console::Token;
use shared::control::State;

use super::RigPort;

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

/// The longest a capture of `seconds` of rig time may take of wall time: ten times its rig
/// time (a virtual rig may run slower than real time) and a minute, then `stall`.
pub fn wall_limit(seconds: f64, stall: Duration) -> Duration {
    Duration::from_secs_f64((10.0 * seconds).max(60.0)) + stall
}

/// Arms a capture (trigger `level_n`, `seconds` of rig time), waits until the rig reports it
/// done, and reads every segment. Refused with the drive not idle, it leaves the drive as it
/// was (the port's guard released). `on_progress` sees the segment count as it grows.
///
/// Bounds: the capture's sample count must advance (at most `stall` without), stop by the
/// capture's own end (its `seconds` at the capture rate), and the whole within [`wall_limit`];
/// the rig holds at most [`SEGMENTS`] segments (a reply claiming more does not read).
///
/// # Errors
/// The drive is not idle, the link failed, one of the bounds above, a segment line that does
/// not read, or no impact was recorded.
pub fn capture(
    port: &mut RigPort,
    level_n: f64,
    seconds: f64,
    stall: Duration,
    mut on_progress: impl FnMut(usize),
) -> Result<CaptureTrace> {
    let status = port.status()?;
    if status.state != State::Idle {
        return Err(port.refuse(anyhow::anyhow!(
            "capture needs the drive idle: the rig is in `{}` (`rig send stop`, or `clear` after \
             a fault)",
            status.state.token()
        )));
    }
    let armed = port.capture_status(CaptureCommand::Arm {
        level_n: level_n as f32,
        seconds: seconds as f32,
    })?;
    ensure!(
        armed.state == CaptureState::Armed,
        "the capture did not arm (state `{}`)",
        armed.state.token()
    );
    let rate = f64::from(port.id().capture_rate_hz);
    let end_samples = (seconds * rate).ceil() as u64;
    let started = Instant::now();
    let limit = wall_limit(seconds, stall);
    let mut last = (0u64, Instant::now());
    let status = loop {
        std::thread::sleep(Duration::from_millis(50));
        let s = port.capture_status(CaptureCommand::Status)?;
        on_progress(usize::from(s.segments));
        if s.state == CaptureState::Done {
            break s;
        }
        let samples = u64::from(s.samples);
        ensure!(
            s.state == CaptureState::Armed,
            "the capture ended in state `{}` without being done",
            s.state.token()
        );
        ensure!(
            samples <= end_samples + 1,
            "the capture reports `armed` at {samples} samples, past its end ({end_samples} at {rate} Hz)"
        );
        if samples != last.0 {
            last = (samples, Instant::now());
        } else if last.1.elapsed() > stall {
            bail!(
                "the capture stopped advancing ({samples} samples) for {:.1} s",
                stall.as_secs_f64()
            );
        }
        ensure!(
            started.elapsed() <= limit,
            "the capture took longer than {:.0} s of wall time for {seconds} s of rig time",
            limit.as_secs_f64()
        );
    };
    let segments = usize::from(status.segments);
    ensure!(
        segments > 0,
        "no impact reached the trigger level of {level_n} N within {seconds} s of rig time"
    );
    debug_assert!(segments <= SEGMENTS);
    let mut trace = CaptureTrace {
        segments,
        ..CaptureTrace::default()
    };
    let sensor = port.id().sensor;
    for k in 0..status.segments {
        let seg = port
            .segment(k)
            .with_context(|| format!("segment {k} of {segments}"))?;
        trace.segment_len = seg.codes.len();
        for (i, &c) in seg.codes.iter().enumerate() {
            let t = (u64::from(seg.start) + i as u64) as f64 / rate;
            if let Some(&prev) = trace.t_s.last() {
                ensure!(
                    t > prev,
                    "segment {k} (start {}) overlaps the previous one",
                    seg.start
                );
            }
            trace.t_s.push(t);
            trace.force_n.push(f64::from(sensor.force_n(c)));
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
        "# {} of {} samples around impacts (trigger {level_n} N); time since arming",
        crate::output::count(trace.segments as u64, "segment"),
        trace.segment_len
    )?;
    writeln!(w, "t_s,force_n")?;
    for (t, f) in trace.t_s.iter().zip(&trace.force_n) {
        writeln!(w, "{t:.7},{f:.4}")?;
    }
    w.flush()?;
    Ok(())
}

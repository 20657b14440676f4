//! `rig sweep`: the thesis' experimental frequency response (§3.3.4, Figs. 3.12–3.14) measured
//! on the rig: the drive dwells at each frequency (`freq`, inside the rig's safe window), and
//! after the transient the mean peak impact force (`F_i/mg`) and the measured regime of the
//! dwell's cycles are recorded. A fault ends the sweep (the rig ramps its drive to zero itself);
//! so does a failure or an interruption (the port's drive guard stops the drive). However it
//! ends, the rig is left as the sweep found it: the drive stopped, and the model's target, not
//! the sweep's last frequency, for the next `start` (`tune`).

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Result, anyhow, bail, ensure};
use serde::Serialize;
use shared::console::Token;
use shared::control::meter::{METER_CYCLES, RegimeMeter};
use shared::control::{AsyncKind, Command, CycleTelemetry, Event, Fault, State};

use super::{Refused, RigPort};

/// What to sweep.
#[derive(Debug, Clone)]
pub struct SweepSpec {
    /// Frequencies, Hz, in order.
    pub freqs_hz: Vec<f64>,
    /// Cycles recorded per frequency.
    pub dwell_cycles: u32,
    /// Cycles skipped after the drive reached a frequency (the transient).
    pub settle_cycles: u32,
    /// Longest wait for the next telemetry line.
    pub quiet: Duration,
}

/// One measured frequency: a row `compare --experiment` reads (`freq_hz`, `impact_force_mg`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SweepPoint {
    /// Drive frequency, Hz.
    pub freq_hz: f64,
    /// Mean peak impact force of the cycles that impacted, over `m g`.
    pub impact_force_mg: f64,
    /// The same in N.
    pub impact_force_n: f64,
    /// Regime of the dwell's cycles (impact counts and peaks, the firmware's meter), written as
    /// `response` writes it (`1/1`, `no impact`, `irregular`).
    pub regime: String,
    /// Cycles recorded.
    pub cycles: u32,
    /// Of which with at least one impact.
    pub impact_cycles: u32,
}

/// How a sweep ended.
#[derive(Debug)]
pub enum SweepOutcome {
    /// Every frequency measured.
    Complete(Vec<SweepPoint>),
    /// It ended early: a fault on the rig, a link failure or deadline, or an interruption.
    Ended {
        /// The points measured before.
        points: Vec<SweepPoint>,
        /// Frequency being measured, Hz.
        at_hz: f64,
        /// Why.
        why: SweepEnd,
    },
}

/// Why a sweep ended early.
#[derive(Debug)]
pub enum SweepEnd {
    /// The rig tripped this fault (it ramps its drive to zero itself).
    Fault(Fault),
    /// A failure on this side or of the link (the drive guard stops the drive).
    Failed(anyhow::Error),
}

/// `lo:hi:step` as frequencies (inclusive of `hi` within a tenth of a step).
///
/// # Errors
/// Reversed, empty, non-finite or over 10,000 points.
pub fn parse_range(s: &str) -> Result<Vec<f64>> {
    let parts: Vec<&str> = s.split(':').collect();
    ensure!(
        parts.len() == 3,
        "--freq-hz `{s}`: expected START:END:STEP (Hz)"
    );
    let v: Vec<f64> = parts
        .iter()
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--freq-hz `{s}`: not numbers"))?;
    let (lo, hi, step) = (v[0], v[1], v[2]);
    ensure!(
        v.iter().all(|x| x.is_finite()) && lo > 0.0 && hi >= lo && step > 0.0,
        "--freq-hz `{s}`: need 0 < START ≤ END and STEP > 0"
    );
    let n = ((hi - lo) / step + 0.1).floor() as usize + 1;
    ensure!(n <= 10_000, "--freq-hz `{s}`: {n} points (at most 10,000)");
    // Rounded to the µHz: the console takes up to 9 significant digits.
    Ok((0..n)
        .map(|i| ((lo + step * i as f64) * 1e6).round() / 1e6)
        .collect())
}

/// Checks the counts of cycles a sweep dwells (`2 ..= 10000`: the regime meter reads two cycles
/// at least) and skips (`0 ..= 10000`) at each frequency.
///
/// # Errors
/// The flag out of range, named.
pub fn check_cycles(dwell_cycles: u32, settle_cycles: u32) -> Result<()> {
    ensure!(
        (2..=10_000).contains(&dwell_cycles),
        "--dwell-cycles = {dwell_cycles} is out of range: allowed 2 ..= 10000 (a regime is \
         read from two cycles at least)"
    );
    ensure!(
        settle_cycles <= 10_000,
        "--settle-cycles = {settle_cycles} is out of range: allowed 0 ..= 10000"
    );
    Ok(())
}

/// Checks what can be checked before the rig moves: the frequencies inside the rig's safe
/// window, the dwell and settle counts, and the rig idle. A refusal leaves the drive as it was
/// (the port's guard released); a failure of the link leaves the guard armed.
///
/// # Errors
/// Each named.
pub fn check(port: &mut RigPort, spec: &SweepSpec) -> Result<()> {
    ensure!(!spec.freqs_hz.is_empty(), "no frequency to sweep");
    check_cycles(spec.dwell_cycles, spec.settle_cycles)?;
    let [lo, hi] = port.id().freq_window_hz.map(f64::from);
    if let Some(f) = spec.freqs_hz.iter().find(|f| !(lo..=hi).contains(*f)) {
        return Err(port.refuse(anyhow!(
            "--freq-hz: {f} Hz is outside the rig's safe window {lo} ..= {hi} Hz"
        )));
    }
    let mut status = port.status()?;
    if status.state == State::Stopping {
        // A drive ramping down (the last sweep's end): wait for idle, at most twice the ramp
        // at the rig's `ramp_mm_per_s` and 5 s more.
        let ramp_s = f64::from(status.amplitude_mm) / f64::from(port.id().ramp_mm_per_s.max(0.01));
        (status, _) = port.wait_status(
            |s| s.state != State::Stopping,
            Duration::from_secs_f64(2.0 * ramp_s + 5.0),
            Duration::from_millis(100),
        )?;
    }
    match status.state {
        State::Idle => Ok(()),
        State::Fault => Err(port.refuse(anyhow!(
            "the rig is in fault ({}): `rig send clear` first",
            status.fault.map_or("?", Token::token)
        ))),
        State::Stopping => Err(port.refuse(anyhow!(
            "the drive is still stopping ({:.3} mm) after waiting for idle: try again when the \
             rig is idle",
            status.amplitude_mm
        ))),
        s => Err(port.refuse(anyhow!(
            "the drive is running (`{}`): `rig send stop` first",
            s.token()
        ))),
    }
}

/// Runs the sweep (after [`check`]). `on_point` sees each point as it is measured. A fault,
/// a failure or an interruption ends it with the points measured so far.
///
/// Each frequency has a deadline in the rig's time, derived from what it waits for: the soft
/// start (the rig's amplitude at its `ramp_mm_per_s`), the slew from the previous frequency (at
/// its `slew_hz_per_s`), and the settling and dwell cycles, twice over and 5 s more.
pub fn sweep(
    port: &mut RigPort,
    spec: &SweepSpec,
    mut on_point: impl FnMut(&SweepPoint),
) -> SweepOutcome {
    let mut points = Vec::new();
    let mut at_hz = spec.freqs_hz.first().copied().unwrap_or(0.0);
    match run(port, spec, &mut points, &mut at_hz, &mut on_point) {
        Ok(None) => SweepOutcome::Complete(points),
        Ok(Some(fault)) => SweepOutcome::Ended {
            points,
            at_hz,
            why: SweepEnd::Fault(fault),
        },
        Err(e) => SweepOutcome::Ended {
            points,
            at_hz,
            why: SweepEnd::Failed(e),
        },
    }
}

fn run(
    port: &mut RigPort,
    spec: &SweepSpec,
    points: &mut Vec<SweepPoint>,
    at_hz: &mut f64,
    on_point: &mut impl FnMut(&SweepPoint),
) -> Result<Option<Fault>> {
    let weight = port.weight_n();
    let id = *port.id();
    let amplitude_mm = port.model()?.amplitude_m * 1e3;
    port.drain_records();
    port.command(Command::Stream(true))?;
    // The sweep's frequencies are manual: whatever ends it, closing the port hands the next
    // `start` back to the model's target.
    port.retune_on_close();
    let mut previous: Option<f64> = None;
    for &f in &spec.freqs_hz {
        *at_hz = f;
        let mut sent = port.command(Command::Freq(f as f32));
        if previous.is_none() && sent.is_ok() {
            sent = port.command(Command::Start);
        }
        if let Err(e) = sent {
            // Refused for a fault the telemetry has not shown yet (it tripped while this
            // program was not listening): the fault ends the sweep, as the rig's status says.
            return match latched_fault(port, &e)? {
                Some(fault) => Ok(Some(fault)),
                None => Err(e),
            };
        }
        let approach = match previous {
            None => amplitude_mm / f64::from(id.ramp_mm_per_s),
            Some(p) => (f - p).abs() / f64::from(id.slew_hz_per_s),
        };
        let cycles = f64::from(spec.settle_cycles + spec.dwell_cycles + 2);
        let deadline_s = 2.0 * (approach + cycles / f) + 5.0;
        match dwell(port, spec, f, deadline_s)? {
            Ok(cycles) => {
                let p = point(f, &cycles, weight);
                on_point(&p);
                points.push(p);
            }
            Err(fault) => {
                let _ = port.command(Command::Stream(false));
                return Ok(Some(fault));
            }
        }
        previous = Some(f);
    }
    port.command(Command::Stop)?;
    // `tune` hands the next `start` back to the model's target (computed again).
    port.command(Command::Tune)?;
    port.tuned();
    port.command(Command::Stream(false))?;
    Ok(None)
}

/// The fault latched on the rig, if `e` is a refusal for one (`fault latched`, or a `start`
/// that tripped one).
fn latched_fault(port: &mut RigPort, e: &anyhow::Error) -> Result<Option<Fault>> {
    use shared::console::AnswerError;
    use shared::control::CommandError;
    let for_fault = e.downcast_ref::<Refused>().is_some_and(|r| {
        matches!(
            r.error,
            AnswerError::Command(CommandError::FaultLatched | CommandError::Tripped(_))
        )
    });
    if !for_fault {
        return Ok(None);
    }
    Ok(port.status()?.fault)
}

/// Where a sweep that ended early writes what it measured: `fr.csv` → `fr.partial.csv`.
pub fn partial_path(out: &Path) -> PathBuf {
    let stem = out
        .file_stem()
        .map_or("sweep".into(), |s| s.to_string_lossy());
    let ext = out
        .extension()
        .map_or("csv".into(), |e| e.to_string_lossy());
    out.with_file_name(format!("{stem}.partial.{ext}"))
}

/// Waits until the drive dwells at `f`, skips the settling cycles and returns the dwell's
/// cycles, or the fault that ended it; at most `deadline_s` of the rig's time (counted from the
/// first telemetry line) and `spec.quiet` between two lines.
fn dwell(
    port: &mut RigPort,
    spec: &SweepSpec,
    f: f64,
    deadline_s: f64,
) -> Result<Result<Vec<CycleTelemetry>, Fault>> {
    let rate = f64::from(shared::control::SAMPLE_RATE_HZ);
    let mut settled = 0;
    let mut cycles = Vec::new();
    let mut first: Option<u64> = None;
    let mut last_seen = String::from("no telemetry yet");
    loop {
        let rec = port.expect_record(spec.quiet, &format!("at {f} Hz"))?;
        // A fault first: it ends the dwell whenever it came.
        let c = match rec.kind {
            AsyncKind::Cycle(c) => c,
            AsyncKind::Event(Event::Fault(fault)) => return Ok(Err(fault)),
            AsyncKind::Event(_) => continue,
        };
        if let Some(fault) = c.fault {
            return Ok(Err(fault));
        }
        let since = (rec.sample.saturating_sub(*first.get_or_insert(rec.sample))) as f64 / rate;
        if since > deadline_s {
            bail!(
                "the rig did not dwell {} cycles at {f} Hz within {deadline_s:.1} s of its time (last seen: {last_seen})",
                spec.settle_cycles + spec.dwell_cycles
            );
        }
        last_seen = format!("state={} freq_hz={:.4}", c.state.token(), c.freq_hz);
        let there = (f64::from(c.freq_hz) - f).abs() < 5e-4 && c.state == State::Dwell;
        if !there {
            settled = 0;
            cycles.clear();
            continue;
        }
        if settled < spec.settle_cycles {
            settled += 1;
            continue;
        }
        cycles.push(c);
        if cycles.len() >= spec.dwell_cycles as usize {
            return Ok(Ok(cycles));
        }
    }
}

fn point(f: f64, cycles: &[CycleTelemetry], weight_n: f64) -> SweepPoint {
    let peaks: Vec<f64> = cycles
        .iter()
        .filter(|c| c.impacts > 0)
        .map(|c| super::log::as_sent(c.peak_n, 1))
        .collect();
    let mean = if peaks.is_empty() {
        0.0
    } else {
        peaks.iter().sum::<f64>() / peaks.len() as f64
    };
    // The firmware's regime meter over the dwell's last cycles.
    let mut meter = RegimeMeter::new();
    for c in cycles {
        for _ in 0..c.impacts {
            meter.on_impact(c.peak_n, c.impulse_n_s / f32::from(c.impacts));
        }
        meter.on_cycle_end();
    }
    let window = cycles.len().min(METER_CYCLES);
    let regime = meter
        .regime(window)
        .map_or("-".to_string(), |r| r.to_string());
    SweepPoint {
        freq_hz: f,
        impact_force_mg: mean / weight_n,
        impact_force_n: mean,
        regime,
        cycles: cycles.len() as u32,
        impact_cycles: peaks.len() as u32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_include_their_end_and_reject_nonsense() {
        let r = parse_range("2.2:4.6:0.1").unwrap();
        assert_eq!(r.len(), 25);
        assert!((r[24] - 4.6).abs() < 1e-9);
        assert!(parse_range("4:2:0.1").is_err());
        assert!(parse_range("2:4:0").is_err());
        assert!(parse_range("2:4").is_err());
        assert!(parse_range("a:4:1").is_err());
    }
}

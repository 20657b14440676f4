//! `rig sweep`: the thesis' experimental frequency response (§3.3.4, Figs. 3.12–3.14) measured
//! on the rig: the drive dwells at each frequency (`freq`, inside the rig's safe window), and
//! after the transient the mean peak impact force (`F_i/mg`) and the measured regime of the
//! dwell's cycles are recorded. A fault ends the sweep (the rig ramps its drive to zero itself).

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Result, bail, ensure};
use serde::Serialize;
use shared::control::State;
use shared::control::meter::{METER_CYCLES, RegimeMeter};

use super::RigPort;
use super::protocol::{AsyncLine, CycleLine, field};

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
#[derive(Debug, Clone, PartialEq)]
pub enum SweepOutcome {
    /// Every frequency measured.
    Complete(Vec<SweepPoint>),
    /// A fault ended it: the points measured before it.
    Faulted {
        /// Measured points.
        points: Vec<SweepPoint>,
        /// The fault's name.
        fault: String,
        /// Frequency being measured, Hz.
        at_hz: f64,
    },
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

/// Runs the sweep. `on_point` sees each point as it is measured.
///
/// # Errors
/// A frequency outside the rig's window, the rig not idle at the start, a refused command, or
/// a link failure (telemetry stopped for `quiet`).
pub fn sweep(
    port: &mut RigPort,
    spec: &SweepSpec,
    mut on_point: impl FnMut(&SweepPoint),
) -> Result<SweepOutcome> {
    ensure!(!spec.freqs_hz.is_empty(), "no frequency to sweep");
    ensure!(
        (1..=10_000).contains(&spec.dwell_cycles) && spec.settle_cycles <= 10_000,
        "--dwell-cycles must be in 1 ..= 10000 and --settle-cycles ≤ 10000"
    );
    let [lo, hi] = port.id.freq_window_hz;
    for &f in &spec.freqs_hz {
        ensure!(
            (lo..=hi).contains(&f),
            "--freq-hz: {f} Hz is outside the rig's safe window {lo} ..= {hi} Hz"
        );
    }
    let status = port.command_ok("status")?;
    match field(&status, "state") {
        Some("idle") => {}
        Some("fault") => bail!(
            "the rig is in fault ({}): `rig send clear` first",
            field(&status, "fault").unwrap_or("?")
        ),
        Some(s) => bail!("the drive is running (`{s}`): `rig send stop` first"),
        None => bail!("malformed status reply: {status}"),
    }
    let weight = port.id.weight_n();
    port.drain_async();
    port.command_ok("stream on")?;
    let first = spec.freqs_hz[0];
    port.command_ok(&format!("freq {first:.6}"))?;
    port.command_ok("start")?;
    let mut points = Vec::new();
    for (i, &f) in spec.freqs_hz.iter().enumerate() {
        if i > 0 {
            port.command_ok(&format!("freq {f:.6}"))?;
        }
        match dwell(port, spec, f)? {
            Ok(cycles) => {
                let p = point(f, &cycles, weight);
                on_point(&p);
                points.push(p);
            }
            Err(fault) => {
                let _ = port.command("stream off");
                return Ok(SweepOutcome::Faulted {
                    points,
                    fault,
                    at_hz: f,
                });
            }
        }
    }
    port.command_ok("stop")?;
    port.command_ok("stream off")?;
    Ok(SweepOutcome::Complete(points))
}

/// Where a sweep ended by a fault writes what it measured: `fr.csv` → `fr.partial.csv`.
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
/// cycles, or the fault that ended it.
fn dwell(port: &mut RigPort, spec: &SweepSpec, f: f64) -> Result<Result<Vec<CycleLine>, String>> {
    let mut settled = 0;
    let mut cycles = Vec::new();
    loop {
        let Some(line) = port.next_async(spec.quiet)? else {
            bail!(
                "no telemetry for {:.1} s at {f} Hz (the rig stopped sending)",
                spec.quiet.as_secs_f64()
            );
        };
        let c = match line {
            AsyncLine::Cycle(c) => c,
            AsyncLine::Event(e) if e.event == "fault" => {
                return Ok(Err(field(&e.text, "fault").unwrap_or("?").to_string()));
            }
            AsyncLine::Event(_) => continue,
        };
        if let Some(fault) = c.fault {
            return Ok(Err(fault.as_str().to_string()));
        }
        let there = (c.freq_hz - f).abs() < 5e-4 && c.state == State::Dwell;
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

fn point(f: f64, cycles: &[CycleLine], weight_n: f64) -> SweepPoint {
    let peaks: Vec<f64> = cycles.iter().filter_map(|c| c.peak_n).collect();
    let mean = if peaks.is_empty() {
        0.0
    } else {
        peaks.iter().sum::<f64>() / peaks.len() as f64
    };
    // The firmware's regime meter over the dwell's last cycles.
    let mut meter = RegimeMeter::new();
    for c in cycles {
        let n = c.impacts.min(255);
        for _ in 0..n {
            let impulse = c.impulse_n_s.unwrap_or(0.0) / f64::from(n.max(1));
            meter.on_impact(c.peak_n.unwrap_or(0.0) as f32, impulse as f32);
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

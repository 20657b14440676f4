//! The measured drop test (thesis §3.3.2, Figs. 3.8–3.10): the force–time trace of the hammer
//! released at rest from the surface and bouncing several times, reduced to its sensor offset,
//! noise level and impacts.
//!
//! - Sensor offset: the median of the trace (most samples are free flight, `F = 0`); it is
//!   subtracted. Noise level `σ`: 1.4826 × the median absolute deviation, at least
//!   [`NOISE_FLOOR`] of the largest force (a noise-free or coarsely quantised trace has a
//!   median absolute deviation of 0, and a fit's intervals and lack-of-fit test need a noise
//!   level: the floor is about what the fit's own simulation and peak estimate reproduce).
//! - Largest force: the largest sample, or, where that is more than `1/`[`SPIKE_RATIO`] times
//!   the largest force held over three samples, the latter (a glitch is not an impact).
//! - Impacts: runs of samples above `max(5σ, 3 % of the largest force)` with at least 3
//!   samples; runs closer than twice the previous run's length are one impact (re-contacts).
//!   At most `max_impacts`, in time order, and only up to the first whose peak is below twice
//!   the threshold: its run above the threshold is then only the pulse's top, its window
//!   (below) does not hold the whole pulse, and its centroid is not the contact's (the
//!   simulated one is): such an impact would bias the fit.
//! - Peak force of an impact: the vertex of a least-squares parabola through the 5 samples
//!   around the largest one (when all 5 are above 80 % of it), else the largest sample.
//! - Impact time: the force-weighted centroid `∫ t F dt / ∫ F dt` over the impact's window
//!   (the run plus half its length on each side): robust to noise, unlike the onset or the
//!   peak of a flat-topped pulse. Only differences to the first impact are used, so the trace's
//!   time origin need not be the release.

use anyhow::{Result, ensure};
use nalgebra::{DMatrix, DVector};

use super::least_squares;
use crate::trace::Trace;

impl DropData {
    /// The impulse `∫ F dt` of impact `i` over its window (trapezoids), N s; `None` if there is
    /// no such impact.
    pub fn impulse_n_s(&self, i: usize) -> Option<f64> {
        let (first, last) = self.impacts.get(i)?.window;
        let (t, f) = (&self.t_s[first..=last], &self.force_n[first..=last]);
        Some(
            t.windows(2)
                .zip(f.windows(2))
                .map(|(t, f)| 0.5 * (t[1] - t[0]) * (f[0] + f[1]))
                .sum(),
        )
    }

    /// Samples per contact: the first impact's width at half maximum over the sampling step.
    pub fn samples_per_contact(&self) -> f64 {
        let dt = self
            .t_s
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        self.impacts.first().map_or(0.0, |i| i.fwhm_s / dt)
    }
}

/// One impact found in the measured trace.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredImpact {
    /// Peak force (offset removed), N.
    pub peak_n: f64,
    /// Force-weighted centroid time, s.
    pub centroid_s: f64,
    /// Width at half maximum, s.
    pub fwhm_s: f64,
    /// Sample index range `[first, last]` of the impact's window.
    pub window: (usize, usize),
    /// Sample index range `[first, last]` of the run above the threshold (the peak's search).
    pub run: (usize, usize),
}

/// A measured drop test after preprocessing.
#[derive(Debug, Clone)]
pub struct DropData {
    /// Sample times, s.
    pub t_s: Vec<f64>,
    /// Force with the offset removed, N.
    pub force_n: Vec<f64>,
    /// Removed sensor offset, N.
    pub offset_n: f64,
    /// Noise standard deviation, N (at least [`NOISE_FLOOR`] of the largest force).
    pub noise_n: f64,
    /// Whether the trace's own noise (its median absolute deviation) was below the floor.
    pub noise_floored: bool,
    /// Impacts, in time order.
    pub impacts: Vec<MeasuredImpact>,
    /// The peak of the first impact left out as too weak to time (below twice the
    /// threshold), N, with the threshold, N.
    pub too_weak: Option<(f64, f64)>,
    /// The largest sample where it is a glitch ([`SPIKE_RATIO`]), N: not an impact, and not
    /// the largest force the threshold and the noise floor refer to.
    pub spike_n: Option<f64>,
}

/// The smallest noise level taken, as a fraction of the largest force (0.1 %).
pub const NOISE_FLOOR: f64 = 1e-3;

/// A largest sample more than `1/SPIKE_RATIO` times the largest force held over three samples is
/// a glitch, not an impact (an impact resolved by 4 samples holds 38 % of its peak).
pub const SPIKE_RATIO: f64 = 0.2;

impl DropData {
    /// Checks that the first two impacts are as far apart as the hammer's free flight makes
    /// them: a quarter to four times its natural period `natural_period_s` (s) — half a period
    /// at gap 0, up to a whole one with a gap, longer for a wide pendulum swing. A trace whose
    /// time column was read in the wrong unit is off by a factor of 1000.
    ///
    /// # Errors
    /// The spacing is outside that range (said with both times and the flags to check).
    pub fn check_spacing(&self, natural_period_s: f64) -> Result<()> {
        let [first, second, ..] = self.impacts[..] else {
            return Ok(());
        };
        let spacing = second.centroid_s - first.centroid_s;
        ensure!(
            (0.25 * natural_period_s..=4.0 * natural_period_s).contains(&spacing),
            "its first two impacts are {spacing:.4e} s apart, where this rig's hammer flies \
             {:.3}–{:.3} s between impacts (half to one natural period, {natural_period_s:.3} s, \
             with a margin): is the time column's unit right (--time-unit, or \
             --sample-rate-hz)?",
            0.25 * natural_period_s,
            4.0 * natural_period_s
        );
        Ok(())
    }
}

/// The median of `v` (reordered; selection, not a sort).
fn median(v: &mut [f64]) -> f64 {
    let n = v.len();
    let (below, mid, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    let mid = *mid;
    if n % 2 == 1 {
        mid
    } else {
        0.5 * (below.iter().copied().fold(f64::NEG_INFINITY, f64::max) + mid)
    }
}

/// Least-squares parabola through `(t, f)`: the vertex `(t*, f*)` if it opens downward.
fn parabola_vertex(t: &[f64], f: &[f64]) -> Option<(f64, f64)> {
    let t0 = t[t.len() / 2];
    // f = a + b x + c x², x = t − t0.
    let design = DMatrix::from_fn(t.len(), 3, |i, k| (t[i] - t0).powi(k as i32));
    let a = least_squares(design, DVector::from_column_slice(f))?;
    let (b, c) = (a[1], a[2]);
    if c >= 0.0 {
        return None;
    }
    let x = -b / (2.0 * c);
    Some((t0 + x, a[0] + b * x + c * x * x))
}

/// The peak force of the impact whose run above the threshold is samples `a..=b` of `f` (times
/// `t`): the vertex of a least-squares parabola through the 5 samples around the largest one,
/// when all 5 are above 80 % of it and the vertex lies between the largest one's neighbours;
/// else the largest sample.
pub(crate) fn peak_estimate(t: &[f64], f: &[f64], a: usize, b: usize) -> f64 {
    let imax = (a..=b).max_by(|&i, &j| f[i].total_cmp(&f[j])).unwrap_or(a);
    let mut peak = f[imax];
    if imax >= a + 2
        && imax + 2 <= b
        && (imax - 2..=imax + 2).all(|i| f[i] > 0.8 * f[imax])
        && let Some((tv, fv)) = parabola_vertex(&t[imax - 2..=imax + 2], &f[imax - 2..=imax + 2])
        && tv >= t[imax - 1]
        && tv <= t[imax + 1]
    {
        peak = fv;
    }
    peak
}

/// Finds the sensor offset, the noise level and the impacts of a measured drop test.
///
/// # Errors
/// No impact stands out of the noise (largest force below 10 σ), or the first is too weak to
/// time (its peak below twice the threshold).
pub fn analyse_drop(trace: &Trace, max_impacts: usize) -> Result<DropData> {
    analyse(trace.t_s.clone(), &trace.value, max_impacts, true)
}

/// [`analyse_drop`] of a noise redraw of the fit (the bootstrap) that is to show the measured
/// trace's `impacts`: the first `impacts` above the threshold, with no impact left out as too
/// weak to time (the measurement chose the impacts; a redraw only moves their noise).
///
/// # Errors
/// No impact stands out of the noise.
pub(crate) fn analyse_redraw(t_s: Vec<f64>, value: &[f64], impacts: usize) -> Result<DropData> {
    analyse(t_s, value, impacts, false)
}

/// The samples of `value` (at times `t_s`) that show the sensor at rest, for its offset and
/// noise: where the trace is a board capture (`rig capture`: runs of consecutive samples with
/// gaps between them, one run per trigger), the first samples of each run, recorded before its
/// trigger (at most a quarter of the run, at most the board's own baseline,
/// `shared::identify::pulse::BASELINE_SAMPLES`): a power law's pulse can fill most of a
/// segment. Else every sample (an impact is a small part of a continuous record).
fn rest_samples(t_s: &[f64], value: &[f64]) -> Vec<f64> {
    let spans = contiguous_spans(t_s);
    if spans.len() < 2 {
        return value.to_vec();
    }
    let mut rest = Vec::new();
    for (from, to) in spans {
        let take = ((to + 1 - from) / 4).min(shared::identify::pulse::BASELINE_SAMPLES);
        rest.extend_from_slice(&value[from..from + take]);
    }
    if rest.is_empty() {
        value.to_vec()
    } else {
        rest
    }
}

/// The index spans `(first, last)` of `t_s` sampled without a gap (a step over 1.5 times the
/// first one ends a span): one for a continuous record, one per segment for a board capture.
fn contiguous_spans(t_s: &[f64]) -> Vec<(usize, usize)> {
    let Some(step) = t_s.get(1).map(|b| b - t_s[0]) else {
        return vec![(0, t_s.len().saturating_sub(1))];
    };
    let mut spans = Vec::new();
    let mut from = 0;
    for i in 1..t_s.len() {
        if t_s[i] - t_s[i - 1] > 1.5 * step {
            spans.push((from, i - 1));
            from = i;
        }
    }
    spans.push((from, t_s.len() - 1));
    spans
}

/// [`analyse_drop`] of the samples `value` at times `t_s` (kept in the result), leaving out the
/// impacts too weak to time where `cut_weak`.
fn analyse(t_s: Vec<f64>, value: &[f64], max_impacts: usize, cut_weak: bool) -> Result<DropData> {
    // One scratch buffer for both medians (the bootstrap analyses hundreds of redraws).
    let mut scratch = rest_samples(&t_s, value);
    let offset = median(&mut scratch);
    let f: Vec<f64> = value.iter().map(|v| v - offset).collect();
    for d in scratch.iter_mut() {
        *d = (*d - offset).abs();
    }
    let mut dev = scratch;
    let sample_max = f.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    // The largest force held over three samples: a glitch of one or two samples far above
    // every impact is not one, and must not set the threshold above them.
    let held = f
        .windows(3)
        .map(|w| w[0].min(w[1]).min(w[2]))
        .fold(f64::NEG_INFINITY, f64::max);
    let (fmax, spike) = if held > 0.0 && held < SPIKE_RATIO * sample_max {
        (held, Some(sample_max))
    } else {
        (sample_max, None)
    };
    let own_noise = 1.4826 * median(&mut dev);
    let noise = own_noise.max(NOISE_FLOOR * fmax.abs());
    if fmax <= 10.0 * noise {
        // An impact presses the sensor: a trace whose pulses stand out below the offset was
        // recorded with the opposite sign.
        let fmin = f.iter().copied().fold(f64::INFINITY, f64::min);
        let inverted = if -fmin > 10.0 * noise {
            format!(
                "; its pulses point the other way ({:.4} N below the offset): an impact \
                 presses the sensor, so its force is positive — is the sensor's sign inverted? \
                 (negate the force column)",
                -fmin
            )
        } else {
            String::new()
        };
        // A largest sample that stands alone: a glitch, or contacts the sampling steps over.
        let alone = spike.map_or(String::new(), |s| {
            let dt = t_s[1] - t_s[0];
            format!(
                "; the largest sample, {s:.4} N, stands out alone (the largest held over \
                 three samples is the {fmax:.4} N above): a glitch, or contacts shorter than \
                 the sampling step ({:.4} ms, {:.0} Hz) — record faster (`rig capture` \
                 records at 100 kHz)",
                1e3 * dt,
                1.0 / dt
            )
        });
        anyhow::bail!(
            "no impact stands out of the noise: largest force {fmax:.4} N above the offset \
             {offset:.4} N, noise {noise:.4} N{inverted}{alone}"
        );
    }
    let t = &t_s;
    let threshold = (5.0 * noise).max(0.03 * fmax);
    // Runs above the threshold.
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut start = None;
    for (i, &fi) in f.iter().enumerate() {
        match (fi > threshold, start) {
            (true, None) => start = Some(i),
            (false, Some(a)) => {
                runs.push((a, i - 1));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(a) = start {
        runs.push((a, f.len() - 1));
    }
    // Merge re-contacts, drop isolated noise spikes.
    let mut merged: Vec<(usize, usize)> = Vec::new();
    for r in runs {
        if let Some(last) = merged.last_mut() {
            let len = t[last.1] - t[last.0];
            if t[r.0] - t[last.1] < 2.0 * len.max(t[1] - t[0]) {
                last.1 = r.1;
                continue;
            }
        }
        merged.push(r);
    }
    // An impact spans three samples at least; shorter runs cannot be timed.
    let short = merged
        .iter()
        .map(|&(a, b)| b - a + 1)
        .filter(|&len| len < 3);
    let (short_runs, longest_short) = (short.clone().count(), short.max().unwrap_or(0));
    merged.retain(|&(a, b)| b >= a + 2);
    let spans = contiguous_spans(t);
    let mut impacts = Vec::new();
    let mut too_weak = None;
    for (a, b) in merged.into_iter().take(max_impacts) {
        let pad = (b - a).div_ceil(2).max(3);
        // Within the pulse's own segment where the record is a board capture.
        let (from, to) = spans
            .iter()
            .copied()
            .find(|&(from, to)| from <= a && a <= to)
            .unwrap_or((0, f.len() - 1));
        let window = (a.saturating_sub(pad).max(from), (b + pad).min(to));
        let peak = peak_estimate(t, &f, a, b);
        if cut_weak && peak < 2.0 * threshold {
            too_weak = Some((peak, threshold));
            break;
        }
        let (mut sf, mut stf) = (0.0, 0.0);
        for i in window.0..=window.1 {
            sf += f[i];
            stf += t[i] * f[i];
        }
        let half: Vec<usize> = (a..=b).filter(|&i| f[i] > 0.5 * peak).collect();
        let dt = t[1] - t[0];
        let fwhm = match (half.first(), half.last()) {
            (Some(&i), Some(&j)) => t[j] - t[i] + dt,
            _ => dt,
        };
        impacts.push(MeasuredImpact {
            peak_n: peak,
            centroid_s: stf / sf,
            fwhm_s: fwhm,
            window,
            run: (a, b),
        });
    }
    if impacts.is_empty() {
        let why = match too_weak {
            Some((p, thr)) => format!(
                ": the first, peak {p:.4} N, is below twice the detection threshold {thr:.4} N"
            ),
            None if short_runs > 0 => format!(
                ": {} above the detection threshold {threshold:.4} N, each for {} at \
                 most, fewer than the 3 that time an impact ({:.0} Hz): contacts shorter than \
                 the sampling can follow — record faster (`rig capture` records at 100 kHz)",
                crate::output::count(short_runs as u64, "pulse"),
                crate::output::count(longest_short as u64, "sample"),
                1.0 / (t[1] - t[0])
            ),
            None => String::new(),
        };
        anyhow::bail!("no impact found in the trace{why}");
    }
    Ok(DropData {
        t_s,
        force_n: f,
        offset_n: offset,
        noise_n: noise,
        noise_floored: own_noise < noise,
        impacts,
        too_weak,
        spike_n: spike,
    })
}

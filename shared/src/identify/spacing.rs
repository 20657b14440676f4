//! The suspension from the impacts' spacing. Released against the surface at its rest position
//! (gap 0), the hammer leaves the surface (`δ = 0`) with some speed and, free, returns to it
//! after half a damped period `π / ω_d` whatever that speed (the linear oscillator's
//! isochronism; the pendulum's amplitude correction `θ₀²/16` is 1e-4 at 3 mm on 75 mm wires).
//! The speed lost on the way gives the damping ratio: `v_in / v_out = exp(−π ζ / √(1 − ζ²))`.
//! Each contact returns `e` of its arrival speed, `e` the fitted law's restitution (a function
//! of the law's shape alone), so successive impulses `J = m (1 + e) v_in` fall by `e` times that
//! ratio: `ln r = ln(J_{k+1} / J_k) − ln e`. The impulses are the pulses' best-measured numbers
//! (a sum over the whole pulse), and `e` comes from all pulses at once; the ratio of one pulse's
//! departure speed to the next one's arrival speed would carry the weaker pulse's arrival-speed
//! error and its `J` error times `(1 + e) / e` (≈ 4 at `e = 0.317`).
//! Arrival and departure times and speeds come from each pulse's fitted line
//! ([`super::linear_fit`]), to a fraction of a sample.

use crate::capture::{SEGMENT_LEN, SEGMENTS};

use super::linear_fit::centred;
use super::record::SAMPLE_PERIOD_S;
use super::{DropRefusal, PulseSummary, ln};

/// Largest deviation of a half period from the median, as a fraction (two drops or a rattling
/// release put impacts off time by much more).
pub const MAX_SPACING_DEVIATION: f32 = 0.02;

/// One impact's timing and speeds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Kinematics {
    /// Segment start, samples since arming.
    pub start: u32,
    /// The pulse window's centre in its segment, samples.
    pub centre: f32,
    /// Arrival (`δ = 0` inwards) from the centre, samples.
    pub arrival: f32,
    /// Departure (`δ = 0` outwards) from the centre, samples.
    pub departure: f32,
    /// Approach speed at the surface, m/s (> 0).
    pub v_arrival: f32,
    /// Penetration rate after the contact, m/s (< 0: leaving).
    pub v_out: f32,
    /// Peak force, N.
    pub peak_n: f32,
}

impl Kinematics {
    /// The kinematics of pulse `s` whose fitted law gives it the rate `v0` (m/s) at its first
    /// sample and the arrival `t0` (samples from its window's centre), for the mass `m` (kg):
    /// the same for any law, from the force's integrals.
    #[inline(never)]
    pub(super) fn of(s: &PulseSummary, (v0, t0): (f32, f32), m: f32) -> Kinematics {
        let dt = SAMPLE_PERIOD_S;
        let t_first = centred(0, s.len);
        let v_arrival = if t0 < t_first {
            v0 + dt * s.first_n * (t_first - t0) / m
        } else {
            v0
        };
        // The force falls to 0 within the sample after the window (linear to the next sample).
        let drop = s.last_n - s.after_n;
        let frac = if drop > 0.0 {
            (s.last_n / drop).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let t_end = centred(s.len - 1, s.len) + frac;
        let i_end = s.int1_last + 0.5 * s.last_n * frac;
        let ii_end = s.int2_last + s.int1_last * frac + s.last_n * frac * frac / 3.0;
        let v_out = v0 - dt * i_end / m;
        let departure = (v0 * t0 + dt / m * (ii_end - i_end * t_end)) / v_out;
        Kinematics {
            start: s.start,
            centre: s.first as f32 + 0.5 * (s.len as f32 - 1.0),
            arrival: t0,
            departure,
            v_arrival,
            v_out,
            peak_n: s.peak_n,
        }
    }
}

/// What the spacing fixed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SuspensionId {
    /// Natural frequency `ω/2π`, Hz.
    pub natural_freq_hz: f32,
    /// Largest deviation of one half period from their mean, %.
    pub spread_pct: f32,
    /// Damping ratio `ζ` from the speed lost in free flight (0 when the speeds show none).
    pub damping_ratio: f32,
    /// Half periods measured.
    pub halves: u16,
}

/// Time from impact `a`'s departure to `b`'s arrival, samples.
fn flight(a: &Kinematics, b: &Kinematics) -> f32 {
    b.start.wrapping_sub(a.start) as f32 + (b.centre + b.arrival) - (a.centre + a.departure)
}

/// The suspension from the impacts `kin` (in order), `restitution` the fitted law's at each
/// impact's approach speed.
///
/// # Errors
/// [`DropRefusal::IrregularSpacing`] when a flight is off the others' median by more than
/// [`MAX_SPACING_DEVIATION`]; [`DropRefusal::TrainStopped`] when `kin` ends the record
/// (`train_end`: the trigger level, N, and the record's samples), the capture ran on past the
/// next impact's time and that impact should have crossed the trigger level twice over.
pub(super) fn suspension(
    kin: &[Kinematics],
    restitution: &[f32],
    train_end: Option<(f32, u32)>,
) -> Result<SuspensionId, DropRefusal> {
    let halves = kin.len().saturating_sub(1).min(SEGMENTS);
    let mut h = [0.0f32; SEGMENTS];
    for (j, w) in kin.windows(2).enumerate() {
        h[j] = flight(&w[0], &w[1]);
    }
    let mut sorted = h;
    let med = super::median(&mut sorted[..halves]);
    let dt_ms = SAMPLE_PERIOD_S * 1e3;
    for (j, &x) in h.iter().enumerate().take(halves) {
        let off = libm::fabsf(x - med);
        if off.is_nan() || off > MAX_SPACING_DEVIATION * med {
            return Err(DropRefusal::IrregularSpacing {
                impact: (j + 1) as u16,
                spacing_ms: x * dt_ms,
                expected_ms: med * dt_ms,
            });
        }
    }
    let mean = h[..halves].iter().sum::<f32>() / halves as f32;
    let spread = h[..halves]
        .iter()
        .map(|&x| libm::fabsf(x - mean))
        .fold(0.0f32, f32::max);
    // Each half's log impulse ratio, weighted by the later impact's peak squared (its
    // impulse's signal-to-noise ratio squared), less the contact's share: with `J = m (1 + e)
    // v_in`, `J_{k+1} / J_k = r e_k (1 + e_{k+1}) / (1 + e_k)`. The share is taken as `e_0`
    // and each half's departure from it (exactly 1 where `e` does not change with speed).
    let impulse = |k: &Kinematics| k.v_arrival - k.v_out;
    let e_ref = restitution.first().copied().unwrap_or(1.0);
    let (mut ln_j, mut wsum) = (0.0f32, 0.0f32);
    for (j, w) in kin.windows(2).enumerate() {
        let weight = w[1].peak_n * w[1].peak_n;
        let e = |i: usize| restitution.get(i).copied().unwrap_or(e_ref);
        let (e0, e1) = (e(j), e(j + 1));
        let share = (e0 * (1.0 + e1)) / ((1.0 + e0) * e_ref);
        ln_j += weight * (ln(impulse(&w[1]) / impulse(&w[0])) - ln(share));
        wsum += weight;
    }
    let ln_r = ln_j / wsum - ln(e_ref);
    let pi = core::f32::consts::PI;
    let zeta = (-ln_r / libm::sqrtf(pi * pi + ln_r * ln_r)).max(0.0);
    let omega_d = pi / (mean * SAMPLE_PERIOD_S);
    let omega_n = omega_d / libm::sqrtf(1.0 - zeta * zeta);
    if let (Some(last), Some((level_n, samples))) = (kin.last(), train_end)
        && kin.len() < SEGMENTS
    {
        let next = last.start as f32 + last.centre + last.departure + mean;
        let speed = -last.v_out * libm::expf(ln_r);
        let expected = last.peak_n * speed / last.v_arrival;
        if expected > 2.0 * level_n && next + (SEGMENT_LEN as f32) < samples as f32 {
            return Err(DropRefusal::TrainStopped {
                impacts: kin.len() as u16,
                expected_n: expected,
            });
        }
    }
    Ok(SuspensionId {
        natural_freq_hz: omega_n / (2.0 * pi),
        spread_pct: 100.0 * spread / mean,
        damping_ratio: zeta,
        halves: halves as u16,
    })
}

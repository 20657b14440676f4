//! Extremum seeking in frequency: keep the measured regime at `1/1` and climb to the largest
//! measured peak force inside the model's predicted `1/1` band; on regime loss step back toward
//! the model's target.
//!
//! Each call to [`HillClimber::next_freq_hz`] is one evaluation (the controller measures for a
//! few cycles at a frequency, then asks where to go). The climber probes alternately above and
//! below a centre frequency, half a first step (`step_hz / 2`) away, and compares each probe
//! with the mean of the two around it on the other side: a force that changes in time at a
//! steady rate (a rig whose natural frequency drifts with temperature or wear) cancels from
//! that difference, where a climber comparing each measurement with the one before would read
//! it as slope. When one side is better by more than `improve_rel` the centre moves toward it
//! by a step that starts at `step_hz`, halves at each reversal down to `min_step_hz` and
//! doubles (up to `step_hz`) when a move repeats; a full step toward the side just probed lands
//! that probe on the new centre's other side, where it counts, so a steady climb decides every
//! two or three evaluations. Every frequency is spread in phase
//! ([`phase_spread_freq_hz`]) so that the sampling error of the peaks cancels in each window's
//! mean.

use super::config::{SAMPLE_RATE_HZ, TrackSettings};
use super::within;
use crate::observe::Regime;

/// The hill climber.
#[derive(Debug, Clone, Copy)]
pub struct HillClimber {
    settings: TrackSettings,
    /// The frequency the probes straddle, Hz.
    centre_hz: f32,
    /// The next move's size, Hz.
    move_hz: f32,
    /// The last move's direction (+1 up, −1 down, 0 none yet).
    last_move: f32,
    /// The side of the centre being measured (+1 above, −1 below, 0 at the centre).
    side: f32,
    /// The last two probes' strengths, older first (the newer on the side opposite `side`).
    probes: [Option<f32>; 2],
    band_hz: [f32; 2],
    target_hz: f32,
}

impl HillClimber {
    /// Climbs within `band_hz` (the predicted `1/1` band ∩ the safe window) from `target_hz`
    /// (measured first, then probed above and below).
    pub fn new(settings: &TrackSettings, band_hz: [f32; 2], target_hz: f32) -> Self {
        HillClimber {
            settings: *settings,
            centre_hz: target_hz,
            move_hz: settings.step_hz,
            last_move: 0.0,
            side: 0.0,
            probes: [None, None],
            band_hz,
            target_hz,
        }
    }

    /// The first frequency to drive, Hz: the target (kept where both probes fit the band),
    /// spread in phase for the measurement.
    pub fn start_hz(&mut self) -> f32 {
        self.at(0.0)
    }

    /// The model's target, Hz.
    pub fn target_hz(&self) -> f32 {
        self.target_hz
    }

    /// The frequency the probes straddle, Hz.
    pub fn centre_hz(&self) -> f32 {
        self.centre_hz
    }

    /// The next move's size, Hz.
    pub fn step_hz(&self) -> f32 {
        self.move_hz
    }

    /// The probes' distance from the centre, Hz: half the first step (0.02 Hz by default; on
    /// the wire rig's flat `1/1` plateau a ±0.04 Hz probe reads noise as slope and wanders off
    /// it).
    fn probe_hz(&self) -> f32 {
        0.5 * self.settings.step_hz
    }

    /// Next frequency (Hz) after measuring `regime` and the impact `strength` at `freq_hz`
    /// (any measure that grows with the impact strength: the controller passes the mean peak
    /// force over the window, N). Always inside the band.
    pub fn next_freq_hz(&mut self, freq_hz: f32, regime: Regime, strength: Option<f32>) -> f32 {
        let strength = match (regime, strength) {
            (Regime::ONE_ONE, Some(f)) => f,
            _ => {
                // Lost 1/1: back toward the model's target, start afresh from there.
                self.probes = [None, None];
                self.side = 0.0;
                self.last_move = 0.0;
                self.move_hz = self.settings.step_hz;
                let to_target = self.target_hz - freq_hz;
                self.centre_hz = if to_target.abs() <= self.settings.step_hz {
                    self.target_hz
                } else {
                    freq_hz + self.settings.step_hz.copysign(to_target)
                };
                return self.at(0.0);
            }
        };
        let side = self.side;
        if side == 0.0 {
            // The centre's measurement only settles the response; the probes decide.
            self.side = 1.0;
            return self.at(1.0);
        }
        if let [Some(s1), Some(s2)] = self.probes {
            // s1 and `strength` on this side, s2 between them in time on the other: a force
            // that drifts linearly in time cancels from the difference.
            let here = 0.5 * (s1 + strength);
            let gain = side * (here - s2);
            if gain.abs() > self.settings.improve_rel * here.max(s2) {
                let d = if gain > 0.0 { 1.0 } else { -1.0 };
                self.move_hz = if self.last_move == -d {
                    (0.5 * self.move_hz).max(self.settings.min_step_hz)
                } else if self.last_move == d {
                    (2.0 * self.move_hz).min(self.settings.step_hz)
                } else {
                    self.move_hz
                };
                self.last_move = d;
                self.centre_hz += d * self.move_hz;
                // A move of two probe offsets toward the side just measured lands that probe's
                // frequency on the new centre's other side: it counts there.
                let reuse = side == d && (self.move_hz - 2.0 * self.probe_hz()).abs() < 1e-6;
                self.probes = [None, if reuse { Some(strength) } else { None }];
                self.side = d;
                let moved_to = self.centre_hz;
                let f = self.at(d);
                if self.centre_hz != moved_to {
                    // Held back by the band's edge: the kept probe is not where it counts.
                    self.probes = [None, None];
                }
                return f;
            }
        }
        self.probes = [self.probes[1], Some(strength)];
        self.side = -side;
        self.at(-side)
    }

    /// The frequency on `side` of the centre (the centre kept where both probes fit the band),
    /// spread in phase for the measurement.
    fn at(&mut self, side: f32) -> f32 {
        let [lo, hi] = self.band_hz;
        let d = self.probe_hz();
        self.centre_hz = if hi - lo > 2.0 * d {
            within(self.centre_hz, lo + d, hi - d)
        } else {
            0.5 * (lo + hi)
        };
        let f = phase_spread_freq_hz(self.centre_hz + side * d, self.settings.measure_cycles);
        within(f, lo, hi)
    }
}

/// The frequency nearest `freq_hz` (Hz) whose period spans `N + k / cycles` samples with `k`
/// coprime to `cycles` (with 8 cycles: within 1.5 steps of 1/8 sample on the period, ≤ 0.0005
/// Hz at 5 Hz): the impacts of `cycles` consecutive cycles of a periodic response then fall at
/// `cycles` evenly spread phases of the sampling grid, and the sampling error of each impact's
/// impulse and peak (a periodic function of that phase: ±0.9 % and ±2 % for the rig's 0.57 ms
/// pulses sampled at 10 kHz, the pulse spectrum at the sampling rate) cancels in their mean
/// over `cycles` (every harmonic of it but the multiples of `cycles`). At a period of a whole
/// number of samples plus a simple fraction it would not cancel, and the climber would read a
/// ±1 % ripple in frequency as force. `freq_hz` not a positive finite number, or `cycles` 0 or
/// 1: unchanged.
pub fn phase_spread_freq_hz(freq_hz: f32, cycles: u16) -> f32 {
    if !freq_hz.is_finite() || freq_hz <= 0.0 || cycles < 2 {
        return freq_hz;
    }
    let m = u32::from(cycles);
    let fs = SAMPLE_RATE_HZ as f32;
    // Samples per period in units of 1/m; at 2 Hz and m = 8: 40,000 (exact in f32).
    let n = libm::roundf(fs / freq_hz * m as f32) as u32;
    let coprime = |k: u32| gcd(k % m, m) == 1;
    // The nearest n' with n' mod m coprime to m (1 always is: the search ends within m).
    let n = (0..m)
        .flat_map(|d| [n.wrapping_add(d), n.wrapping_sub(d)])
        .find(|&k| k > 0 && coprime(k))
        .unwrap_or(n);
    fs * m as f32 / n as f32
}

fn gcd(mut a: u32, mut b: u32) -> u32 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth force hill with its maximum of 96 N at 3.70 Hz.
    fn hill(f: f32) -> f32 {
        96.0 - 40.0 * (f - 3.70) * (f - 3.70)
    }

    /// Runs `n` evaluations from `start_hz` on `force(f, k)` (k the evaluation), returning the
    /// frequencies visited.
    fn climb(
        c: &mut HillClimber,
        start_hz: f32,
        n: usize,
        force: impl Fn(f32, usize) -> f32,
    ) -> std::vec::Vec<f32> {
        let mut f = start_hz;
        (0..n)
            .map(|k| {
                f = c.next_freq_hz(f, Regime::ONE_ONE, Some(force(f, k)));
                f
            })
            .collect()
    }

    // With probes at c ± δ (δ = 0.02 Hz), the hill's probe difference is 160 δ |c − 3.70| =
    // 3.2 |c − 3.70| N; the centre stops moving once that is ≤ improve_rel · 96 = 0.192 N, i.e.
    // |c − 3.70| ≤ 0.06 Hz, so every probe lies within 0.08 Hz of the peak, at ≥ 96 − 40 · 0.08²
    // = 95.744 N (99.73 %).
    const SETTLED_HZ: f32 = 0.08;

    #[test]
    fn climbs_to_the_maximum_and_probes_around_it() {
        let mut c = HillClimber::new(&TrackSettings::default(), [2.2, 4.7], 3.45);
        let visited = climb(&mut c, 3.45, 80, |f, _| hill(f));
        let tail = &visited[50..];
        for &v in tail {
            assert!((v - 3.70).abs() <= SETTLED_HZ + 1e-3, "{tail:?}");
            assert!(hill(v) >= 95.74, "{tail:?}");
        }
        // It probes on both sides of the centre, 0.02 Hz away (plus the phase spread's 0.0003).
        let (lo, hi) = tail
            .iter()
            .fold((f32::INFINITY, 0.0f32), |(a, b), &v| (a.min(v), b.max(v)));
        assert!(hi - lo > 0.039, "{tail:?}");
    }

    #[test]
    fn starting_above_the_peak_it_turns_around() {
        let mut c = HillClimber::new(&TrackSettings::default(), [2.2, 4.7], 4.2);
        let visited = climb(&mut c, 4.2, 80, |f, _| hill(f));
        for &v in &visited[50..] {
            assert!((v - 3.70).abs() <= SETTLED_HZ + 1e-3, "{visited:?}");
        }
    }

    #[test]
    fn a_force_that_only_grows_in_time_does_not_move_it() {
        // No frequency dependence, +0.5 % per evaluation (a rig warming up): each probe is
        // compared with the mean of its neighbours in time, so a linear trend cancels; a
        // climber comparing successive measurements would walk one way for ever.
        let mut c = HillClimber::new(&TrackSettings::default(), [2.2, 4.7], 3.7);
        let visited = climb(&mut c, 3.7, 60, |_, k| 96.0 * (1.0 + 0.005 * k as f32));
        assert!((c.centre_hz() - 3.7).abs() < 1e-6, "{visited:?}");
        for &v in &visited {
            assert!((v - 3.7).abs() <= 0.021, "{visited:?}");
        }
    }

    #[test]
    fn follows_a_drifting_maximum_whose_height_grows() {
        // The peak moves up 0.005 Hz and grows 0.3 % per evaluation (a natural frequency rising
        // 10 % over ~70 evaluations, ~4.5 min of tracking). A move takes three probes to
        // decide and is at most 0.04 Hz, so the centre keeps within the settled band (0.06 Hz)
        // plus one move (0.04 Hz) of the peak; the probes within 0.12 Hz, at ≥ 99.4 % of the
        // peak (40 · 0.12² / 96 = 0.6 %).
        let peak = |k: usize| 3.70 + 0.005 * k as f32;
        let force = |f: f32, k: usize| {
            let d = f - peak(k);
            (96.0 - 40.0 * d * d) * (1.0 + 0.003 * k as f32)
        };
        let mut c = HillClimber::new(&TrackSettings::default(), [2.2, 4.7], 3.7);
        let visited = climb(&mut c, 3.7, 80, force);
        for (k, &v) in visited.iter().enumerate().skip(10) {
            assert!((v - peak(k)).abs() <= 0.12, "{k}: {v} vs {}", peak(k));
        }
        assert!(visited[79] > 3.95, "{}", visited[79]);
    }

    #[test]
    fn on_a_steady_slope_a_full_step_takes_two_or_three_probes() {
        // Always better upward. Evaluation 1 is the centre's; 2–4 probe above, below, above and
        // decide a full step (0.04 Hz), which lands probe 4 (above) on the new centre's lower
        // side, where it counts: 5–6 decide the next; 6 was below, so 7–9 need three again,
        // then 10–11 two, … Moves after 4, 6, 9, 11, …, 36, 39: 15 · 0.04 = 0.60 Hz (without
        // the reuse, every three evaluations after 4, 7, …, 40: 13 · 0.04 = 0.52 Hz).
        let mut c = HillClimber::new(&TrackSettings::default(), [2.2, 4.7], 3.7);
        climb(&mut c, 3.7, 40, |f, _| 96.0 + 10.0 * (f - 3.7));
        assert!((c.centre_hz() - 4.30).abs() < 1e-4, "{}", c.centre_hz());
    }

    #[test]
    fn regime_loss_steps_back_toward_the_target_and_the_band_is_never_left() {
        let mut c = HillClimber::new(&TrackSettings::default(), [3.0, 3.5], 3.2);
        let f = c.next_freq_hz(3.45, Regime::Periodic { p: 1, q: 2 }, Some(150.0));
        assert!((f - 3.41).abs() < 1e-3, "{f}");
        let f = c.next_freq_hz(3.21, Regime::Irregular, None);
        assert!((f - 3.2).abs() < 1e-3, "{f}");
        // A force rising forever toward the band edge: the probes stop at the edge.
        let visited = climb(&mut c, f, 60, |f, _| f * 10.0);
        for &v in &visited {
            assert!((3.0..=3.5).contains(&v), "{v}");
        }
        assert!(visited[59] > 3.45, "{visited:?}");
    }

    /// The mean over `m` cycles of a sampling error `cos(2π φ)`, φ the sub-sample phase of the
    /// cycle's impact (advancing by the period in samples each cycle).
    fn mean_phase_error(freq_hz: f32, m: u16) -> f64 {
        let x = f64::from(SAMPLE_RATE_HZ) / f64::from(freq_hz);
        (0..m)
            .map(|j| (2.0 * core::f64::consts::PI * (f64::from(j) * x).fract()).cos())
            .sum::<f64>()
            / f64::from(m)
    }

    #[test]
    fn the_phase_spread_cancels_the_sampling_error_over_the_window() {
        // 10 kHz / 3.7037… Hz = 2,700 samples: every impact at the same sampling phase, the
        // error does not average (mean 1); snapped, the 8 phases are evenly spread (mean 0).
        assert!(mean_phase_error(10_000.0 / 2_700.0, 8) > 0.999);
        for f in [2.0f32, 3.6404, 10_000.0 / 2_700.0, 3.705, 4.5, 5.0] {
            for m in [2u16, 5, 8, 12] {
                let g = phase_spread_freq_hz(f, m);
                // The nearest coprime residue is ≤ 2 steps of 1/m sample away for these m (12:
                // from 3 or 9), plus half a step of rounding; a step is f² / (fs m) Hz.
                assert!(
                    (g - f).abs() <= 2.5 * f * f / (10_000.0 * f32::from(m)),
                    "{f} → {g} (m {m})"
                );
                let e = mean_phase_error(g, m);
                assert!(e.abs() < 1e-2, "{f} → {g} (m {m}): {e}");
            }
        }
        assert_eq!(phase_spread_freq_hz(3.7, 1), 3.7);
        assert_eq!(phase_spread_freq_hz(-1.0, 8), -1.0);
        assert!(phase_spread_freq_hz(f32::NAN, 8).is_nan());
    }
}

//! Extremum seeking in frequency: keep the measured regime at `1/1` and climb to the largest
//! measured impact strength (the controller climbs on the impulse per cycle, which peaks where
//! the peak force does) by small frequency steps inside the model's predicted `1/1` band; on
//! regime loss step back toward the model's target.
//!
//! Each call to [`HillClimber::next_freq_hz`] is one evaluation (the controller measures for a
//! few cycles at a frequency, then asks where to go). The step halves at every reversal down to
//! `min_step_hz`, so the frequency ends up dithering by `min_step_hz` around the force maximum.

use super::config::TrackSettings;
use super::within;
use crate::observe::Regime;

/// The hill climber.
#[derive(Debug, Clone, Copy)]
pub struct HillClimber {
    settings: TrackSettings,
    step_hz: f32,
    direction: f32,
    /// The strength measured at the previous evaluation.
    last_strength: Option<f32>,
    band_hz: [f32; 2],
    target_hz: f32,
}

impl HillClimber {
    /// Climbs within `band_hz` (the predicted `1/1` band ∩ the safe window), starting upward
    /// from `target_hz`.
    pub fn new(settings: &TrackSettings, band_hz: [f32; 2], target_hz: f32) -> Self {
        HillClimber {
            settings: *settings,
            step_hz: settings.step_hz,
            direction: 1.0,
            last_strength: None,
            band_hz,
            target_hz,
        }
    }

    /// The model's target, Hz.
    pub fn target_hz(&self) -> f32 {
        self.target_hz
    }

    /// Current step, Hz.
    pub fn step_hz(&self) -> f32 {
        self.step_hz
    }

    /// Next frequency (Hz) after measuring `regime` and the impact `strength` at `freq_hz`
    /// (any measure that grows with the impact strength: the controller passes the mean impulse
    /// per cycle, N·s). Always inside the band.
    pub fn next_freq_hz(&mut self, freq_hz: f32, regime: Regime, strength: Option<f32>) -> f32 {
        let [lo, hi] = self.band_hz;
        let strength = match (regime, strength) {
            (Regime::ONE_ONE, Some(f)) => f,
            _ => {
                // Lost 1/1: back toward the model's target, start climbing afresh from there.
                self.last_strength = None;
                self.step_hz = self.settings.step_hz;
                let to_target = self.target_hz - freq_hz;
                self.direction = if to_target >= 0.0 { 1.0 } else { -1.0 };
                let next = if to_target.abs() <= self.step_hz {
                    self.target_hz
                } else {
                    freq_hz + self.direction * self.step_hz
                };
                return within(next, lo, hi);
            }
        };
        if let Some(last) = self.last_strength {
            let better = strength > last * (1.0 + self.settings.improve_rel);
            if !better {
                self.direction = -self.direction;
                self.step_hz = (self.step_hz * 0.5).max(self.settings.min_step_hz);
            }
        }
        self.last_strength = Some(strength);
        let mut next = freq_hz + self.direction * self.step_hz;
        if next > hi || next < lo {
            self.direction = -self.direction;
            next = freq_hz + self.direction * self.step_hz;
        }
        within(next, lo, hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth force hill with its maximum of 96 N at 3.70 Hz.
    fn hill(f: f32) -> f32 {
        96.0 - 40.0 * (f - 3.70) * (f - 3.70)
    }

    #[test]
    fn climbs_to_the_maximum_and_dithers_by_the_min_step() {
        let mut c = HillClimber::new(&TrackSettings::default(), [2.2, 4.7], 3.45);
        let mut f = 3.45;
        let mut visited = std::vec::Vec::new();
        for _ in 0..60 {
            f = c.next_freq_hz(f, Regime::ONE_ONE, Some(hill(f)));
            visited.push(f);
        }
        // It stops where the force changes by less than `improve_rel` (0.2 %) per step: within
        // 40 δ² ≤ 0.002 · 96, i.e. |δ| ≤ 0.069 Hz of the peak, at ≥ 99.8 % of the peak force.
        let tail = &visited[40..];
        for &v in tail {
            assert!((v - 3.70).abs() <= 0.07, "{tail:?}");
            assert!(hill(v) >= 0.998 * 96.0, "{tail:?}");
        }
        assert!((c.step_hz() - 0.01).abs() < 1e-6);
    }

    #[test]
    fn starting_above_the_peak_it_turns_around() {
        let mut c = HillClimber::new(&TrackSettings::default(), [2.2, 4.7], 4.2);
        let mut f = 4.2;
        for _ in 0..80 {
            f = c.next_freq_hz(f, Regime::ONE_ONE, Some(hill(f)));
        }
        // Coming down the slope with the halved step (0.02 Hz) it stops where a step gains
        // less than 0.2 %: |80 δ| · 0.02 ≤ 0.002 · 96, δ ≤ 0.12 Hz, ≥ 99.4 % of the peak.
        assert!((f - 3.70).abs() <= 0.12 && hill(f) >= 0.994 * 96.0, "{f}");
    }

    #[test]
    fn regime_loss_steps_back_toward_the_target_and_the_band_is_never_left() {
        let mut c = HillClimber::new(&TrackSettings::default(), [3.0, 3.5], 3.2);
        let f = c.next_freq_hz(3.45, Regime::Periodic { p: 1, q: 2 }, Some(150.0));
        assert!((f - 3.41).abs() < 1e-6);
        let f = c.next_freq_hz(3.21, Regime::Irregular, None);
        assert!((f - 3.2).abs() < 1e-6);
        // A force rising forever toward the band edge stops at the edge.
        let mut f = 3.2;
        for _ in 0..50 {
            f = c.next_freq_hz(f, Regime::ONE_ONE, Some(f * 10.0));
            assert!((3.0..=3.5).contains(&f));
        }
        assert!(f > 3.45, "{f}");
    }
}

//! Online impact detection on the force samples: a threshold with hysteresis opens an impact,
//! re-contacts within the refractory time after it closes belong to the same impact
//! (chattering), and the impact is reported once the refractory time has passed, with its peak
//! force and the sample index of the peak.

use super::config::{DetectorSettings, SAMPLE_RATE_HZ, samples};

/// Sampling period, s.
const SAMPLE_DT_S: f32 = 1.0 / SAMPLE_RATE_HZ as f32;

/// One detected impact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectedImpact {
    /// Peak force, N.
    pub peak_n: f32,
    /// Sample index of the peak.
    pub peak_sample: u64,
    /// Sample index where the force first crossed the threshold.
    pub start_sample: u64,
    /// The ADC was at a rail during the impact: the peak is a lower bound.
    pub saturated: bool,
    /// Impulse `Σ F·Δt` over the impact's samples with positive force (from the sample before
    /// the threshold crossing), N·s. Less sensitive to where the samples fall on the pulse than
    /// the peak (a 0.57 ms half-sine sampled every 100 µs: the largest sample varies by 3.1 %
    /// with the offset, the impulse by 1.9 %).
    pub impulse_n_s: f32,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum State {
    Idle,
    /// Above the threshold (or not yet below `threshold − hysteresis`).
    Open,
    /// Below; the impact closes at `until` unless the force rises again.
    Closing {
        until: u64,
    },
}

/// The impact detector. Feed every sample to [`ImpactDetector::update`].
#[derive(Debug, Clone)]
pub struct ImpactDetector {
    on_n: f32,
    off_n: f32,
    refractory: u64,
    state: State,
    current: DetectedImpact,
    /// The previous sample's force, N (the rising edge's first sample).
    last_n: f32,
}

impl ImpactDetector {
    /// A detector with validated settings ([`super::ControllerConfig::validate`]).
    pub fn new(settings: &DetectorSettings) -> Self {
        ImpactDetector {
            on_n: settings.threshold_n,
            off_n: settings.threshold_n - settings.hysteresis_n,
            refractory: u64::from(samples(settings.refractory_s, 0)),
            state: State::Idle,
            current: DetectedImpact {
                peak_n: 0.0,
                peak_sample: 0,
                start_sample: 0,
                saturated: false,
                impulse_n_s: 0.0,
            },
            last_n: 0.0,
        }
    }

    /// Forgets any impact in progress.
    pub fn reset(&mut self) {
        self.state = State::Idle;
    }

    /// Processes sample `index` of force `force_n` (N); `saturated` when the ADC code is at a
    /// rail. Returns the impact that closed at this sample, if any.
    pub fn update(&mut self, index: u64, force_n: f32, saturated: bool) -> Option<DetectedImpact> {
        let out = self.advance(index, force_n, saturated);
        self.last_n = force_n;
        out
    }

    fn advance(&mut self, index: u64, force_n: f32, saturated: bool) -> Option<DetectedImpact> {
        match self.state {
            State::Idle => {
                if force_n > self.on_n {
                    self.current = DetectedImpact {
                        peak_n: force_n,
                        peak_sample: index,
                        start_sample: index,
                        saturated,
                        impulse_n_s: (self.last_n.max(0.0) + force_n) * SAMPLE_DT_S,
                    };
                    self.state = State::Open;
                }
                None
            }
            State::Open => {
                self.track(index, force_n, saturated);
                if force_n < self.off_n {
                    self.state = State::Closing {
                        until: index.saturating_add(self.refractory),
                    };
                    if self.refractory == 0 {
                        self.state = State::Idle;
                        return Some(self.current);
                    }
                }
                None
            }
            State::Closing { until } => {
                if force_n > self.on_n {
                    self.track(index, force_n, saturated);
                    self.state = State::Open;
                    None
                } else if index >= until {
                    self.state = State::Idle;
                    Some(self.current)
                } else {
                    self.current.impulse_n_s += force_n.max(0.0) * SAMPLE_DT_S;
                    None
                }
            }
        }
    }

    fn track(&mut self, index: u64, force_n: f32, saturated: bool) {
        self.current.impulse_n_s += force_n.max(0.0) * SAMPLE_DT_S;
        if force_n > self.current.peak_n {
            self.current.peak_n = force_n;
            self.current.peak_sample = index;
        }
        self.current.saturated |= saturated;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::config::SAMPLE_RATE_HZ;

    /// A half-sine contact pulse of `peak_n` lasting `dur_s`, starting at `t0_s`.
    fn pulse(t_s: f64, t0_s: f64, dur_s: f64, peak_n: f64) -> f64 {
        if t_s >= t0_s && t_s <= t0_s + dur_s {
            peak_n * libm::sin(core::f64::consts::PI * (t_s - t0_s) / dur_s)
        } else {
            0.0
        }
    }

    /// Runs the detector over `n` samples of `force(t)`, with a rail at `rail_n`.
    fn detect(n: u64, rail_n: f64, force: impl Fn(f64) -> f64) -> std::vec::Vec<DetectedImpact> {
        let mut d = ImpactDetector::new(&DetectorSettings::default());
        let mut out = std::vec::Vec::new();
        for i in 0..n {
            let t = i as f64 / f64::from(SAMPLE_RATE_HZ);
            let f = force(t).min(rail_n);
            if let Some(imp) = d.update(i, f as f32, f >= rail_n) {
                out.push(imp);
            }
        }
        out
    }

    /// Deterministic noise, uniform in ±amp (xorshift).
    fn noise(seed: &mut u64, amp: f64) -> f64 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        (((*seed >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0) * amp
    }

    #[test]
    fn single_impact_peak_and_time() {
        // 96 N (32.85 mg) lasting 1.2 ms at t = 0.1 s: sampled at 10 kHz, the peak sample is the
        // sample nearest the pulse centre, 0.1006 s.
        let imps = detect(3000, 1e9, |t| pulse(t, 0.1, 0.0012, 96.0));
        assert_eq!(imps.len(), 1);
        let expected = 96.0 * libm::sin(core::f64::consts::PI * 0.0006 / 0.0012);
        assert!((f64::from(imps[0].peak_n) - expected).abs() < 1e-3);
        assert_eq!(imps[0].peak_sample, 1006);
        assert!(!imps[0].saturated);
    }

    #[test]
    fn impulse_is_insensitive_to_the_sampling_phase() {
        // A 96 N half-sine of 0.57 ms: impulse 2/π · 96 · 0.57e-3 = 34.84 mN·s, read within
        // 1.5 % (the rectangle rule over 5–6 samples) at every offset of the pulse within a
        // sample, varying less with the offset than the largest sample does.
        let exact = 2.0 / core::f64::consts::PI * 96.0 * 0.00057;
        let (mut pmin, mut pmax) = (f64::INFINITY, 0.0f64);
        let (mut imin, mut imax) = (f64::INFINITY, 0.0f64);
        for k in 0..10 {
            let t0 = 0.1 + f64::from(k) * 1e-5;
            let imps = detect(3000, 1e9, |t| pulse(t, t0, 0.00057, 96.0));
            assert_eq!(imps.len(), 1);
            let i = f64::from(imps[0].impulse_n_s);
            assert!((i / exact - 1.0).abs() < 0.015, "{k}: {i} vs {exact}");
            imin = imin.min(i);
            imax = imax.max(i);
            pmin = pmin.min(f64::from(imps[0].peak_n));
            pmax = pmax.max(f64::from(imps[0].peak_n));
        }
        assert!(pmax / pmin > 1.02, "the peak does vary: {pmin} .. {pmax}");
        // Measured: peak 93.06 .. 95.96 N (3.1 %), impulse 34.51 .. 35.15 mN·s (1.9 %).
        assert!(imax / imin < 1.02, "impulse {imin} .. {imax}");
        assert!(
            imax / imin - 1.0 < 0.7 * (pmax / pmin - 1.0),
            "impulse {imin} .. {imax}, peak {pmin} .. {pmax}"
        );
    }

    #[test]
    fn double_impact_separated_beyond_refractory_counts_twice() {
        let imps = detect(5000, 1e9, |t| {
            pulse(t, 0.1, 0.001, 80.0) + pulse(t, 0.12, 0.001, 40.0)
        });
        assert_eq!(imps.len(), 2);
        assert!(imps[0].peak_n > 79.0 && imps[1].peak_n > 39.0 && imps[1].peak_n < 40.1);
        assert!(((imps[1].peak_sample - imps[0].peak_sample) as i64 - 200).abs() <= 1);
    }

    #[test]
    fn chattering_within_refractory_is_one_impact_with_the_largest_peak() {
        // Three re-contacts 2 ms apart (refractory 5 ms): one impact, peak of the second.
        let imps = detect(5000, 1e9, |t| {
            pulse(t, 0.1, 0.001, 50.0)
                + pulse(t, 0.102, 0.001, 70.0)
                + pulse(t, 0.104, 0.0005, 10.0)
        });
        assert_eq!(imps.len(), 1);
        assert!((imps[0].peak_n - 70.0).abs() < 0.1);
        assert_eq!(imps[0].start_sample, 1001);
    }

    #[test]
    fn noise_below_the_threshold_is_ignored_and_does_not_split_an_impact() {
        // ±1.2 N noise (below the 3 N threshold; the hysteresis is 1.5 N) on a train of four
        // impacts of 30 N: exactly four impacts, peaks within the noise.
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        let mut d = ImpactDetector::new(&DetectorSettings::default());
        let mut imps = std::vec::Vec::new();
        for i in 0..20_000u64 {
            let t = i as f64 / 1e4;
            let f = (0..4)
                .map(|k| pulse(t, 0.3 + 0.45 * f64::from(k), 0.002, 30.0))
                .sum::<f64>()
                + noise(&mut seed, 1.2);
            if let Some(imp) = d.update(i, f as f32, false) {
                imps.push(imp);
            }
        }
        assert_eq!(imps.len(), 4);
        for imp in &imps {
            assert!((imp.peak_n - 30.0).abs() < 1.25, "{}", imp.peak_n);
        }
    }

    #[test]
    fn saturation_is_flagged_and_the_peak_is_the_rail() {
        let imps = detect(3000, 310.0, |t| pulse(t, 0.1, 0.002, 400.0));
        assert_eq!(imps.len(), 1);
        assert!(imps[0].saturated);
        assert!((imps[0].peak_n - 310.0).abs() < 1e-3);
    }
}

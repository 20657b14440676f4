//! The sensor at rest, measured: the commissioning's first step (the shaker controllers'
//! background-noise check) asks the controller to add up the next `n` force samples' codes,
//! with the drive off and the hammer still. Integer sums (no `f64` on the MCU's sampling path):
//! the mean, the standard deviation, the extremes and the rate at which the samples came.

/// What a finished probe found, in ADC codes and the samples' own clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RestStats {
    /// Samples read (codes), not counting those the ADC lost.
    pub samples: u32,
    /// Samples the ADC lost (overruns).
    pub lost: u32,
    /// Sum of the codes.
    pub sum: u64,
    /// Sum of the codes' squares.
    pub sum_sq: u64,
    /// Smallest code.
    pub min: u16,
    /// Largest code.
    pub max: u16,
    /// Time of the first sample, µs.
    pub first_us: u64,
    /// Time of the last sample, µs.
    pub last_us: u64,
}

impl RestStats {
    /// Mean code (0 without samples).
    pub fn mean_code(&self) -> f32 {
        if self.samples == 0 {
            return 0.0;
        }
        (self.sum as f64 / f64::from(self.samples)) as f32
    }

    /// Standard deviation of the codes (population; 0 with fewer than 2 samples).
    pub fn sd_code(&self) -> f32 {
        if self.samples < 2 {
            return 0.0;
        }
        let n = f64::from(self.samples);
        let mean = self.sum as f64 / n;
        let var = (self.sum_sq as f64 / n - mean * mean).max(0.0);
        libm::sqrt(var) as f32
    }

    /// The rate the samples came at, Hz, from their clock (0 when it did not move).
    pub fn rate_hz(&self) -> f32 {
        let span = self.last_us.saturating_sub(self.first_us);
        let n = self.samples + self.lost;
        if span == 0 || n < 2 {
            return 0.0;
        }
        (f64::from(n - 1) * 1e6 / span as f64) as f32
    }
}

/// A probe running: samples still to take, and what the taken ones add up to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RestProbe {
    remaining: u32,
    stats: RestStats,
}

impl RestProbe {
    /// A probe of the next `samples` samples.
    pub fn new(samples: u32) -> Self {
        RestProbe {
            remaining: samples,
            stats: RestStats {
                samples: 0,
                lost: 0,
                sum: 0,
                sum_sq: 0,
                min: u16::MAX,
                max: 0,
                first_us: 0,
                last_us: 0,
            },
        }
    }

    /// One sample (`None`: the ADC lost it) at `now_us`.
    pub fn push(&mut self, code: Option<u16>, now_us: u64) {
        if self.remaining == 0 {
            return;
        }
        self.remaining -= 1;
        let s = &mut self.stats;
        if s.samples + s.lost == 0 {
            s.first_us = now_us;
        }
        s.last_us = now_us;
        match code {
            Some(c) => {
                s.samples += 1;
                s.sum += u64::from(c);
                s.sum_sq += u64::from(c) * u64::from(c);
                s.min = s.min.min(c);
                s.max = s.max.max(c);
            }
            None => s.lost += 1,
        }
    }

    /// The statistics, once every sample asked for was taken.
    pub fn done(&self) -> Option<RestStats> {
        (self.remaining == 0).then_some(self.stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_statistics_are_the_codes_mean_spread_and_rate() {
        let mut p = RestProbe::new(1000);
        let mut reference = std::vec::Vec::new();
        for k in 0..1000u64 {
            // A deterministic wobble around 300 codes, one sample lost at k = 500.
            let c = 300 + ((k * 7919) % 11) as u16;
            let code = (k != 500).then_some(c);
            if let Some(c) = code {
                reference.push(f64::from(c));
            }
            assert!(p.done().is_none());
            p.push(code, 1_000 + 100 * k);
        }
        let s = p.done().unwrap();
        assert_eq!((s.samples, s.lost), (999, 1));
        let n = reference.len() as f64;
        let mean = reference.iter().sum::<f64>() / n;
        let sd = (reference
            .iter()
            .map(|x| (x - mean) * (x - mean))
            .sum::<f64>()
            / n)
            .sqrt();
        assert!((f64::from(s.mean_code()) - mean).abs() < 1e-4, "{s:?}");
        assert!(
            (f64::from(s.sd_code()) - sd).abs() < 1e-4,
            "{} vs {sd}",
            s.sd_code()
        );
        assert_eq!((s.min, s.max), (300, 310));
        assert!((s.rate_hz() - 10_000.0).abs() < 1e-3, "{}", s.rate_hz());
        // More samples change nothing.
        p.push(Some(4095), 1_000_000);
        assert_eq!(p.done(), Some(s));
    }
}

//! The sampling health check behind the watchdog: samples taken against time elapsed on an
//! independent time base (the firmware's SysTick monotonic), so a stalled or slowed sampling
//! stops feeding the watchdog. Counting samples per report alone cannot see this when the
//! sampling task itself triggers the report.

use crate::control::SAMPLE_RATE_HZ;

/// What a check found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Health {
    /// Sampling keeps at least 90 % of its rate (or this is the first check): feed the watchdog.
    Feed,
    /// Sampling fell behind: do not feed.
    Stalled {
        /// Samples taken since the last check.
        samples: u32,
        /// Samples due in that time.
        expected: u32,
    },
}

/// The check; call it periodically with the sample count and the time base's milliseconds.
#[derive(Debug, Clone, Copy, Default)]
pub struct HealthCheck {
    last: Option<(u64, u32)>,
}

impl HealthCheck {
    /// No check yet.
    pub const fn new() -> Self {
        HealthCheck { last: None }
    }

    /// `samples` taken so far at `now_ms` (wrapping millisecond counter).
    pub fn check(&mut self, samples: u64, now_ms: u32) -> Health {
        let Some((s0, t0)) = self.last.replace((samples, now_ms)) else {
            return Health::Feed;
        };
        let elapsed_ms = u64::from(now_ms.wrapping_sub(t0));
        let expected = elapsed_ms * u64::from(SAMPLE_RATE_HZ) / 1000;
        let done = samples.wrapping_sub(s0);
        if done.saturating_mul(10) >= expected.saturating_mul(9) {
            Health::Feed
        } else {
            Health::Stalled {
                samples: u32::try_from(done).unwrap_or(u32::MAX),
                expected: u32::try_from(expected).unwrap_or(u32::MAX),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stalled_or_slowed_sampling_stops_the_feeding() {
        let mut h = HealthCheck::new();
        assert_eq!(h.check(0, 0), Health::Feed);
        // 10 kHz for a second: fed.
        assert_eq!(h.check(10_000, 1000), Health::Feed);
        // A report that comes late (1.5 s) with the samples of 1.5 s: still fed. (A check that
        // counts samples per report would not know the time.)
        assert_eq!(h.check(25_000, 2500), Health::Feed);
        // Stalled: no samples in a second.
        assert_eq!(
            h.check(25_000, 3500),
            Health::Stalled {
                samples: 0,
                expected: 10_000
            }
        );
        // Slowed to 80 %: not fed; at 95 %: fed.
        assert!(matches!(h.check(33_000, 4500), Health::Stalled { .. }));
        assert_eq!(h.check(42_500, 5500), Health::Feed);
        // The millisecond counter wraps.
        let mut h = HealthCheck::new();
        h.check(0, u32::MAX - 499);
        assert_eq!(h.check(10_000, 500), Health::Feed);
    }
}

//! Faults: what aborts the drive, and the per-sample sensor checks that find them. A fault is
//! latched by the controller (the drive ramps to zero at the abort rate) until the operator
//! sends `clear`.

use super::config::{FaultSettings, samples};

/// Why the controller aborted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// An impact's peak force exceeded `force_limit_n`.
    OverForce,
    /// No impact for `no_signal_s` while driving at full amplitude after impacts had been seen,
    /// or within [`IMPACTS_EXPECTED_PCT`] of the model's target (where the model has `z = 1/1`
    /// at every point): the sensor or its cable is open.
    SensorOpen,
    /// The ADC sat at a rail for `rail_s` while the drive was on.
    SensorStuck,
    /// The ADC overran or timed out.
    AdcOverrun,
    /// The sampling task ran later than `deadline_us` after the previous sample.
    MissedDeadline,
    /// The configuration or the model's target is outside the allowed window.
    BadConfig,
    /// No console line (nor keep-alive) for the link timeout while the drive ran: the desktop
    /// that drove the rig is gone.
    LinkLost,
}

impl Fault {
    /// Every fault.
    pub const ALL: [Fault; 7] = [
        Fault::OverForce,
        Fault::SensorOpen,
        Fault::SensorStuck,
        Fault::AdcOverrun,
        Fault::MissedDeadline,
        Fault::BadConfig,
        Fault::LinkLost,
    ];
}

/// Half-width of the frequency window around the model's target inside which impacts are
/// expected from the first sample at full amplitude, %: the selection's robustness margin
/// (every point within ±5 % of the target is `z = 1/1` at the gap ± 0.1 mm,
/// `crate::analysis::selection`). Elsewhere the no-signal check waits for a first impact, since
/// a regime without impacts is legitimate there.
pub const IMPACTS_EXPECTED_PCT: f32 = 5.0;

/// Per-sample sensor checks: pinned at a rail, and no signal.
#[derive(Debug, Clone)]
pub struct SensorMonitor {
    rail_lo: u16,
    rail_hi: u16,
    rail_limit: u32,
    at_rail: u32,
    no_signal_min: u32,
    since_impact: u32,
    armed: bool,
}

impl SensorMonitor {
    /// A monitor with validated settings.
    pub fn new(settings: &FaultSettings) -> Self {
        SensorMonitor {
            rail_lo: settings.rail_margin_codes,
            rail_hi: crate::hal::ADC_MAX.saturating_sub(settings.rail_margin_codes),
            rail_limit: samples(settings.rail_s, 1),
            at_rail: 0,
            no_signal_min: samples(settings.no_signal_s, 1),
            since_impact: 0,
            armed: false,
        }
    }

    /// Whether `code` is at a rail.
    pub fn at_rail(&self, code: u16) -> bool {
        code <= self.rail_lo || code >= self.rail_hi
    }

    /// Forgets the no-signal history (the drive changed state).
    pub fn disarm(&mut self) {
        self.armed = false;
        self.since_impact = 0;
    }

    /// Checks one sample. `driving`: the drive is on; `full_drive`: at full amplitude in a
    /// measuring state; `impact`: an impact was reported at this sample; `expected_gap_samples`:
    /// the longest impact-free stretch the measured regime allows (`q` periods);
    /// `impacts_expected`: whether the model expects impacts at this frequency (then no first
    /// impact is waited for; asked only when that decides).
    pub fn check(
        &mut self,
        code: u16,
        driving: bool,
        full_drive: bool,
        impact: bool,
        expected_gap_samples: u32,
        impacts_expected: impl FnOnce() -> bool,
    ) -> Option<Fault> {
        if driving && self.at_rail(code) {
            self.at_rail = self.at_rail.saturating_add(1);
            if self.at_rail >= self.rail_limit {
                return Some(Fault::SensorStuck);
            }
        } else {
            self.at_rail = 0;
        }
        if !full_drive {
            self.disarm();
            return None;
        }
        if impact {
            self.armed = true;
            self.since_impact = 0;
            return None;
        }
        self.since_impact = self.since_impact.saturating_add(1);
        let limit = self
            .no_signal_min
            .max(expected_gap_samples.saturating_add(expected_gap_samples / 2));
        (self.since_impact > limit && (self.armed || impacts_expected()))
            .then_some(Fault::SensorOpen)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` impact-free samples `code` (drive on and at full amplitude as `driving`, the
    /// regime's longest impact-free stretch `expected_gap_samples`): no fault.
    fn assert_quiet(
        m: &mut SensorMonitor,
        n: u32,
        code: u16,
        driving: bool,
        expected_gap_samples: u32,
    ) {
        for i in 0..n {
            let f = m.check(code, driving, driving, false, expected_gap_samples, || {
                false
            });
            assert_eq!(f, None, "sample {i}");
        }
    }

    #[test]
    fn rail_for_twenty_ms_is_stuck_but_an_impact_at_the_rail_is_not() {
        let mut m = SensorMonitor::new(&FaultSettings::default());
        // A 5 ms saturated impact: no fault.
        assert_quiet(&mut m, 50, 4095, true, 0);
        assert_eq!(m.check(1000, true, true, true, 0, || false), None);
        // Pinned: the 200th consecutive rail sample (20 ms) trips.
        for i in 1..=200 {
            let f = m.check(0, true, true, false, 0, || false);
            assert_eq!(f.is_some(), i == 200, "{i}");
        }
        // Not while the drive is off.
        let mut m = SensorMonitor::new(&FaultSettings::default());
        assert_quiet(&mut m, 10_000, 4095, false, 0);
    }

    #[test]
    fn no_signal_needs_earlier_impacts_and_the_regime_period() {
        let mut m = SensorMonitor::new(&FaultSettings::default());
        // Never impacted: no fault however long (a no-impact regime is legitimate).
        assert_quiet(&mut m, 20_000, 250, true, 2733);
        // After an impact, 1/1 at 3.659 Hz (2733 samples per period): max(0.4 s, 1.5 T) =
        // 4099 samples.
        assert_eq!(m.check(250, true, true, true, 2733, || false), None);
        let mut tripped = 0;
        for i in 1..=5000 {
            if m.check(250, true, true, false, 2733, || false).is_some() {
                tripped = i;
                break;
            }
        }
        assert_eq!(tripped, 4100);
        // A short period: the 0.4 s floor.
        let mut m = SensorMonitor::new(&FaultSettings::default());
        m.check(250, true, true, true, 1000, || false);
        let n = (1..10_000).find(|_| m.check(250, true, true, false, 1000, || false).is_some());
        assert_eq!(n, Some(4001));
    }
}

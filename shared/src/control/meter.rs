//! The measured regime `z = p/q` and peak force, online: impacts are counted per excitation
//! cycle (cycles start where the drive's phase wraps), and the last cycles are searched for the
//! shortest period `q ≤ MAX_MEASURED_Q` on which the per-cycle impact counts repeat and the
//! per-cycle peak forces repeat to within [`PEAK_MATCH_REL`] (so a period-2 orbit with
//! alternating peaks reads `2/2`, as the model's Poincaré classification says, not `1/1`).

use crate::observe::Regime;
use crate::observe::period::smallest_period;

/// Cycles remembered.
pub const METER_CYCLES: usize = 16;
/// Largest period searched, cycles.
pub const MAX_MEASURED_Q: usize = 4;
/// Two cycles' peak forces match when they differ by less than this fraction of the larger
/// (0.1).
pub const PEAK_MATCH_REL: f32 = 0.1;

/// One finished cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CycleRecord {
    /// Impacts in the cycle.
    pub impacts: u8,
    /// Largest impact peak in the cycle, N (0 without impacts).
    pub peak_n: f32,
    /// Sum of the impacts' impulses in the cycle, N·s.
    pub impulse_n_s: f32,
}

/// The online regime meter.
#[derive(Debug, Clone)]
pub struct RegimeMeter {
    ring: [CycleRecord; METER_CYCLES],
    /// Cycles recorded since the last reset (saturating).
    filled: usize,
    /// Index of the most recent cycle in `ring`.
    head: usize,
    current: CycleRecord,
}

impl Default for RegimeMeter {
    fn default() -> Self {
        Self::new()
    }
}

impl RegimeMeter {
    /// An empty meter.
    pub fn new() -> Self {
        RegimeMeter {
            ring: [CycleRecord::default(); METER_CYCLES],
            filled: 0,
            head: 0,
            current: CycleRecord::default(),
        }
    }

    /// Forgets every cycle (after a frequency or amplitude change).
    pub fn reset(&mut self) {
        self.filled = 0;
        self.current = CycleRecord::default();
    }

    /// Counts an impact of peak `peak_n` (N) and impulse `impulse_n_s` (N·s) in the current cycle.
    pub fn on_impact(&mut self, peak_n: f32, impulse_n_s: f32) {
        self.current.impacts = self.current.impacts.saturating_add(1);
        self.current.impulse_n_s += impulse_n_s;
        if peak_n > self.current.peak_n {
            self.current.peak_n = peak_n;
        }
    }

    /// Closes the current cycle.
    pub fn on_cycle_end(&mut self) {
        self.head = (self.head + 1) % METER_CYCLES;
        if let Some(slot) = self.ring.get_mut(self.head) {
            *slot = self.current;
        }
        self.filled = (self.filled + 1).min(METER_CYCLES);
        self.current = CycleRecord::default();
    }

    /// Finished cycles available (at most [`METER_CYCLES`]).
    pub fn cycles(&self) -> usize {
        self.filled
    }

    /// The `k`-th most recent finished cycle (`k = 0` is the last one).
    pub fn cycle(&self, k: usize) -> Option<CycleRecord> {
        if k >= self.filled {
            return None;
        }
        let i = (self.head + METER_CYCLES - k % METER_CYCLES) % METER_CYCLES;
        self.ring.get(i).copied()
    }

    /// The regime of the last `window` cycles (`window` clamped to `2 ..= METER_CYCLES`), or
    /// `None` until that many cycles are recorded. `NoImpact` when no cycle impacted;
    /// `Periodic { p, q }` for the shortest `q ≤ min(MAX_MEASURED_Q, window / 2)` that
    /// repeats; otherwise `Irregular`.
    pub fn regime(&self, window: usize) -> Option<Regime> {
        let w = window.clamp(2, METER_CYCLES);
        if self.filled < w {
            return None;
        }
        let all_silent = (0..w).all(|k| self.cycle(k).is_some_and(|c| c.impacts == 0));
        if all_silent {
            return Some(Regime::NoImpact);
        }
        let period = smallest_period(
            MAX_MEASURED_Q,
            |q| (2 * q <= w).then_some(w),
            |a, b| match (self.cycle(a), self.cycle(b)) {
                (Some(a), Some(b)) => same(a, b),
                _ => false,
            },
        );
        Some(match period {
            Some(q) => {
                let p: u16 = (0..q)
                    .filter_map(|k| self.cycle(k))
                    .map(|c| u16::from(c.impacts))
                    .sum();
                Regime::Periodic { p, q: q as u16 }
            }
            None => Regime::Irregular,
        })
    }

    /// Mean and maximum of the per-cycle peak forces over the last `window` cycles that
    /// impacted, N; `None` when none did.
    pub fn peak_force_n(&self, window: usize) -> Option<(f32, f32)> {
        let mut n = 0u32;
        let (mut sum, mut max) = (0.0f32, 0.0f32);
        for c in (0..window.min(self.filled)).filter_map(|k| self.cycle(k)) {
            if c.impacts > 0 {
                n += 1;
                sum += c.peak_n;
                max = max.max(c.peak_n);
            }
        }
        (n > 0).then(|| (sum / n as f32, max))
    }
}

fn same(a: CycleRecord, b: CycleRecord) -> bool {
    a.impacts == b.impacts && (a.peak_n - b.peak_n).abs() <= PEAK_MATCH_REL * a.peak_n.max(b.peak_n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meter(cycles: &[(u8, f32)]) -> RegimeMeter {
        let mut m = RegimeMeter::new();
        for &(n, peak) in cycles {
            for _ in 0..n {
                m.on_impact(peak, peak * 1e-3);
            }
            m.on_cycle_end();
        }
        m
    }

    #[test]
    fn regimes_from_count_and_peak_sequences() {
        let one = meter(&[(1, 96.0); 8]);
        assert_eq!(one.regime(8), Some(Regime::ONE_ONE));
        assert_eq!(one.peak_force_n(8), Some((96.0, 96.0)));
        // Impacts every other cycle: 1/2.
        let half = meter(&[
            (1, 150.0),
            (0, 0.0),
            (1, 150.0),
            (0, 0.0),
            (1, 150.0),
            (0, 0.0),
            (1, 150.0),
            (0, 0.0),
        ]);
        assert_eq!(half.regime(8), Some(Regime::Periodic { p: 1, q: 2 }));
        // One impact per cycle, alternating peaks: a period-2 orbit, 2/2.
        let alt = meter(&[
            (1, 50.0),
            (1, 80.0),
            (1, 50.0),
            (1, 80.0),
            (1, 50.0),
            (1, 80.0),
            (1, 50.0),
            (1, 80.0),
        ]);
        assert_eq!(alt.regime(8), Some(Regime::Periodic { p: 2, q: 2 }));
        // Two impacts per cycle: 2/1.
        assert_eq!(
            meter(&[(2, 40.0); 8]).regime(8),
            Some(Regime::Periodic { p: 2, q: 1 })
        );
        assert_eq!(meter(&[(0, 0.0); 8]).regime(8), Some(Regime::NoImpact));
        let irregular = meter(&[
            (1, 30.0),
            (2, 60.0),
            (0, 0.0),
            (1, 90.0),
            (1, 20.0),
            (3, 50.0),
            (0, 0.0),
            (1, 70.0),
        ]);
        assert_eq!(irregular.regime(8), Some(Regime::Irregular));
    }

    #[test]
    fn needs_a_full_window_and_sees_only_it() {
        let mut m = meter(&[(1, 96.0); 7]);
        assert_eq!(m.regime(8), None);
        m.on_cycle_end(); // an empty cycle: no longer 1/1
        assert_eq!(m.regime(8), Some(Regime::Irregular));
        for _ in 0..8 {
            m.on_impact(90.0, 0.09);
            m.on_cycle_end();
        }
        assert_eq!(m.regime(8), Some(Regime::ONE_ONE));
        // Peak noise of ±3 % is still 1/1.
        for k in 0..8 {
            m.on_impact(if k % 2 == 0 { 93.0 } else { 98.0 }, 0.03);
            m.on_cycle_end();
        }
        assert_eq!(m.regime(8), Some(Regime::ONE_ONE));
        assert_eq!(m.peak_force_n(8), Some((95.5, 98.0)));
        m.reset();
        assert_eq!(m.regime(2), None);
        assert_eq!(m.peak_force_n(8), None);
    }
}

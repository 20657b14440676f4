//! Impact detection (docs/model.md, "Impacts and their counting").
//!
//! An impact begins at an arrival through `δ = 0` (`δ` goes from `≤ 0` to `> 0`). Its episode
//! lasts until the hammer has clearly left the surface (`δ < −s`, the separation
//! [`DEFAULT_SEPARATION_M`] = 1 µm unless the protocol says otherwise), so re-contacts while
//! `δ` stays above `−s` (slow separations, the end of a chattering sequence) continue the same
//! impact. The peak force is the maximum of `F_i` over the whole episode.
//!
//! `s` is a physical threshold, not the switch model's numerical band `η_δ` (10 nm): refining
//! the band for a convergence study must not change how many impacts a chattering sequence
//! counts (bounces of a few nm depend on the band; 1 µm is 0.1 % of the cart amplitude).

/// Default separation that ends an impact episode, m (1 µm).
pub const DEFAULT_SEPARATION_M: f64 = 1e-6;

use crate::real::Real;

/// What one sample did to the impact bookkeeping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ImpactEvent<T> {
    /// A new impact began (arrival through `δ = 0`).
    Arrival,
    /// The episode ended; its peak contact force, N.
    End {
        /// `max F_i` over the episode, N.
        peak_n: T,
    },
}

/// Tracks impact episodes from a stream of `(δ, F_i)` samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImpactTracker<T> {
    separation: T,
    prev_delta: T,
    in_episode: bool,
    peak: T,
}

impl<T: Real> ImpactTracker<T> {
    /// A tracker whose previous sample had penetration `initial_delta` (m); an episode ends when
    /// `δ < −separation_m` (m, e.g. [`DEFAULT_SEPARATION_M`]).
    pub fn new(separation_m: T, initial_delta: T) -> Self {
        ImpactTracker {
            separation: separation_m,
            prev_delta: initial_delta,
            in_episode: false,
            peak: T::zero(),
        }
    }

    /// Feeds one sample: penetration `delta` (m), the smallest penetration since the previous
    /// sample `delta_min` (m, `≤ delta`; [`crate::integrate::StepSample::delta_min`], or `delta`
    /// itself for samples without a trajectory between them) and contact force `force` (N).
    #[inline(always)]
    pub fn update(&mut self, delta: T, delta_min: T, force: T) -> Option<ImpactEvent<T>> {
        let prev = self.prev_delta;
        self.prev_delta = delta;
        if self.in_episode {
            if leaves(self.separation, delta_min) {
                // Left by the separation since the last sample (perhaps only between the
                // samples). The next sample with `δ > 0` is an arrival, even if this one is
                // already back on the surface (this sample's force is not this impact's).
                self.in_episode = false;
                self.prev_delta = delta_min;
                return Some(ImpactEvent::End { peak_n: self.peak });
            }
            self.peak = self.peak.max_of(force);
            None
        } else if arrives(prev, delta) {
            self.in_episode = true;
            self.peak = force;
            Some(ImpactEvent::Arrival)
        } else {
            None
        }
    }

    /// Whether an impact episode is in progress.
    #[inline(always)]
    pub fn in_episode(&self) -> bool {
        self.in_episode
    }

    /// Records that the hammer is clear of the surface at penetration `delta` (m, `< 0`) after
    /// steps that were not fed to [`ImpactTracker::update`] (`crate::integrate::lanes`):
    /// outside an episode, what `update(delta, delta_min, 0)` would have done for each of them.
    #[inline(always)]
    pub fn clear_at(&mut self, delta: T) {
        debug_assert!(!self.in_episode && delta <= T::zero());
        self.prev_delta = delta;
    }

    /// `(separation, previous penetration, in episode, peak)` (m, m, -, N): what a lane that
    /// takes the run's quiet samples carries ([`ImpactTracker::quiet`]).
    #[inline(always)]
    pub(crate) fn parts(&self) -> (T, T, bool, T) {
        (self.separation, self.prev_delta, self.in_episode, self.peak)
    }

    /// Takes back the previous penetration and the peak after quiet samples taken elsewhere.
    #[inline(always)]
    pub(crate) fn resume(&mut self, prev_delta: T, peak: T) {
        self.prev_delta = prev_delta;
        self.peak = peak;
    }

    /// Whether [`ImpactTracker::update`] of a tracker in the state `(separation, prev_delta,
    /// in_episode)` reports no event for the sample `(delta, delta_min)`; the sample then only
    /// sets the previous penetration to `delta` and, in an episode, raises the peak to its
    /// force.
    #[inline(always)]
    pub(crate) fn quiet(
        separation: T,
        prev_delta: T,
        in_episode: bool,
        delta: T,
        delta_min: T,
    ) -> bool {
        if in_episode {
            !leaves(separation, delta_min)
        } else {
            !arrives(prev_delta, delta)
        }
    }

    /// Peak force of the episode in progress so far, N.
    pub fn current_peak(&self) -> Option<T> {
        self.in_episode.then_some(self.peak)
    }
}

/// Whether the hammer has left the surface by `separation` (the episode ends), given the
/// smallest penetration since the previous sample.
#[inline(always)]
fn leaves<T: Real>(separation: T, delta_min: T) -> bool {
    delta_min < -separation
}

/// Whether a sample with penetration `delta` after one with `prev_delta` is an arrival.
#[inline(always)]
fn arrives<T: Real>(prev_delta: T, delta: T) -> bool {
    prev_delta <= T::zero() && delta > T::zero()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recontacts_continue_the_impact_and_peaks_include_them() {
        let mut t = ImpactTracker::<f64>::new(1e-8, -1e-3);
        let trace = [
            (-1e-4, 0.0),
            (1e-6, 20.0), // arrival
            (3e-6, 35.0),
            (1e-9, 0.0),  // force vanished, δ > 0
            (2e-6, 40.0), // re-contact: same impact, larger peak
            (-5e-9, 0.0), // inside the band: still the same episode
            (1e-7, 3.0),
            (-1e-6, 0.0), // gone
            (-1e-5, 0.0),
            (1e-6, 9.0), // a new arrival
            (-1e-6, 0.0),
        ];
        let events: Vec<_> = trace
            .iter()
            .filter_map(|&(d, f)| t.update(d, d, f))
            .collect();
        assert_eq!(
            events,
            vec![
                ImpactEvent::Arrival,
                ImpactEvent::End { peak_n: 40.0 },
                ImpactEvent::Arrival,
                ImpactEvent::End { peak_n: 9.0 },
            ]
        );
    }

    #[test]
    fn a_hop_beyond_the_separation_between_samples_ends_the_impact() {
        let mut t = ImpactTracker::<f64>::new(1e-6, -1e-3);
        assert_eq!(t.update(2e-6, 2e-6, 30.0), Some(ImpactEvent::Arrival));
        // Both samples within 1 µm of the surface, but the hammer was 1.2 µm away in between.
        assert_eq!(t.update(-3e-7, -3e-7, 0.0), None);
        assert_eq!(
            t.update(-2e-7, -1.2e-6, 0.0),
            Some(ImpactEvent::End { peak_n: 30.0 })
        );
        assert_eq!(t.update(1e-7, 1e-7, 4.0), Some(ImpactEvent::Arrival));
        // The same hop at 0.8 µm is one episode with the re-contact.
        let mut t = ImpactTracker::<f64>::new(1e-6, -1e-3);
        t.update(2e-6, 2e-6, 30.0);
        assert_eq!(t.update(-2e-7, -8e-7, 0.0), None);
        assert_eq!(t.update(1e-7, 1e-7, 40.0), None);
        assert_eq!(
            t.update(-2e-6, -2e-6, 0.0),
            Some(ImpactEvent::End { peak_n: 40.0 })
        );
    }

    #[test]
    fn quiet_is_update_without_an_event() {
        // Every combination of episode state, previous penetration, the sample's penetration
        // and smallest penetration around the surface and the separation (1 µm): `quiet` says
        // whether `update` reports nothing, and a quiet sample changes only the previous
        // penetration and (in an episode) the peak.
        let values = [-2e-6, -1e-6, -5e-7, 0.0, 5e-7, 2e-6];
        let mut quiet_seen = [0; 2];
        for in_episode in [false, true] {
            for prev in values {
                for delta in values {
                    for delta_min in values.iter().copied().filter(|&m| m <= delta) {
                        let mut t = ImpactTracker::<f64>::new(1e-6, prev);
                        t.in_episode = in_episode;
                        t.peak = 7.0;
                        let (sep, p, e, peak) = t.parts();
                        let quiet = ImpactTracker::quiet(sep, p, e, delta, delta_min);
                        let event = t.update(delta, delta_min, 9.0);
                        assert_eq!(
                            quiet,
                            event.is_none(),
                            "{in_episode} {prev} {delta} {delta_min}"
                        );
                        if quiet {
                            quiet_seen[usize::from(in_episode)] += 1;
                            let peak_after = if in_episode { 9.0 } else { peak };
                            assert_eq!(t.parts(), (sep, delta, e, peak_after));
                        }
                    }
                }
            }
        }
        assert!(quiet_seen[0] > 0 && quiet_seen[1] > 0, "{quiet_seen:?}");
    }
}

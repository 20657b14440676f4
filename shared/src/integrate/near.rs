//! Where a free-flight trial that came near the surface is split (`Simulator::free_trial`):
//! the first time its cubic Hermite dense output comes within `η_δ` of the surface, or, if it
//! never does, where it peaks.
//!
//! The search: the penetration `δ` at [`SAMPLES`] evenly spaced points of the trial; in the
//! first interval whose end has `δ > −η_δ`, [`HALVINGS`] halvings of `δ + η_δ` (this only
//! places the start of the sub-steps, to 1/8192 of the step); without one, the sample with
//! the largest `δ` (the trial's start if none exceeds it).
//!
//! [`first_near_alone`] evaluates one point after the other (the MCU, and any point of the
//! host where the lanes cannot: an angle beyond their short sine). On the host,
//! [`first_near`] evaluates the same points in vector lanes: the eight samples at once, and
//! the halvings [`LEVELS`] at a time (the `2^LEVELS − 1` midpoints those halvings can reach,
//! computed as the halvings compute them, then the decisions taken among them). The host's
//! grid analyses search several runs' trials side by side instead ([`NearLanes`]: lane `i`
//! one trial, one point of every search per round). The same points, values and decisions in
//! all three, so the same time, bit for bit. The periodic-orbit map takes the crossing
//! to round-off instead, differentiated through its root ([`NearTrial::search_exact`]).

use super::bracket::{Rule, bracket_rising};
use super::dense::{DenseStep, MAX_EVENT_EVALS, hermite_weights};
use super::free::SmallTrig;
use super::isa::{Isa, Kernel, Variant};
use super::lane_field::LaneContact;
use crate::model::Hammer;
use crate::real::Real;
use nalgebra::Vector2;

/// Samples of the trial's dense output.
pub(super) const SAMPLES: u32 = 8;

/// Halvings of the sample interval where the trial first comes near.
pub(super) const HALVINGS: u32 = 10;

/// A free-flight trial that came near the surface (`Simulator::free_trial`), to be searched
/// for where it first comes within `η_δ` of it: its dense output, the penetration at its start
/// (m) and `η_δ` (m).
#[derive(Clone, Copy)]
pub(crate) struct NearTrial<T: Real> {
    pub(super) dense: DenseStep<T>,
    pub(super) start_delta: T,
    pub(super) eta: T,
}

impl<T: Real> NearTrial<T> {
    /// Where the trial first comes near (s from its start), searched alone: on the host in
    /// vector lanes where they can ([`first_near`]), else one point after the other.
    #[inline(always)]
    pub(crate) fn search_alone(&self, hammer: &Hammer<T>) -> T {
        #[cfg(feature = "std")]
        if let Some(t) = first_near(hammer, &self.dense, self.start_delta, self.eta) {
            return t;
        }
        first_near_alone(hammer, &self.dense, self.start_delta, self.eta)
    }

    /// [`first_near_alone`] with the crossing of `−η_δ` located by Illinois regula falsi to
    /// four rounding units of the trial (at most [`MAX_EVENT_EVALS`] evaluations) instead of
    /// [`HALVINGS`] halvings, and its time differentiated through the root
    /// ([`Real::root_derivative`]: `−(∂δ/∂x·∂x/∂s)/(dδ/dt)` along the dense output) rather
    /// than held fixed: the periodic-orbit map's split (`Simulator::step_exact`). The halvings
    /// make that map jump wherever the split moves by a halving, with a slope between jumps
    /// that need not be the map's (`crate::orbit`); this split moves with the state, so the
    /// map is smooth and its tangent is its derivative. Where the trial only peaks (no
    /// crossing) the sample of the peak, as alone.
    #[inline]
    pub(crate) fn search_exact(&self, hammer: &Hammer<T>) -> T {
        let (dense, eta) = (&self.dense, self.eta);
        scan_samples(
            hammer,
            dense,
            self.start_delta,
            eta,
            |lo, hi, (d_lo, d_hi)| {
                let near = |m: T| hammer.penetration(&dense.at(m / dense.h)).0 + eta;
                let rule = Rule::Illinois {
                    tol: dense.h * T::from_f64(4.0 * T::EPSILON),
                    max_evals: MAX_EVENT_EVALS,
                    ends: (d_lo + eta, d_hi + eta),
                };
                let root = bracket_rising(lo, hi, rule, near).0;
                let (x, rate) = dense.position_and_rate(root);
                let slope = hammer.penetration(&Vector2::new(x[0], rate[0])).1;
                root.root_derivative(near(root), slope)
            },
        )
    }
}

/// `δ` (m) of the trial `(x0, f0, x1, f1)` (its position and the position's slope at both
/// ends) of `rest` s at `t` s from its start, with `DenseStep::at`'s and
/// `Hammer::penetration`'s operations, and whether the short sine was exact there.
#[inline(always)]
fn delta_at<T: Real, F: LaneContact<T>>(
    field: &F,
    [x0, f0, x1, f1]: [T; 4],
    rest: T,
    t: T,
) -> (T, bool) {
    let (h00, h10, h01, h11) = hermite_weights(t / rest, rest);
    let u0 = x0 * h00 + f0 * h10 + x1 * h01 + f1 * h11;
    let (delta, _, _, exact) = field.penetration::<SmallTrig>(u0, T::zero());
    (delta, exact)
}

/// Up to `K` trials of runs with the suspension `F` searched side by side (the host's grid
/// analyses, `analysis::batch`): lane `i` one trial, each round one point of every search, the
/// points and decisions of [`first_near_alone`] (branch-free: every lane takes all
/// [`SAMPLES`] samples and [`HALVINGS`] halvings, and keeps what the search alone would).
pub(crate) struct NearLanes<T: Real, F, const K: usize> {
    isa: Isa,
    /// Trials set (lanes `0..n`).
    n: usize,
    field: [F; K],
    /// The position and its slope at the trial's start and end, its length (s), the
    /// penetration at its start and `η_δ` (m).
    x0: [T; K],
    f0: [T; K],
    x1: [T; K],
    f1: [T; K],
    h: [T; K],
    start_delta: [T; K],
    eta: [T; K],
}

/// [`NearLanes::search`]'s searches as a [`Kernel`].
struct Searches<'a, T: Real, F, const K: usize> {
    lanes: &'a NearLanes<T, F, K>,
}

impl<T: Real, F: LaneContact<T>, const K: usize> Kernel for Searches<'_, T, F, K> {
    type Output = [Option<T>; K];
    #[inline(always)]
    fn run<I: Variant>(self) -> [Option<T>; K] {
        self.lanes.search_kernel()
    }
}

impl<T: Real, F: LaneContact<T>, const K: usize> NearLanes<T, F, K> {
    /// Empty lanes, the kernel in the instruction set of [`Isa::detect`].
    pub(crate) fn new() -> Self {
        let one = T::from_f64(1.0);
        let zero = T::zero();
        NearLanes {
            isa: Isa::detect(),
            n: 0,
            field: [F::default(); K],
            x0: [zero; K],
            f0: [zero; K],
            x1: [zero; K],
            f1: [zero; K],
            h: [one; K],
            start_delta: [zero; K],
            eta: [zero; K],
        }
    }

    /// Trials set.
    #[inline]
    pub(crate) fn len(&self) -> usize {
        self.n
    }

    /// Sets `trial` of a run on `hammer` into the next lane: its number, or `None` if the lanes
    /// are full or the hammer is not of the suspension `F`.
    #[inline]
    pub(crate) fn push(&mut self, hammer: &Hammer<T>, trial: &NearTrial<T>) -> Option<usize> {
        let i = self.n;
        if i >= K {
            return None;
        }
        let field = F::of(&hammer.free_flight())?;
        let d = &trial.dense;
        self.field[i] = field;
        (self.x0[i], self.f0[i], self.x1[i], self.f1[i]) = (d.x0[0], d.f0[0], d.x1[0], d.f1[0]);
        self.h[i] = d.h;
        self.start_delta[i] = trial.start_delta;
        self.eta[i] = trial.eta;
        self.n += 1;
        Some(i)
    }

    /// Drops the trials set.
    #[inline]
    pub(crate) fn clear(&mut self) {
        self.n = 0;
    }

    /// Searches the trials set, lane `i` giving where trial `i` first comes near (s from its
    /// start; `None`: a point beyond the short sine, `|θ| > 1/8` rad, to be searched alone),
    /// and clears the lanes.
    pub(crate) fn search(&mut self) -> [Option<T>; K] {
        self.n = 0;
        self.isa.run(Searches { lanes: self })
    }

    /// The searches lane by lane (lanes not set search their last trial again, unread).
    #[inline(always)]
    fn search_kernel(&self) -> [Option<T>; K] {
        let zero = T::zero();
        let half = T::from_f64(0.5);
        let dt: [T; K] = core::array::from_fn(|i| self.h[i] / T::from_u32(SAMPLES));
        let mut exact = [true; K];
        // The first sample interval whose end comes within `η_δ` (`found`), else the sample
        // with the largest `δ` (the start's if none exceeds it).
        let mut found = [false; K];
        let (mut lo, mut hi) = ([zero; K], [zero; K]);
        let (mut best_t, mut best_d) = ([zero; K], self.start_delta);
        for j in 1..=SAMPLES {
            for i in 0..K {
                let t = dt[i] * T::from_u32(j);
                let (d, ok) = self.delta(i, t);
                // Samples after the crossing are not the search's: their range does not count.
                exact[i] &= ok | found[i];
                let cross = !found[i] & (d > -self.eta[i]);
                lo[i] = if cross { t - dt[i] } else { lo[i] };
                hi[i] = if cross { t } else { hi[i] };
                let better = !found[i] & !cross & (d > best_d[i]);
                best_t[i] = if better { t } else { best_t[i] };
                best_d[i] = if better { d } else { best_d[i] };
                found[i] |= cross;
            }
        }
        for _ in 0..HALVINGS {
            for i in 0..K {
                let mid = (lo[i] + hi[i]) * half;
                let (d, ok) = self.delta(i, mid);
                exact[i] &= ok | !found[i];
                let up = d + self.eta[i] > zero;
                hi[i] = if up { mid } else { hi[i] };
                lo[i] = if up { lo[i] } else { mid };
            }
        }
        core::array::from_fn(|i| exact[i].then_some(if found[i] { lo[i] } else { best_t[i] }))
    }

    /// Lane `i`'s `δ` (m) at `t` s into its trial, and whether the short sine was exact.
    #[inline(always)]
    fn delta(&self, i: usize, t: T) -> (T, bool) {
        let ends = [self.x0[i], self.f0[i], self.x1[i], self.f1[i]];
        delta_at(&self.field[i], ends, self.h[i], t)
    }
}

/// The time (s from the trial's start) at which the trial `dense` (of `dense.h` seconds, from a
/// state with penetration `start_delta`, m) first comes within `eta` (m) of the surface, or
/// peaks: one point after the other.
#[inline(always)]
pub(super) fn first_near_alone<T: Real>(
    hammer: &Hammer<T>,
    dense: &DenseStep<T>,
    start_delta: T,
    eta: T,
) -> T {
    scan_samples(hammer, dense, start_delta, eta, |lo, hi, _| {
        let near = |m: T| hammer.penetration(&dense.at(m / dense.h)).0 + eta;
        bracket_rising(lo, hi, Rule::Bisect(HALVINGS), near).0
    })
}

/// The trial's [`SAMPLES`] evenly spaced points, one after the other: at the first whose `δ`
/// exceeds `−eta`, what `locate` makes of the interval from the previous sample to it (its
/// ends, s from the trial's start, and `δ` there, m); without one, the sample with the largest
/// `δ` (the trial's start if none exceeds `start_delta`).
#[inline(always)]
fn scan_samples<T: Real>(
    hammer: &Hammer<T>,
    dense: &DenseStep<T>,
    start_delta: T,
    eta: T,
    locate: impl FnOnce(T, T, (T, T)) -> T,
) -> T {
    let rest = dense.h;
    let dt = rest / T::from_u32(SAMPLES);
    let (mut best_t, mut best_d) = (T::zero(), start_delta);
    let mut d_before = start_delta;
    for i in 1..=SAMPLES {
        let t = dt * T::from_u32(i);
        let d = hammer.penetration(&dense.at(t / rest)).0;
        if d > -eta {
            return locate(t - dt, t, (d_before, d));
        }
        if d > best_d {
            best_t = t;
            best_d = d;
        }
        d_before = d;
    }
    best_t
}

#[cfg(feature = "std")]
pub(super) use lanes::first_near;

#[cfg(feature = "std")]
mod lanes {
    use super::*;
    use crate::model::hammer::FreeFlight;

    /// Halvings taken together: `2^LEVELS − 1` midpoints evaluated at once.
    const LEVELS: u32 = 4;

    /// Points a halving round evaluates together: its midpoints and one spare.
    const POINTS: usize = 1 << LEVELS;

    /// [`SAMPLES`] as a length.
    const SAMPLE_POINTS: usize = SAMPLES as usize;

    /// [`first_near_alone`] with its points evaluated in vector lanes (`None`: a point the lanes
    /// evaluated lies beyond their short sine, `|θ| > 1/8` rad; the caller then searches alone).
    #[inline]
    pub(in super::super) fn first_near<T: Real>(
        hammer: &Hammer<T>,
        dense: &DenseStep<T>,
        start_delta: T,
        eta: T,
    ) -> Option<T> {
        match hammer.free_flight() {
            FreeFlight::Wires(w) => dispatch(&w, dense, start_delta, eta),
            FreeFlight::Beam(b) => dispatch(&b, dense, start_delta, eta),
        }
    }

    /// [`first_near`] for the suspension `F`, compiled for the CPU's widest instructions.
    #[inline(always)]
    fn dispatch<T: Real, F: LaneContact<T>>(
        field: &F,
        dense: &DenseStep<T>,
        start_delta: T,
        eta: T,
    ) -> Option<T> {
        Isa::detect().run(Search {
            field,
            dense,
            start_delta,
            eta,
        })
    }

    /// [`search`] with its arguments, as a [`Kernel`].
    struct Search<'a, T: Real, F> {
        field: &'a F,
        dense: &'a DenseStep<T>,
        start_delta: T,
        eta: T,
    }

    impl<T: Real, F: LaneContact<T>> Kernel for Search<'_, T, F> {
        type Output = Option<T>;
        #[inline(always)]
        fn run<I: Variant>(self) -> Option<T> {
            search(self.field, self.dense, self.start_delta, self.eta)
        }
    }

    /// [`first_near_alone`]'s search, its points [`POINTS`] at a time.
    #[inline(always)]
    fn search<T: Real, F: LaneContact<T>>(
        field: &F,
        dense: &DenseStep<T>,
        start_delta: T,
        eta: T,
    ) -> Option<T> {
        let rest = dense.h;
        let dt = rest / T::from_u32(SAMPLES);
        let t: [T; SAMPLE_POINTS] = core::array::from_fn(|i| dt * T::from_u32(i as u32 + 1));
        let d = deltas(field, dense, &t)?;
        let (mut best_t, mut best_d) = (T::zero(), start_delta);
        for i in 0..SAMPLE_POINTS {
            if d[i] > -eta {
                return bisect_rounds(field, dense, t[i] - dt, t[i], eta);
            }
            if d[i] > best_d {
                best_t = t[i];
                best_d = d[i];
            }
        }
        Some(best_t)
    }

    /// [`HALVINGS`] halvings of `[lo, hi]` for the rising zero of `δ + eta`, [`LEVELS`] at a
    /// time: the lower end of the bracket `bracket_rising` leaves (`None`: a point beyond the
    /// short sine).
    #[inline(always)]
    fn bisect_rounds<T: Real, F: LaneContact<T>>(
        field: &F,
        dense: &DenseStep<T>,
        mut lo: T,
        mut hi: T,
        eta: T,
    ) -> Option<T> {
        let half = T::from_f64(0.5);
        let zero = T::zero();
        let mut left = HALVINGS;
        while left > 0 {
            let levels = left.min(LEVELS);
            // The midpoints as a binary tree in heap order (node 1 halves `[lo, hi]`; node
            // `n`'s halves are nodes `2n` below it and `2n + 1` above), each the halving's own
            // `(lo + hi) · ½` of its interval; node 0 a spare copy of node 1.
            let mut p = [zero; POINTS];
            let mut lo_of = [lo; POINTS];
            let mut hi_of = [hi; POINTS];
            p[1] = (lo + hi) * half;
            for n in 1..POINTS / 2 {
                (lo_of[2 * n], hi_of[2 * n]) = (lo_of[n], p[n]);
                (lo_of[2 * n + 1], hi_of[2 * n + 1]) = (p[n], hi_of[n]);
                p[2 * n] = (lo_of[n] + p[n]) * half;
                p[2 * n + 1] = (p[n] + hi_of[n]) * half;
            }
            p[0] = p[1];
            let d = deltas(field, dense, &p)?;
            // Each midpoint's decision as a bit (set: `δ + η_δ > 0`, the bracket's upper end
            // moves there), so that the walk down the tree waits on no load.
            let mut up = 0u32;
            for (i, di) in d.iter().enumerate() {
                up |= u32::from(*di + eta > zero) << i;
            }
            // The walk by indices (selects, not branches: the decisions are coin flips to a
            // branch predictor); index 0: the round's own end.
            let (mut n, mut lo_at, mut hi_at) = (1usize, 0usize, 0usize);
            for _ in 0..levels {
                let bit = ((up >> n) & 1) as usize;
                hi_at = if bit != 0 { n } else { hi_at };
                lo_at = if bit != 0 { lo_at } else { n };
                n = 2 * n + 1 - bit;
            }
            lo = if lo_at == 0 { lo } else { p[lo_at] };
            hi = if hi_at == 0 { hi } else { p[hi_at] };
            left -= levels;
        }
        Some(lo)
    }

    /// `δ` (m) of the dense output at the times `t` (s from its start), lane by lane
    /// (`DenseStep::at`'s position and `Hammer::penetration`'s operations; `None` if a sine
    /// left the short range).
    #[inline(always)]
    fn deltas<T: Real, F: LaneContact<T>, const K: usize>(
        field: &F,
        dense: &DenseStep<T>,
        t: &[T; K],
    ) -> Option<[T; K]> {
        let ends = [dense.x0[0], dense.f0[0], dense.x1[0], dense.f1[0]];
        let mut d = [T::zero(); K];
        let mut exact = true;
        for i in 0..K {
            let (delta, ok) = delta_at(field, ends, dense.h, t[i]);
            d[i] = delta;
            exact &= ok;
        }
        exact.then_some(d)
    }
}

#[cfg(all(test, feature = "std"))]
mod tests {
    use nalgebra::Vector2;

    use super::*;
    use crate::integrate::isa::{Isa, with_isa};
    use crate::model::hammer::{BeamFree, Body, WiresFree};
    use crate::model::{RigId, SwitchBands};

    /// Trials of `h` s on `hammer` whose penetration follows `p(t) = p0 + v t + ½ a t²` (m),
    /// as the stepper's dense output of them (`state(p, ṗ)` the state at penetration `p`
    /// and rate `ṗ`, `slope(p, ṗ, p̈)` its time derivative, in f64): crossings of `−η_δ` in
    /// every sample interval, near misses that peak below it, and trials that fall away.
    fn trials<T: Real>(
        hammer: &Hammer<T>,
        state: impl Fn(f64, f64) -> [f64; 2],
        slope: impl Fn(f64, f64, f64) -> [f64; 2],
    ) -> std::vec::Vec<(DenseStep<T>, T)> {
        let eta = hammer.eta_delta().to_f64();
        let h = 1e-3;
        let v2 = |[a, b]: [f64; 2]| Vector2::new(T::from_f64(a), T::from_f64(b));
        let mut out = std::vec::Vec::new();
        for i in 0..6 {
            let p0 = -(1.2 + 0.7 * f64::from(i)) * eta;
            for j in 0..9 {
                let v = (f64::from(j) - 2.0) * 0.4 * eta / h;
                for a in [-3.0, 0.0, 2.5] {
                    let a = a * eta / (h * h);
                    let p1 = p0 + v * h + 0.5 * a * h * h;
                    let dense = DenseStep {
                        x0: v2(state(p0, v)),
                        f0: v2(slope(p0, v, a)),
                        x1: v2(state(p1, v + a * h)),
                        f1: v2(slope(p1, v + a * h, a)),
                        h: T::from_f64(h),
                    };
                    out.push((dense, hammer.penetration(&dense.x0).0));
                }
            }
        }
        out
    }

    /// The lanes' search against the search alone on every trial, bit for bit; how many
    /// trials came within `η_δ` (of all).
    fn lanes_match_alone<T: Real>(hammer: &Hammer<T>, all: &[(DenseStep<T>, T)]) -> usize {
        let eta = hammer.eta_delta();
        let mut crossed = 0;
        for (dense, start_delta) in all {
            let alone = first_near_alone(hammer, dense, *start_delta, eta).to_f64();
            let lanes = first_near(hammer, dense, *start_delta, eta).map(T::to_f64);
            assert_eq!(lanes.map(f64::to_bits), Some(alone.to_bits()));
            // A crossing lies off the sample grid (the halvings moved it).
            let on_grid = (alone / dense.h.to_f64() * f64::from(SAMPLES)).fract() == 0.0;
            crossed += usize::from(!on_grid);
        }
        crossed
    }

    /// The trials searched side by side in [`NearLanes`] (in sets of 1 to 8, so that lanes
    /// left from the last set are searched again, unread) against the search alone, bit for
    /// bit; a hammer of the other suspension is refused.
    fn near_lanes_match_alone<T: Real, F: LaneContact<T>, G: LaneContact<T>>(
        hammer: &Hammer<T>,
        all: &[(DenseStep<T>, T)],
    ) {
        let eta = hammer.eta_delta();
        let mut lanes = NearLanes::<T, F, 8>::new();
        let mut sizes = (1..=8).cycle();
        let mut rest = all;
        while !rest.is_empty() {
            let (set, next) = rest.split_at(sizes.next().unwrap_or(8).min(rest.len()));
            for (i, (dense, start_delta)) in set.iter().enumerate() {
                let trial = NearTrial {
                    dense: *dense,
                    start_delta: *start_delta,
                    eta,
                };
                assert_eq!(lanes.push(hammer, &trial), Some(i));
            }
            assert_eq!(lanes.len(), set.len());
            let found = lanes.search();
            assert_eq!(lanes.len(), 0);
            for ((dense, start_delta), t) in set.iter().zip(found) {
                let alone = first_near_alone(hammer, dense, *start_delta, eta).to_f64();
                assert_eq!(t.map(|t| t.to_f64().to_bits()), Some(alone.to_bits()));
            }
            rest = next;
        }
        let (dense, start_delta) = all[0];
        let trial = NearTrial {
            dense,
            start_delta,
            eta,
        };
        assert_eq!(NearLanes::<T, G, 8>::new().push(hammer, &trial), None);
        let mut full = NearLanes::<T, F, 2>::new();
        assert_eq!(full.push(hammer, &trial), Some(0));
        assert_eq!(full.push(hammer, &trial), Some(1));
        assert_eq!(full.push(hammer, &trial), None);
    }

    /// [`lanes_match_alone`] on the wire and the beam rig at a 1 mm gap, in every instruction
    /// set the CPU runs; the pendulum past the short sine and a trial with NaN are searched
    /// alone.
    fn both_rigs<T: Real>() {
        let bands = SwitchBands::default();
        let gap = 1e-3;
        let wires = Hammer::<T>::new(&RigId::Wires.preset(), gap, 20.0, &bands).unwrap();
        let Body::Wires { length, .. } = *wires.body() else {
            panic!("the wire rig's body");
        };
        let l = length.to_f64();
        // θ = asin((gap + p)/l): θ̇ = ṗ/(l cos θ), θ̈ from differentiating that.
        let theta = |p: f64| ((gap + p) / l).asin();
        let pendulum = |p: f64, v: f64| {
            let th = theta(p);
            [th, v / (l * th.cos())]
        };
        let pendulum_slope = |p: f64, v: f64, a: f64| {
            let th = theta(p);
            let w = v / (l * th.cos());
            [w, (a + l * w * w * th.sin()) / (l * th.cos())]
        };
        let beam_hammer = Hammer::<T>::new(&RigId::Beam170.preset(), gap, 60.0, &bands).unwrap();
        let beam = |p: f64, v: f64| [gap + p, v];
        let beam_slope = |_: f64, v: f64, a: f64| [v, a];
        let wire_trials = trials(&wires, pendulum, pendulum_slope);
        let beam_trials = trials(&beam_hammer, beam, beam_slope);
        let v2 = |a: f64, b: f64| Vector2::new(T::from_f64(a), T::from_f64(b));
        for isa in Isa::supported() {
            with_isa(isa, || {
                // Both kinds of answer are tested: crossings (halved) and peaks or starts.
                for (hammer, all) in [(&wires, &wire_trials), (&beam_hammer, &beam_trials)] {
                    let crossed = lanes_match_alone(hammer, all);
                    assert!(
                        crossed >= 40 && crossed + 40 <= all.len(),
                        "{crossed} of {}",
                        all.len()
                    );
                }
                // A pendulum at 0.6 rad, past the lanes' short sine, and a trial with NaN:
                // searched alone instead.
                let wide = DenseStep {
                    x0: v2(0.55, 1.0),
                    f0: v2(1.0, 0.0),
                    x1: v2(0.65, 1.0),
                    f1: v2(1.0, 0.0),
                    h: T::from_f64(0.1),
                };
                let eta = wires.eta_delta();
                assert_eq!(first_near(&wires, &wide, T::from_f64(-1.0), eta), None);
                let nan = DenseStep {
                    f1: v2(f64::NAN, 0.0),
                    ..wire_trials[0].0
                };
                assert_eq!(first_near(&wires, &nan, wire_trials[0].1, eta), None);
                // Several runs' trials side by side, the same two searched alone there too.
                near_lanes_match_alone::<T, WiresFree<T>, BeamFree<T>>(&wires, &wire_trials);
                near_lanes_match_alone::<T, BeamFree<T>, WiresFree<T>>(&beam_hammer, &beam_trials);
                let mut lanes = NearLanes::<T, WiresFree<T>, 8>::new();
                for (dense, start_delta) in [(wide, T::from_f64(-1.0)), (nan, wire_trials[0].1)] {
                    let trial = NearTrial {
                        dense,
                        start_delta,
                        eta,
                    };
                    lanes.push(&wires, &trial);
                }
                lanes.push(
                    &wires,
                    &NearTrial {
                        dense: wire_trials[0].0,
                        start_delta: wire_trials[0].1,
                        eta,
                    },
                );
                let found = lanes.search();
                assert_eq!(found[..2], [None, None]);
                assert!(found[2].is_some());
            });
        }
    }

    #[test]
    fn the_lanes_find_where_a_trial_comes_near_as_the_search_alone() {
        both_rigs::<f32>();
        both_rigs::<f64>();
    }

    /// The exact split on the beam, whose dense output reproduces a parabola `p(t) = p0 + v t
    /// + ½ a t²` exactly: the first root of `p(t) = −η_δ` (closed form) to 1e-10 of the step, within
    /// one halving (`h/8/1024`) above the bisected split, and its derivative in `p0` the
    /// implicit one, `−1/ṗ(t*)` (a dual seed on the whole trial).
    #[test]
    fn the_exact_split_is_the_crossing_and_moves_with_the_state() {
        use crate::dual::Dual;
        type D = Dual<f64, 1>;
        let bands = SwitchBands::default();
        let gap = 1e-3;
        let preset = RigId::Beam170.preset();
        let beam = Hammer::<f64>::new(&preset, gap, 60.0, &bands).unwrap();
        let beam_d = Hammer::<D>::new(&preset, gap, 60.0, &bands).unwrap();
        let eta = beam.eta_delta();
        let all = trials(&beam, |p, v| [gap + p, v], |_, v, a| [v, a]);
        let mut crossed = 0;
        for (dense, start_delta) in &all {
            let h = dense.h;
            let alone = first_near_alone(&beam, dense, *start_delta, eta);
            let exact = NearTrial {
                dense: *dense,
                start_delta: *start_delta,
                eta,
            }
            .search_exact(&beam);
            let dt = h / f64::from(SAMPLES);
            let crosses =
                (1..=SAMPLES).any(|i| beam.penetration(&dense.at(dt * f64::from(i) / h)).0 > -eta);
            if !crosses {
                assert_eq!(exact, alone, "no crossing: the same sample");
                continue;
            }
            crossed += 1;
            // The parabola through the trial's ends: p0, v = ṗ(0), a from ṗ(h).
            let (p0, v) = (dense.x0[0] - gap, dense.x0[1]);
            let a = (dense.x1[1] - v) / h;
            let c = p0 + eta;
            let root = if a == 0.0 {
                -c / v
            } else {
                // The smaller root in (0, h] of ½a t² + v t + c = 0, rising.
                let disc = (v * v - 2.0 * a * c).sqrt();
                let roots = [(-v - disc) / a, (-v + disc) / a];
                roots
                    .into_iter()
                    .filter(|t| *t > 0.0 && *t <= h * (1.0 + 1e-12) && v + a * t > 0.0)
                    .fold(f64::INFINITY, f64::min)
            };
            assert!((exact - root).abs() < 1e-10 * h, "{exact} vs {root}");
            let halving = h / f64::from(SAMPLES) / f64::from(1u32 << HALVINGS);
            assert!(alone <= exact && exact - alone < halving * (1.0 + 1e-9));
            // The whole trial moved by ε in p: the crossing moves by −ε/ṗ(t*).
            let lift = |x: Vector2<f64>| Vector2::new(D::seed(x[0], 0), D::from_f64(x[1]));
            let flat = |x: Vector2<f64>| Vector2::new(D::from_f64(x[0]), D::from_f64(x[1]));
            let dual = DenseStep {
                x0: lift(dense.x0),
                f0: flat(dense.f0),
                x1: lift(dense.x1),
                f1: flat(dense.f1),
                h: D::from_f64(h),
            };
            let t = NearTrial {
                dense: dual,
                start_delta: D::seed(*start_delta, 0),
                eta: D::from_f64(eta),
            }
            .search_exact(&beam_d);
            let expect = -1.0 / (v + a * root);
            assert!(
                (t.d[0] - expect).abs() < 1e-9 * expect.abs(),
                "{} vs {expect}",
                t.d[0]
            );
        }
        assert!(crossed >= 40, "{crossed} of {}", all.len());
    }
}

//! Switching events of several runs located at once (host grids): the Illinois searches of
//! the contact lanes' sub-steps that hold an event ([`super::stepper`]'s `switch_begin`), `K`
//! side by side in vector lanes, each with the operations of the stepper's search alone
//! (`SwitchSearch::locate`), so with the same points, decisions and result, bit for bit.
//!
//! A search whose dense output leaves the lanes' short sine (`|θ| > 0.5` rad, the wire
//! pendulum) reports no result; the caller locates that one alone.

use super::bracket::{illinois_step, illinois_update};
use super::contact_lanes::LaneContact;
use super::dense::{MAX_EVENT_EVALS, hermite_weights};
use super::free::SmallTrig;
use super::isa::{Isa, Kernel};
use super::stepper::{EventCase, PendingSwitch, Simulator, SwitchSearch};
use crate::model::Hammer;
use crate::model::contact::LawCoeffs;
use crate::real::Real;

/// The event function's case as a lane code.
const LEAVES: u32 = 0;
const ARRIVES: u32 = 1;
const PRESSES: u32 = 2;

/// Up to `K` switching-event searches of runs with the suspension `F` and the linear law.
pub(crate) struct SwitchLanes<T: Real, F, const K: usize> {
    isa: Isa,
    /// Searches set (lanes `0..n`).
    n: usize,
    field: [F; K],
    /// The linear law's `k` (N/m) and `c` (N·s/m).
    k: [T; K],
    c: [T; K],
    /// The dense output: start `(x0, x1)`, its slope `(f0, f1)`, end `(y0, y1)`, its slope
    /// `(g0, g1)`, length `h` (s).
    x0: [T; K],
    x1: [T; K],
    f0: [T; K],
    f1: [T; K],
    y0: [T; K],
    y1: [T; K],
    g0: [T; K],
    g1: [T; K],
    h: [T; K],
    case: [u32; K],
    tol: [T; K],
    /// The event function at the ends.
    g_start: [T; K],
    g_end: [T; K],
}

/// [`SwitchLanes::locate`]'s searches as a [`Kernel`].
struct Locate<'a, T: Real, F, const K: usize> {
    lanes: &'a SwitchLanes<T, F, K>,
}

impl<T: Real, F: LaneContact<T>, const K: usize> Kernel for Locate<'_, T, F, K> {
    type Output = [Option<T>; K];
    #[inline(always)]
    fn run(self) -> [Option<T>; K] {
        self.lanes.locate_kernel()
    }
}

impl<T: Real, F: LaneContact<T>, const K: usize> SwitchLanes<T, F, K> {
    /// No search set.
    pub(crate) fn new() -> Self {
        let z = [T::zero(); K];
        SwitchLanes {
            isa: Isa::detect(),
            n: 0,
            field: [F::default(); K],
            k: z,
            c: z,
            x0: z,
            x1: z,
            f0: z,
            f1: z,
            y0: z,
            y1: z,
            g0: z,
            g1: z,
            h: z,
            case: [0; K],
            tol: z,
            g_start: z,
            g_end: z,
        }
    }

    /// Searches set.
    #[inline]
    pub(crate) fn len(&self) -> usize {
        self.n
    }

    /// Sets `sim`'s pending search into the next lane, and returns that lane (`None`, nothing
    /// set: all are taken, or `sim` is not of this suspension and the linear law).
    #[inline]
    pub(crate) fn push(
        &mut self,
        sim: &Simulator<'_, T>,
        pending: &PendingSwitch<T>,
    ) -> Option<usize> {
        self.push_search(sim.hammer(), &pending.search)
    }

    /// [`SwitchLanes::push`] of a search on `hammer`.
    #[inline]
    fn push_search(&mut self, hammer: &Hammer<T>, s: &SwitchSearch<T>) -> Option<usize> {
        let i = self.n;
        let (true, Some(field), LawCoeffs::Linear { k, c }) =
            (i < K, F::of(&hammer.free_flight()), hammer.switch().law)
        else {
            return None;
        };
        let d = &s.dense;
        self.field[i] = field;
        (self.k[i], self.c[i]) = (k, c);
        (self.x0[i], self.x1[i], self.f0[i], self.f1[i]) = (d.x0[0], d.x0[1], d.f0[0], d.f0[1]);
        (self.y0[i], self.y1[i], self.g0[i], self.g1[i]) = (d.x1[0], d.x1[1], d.f1[0], d.f1[1]);
        self.h[i] = d.h;
        self.case[i] = match s.case {
            EventCase::Leaves => LEAVES,
            EventCase::Arrives => ARRIVES,
            EventCase::Presses => PRESSES,
        };
        self.tol[i] = s.tol;
        (self.g_start[i], self.g_end[i]) = s.ends;
        self.n += 1;
        Some(i)
    }

    /// Drops the searches set.
    #[inline]
    pub(crate) fn clear(&mut self) {
        self.n = 0;
    }

    /// Locates the events of the searches set, as fractions of their sub-steps (`None`: a
    /// sine outside the short range, to be located alone), and clears the lanes.
    pub(crate) fn locate(&mut self) -> [Option<T>; K] {
        // Lanes not set take no step (their ends do not bracket a zero).
        for i in self.n..K {
            (self.g_start[i], self.g_end[i]) = (T::from_f64(1.0), T::from_f64(1.0));
            self.tol[i] = T::from_f64(1.0);
        }
        self.n = 0;
        self.isa.run(Locate { lanes: self })
    }

    /// The searches lane by lane, branch-free: each round one point of every search still
    /// going ([`illinois_step`]), its dense-output state (`DenseStep::at`), penetration
    /// (`Hammer::penetration`, the lanes' short sine) and event function (`EventCase::value`
    /// of the linear law).
    #[inline(always)]
    fn locate_kernel(&self) -> [Option<T>; K] {
        let zero = T::zero();
        let one = T::from_f64(1.0);
        let mut lo = [zero; K];
        let mut hi = [one; K];
        let mut g_lo = self.g_start;
        let mut g_hi = self.g_end;
        let mut side = [0u32; K];
        let mut searching = [0u32; K];
        let mut exact = [1u32; K];
        for i in 0..K {
            let brackets = (g_lo[i] <= zero) & (g_hi[i] > zero);
            searching[i] = u32::from(brackets);
            // Where the ends do not bracket a rising zero: the end `illinois` gives.
            let end = if g_lo[i] > zero { zero } else { one };
            lo[i] = if brackets { zero } else { end };
            hi[i] = if brackets { one } else { end };
        }
        for _ in 0..MAX_EVENT_EVALS {
            let mut mids = [zero; K];
            let mut going = 0u32;
            for i in 0..K {
                let on = (searching[i] != 0) & (hi[i] - lo[i] > self.tol[i]);
                searching[i] = u32::from(on);
                going |= searching[i];
                mids[i] = illinois_step(lo[i], hi[i], g_lo[i], g_hi[i]);
            }
            if going == 0 {
                break;
            }
            let mut g_mid = [zero; K];
            for i in 0..K {
                // `DenseStep::at`, component by component.
                let (h00, h10, h01, h11) = hermite_weights(mids[i], self.h[i]);
                let u0 = self.x0[i] * h00 + self.f0[i] * h10 + self.y0[i] * h01 + self.g0[i] * h11;
                let u1 = self.x1[i] * h00 + self.f1[i] * h10 + self.y1[i] * h01 + self.g1[i] * h11;
                let (d, dd, _, ok) = self.field[i].penetration::<SmallTrig>(u0, u1);
                let f = self.k[i] * d + self.c[i] * dd;
                let case = self.case[i];
                g_mid[i] = if case == LEAVES {
                    -f
                } else if case == ARRIVES {
                    d
                } else {
                    f
                };
                exact[i] &= u32::from(ok) | (searching[i] ^ 1);
            }
            for i in 0..K {
                illinois_update(
                    searching[i] != 0,
                    (mids[i], g_mid[i]),
                    (&mut lo[i], &mut hi[i]),
                    (&mut g_lo[i], &mut g_hi[i]),
                    &mut side[i],
                );
            }
        }
        core::array::from_fn(|i| (exact[i] != 0).then_some(hi[i]))
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector2;

    use super::*;
    use crate::integrate::dense::{DenseStep, EVENT_TOL};
    use crate::integrate::isa::with_isa;
    use crate::model::hammer::{BeamFree, Body, WiresFree};
    use crate::model::{RigId, SwitchBands};

    /// A search on `hammer` over a sub-step of `h` s from `x0` to `x1` (slopes from the
    /// straight line between them and a constant acceleration `acc`), its ends from the event
    /// function itself.
    fn search(
        hammer: &Hammer<f32>,
        case: EventCase,
        x0: Vector2<f32>,
        x1: Vector2<f32>,
        acc: f32,
    ) -> SwitchSearch<f32> {
        let h = 4.5e-5;
        let mut s = SwitchSearch {
            dense: DenseStep {
                x0,
                f0: Vector2::new(x0[1], acc),
                x1,
                f1: Vector2::new(x1[1], acc),
                h,
            },
            ends: (0.0, 0.0),
            case,
            v_in: 0.05,
            tol: EVENT_TOL as f32,
            offset: 0.0,
            s_end: 0.0,
            touching: case == EventCase::Leaves,
        };
        s.ends = (s.event_at(hammer, case, 0.0), s.event_at(hammer, case, 1.0));
        s
    }

    /// Searches of every case on `hammer`, whose state `x` at penetration `d` (m) and rate
    /// `v` (m/s) is `state(d, v)`: arrivals across the surface, departures with the force
    /// falling through 0, presses from inside, and some that do not bracket a zero.
    fn searches(
        hammer: &Hammer<f32>,
        state: impl Fn(f64, f64) -> Vector2<f32>,
    ) -> std::vec::Vec<SwitchSearch<f32>> {
        let mut out = std::vec::Vec::new();
        for j in 0..12 {
            let a = 1.0 + j as f64 * 0.37;
            // An arrival: δ from −2 µm·a to +3 µm, approaching at 0.05·a m/s.
            let v = 0.05 * a;
            let (d0, d1) = (-2e-6 * a, 3e-6);
            out.push(search(
                hammer,
                EventCase::Arrives,
                state(d0, v),
                state(d1, v),
                -2.0,
            ));
            // A departure: the spring–dashpot force k δ + c δ̇ falling through 0 (δ̇ from 0 to
            // a rate that outweighs the spring), and inside the surface the same rising.
            let LawCoeffs::Linear { k, c } = hammer.switch().law else {
                panic!("the presets' linear law");
            };
            let w1 = -2.0 * a * f64::from(k) * 1e-6 / f64::from(c);
            let (press, release) = (state(1e-6, 0.0), state(0.5e-6, w1));
            out.push(search(hammer, EventCase::Leaves, press, release, 0.0));
            out.push(search(hammer, EventCase::Presses, release, press, 0.0));
        }
        out
    }

    /// Every search through the lanes (8 at a time and a last partial set), against the
    /// stepper's search alone: the same fraction, bit for bit, or none where the lanes' sine
    /// does not reach.
    fn lanes_match_alone<F: LaneContact<f32>>(
        hammer: &Hammer<f32>,
        all: &[SwitchSearch<f32>],
        expect_some: bool,
    ) -> usize {
        let mut lanes = SwitchLanes::<f32, F, 8>::new();
        let mut bracketed = 0;
        for chunk in all.chunks(8) {
            for s in chunk {
                assert!(lanes.push_search(hammer, s).is_some());
            }
            assert_eq!(lanes.len(), chunk.len());
            let got = lanes.locate();
            assert_eq!(lanes.len(), 0);
            for (s, g) in chunk.iter().zip(got) {
                let alone = s.locate(hammer);
                if expect_some {
                    assert_eq!(g.map(f32::to_bits), Some(alone.to_bits()), "{:?}", s.case);
                } else {
                    assert_eq!(g, None, "{:?}", s.case);
                }
                bracketed += usize::from(alone > 0.0 && alone < 1.0);
            }
        }
        bracketed
    }

    #[test]
    fn switch_lanes_locate_every_event_as_the_stepper_alone() {
        let bands = SwitchBands::default();
        let wires = Hammer::<f32>::new(&RigId::Wires.preset(), 1e-3, 20.0, &bands).unwrap();
        let Body::Wires { length, .. } = *wires.body() else {
            panic!("the wire rig's body");
        };
        let l = f64::from(length);
        let gap = 1e-3;
        let pendulum = |d: f64, v: f64| {
            let theta = ((gap + d) / l).asin();
            Vector2::new(theta as f32, (v / (l * theta.cos())) as f32)
        };
        let beam_hammer = Hammer::<f32>::new(&RigId::Beam170.preset(), 1e-3, 60.0, &bands).unwrap();
        let beam = |d: f64, v: f64| Vector2::new((gap + d) as f32, v as f32);
        for isa in Isa::supported() {
            with_isa(isa, || {
                let n =
                    lanes_match_alone::<WiresFree<f32>>(&wires, &searches(&wires, pendulum), true);
                // Most searches bracket an event (the test is not of the ends alone).
                assert!(n >= 30, "{n} of 36 bracketed");
                let n = lanes_match_alone::<BeamFree<f32>>(
                    &beam_hammer,
                    &searches(&beam_hammer, beam),
                    true,
                );
                assert!(n >= 30, "{n} of 36 bracketed");
                // A pendulum at 0.6 rad, past the lanes' short sine: located alone instead.
                let wide = [search(
                    &wires,
                    EventCase::Arrives,
                    Vector2::new(0.55, 1.0),
                    Vector2::new(0.65, 1.0),
                    0.0,
                )];
                let mut lanes = SwitchLanes::<f32, WiresFree<f32>, 8>::new();
                let mut w = wide[0];
                w.ends = (-1.0, 1.0);
                assert!(lanes.push_search(&wires, &w).is_some());
                assert_eq!(lanes.locate()[0], None);
            });
        }
    }
}

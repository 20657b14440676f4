//! Switching events of several runs located at once (host grids): the Illinois searches of
//! the contact lanes' sub-steps that hold an event ([`super::stepper`]'s `switch_begin`), `K`
//! side by side in vector lanes, each with the operations of the stepper's search alone
//! (`SwitchSearch::locate`), so with the same points, decisions and result, bit for bit.
//!
//! Each lane then ends its sub-step as the stepper would after its event
//! (`Simulator::switch_finish`: the state at the event from the dense output, one RK4 step of
//! the switch model to the sub-step's end), with the same operations, so with the same state.
//!
//! A search whose dense output leaves the lanes' short sine (`|θ| > 0.5` rad, the wire
//! pendulum) reports no result, and the caller locates that one alone; a sub-step whose end
//! leaves it (or the phase's short sine) reports the event only, and the caller ends it.

use core::marker::PhantomData;

use nalgebra::Vector2;

use super::bracket::{illinois_step, illinois_update};
use super::contact_lanes::{linear_switch_force, region_of};
use super::dense::{MAX_EVENT_EVALS, hermite_weights};
use super::free::SmallTrig;
use super::isa::{Isa, Kernel, Variant};
use super::lane_field::LaneContact;
use super::rk4::rk4_step_compensated;
use super::stepper::{
    EventCase, EventFound, Handback, PendingSwitch, Simulator, SwitchSearch, min_approach,
};
use crate::model::Hammer;
use crate::model::contact::LawCoeffs;
use crate::model::hammer::{Damped, FieldEval, Undamped, Viscous};
use crate::real::Real;

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
    /// The event function's case as two lane masks (1: yes): the force `−F` on a departure,
    /// the penetration `δ` on an arrival, else the force `F` (a press). (Masks rather than a
    /// case code: two selects and no comparisons in each round of the searches.)
    leaves: [u32; K],
    arrives: [u32; K],
    tol: [T; K],
    /// The event function at the ends.
    g_start: [T; K],
    g_end: [T; K],
    // What ending the sub-step after its event takes: its start, s into the step, and `sin Ωt`
    // at its end; 1 if it starts touching; the approach speed (m/s); `Ω` (rad/s) and `sin Ωt`,
    // `cos Ωt` at the step's start; the suspension's `inv_mass`; the bands `η_δ` (m), `η_F` (N).
    offset: [T; K],
    s_end: [T; K],
    touching: [u32; K],
    v_in: [T; K],
    omega: [T; K],
    sin0: [T; K],
    cos0: [T; K],
    inv_mass: [T; K],
    eta_d: [T; K],
    eta_f: [T; K],
    /// Whether the searches are of the damped pendulum (the [`Damped`] field), once one is set.
    damped: Option<bool>,
}

/// [`SwitchLanes::locate`]'s searches and sub-step ends as a [`Kernel`], the pendulum's viscous
/// term as `V` has it.
struct Locate<'a, T: Real, F, const K: usize, V> {
    lanes: &'a SwitchLanes<T, F, K>,
    viscous: PhantomData<V>,
}

impl<T: Real, F: LaneContact<T>, const K: usize, V: Viscous> Kernel for Locate<'_, T, F, K, V> {
    type Output = [EventFound<T>; K];
    #[inline(always)]
    fn run<I: Variant>(self) -> [EventFound<T>; K] {
        let fracs = self.lanes.locate_kernel();
        self.lanes.finish_kernel::<V>(fracs)
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
            leaves: [0; K],
            arrives: [0; K],
            tol: z,
            g_start: z,
            g_end: z,
            offset: z,
            s_end: z,
            touching: [0; K],
            v_in: z,
            omega: z,
            sin0: z,
            cos0: z,
            inv_mass: z,
            eta_d: z,
            eta_f: z,
            damped: None,
        }
    }

    /// Searches set.
    #[inline]
    pub(crate) fn len(&self) -> usize {
        self.n
    }

    /// Sets `sim`'s pending search into the next lane, and returns that lane (`None`, nothing
    /// set: all are taken, `sim` is not of this suspension and the linear law, or (the
    /// pendulum) damped where the searches set since the lanes were made are not, or the other
    /// way round).
    #[inline]
    pub(crate) fn push(
        &mut self,
        sim: &Simulator<'_, T>,
        pending: &PendingSwitch<T>,
    ) -> Option<usize> {
        self.push_search(sim.hammer(), &pending.search, sim.step_phase())
    }

    /// [`SwitchLanes::push`] of a search on `hammer` in the step whose `(Ω, sin Ωt, cos Ωt)` at
    /// its start is `phase` (rad/s, 1, 1).
    #[inline]
    fn push_search(
        &mut self,
        hammer: &Hammer<T>,
        s: &SwitchSearch<T>,
        phase: (T, T, T),
    ) -> Option<usize> {
        let i = self.n;
        let (true, Some(field), Some(inv_mass), LawCoeffs::Linear { k, c }) = (
            i < K,
            F::of(&hammer.free_flight()),
            F::inv_mass(hammer.body()),
            hammer.switch().law,
        ) else {
            return None;
        };
        let damped = hammer.is_damped_wires();
        if *self.damped.get_or_insert(damped) != damped {
            return None;
        }
        (self.offset[i], self.s_end[i], self.v_in[i]) = (s.offset, s.s_end, s.v_in);
        self.touching[i] = u32::from(s.touching);
        (self.omega[i], self.sin0[i], self.cos0[i]) = phase;
        self.inv_mass[i] = inv_mass;
        (self.eta_d[i], self.eta_f[i]) = (hammer.switch().eta_delta, hammer.switch().eta_force);
        let d = &s.dense;
        self.field[i] = field;
        (self.k[i], self.c[i]) = (k, c);
        (self.x0[i], self.x1[i], self.f0[i], self.f1[i]) = (d.x0[0], d.x0[1], d.f0[0], d.f0[1]);
        (self.y0[i], self.y1[i], self.g0[i], self.g1[i]) = (d.x1[0], d.x1[1], d.f1[0], d.f1[1]);
        self.h[i] = d.h;
        self.leaves[i] = u32::from(s.case == EventCase::Leaves);
        self.arrives[i] = u32::from(s.case == EventCase::Arrives);
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

    /// Locates the events of the searches set and ends their sub-steps, and clears the lanes:
    /// for each search, the sub-step ended ([`EventFound::Ended`]), or the event only as a
    /// fraction of the sub-step (`At`: the end's sine outside the short range), or nothing
    /// (`Alone`: the search's sine outside it).
    pub(crate) fn locate(&mut self) -> [EventFound<T>; K] {
        // Lanes not set take no step (their ends do not bracket a zero).
        for i in self.n..K {
            (self.g_start[i], self.g_end[i]) = (T::from_f64(1.0), T::from_f64(1.0));
            self.tol[i] = T::from_f64(1.0);
        }
        self.n = 0;
        if self.damped == Some(true) {
            self.isa.run(Locate {
                lanes: self,
                viscous: PhantomData::<Damped>,
            })
        } else {
            self.isa.run(Locate {
                lanes: self,
                viscous: PhantomData::<Undamped>,
            })
        }
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
                let g = if self.arrives[i] != 0 { d } else { f };
                g_mid[i] = if self.leaves[i] != 0 { -f } else { g };
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

    /// Each lane's sub-step ended after its event at fraction `fracs[i]` of it, lane by lane
    /// with `Simulator::switch_finish`'s operations (branch-free): the state at the event from
    /// the dense output, its switch-model field (the approach speed taken there on an arrival),
    /// one compensated RK4 step of the switch model over the rest of the sub-step, and the
    /// field at its end.
    #[inline(always)]
    fn finish_kernel<V: Viscous>(&self, fracs: [Option<T>; K]) -> [EventFound<T>; K] {
        let zero = T::zero();
        let half = T::from_f64(0.5);
        let frac: [T; K] = core::array::from_fn(|i| fracs[i].unwrap_or(zero));
        // Every lane's end, one array per field (so that the lanes vectorise).
        let (mut o_x0, mut o_x1, mut o_c0, mut o_c1) = ([zero; K], [zero; K], [zero; K], [zero; K]);
        let (mut o_acc, mut o_d, mut o_dd, mut o_force) =
            ([zero; K], [zero; K], [zero; K], [zero; K]);
        let (mut o_v, mut o_region, mut o_exact) = ([zero; K], [0u32; K], [0u32; K]);
        for i in 0..K {
            let (field, inv_mass) = (&self.field[i], self.inv_mass[i]);
            let (k, c, eta_d, eta_f) = (self.k[i], self.c[i], self.eta_d[i], self.eta_f[i]);
            let len = self.h[i];
            let tau = frac[i] * len;
            // `DenseStep::at`, component by component.
            let (h00, h10, h01, h11) = hermite_weights(frac[i], len);
            let xa0 = self.x0[i] * h00 + self.f0[i] * h10 + self.y0[i] * h01 + self.g0[i] * h11;
            let xa1 = self.x1[i] * h00 + self.f1[i] * h10 + self.y1[i] * h01 + self.g1[i] * h11;
            let (_, dd_a, _, mut exact) = field.penetration::<SmallTrig>(xa0, xa1);
            let v_in = if self.touching[i] != 0 {
                self.v_in[i]
            } else {
                dd_a.max_of(min_approach())
            };
            // `sin Ωt` at `dt` into the step (`Simulator::sin_at`).
            let phase = |dt: T| {
                let (s, c, exact) = (self.omega[i] * dt).sin_cos_lane();
                (self.sin0[i] * c + self.cos0[i] * s, exact)
            };
            let rest = len - tau;
            let (s_a, exact_a) = phase(self.offset[i] + tau);
            let (s_rest, exact_rest) = phase(self.offset[i] + tau + rest * half);
            exact &= exact_a & exact_rest;
            // The switch-model field (`Hammer::field`, the linear law).
            let mut field_at = |y0: T, y1: T, s: T| {
                let mut region = 0;
                let (acc, d, dd, force, ok) =
                    field.contact_field::<SmallTrig, V, _>(inv_mass, y0, y1, s, |d, dd| {
                        let f;
                        (f, region) = linear_switch_force(k, c, eta_d, eta_f, d, dd);
                        f
                    });
                exact &= ok;
                (acc, d, dd, force, region)
            };
            let (acc_a, ..) = field_at(xa0, xa1, s_a);
            let (x, carry) = rk4_step_compensated(
                &Vector2::new(xa0, xa1),
                &Vector2::new(zero, zero),
                &Vector2::new(xa1, acc_a),
                rest,
                s_rest,
                self.s_end[i],
                |y, s| Vector2::new(y[1], field_at(y[0], y[1], s).0),
            );
            let (acc, d, dd, force, region) = field_at(x[0], x[1], self.s_end[i]);
            (o_x0[i], o_x1[i], o_c0[i], o_c1[i]) = (x[0], x[1], carry[0], carry[1]);
            (o_acc[i], o_d[i], o_dd[i], o_force[i]) = (acc, d, dd, force);
            (o_v[i], o_region[i], o_exact[i]) = (v_in, region, u32::from(exact));
        }
        core::array::from_fn(|i| match fracs[i] {
            None => EventFound::Alone,
            Some(frac) if o_exact[i] == 0 => EventFound::At(frac),
            Some(_) => EventFound::Ended(Handback {
                x: Vector2::new(o_x0[i], o_x1[i]),
                carry: Vector2::new(o_c0[i], o_c1[i]),
                at_x: FieldEval {
                    dx: Vector2::new(o_x1[i], o_acc[i]),
                    force: o_force[i],
                    region: region_of(o_region[i]),
                    delta: o_d[i],
                    delta_dot: o_dd[i],
                },
                approach_speed: o_v[i],
            }),
        })
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector2;

    use super::*;
    use crate::integrate::dense::{DenseStep, EVENT_TOL};
    use crate::integrate::isa::with_isa;
    use crate::model::hammer::{BeamFree, Body, WiresFree};
    use crate::model::{RigId, Suspension, SwitchBands};

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

    /// A search with the phase of its step, `(Ω, sin Ωt, cos Ωt)` at the step's start.
    type Phased = (SwitchSearch<f32>, (f32, f32, f32));

    /// The phase of the step each search of [`searches`] falls in: `(Ω, sin Ωt, cos Ωt)` at the
    /// step's start (rad/s, 1, 1), with its start `offset` (s) and `sin Ωt` at its end set in
    /// the search. Every fourth search starts so late in its step (`Ω · offset` = 1 rad) that
    /// the lanes' short sine of the phase does not reach: its event located, its end not.
    fn phased(all: std::vec::Vec<SwitchSearch<f32>>) -> std::vec::Vec<Phased> {
        all.into_iter()
            .enumerate()
            .map(|(j, mut s)| {
                let (omega, offset) = if j % 4 == 3 {
                    (1000.0, 1e-3)
                } else {
                    (18.85, 1e-4 * j as f64)
                };
                let t0 = 0.7 + 0.05 * j as f64;
                let at = |dt: f64| (t0 + omega * dt).sin() as f32;
                s.offset = offset as f32;
                s.s_end = at(offset + f64::from(s.dense.h));
                (s, (omega as f32, t0.sin() as f32, t0.cos() as f32))
            })
            .collect()
    }

    /// A sub-step's end as bits.
    fn bits(d: &Handback<f32>) -> [u32; 10] {
        let e = &d.at_x;
        [
            d.x[0],
            d.x[1],
            d.carry[0],
            d.carry[1],
            e.dx[1],
            e.force,
            e.delta,
            e.delta_dot,
            d.approach_speed,
            e.dx[0],
        ]
        .map(f32::to_bits)
    }

    /// Every search through the lanes (8 at a time and a last partial set), against the
    /// stepper's search and sub-step end alone: the same fraction and end, bit for bit, or the
    /// fraction alone where the lanes' sine of the phase does not reach. Returns the searches
    /// that bracket an event and the sub-steps the lanes ended.
    fn lanes_match_alone<F: LaneContact<f32>>(
        hammer: &Hammer<f32>,
        all: &[Phased],
    ) -> (usize, usize) {
        let mut lanes = SwitchLanes::<f32, F, 8>::new();
        let (mut bracketed, mut ended) = (0, 0);
        for chunk in all.chunks(8) {
            for (s, phase) in chunk {
                assert!(lanes.push_search(hammer, s, *phase).is_some());
            }
            assert_eq!(lanes.len(), chunk.len());
            let got = lanes.locate();
            assert_eq!(lanes.len(), 0);
            for ((s, phase), g) in chunk.iter().zip(got) {
                let alone = s.locate(hammer);
                let late = phase.0 * s.offset > 0.5;
                match g {
                    EventFound::Ended(d) => {
                        assert!(!late, "{:?}: ended past the short sine", s.case);
                        let want = s.finish(hammer, alone, *phase);
                        assert_eq!(bits(&d), bits(&want), "{:?}", s.case);
                        assert_eq!(d.at_x.region, want.at_x.region, "{:?}", s.case);
                        ended += 1;
                    }
                    EventFound::At(frac) => {
                        assert!(late, "{:?}: not ended in the lanes", s.case);
                        assert_eq!(frac.to_bits(), alone.to_bits(), "{:?}", s.case);
                    }
                    EventFound::Alone => panic!("{:?}: not located in the lanes", s.case),
                }
                bracketed += usize::from(alone > 0.0 && alone < 1.0);
            }
        }
        (bracketed, ended)
    }

    #[test]
    fn switch_lanes_locate_every_event_and_end_its_substep_as_the_stepper_alone() {
        let bands = SwitchBands::default();
        let mut damped = RigId::Wires.preset();
        let Suspension::Wires { damping_ratio, .. } = &mut damped.suspension else {
            panic!("the wire rig's suspension");
        };
        *damping_ratio = 0.004;
        let gap = 1e-3;
        let beam_hammer = Hammer::<f32>::new(&RigId::Beam170.preset(), gap, 60.0, &bands).unwrap();
        let beam = |d: f64, v: f64| Vector2::new((gap + d) as f32, v as f32);
        for isa in Isa::supported() {
            with_isa(isa, || {
                for rig in [RigId::Wires.preset(), damped] {
                    let wires = Hammer::<f32>::new(&rig, gap, 20.0, &bands).unwrap();
                    let Body::Wires { length, .. } = *wires.body() else {
                        panic!("the wire rig's body");
                    };
                    let l = f64::from(length);
                    let pendulum = |d: f64, v: f64| {
                        let theta = ((gap + d) / l).asin();
                        Vector2::new(theta as f32, (v / (l * theta.cos())) as f32)
                    };
                    let all = phased(searches(&wires, pendulum));
                    let (n, ended) = lanes_match_alone::<WiresFree<f32>>(&wires, &all);
                    // Most searches bracket an event (the test is not of the ends alone), and
                    // all but the late ones are ended in the lanes.
                    assert!(n >= 30, "{n} of 36 bracketed");
                    assert_eq!(ended, 27);
                }
                let all = phased(searches(&beam_hammer, beam));
                let (n, ended) = lanes_match_alone::<BeamFree<f32>>(&beam_hammer, &all);
                assert!(n >= 30, "{n} of 36 bracketed");
                assert_eq!(ended, 27);
                // A pendulum at 0.6 rad, past the lanes' short sine: located alone instead.
                let wires = Hammer::<f32>::new(&RigId::Wires.preset(), gap, 20.0, &bands).unwrap();
                let mut w = search(
                    &wires,
                    EventCase::Arrives,
                    Vector2::new(0.55, 1.0),
                    Vector2::new(0.65, 1.0),
                    0.0,
                );
                w.ends = (-1.0, 1.0);
                let mut lanes = SwitchLanes::<f32, WiresFree<f32>, 8>::new();
                assert!(lanes.push_search(&wires, &w, (18.85, 0.0, 1.0)).is_some());
                assert!(matches!(lanes.locate()[0], EventFound::Alone));
                // The lanes hold searches of one kind: a damped pendulum's after an undamped
                // one's is refused (the caller then ends it alone).
                let damped_hammer = Hammer::<f32>::new(&damped, gap, 20.0, &bands).unwrap();
                let s = search(
                    &wires,
                    EventCase::Arrives,
                    Vector2::new(0.01, 0.1),
                    Vector2::new(0.02, 0.1),
                    0.0,
                );
                assert!(lanes.push_search(&wires, &s, (18.85, 0.0, 1.0)).is_some());
                assert!(
                    lanes
                        .push_search(&damped_hammer, &s, (18.85, 0.0, 1.0))
                        .is_none()
                );
            });
        }
    }
}

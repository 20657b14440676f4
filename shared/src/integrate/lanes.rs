//! Whole free-flight steps of several simulators in lockstep (the host's grid analyses).
//!
//! Far from the surface, the next step of a [`Simulator`] is one RK4 step of `h = T/N` in free
//! flight (the first branch of [`Simulator::step`]): the same short chain of `+` and `×` for
//! every simulator of a grid. [`free_flight`] evaluates it for `L` simulators at once, so the
//! compiler packs the lanes into SIMD registers, and skips the per-step bookkeeping in between.
//! Each lane takes exactly the steps [`Simulator::step`] would take in one piece, bit for bit
//! the same numbers (the same operations in the same order, the field from the same
//! [`wires_free`]/[`beam_free`] formulas), and stops before the period's last step (the Poincaré
//! section), before any step that the scalar path would split near the surface, and (wires)
//! before an angle outside the short sine polynomial's range `|θ| ≤ 1/8`. The caller then
//! takes the next step with [`Simulator::step`] as usual.

use nalgebra::Vector2;

use super::Simulator;
use crate::model::Region;
use crate::model::hammer::{Body, FieldEval, beam_free, wires_free};
use crate::real::Real;

/// One lane's state between lockstep steps: `x = (x0, x1)`, the field's second component `a`
/// at `x`, penetration `d` and its rate `dd`.
#[derive(Clone, Copy, Default)]
struct LaneState<T> {
    x0: T,
    x1: T,
    a: T,
    d: T,
    dd: T,
}

/// The states of `L` lanes, one array per field (so that the lanes pack into SIMD registers).
struct States<T, const L: usize> {
    x0: [T; L],
    x1: [T; L],
    a: [T; L],
    d: [T; L],
    dd: [T; L],
}

impl<T: Real, const L: usize> States<T, L> {
    fn new() -> Self {
        States {
            x0: [T::zero(); L],
            x1: [T::zero(); L],
            a: [T::zero(); L],
            d: [T::zero(); L],
            dd: [T::zero(); L],
        }
    }
    #[inline(always)]
    fn get(&self, i: usize) -> LaneState<T> {
        LaneState {
            x0: self.x0[i],
            x1: self.x1[i],
            a: self.a[i],
            d: self.d[i],
            dd: self.dd[i],
        }
    }
    /// Takes lane `i` from `next` where `go[i]` is 1, keeps it where 0.
    #[inline(always)]
    fn select(&mut self, go: &[u32; L], next: &Self) {
        #[inline(always)]
        fn pick<T: Copy, const L: usize>(cur: &mut [T; L], new: &[T; L], go: &[u32; L]) {
            for i in 0..L {
                cur[i] = if go[i] != 0 { new[i] } else { cur[i] };
            }
        }
        pick(&mut self.x0, &next.x0, go);
        pick(&mut self.x1, &next.x1, go);
        pick(&mut self.a, &next.a, go);
        pick(&mut self.d, &next.d, go);
        pick(&mut self.dd, &next.dd, go);
    }
    #[inline(always)]
    fn set(&mut self, i: usize, s: LaneState<T>) {
        self.x0[i] = s.x0;
        self.x1[i] = s.x1;
        self.a[i] = s.a;
        self.d[i] = s.d;
        self.dd[i] = s.dd;
    }
}

/// A lane's constants: the body's three coefficients, gap and step.
#[derive(Clone, Copy, Default)]
struct LaneConst<T> {
    c0: T,
    c1: T,
    c2: T,
    gap: T,
    h: T,
}

/// Free-flight `(acceleration, δ, δ̇)` of state `(y0, y1)` for wires (`c0, c1, c2 = l, g/l,
/// A0Ω²/l`, `y0 = θ`; `δ̇ = l θ̇ cos θ` as in the field's kinematics) or beams (`k/m, c/m,
/// A0Ω²`), and whether the short sine polynomial was in range. (The RK4 stages use only the
/// first two; the compiler drops `δ̇` there.)
#[inline(always)]
fn free<T: Real, const WIRES: bool>(c: &LaneConst<T>, y0: T, y1: T, s: T) -> (T, T, T, bool) {
    if WIRES {
        let (st, ct) = y0.sin_cos_small();
        let lim = T::from_f64(0.125);
        let (acc, d) = wires_free(c.c0, c.c1, c.c2, c.gap, st, ct, s);
        (acc, d, c.c0 * y1 * ct, y0 <= lim && y0 >= -lim)
    } else {
        let (acc, d) = beam_free(c.c0, c.c1, c.c2, c.gap, y0, y1, s);
        (acc, d, y1, true)
    }
}

/// One trial step of a lane: the new state and whether [`Simulator::step`] would accept it in
/// one piece (`free_trial`'s test, plus the polynomial's range).
#[inline(always)]
fn trial<T: Real, const WIRES: bool>(
    c: &LaneConst<T>,
    st: &LaneState<T>,
    eta: T,
    s_mid: T,
    s_end: T,
) -> (LaneState<T>, bool) {
    let half = T::from_f64(0.5);
    let sixth = T::from_f64(1.0 / 6.0);
    let two = T::from_f64(2.0);
    let (h, th, w, acc0) = (c.h, st.x0, st.x1, st.a);
    // rk4_step with k1 = (x1, a): the same operations in the same order.
    let hh = h * half;
    let (y2_0, y2_1) = (th + w * hh, w + acc0 * hh);
    let (a2, d2, _, ok2) = free::<T, WIRES>(c, y2_0, y2_1, s_mid);
    let (y3_0, y3_1) = (th + y2_1 * hh, w + a2 * hh);
    let (a3, d3, _, ok3) = free::<T, WIRES>(c, y3_0, y3_1, s_mid);
    let (y4_0, y4_1) = (th + y3_1 * h, w + a3 * h);
    let (a4, d4, _, ok4) = free::<T, WIRES>(c, y4_0, y4_1, s_end);
    let h6 = h * sixth;
    let n0 = th + (w + y2_1 * two + y3_1 * two + y4_1) * h6;
    let n1 = w + (acc0 + a2 * two + a3 * two + a4) * h6;
    // The end state's field (`field_in(Free, ..)`: the force is 0).
    let (a5, d5, dd5, ok5) = free::<T, WIRES>(c, n0, n1, s_end);
    let neg_eta = -eta;
    let touched = (d2 > neg_eta) | (d3 > neg_eta) | (d4 > neg_eta);
    let mut near = touched | (d5 > neg_eta);
    // Turned round inside the step: the peak lies under the two tangent lines.
    let turned = (st.dd > T::zero()) & (dd5 < T::zero());
    let slope = st.dd - dd5;
    let t_star = (d5 - st.d - dd5 * h) / slope;
    near |= turned & (st.d + st.dd * t_star > neg_eta);
    let next = LaneState {
        x0: n0,
        x1: n1,
        a: a5,
        d: d5,
        dd: dd5,
    };
    (next, ok2 & ok3 & ok4 & ok5 & !near)
}

/// Takes whole free-flight steps on the simulators of `sims` (at most `L` of them; further
/// ones are left alone) in lockstep, as long as at least a quarter of the lanes that started can
/// go on. A simulator takes part if it has the first one's `N`, suspension type and band
/// `η_δ`, is clear of the surface, and is not at its period's last step. Returns the steps
/// each took (0 for those that did not take part). Each simulator ends exactly where the same
/// number of [`Simulator::step`] calls would have left it.
///
/// With the `std` feature on x86-64 (the host), the kernel runs as AVX2 code when the CPU has
/// it (chosen at run time: 8 `f32` lanes per register instead of 4): the same operations in the
/// same order, no fused multiply-add, so the same bits.
pub fn free_flight<T: Real, const L: usize>(sims: &mut [&mut Simulator<T>]) -> [u32; L] {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    if std::is_x86_feature_detected!("avx") && std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX and AVX2 (checked just above).
        return unsafe { free_flight_avx::<T, L>(sims) };
    }
    free_flight_kernel::<T, L>(sims)
}

/// [`free_flight`] compiled for AVX2.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx,avx2")]
fn free_flight_avx<T: Real, const L: usize>(sims: &mut [&mut Simulator<T>]) -> [u32; L] {
    free_flight_kernel::<T, L>(sims)
}

/// The body of [`free_flight`] (inlined into each instruction-set variant).
#[inline(always)]
fn free_flight_kernel<T: Real, const L: usize>(sims: &mut [&mut Simulator<T>]) -> [u32; L] {
    let mut taken = [0u32; L];
    let lanes = sims.len().min(L);
    if lanes == 0 {
        return taken;
    }
    let wires = matches!(sims[0].hammer.body, Body::Wires { .. });
    let n = sims[0].n;
    let eta = sims[0].hammer.switch.eta_delta;
    let mut cst = [LaneConst::default(); L];
    let mut state = States::<T, L>::new();
    let mut k = [0u32; L];
    let mut rem = [0u32; L];
    for (i, sim) in sims.iter().take(lanes).enumerate() {
        let (c, same_kind) = match sim.hammer.body {
            Body::Wires {
                length,
                g_over_l,
                a0w2_over_l,
                ..
            } => ((length, g_over_l, a0w2_over_l), wires),
            Body::Beam {
                k_over_m,
                c_over_m,
                a0w2,
                ..
            } => ((k_over_m, c_over_m, a0w2), !wires),
        };
        cst[i] = LaneConst {
            c0: c.0,
            c1: c.1,
            c2: c.2,
            gap: sim.hammer.gap,
            h: sim.h,
        };
        state.set(
            i,
            LaneState {
                x0: sim.x[0],
                x1: sim.x[1],
                a: sim.at_x.dx[1],
                d: sim.at_x.delta,
                dd: sim.at_x.delta_dot,
            },
        );
        k[i] = sim.k;
        let eligible = same_kind
            && sim.n == n
            && sim.hammer.switch.eta_delta == eta
            && sim.clear(&sim.at_x)
            && sim.k + 1 < n;
        rem[i] = if eligible { n - 1 - sim.k } else { 0 };
    }
    let started = rem.iter().filter(|&&r| r > 0).count();
    if started == 0 {
        return taken;
    }
    let stop_below = started.div_ceil(4);
    let table = &sims[0].sin_half;
    loop {
        let active = rem.iter().filter(|&&r| r > 0).count();
        if active == 0 || active < stop_below {
            break;
        }
        let mut s_mid = [T::zero(); L];
        let mut s_end = [T::zero(); L];
        for i in 0..L {
            // k < N − 1 on active lanes; idle lanes read a valid entry and are discarded.
            let j = 2 * (k[i] as usize).min(n as usize - 2);
            s_mid[i] = table[j + 1];
            s_end[i] = table[j + 2];
        }
        let mut next = States::<T, L>::new();
        let mut ok = [false; L];
        if wires {
            for i in 0..L {
                let (n, o) = trial::<T, true>(&cst[i], &state.get(i), eta, s_mid[i], s_end[i]);
                next.set(i, n);
                ok[i] = o;
            }
        } else {
            for i in 0..L {
                let (n, o) = trial::<T, false>(&cst[i], &state.get(i), eta, s_mid[i], s_end[i]);
                next.set(i, n);
                ok[i] = o;
            }
        }
        // Branch-free, one array at a time (so that it vectorises too).
        let mut go = [0u32; L];
        for i in 0..L {
            go[i] = u32::from((rem[i] > 0) & ok[i]);
        }
        state.select(&go, &next);
        for i in 0..L {
            k[i] += go[i];
            rem[i] = (rem[i] - go[i]) * go[i];
            taken[i] += go[i];
        }
    }
    for (i, sim) in sims.iter_mut().take(lanes).enumerate() {
        if taken[i] == 0 {
            continue;
        }
        let s = state.get(i);
        sim.x = Vector2::new(s.x0, s.x1);
        sim.at_x = FieldEval {
            dx: Vector2::new(s.x1, s.a),
            force: T::zero(),
            region: Region::Free,
            delta: s.d,
            delta_dot: s.dd,
        };
        sim.k = k[i];
        sim.steps += u64::from(taken[i]);
        sim.rk4_steps += u64::from(taken[i]);
    }
    taken
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{SimSettings, simulator_at};
    use crate::model::RigId;

    /// Lockstep steps leave every simulator exactly where as many scalar steps do, and they do
    /// run (from rest, far from the surface, until the period's last step or until fewer than a
    /// quarter of the lanes that started can go on).
    fn check(rig: RigId, gap_m: f64) {
        let p = rig.preset();
        let s = SimSettings::default();
        let ratios = [0.6, 0.9, 1.3, 1.7, 2.0, 2.6, 3.1, 3.9];
        let mut sims: std::vec::Vec<Simulator<f32>> = ratios
            .iter()
            .map(|&r| simulator_at::<f32>(&p, gap_m, r, &s).expect("valid"))
            .collect();
        // Stagger the phases so that the lanes are not all at step 0.
        for (i, sim) in sims.iter_mut().enumerate() {
            for _ in 0..3 * i {
                sim.step(&mut |_| {});
            }
        }
        let reference = sims.clone();
        let mut refs: std::vec::Vec<&mut Simulator<f32>> = sims.iter_mut().collect();
        let taken = free_flight::<f32, 8>(&mut refs);
        assert!(taken.iter().sum::<u32>() >= 4 * 20, "{rig:?}: {taken:?}");
        for ((sim, mut r), &t) in sims.iter().zip(reference).zip(taken.iter()) {
            for _ in 0..t {
                r.step(&mut |_| {});
            }
            assert_eq!(sim.x, r.x, "{rig:?}");
            assert_eq!(sim.at_x, r.at_x, "{rig:?}");
            assert_eq!(
                (sim.k, sim.steps, sim.rk4_steps),
                (r.k, r.steps, r.rk4_steps)
            );
        }
    }

    #[test]
    fn lockstep_steps_equal_scalar_steps() {
        check(RigId::Wires, 3.0e-3);
        check(RigId::Beam170, 3.0e-3);
    }
}

//! Whole free-flight steps of several simulators in lockstep (the host's grid analyses).
//!
//! Far from the surface, the next step of a [`Simulator`] is one RK4 step of `h = T/N` in free
//! flight (the first branch of [`Simulator::step`]): the same short chain of `+` and `×` for
//! every simulator of a grid. [`free_flight`] evaluates it for `L` simulators at once, so the
//! compiler packs the lanes into SIMD registers, and skips the per-step bookkeeping in between.
//! Each lane runs the stepper's own kernel (`integrate::free`) and stops before the
//! period's last step (the Poincaré section), before any step that the stepper would split
//! near the surface, and (wires) before an angle outside the short sine polynomial's range
//! `|θ| ≤ 1/8`. The caller then takes the next step with [`Simulator::step`] as usual.

use super::Simulator;
use super::free::{Beam, FreeState, SmallTrig, Suspension, Wires, free_step};
use crate::model::hammer::FreeFlight;
use crate::real::Real;

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
    fn get(&self, i: usize) -> FreeState<T> {
        FreeState {
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
    fn set(&mut self, i: usize, s: FreeState<T>) {
        self.x0[i] = s.x0;
        self.x1[i] = s.x1;
        self.a[i] = s.a;
        self.d[i] = s.d;
        self.dd[i] = s.dd;
    }
}

/// One trial step of every lane (`cst`: its free-flight coefficients and `h`; `s_mid`,
/// `s_end`: `sin Ωt` at the step's midpoint and end): the states after it, and whether the
/// stepper would take it in one piece (into `next`, `ok`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn trials<T: Real, S: Suspension, const L: usize>(
    kind: S,
    cst: &[(FreeFlight<T>, T); L],
    state: &States<T, L>,
    s_mid: &[T; L],
    s_end: &[T; L],
    eta: T,
    next: &mut States<T, L>,
    ok: &mut [bool; L],
) {
    for i in 0..L {
        let (c, h) = &cst[i];
        let (nx, exact, near) =
            free_step::<T, S, SmallTrig>(kind, c, &state.get(i), *h, s_mid[i], s_end[i], eta);
        next.set(i, nx);
        ok[i] = exact & !near;
    }
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
pub fn free_flight<T: Real, const L: usize>(sims: &mut [&mut Simulator<'_, T>]) -> [u32; L] {
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
fn free_flight_avx<T: Real, const L: usize>(sims: &mut [&mut Simulator<'_, T>]) -> [u32; L] {
    free_flight_kernel::<T, L>(sims)
}

/// The body of [`free_flight`] (inlined into each instruction-set variant).
#[inline(always)]
fn free_flight_kernel<T: Real, const L: usize>(sims: &mut [&mut Simulator<'_, T>]) -> [u32; L] {
    let mut taken = [0u32; L];
    let lanes = sims.len().min(L);
    if lanes == 0 {
        return taken;
    }
    let (table, wires, eta) = sims[0].lane_kind();
    let n = table.steps_per_period();
    let mut cst = [(FreeFlight::default(), T::zero()); L];
    let mut state = States::<T, L>::new();
    let mut k = [0u32; L];
    let mut rem = [0u32; L];
    for i in 0..lanes {
        let sim = &*sims[i];
        if !sims[0].lane_compatible(sim) {
            continue;
        }
        if let Some((st, r)) = sim.lane_start() {
            cst[i] = sim.lane_constants();
            state.set(i, st);
            k[i] = n - 1 - r;
            rem[i] = r;
        }
    }
    let started = rem.iter().filter(|&&r| r > 0).count();
    if started == 0 {
        return taken;
    }
    let stop_below = started.div_ceil(4);
    loop {
        let active = rem.iter().filter(|&&r| r > 0).count();
        if active == 0 || active < stop_below {
            break;
        }
        let mut s_mid = [T::zero(); L];
        let mut s_end = [T::zero(); L];
        for i in 0..L {
            // k < N − 1 on active lanes (so the step's end is not the period's); idle lanes
            // read a valid entry and are discarded.
            let j = 2 * (k[i] as usize).min(n as usize - 2);
            s_mid[i] = table.sin_half(j + 1);
            s_end[i] = table.sin_half(j + 2);
        }
        let mut next = States::<T, L>::new();
        let mut ok = [false; L];
        if wires {
            trials(Wires, &cst, &state, &s_mid, &s_end, eta, &mut next, &mut ok);
        } else {
            trials(Beam, &cst, &state, &s_mid, &s_end, eta, &mut next, &mut ok);
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
        if taken[i] > 0 {
            sim.lane_finish(&state.get(i), taken[i]);
        }
    }
    taken
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{SimSettings, simulator_at};
    use crate::integrate::PhaseTable;
    use crate::model::RigId;
    use std::format;

    /// Lockstep steps leave every simulator exactly where as many scalar steps do, and they do
    /// run (from rest, far from the surface, until the period's last step or until fewer than a
    /// quarter of the lanes that started can go on).
    fn check(rig: RigId, gap_m: f64) {
        let p = rig.preset();
        let s = SimSettings::default();
        let ratios = [0.6, 0.9, 1.3, 1.7, 2.0, 2.6, 3.1, 3.9];
        let phases = PhaseTable::new(s.steps.steps_per_period).expect("valid N");
        let mut sims: std::vec::Vec<Simulator<f32>> = ratios
            .iter()
            .map(|&r| simulator_at::<f32>(&p, gap_m, r, &s, &phases).expect("valid"))
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
            assert_eq!(sim.state(), r.state(), "{rig:?}");
            assert_eq!(sim.state_penetration(), r.state_penetration(), "{rig:?}");
            assert_eq!(
                (sim.periods_done(), sim.rk4_steps()),
                (r.periods_done(), r.rk4_steps())
            );
            assert_eq!(format!("{sim:?}"), format!("{r:?}"), "{rig:?}");
        }
    }

    #[test]
    fn lockstep_steps_equal_scalar_steps() {
        check(RigId::Wires, 3.0e-3);
        check(RigId::Beam170, 3.0e-3);
    }
}

//! Whole free-flight steps of several simulators in lockstep (the host's grid analyses).
//!
//! Far from the surface, the next step of a [`Simulator`] is one RK4 step of `h = T/N` in free
//! flight (the first branch of [`Simulator::step`]): the same short chain of `+` and `×` for
//! every simulator of a grid. `Lockstep` holds the free-flight states of up to `L` simulators,
//! one array per field, and steps them together, so the compiler packs the lanes into SIMD
//! registers, without the per-step bookkeeping in between. Each lane runs the stepper's own
//! kernel (`integrate::free`) and stops after the period's last step (the Poincaré section,
//! which the caller takes), before any step that the stepper would split near the surface, and
//! (wires) before an angle outside the short sine polynomial's range `|θ| ≤ 1/8`.
//! `Lockstep::run` returns as soon as one lane stops; the caller takes that simulator's next
//! steps with [`Simulator::step`] and loads it (or another simulator) into the lane again, so
//! the other lanes never wait. A lane that stopped before a step that came near the surface
//! hands that step on (`Lockstep::take_trial`), so that the caller's first free-flight trial
//! is not computed twice.

use super::Simulator;
use super::free::{FreeState, SmallTrig, free_step_parts, peak_near};
use super::isa::{Isa, Kernel, Variant};
use super::lane_field::{COEFS, LaneField};
use super::plan::PhaseTable;
use crate::model::hammer::{BeamFree, Damped, Undamped, Viscous, WiresFree};
use crate::real::Real;
use core::marker::PhantomData;

/// The states of `L` lanes, one array per field (so that the lanes pack into SIMD registers).
#[derive(Clone, Copy)]
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

/// Up to `L` simulators' whole free-flight steps in lockstep, for one suspension (`F`:
/// [`WiresFree`] or [`BeamFree`]), one step grid `N` and one band `η_δ`.
///
/// A simulator is loaded into a lane ([`Lockstep::load`]) when it is clear of the surface;
/// [`Lockstep::run`] steps every loaded lane until one of them stops (at the latest at its
/// period's end); [`Lockstep::unload`] hands its steps back to the simulator, which ends
/// exactly where the same number of [`Simulator::step`] calls would have left it.
///
/// With the `std` feature on x86-64 (the host), the kernel runs as AVX-512 or AVX2 code when
/// the CPU has it (chosen at run time, [`Isa`]: 16 or 8 `f32` lanes per register instead of
/// 4): the same operations in the same order, no fused multiply-add, so the same bits.
pub(crate) struct Lockstep<'t, T: Real, F, const L: usize> {
    phases: &'t PhaseTable<T>,
    eta: T,
    wires: bool,
    /// The damped pendulum: the lanes run the [`Damped`] kernel (else [`Undamped`]).
    damped: bool,
    /// Each lane's coefficients ([`LaneField::to_coefs`]), one array per coefficient.
    coef: [[T; L]; COEFS],
    suspension: PhantomData<F>,
    h: [T; L],
    state: States<T, L>,
    /// Step index within the period of each lane.
    k: [u32; L],
    /// Steps a lane may still take to its period's end (0: the lane is empty or stopped).
    rem: [u32; L],
    /// Steps taken since the lane was loaded.
    taken: [u32; L],
    /// The lanes that stopped in the last call before a step that came near the surface
    /// (bit `i`: lane `i`; exact, so the stepper's trial of that step would be the same), and
    /// that step's end in each (`Lockstep::take_trial`).
    trials: u32,
    trial_end: States<T, L>,
    /// Lockstep rounds run, and lane-steps taken in them (`Lockstep::stats`).
    rounds: u64,
    lane_steps: u64,
    /// The instruction set the kernel runs.
    isa: Isa,
}

/// [`Lockstep::run_at_most`]'s body as a [`Kernel`]: up to `rounds` rounds of the lanes, the
/// pendulum's viscous term as `V` has it.
struct FreeRounds<'a, 't, T: Real, F: LaneField<T>, const L: usize, V> {
    lanes: &'a mut Lockstep<'t, T, F, L>,
    rounds: u64,
    viscous: PhantomData<V>,
}

impl<T: Real, F: LaneField<T>, const L: usize, V: Viscous> Kernel
    for FreeRounds<'_, '_, T, F, L, V>
{
    type Output = u32;
    #[inline(always)]
    fn run<I: Variant>(self) -> u32 {
        self.lanes.run_kernel::<V, I>(self.rounds)
    }
}

impl<'t, T: Real, F: LaneField<T>, const L: usize> Lockstep<'t, T, F, L> {
    /// Empty lanes for the simulators that share `sim`'s step grid, suspension and band.
    pub(crate) fn for_simulator(sim: &Simulator<'t, T>) -> Self {
        let (phases, wires, eta, damped) = sim.lane_kind();
        Lockstep {
            phases,
            eta,
            wires,
            damped,
            coef: [[T::zero(); L]; COEFS],
            suspension: PhantomData,
            h: [T::zero(); L],
            state: States::new(),
            k: [0; L],
            rem: [0; L],
            taken: [0; L],
            trials: 0,
            trial_end: States::new(),
            rounds: 0,
            lane_steps: 0,
            isa: Isa::detect(),
        }
    }

    /// Loads `sim` into lane `i` (`i < L`, the lane empty) if it can take whole free-flight
    /// steps in lockstep now: the same `N`, suspension (the pendulum damped or not) and `η_δ`
    /// as the others, and clear of the surface. Returns whether it did.
    #[inline]
    pub(crate) fn load(&mut self, i: usize, sim: &Simulator<'t, T>) -> bool {
        if !self.same_kind(sim) {
            return false;
        }
        let Some((st, r)) = sim.lane_start() else {
            return false;
        };
        let (ff, h) = sim.lane_constants();
        let Some(c) = F::of(&ff) else {
            return false;
        };
        for (lanes, v) in self.coef.iter_mut().zip(c.to_coefs()) {
            lanes[i] = v;
        }
        self.h[i] = h;
        self.state.set(i, st);
        self.k[i] = self.n() - r;
        self.rem[i] = r;
        self.taken[i] = 0;
        true
    }

    /// Whether [`Lockstep::load`] would load `sim` now.
    #[inline]
    pub(crate) fn accepts(&self, sim: &Simulator<'t, T>) -> bool {
        self.same_kind(sim)
            && sim.lane_start().is_some()
            && F::of(&sim.lane_constants().0).is_some()
    }

    /// The same `N`, suspension (the pendulum damped or not) and `η_δ` as the lanes.
    #[inline]
    fn same_kind(&self, sim: &Simulator<'t, T>) -> bool {
        let (phases, wires, eta, damped) = sim.lane_kind();
        phases.steps_per_period() == self.n()
            && wires == self.wires
            && eta == self.eta
            && damped == self.damped
    }

    /// Ends lane `i`: the steps it took since [`Lockstep::load`] go to `sim` (the simulator
    /// loaded there). Returns how many (0: `sim` is unchanged).
    #[inline]
    pub(crate) fn unload(&mut self, i: usize, sim: &mut Simulator<'t, T>) -> u32 {
        let taken = self.taken[i];
        if taken > 0 {
            sim.lane_finish(&self.state.get(i), taken);
        }
        self.rem[i] = 0;
        self.taken[i] = 0;
        taken
    }

    /// The end of the step before which lane `i` stopped in the last call, if it stopped because
    /// that step came near the surface (every field evaluation exact): the step the stepper's
    /// next free-flight trial would take, bit for bit ([`Simulator::lane_trial`]). Once.
    #[inline]
    pub(crate) fn take_trial(&mut self, i: usize) -> Option<FreeState<T>> {
        let bit = 1u32 << i;
        if self.trials & bit == 0 {
            return None;
        }
        self.trials &= !bit;
        Some(self.trial_end.get(i))
    }

    /// Whether any lane is loaded and running.
    #[inline]
    pub(crate) fn any_running(&self) -> bool {
        self.rem.iter().any(|&r| r > 0)
    }

    /// Lockstep rounds run so far and the lane-steps taken in them (a round offers `L`).
    pub(crate) fn stats(&self) -> (u64, u64) {
        (self.rounds, self.lane_steps)
    }

    fn n(&self) -> u32 {
        self.phases.steps_per_period()
    }

    /// Steps every running lane in lockstep until at least one of them stops (after its
    /// period's last step, or before a step that the stepper would split or that `|θ| > 1/8`
    /// makes inexact). Returns the stopped lanes as a bit mask (bit `i`: lane `i`), which must
    /// be [`Lockstep::unload`]ed before they are loaded again. Nothing happens if no lane runs.
    pub(crate) fn run(&mut self) -> u32 {
        self.run_at_most(u64::MAX)
    }

    /// [`Lockstep::run`] for at most `rounds` rounds.
    pub(crate) fn run_at_most(&mut self, rounds: u64) -> u32 {
        if self.damped {
            self.run_viscous::<Damped>(rounds)
        } else {
            self.run_viscous::<Undamped>(rounds)
        }
    }

    /// [`Lockstep::run_at_most`] with the pendulum's viscous term as `V` has it, in the
    /// instruction set of [`Isa::detect`].
    #[inline(always)]
    fn run_viscous<V: Viscous>(&mut self, rounds: u64) -> u32 {
        let isa = self.isa;
        isa.run(FreeRounds {
            lanes: self,
            rounds,
            viscous: PhantomData::<V>,
        })
    }

    /// The body of [`Lockstep::run`] (inlined into each instruction-set variant).
    #[inline(always)]
    fn run_kernel<V: Viscous, I: Variant>(&mut self, max_rounds: u64) -> u32 {
        const { assert!(L <= 32) };
        let mut stopped = 0u32;
        self.trials = 0;
        if !self.any_running() {
            return stopped;
        }
        let n = self.n();
        let table = self.phases;
        let eta = self.eta;
        let coef = self.coef;
        let mut state = self.state;
        let mut k = self.k;
        let mut rem = self.rem;
        let mut taken = self.taken;
        let taken_before = taken;
        let mut rounds = 0u64;
        loop {
            // k < N on running lanes (the end of the period's last step is the next period's
            // start, `PhaseTable::step_mid_end`); the others read a valid entry and are
            // discarded. One gather per array where the variant has it, else lane by lane.
            let mut s_mid = [T::zero(); L];
            let mut s_end = [T::zero(); L];
            if let Some((mid, end)) = gathered::<T, L, I>(table, &k) {
                s_mid = mid;
                s_end = end;
            } else {
                for i in 0..L {
                    let j = 2 * k[i].min(n - 1) as usize;
                    s_mid[i] = table.sin_half(j + 1);
                    s_end[i] = table.sin_half(j + 2);
                }
            }
            let mut next = States::<T, L>::new();
            let mut ok = [0u32; L];
            let mut exact = [false; L];
            let step = |i: usize| {
                free_step_parts::<T, F, SmallTrig, V>(
                    &F::from_coefs(core::array::from_fn(|f| coef[f][i])),
                    &state.get(i),
                    self.h[i],
                    s_mid[i],
                    s_end[i],
                    eta,
                )
            };
            if !I::SPLIT_PEAK_TEST {
                // `free_step`, the peak test in every round (lane `i` of several arrays).
                #[allow(clippy::needless_range_loop)]
                for i in 0..L {
                    let (nx, ex, near, turned) = step(i);
                    let near = near | (turned & peak_near(&state.get(i), &nx, self.h[i], -eta));
                    next.set(i, nx);
                    exact[i] = ex;
                    ok[i] = u32::from(ex & !near);
                }
            } else {
                let mut near = [false; L];
                let mut turned = [false; L];
                for i in 0..L {
                    let nx;
                    (nx, exact[i], near[i], turned[i]) = step(i);
                    next.set(i, nx);
                }
                // The peak test (a division) only in the rounds where a lane turned round.
                if turned.iter().any(|&t| t) {
                    for i in 0..L {
                        near[i] |=
                            turned[i] & peak_near(&state.get(i), &next.get(i), self.h[i], -eta);
                    }
                }
                for i in 0..L {
                    ok[i] = u32::from(exact[i] & !near[i]);
                }
            }
            // Branch-free, one array at a time (so that it vectorises too): a running lane
            // takes the step if it may, and stops if it may not or if that step ended its
            // period (the Poincaré section, which the caller takes).
            let mut go = [0u32; L];
            let mut stop = [0u32; L];
            for i in 0..L {
                let running = u32::from(rem[i] > 0);
                go[i] = running & ok[i];
                stop[i] = running & ((ok[i] ^ 1) | u32::from(rem[i] == 1));
            }
            state.select(&go, &next);
            let mut any_stop = 0u32;
            for i in 0..L {
                // A lane whose step ended its period has stopped; its `k` of `N` is read
                // clamped until it is loaded again (and the simulator wraps its own).
                k[i] += go[i];
                taken[i] += go[i];
                rem[i] = (rem[i] - go[i]) * (stop[i] ^ 1);
                any_stop |= stop[i];
            }
            rounds += 1;
            if any_stop != 0 {
                // A lane that stopped without its step, though exact there, stopped because the
                // step came near the surface: its end goes to the caller.
                let mut trials = 0u32;
                for i in 0..L {
                    stopped |= stop[i] << i;
                    trials |= (stop[i] & (go[i] ^ 1) & u32::from(exact[i])) << i;
                }
                if trials != 0 {
                    self.trials = trials;
                    self.trial_end = next;
                }
                break;
            }
            if rounds >= max_rounds {
                break;
            }
        }
        let lane_steps: u64 = (0..L).map(|i| u64::from(taken[i] - taken_before[i])).sum();
        self.state = state;
        self.k = k;
        self.rem = rem;
        self.taken = taken;
        self.rounds += rounds;
        self.lane_steps += lane_steps;
        stopped
    }
}

/// [`PhaseTable::step_mid_end_gathered`] where the variant `I` gathers (AVX-512), else `None`
/// without a trace in the variant's code.
#[inline(always)]
fn gathered<T: Real, const L: usize, I: Variant>(
    table: &PhaseTable<T>,
    k: &[u32; L],
) -> Option<([T; L], [T; L])> {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    if I::ISA == Isa::Avx512 {
        return table.step_mid_end_gathered(I::ISA, k);
    }
    // No gather in the MCU's code.
    #[cfg(not(all(feature = "std", target_arch = "x86_64")))]
    let _ = (table, k, I::ISA);
    None
}

/// Takes whole free-flight steps on the simulators of `sims` (at most `L` of them; further ones
/// are left alone) in lockstep until the first of them stops (`Lockstep`). A simulator takes
/// part if it has the first one's `N`, suspension and band `η_δ`, and is clear of the surface
/// (it stops at its period's end at the latest). Returns the steps each took (0 for those that
/// did not take part); each simulator ends exactly where the same number of
/// [`Simulator::step`] calls would have left it. (The grid analyses keep their lanes loaded
/// across stops: `crate::analysis::batch`; this one-shot form serves benchmarks and tests.)
pub fn free_flight<T: Real, const L: usize>(sims: &mut [&mut Simulator<'_, T>]) -> [u32; L] {
    fn go<'t, T: Real, F: LaneField<T>, const L: usize>(
        sims: &mut [&mut Simulator<'t, T>],
    ) -> [u32; L] {
        let mut taken = [0u32; L];
        let Some(first) = sims.first() else {
            return taken;
        };
        let mut lanes = Lockstep::<T, F, L>::for_simulator(first);
        for (i, sim) in sims.iter().take(L).enumerate() {
            lanes.load(i, sim);
        }
        lanes.run();
        for (i, sim) in sims.iter_mut().take(L).enumerate() {
            taken[i] = lanes.unload(i, sim);
        }
        taken
    }
    match sims.first().map(|s| s.hammer().is_wires()) {
        Some(true) => go::<T, WiresFree<T>, L>(sims),
        Some(false) => go::<T, BeamFree<T>, L>(sims),
        None => [0; L],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{SimSettings, simulator_at};
    use crate::integrate::PhaseTable;
    use crate::integrate::isa::with_isa;
    use crate::model::RigId;
    use std::format;

    /// Lockstep steps leave every simulator exactly where as many scalar steps do, and they do
    /// run (from rest, far from the surface, until a lane reaches its period's last step). In
    /// `L` lanes: 16 reads the phase table with AVX-512's gather where the CPU has it.
    fn check<F: LaneField<f32>, const L: usize>(rig: RigId, zeta: f64, gap_m: f64) {
        let p = rig.preset().with_damping_ratio(zeta);
        let s = SimSettings::default();
        let ratios = &[
            0.6, 0.9, 1.3, 1.7, 2.0, 2.6, 3.1, 3.9, 0.65, 0.95, 1.35, 1.75, 2.05, 2.65, 3.15, 3.85,
        ][..L];
        let phases = PhaseTable::new(s.steps.steps_per_period).expect("valid N");
        let mut sims: std::vec::Vec<Simulator<f32>> = ratios
            .iter()
            .map(|&r| simulator_at::<f32>(&p, gap_m, r, &s, &phases).expect("valid"))
            .collect();
        // Stagger the phases so that the lanes are not all at step 0 (lanes 8–15 as 0–7).
        for (i, sim) in sims.iter_mut().enumerate() {
            for _ in 0..3 * (i % 8) {
                sim.step(&mut |_| {});
            }
        }
        let reference = sims.clone();
        let mut lanes = Lockstep::<f32, F, L>::for_simulator(&sims[0]);
        assert_eq!(lanes.isa, Isa::detect());
        assert_eq!(lanes.damped, rig == RigId::Wires && zeta > 0.0);
        for (i, sim) in sims.iter().enumerate() {
            assert!(lanes.load(i, sim), "{rig:?}: lane {i}");
        }
        let stopped = lanes.run();
        assert!(stopped != 0 && u64::from(stopped) < 1 << L);
        let taken: std::vec::Vec<u32> = sims
            .iter_mut()
            .enumerate()
            .map(|(i, sim)| lanes.unload(i, sim))
            .collect();
        // Every lane ran until the first stopped: at the latest the last lane (21 steps in),
        // 64 − 21 = 43 steps later (its period's last step included); a lane that stopped
        // before a step did not take it.
        let (rounds, lane_steps) = lanes.stats();
        assert!((10..=43).contains(&rounds), "{rig:?}: {rounds} rounds");
        assert!(
            taken
                .iter()
                .all(|&t| t == rounds as u32 || t + 1 == rounds as u32)
        );
        assert_eq!(lane_steps, taken.iter().map(|&t| u64::from(t)).sum::<u64>());
        for ((sim, mut r), &t) in sims.iter().zip(reference).zip(taken.iter()) {
            let reference_trials = r.counts().free_trials;
            for _ in 0..t {
                r.step(&mut |_| {});
            }
            assert_eq!(sim.state(), r.state(), "{rig:?}");
            assert_eq!(sim.state_penetration(), r.state_penetration(), "{rig:?}");
            assert_eq!(
                (sim.periods_done(), sim.rk4_steps()),
                (r.periods_done(), r.rk4_steps())
            );
            assert_eq!(sim.counts().lane_steps, u64::from(t));
            assert_eq!(r.counts().free_trials, reference_trials + u64::from(t));
            let same = sim.with_counts_of(&r);
            assert_eq!(format!("{same:?}"), format!("{r:?}"), "{rig:?}");
        }
    }

    #[test]
    fn lanes_refuse_a_pendulum_of_the_other_damping() {
        // One kernel per lane set: damped and undamped pendulums never share lanes.
        let s = SimSettings::default();
        let phases = PhaseTable::new(s.steps.steps_per_period).expect("valid N");
        let at = |zeta: f64| {
            let p = RigId::Wires.preset().with_damping_ratio(zeta);
            simulator_at::<f32>(&p, 3.0e-3, 1.3, &s, &phases).expect("valid")
        };
        let (undamped, damped) = (at(0.0), at(0.003));
        let mut lanes = Lockstep::<f32, WiresFree<f32>, 8>::for_simulator(&undamped);
        assert!(lanes.load(0, &undamped));
        assert!(!lanes.load(1, &damped));
        let mut lanes = Lockstep::<f32, WiresFree<f32>, 8>::for_simulator(&damped);
        assert!(lanes.load(0, &damped));
        assert!(!lanes.load(1, &undamped));
    }

    #[test]
    fn lockstep_steps_equal_scalar_steps() {
        for isa in Isa::supported() {
            with_isa(isa, || {
                check::<WiresFree<f32>, 8>(RigId::Wires, 0.0, 3.0e-3);
                check::<WiresFree<f32>, 16>(RigId::Wires, 0.0, 3.0e-3);
                // The damped pendulum: the lanes run the `Damped` kernel, the stepper `AsSet`.
                check::<WiresFree<f32>, 8>(RigId::Wires, 0.003, 3.0e-3);
                check::<WiresFree<f32>, 16>(RigId::Wires, 0.003, 3.0e-3);
                check::<BeamFree<f32>, 8>(RigId::Beam170, 0.004, 3.0e-3);
                check::<BeamFree<f32>, 16>(RigId::Beam170, 0.004, 3.0e-3);
            });
        }
    }
}

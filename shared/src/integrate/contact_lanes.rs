//! Ordinary contact sub-steps of several simulators at once (the host's grid analyses).
//!
//! Near and in contact a [`Simulator`] advances by sub-steps ([`Simulator::step`]): one RK4
//! step with the field of the mode it starts in (free flight `f−` or contact `f+`), then the
//! switch-model field at its end; only if that end is in the other mode is a switching event
//! located. [`ContactLanes`] computes the first part for up to `L` simulators together, the
//! same operations in the same order as the stepper (so the compiler packs the lanes into SIMD
//! registers and the bits are the stepper's), for the linear (spring–dashpot) law; each
//! simulator then ends its sub-step with [`Simulator::commit_substep`], which takes a
//! switching event (or an angle outside the short sine's range `|θ| ≤ 1/8`) itself.
//!
//! Most sub-steps are followed at once by another ordinary one. A lane ends such a sub-step
//! itself and sets up the next, with the same operations as the simulator and its run would
//! (the commit, the sample's smallest `δ`, the run's bookkeeping of the sample through
//! [`QuietSample`], the next sub-step's length through [`SubstepRule`]), as long as nothing
//! else has to happen: the sub-step stays in its mode, does not end the step, its sample
//! causes no impact event and no slope turn between samples, and the next one is again an
//! ordinary sub-step. Otherwise the lane stops with its trial ([`RunLanes::continues`]
//! false), and the simulator takes back what the lane did ([`ContactLanes::resume`]) before it
//! commits the trial itself.

use core::marker::PhantomData;
use nalgebra::Vector2;

use super::Simulator;
use super::free::SmallTrig;
use super::isa::{Isa, Kernel, Variant};
use super::lane_field::LaneContact;
use super::plan::SubstepRule;
use super::rk4::rk4_step_compensated;
use super::stepper::{Handback, LaneResume, LaneTrial, SubPlan, min_approach};
use crate::model::Region;
use crate::model::contact::LawCoeffs;
use crate::model::hammer::{Damped, FieldEval, Undamped, Viscous};
use crate::real::Real;

/// A run's bookkeeping of its samples (the impact tracker and the period's largest contact
/// force, `crate::observe::ProtocolRun::sample`) as a contact lane carries it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SampleBook<T> {
    /// Separation that ends an impact episode, m.
    pub(crate) separation: T,
    /// Penetration of the previous sample, m.
    pub(crate) prev_delta: T,
    /// Whether an impact episode is open.
    pub(crate) in_episode: bool,
    /// Its peak force so far, N.
    pub(crate) peak: T,
    /// Largest contact force of the period so far, N.
    pub(crate) period_force: T,
}

/// How a run books a sample that a contact lane takes for it (implemented by the protocol's
/// run, `crate::observe::ProtocolRun`).
pub(crate) trait QuietSample<T: Real> {
    /// The book after the sample `(δ, δ_min, F_i)` (m, m, N: penetration, smallest penetration
    /// since the previous sample, contact force), and whether the sample is quiet: it changes
    /// nothing but the book (no event for the run or its observer). A lane takes only quiet
    /// samples.
    fn take(book: &SampleBook<T>, delta: T, delta_min: T, force: T) -> (SampleBook<T>, bool);
}

/// What a lane's trial is ([`LaneTrial`]): inexact, ending in its start's mode, or in the other.
const STAYS: u32 = 1;
const SWITCHES: u32 = 2;

/// Switch-model regions as lane codes.
const FREE: u32 = 0;
const CONTACT: u32 = 1;
const BAND_ALPHA: u32 = 2;
const BAND_BETA: u32 = 3;

/// What each contact lane carries of its run to end its sub-steps itself
/// ([`ContactLanes::run`]); kept apart from the [`ContactLanes`] (in one struct with them, the
/// compiler no longer vectorised the sub-step's kernel: measured).
pub(crate) struct RunLanes<T, const L: usize> {
    // The sub-step length rule ([`SubstepRule`]).
    h_c: [T; L],
    h_rest: [T; L],
    receding_max: [T; L],
    eps_omega_c: [T; L],
    // The rest of the switch-model field at the start: force, region, `δ`, `δ̇`; the approach
    // speed; the time to the step's end.
    force0: [T; L],
    region0: [u32; L],
    d0: [T; L],
    dd0: [T; L],
    approach: [T; L],
    rest: [T; L],
    // The run's book of its samples ([`SampleBook`]).
    separation: [T; L],
    prev_delta: [T; L],
    in_episode: [u32; L],
    peak: [T; L],
    period_force: [T; L],
    // The sub-steps the lane ended itself since it was set.
    taken: [u32; L],
    // 1 if the lane ended its last sub-step itself and holds its next (`u32` masks, as the
    // other flags: the loop vectorises).
    cont: [u32; L],
    start: Start<T, L>,
}

impl<T: Real, const L: usize> RunLanes<T, L> {
    /// Empty lanes.
    pub(crate) fn new() -> Self {
        let z = [T::zero(); L];
        RunLanes {
            h_c: z,
            h_rest: z,
            receding_max: z,
            eps_omega_c: z,
            force0: z,
            region0: [FREE; L],
            d0: z,
            dd0: z,
            approach: z,
            rest: z,
            separation: z,
            prev_delta: z,
            in_episode: [0; L],
            peak: z,
            period_force: z,
            taken: [0; L],
            cont: [0; L],
            start: Start {
                x0: z,
                x1: z,
                carry0: z,
                carry1: z,
                a: z,
                offset: z,
                len: z,
                last: [0; L],
                band: [0; L],
                s_start: z,
                touching: [0; L],
                approach: z,
                force0: z,
                region0: [FREE; L],
                d0: z,
                dd0: z,
                rest: z,
                prev_delta: z,
                peak: z,
                period_force: z,
            },
        }
    }

    /// The book of lane `i`'s run.
    #[inline(always)]
    fn book(&self, i: usize) -> SampleBook<T> {
        SampleBook {
            separation: self.separation[i],
            prev_delta: self.prev_delta[i],
            in_episode: self.in_episode[i] != 0,
            peak: self.peak[i],
            period_force: self.period_force[i],
        }
    }

    /// Whether lane `i` ended its sub-step itself after [`ContactLanes::run`] and holds its
    /// next one (else its [`ContactLanes::result`] is for [`Simulator::commit_substep`], after
    /// [`ContactLanes::resume`]).
    #[inline(always)]
    pub(crate) fn continues(&self, i: usize) -> bool {
        self.cont[i] != 0
    }

    /// The sub-step length rule of lane `i`.
    #[inline(always)]
    fn rule(&self, i: usize) -> SubstepRule<T> {
        SubstepRule {
            h_c: self.h_c[i],
            h_rest: self.h_rest[i],
            receding_max: self.receding_max[i],
            eps_omega_c: self.eps_omega_c[i],
        }
    }
}

/// The start of each lane's last sub-step, kept by [`ContactLanes::run`] for
/// [`ContactLanes::resume`] (the lanes' arrays hold the next sub-step by then).
#[derive(Clone, Copy)]
struct Start<T, const L: usize> {
    x0: [T; L],
    x1: [T; L],
    carry0: [T; L],
    carry1: [T; L],
    a: [T; L],
    offset: [T; L],
    len: [T; L],
    last: [u32; L],
    band: [u32; L],
    s_start: [T; L],
    touching: [u32; L],
    approach: [T; L],
    force0: [T; L],
    region0: [u32; L],
    d0: [T; L],
    dd0: [T; L],
    rest: [T; L],
    prev_delta: [T; L],
    peak: [T; L],
    period_force: [T; L],
}

/// Up to `L` simulators' ordinary sub-steps at once, for one suspension (`F`) and the linear
/// contact law: [`ContactLanes::set`] a simulator's next sub-step into a lane,
/// [`ContactLanes::run`] all of them, [`ContactLanes::result`] each lane's trial for
/// [`Simulator::commit_substep`]. One array per quantity, so that the lanes pack into SIMD
/// registers.
pub(crate) struct ContactLanes<T: Real, F, const L: usize> {
    // Constants: the suspension's free-flight coefficients, the contact term's `1/m` (wires
    // `1/(m l)`), the law's `k`, `c`, the bands `η_δ`, `η_F`.
    field: [F; L],
    /// Whether the lanes hold the damped pendulum (the [`Damped`] kernel), once a lane's
    /// constants have been set; a simulator of the other kind is refused.
    damped: Option<bool>,
    inv_mass: [T; L],
    k: [T; L],
    c: [T; L],
    eta_d: [T; L],
    eta_f: [T; L],
    // The sub-step: start state, carry, the field's second component there (RK4's first
    // stage), length, `sin Ωt` at its midpoint and end, 1 if it starts touching.
    x0: [T; L],
    x1: [T; L],
    carry0: [T; L],
    carry1: [T; L],
    a: [T; L],
    len: [T; L],
    s_start: [T; L],
    // `sin Ωt` at the sub-step's midpoint and end from `Ω`, the step's start phase
    // (`sin`, `cos`) and the sub-step's offset into the step (s), or the step's end phase if
    // `last`.
    omega: [T; L],
    sin0: [T; L],
    cos0: [T; L],
    offset: [T; L],
    step_end: [T; L],
    last: [u32; L],
    // Out: `sin Ωt` at the sub-step's end.
    s_end: [T; L],
    band: [u32; L],
    touching: [u32; L],
    // What the trial is (`STAYS`, `SWITCHES`, or 0: a sine outside the short range); its end
    // state, carry and switch-model field are where the next sub-step starts (`x0`, … and
    // the `RunLanes`' start field).
    ok: [u32; L],
    /// The instruction set the kernel runs.
    isa: Isa,
}

/// [`ContactLanes::run`]'s body as a [`Kernel`]: one sub-step of every lane, the pendulum's
/// viscous term as `V` has it, the samples booked by `B`.
struct ContactRound<'a, T: Real, F, const L: usize, V, B> {
    lanes: &'a mut ContactLanes<T, F, L>,
    runs: &'a mut RunLanes<T, L>,
    kinds: PhantomData<(V, B)>,
}

impl<T: Real, F: LaneContact<T>, const L: usize, V: Viscous, B: QuietSample<T>> Kernel
    for ContactRound<'_, T, F, L, V, B>
{
    type Output = ();
    #[inline(always)]
    fn run<I: Variant>(self) {
        self.lanes.run_kernel::<V, B>(self.runs);
    }
}

impl<T: Real, F: LaneContact<T>, const L: usize> ContactLanes<T, F, L> {
    /// Empty lanes.
    pub(crate) fn new() -> Self {
        let z = [T::zero(); L];
        ContactLanes {
            field: [F::default(); L],
            damped: None,
            inv_mass: z,
            k: z,
            c: z,
            eta_d: z,
            eta_f: z,
            x0: z,
            x1: z,
            carry0: z,
            carry1: z,
            a: z,
            len: z,
            s_start: z,
            omega: z,
            sin0: z,
            cos0: z,
            offset: z,
            step_end: z,
            last: [0; L],
            s_end: z,
            band: [0; L],
            touching: [0; L],
            ok: [0; L],
            isa: Isa::detect(),
        }
    }

    /// Empty lanes for simulators of `sim`'s kind (the pendulum damped or not).
    pub(crate) fn for_simulator(sim: &Simulator<'_, T>) -> Self {
        let mut lanes = Self::new();
        lanes.damped = Some(sim.hammer().is_damped_wires());
        lanes
    }

    /// Whether the lanes take `sim`'s sub-steps: of this suspension and the linear law, and
    /// (the pendulum) damped as the lanes' first simulator or not (what
    /// [`ContactLanes::set`] with its constants checks).
    pub(crate) fn accepts(&self, sim: &Simulator<'_, T>) -> bool {
        let hammer = sim.hammer();
        F::of(&hammer.free_flight()).is_some()
            && F::inv_mass(hammer.body()).is_some()
            && matches!(hammer.switch().law, LawCoeffs::Linear { .. })
            && self.damped.is_none_or(|d| d == hammer.is_damped_wires())
    }

    /// Puts `sim`'s next sub-step `p` ([`Simulator::plain_substep`]) into lane `i`, with its
    /// run's `book` and `sim`'s constants if `constants` (else the lane keeps those of its last
    /// [`set`], which must be `sim`'s). Returns `false` (nothing set) if `sim` is not of this
    /// suspension, not of the linear law, or (the pendulum) damped where the lanes' first simulator was not or
    /// the other way round.
    ///
    /// [`set`]: ContactLanes::set
    #[inline]
    pub(crate) fn set(
        &mut self,
        runs: &mut RunLanes<T, L>,
        i: usize,
        sim: &Simulator<'_, T>,
        p: &SubPlan<T>,
        book: &SampleBook<T>,
        constants: bool,
    ) -> bool {
        if constants {
            let hammer = sim.hammer();
            let (Some(field), Some(inv_mass)) =
                (F::of(&hammer.free_flight()), F::inv_mass(hammer.body()))
            else {
                return false;
            };
            let LawCoeffs::Linear { k, c } = hammer.switch().law else {
                return false;
            };
            let damped = hammer.is_damped_wires();
            if *self.damped.get_or_insert(damped) != damped {
                return false;
            }
            self.field[i] = field;
            self.inv_mass[i] = inv_mass;
            self.k[i] = k;
            self.c[i] = c;
            self.eta_d[i] = hammer.switch().eta_delta;
            self.eta_f[i] = hammer.switch().eta_force;
            let rule = sim.substep_rule();
            runs.h_c[i] = rule.h_c;
            runs.h_rest[i] = rule.h_rest;
            runs.receding_max[i] = rule.receding_max;
            runs.eps_omega_c[i] = rule.eps_omega_c;
        }
        let (x, carry, start, approach) = sim.substep_start();
        self.x0[i] = x[0];
        self.x1[i] = x[1];
        self.carry0[i] = carry[0];
        self.carry1[i] = carry[1];
        self.a[i] = start.dx[1];
        runs.force0[i] = start.force;
        runs.region0[i] = code_of(start.region);
        runs.d0[i] = start.delta;
        runs.dd0[i] = start.delta_dot;
        runs.approach[i] = approach;
        runs.rest[i] = p.rest;
        runs.separation[i] = book.separation;
        runs.prev_delta[i] = book.prev_delta;
        runs.in_episode[i] = u32::from(book.in_episode);
        runs.peak[i] = book.peak;
        runs.period_force[i] = book.period_force;
        runs.taken[i] = 0;
        self.len[i] = p.len;
        self.s_start[i] = p.s_start;
        (self.omega[i], self.sin0[i], self.cos0[i]) = sim.step_phase();
        self.offset[i] = p.offset;
        self.step_end[i] = p.step_end;
        self.last[i] = u32::from(p.last);
        self.band[i] = u32::from(p.band);
        self.touching[i] = u32::from(p.touching);
        true
    }

    /// Lane `i`'s trial after [`ContactLanes::run`], for [`Simulator::commit_substep`] (the
    /// run kept the trial's end as the lane's next start).
    #[inline]
    pub(crate) fn result(&self, runs: &RunLanes<T, L>, i: usize) -> LaneTrial<T> {
        let (x0, x1) = (self.x0[i], self.x1[i]);
        match self.ok[i] {
            STAYS => LaneTrial::Stays {
                x: Vector2::new(x0, x1),
                carry: Vector2::new(self.carry0[i], self.carry1[i]),
                end: FieldEval {
                    dx: Vector2::new(x1, self.a[i]),
                    force: runs.force0[i],
                    region: region_of(runs.region0[i]),
                    delta: runs.d0[i],
                    delta_dot: runs.dd0[i],
                },
            },
            SWITCHES => LaneTrial::Switches {
                x: Vector2::new(x0, x1),
                s_end: self.s_end[i],
            },
            _ => LaneTrial::Inexact,
        }
    }

    /// Where the run of lane `i` stands if the lane ended sub-steps itself since it was set and
    /// stopped in the last [`ContactLanes::run`]: for [`Simulator::resume_substeps`] (with its
    /// cursor), the plan `p` of the sub-step the lane stopped in (updated here), and the run's
    /// book.
    #[inline]
    pub(crate) fn resume(
        &self,
        runs: &RunLanes<T, L>,
        i: usize,
        p: &mut SubPlan<T>,
    ) -> Option<(LaneResume<T>, SampleBook<T>)> {
        if runs.taken[i] == 0 {
            return None;
        }
        let st = &runs.start;
        *p = SubPlan {
            len: st.len[i],
            last: st.last[i] != 0,
            band: st.band[i] != 0,
            s_start: st.s_start[i],
            offset: st.offset[i],
            step_end: self.step_end[i],
            touching: st.touching[i] != 0,
            rest: st.rest[i],
        };
        let x1 = st.x1[i];
        let resume = LaneResume {
            state: Handback {
                x: Vector2::new(st.x0[i], x1),
                carry: Vector2::new(st.carry0[i], st.carry1[i]),
                at_x: FieldEval {
                    dx: Vector2::new(x1, st.a[i]),
                    force: st.force0[i],
                    region: region_of(st.region0[i]),
                    delta: st.d0[i],
                    delta_dot: st.dd0[i],
                },
                approach_speed: st.approach[i],
            },
            offset: st.offset[i],
            rest: st.rest[i],
            substeps: runs.taken[i],
        };
        let book = SampleBook {
            prev_delta: st.prev_delta[i],
            peak: st.peak[i],
            period_force: st.period_force[i],
            ..runs.book(i)
        };
        Some((resume, book))
    }

    /// Takes every lane's sub-step, and where nothing else has to happen ends it and sets up
    /// the next (lanes not set since the last run repeat their last one and are to be ignored).
    /// `B` books the runs' samples.
    pub(crate) fn run<B: QuietSample<T>>(&mut self, runs: &mut RunLanes<T, L>) {
        if self.damped == Some(true) {
            self.run_viscous::<Damped, B>(runs);
        } else {
            self.run_viscous::<Undamped, B>(runs);
        }
    }

    /// [`ContactLanes::run`] with the pendulum's viscous term as `V` has it, in the
    /// instruction set of [`Isa::detect`].
    #[inline(always)]
    fn run_viscous<V: Viscous, B: QuietSample<T>>(&mut self, runs: &mut RunLanes<T, L>) {
        let isa = self.isa;
        isa.run(ContactRound {
            lanes: self,
            runs,
            kinds: PhantomData::<(V, B)>,
        });
    }

    /// The body of [`ContactLanes::run`]: [`Simulator::substep`]'s trial and end field, lane by
    /// lane with the same operations (branch-free, so that it vectorises).
    #[inline(always)]
    fn run_kernel<V: Viscous, B: QuietSample<T>>(&mut self, runs: &mut RunLanes<T, L>) {
        let zero = T::zero();
        // Every lane's start, kept for `resume` (the arrays take the next sub-step below).
        let st = &mut runs.start;
        st.x0 = self.x0;
        st.x1 = self.x1;
        st.carry0 = self.carry0;
        st.carry1 = self.carry1;
        st.a = self.a;
        st.offset = self.offset;
        st.len = self.len;
        st.last = self.last;
        st.band = self.band;
        st.s_start = self.s_start;
        st.touching = self.touching;
        st.approach = runs.approach;
        st.force0 = runs.force0;
        st.region0 = runs.region0;
        st.d0 = runs.d0;
        st.dd0 = runs.dd0;
        st.rest = runs.rest;
        st.prev_delta = runs.prev_delta;
        st.peak = runs.peak;
        st.period_force = runs.period_force;
        let mut tx0 = [zero; L];
        let mut tx1 = [zero; L];
        let mut tc0 = [zero; L];
        let mut tc1 = [zero; L];
        let mut exact = [true; L];
        let mut end_exact = [true; L];
        let (mut o_acc, mut o_d, mut o_dd, mut o_force) =
            ([zero; L], [zero; L], [zero; L], [zero; L]);
        let (mut o_region, mut o_ok) = ([0u32; L], [0u32; L]);
        for i in 0..L {
            let (kk, cc) = (self.k[i], self.c[i]);
            let touching = self.touching[i] != 0;
            let field = &self.field[i];
            let inv_mass = self.inv_mass[i];
            // `sin Ωt` at the midpoint and the end (`Simulator::sin_at`).
            let phase = |dt: T| {
                let (s, c, exact) = (self.omega[i] * dt).sin_cos_lane();
                (self.sin0[i] * c + self.cos0[i] * s, exact)
            };
            let (offset, len) = (self.offset[i], self.len[i]);
            let (s_mid, mid_exact) = phase(offset + len * T::from_f64(0.5));
            let (s_end_at, end_exact_l) = phase(offset + len);
            let last = self.last[i] != 0;
            let s_end = if last { self.step_end[i] } else { s_end_at };
            self.s_end[i] = s_end;
            let mut ex = mid_exact & (last | end_exact_l);
            end_exact[i] = end_exact_l;
            // The mode's field: the law continued (`f+`, `LawCoeffs::unswitched_force`) or
            // free flight (`f−`, no force).
            let mut mode_field = |y: &Vector2<T>, s: T| {
                let (acc, _, _, _, ok) =
                    field.contact_field::<SmallTrig, V, _>(inv_mass, y[0], y[1], s, |d, dd| {
                        let f = kk * d + cc * dd;
                        if touching { f } else { zero }
                    });
                ex &= ok;
                Vector2::new(y[1], acc)
            };
            let x = Vector2::new(self.x0[i], self.x1[i]);
            // RK4's first stage: the switch model's field at the start, or in a band the
            // mode's.
            let k1 = if self.band[i] != 0 {
                mode_field(&x, self.s_start[i])
            } else {
                Vector2::new(self.x1[i], self.a[i])
            };
            let (trial, carry) = rk4_step_compensated(
                &x,
                &Vector2::new(self.carry0[i], self.carry1[i]),
                &k1,
                self.len[i],
                s_mid,
                s_end,
                mode_field,
            );
            tx0[i] = trial[0];
            tx1[i] = trial[1];
            tc0[i] = carry[0];
            tc1[i] = carry[1];
            exact[i] = ex;
        }
        for i in 0..L {
            // The switch-model field at the end (`SwitchModel::force`): the regions by
            // priority, the last assignment winning.
            let (kk, cc) = (self.k[i], self.c[i]);
            let (eta_d, eta_f) = (self.eta_d[i], self.eta_f[i]);
            let mut region = FREE;
            let (acc, d, dd, force, ok) = self.field[i].contact_field::<SmallTrig, V, _>(
                self.inv_mass[i],
                tx0[i],
                tx1[i],
                self.s_end[i],
                |d, dd| {
                    let f;
                    (f, region) = linear_switch_force(kk, cc, eta_d, eta_f, d, dd);
                    f
                },
            );
            let end_touching = u32::from(region == CONTACT) | u32::from(region == BAND_ALPHA);
            (o_acc[i], o_d[i], o_dd[i], o_force[i]) = (acc, d, dd, force);
            o_region[i] = region;
            // STAYS (1), SWITCHES (2) or INEXACT (0), without a branch.
            let exact = u32::from(exact[i] & ok);
            o_ok[i] = exact << u32::from(end_touching != self.touching[i]);
        }
        // Each lane's next sub-step (meaningful where the lane goes on).
        let mut n_approach = [zero; L];
        let (mut n_offset, mut n_rest, mut n_len, mut n_s_start) =
            ([zero; L], [zero; L], [zero; L], [zero; L]);
        let (mut n_prev_delta, mut n_peak, mut n_period_force) = ([zero; L], [zero; L], [zero; L]);
        let (mut n_last, mut n_band, mut n_touching) = ([0u32; L], [0u32; L], [0u32; L]);
        for i in 0..L {
            let (acc, d, dd, force, region) = (o_acc[i], o_d[i], o_dd[i], o_force[i], o_region[i]);
            let ok = o_ok[i];
            let eta_d = self.eta_d[i];
            let end_touching = u32::from(region == CONTACT) | u32::from(region == BAND_ALPHA);

            // The commit (`Simulator::commit_substep`) and its sample (`Simulator::sample`):
            // the smallest `δ` since the start is the smaller end unless the slope turns.
            let (d0, dd0) = (runs.d0[i], runs.dd0[i]);
            let turn = (dd0 < zero) & (dd > zero);
            let (book, quiet) = B::take(&runs.book(i), d, d0.min_of(d), force);
            // The next sub-step (`Simulator::plain_substep`): not clear of the surface, in a
            // band with `sin Ωt` at its start (the end's, computed above), its length.
            let clear = (region == FREE) & (d <= -eta_d);
            let band = (region == BAND_ALPHA) | (region == BAND_BETA);
            let (offset, rest) = (self.offset[i] + self.len[i], runs.rest[i] - self.len[i]);
            let (len, next_last) = runs.rule(i).len(
                eta_d,
                region == FREE,
                region == CONTACT,
                d,
                dd,
                acc,
                || force * self.inv_mass[i],
                rest,
            );
            let cont = (ok == STAYS)
                & (self.last[i] == 0)
                & !turn
                & quiet
                & !clear
                & (!band | end_exact[i]);
            runs.cont[i] = u32::from(cont);
            // The approach speed of an arrival from free flight.
            let arrival = (self.touching[i] == 0) & (d0 <= zero);
            n_approach[i] = if arrival {
                dd0.max_of(min_approach())
            } else {
                runs.approach[i]
            };
            (n_offset[i], n_rest[i], n_len[i]) = (offset, rest, len);
            n_last[i] = u32::from(next_last);
            n_band[i] = u32::from(band);
            n_s_start[i] = if band { self.s_end[i] } else { zero };
            n_touching[i] = end_touching;
            (n_prev_delta[i], n_peak[i]) = (book.prev_delta, book.peak);
            n_period_force[i] = book.period_force;
            runs.taken[i] += u32::from(cont);
        }
        // Every lane's next sub-step set, whole arrays stored (lanes that stop hold junk from
        // here on until they are set again; a conditional store per lane cost more than the
        // rest of the kernel: measured).
        (self.x0, self.x1, self.carry0, self.carry1, self.a) = (tx0, tx1, tc0, tc1, o_acc);
        (self.offset, self.len, self.last, self.band) = (n_offset, n_len, n_last, n_band);
        (self.s_start, self.touching) = (n_s_start, n_touching);
        (runs.approach, runs.force0, runs.region0) = (n_approach, o_force, o_region);
        (runs.d0, runs.dd0, runs.rest) = (o_d, o_dd, n_rest);
        (runs.prev_delta, runs.peak, runs.period_force) = (n_prev_delta, n_peak, n_period_force);
        self.ok = o_ok;
    }
}

/// The switch-model force (N) and region code at penetration `d` (m) and rate `dd` (m/s) for
/// the linear law `k δ + c δ̇` (N/m, N·s/m) and the bands `η_δ` = `eta_d` (m), `η_F` = `eta_f`
/// (N): `SwitchModel::force` (Eq. 3-27–3-29) without a branch, the regions by priority, the last
/// assignment winning.
#[inline(always)]
pub(crate) fn linear_switch_force<T: Real>(
    k: T,
    c: T,
    eta_d: T,
    eta_f: T,
    d: T,
    dd: T,
) -> (T, u32) {
    let zero = T::zero();
    let (elastic, dissipative) = (k * d, c * dd);
    let h_beta = elastic + dissipative;
    let mut region = FREE;
    let mut f = zero;
    if d > zero && h_beta > zero {
        region = CONTACT;
        f = h_beta;
    }
    if h_beta.abs() < eta_f && d >= zero {
        region = BAND_BETA;
        f = zero;
    }
    if d.abs() < eta_d && h_beta >= zero {
        region = BAND_ALPHA;
        f = dissipative.max_of(zero);
    }
    if d <= -eta_d {
        region = FREE;
        f = zero;
    }
    (f, region)
}

/// The lane code of a switch-model region ([`region_of`] reversed).
#[inline(always)]
fn code_of(region: Region) -> u32 {
    match region {
        Region::Free => FREE,
        Region::Contact => CONTACT,
        Region::BandAlpha => BAND_ALPHA,
        Region::BandBeta => BAND_BETA,
    }
}

/// The switch-model region of a lane code.
#[inline(always)]
pub(crate) fn region_of(code: u32) -> Region {
    match code {
        CONTACT => Region::Contact,
        BAND_ALPHA => Region::BandAlpha,
        BAND_BETA => Region::BandBeta,
        _ => Region::Free,
    }
}

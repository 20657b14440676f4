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

use nalgebra::Vector2;

use super::Simulator;
use super::free::{SmallTrig, Trig};
use super::isa::Isa;
use super::lanes::LaneField;
use super::rk4::rk4_step_compensated;
use super::stepper::{LaneTrial, SubPlan};
use crate::model::Region;
use crate::model::contact::LawCoeffs;
use crate::model::hammer::{BeamFree, Body, Damped, FieldEval, Undamped, Viscous, WiresFree};
use crate::real::Real;

/// The contact field of one suspension in a lane.
pub(crate) trait LaneContact<T: Real>: LaneField<T> {
    /// What the acceleration needs of the position besides `y1` (wires `(sin θ, cos θ)`,
    /// beams `u`).
    type Position: Copy;
    /// `(δ, δ̇, position, exact)` at `(y0, y1)`, the sine by `G` (`exact`: within its range).
    fn penetration<G: Trig>(&self, y0: T, y1: T) -> (T, T, Self::Position, bool);
    /// The acceleration at `position`, `y1` with `sin Ωt = sin_phase` and the contact term
    /// `contact` (wires `F_i/(m l)`, beams `F_i/m`), the pendulum's viscous term as `V` has it.
    fn accel_at<V: Viscous>(&self, position: Self::Position, y1: T, sin_phase: T, contact: T) -> T;

    /// The field at `(y0, y1)` with `sin Ωt = sin_phase` and the contact acceleration term
    /// `force · inv_mass` (wires `1/(m l)`, beams `1/m`) given by `force(δ, δ̇)`:
    /// `(acceleration, δ, δ̇, force, exact)`.
    #[inline(always)]
    fn contact_field<G: Trig, V: Viscous, P: FnOnce(T, T) -> T>(
        &self,
        inv_mass: T,
        y0: T,
        y1: T,
        sin_phase: T,
        force: P,
    ) -> (T, T, T, T, bool) {
        let (d, dd, position, exact) = self.penetration::<G>(y0, y1);
        let f = force(d, dd);
        let acc = self.accel_at::<V>(position, y1, sin_phase, f * inv_mass);
        (acc, d, dd, f, exact)
    }

    /// The suspension's `inv_mass` from the hammer's body (`None` for the other suspension).
    fn inv_mass(body: &Body<T>) -> Option<T>;
}

impl<T: Real> LaneContact<T> for WiresFree<T> {
    type Position = (T, T);
    #[inline(always)]
    fn penetration<G: Trig>(&self, y0: T, y1: T) -> (T, T, (T, T), bool) {
        let (st, ct, exact) = G::sin_cos(y0);
        (
            self.length * st - self.gap,
            self.length * y1 * ct,
            (st, ct),
            exact,
        )
    }
    #[inline(always)]
    fn accel_at<V: Viscous>(&self, sin_cos: (T, T), y1: T, sin_phase: T, contact: T) -> T {
        self.accel::<V>(sin_cos, y1, sin_phase, contact)
    }
    #[inline(always)]
    fn inv_mass(body: &Body<T>) -> Option<T> {
        match body {
            Body::Wires { inv_ml, .. } => Some(*inv_ml),
            Body::Beam { .. } => None,
        }
    }
}

impl<T: Real> LaneContact<T> for BeamFree<T> {
    type Position = T;
    #[inline(always)]
    fn penetration<G: Trig>(&self, y0: T, y1: T) -> (T, T, T, bool) {
        (y0 - self.gap, y1, y0, true)
    }
    #[inline(always)]
    fn accel_at<V: Viscous>(&self, u: T, y1: T, sin_phase: T, contact: T) -> T {
        self.accel(u, y1, sin_phase, contact)
    }
    #[inline(always)]
    fn inv_mass(body: &Body<T>) -> Option<T> {
        match body {
            Body::Beam { inv_m, .. } => Some(*inv_m),
            Body::Wires { .. } => None,
        }
    }
}

/// What a lane's trial is ([`LaneTrial`]): inexact, ending in its start's mode, or in the other.
const STAYS: u32 = 1;
const SWITCHES: u32 = 2;

/// Switch-model regions as lane codes.
const FREE: u32 = 0;
const CONTACT: u32 = 1;
const BAND_ALPHA: u32 = 2;
const BAND_BETA: u32 = 3;

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
    // The result: end state, carry, switch-model field there, and what it is (`STAYS`,
    // `SWITCHES`, or 0: a sine outside the short range).
    out_x0: [T; L],
    out_x1: [T; L],
    out_carry0: [T; L],
    out_carry1: [T; L],
    out_acc: [T; L],
    out_d: [T; L],
    out_dd: [T; L],
    out_force: [T; L],
    region: [u32; L],
    ok: [u32; L],
    /// The instruction set the kernel runs.
    isa: Isa,
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
            out_x0: z,
            out_x1: z,
            out_carry0: z,
            out_carry1: z,
            out_acc: z,
            out_d: z,
            out_dd: z,
            out_force: z,
            region: [0; L],
            ok: [0; L],
            isa: Isa::detect(),
        }
    }

    /// Puts `sim`'s next sub-step `p` ([`Simulator::plain_substep`]) into lane `i`, with
    /// `sim`'s constants if `constants` (else the lane keeps those of its last [`set`], which
    /// must be `sim`'s). Returns `false` (nothing set) if `sim` is not of this suspension, not
    /// of the linear law, or (the pendulum) damped where the lanes' first simulator was not or
    /// the other way round.
    ///
    /// [`set`]: ContactLanes::set
    #[inline]
    pub(crate) fn set(
        &mut self,
        i: usize,
        sim: &Simulator<'_, T>,
        p: &SubPlan<T>,
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
        }
        let (x, carry, start) = sim.substep_start();
        self.x0[i] = x[0];
        self.x1[i] = x[1];
        self.carry0[i] = carry[0];
        self.carry1[i] = carry[1];
        self.a[i] = start.dx[1];
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

    /// Lane `i`'s trial after [`ContactLanes::run`], for [`Simulator::commit_substep`].
    #[inline]
    pub(crate) fn result(&self, i: usize) -> LaneTrial<T> {
        let (x0, x1) = (self.out_x0[i], self.out_x1[i]);
        match self.ok[i] {
            STAYS => {
                let region = match self.region[i] {
                    CONTACT => Region::Contact,
                    BAND_ALPHA => Region::BandAlpha,
                    BAND_BETA => Region::BandBeta,
                    _ => Region::Free,
                };
                LaneTrial::Stays {
                    x: Vector2::new(x0, x1),
                    carry: Vector2::new(self.out_carry0[i], self.out_carry1[i]),
                    end: FieldEval {
                        dx: Vector2::new(x1, self.out_acc[i]),
                        force: self.out_force[i],
                        region,
                        delta: self.out_d[i],
                        delta_dot: self.out_dd[i],
                    },
                }
            }
            SWITCHES => LaneTrial::Switches {
                x: Vector2::new(x0, x1),
                s_end: self.s_end[i],
            },
            _ => LaneTrial::Inexact,
        }
    }

    /// Takes every lane's sub-step (lanes not set since the last run repeat their last one and
    /// are to be ignored).
    pub(crate) fn run(&mut self) {
        if self.damped == Some(true) {
            self.run_viscous::<Damped>();
        } else {
            self.run_viscous::<Undamped>();
        }
    }

    /// [`ContactLanes::run`] with the pendulum's viscous term as `V` has it, in the
    /// instruction set of [`Isa::detect`].
    #[inline(always)]
    fn run_viscous<V: Viscous>(&mut self) {
        match self.isa {
            // SAFETY: the CPU supports the variant's instructions (`Isa::detect`).
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            #[allow(unsafe_code)]
            Isa::Avx512 => unsafe { self.run_avx512::<V>() },
            // SAFETY: as above.
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            #[allow(unsafe_code)]
            Isa::Avx2 => unsafe { self.run_avx2::<V>() },
            Isa::Portable => self.run_kernel::<V>(),
        }
    }

    /// [`ContactLanes::run`] compiled for AVX-512.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx,avx2,avx512f,avx512vl,avx512dq,avx512bw")]
    fn run_avx512<V: Viscous>(&mut self) {
        self.run_kernel::<V>();
    }

    /// [`ContactLanes::run`] compiled for AVX2.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx,avx2")]
    fn run_avx2<V: Viscous>(&mut self) {
        self.run_kernel::<V>();
    }

    /// The body of [`ContactLanes::run`]: [`Simulator::substep`]'s trial and end field, lane by
    /// lane with the same operations (branch-free, so that it vectorises).
    #[inline(always)]
    fn run_kernel<V: Viscous>(&mut self) {
        let zero = T::zero();
        let mut tx0 = [zero; L];
        let mut tx1 = [zero; L];
        let mut tc0 = [zero; L];
        let mut tc1 = [zero; L];
        let mut exact = [true; L];
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
            let (s_end_at, end_exact) = phase(offset + len);
            let last = self.last[i] != 0;
            let s_end = if last { self.step_end[i] } else { s_end_at };
            self.s_end[i] = s_end;
            let mut ex = mid_exact & (last | end_exact);
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
                    let (elastic, dissipative) = (kk * d, cc * dd);
                    let h_beta = elastic + dissipative;
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
        // Whole arrays out (one store each, where a lane at a time would take them apart).
        (self.out_x0, self.out_x1, self.out_carry0, self.out_carry1) = (tx0, tx1, tc0, tc1);
        (self.out_acc, self.out_d, self.out_dd, self.out_force) = (o_acc, o_d, o_dd, o_force);
        (self.region, self.ok) = (o_region, o_ok);
    }
}

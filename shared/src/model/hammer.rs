//! A rig compiled for one gap and one excitation frequency: the switch-model vector field
//! `ẋ = f(x, t)` in the float type `T`.
//!
//! - Wires (generalised coordinate `θ`), Eq. (3-26)–(3-29):
//!   `θ̈ = (A0 Ω²/l) cos θ sin Ωt − (g/l) sin θ − F_i/(m l)`, with `u = l sin θ`, `δ̇ = l θ̇ cos θ`.
//!   The contact force enters as `−F_i l` in the moment balance exactly as the thesis writes it.
//!   The project adds the viscous term `− 2ζω θ̇`, `ω = sqrt(g/l)` (the pendulum's pivot and
//!   air, docs/model.md); with `ζ = 0` (the `wires` preset) the field is the thesis' to the bit
//!   (`Viscous`).
//! - Beam springs (coordinate `u = x − y`), Eq. (3-36)–(3-39) rewritten relative to the cart:
//!   `ü = −(c/m) u̇ − (k/m) u − (k/m) u³ − F_i/m + A0 Ω² sin Ωt`, `k = m ω²`, `c = 2ζ m ω`.
//!
//! Sign convention (docs/model.md): the impact surface is at `u = gap` on the `+u` side;
//! `δ = u − gap`; `F_i ≥ 0` pushes the hammer back toward `−u`.
//!
//! Each suspension's acceleration is written once (`wires_accel`, `beam_accel`): the
//! switch-model field, the free-flight field and the integrator's free-flight kernel
//! (`crate::integrate::free`) all evaluate it.

use nalgebra::Vector2;

use super::rig::{RigParams, Suspension};
use super::switch::{Region, SwitchBands, SwitchModel};
use crate::error::{ParamError, check_range};
use crate::real::Real;

pub use super::rig::MAX_GAP_M;
/// Accepted excitation angular frequencies `Ω`, rad/s.
pub const OMEGA_EXC_RANGE: (f64, f64) = (1e-2, 1e4);

/// The suspension's coefficients in `T`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Body<T> {
    /// Embarked pendulum, state `(θ, θ̇)`.
    Wires {
        /// `l`, m.
        length: T,
        /// `g/l`, 1/s².
        g_over_l: T,
        /// `2ζω`, 1/s (0: the thesis' undamped pendulum).
        damping: T,
        /// `A0 Ω²/l`, 1/s².
        a0w2_over_l: T,
        /// `1/(m l)`, 1/(kg m).
        inv_ml: T,
    },
    /// Beam springs, state `(u, u̇)`.
    Beam {
        /// `k/m = ω²`, 1/s².
        k_over_m: T,
        /// `c/m = 2ζω`, 1/s.
        c_over_m: T,
        /// `A0 Ω²`, m/s².
        a0w2: T,
        /// `1/m`, 1/kg.
        inv_m: T,
    },
}

/// Which vector field to evaluate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldMode {
    /// Leine's switch model (the physics).
    Switch,
    /// Free flight `f−` whatever the state (locating arrivals).
    Free,
    /// Contact `f+` with the law continued past `h_β = 0` (locating departures).
    Contact,
}

impl FieldMode {
    /// The mode a sub-step is first taken in: contact `f+` if it starts touching, else free
    /// flight `f−`.
    #[inline(always)]
    pub fn of_start(touching: bool) -> Self {
        if touching {
            FieldMode::Contact
        } else {
            FieldMode::Free
        }
    }
}

/// The base excitation entering the field.
#[derive(Debug, Clone, Copy)]
enum Drive<T> {
    /// `sin Ωt` of the harmonic cart motion `y = A0 sin Ωt`.
    Harmonic(T),
    /// The cart's acceleration `ÿ`, m/s².
    Cart(T),
}

/// One evaluation of the vector field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldEval<T> {
    /// `ẋ` (for wires `(θ̇, θ̈)`, for beams `(u̇, ü)`).
    pub dx: Vector2<T>,
    /// Contact force `F_i`, N.
    pub force: T,
    /// Region of the switch model.
    pub region: Region,
    /// Penetration `δ = u − gap`, m.
    pub delta: T,
    /// Penetration rate `δ̇`, m/s.
    pub delta_dot: T,
}

/// The pendulum's `θ̈` (1/s²), Eq. (3-26): `excitation − (g/l) sin θ − contact`, with
/// `excitation` the drive term (`(A0 Ω²/l) cos θ sin Ωt` for the harmonic cart) and `contact`
/// the contact force's term `F_i/(m l)` (0 in free flight).
#[inline(always)]
pub(crate) fn wires_accel<T: Real>(g_over_l: T, sin_theta: T, excitation: T, contact: T) -> T {
    excitation - g_over_l * sin_theta - contact
}

/// How the pendulum's viscous term enters its `θ̈`: `acc − 2ζω θ̇` after Eq. (3-26)'s terms
/// (`acc` = [`wires_accel`]), or not at all. Chosen at compile time in the lockstep lanes (one
/// kernel per choice, so that the undamped lanes run the thesis' operations only) and at run
/// time elsewhere ([`AsSet`]); with `2ζω = 0` every choice gives the undamped bits.
pub(crate) trait Viscous {
    /// `θ̈` (1/s²) from Eq. (3-26)'s `acc`, `damping = 2ζω` (1/s) and `θ̇` (rad/s).
    fn apply<T: Real>(acc: T, damping: T, theta_dot: T) -> T;
}

/// No viscous term: `acc` (the lanes of an undamped pendulum).
pub(crate) struct Undamped;

/// The viscous term: `acc − damping · θ̇` (the lanes of a damped pendulum).
pub(crate) struct Damped;

/// The viscous term if `damping ≠ 0`, else `acc` itself (the stepper and the switch-model
/// field: with `ζ = 0`, the thesis' operations exactly, as in [`Undamped`]).
pub(crate) struct AsSet;

impl Viscous for Undamped {
    #[inline(always)]
    fn apply<T: Real>(acc: T, _: T, _: T) -> T {
        acc
    }
}

impl Viscous for Damped {
    #[inline(always)]
    fn apply<T: Real>(acc: T, damping: T, theta_dot: T) -> T {
        acc - damping * theta_dot
    }
}

impl Viscous for AsSet {
    #[inline(always)]
    fn apply<T: Real>(acc: T, damping: T, theta_dot: T) -> T {
        if damping != T::zero() {
            Damped::apply(acc, damping, theta_dot)
        } else {
            acc
        }
    }
}

/// The beam hammer's `ü` (m/s²) relative to the cart, Eq. (3-36):
/// `−(c/m) u̇ − (k/m)(u + u³) − contact + excitation`, with `excitation` the drive term
/// (`A0 Ω² sin Ωt` for the harmonic cart) and `contact` the contact force's term `F_i/m`.
#[inline(always)]
pub(crate) fn beam_accel<T: Real>(
    k_over_m: T,
    c_over_m: T,
    u: T,
    du: T,
    excitation: T,
    contact: T,
) -> T {
    -c_over_m * du - k_over_m * (u + u * u * u) - contact + excitation
}

/// What a free-flight step of the wire pendulum needs (Eq. 3-26 with `F_i = 0`, and the
/// viscous term).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct WiresFree<T> {
    /// `l`, m.
    pub(crate) length: T,
    /// `g/l`, 1/s².
    pub(crate) g_over_l: T,
    /// `2ζω`, 1/s.
    pub(crate) damping: T,
    /// `A0 Ω²/l`, 1/s².
    pub(crate) a0w2_over_l: T,
    /// Gap, m.
    pub(crate) gap: T,
}

impl<T: Real> WiresFree<T> {
    /// The free-flight field at `(θ, θ̇)` = `(_, y1)` given `(sin θ, cos θ)` and
    /// `sin Ωt = sin_phase`, the viscous term as `V` has it: `(θ̈, δ, δ̇)` (1/s², m, m/s).
    #[inline(always)]
    pub(crate) fn eval<V: Viscous>(&self, y1: T, (st, ct): (T, T), sin_phase: T) -> (T, T, T) {
        let acc = self.accel::<V>((st, ct), y1, sin_phase, T::zero());
        (acc, self.length * st - self.gap, self.length * y1 * ct)
    }

    /// `θ̈` (1/s²) given `(sin θ, cos θ)`, `θ̇ = y1`, `sin Ωt = sin_phase` and the contact term
    /// `contact = F_i/(m l)` (0 in free flight): Eq. (3-26), the viscous term as `V` has it.
    #[inline(always)]
    pub(crate) fn accel<V: Viscous>(&self, (st, ct): (T, T), y1: T, sin_phase: T, contact: T) -> T {
        V::apply(
            wires_accel(
                self.g_over_l,
                st,
                self.a0w2_over_l * ct * sin_phase,
                contact,
            ),
            self.damping,
            y1,
        )
    }
}

/// What a free-flight step of the beam-spring hammer needs (Eq. 3-36 with `F_i = 0`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct BeamFree<T> {
    /// `k/m = ω²`, 1/s².
    pub(crate) k_over_m: T,
    /// `c/m = 2ζω`, 1/s.
    pub(crate) c_over_m: T,
    /// `A0 Ω²`, m/s².
    pub(crate) a0w2: T,
    /// Gap, m.
    pub(crate) gap: T,
}

impl<T: Real> BeamFree<T> {
    /// The free-flight field at `(u, u̇)` = `(y0, y1)` with `sin Ωt = sin_phase`:
    /// `(ü, δ, δ̇)` (m/s², m, m/s).
    #[inline(always)]
    pub(crate) fn eval(&self, y0: T, y1: T, sin_phase: T) -> (T, T, T) {
        let acc = self.accel(y0, y1, sin_phase, T::zero());
        (acc, y0 - self.gap, y1)
    }

    /// `ü` (m/s²) at `(u, u̇)` = `(y0, y1)` with `sin Ωt = sin_phase` and the contact term
    /// `contact = F_i/m` (0 in free flight): Eq. (3-36).
    #[inline(always)]
    pub(crate) fn accel(&self, y0: T, y1: T, sin_phase: T, contact: T) -> T {
        beam_accel(
            self.k_over_m,
            self.c_over_m,
            y0,
            y1,
            self.a0w2 * sin_phase,
            contact,
        )
    }
}

/// What a free-flight step needs of a hammer, per suspension ([`Hammer::free_flight`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum FreeFlight<T> {
    /// The wire pendulum.
    Wires(WiresFree<T>),
    /// The beam springs.
    Beam(BeamFree<T>),
}

/// A rig at one gap and one excitation frequency, in the float type `T` (built by
/// [`Hammer::new`], which checks every value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hammer<T> {
    body: Body<T>,
    switch: SwitchModel<T>,
    gap: T,
    /// `Ω`, rad/s, in f64: the step grid is computed from it.
    omega_exc: f64,
    amplitude: T,
}

impl<T: Real> Hammer<T> {
    /// Compiles `params` for `gap_m` (m, ≥ 0) and excitation angular frequency `omega_exc` (rad/s).
    ///
    /// # Errors
    /// [`ParamError`] for invalid rig parameters, bands, a gap outside `0 ..= 0.05 m`
    /// (wires: `0 ..= l/4`), or `Ω` outside [`OMEGA_EXC_RANGE`].
    pub fn new(
        params: &RigParams,
        gap_m: f64,
        omega_exc: f64,
        bands: &SwitchBands,
    ) -> Result<Self, ParamError> {
        params.validate()?;
        bands.validate()?;
        check_range("gap_m", gap_m, 0.0, params.max_gap_m())?;
        check_range("omega_exc", omega_exc, OMEGA_EXC_RANGE.0, OMEGA_EXC_RANGE.1)?;
        let c = T::from_f64;
        let m = params.mass_kg;
        let a0w2 = params.amplitude_m * omega_exc * omega_exc;
        let body = match params.suspension {
            Suspension::Wires {
                length_m,
                damping_ratio,
            } => Body::Wires {
                length: c(length_m),
                g_over_l: c(params.gravity_m_s2 / length_m),
                damping: c(2.0 * damping_ratio * params.omega_n()),
                a0w2_over_l: c(a0w2 / length_m),
                inv_ml: c(1.0 / (m * length_m)),
            },
            Suspension::Beam { damping_ratio, .. } => {
                let w = params.omega_n();
                Body::Beam {
                    k_over_m: c(w * w),
                    c_over_m: c(2.0 * damping_ratio * w),
                    a0w2: c(a0w2),
                    inv_m: c(1.0 / m),
                }
            }
        };
        Ok(Hammer {
            body,
            switch: SwitchModel::new(params.contact.compile(m), bands),
            gap: c(gap_m),
            omega_exc,
            amplitude: c(params.amplitude_m),
        })
    }

    /// The same rig with the cart at rest (`A0 = 0`, no excitation term): the drop test
    /// (`crate::analysis::drop`). `Ω` stays: it sets the step grid.
    pub fn without_excitation(mut self) -> Self {
        match &mut self.body {
            Body::Wires { a0w2_over_l, .. } => *a0w2_over_l = T::zero(),
            Body::Beam { a0w2, .. } => *a0w2 = T::zero(),
        }
        self.amplitude = T::zero();
        self
    }

    /// Suspension coefficients.
    pub fn body(&self) -> &Body<T> {
        &self.body
    }
    /// The contact law with the switch-model bands.
    pub fn switch(&self) -> &SwitchModel<T> {
        &self.switch
    }
    /// Gap, m.
    pub fn gap(&self) -> T {
        self.gap
    }
    /// Excitation angular frequency `Ω`, rad/s.
    pub fn omega_exc(&self) -> f64 {
        self.omega_exc
    }
    /// Cart amplitude `A0`, m.
    pub fn amplitude(&self) -> T {
        self.amplitude
    }
    /// `η_δ`, m: within it of the surface the switch model may switch.
    #[inline(always)]
    pub fn eta_delta(&self) -> T {
        self.switch.eta_delta
    }
    /// Whether the suspension is the wire pendulum.
    #[inline(always)]
    pub(crate) fn is_wires(&self) -> bool {
        matches!(self.body, Body::Wires { .. })
    }
    /// Whether the suspension is the wire pendulum with its viscous term (`ζ > 0`): the
    /// lockstep lanes take it with the [`Damped`] kernel.
    #[inline(always)]
    pub(crate) fn is_damped_wires(&self) -> bool {
        matches!(self.body, Body::Wires { damping, .. } if damping != T::zero())
    }
    /// The free-flight coefficients ([`FreeFlight`]).
    #[inline(always)]
    pub(crate) fn free_flight(&self) -> FreeFlight<T> {
        match self.body {
            Body::Wires {
                length,
                g_over_l,
                damping,
                a0w2_over_l,
                ..
            } => FreeFlight::Wires(WiresFree {
                length,
                g_over_l,
                damping,
                a0w2_over_l,
                gap: self.gap,
            }),
            Body::Beam {
                k_over_m,
                c_over_m,
                a0w2,
                ..
            } => FreeFlight::Beam(BeamFree {
                k_over_m,
                c_over_m,
                a0w2,
                gap: self.gap,
            }),
        }
    }

    /// The switch-model field at state `x`, with `sin_phase = sin(Ω t)` and the current
    /// impact's approach speed (m/s, Lankarani–Nikravesh only).
    #[inline(always)]
    pub fn field(&self, x: &Vector2<T>, sin_phase: T, approach_speed: T) -> FieldEval<T> {
        self.field_in(FieldMode::Switch, x, sin_phase, approach_speed)
    }

    /// The field in a given [`FieldMode`].
    #[inline(always)]
    pub fn field_in(
        &self,
        mode: FieldMode,
        x: &Vector2<T>,
        sin_phase: T,
        approach_speed: T,
    ) -> FieldEval<T> {
        self.eval(mode, x, Drive::Harmonic(sin_phase), approach_speed)
    }

    /// The switch-model field for an arbitrary cart motion, `cart_accel_m_s2` = `ÿ(t)` (m/s²):
    /// Eq. (3-26)–(3-29) / (3-36)–(3-39) with `−ÿ` in place of the harmonic `A0 Ω² sin Ωt`
    /// (the rig's shaker chain in host-sim's virtual rig). `approach_speed` as in
    /// [`Hammer::field`].
    #[inline]
    pub fn field_driven(
        &self,
        x: &Vector2<T>,
        cart_accel_m_s2: T,
        approach_speed: T,
    ) -> FieldEval<T> {
        self.eval(
            FieldMode::Switch,
            x,
            Drive::Cart(cart_accel_m_s2),
            approach_speed,
        )
    }

    /// [`Hammer::field`] at `x` given `kin` = `self.kinematics(x)` (where the caller has them).
    #[inline(always)]
    pub(crate) fn field_with(
        &self,
        x: &Vector2<T>,
        kin: (T, T, T, T),
        sin_phase: T,
        approach_speed: T,
    ) -> FieldEval<T> {
        self.eval_with(
            FieldMode::Switch,
            x,
            kin,
            Drive::Harmonic(sin_phase),
            approach_speed,
        )
    }

    #[inline(always)]
    fn eval(
        &self,
        mode: FieldMode,
        x: &Vector2<T>,
        drive: Drive<T>,
        approach_speed: T,
    ) -> FieldEval<T> {
        self.eval_with(mode, x, self.kinematics(x), drive, approach_speed)
    }

    #[inline(always)]
    fn eval_with(
        &self,
        mode: FieldMode,
        x: &Vector2<T>,
        (delta, delta_dot, st, ct): (T, T, T, T),
        drive: Drive<T>,
        approach_speed: T,
    ) -> FieldEval<T> {
        let (force, region) = match mode {
            FieldMode::Switch => self.switch.force(delta, delta_dot, approach_speed),
            FieldMode::Free => (T::zero(), Region::Free),
            FieldMode::Contact => (
                self.switch
                    .law
                    .unswitched_force(delta, delta_dot, approach_speed),
                Region::Contact,
            ),
        };
        let acc = self.accel(x, st, ct, force, drive);
        FieldEval {
            dx: Vector2::new(x[1], acc),
            force,
            region,
            delta,
            delta_dot,
        }
    }

    /// The second component of `ẋ` given the kinematics, the contact force and the drive.
    #[inline(always)]
    fn accel(&self, x: &Vector2<T>, st: T, ct: T, force: T, drive: Drive<T>) -> T {
        let contact = self.contact_accel(force);
        match self.body {
            Body::Wires {
                length,
                g_over_l,
                damping,
                a0w2_over_l,
                ..
            } => {
                let excitation = match drive {
                    Drive::Harmonic(sin_phase) => a0w2_over_l * ct * sin_phase,
                    Drive::Cart(cart_accel) => T::zero() - cart_accel / length * ct,
                };
                AsSet::apply(
                    wires_accel(g_over_l, st, excitation, contact),
                    damping,
                    x[1],
                )
            }
            Body::Beam {
                k_over_m,
                c_over_m,
                a0w2,
                ..
            } => {
                let excitation = match drive {
                    Drive::Harmonic(sin_phase) => a0w2 * sin_phase,
                    Drive::Cart(cart_accel) => T::zero() - cart_accel,
                };
                beam_accel(k_over_m, c_over_m, x[0], x[1], excitation, contact)
            }
        }
    }

    /// The part of the second component of `ẋ` that a contact force `force` (N) causes, in the
    /// state's units (wires: `F/(m l)`, rad/s²; beams: `F/m`, m/s²), with the sign of `F`.
    #[inline(always)]
    pub fn contact_accel(&self, force: T) -> T {
        match self.body {
            Body::Wires { inv_ml, .. } => force * inv_ml,
            Body::Beam { inv_m, .. } => force * inv_m,
        }
    }

    /// `(δ, δ̇, sin θ, cos θ)` of state `x` (beams: `sin θ`, `cos θ` unused, returned as 0, 1):
    /// [`Hammer::penetration`] with the angle's sine and cosine.
    #[inline(always)]
    pub(crate) fn kinematics(&self, x: &Vector2<T>) -> (T, T, T, T) {
        let (u, du, st, ct) = self.relative_trig(x);
        (u - self.gap, du, st, ct)
    }

    /// `(u, u̇, sin θ, cos θ)` of state `x` (beams: 0, 1 for the unused sine and cosine).
    #[inline(always)]
    fn relative_trig(&self, x: &Vector2<T>) -> (T, T, T, T) {
        match self.body {
            Body::Wires { length, .. } => {
                let (st, ct) = x[0].sin_cos();
                (length * st, length * x[1] * ct, st, ct)
            }
            Body::Beam { .. } => (x[0], x[1], T::zero(), T::from_f64(1.0)),
        }
    }

    /// Relative displacement and velocity `(u, u̇)` (m, m/s) of state `x`.
    #[inline(always)]
    pub fn relative(&self, x: &Vector2<T>) -> (T, T) {
        let (u, du, _, _) = self.relative_trig(x);
        (u, du)
    }

    /// Penetration `δ = u − gap` and its rate `δ̇ = u̇` of state `x`, m and m/s.
    #[inline(always)]
    pub fn penetration(&self, x: &Vector2<T>) -> (T, T) {
        let (d, dd, _, _) = self.kinematics(x);
        (d, dd)
    }

    /// The state with relative displacement `u_m` (m) and velocity `du_m_s` (m/s).
    ///
    /// # Errors
    /// [`ParamError`] if either is not finite, or (wires) `|u| ≥ l/2`.
    pub fn state_from_relative(&self, u_m: f64, du_m_s: f64) -> Result<Vector2<T>, ParamError> {
        match self.body {
            Body::Wires { length, .. } => {
                let l = length.to_f64();
                check_range("u0_m", u_m, -0.5 * l, 0.5 * l)?;
                check_range("v0_m_s", du_m_s, -1e3, 1e3)?;
                let theta = libm::asin(u_m / l);
                Ok(Vector2::new(
                    T::from_f64(theta),
                    T::from_f64(du_m_s / (l * libm::cos(theta))),
                ))
            }
            Body::Beam { .. } => {
                check_range("u0_m", u_m, -1.0, 1.0)?;
                check_range("v0_m_s", du_m_s, -1e3, 1e3)?;
                Ok(Vector2::new(T::from_f64(u_m), T::from_f64(du_m_s)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::RigId;

    #[test]
    fn rejects_bad_gap_and_frequency() {
        let p = RigId::Wires.preset();
        let b = SwitchBands::default();
        assert!(matches!(
            Hammer::<f32>::new(&p, -1e-4, 10.0, &b),
            Err(ParamError::OutOfRange { field: "gap_m", .. })
        ));
        assert!(matches!(
            Hammer::<f32>::new(&p, 0.0, f64::NAN, &b),
            Err(ParamError::NotFinite { field: "omega_exc" })
        ));
        assert!(Hammer::<f32>::new(&p, 1e-3, 10.0, &b).is_ok());
    }

    #[test]
    fn pendulum_field_matches_eq_3_26() {
        let p = RigId::Wires.preset();
        let w = 2.0 * 11.0;
        let h = Hammer::<f64>::new(&p, 2e-3, w, &SwitchBands::default()).unwrap();
        let x = Vector2::new(0.01, 0.2);
        let s = 0.3;
        let e = h.field(&x, s, 0.1);
        let expect = 0.89e-3 * w * w / 0.075 * libm::cos(0.01) * s - 9.81 / 0.075 * libm::sin(0.01);
        assert_eq!(e.region, Region::Free);
        assert!((e.dx[1] - expect).abs() < 1e-12);
        assert_eq!(e.dx[0], 0.2);
        let (u, du) = h.relative(&x);
        assert!((u - 0.075 * libm::sin(0.01)).abs() < 1e-15);
        assert!((du - 0.075 * 0.2 * libm::cos(0.01)).abs() < 1e-15);
        let back = h.state_from_relative(u, du).unwrap();
        assert!((back - x).norm() < 1e-12);
        // The free-flight coefficients give the free field bit for bit (the integrator's
        // whole free-flight steps rest on it).
        let free = h.field_in(FieldMode::Free, &x, s, 0.1);
        let FreeFlight::Wires(w) = h.free_flight() else {
            panic!("the wire rig's free flight is the pendulum's")
        };
        let ff = w.eval::<AsSet>(x[1], x[0].sin_cos(), s);
        assert_eq!(ff, (free.dx[1], free.delta, free.delta_dot));
        // Undamped, every viscous choice is the thesis' field.
        assert_eq!(w.eval::<Undamped>(x[1], x[0].sin_cos(), s), ff);
    }

    #[test]
    fn damped_pendulum_field_adds_the_viscous_term() {
        // θ̈ = Eq. (3-26) − 2ζω θ̇, ω = sqrt(g/l), in the switch field, the cart-driven field
        // and the free-flight coefficients alike.
        let zeta = 0.003;
        let mut p = RigId::Wires.preset();
        p.suspension = Suspension::Wires {
            length_m: 0.075,
            damping_ratio: zeta,
        };
        let w = 2.0 * 11.0;
        let h = Hammer::<f64>::new(&p, 2e-3, w, &SwitchBands::default()).unwrap();
        let x = Vector2::new(0.01, 0.2);
        let s = 0.3;
        let omega = libm::sqrt(9.81 / 0.075);
        let undamped =
            0.89e-3 * w * w / 0.075 * libm::cos(0.01) * s - 9.81 / 0.075 * libm::sin(0.01);
        let expect = undamped - 2.0 * zeta * omega * 0.2;
        let e = h.field(&x, s, 0.1);
        assert!((e.dx[1] - expect).abs() < 1e-12, "{} {expect}", e.dx[1]);
        // The viscous term is 2ζω θ̇ = 0.0137 rad/s²: well above the tolerance.
        assert!((e.dx[1] - undamped).abs() > 1e-2);
        let cart = -0.89e-3 * w * w * s;
        let d = h.field_driven(&x, cart, 0.1);
        assert!((d.dx[1] - expect).abs() < 1e-12, "{} {expect}", d.dx[1]);
        let FreeFlight::Wires(ff) = h.free_flight() else {
            panic!("the wire rig's free flight is the pendulum's")
        };
        let free = h.field_in(FieldMode::Free, &x, s, 0.1);
        let damped = ff.eval::<Damped>(x[1], x[0].sin_cos(), s);
        assert_eq!(damped, (free.dx[1], free.delta, free.delta_dot));
        assert_eq!(ff.eval::<AsSet>(x[1], x[0].sin_cos(), s), damped);
        assert!(h.is_damped_wires());
        assert!(
            !Hammer::<f64>::new(&RigId::Wires.preset(), 2e-3, w, &SwitchBands::default())
                .unwrap()
                .is_damped_wires()
        );
    }
}

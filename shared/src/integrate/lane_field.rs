//! The lane traits: what a suspension's coefficients are to the vector lanes, in free flight
//! ([`LaneField`]: the lockstep lanes, `super::lanes`) and in contact ([`LaneContact`]: the
//! contact lanes, `super::contact_lanes`, the near-search lanes, `super::near`, and the
//! switching-event lanes, `super::switch_lanes`). They hold no lane and no simulator: every
//! kind of lane, and the stepper through the near search, builds on them.

use super::free::{FreeField, Trig};
use crate::model::hammer::{BeamFree, Body, FreeFlight, Viscous, WiresFree};
use crate::real::Real;

/// The free-flight coefficients of one suspension as a lockstep lane holds them: [`WiresFree`]
/// or [`BeamFree`] (one [`Lockstep`] per suspension).
pub(crate) trait LaneField<T: Real>: FreeField<T> + Default {
    /// This suspension's coefficients, if `ff` is of it.
    fn of(ff: &FreeFlight<T>) -> Option<Self>;
    /// The coefficients as an array (the lanes keep one array of `L` per coefficient, so that
    /// a round reads each as one vector; unused entries 0).
    fn to_coefs(&self) -> [T; COEFS];
    /// From [`LaneField::to_coefs`]'s array.
    fn from_coefs(c: [T; COEFS]) -> Self;
}

/// Coefficients a lane holds at most (the pendulum's five).
pub(super) const COEFS: usize = 5;

impl<T: Real> LaneField<T> for WiresFree<T> {
    #[inline(always)]
    fn of(ff: &FreeFlight<T>) -> Option<Self> {
        match ff {
            FreeFlight::Wires(w) => Some(*w),
            FreeFlight::Beam(_) => None,
        }
    }
    #[inline(always)]
    fn to_coefs(&self) -> [T; COEFS] {
        [
            self.length,
            self.g_over_l,
            self.damping,
            self.a0w2_over_l,
            self.gap,
        ]
    }
    #[inline(always)]
    fn from_coefs([length, g_over_l, damping, a0w2_over_l, gap]: [T; COEFS]) -> Self {
        WiresFree {
            length,
            g_over_l,
            damping,
            a0w2_over_l,
            gap,
        }
    }
}

impl<T: Real> LaneField<T> for BeamFree<T> {
    #[inline(always)]
    fn of(ff: &FreeFlight<T>) -> Option<Self> {
        match ff {
            FreeFlight::Beam(b) => Some(*b),
            FreeFlight::Wires(_) => None,
        }
    }
    #[inline(always)]
    fn to_coefs(&self) -> [T; COEFS] {
        [self.k_over_m, self.c_over_m, self.a0w2, self.gap, T::zero()]
    }
    #[inline(always)]
    fn from_coefs([k_over_m, c_over_m, a0w2, gap, _]: [T; COEFS]) -> Self {
        BeamFree {
            k_over_m,
            c_over_m,
            a0w2,
            gap,
        }
    }
}

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

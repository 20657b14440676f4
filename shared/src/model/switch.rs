//! Leine's switch model for the Filippov impact system, thesis Eq. (3-19)–(3-29) and (3-35)–(3-39).
//!
//! Two indicator functions: `h_α = δ` (distance; contact starts when the hammer reaches the
//! surface) and `h_β = F_i(δ, δ̇)` (force; contact ends when the contact force vanishes).
//! The state space splits into free flight `Γ−`, contact `Γ+` and two bands of half-width
//! `η_δ` (m) around `Σ_α` and `η_F` (N) around `Σ_β`, each with its own field:
//!
//! | region | condition | contact force used |
//! |---|---|---|
//! | `Σ_α` | `|h_α| < η_δ` and `h_β ≥ 0` | dissipative part only, Eq. (3-28)/(3-38), never negative |
//! | `Σ_β` | `|h_β| < η_F` and `h_α ≥ 0` | none (free field), Eq. (3-29)/(3-39) |
//! | `Γ+`  | `h_α > 0` and `h_β > 0` | full law, Eq. (3-27)/(3-37) |
//! | `Γ−`  | otherwise | none, Eq. (3-26)/(3-36) |
//!
//! The bands are tested in the order of the table (`Σ_α` first where both apply).
//!
//! In `Σ_α` the literal Eq. (3-28) term `c_i δ̇` turns adhesive (negative) when the hammer peels
//! slowly off a resting contact (`δ̇ < 0` while `k δ + c δ̇ ≥ 0` inside the band, a few 0.01 N);
//! The contact force never pulls (`F_i ≥ 0`, docs/model.md), so the band force is clamped at 0.

use serde::{Deserialize, Serialize};

use super::contact::LawCoeffs;
use crate::error::{ParamError, check_range};
use crate::real::Real;

/// Which field of the switch model applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Region {
    /// `Γ−`: free flight.
    Free,
    /// `Γ+`: contact.
    Contact,
    /// `Σ_α` band: arrival at the surface.
    BandAlpha,
    /// `Σ_β` band: the force vanishing.
    BandBeta,
}

impl Region {
    /// Whether a contact force can act (`Γ+` or `Σ_α`).
    pub const fn touching(self) -> bool {
        matches!(self, Region::Contact | Region::BandAlpha)
    }
}

/// Band half-widths of the switch model (the thesis' single `η ≪ 1`, split by unit).
///
/// Defaults: `η_δ = 1e-8 m` (10 nm, three orders below the ~10 µm penetration of a typical
/// impact) and `η_F = 1e-3 N` (below 1/1000 of `mg` = 2.92 N). Halving both changes the
/// wire-rig results by less than 1 % (test `halving_eta_changes_results_below_1pct` in host-sim).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwitchBands {
    /// `η_δ`: half-width of the `Σ_α` band in penetration, m.
    pub eta_delta_m: f64,
    /// `η_F`: half-width of the `Σ_β` band in contact force, N.
    pub eta_force_n: f64,
}

impl Default for SwitchBands {
    fn default() -> Self {
        SwitchBands {
            eta_delta_m: 1e-8,
            eta_force_n: 1e-3,
        }
    }
}

impl SwitchBands {
    /// Checks the band widths.
    ///
    /// # Errors
    /// [`ParamError`] naming `eta_delta_m` (allowed 1e-12..=1e-4 m) or `eta_force_n` (1e-9..=1 N).
    pub fn validate(&self) -> Result<(), ParamError> {
        check_range("eta_delta_m", self.eta_delta_m, 1e-12, 1e-4)?;
        check_range("eta_force_n", self.eta_force_n, 1e-9, 1.0)?;
        Ok(())
    }

    /// Both bands scaled by `factor` (for convergence studies).
    pub fn scaled(&self, factor: f64) -> Self {
        SwitchBands {
            eta_delta_m: self.eta_delta_m * factor,
            eta_force_n: self.eta_force_n * factor,
        }
    }
}

/// The switch model compiled to `T`: law + bands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwitchModel<T> {
    /// The contact law.
    pub law: LawCoeffs<T>,
    /// `η_δ`, m.
    pub eta_delta: T,
    /// `η_F`, N.
    pub eta_force: T,
}

impl<T: Real> SwitchModel<T> {
    /// Compiles the law and bands.
    pub fn new(law: LawCoeffs<T>, bands: &SwitchBands) -> Self {
        SwitchModel {
            law,
            eta_delta: T::from_f64(bands.eta_delta_m),
            eta_force: T::from_f64(bands.eta_force_n),
        }
    }

    /// The contact force (N, positive pushes the hammer away from the surface) and the region,
    /// for penetration `delta` (m), its rate `delta_dot` (m/s) and the approach speed of the
    /// current impact (m/s, Lankarani–Nikravesh only).
    ///
    /// Table 3.1's spring–dashpot law 10 µm into the surface, closing at 0.1 m/s:
    /// `5.5e6 · 1e-5 + 1.2e3 · 0.1` = 175 N (Eq. 3-3), in contact (`Γ+`); leaving the surface
    /// fast enough that `k δ + c δ̇ < 0`, the force is 0 and the hammer is free (`h_β < 0`).
    /// ```
    /// use shared::model::switch::SwitchModel;
    /// use shared::model::{ContactLaw, Region, SwitchBands};
    /// let sw = SwitchModel::<f64>::new(ContactLaw::identified().compile(0.1), &SwitchBands::default());
    /// let (f, region) = sw.force(1e-5, 0.1, 0.1);
    /// assert!((f - 175.0).abs() < 1e-9);
    /// assert_eq!(region, Region::Contact);
    /// assert_eq!(sw.force(1e-5, -0.1, 0.1), (0.0, Region::Free));
    /// ```
    #[inline(always)]
    pub fn force(&self, delta: T, delta_dot: T, approach_speed: T) -> (T, Region) {
        if delta <= -self.eta_delta {
            // h_α ≤ −η_δ: free flight whatever h_β (no need to evaluate the law).
            return (T::zero(), Region::Free);
        }
        let (elastic, dissipative) = self.law.parts(delta, delta_dot, approach_speed);
        let h_alpha = delta;
        let h_beta = elastic + dissipative;
        let zero = T::zero();
        if h_alpha.abs() < self.eta_delta && h_beta >= zero {
            (dissipative.max_of(zero), Region::BandAlpha)
        } else if h_beta.abs() < self.eta_force && h_alpha >= zero {
            (zero, Region::BandBeta)
        } else if h_alpha > zero && h_beta > zero {
            (h_beta, Region::Contact)
        } else {
            (zero, Region::Free)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ContactLaw;

    fn sd() -> SwitchModel<f64> {
        SwitchModel::new(
            ContactLaw::identified().compile(0.1),
            &SwitchBands::default(),
        )
    }

    #[test]
    fn regions_follow_the_indicator_functions() {
        let s = sd();
        // Far away: free.
        assert_eq!(s.force(-1e-3, 0.1, 0.1), (0.0, Region::Free));
        // Inside, pressing: full law k δ + c δ̇.
        let (f, r) = s.force(1e-5, 0.01, 0.01);
        assert_eq!(r, Region::Contact);
        assert!((f - (5.5e6 * 1e-5 + 1.2e3 * 0.01)).abs() < 1e-9);
        // Inside but separating fast: h_β < 0 → free although δ > 0 (Eq. 3-21).
        assert_eq!(s.force(1e-6, -0.1, 0.1).1, Region::Free);
        // Arrival band: damping part only (Eq. 3-28).
        let (f, r) = s.force(1e-9, 0.05, 0.05);
        assert_eq!(r, Region::BandAlpha);
        assert!((f - 1.2e3 * 0.05).abs() < 1e-9);
        // Peeling off inside the band: no adhesive force.
        assert_eq!(s.force(5e-9, -1e-5, 0.05), (0.0, Region::BandAlpha));
        // Force band: free field (Eq. 3-29).
        let delta = 1e-6;
        let dd = -5.5e6 * delta / 1.2e3 + 1e-7; // h_β ≈ 1.2e-4 N < η_F
        assert_eq!(s.force(delta, dd, 0.1), (0.0, Region::BandBeta));
    }

    #[test]
    fn bands_validate() {
        SwitchBands::default().validate().unwrap();
        let bad = SwitchBands {
            eta_delta_m: -1.0,
            eta_force_n: 1e-3,
        };
        assert!(matches!(
            bad.validate(),
            Err(ParamError::OutOfRange {
                field: "eta_delta_m",
                ..
            })
        ));
    }
}

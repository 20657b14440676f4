//! Rig parameters (SI units) and the thesis' identified presets.
//!
//! Source: thesis Table 3.1 (impact law), Table 3.2 (hammer on wires), Table 3.3 (hammer on
//! beam springs). All fields are SI; the unit is part of every field name.

use core::fmt;
use core::str::FromStr;

use serde::{Deserialize, Serialize};

use super::contact::ContactLaw;
use crate::error::{ParamError, check_half_open, check_range};

/// Standard gravity used by the thesis, m/s².
pub const GRAVITY_M_S2: f64 = 9.81;

/// Impact speeds of the rigs, m/s, at which a contact law's effective restitution is reported
/// ([`super::contact::ContactLaw::restitution`]): from drop tests (the wire rig released 3 mm
/// from the surface, the thesis' drop test, hits at 0.034 m/s; released 0.9 mm at 0.01) to
/// operation at 0.0 mm gap (0.03–0.24 m/s on the wire rig, 0.1–0.5 on the 170 mm beam,
/// `host-sim simulate`).
pub const IMPACT_SPEEDS_M_S: [f64; 4] = [0.01, 0.03, 0.1, 0.3];

/// Declares [`RigId`] from one list of its variants and their names: the enum,
/// [`RigId::ALL`], [`RigId::NAMES`] and [`RigId::name`] all come from the list, so a rig added to
/// it is in each of them (and every `match` on the rig, [`RigId::preset`] among them, fails to
/// compile until it handles the rig). The serde names stay the derive's own (kebab-case of the
/// variant: `beam170`), as before.
macro_rules! rig_ids {
    ($($(#[doc = $doc:literal])* $variant:ident => $name:literal,)+) => {
        /// The rigs of the thesis.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
        #[serde(rename_all = "kebab-case")]
        pub enum RigId {
            $($(#[doc = $doc])* $variant,)+
        }

        impl RigId {
            /// All rigs, in the order of the thesis.
            pub const ALL: [RigId; [$($name),+].len()] = [$(RigId::$variant),+];

            /// The names of [`RigId::ALL`], in its order: every text that lists the rigs (the
            /// unknown rig's errors, the console's `help`, `--rig`'s help) is built from it.
            pub const NAMES: [&'static str; [$($name),+].len()] = [$($name),+];

            /// Command-line name (`wires`, `beam-170`, ...).
            pub const fn name(self) -> &'static str {
                match self {
                    $(RigId::$variant => $name,)+
                }
            }
        }
    };
}

rig_ids! {
    /// Hammer on wires: an embarked pendulum, Eq. (3-15)–(3-18), Table 3.2.
    Wires => "wires",
    /// Hammer on beam springs, couplings distance 170 mm (4.50 Hz), Table 3.3.
    Beam170 => "beam-170",
    /// Hammer on beam springs, couplings distance 150 mm (5.25 Hz), Table 3.3.
    Beam150 => "beam-150",
    /// Hammer on beam springs, couplings distance 135 mm (6.50 Hz), Table 3.3.
    Beam135 => "beam-135",
}

impl RigId {
    /// The thesis' identified parameters for this rig, with the identified spring–dashpot law
    /// (Table 3.1).
    pub fn preset(self) -> RigParams {
        // Every beam has the same damping ratio; they differ in natural frequency.
        let beam = |natural_freq_hz| Suspension::Beam {
            natural_freq_hz,
            damping_ratio: 0.004,
        };
        let suspension = match self {
            RigId::Wires => Suspension::Wires {
                length_m: 0.075,
                damping_ratio: 0.0,
            },
            RigId::Beam170 => beam(4.50),
            RigId::Beam150 => beam(5.25),
            RigId::Beam135 => beam(6.50),
        };
        RigParams {
            mass_kg: 0.298,
            cart_mass_kg: 5.38,
            amplitude_m: 0.89e-3,
            gravity_m_s2: GRAVITY_M_S2,
            suspension,
            contact: ContactLaw::identified(),
        }
    }
}

impl fmt::Display for RigId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Error of [`RigId::from_str`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnknownRig;

impl fmt::Display for UnknownRig {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("unknown rig: expected one of ")?;
        for (i, name) in RigId::NAMES.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            f.write_str(name)?;
        }
        Ok(())
    }
}

impl FromStr for RigId {
    type Err = UnknownRig;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        RigId::ALL
            .into_iter()
            .find(|r| r.name() == s)
            .ok_or(UnknownRig)
    }
}

/// How the hammer hangs on the cart.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum Suspension {
    /// Embarked pendulum of length `l`, Eq. (3-15)–(3-18): `ω = sqrt(g/l)`, with the project's
    /// viscous damping ratio `ζ` (0 in the `wires` preset: the thesis' undamped model).
    Wires {
        /// Pendulum (wire) length `l`, m. Table 3.2: 0.075.
        length_m: f64,
        /// Viscous damping ratio `ζ` of the pendulum (pivot and air), `0 ≤ ζ < 1`: the term
        /// `−2ζω θ̇` added to Eq. (3-26) (the project's addition, docs/model.md; the thesis
        /// leaves the rig's damping out). Absent from a config: 0 (the `wires` preset). The
        /// beam rigs' identified `ζ` is 0.004 (Table 3.3); `identify free` measures it.
        #[serde(default)]
        damping_ratio: f64,
    },
    /// Base-excited oscillator, Eq. (3-30)–(3-34): `k = m ω²`, `c = 2 ζ m ω`, cubic term `k u³`.
    Beam {
        /// Identified natural frequency `ω/2π`, Hz. Table 3.3: 4.50 / 5.25 / 6.50.
        natural_freq_hz: f64,
        /// Viscous damping ratio `ζ`. Table 3.3: 0.004.
        damping_ratio: f64,
    },
}

/// Largest damping ratio accepted (exclusive): the suspension must be underdamped.
pub const MAX_DAMPING_RATIO: f64 = 1.0;

/// Everything that defines a rig, in SI units. Validated by [`RigParams::validate`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigParams {
    /// Hammer mass `m`, kg (Table 3.2: 0.298).
    pub mass_kg: f64,
    /// Cart mass `M`, kg (Table 3.2: 5.38). Informational: the cart motion is prescribed.
    pub cart_mass_kg: f64,
    /// Cart displacement amplitude `A0`, m (Table 3.2: 0.89e-3).
    pub amplitude_m: f64,
    /// Gravity `g`, m/s² (9.81).
    pub gravity_m_s2: f64,
    /// Hammer suspension.
    pub suspension: Suspension,
    /// Contact law and its parameters.
    pub contact: ContactLaw,
}

/// Largest accepted gap, m (the wire pendulum additionally needs `gap ≤ l/4`:
/// [`RigParams::max_gap_m`]).
pub const MAX_GAP_M: f64 = 0.05;

impl RigParams {
    /// The largest gap these parameters take, m: [`MAX_GAP_M`], and for the wire pendulum at
    /// most `l/4` (what `Hammer::new` accepts).
    pub fn max_gap_m(&self) -> f64 {
        match self.suspension {
            Suspension::Wires { length_m, .. } => MAX_GAP_M.min(0.25 * length_m),
            Suspension::Beam { .. } => MAX_GAP_M,
        }
    }

    /// These parameters with the contact stiffness scaled by `factor` (spring–dashpot damping
    /// by `sqrt(factor)`, which keeps its restitution): a harder or softer contact than
    /// identified (the virtual rig's drifts and hard-contact scenario).
    pub fn with_contact_scaled(&self, factor: f64) -> RigParams {
        let mut p = *self;
        p.contact = match p.contact {
            ContactLaw::SpringDashpot {
                stiffness_n_m,
                damping_n_s_m,
            } => ContactLaw::SpringDashpot {
                stiffness_n_m: stiffness_n_m * factor,
                damping_n_s_m: damping_n_s_m * libm::sqrt(factor),
            },
            ContactLaw::Hertz {
                stiffness,
                exponent,
            } => ContactLaw::Hertz {
                stiffness: stiffness * factor,
                exponent,
            },
            ContactLaw::HuntCrossley {
                stiffness,
                exponent,
                lambda_s_m,
            } => ContactLaw::HuntCrossley {
                stiffness: stiffness * factor,
                exponent,
                lambda_s_m,
            },
            ContactLaw::LankaraniNikravesh {
                stiffness,
                exponent,
                restitution,
            } => ContactLaw::LankaraniNikravesh {
                stiffness: stiffness * factor,
                exponent,
                restitution,
            },
        };
        p
    }

    /// These parameters with the natural frequency scaled by `factor` (wires: the pendulum
    /// length by `1/factor²`; beams: `natural_freq_hz`).
    pub fn with_natural_freq_scaled(&self, factor: f64) -> RigParams {
        let mut p = *self;
        p.suspension = match p.suspension {
            Suspension::Wires {
                length_m,
                damping_ratio,
            } => Suspension::Wires {
                length_m: length_m / (factor * factor),
                damping_ratio,
            },
            Suspension::Beam {
                natural_freq_hz,
                damping_ratio,
            } => Suspension::Beam {
                natural_freq_hz: natural_freq_hz * factor,
                damping_ratio,
            },
        };
        p
    }

    /// The suspension's viscous damping ratio `ζ` (wires: the project's pendulum damping, 0 in
    /// the thesis' model; beams: Table 3.3's).
    pub fn damping_ratio(&self) -> f64 {
        match self.suspension {
            Suspension::Wires { damping_ratio, .. } | Suspension::Beam { damping_ratio, .. } => {
                damping_ratio
            }
        }
    }

    /// Whether the hammer's free flight conserves area on the stroboscopic map: no damping in
    /// the suspension (`ζ = 0`, the thesis' wire rig), so that the field's divergence, its
    /// damping term alone (Eq. 3-26 and 3-34 with the project's `−2ζω θ̇`, docs/model.md), is
    /// zero and by Liouville's formula `det M = exp(∫ div f dt) = 1` along any motion that
    /// never touches the surface. Such a motion attracts nothing: its multipliers are a pair
    /// `μ, 1/μ` or a complex pair on the unit circle.
    pub fn free_flight_conservative(&self) -> bool {
        self.damping_ratio() == 0.0
    }

    /// These parameters with the suspension's damping ratio set to `zeta` (unchecked:
    /// [`RigParams::validate`] checks it).
    pub fn with_damping_ratio(&self, zeta: f64) -> RigParams {
        let mut p = *self;
        match &mut p.suspension {
            Suspension::Wires { damping_ratio, .. } | Suspension::Beam { damping_ratio, .. } => {
                *damping_ratio = zeta
            }
        }
        p
    }

    /// Checks every field against its physical range.
    ///
    /// # Errors
    /// The first offending field, as a [`ParamError`] naming it and its allowed range.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_range("mass_kg", self.mass_kg, 1e-6, 1e3)?;
        check_range("cart_mass_kg", self.cart_mass_kg, 0.0, 1e6)?;
        check_range("amplitude_m", self.amplitude_m, 1e-7, 0.1)?;
        check_range("gravity_m_s2", self.gravity_m_s2, 0.1, 100.0)?;
        match self.suspension {
            Suspension::Wires {
                length_m,
                damping_ratio,
            } => {
                check_range("suspension.wires.length_m", length_m, 1e-3, 10.0)?;
                check_half_open(
                    "suspension.wires.damping_ratio",
                    damping_ratio,
                    0.0,
                    MAX_DAMPING_RATIO,
                )?;
                // The pendulum must be able to reach the surface: A0 and gaps are ≪ l.
                if self.amplitude_m >= 0.5 * length_m {
                    return Err(ParamError::OutOfRange {
                        field: "amplitude_m",
                        value: self.amplitude_m,
                        min: 1e-7,
                        max: 0.5 * length_m,
                    });
                }
            }
            Suspension::Beam {
                natural_freq_hz,
                damping_ratio,
            } => {
                check_range(
                    "suspension.beam.natural_freq_hz",
                    natural_freq_hz,
                    0.01,
                    1e3,
                )?;
                check_range("suspension.beam.damping_ratio", damping_ratio, 0.0, 2.0)?;
            }
        }
        self.contact.validate()
    }

    /// Natural angular frequency `ω` of the free hammer, rad/s (wires: `sqrt(g/l)`; beams:
    /// `2π f_n`, Table 3.3).
    pub fn omega_n(&self) -> f64 {
        match self.suspension {
            Suspension::Wires { length_m, .. } => libm::sqrt(self.gravity_m_s2 / length_m),
            Suspension::Beam {
                natural_freq_hz, ..
            } => 2.0 * core::f64::consts::PI * natural_freq_hz,
        }
    }

    /// Natural frequency `ω/2π`, Hz.
    pub fn natural_freq_hz(&self) -> f64 {
        self.omega_n() / (2.0 * core::f64::consts::PI)
    }

    /// Hammer weight `m g`, N: the unit of the non-dimensional impact force `F_i/mg`.
    pub fn weight_n(&self) -> f64 {
        self.mass_kg * self.gravity_m_s2
    }

    /// Excitation frequency in Hz for a frequency ratio `Ω/ω`.
    pub fn freq_hz_from_ratio(&self, omega_ratio: f64) -> f64 {
        omega_ratio * self.natural_freq_hz()
    }

    /// Frequency ratio `Ω/ω` for an excitation frequency in Hz.
    pub fn ratio_from_freq_hz(&self, freq_hz: f64) -> f64 {
        freq_hz / self.natural_freq_hz()
    }

    /// Excitation periods `2π/Ω` (at `omega_ratio` Ω/ω) the suspension's free oscillation takes
    /// to shrink by the factor `by` (`0 < by < 1`): `ln(1/by) / (σ 2π/Ω)` with the envelope
    /// `e^{−σ t}` of the linearised free oscillation `ü + 2ζω u̇ + ω² u = 0` (Eq. 3-26 at small
    /// angles with the project's pendulum damping, Eq. 3-34 without its cubic term), `σ = ζω`
    /// when underdamped and `ω (ζ − sqrt(ζ² − 1))`, the slower mode, when not: how long a start
    /// takes to forget itself while it does not touch the surface.
    ///
    /// `None` without damping (`ζ = 0`: the free oscillation never decays) or for `by` or
    /// `omega_ratio` outside their ranges (`0 < by < 1`, `omega_ratio > 0`, finite).
    pub fn free_decay_periods(&self, omega_ratio: f64, by: f64) -> Option<f64> {
        let zeta = self.damping_ratio();
        if !(zeta > 0.0 && by > 0.0 && by < 1.0 && omega_ratio > 0.0 && omega_ratio.is_finite()) {
            return None;
        }
        // Per unit of ω t; the period is 2π/Ω = (2π/ω) / omega_ratio.
        let rate = if zeta <= 1.0 {
            zeta
        } else {
            zeta - libm::sqrt(zeta * zeta - 1.0)
        };
        Some(libm::log(1.0 / by) * omega_ratio / (2.0 * core::f64::consts::PI * rate))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_rig_natural_frequency_is_table_3_2() {
        // sqrt(9.81 / 0.075) / 2π = 1.8203 Hz; Table 3.2 reports 1.82 Hz.
        let f = RigId::Wires.preset().natural_freq_hz();
        assert!((f - 1.8203).abs() < 1e-3, "{f}");
    }

    /// The decay rate behind `free_decay_periods` against the slower eigenvalue of the linear
    /// oscillator's companion matrix `[[0, 1], [−1, −2ζ]]` (time in units of 1/ω), computed by
    /// nalgebra: under-, critically and overdamped (the beam accepts ζ up to 2).
    #[test]
    fn free_decay_follows_the_slower_eigenvalue_of_the_linear_oscillator() {
        let beam = RigId::Beam170.preset();
        let (ratio, by) = (1.6, 1e-6);
        for zeta in [0.004, 0.3, 0.999, 1.0, 1.25, 2.0] {
            let m = nalgebra::Matrix2::new(0.0, 1.0, -1.0, -2.0 * zeta);
            let slowest = m
                .complex_eigenvalues()
                .iter()
                .map(|l| -l.re)
                .fold(f64::INFINITY, f64::min);
            let periods = beam
                .with_damping_ratio(zeta)
                .free_decay_periods(ratio, by)
                .unwrap();
            // Periods of 2π/Ω = 2π/(ratio ω): the envelope e^{−σ ω t} shrinks by `by` over them.
            let shrink = (-slowest * periods * 2.0 * core::f64::consts::PI / ratio).exp();
            assert!(
                (shrink / by - 1.0).abs() < 1e-6,
                "ζ {zeta}: {shrink} against {by}"
            );
        }
        assert_eq!(
            beam.with_damping_ratio(0.0).free_decay_periods(ratio, by),
            None
        );
        assert_eq!(beam.free_decay_periods(0.0, by), None);
        assert_eq!(beam.free_decay_periods(ratio, 0.0), None);
    }

    #[test]
    fn beam_damping_matches_table_3_3_coefficients() {
        // Table 3.3 lists c = 0.06 / 0.08 / 0.09 N s/m: 2 ζ m ω = 0.067 / 0.079 / 0.097 to two decimals.
        // A match, not a list: a new rig stops the build here until its table value is given.
        let table_c = |rig| match rig {
            RigId::Wires => None,
            RigId::Beam170 => Some(0.06),
            RigId::Beam150 => Some(0.08),
            RigId::Beam135 => Some(0.09),
        };
        for rig in RigId::ALL {
            let Some(c_table) = table_c(rig) else {
                continue;
            };
            let p = rig.preset();
            let Suspension::Beam { damping_ratio, .. } = p.suspension else {
                panic!("beam preset")
            };
            let c = 2.0 * damping_ratio * p.mass_kg * p.omega_n();
            assert!((c - c_table).abs() < 0.01, "{rig}: c = {c}");
        }
    }

    #[test]
    fn unknown_rig_lists_every_rig() {
        let names: std::vec::Vec<&str> = RigId::ALL.iter().map(|r| r.name()).collect();
        assert_eq!(RigId::NAMES.to_vec(), names);
        assert_eq!(
            "beam-200".parse::<RigId>().unwrap_err().to_string(),
            std::format!("unknown rig: expected one of {}", names.join(", "))
        );
    }

    #[test]
    fn presets_validate_and_bad_values_are_named() {
        for r in RigId::ALL {
            r.preset().validate().unwrap();
            assert_eq!(r.name().parse::<RigId>(), Ok(r));
        }
        let mut p = RigId::Wires.preset();
        p.mass_kg = -1.0;
        match p.validate() {
            Err(ParamError::OutOfRange { field, .. }) => assert_eq!(field, "mass_kg"),
            e => panic!("{e:?}"),
        }
        p.mass_kg = f64::NAN;
        assert_eq!(
            p.validate(),
            Err(ParamError::NotFinite { field: "mass_kg" })
        );
        assert!("beam-171".parse::<RigId>().is_err());
    }

    #[test]
    fn pendulum_damping_ratio_is_checked_in_0_to_1() {
        let p = RigId::Wires.preset();
        assert_eq!(p.damping_ratio(), 0.0);
        for ok in [0.0, 0.003, 0.999] {
            p.with_damping_ratio(ok).validate().unwrap();
        }
        let field = "suspension.wires.damping_ratio";
        for bad in [1.0, -0.1, 1.5] {
            assert_eq!(
                p.with_damping_ratio(bad).validate(),
                Err(ParamError::OutOfHalfOpenRange {
                    field,
                    value: bad,
                    min: 0.0,
                    max: 1.0
                })
            );
        }
        assert_eq!(
            p.with_damping_ratio(f64::NAN).validate(),
            Err(ParamError::NotFinite { field })
        );
        let text = std::format!("{}", p.with_damping_ratio(1.0).validate().unwrap_err());
        assert_eq!(
            text,
            "`suspension.wires.damping_ratio` = 1 is out of range: allowed 0 ≤ \
             suspension.wires.damping_ratio < 1"
        );
        // The beams keep their own range, and the setter reaches either suspension.
        let b = RigId::Beam170.preset().with_damping_ratio(0.01);
        assert_eq!(b.damping_ratio(), 0.01);
    }

    #[test]
    fn scaled_parameters_keep_what_they_should() {
        use crate::model::contact::spring_dashpot_restitution;
        for rig in RigId::ALL {
            let p = rig.preset();
            let q = p.with_natural_freq_scaled(1.05);
            assert!((q.natural_freq_hz() / p.natural_freq_hz() - 1.05).abs() < 1e-12);
            let h = p.with_contact_scaled(4.0);
            let (
                ContactLaw::SpringDashpot {
                    stiffness_n_m: k0,
                    damping_n_s_m: c0,
                },
                ContactLaw::SpringDashpot {
                    stiffness_n_m: k1,
                    damping_n_s_m: c1,
                },
            ) = (p.contact, h.contact)
            else {
                panic!("the presets are spring-dashpot")
            };
            assert_eq!(k1, 4.0 * k0);
            // The restitution (the contact's damping ratio) does not change.
            let (e0, t0) = spring_dashpot_restitution(k0, c0, p.mass_kg).unwrap();
            let (e1, t1) = spring_dashpot_restitution(k1, c1, p.mass_kg).unwrap();
            assert!((e0 - e1).abs() < 1e-12, "{e0} {e1}");
            // … while the contact lasts half as long (ω of the contact doubled).
            assert!((t1 / t0 - 0.5).abs() < 1e-12, "{t0} {t1}");
        }
    }
}

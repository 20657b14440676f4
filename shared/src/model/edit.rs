//! Editing a rig model one field at a time (the console's `model <field> <value>`, `model law
//! <name>`, `model suspension <kind>`): the fields of [`RigParams`] by their TOML leaf names, and
//! the edits that keep a model whole. Every edit is validated as the desktop's TOML is
//! ([`RigParams::validate`]): a refused edit names the field and its range and changes nothing.

use core::fmt;
use core::str::FromStr;

use super::contact::{ContactLaw, ContactLawKind};
use super::rig::{RigParams, Suspension};
use crate::error::ParamError;

/// How the hammer hangs: the kind of [`Suspension`], without its parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SuspensionKind {
    /// [`Suspension::Wires`]: the embarked pendulum.
    Wires,
    /// [`Suspension::Beam`]: the base-excited oscillator.
    Beam,
}

impl SuspensionKind {
    /// Every kind.
    pub const ALL: [SuspensionKind; 2] = [SuspensionKind::Wires, SuspensionKind::Beam];

    /// Its name (the TOML table's: `[rig.suspension.wires]`).
    pub const fn name(self) -> &'static str {
        match self {
            SuspensionKind::Wires => "wires",
            SuspensionKind::Beam => "beam",
        }
    }

    /// The kind of `s`.
    pub const fn of(s: &Suspension) -> SuspensionKind {
        match s {
            Suspension::Wires { .. } => SuspensionKind::Wires,
            Suspension::Beam { .. } => SuspensionKind::Beam,
        }
    }
}

impl fmt::Display for SuspensionKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for SuspensionKind {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        SuspensionKind::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s))
            .ok_or(())
    }
}

/// A number of a rig model, by its TOML leaf name. Which of them a model has depends on its
/// suspension and contact law ([`RigParams::value`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelField {
    /// [`RigParams::mass_kg`].
    MassKg,
    /// [`RigParams::cart_mass_kg`].
    CartMassKg,
    /// [`RigParams::amplitude_m`].
    AmplitudeM,
    /// [`RigParams::gravity_m_s2`].
    GravityMS2,
    /// The pendulum's length (wires).
    LengthM,
    /// The natural frequency (beam springs).
    NaturalFreqHz,
    /// The suspension's damping ratio (both).
    DampingRatio,
    /// The spring–dashpot law's stiffness.
    StiffnessNM,
    /// The spring–dashpot law's damping.
    DampingNSM,
    /// A power law's stiffness `k_i` (N/m^n).
    Stiffness,
    /// A power law's exponent `n`.
    Exponent,
    /// Hunt–Crossley's `λ_i`.
    LambdaSM,
    /// Lankarani–Nikravesh's `e`.
    Restitution,
}

impl ModelField {
    /// Every field, in the order a model is shown.
    pub const ALL: [ModelField; 13] = [
        ModelField::MassKg,
        ModelField::CartMassKg,
        ModelField::AmplitudeM,
        ModelField::GravityMS2,
        ModelField::LengthM,
        ModelField::NaturalFreqHz,
        ModelField::DampingRatio,
        ModelField::StiffnessNM,
        ModelField::DampingNSM,
        ModelField::Stiffness,
        ModelField::Exponent,
        ModelField::LambdaSM,
        ModelField::Restitution,
    ];

    /// The TOML leaf name (`mass_kg`, `stiffness_n_m`, …).
    pub const fn name(self) -> &'static str {
        match self {
            ModelField::MassKg => "mass_kg",
            ModelField::CartMassKg => "cart_mass_kg",
            ModelField::AmplitudeM => "amplitude_m",
            ModelField::GravityMS2 => "gravity_m_s2",
            ModelField::LengthM => "length_m",
            ModelField::NaturalFreqHz => "natural_freq_hz",
            ModelField::DampingRatio => "damping_ratio",
            ModelField::StiffnessNM => "stiffness_n_m",
            ModelField::DampingNSM => "damping_n_s_m",
            ModelField::Stiffness => "stiffness",
            ModelField::Exponent => "exponent",
            ModelField::LambdaSM => "lambda_s_m",
            ModelField::Restitution => "restitution",
        }
    }
}

impl fmt::Display for ModelField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ModelField {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        ModelField::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s))
            .ok_or(())
    }
}

/// One change to a rig model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ModelEdit {
    /// A field to a value.
    Set(ModelField, f64),
    /// Another contact law, with its default coefficients ([`ContactLaw::preset`]).
    Law(ContactLawKind),
    /// Another suspension with the same natural frequency and damping ratio (wires: the
    /// pendulum's length `g/ω²`).
    Suspension(SuspensionKind),
}

/// Why an edit was refused (the model unchanged).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EditError {
    /// The field belongs to another law or suspension than the model's: its `law_or_suspension`
    /// (`spring-dashpot`, `wires`, …) has other fields.
    NotOfThisModel {
        /// The field.
        field: ModelField,
        /// The model's law or suspension that lacks it.
        model_has: &'static str,
    },
    /// The edited model fails validation (the field and its range named).
    Invalid(ParamError),
}

impl fmt::Display for EditError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EditError::NotOfThisModel { field, model_has } => write!(
                f,
                "`{field}` is not a field of the {model_has} model (change the law or suspension first)"
            ),
            EditError::Invalid(e) => write!(f, "{e}"),
        }
    }
}

impl RigParams {
    /// The value of `field`, if this model has it (its suspension's and its contact law's
    /// fields, and the four common ones).
    pub fn value(&self, field: ModelField) -> Option<f64> {
        let common = match field {
            ModelField::MassKg => Some(self.mass_kg),
            ModelField::CartMassKg => Some(self.cart_mass_kg),
            ModelField::AmplitudeM => Some(self.amplitude_m),
            ModelField::GravityMS2 => Some(self.gravity_m_s2),
            _ => None,
        };
        common
            .or_else(|| suspension_value(&self.suspension, field))
            .or_else(|| law_value(&self.contact, field))
    }

    /// This model with `edit` made, validated.
    ///
    /// # Errors
    /// [`EditError::NotOfThisModel`]: the field belongs to another law or suspension;
    /// [`EditError::Invalid`]: the result fails [`RigParams::validate`] (the field and range).
    pub fn edited(&self, edit: ModelEdit) -> Result<RigParams, EditError> {
        let mut p = *self;
        match edit {
            ModelEdit::Law(kind) => p.contact = ContactLaw::preset(kind),
            ModelEdit::Suspension(kind) => {
                let (omega, zeta) = (self.omega_n(), self.damping_ratio());
                p.suspension = match kind {
                    SuspensionKind::Wires => Suspension::Wires {
                        length_m: self.gravity_m_s2 / (omega * omega),
                        damping_ratio: zeta,
                    },
                    SuspensionKind::Beam => Suspension::Beam {
                        natural_freq_hz: self.natural_freq_hz(),
                        damping_ratio: zeta,
                    },
                };
            }
            ModelEdit::Set(field, v) => {
                if p.value(field).is_none() {
                    return Err(EditError::NotOfThisModel {
                        field,
                        model_has: if is_suspension_field(field) {
                            SuspensionKind::of(&p.suspension).name()
                        } else {
                            p.contact.kind().name()
                        },
                    });
                }
                set(&mut p, field, v);
            }
        }
        p.validate().map_err(EditError::Invalid)?;
        Ok(p)
    }
}

fn is_suspension_field(field: ModelField) -> bool {
    matches!(
        field,
        ModelField::LengthM | ModelField::NaturalFreqHz | ModelField::DampingRatio
    )
}

fn suspension_value(s: &Suspension, field: ModelField) -> Option<f64> {
    match (*s, field) {
        (Suspension::Wires { length_m, .. }, ModelField::LengthM) => Some(length_m),
        (
            Suspension::Beam {
                natural_freq_hz, ..
            },
            ModelField::NaturalFreqHz,
        ) => Some(natural_freq_hz),
        (
            Suspension::Wires { damping_ratio, .. } | Suspension::Beam { damping_ratio, .. },
            ModelField::DampingRatio,
        ) => Some(damping_ratio),
        _ => None,
    }
}

fn law_value(law: &ContactLaw, field: ModelField) -> Option<f64> {
    match (*law, field) {
        (ContactLaw::SpringDashpot { stiffness_n_m, .. }, ModelField::StiffnessNM) => {
            Some(stiffness_n_m)
        }
        (ContactLaw::SpringDashpot { damping_n_s_m, .. }, ModelField::DampingNSM) => {
            Some(damping_n_s_m)
        }
        (
            ContactLaw::Hertz { stiffness, .. }
            | ContactLaw::HuntCrossley { stiffness, .. }
            | ContactLaw::LankaraniNikravesh { stiffness, .. },
            ModelField::Stiffness,
        ) => Some(stiffness),
        (
            ContactLaw::Hertz { exponent, .. }
            | ContactLaw::HuntCrossley { exponent, .. }
            | ContactLaw::LankaraniNikravesh { exponent, .. },
            ModelField::Exponent,
        ) => Some(exponent),
        (ContactLaw::HuntCrossley { lambda_s_m, .. }, ModelField::LambdaSM) => Some(lambda_s_m),
        (ContactLaw::LankaraniNikravesh { restitution, .. }, ModelField::Restitution) => {
            Some(restitution)
        }
        _ => None,
    }
}

/// Sets `field` (one the model has: [`RigParams::value`] is `Some`).
fn set(p: &mut RigParams, field: ModelField, v: f64) {
    let slot: Option<&mut f64> = match field {
        ModelField::MassKg => Some(&mut p.mass_kg),
        ModelField::CartMassKg => Some(&mut p.cart_mass_kg),
        ModelField::AmplitudeM => Some(&mut p.amplitude_m),
        ModelField::GravityMS2 => Some(&mut p.gravity_m_s2),
        ModelField::LengthM => match &mut p.suspension {
            Suspension::Wires { length_m, .. } => Some(length_m),
            Suspension::Beam { .. } => None,
        },
        ModelField::NaturalFreqHz => match &mut p.suspension {
            Suspension::Beam {
                natural_freq_hz, ..
            } => Some(natural_freq_hz),
            Suspension::Wires { .. } => None,
        },
        ModelField::DampingRatio => match &mut p.suspension {
            Suspension::Wires { damping_ratio, .. } | Suspension::Beam { damping_ratio, .. } => {
                Some(damping_ratio)
            }
        },
        ModelField::StiffnessNM => match &mut p.contact {
            ContactLaw::SpringDashpot { stiffness_n_m, .. } => Some(stiffness_n_m),
            _ => None,
        },
        ModelField::DampingNSM => match &mut p.contact {
            ContactLaw::SpringDashpot { damping_n_s_m, .. } => Some(damping_n_s_m),
            _ => None,
        },
        ModelField::Stiffness => match &mut p.contact {
            ContactLaw::Hertz { stiffness, .. }
            | ContactLaw::HuntCrossley { stiffness, .. }
            | ContactLaw::LankaraniNikravesh { stiffness, .. } => Some(stiffness),
            ContactLaw::SpringDashpot { .. } => None,
        },
        ModelField::Exponent => match &mut p.contact {
            ContactLaw::Hertz { exponent, .. }
            | ContactLaw::HuntCrossley { exponent, .. }
            | ContactLaw::LankaraniNikravesh { exponent, .. } => Some(exponent),
            ContactLaw::SpringDashpot { .. } => None,
        },
        ModelField::LambdaSM => match &mut p.contact {
            ContactLaw::HuntCrossley { lambda_s_m, .. } => Some(lambda_s_m),
            _ => None,
        },
        ModelField::Restitution => match &mut p.contact {
            ContactLaw::LankaraniNikravesh { restitution, .. } => Some(restitution),
            _ => None,
        },
    };
    if let Some(slot) = slot {
        *slot = v;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::RigId;

    #[test]
    fn every_field_a_model_has_is_set_and_read_back_and_others_are_refused() {
        for rig in RigId::ALL {
            for kind in ContactLawKind::ALL {
                let p = rig.preset().edited(ModelEdit::Law(kind)).unwrap();
                assert_eq!(p.contact, ContactLaw::preset(kind));
                for field in ModelField::ALL {
                    match p.value(field) {
                        Some(v) => {
                            // A value within every range: the field's own, nudged by 1 ppm.
                            let w = v * (1.0 + 1e-6) + if v == 0.0 { 1e-4 } else { 0.0 };
                            let q = p.edited(ModelEdit::Set(field, w)).unwrap();
                            assert_eq!(q.value(field), Some(w), "{rig} {kind} {field}");
                            // Nothing else moved.
                            for other in ModelField::ALL.into_iter().filter(|f| *f != field) {
                                assert_eq!(q.value(other), p.value(other), "{field} moved {other}");
                            }
                            // NaN and a negative value are refused, naming the field.
                            let e = p.edited(ModelEdit::Set(field, f64::NAN)).unwrap_err();
                            assert!(
                                matches!(e, EditError::Invalid(pe) if pe.field().ends_with(field.name())),
                                "{field}: {e}"
                            );
                        }
                        None => assert!(
                            matches!(
                                p.edited(ModelEdit::Set(field, 1.0)),
                                Err(EditError::NotOfThisModel { field: f, .. }) if f == field
                            ),
                            "{rig} {kind} {field}"
                        ),
                    }
                }
            }
        }
    }

    #[test]
    fn a_new_suspension_keeps_the_natural_frequency_and_damping() {
        let beam = RigId::Beam170.preset();
        let wires = beam
            .edited(ModelEdit::Suspension(SuspensionKind::Wires))
            .unwrap();
        assert!((wires.natural_freq_hz() - 4.50).abs() < 1e-12);
        assert_eq!(wires.damping_ratio(), 0.004);
        let back = wires
            .edited(ModelEdit::Suspension(SuspensionKind::Beam))
            .unwrap();
        assert!((back.natural_freq_hz() - 4.50).abs() < 1e-12);
        // The wire rig's pendulum of 0.075 m: ω = sqrt(9.81 / 0.075).
        let w = RigId::Wires.preset();
        let b = w
            .edited(ModelEdit::Suspension(SuspensionKind::Beam))
            .unwrap();
        assert!(
            (b.natural_freq_hz() - (9.81f64 / 0.075).sqrt() / (2.0 * core::f64::consts::PI)).abs()
                < 1e-12
        );
    }
}

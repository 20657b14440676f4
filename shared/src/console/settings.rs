//! The settings on the console: the model line ([`ModelView`]), the calibration line
//! ([`CalibView`]), the store line ([`StoreView`]) and the refusals of edits, saves and reverts
//! ([`SettingsRefusal`], [`StoreRefusal`]), each a type with its text and its reading. Every
//! number is written [`Exact`]: what the desktop reads back is the board's value bit for bit,
//! and the model line carries its hash, checked against its fields as it is read.
//!
//! ```text
//! model of=active rig=stored rig_hash=5c1d2a77 mass_kg=0.31 cart_mass_kg=5.38 amplitude_m=0.00089 gravity_m_s2=9.81 suspension=wires length_m=0.075 damping_ratio=0.01 law=hunt-crossley stiffness=210000000 exponent=1.6 lambda_s_m=0.6
//! calib of=active volts_per_n=0.0098 offset_v=0.2 adc_full_scale_v=3.3 dac_full_scale_v=3.3 cart_mm_per_v=1 freq_min_hz=1 freq_max_hz=30 amplitude_max_mm=1.5 freq_slew_hz_per_s=0.5 amp_ramp_mm_per_s=0.5 abort_ramp_mm_per_s=4 force_limit_n=280
//! store state=ok saves=3 rig_hash=5c1d2a77
//! error: `mass_kg` = -1 is out of range: allowed 0.000001 ..= 1000
//! ```

use core::fmt;
use core::str::FromStr;

use super::decimal::{Exact, parse_exact};
use super::fields::{Fields, WireError};
use super::token::Token;
use crate::control::{CalibField, Calibration, ControllerConfig, ModelSource, SettingsError};
use crate::error::ParamError;
use crate::model::{
    ContactLaw, ContactLawKind, EditError, ModelField, RigParams, Suspension, SuspensionKind,
    params_hash,
};
use crate::store::{SaveError, StoreState};

/// Which model a model line shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelOf {
    /// The active one, and where it came from.
    Active(ModelSource),
    /// The draft (`draft begin`).
    Draft,
}

/// The model line: `model of=… [rig=…] rig_hash=… <fields>`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelView {
    /// Active or draft.
    pub of: ModelOf,
    /// The model.
    pub params: RigParams,
}

/// The calibration line: `calib of=<active|draft> <fields>`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibView {
    /// The draft's (`true`) or the active one.
    pub draft: bool,
    /// The calibration.
    pub calibration: Calibration,
}

/// The store line: `store state=… saves=… rig_hash=<hex|->`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StoreView {
    /// What the store held at its last load, or `ok` after a save.
    pub state: StoreState,
    /// The number of the last save (0: none).
    pub saves: u32,
    /// The stored model's hash, when readable.
    pub hash: Option<u32>,
}

fn of_token(of: ModelOf) -> &'static str {
    match of {
        ModelOf::Active(_) => "active",
        ModelOf::Draft => "draft",
    }
}

impl fmt::Display for ModelView {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "model of={}", of_token(self.of))?;
        if let ModelOf::Active(source) = self.of {
            write!(f, " rig={}", source.token())?;
        }
        write!(f, " rig_hash={:08x}", params_hash(&self.params))?;
        let p = &self.params;
        let show = |f: &mut fmt::Formatter<'_>, field: ModelField| -> fmt::Result {
            match p.value(field) {
                Some(v) => write!(f, " {field}={}", Exact::f64(v)),
                None => Ok(()),
            }
        };
        for field in [
            ModelField::MassKg,
            ModelField::CartMassKg,
            ModelField::AmplitudeM,
            ModelField::GravityMS2,
        ] {
            show(f, field)?;
        }
        write!(f, " suspension={}", SuspensionKind::of(&p.suspension))?;
        for field in [
            ModelField::LengthM,
            ModelField::NaturalFreqHz,
            ModelField::DampingRatio,
        ] {
            show(f, field)?;
        }
        write!(f, " law={}", p.contact.kind())?;
        for field in [
            ModelField::StiffnessNM,
            ModelField::DampingNSM,
            ModelField::Stiffness,
            ModelField::Exponent,
            ModelField::LambdaSM,
            ModelField::Restitution,
        ] {
            show(f, field)?;
        }
        Ok(())
    }
}

/// The next field `key` as an exact number.
fn exact(w: &mut Fields<'_>, key: &'static str) -> Result<f64, WireError> {
    w.with(key, parse_exact)
}

impl FromStr for ModelView {
    type Err = WireError;

    /// Reads a model line; the model must pass [`RigParams::validate`] and hash to the line's
    /// `rig_hash`.
    fn from_str(s: &str) -> Result<Self, WireError> {
        let mut w = Fields::after(s, "model ")?;
        let of = match w.raw("of")? {
            "active" => ModelOf::Active(w.token("rig")?),
            "draft" => ModelOf::Draft,
            _ => return Err(WireError::Bad("of")),
        };
        let hash = w.with("rig_hash", |v| {
            (v.len() == 8).then(|| u32::from_str_radix(v, 16).ok())?
        })?;
        let mass_kg = exact(&mut w, "mass_kg")?;
        let cart_mass_kg = exact(&mut w, "cart_mass_kg")?;
        let amplitude_m = exact(&mut w, "amplitude_m")?;
        let gravity_m_s2 = exact(&mut w, "gravity_m_s2")?;
        let suspension = match w.with("suspension", |v| v.parse::<SuspensionKind>().ok())? {
            SuspensionKind::Wires => Suspension::Wires {
                length_m: exact(&mut w, "length_m")?,
                damping_ratio: exact(&mut w, "damping_ratio")?,
            },
            SuspensionKind::Beam => Suspension::Beam {
                natural_freq_hz: exact(&mut w, "natural_freq_hz")?,
                damping_ratio: exact(&mut w, "damping_ratio")?,
            },
        };
        let contact = match w.with("law", |v| v.parse::<ContactLawKind>().ok())? {
            ContactLawKind::SpringDashpot => ContactLaw::SpringDashpot {
                stiffness_n_m: exact(&mut w, "stiffness_n_m")?,
                damping_n_s_m: exact(&mut w, "damping_n_s_m")?,
            },
            ContactLawKind::Hertz => ContactLaw::Hertz {
                stiffness: exact(&mut w, "stiffness")?,
                exponent: exact(&mut w, "exponent")?,
            },
            ContactLawKind::HuntCrossley => ContactLaw::HuntCrossley {
                stiffness: exact(&mut w, "stiffness")?,
                exponent: exact(&mut w, "exponent")?,
                lambda_s_m: exact(&mut w, "lambda_s_m")?,
            },
            ContactLawKind::LankaraniNikravesh => ContactLaw::LankaraniNikravesh {
                stiffness: exact(&mut w, "stiffness")?,
                exponent: exact(&mut w, "exponent")?,
                restitution: exact(&mut w, "restitution")?,
            },
        };
        w.end()?;
        let params = RigParams {
            mass_kg,
            cart_mass_kg,
            amplitude_m,
            gravity_m_s2,
            suspension,
            contact,
        };
        params
            .validate()
            .map_err(|e| WireError::Bad(leaf(e.field())))?;
        if params_hash(&params) != hash {
            return Err(WireError::Mismatch("rig_hash"));
        }
        Ok(ModelView { of, params })
    }
}

/// A dotted field name's last part (`contact.hertz.stiffness` → `stiffness`).
fn leaf(field: &'static str) -> &'static str {
    field.rsplit('.').next().unwrap_or(field)
}

impl fmt::Display for CalibView {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "calib of={}",
            if self.draft { "draft" } else { "active" }
        )?;
        for field in CalibField::ALL {
            write!(f, " {field}={}", Exact::f32(self.calibration.value(field)))?;
        }
        Ok(())
    }
}

impl FromStr for CalibView {
    type Err = WireError;

    /// Reads a calibration line; it must pass the controller's checks with the firmware's
    /// other settings ([`Calibration::applied_to`] the default configuration).
    fn from_str(s: &str) -> Result<Self, WireError> {
        let mut w = Fields::after(s, "calib ")?;
        let draft = match w.raw("of")? {
            "active" => false,
            "draft" => true,
            _ => return Err(WireError::Bad("of")),
        };
        let mut calibration = Calibration::default();
        for field in CalibField::ALL {
            let v = w.with(field.name(), |v| parse_exact(v).map(|x| x as f32))?;
            calibration = calibration.with(field, v);
        }
        w.end()?;
        calibration
            .applied_to(&ControllerConfig::default())
            .map_err(|e| WireError::Bad(e.field()))?;
        Ok(CalibView { draft, calibration })
    }
}

impl fmt::Display for StoreView {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "store state={} saves={} rig_hash=",
            self.state.token(),
            self.saves
        )?;
        match self.hash {
            Some(h) => write!(f, "{h:08x}"),
            None => f.write_str("-"),
        }
    }
}

impl FromStr for StoreView {
    type Err = WireError;
    fn from_str(s: &str) -> Result<Self, WireError> {
        let mut w = Fields::after(s, "store ")?;
        let v = StoreView {
            state: w.token("state")?,
            saves: w.int("saves")?,
            hash: w.with("rig_hash", |v| match v {
                "-" => Some(None),
                h if h.len() == 8 => u32::from_str_radix(h, 16).ok().map(Some),
                _ => None,
            })?,
        };
        w.end()?;
        Ok(v)
    }
}

/// Every field name a refused edit or load can name: the model's (as [`RigParams::validate`]
/// names them), the gap, and the controller configuration's (a calibration is checked with
/// it whole).
const FIELD_NAMES: [&str; 43] = [
    "mass_kg",
    "cart_mass_kg",
    "amplitude_m",
    "gravity_m_s2",
    "suspension.wires.length_m",
    "suspension.wires.damping_ratio",
    "suspension.beam.natural_freq_hz",
    "suspension.beam.damping_ratio",
    "contact.hertz.stiffness",
    "contact.hertz.exponent",
    "contact.spring-dashpot.stiffness_n_m",
    "contact.spring-dashpot.damping_n_s_m",
    "contact.hunt-crossley.stiffness",
    "contact.hunt-crossley.exponent",
    "contact.hunt-crossley.lambda_s_m",
    "contact.lankarani-nikravesh.stiffness",
    "contact.lankarani-nikravesh.exponent",
    "contact.lankarani-nikravesh.restitution",
    "gap_mm",
    "dac_full_scale_v",
    "cart_mm_per_v",
    "volts_per_n",
    "offset_v",
    "adc_full_scale_v",
    "freq_min_hz",
    "freq_max_hz",
    "amplitude_max_mm",
    "freq_slew_hz_per_s",
    "amp_ramp_mm_per_s",
    "abort_ramp_mm_per_s",
    "force_limit_n",
    "threshold_n",
    "hysteresis_n",
    "refractory_s",
    "step_hz",
    "min_step_hz",
    "settle_cycles",
    "measure_cycles",
    "improve_rel",
    "no_signal_s",
    "rail_margin_codes",
    "rail_s",
    "deadline_us",
];

/// What is wrong with a field's value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FieldProblem {
    /// NaN or infinite.
    NotFinite,
    /// Outside `[min, max]`.
    OutOfRange {
        /// The value.
        value: f64,
        /// Smallest allowed.
        min: f64,
        /// Largest allowed.
        max: f64,
    },
    /// Outside `[min, max)`.
    OutOfHalfOpen {
        /// The value.
        value: f64,
        /// Smallest allowed.
        min: f64,
        /// The bound it must stay below.
        max: f64,
    },
}

/// Why a settings change was refused (nothing changed); the refusals of state (not idle, a
/// fault latched) are the commands' ([`super::AnswerError::Command`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SettingsRefusal {
    /// The field belongs to another law or suspension than the model's.
    NotOfThisModel {
        /// The field.
        field: ModelField,
        /// The model's law or suspension (its name), which lacks it.
        model_has: &'static str,
    },
    /// A field's value refused (a model field by its dotted name, a calibration field, the gap).
    Invalid {
        /// The field.
        field: &'static str,
        /// What is wrong.
        problem: FieldProblem,
    },
    /// `draft apply` or `draft discard` without `draft begin`.
    NoDraft,
}

impl SettingsRefusal {
    /// The refusal of a parameter error.
    pub fn of_param(e: ParamError) -> SettingsRefusal {
        let (field, problem) = match e {
            ParamError::NotFinite { field } => (field, FieldProblem::NotFinite),
            ParamError::OutOfRange {
                field,
                value,
                min,
                max,
            } => (field, FieldProblem::OutOfRange { value, min, max }),
            ParamError::OutOfHalfOpenRange {
                field,
                value,
                min,
                max,
            } => (field, FieldProblem::OutOfHalfOpen { value, min, max }),
            // Counts and ranges are not settings: said as a range of the count.
            ParamError::CountOutOfRange {
                field,
                value,
                min,
                max,
            } => (
                field,
                FieldProblem::OutOfRange {
                    value: f64::from(value),
                    min: f64::from(min),
                    max: f64::from(max),
                },
            ),
            ParamError::BadRange { field, .. } => (field, FieldProblem::NotFinite),
        };
        SettingsRefusal::Invalid { field, problem }
    }

    /// The refusal of a [`SettingsError`] that is not a command's (`None` for those: they are
    /// answered as the commands' refusals).
    pub fn of(e: SettingsError) -> Option<SettingsRefusal> {
        match e {
            SettingsError::Command(_) => None,
            SettingsError::Model(EditError::NotOfThisModel { field, model_has }) => {
                Some(SettingsRefusal::NotOfThisModel { field, model_has })
            }
            SettingsError::Model(EditError::Invalid(p))
            | SettingsError::Calibration(p)
            | SettingsError::Invalid(p) => Some(SettingsRefusal::of_param(p)),
            SettingsError::NoDraft => Some(SettingsRefusal::NoDraft),
        }
    }
}

const NO_DRAFT: &str = "no draft open: `draft begin` first";
const NOT_OF: (&str, &str, &str) = (
    "` is not a field of the ",
    " model (change the law or suspension first)",
    "`",
);
const NOT_FINITE: &str = "` must be a finite number";
const OUT_OF: (&str, &str, &str) = ("` = ", " is out of range: allowed ", " ..= ");
const HALF_OPEN: (&str, &str) = (" ≤ value < ", "");

impl fmt::Display for SettingsRefusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            SettingsRefusal::NoDraft => f.write_str(NO_DRAFT),
            SettingsRefusal::NotOfThisModel { field, model_has } => {
                write!(f, "{}{field}{}{model_has}{}", NOT_OF.2, NOT_OF.0, NOT_OF.1)
            }
            SettingsRefusal::Invalid { field, problem } => match problem {
                FieldProblem::NotFinite => write!(f, "`{field}{NOT_FINITE}"),
                FieldProblem::OutOfRange { value, min, max } => write!(
                    f,
                    "`{field}{}{}{}{}{}{}",
                    OUT_OF.0,
                    Exact::f64(value),
                    OUT_OF.1,
                    Exact::f64(min),
                    OUT_OF.2,
                    Exact::f64(max)
                ),
                FieldProblem::OutOfHalfOpen { value, min, max } => write!(
                    f,
                    "`{field}{}{}{}{}{}{}{}",
                    OUT_OF.0,
                    Exact::f64(value),
                    OUT_OF.1,
                    Exact::f64(min),
                    HALF_OPEN.0,
                    Exact::f64(max),
                    HALF_OPEN.1
                ),
            },
        }
    }
}

fn field_named(name: &str) -> Option<&'static str> {
    FIELD_NAMES.into_iter().find(|n| *n == name)
}

fn owner_named(name: &str) -> Option<&'static str> {
    ContactLawKind::ALL
        .into_iter()
        .map(ContactLawKind::name)
        .chain(SuspensionKind::ALL.into_iter().map(SuspensionKind::name))
        .find(|n| *n == name)
}

impl FromStr for SettingsRefusal {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        if s == NO_DRAFT {
            return Ok(SettingsRefusal::NoDraft);
        }
        let body = s.strip_prefix('`').ok_or(())?;
        if let Some((field, rest)) = body.split_once(NOT_OF.0) {
            let owner = rest.strip_suffix(NOT_OF.1).ok_or(())?;
            return Ok(SettingsRefusal::NotOfThisModel {
                field: field.parse()?,
                model_has: owner_named(owner).ok_or(())?,
            });
        }
        if let Some(field) = body.strip_suffix(NOT_FINITE) {
            return Ok(SettingsRefusal::Invalid {
                field: field_named(field).ok_or(())?,
                problem: FieldProblem::NotFinite,
            });
        }
        let (field, rest) = body.split_once(OUT_OF.0).ok_or(())?;
        let field = field_named(field).ok_or(())?;
        let (value, range) = rest.split_once(OUT_OF.1).ok_or(())?;
        let value = parse_exact(value).ok_or(())?;
        let problem = if let Some((min, max)) = range.split_once(OUT_OF.2) {
            FieldProblem::OutOfRange {
                value,
                min: parse_exact(min).ok_or(())?,
                max: parse_exact(max).ok_or(())?,
            }
        } else {
            let (min, max) = range.split_once(HALF_OPEN.0).ok_or(())?;
            FieldProblem::OutOfHalfOpen {
                value,
                min: parse_exact(min).ok_or(())?,
                max: parse_exact(max).ok_or(())?,
            }
        };
        Ok(SettingsRefusal::Invalid { field, problem })
    }
}

/// Why a `save`, `revert` or `reset` was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StoreRefusal {
    /// The save failed; the store keeps its last good save.
    SaveFailed(SaveError),
    /// `revert` with nothing usable stored (the store's state says why).
    NothingToRevert(StoreState),
}

const SAVE_FAILED: (&str, &str) = ("save failed (", "): the store keeps its last good save");
const NOTHING: (&str, &str) = ("nothing to revert to: the store is ", "");

fn save_error_name(e: SaveError) -> &'static str {
    match e {
        SaveError::Flash => "flash error",
        SaveError::Storage => "store error",
        SaveError::TooBig => "record too big",
    }
}

impl fmt::Display for StoreRefusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StoreRefusal::SaveFailed(e) => {
                write!(
                    f,
                    "{}{}{}",
                    SAVE_FAILED.0,
                    save_error_name(*e),
                    SAVE_FAILED.1
                )
            }
            StoreRefusal::NothingToRevert(state) => {
                write!(f, "{}{}{}", NOTHING.0, state.token(), NOTHING.1)
            }
        }
    }
}

impl FromStr for StoreRefusal {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        if let Some(name) = s
            .strip_prefix(SAVE_FAILED.0)
            .and_then(|r| r.strip_suffix(SAVE_FAILED.1))
        {
            return [SaveError::Flash, SaveError::Storage, SaveError::TooBig]
                .into_iter()
                .find(|e| save_error_name(*e) == name)
                .map(StoreRefusal::SaveFailed)
                .ok_or(());
        }
        let name = s.strip_prefix(NOTHING.0).ok_or(())?;
        StoreState::from_token(name)
            .map(StoreRefusal::NothingToRevert)
            .ok_or(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::Controller;
    use crate::model::{ModelEdit, RigId};

    #[test]
    fn every_refusal_an_edit_can_give_reads_back() {
        // Every model field of every law and suspension, NaN and far out of range.
        for rig in RigId::ALL {
            for kind in ContactLawKind::ALL {
                let p = rig.preset().edited(ModelEdit::Law(kind)).unwrap();
                for field in ModelField::ALL {
                    for v in [f64::NAN, -1.0, 1e300] {
                        let Err(e) = p.edited(ModelEdit::Set(field, v)) else {
                            continue;
                        };
                        let r = SettingsRefusal::of(SettingsError::Model(e)).unwrap();
                        let text = std::format!("{r}");
                        assert_eq!(text.parse::<SettingsRefusal>(), Ok(r), "{text}");
                    }
                }
            }
        }
        // Every calibration field.
        let mut c = Controller::new(ControllerConfig::default(), RigId::Wires, 0.0).unwrap();
        for field in CalibField::ALL {
            for v in [f32::NAN, -1.0, 0.0, 1e30] {
                let Err(e) = c.edit_calibration(field, v) else {
                    continue;
                };
                let r = SettingsRefusal::of(e).unwrap();
                let text = std::format!("{r}");
                assert_eq!(text.parse::<SettingsRefusal>(), Ok(r), "{text}");
            }
        }
    }
}

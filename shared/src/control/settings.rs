//! What the controller runs on besides its firmware defaults: the rig model (a full
//! [`RigParams`], wherever it came from), the gap and the calibration — the [`Settings`] the
//! board keeps in flash.
//!
//! Edits are made at the console one field at a time, or staged in a [`Draft`] and applied
//! whole (`draft begin` … `draft apply`): what the desktop's `rig model push` uses, so that a
//! push is all fields or none.

use serde::{Deserialize, Serialize};

use super::calibration::{CalibField, Calibration};
use super::command::CommandError;
use crate::error::ParamError;
use crate::model::{EditError, ModelEdit, RigParams};

/// What the board keeps in flash: the rig model, the gap and the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    /// The rig model.
    pub params: RigParams,
    /// The gap, mm.
    pub gap_mm: f32,
    /// The calibration.
    pub calibration: Calibration,
}

/// Staged changes, applied whole or not at all.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Draft {
    /// The model as edited so far.
    pub params: RigParams,
    /// The calibration as edited so far.
    pub calibration: Calibration,
}

/// Why a change to the settings was refused (nothing changed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SettingsError {
    /// Only while idle (or a fault is latched).
    Command(CommandError),
    /// The model edit was refused.
    Model(EditError),
    /// The calibration was refused (the field and its range).
    Calibration(ParamError),
    /// The settings loaded (`revert`, a stored record) fail validation: the model's field.
    Invalid(ParamError),
    /// `draft apply` or `draft discard` without `draft begin`.
    NoDraft,
}

/// Edits one calibration field of `cal`, checked against `config` as a whole.
pub(super) fn edit_calibration(
    cal: &Calibration,
    config: &super::config::ControllerConfig,
    field: CalibField,
    value: f32,
) -> Result<Calibration, SettingsError> {
    let c = cal.with(field, value);
    c.applied_to(config).map_err(SettingsError::Calibration)?;
    Ok(c)
}

/// Edits the model `params`.
pub(super) fn edit_model(params: &RigParams, edit: ModelEdit) -> Result<RigParams, SettingsError> {
    params.edited(edit).map_err(SettingsError::Model)
}

//! Where the active rig model came from ([`ModelId`]: a preset, the store, or the console's
//! edits, with the model's hash), so that every log says what the target frequency was computed
//! from.

use crate::model::{RigId, RigParams, params_hash};

/// Where the active rig model came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelSource {
    /// A preset (`rig <name>`, or the power-up fallback), unchanged.
    Preset(RigId),
    /// The store (loaded at power-up or by `revert`, or saved since).
    Stored,
    /// Changed at the console since (not saved).
    Edited,
}

/// Which model is active: where it came from and its hash ([`params_hash`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelId {
    /// Where it came from.
    pub source: ModelSource,
    /// The CRC-32 of its canonical bytes.
    pub hash: u32,
}

impl ModelId {
    /// The id of `params` from `source`.
    pub fn of(params: &RigParams, source: ModelSource) -> ModelId {
        ModelId {
            source,
            hash: params_hash(params),
        }
    }
}

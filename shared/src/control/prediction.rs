//! The model's prediction for the controller: the operating-frequency selection of
//! [`crate::analysis::select_sequential`] in f32 with the on-target profile
//! ([`SelectionSpec::embedded`], [`SimSettings::embedded`]): the firmware's low-priority model
//! task calls [`predict`], and `host-sim select --profile embedded` gives the same numbers.

use crate::analysis::{SelectionError, SelectionSpec, SimSettings, select_sequential};
use crate::model::{RigParams, params_hash};

/// What the controller needs from the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    /// The hash of the rig model it was computed for ([`crate::model::params_hash`]).
    pub model_hash: u32,
    /// Gap it was computed for, mm.
    pub gap_mm: f32,
    /// Target (operating) frequency, Hz.
    pub target_hz: f32,
    /// The `1/1` band holding the target, Hz.
    pub band_hz: [f32; 2],
    /// Predicted maximum impact force at the target, `F_i/mg`.
    pub impact_force_mg: f32,
    /// The same in N.
    pub impact_force_n: f32,
    /// Cart amplitude the model assumes (the rig's `A0`), mm.
    pub amplitude_mm: f32,
    /// Hammer weight `m g`, N.
    pub weight_n: f32,
    /// Natural frequency `ω/2π`, Hz.
    pub natural_freq_hz: f32,
}

/// Runs the on-target selection for the rig model `params` (a preset, the stored model, the
/// console's edits: any valid [`RigParams`]) at `gap_mm`: what `host-sim select --profile
/// embedded` gives for the same parameters, bit for bit.
///
/// # Errors
/// [`SelectionError`]: invalid parameters or gap, no `1/1` band, or no robust `1/1` point.
pub fn predict(params: &RigParams, gap_mm: f32) -> Result<Prediction, SelectionError> {
    let gap_m = f64::from(gap_mm) * 1e-3;
    let sel = select_sequential::<f32>(
        params,
        gap_m,
        &SelectionSpec::embedded(),
        &SimSettings::embedded(),
    )?;
    let weight_n = params.weight_n();
    Ok(Prediction {
        model_hash: params_hash(params),
        gap_mm,
        target_hz: sel.best.freq_hz as f32,
        band_hz: [sel.band_hz[0] as f32, sel.band_hz[1] as f32],
        impact_force_mg: sel.best.impact_force_mg as f32,
        impact_force_n: (sel.best.impact_force_mg * weight_n) as f32,
        amplitude_mm: (params.amplitude_m * 1e3) as f32,
        weight_n: weight_n as f32,
        natural_freq_hz: params.natural_freq_hz() as f32,
    })
}

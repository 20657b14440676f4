//! One operating point of a frequency response: the protocol run from rest at `(gap, Ω/ω)`.

use serde::{Deserialize, Serialize};

use crate::error::{ParamError, check_range};
use crate::integrate::{PhaseTable, Simulator, StepSettings};
use crate::model::{RigParams, SwitchBands};
use crate::observe::{Observer, PointResult, Protocol, Regime, run_protocol};
use crate::real::Real;

/// Accepted frequency ratios `Ω/ω`.
pub const OMEGA_RATIO_RANGE: (f64, f64) = (0.05, 50.0);

/// Every numerical setting of a simulation (switch-model bands, steps, protocol).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimSettings {
    /// Switch-model band widths.
    pub bands: SwitchBands,
    /// Fixed-step settings.
    pub steps: StepSettings,
    /// Canonical protocol.
    pub protocol: Protocol,
}

impl SimSettings {
    /// The on-target profile the firmware's model task runs (and `host-sim --profile embedded`
    /// reproduces): `N = 32` steps per period, `K = 8` contact sub-steps, a transient of at most
    /// 60 periods, periods `q ≤ 4`, an 8-period observation window. Many times cheaper than the
    /// default per point, so that the whole selection fits the MCU's 0.5 s budget
    /// (docs/operator.md, "Budgets, measured"); the default profile stays the reference for the
    /// analyses. (The 60-period transient: with 40, the host profile's `q ≤ 4` regimes of the
    /// wire rig's 0.0 mm response agree at 93.8 % of its points, the rest near bifurcations
    /// that take the host 56–200 periods to settle; with 60, at 95.9 %. docs/model.md.)
    pub fn embedded() -> Self {
        SimSettings {
            bands: SwitchBands::default(),
            steps: StepSettings {
                steps_per_period: 32,
                substeps_per_contact: 8,
            },
            protocol: Protocol {
                max_transient_periods: 60,
                max_q: 4,
                observe_periods: 8,
                ..Protocol::default()
            },
        }
    }

    /// The convergence reference (docs/accuracy.md): steps and sub-steps `factor`× finer and both
    /// bands `factor`× narrower.
    pub fn refined(&self, factor: u32) -> Self {
        SimSettings {
            bands: self.bands.scaled(1.0 / f64::from(factor)),
            steps: self.steps.refined(factor),
            protocol: self.protocol,
        }
    }
}

/// Runs the canonical protocol at `gap_m` (m) and `omega_ratio` (`Ω/ω`) from rest at phase 0,
/// in the float type `T`, reporting to `obs`.
///
/// # Errors
/// [`ParamError`] for invalid parameters, gap, settings, or `omega_ratio` outside
/// [`OMEGA_RATIO_RANGE`].
pub fn evaluate_point_observed<T: Real, O: Observer<T>>(
    params: &RigParams,
    gap_m: f64,
    omega_ratio: f64,
    settings: &SimSettings,
    obs: &mut O,
) -> Result<PointResult, ParamError> {
    let phases = PhaseTable::new(settings.steps.steps_per_period)?;
    evaluate_point_on(params, gap_m, omega_ratio, settings, &phases, obs)
}

/// [`evaluate_point_observed`] on the step grid of `phases` (built for
/// `settings.steps.steps_per_period`; one table serves every point of a sweep).
///
/// # Errors
/// As [`evaluate_point_observed`], and a table for another `N`.
pub fn evaluate_point_on<T: Real, O: Observer<T>>(
    params: &RigParams,
    gap_m: f64,
    omega_ratio: f64,
    settings: &SimSettings,
    phases: &PhaseTable<T>,
    obs: &mut O,
) -> Result<PointResult, ParamError> {
    let mut sim = simulator_at(params, gap_m, omega_ratio, settings, phases)?;
    run_protocol(&mut sim, &settings.protocol, params.weight_n(), obs)
}

/// A simulator at rest at phase 0 for `gap_m` (m) and `omega_ratio` (`Ω/ω`) on the step grid
/// of `phases` (built for `settings.steps.steps_per_period`).
///
/// # Errors
/// [`ParamError`] for invalid parameters, gap or settings, a table for another `N`, or
/// `omega_ratio` outside [`OMEGA_RATIO_RANGE`].
pub fn simulator_at<'t, T: Real>(
    params: &RigParams,
    gap_m: f64,
    omega_ratio: f64,
    settings: &SimSettings,
    phases: &'t PhaseTable<T>,
) -> Result<Simulator<'t, T>, ParamError> {
    check_range(
        "omega_ratio",
        omega_ratio,
        OMEGA_RATIO_RANGE.0,
        OMEGA_RATIO_RANGE.1,
    )?;
    let omega_exc = omega_ratio * params.omega_n();
    Simulator::<T>::new(
        params,
        gap_m,
        omega_exc,
        &settings.bands,
        &settings.steps,
        phases,
    )
}

/// [`evaluate_point_observed`] without an observer.
///
/// The wire rig at 0.0 mm gap driven at twice its natural frequency: one impact per period
/// (`z = 1/1`) of about 33 `mg` — the chosen operating point's neighbour.
/// ```
/// use shared::analysis::{SimSettings, evaluate_point};
/// use shared::model::RigId;
/// use shared::observe::Regime;
/// let r = evaluate_point::<f32>(&RigId::Wires.preset(), 0.0, 2.0, &SimSettings::default())?;
/// assert_eq!(r.regime, Regime::ONE_ONE);
/// assert!((r.impact_force_mg - 33.0).abs() < 1.0);
/// # Ok::<(), shared::ParamError>(())
/// ```
///
/// # Errors
/// As [`evaluate_point_observed`].
pub fn evaluate_point<T: Real>(
    params: &RigParams,
    gap_m: f64,
    omega_ratio: f64,
    settings: &SimSettings,
) -> Result<PointResult, ParamError> {
    evaluate_point_observed::<T, ()>(params, gap_m, omega_ratio, settings, &mut ())
}

/// The compact result a selection needs per frequency: regime and `F_i/mg`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResponseSample {
    /// Impact regime.
    pub regime: Regime,
    /// Maximum impact force over the window, `F_i/mg`.
    pub impact_force_mg: f32,
}

impl From<&PointResult> for ResponseSample {
    fn from(r: &PointResult) -> Self {
        ResponseSample {
            regime: r.regime,
            impact_force_mg: r.impact_force_mg as f32,
        }
    }
}

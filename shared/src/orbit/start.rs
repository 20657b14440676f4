//! Where the orbit tools start: the canonical protocol run from a given state (rest, or initial
//! conditions), ending on the stroboscopic section with the regime it saw, and the periodic
//! orbit found from there by shooting with that regime's period.

use nalgebra::Vector2;

use super::map::{MapPoint, iterate};
use super::shooting::{Orbit, OrbitError, ShootSettings, scaled_norm, shoot};
use crate::error::ParamError;
use crate::integrate::PhaseTable;
use crate::observe::{PointResult, Regime, run_protocol};
use crate::real::Real;

/// The protocol's run at `at` from the relative state `(u0_m, v0_m_s)` (m, m/s; rest is
/// `(0, 0)`) at phase 0: its result, and the state (the simulator's: `(θ, θ̇)` or `(u, u̇)`)
/// on the section where it stopped.
///
/// # Errors
/// [`ParamError`]: an invalid point or settings, an initial state out of range.
pub fn settle<T: Real>(
    at: &MapPoint,
    u0_m: f64,
    v0_m_s: f64,
) -> Result<(PointResult, Vector2<T>), ParamError> {
    let table = PhaseTable::<T>::new(at.settings.steps.steps_per_period)?;
    let mut sim =
        crate::analysis::simulator_at(&at.params, at.gap_m, at.omega_ratio, &at.settings, &table)?;
    sim.reset_relative(u0_m, v0_m_s)?;
    let result = run_protocol(
        &mut sim,
        &at.settings.protocol,
        at.params.weight_n(),
        &mut (),
    )?;
    Ok((result, sim.state()))
}

/// `(u, u̇)` (m, m/s) of the simulator's state `x` at `at`.
///
/// # Errors
/// [`ParamError`]: an invalid point.
pub fn relative<T: Real>(at: &MapPoint, x: &Vector2<T>) -> Result<(f64, f64), ParamError> {
    let table = PhaseTable::<T>::new(at.settings.steps.steps_per_period)?;
    let sim =
        crate::analysis::simulator_at(&at.params, at.gap_m, at.omega_ratio, &at.settings, &table)?;
    let (u, du) = sim.hammer().relative(x);
    Ok((u.to_f64(), du.to_f64()))
}

/// The simulator's state at relative displacement `u_m` (m) and velocity `du_m_s` (m/s).
///
/// # Errors
/// [`ParamError`]: an invalid point, a state out of range.
pub fn state_of<T: Real>(at: &MapPoint, u_m: f64, du_m_s: f64) -> Result<Vector2<T>, ParamError> {
    let table = PhaseTable::<T>::new(at.settings.steps.steps_per_period)?;
    let sim =
        crate::analysis::simulator_at(&at.params, at.gap_m, at.omega_ratio, &at.settings, &table)?;
    sim.hammer().state_from_relative(u_m, du_m_s)
}

/// The periodic orbit the protocol settles on from `(u0_m, v0_m_s)`: the protocol runs, and
/// shooting with its period `q` (or `q` if given) starts from where it stopped.
///
/// # Errors
/// [`OrbitError::NoPeriod`] when the protocol saw no period and none was given (with the
/// regime it saw: `irregular`, `chaotic`; a `no impact` point has period 1);
/// otherwise as [`shoot`].
pub fn orbit_from<T: Real>(
    at: &MapPoint,
    u0_m: f64,
    v0_m_s: f64,
    q: Option<u32>,
    settings: &ShootSettings,
) -> Result<(PointResult, Orbit<T>), OrbitError> {
    let (result, x) = settle::<T>(at, u0_m, v0_m_s)?;
    let q = match (q, result.regime) {
        (Some(q), _) => q,
        (None, Regime::Periodic { q, .. }) => u32::from(q),
        (None, Regime::NoImpact) => 1,
        (None, regime) => return Err(OrbitError::NoPeriod { regime }),
    };
    let orbit = shoot(at, q, x, settings)?;
    Ok((result, minimal_period(at, orbit, settings)))
}

/// The orbit at its minimal period: a fixed point of `P^q` that is already one of `P^d`
/// (`d` a proper divisor of `q`, the scaled residual of `P^d(x) − x` within Newton's
/// tolerance) is the `d`-periodic orbit, re-converged at `d` (so that a `1/1` orbit asked at
/// `q = 3` is reported as `1/1`, not `3/3`).
pub fn minimal_period<T: Real>(
    at: &MapPoint,
    orbit: Orbit<T>,
    settings: &ShootSettings,
) -> Orbit<T> {
    let scales = at.scales();
    for d in (1..orbit.q).filter(|&d| orbit.q.is_multiple_of(d)) {
        let Ok(img) = iterate(at, d, orbit.x) else {
            continue;
        };
        let r = [
            img.x[0].to_f64() - orbit.x[0].to_f64(),
            img.x[1].to_f64() - orbit.x[1].to_f64(),
        ];
        if scaled_norm(r, scales) <= settings.tolerance
            && let Ok(o) = shoot(at, d, orbit.x, settings)
        {
            return o;
        }
    }
    orbit
}

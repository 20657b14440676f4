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

/// The orbit at its minimal period: a fixed point of `P^q` that is already one of `P^d` (`d` a
/// proper divisor of `q`) is the `d`-periodic orbit, re-converged at `d` (so that a `1/1` orbit
/// asked at `q = 3` is reported as `1/1`, not `3/3`). It is one where the scaled residual of
/// `P^d(x) − x` is within Newton's tolerance, or where Newton at `d` from `x` converges, with
/// `q/d` times fewer impacts, within the `q`-orbit's own error of `x` (the tolerance through
/// `(M − I)⁻¹`): near a period doubling (`μ → −1` at `d`, so `μ² → +1` at `q`), or in f32, the
/// `q`-orbit's point is only that close to the `d`-orbit, and the residual of `P^d` is far above
/// the tolerance (the wire rig's `1/1` at 0.0 mm, Ω/ω 2.66, `μ = −0.998`).
pub fn minimal_period<T: Real>(
    at: &MapPoint,
    orbit: Orbit<T>,
    settings: &ShootSettings,
) -> Orbit<T> {
    let scales = at.scales();
    let reach = reach(&orbit, settings);
    for d in (1..orbit.q).filter(|&d| orbit.q.is_multiple_of(d)) {
        let Ok(img) = iterate(at, d, orbit.x) else {
            continue;
        };
        let gap = |y: &Vector2<T>| {
            scaled_norm(
                [
                    y[0].to_f64() - orbit.x[0].to_f64(),
                    y[1].to_f64() - orbit.x[1].to_f64(),
                ],
                scales,
            )
        };
        let r = gap(&img.x);
        if r <= settings.tolerance {
            if let Ok(o) = shoot(at, d, orbit.x, settings) {
                return o;
            }
            continue;
        }
        // Along a multiplier `μ` of the `d`-orbit, `P^d(x) − x` is `μ − 1` times the point's
        // error: within `(1 + |μ|)` of the reach (`|μ|` from `P^q`'s largest), with a margin.
        let stretch = 1.0 + libm::pow(orbit.floquet.max_abs(), f64::from(d) / f64::from(orbit.q));
        if r.is_nan() || r > REACH_MARGIN * stretch * reach {
            continue;
        }
        if let Ok(o) = shoot(at, d, orbit.x, settings)
            && o.trace.impacts * (orbit.q / d) == orbit.trace.impacts
            && gap(&o.x) <= REACH_MARGIN * reach
        {
            return o;
        }
    }
    orbit
}

/// The margin on [`reach`] within which a `q`-orbit's point is taken as the `d`-orbit's.
const REACH_MARGIN: f64 = 4.0;

/// The largest reach taken (scaled): farther apart, two orbits are told apart whatever the
/// conditioning (1e-3 of the cart's amplitude).
const REACH_CAP: f64 = 1e-3;

/// How far (scaled, [`MapPoint::scales`]) the orbit's point may lie from the exact fixed point
/// of `P^q` it approximates: Newton's residual bound (the tolerance, or the residual reached if
/// larger) through `(M − I)⁻¹` in the scaled max norm, at most [`REACH_CAP`].
fn reach<T: Real>(orbit: &Orbit<T>, settings: &ShootSettings) -> f64 {
    let s = orbit.at.scales();
    let m = &orbit.monodromy;
    // M − I in scaled coordinates, and its inverse's largest row sum.
    let a = |i: usize, j: usize| (m[i][j] - if i == j { 1.0 } else { 0.0 }) * s[j] / s[i];
    let det = a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0);
    let norm = (a(1, 1).abs() + a(0, 1).abs()).max(a(1, 0).abs() + a(0, 0).abs()) / det.abs();
    let reach = settings.tolerance.max(orbit.residual) * norm;
    if reach.is_finite() {
        reach.min(REACH_CAP)
    } else {
        REACH_CAP
    }
}

//! The stroboscopic map `P: x(kT) → x((k+1)T)` the simulator iterates, and its derivative.
//!
//! The state `x` is the simulator's: `(θ, θ̇)` for the wire pendulum, `(u, u̇)` for the beam
//! springs, at excitation phase 0. `P^q` runs `q` periods of the same simulator (same step plan,
//! vector field, switch model and sub-steps) from `x`, with its switching events located to
//! round-off rather than to `2^-14` of a sub-step (`Simulator::locate_events_exactly`) and the
//! split of a free-flight step that nears the surface located to round-off and differentiated
//! through its root rather than bisected to 1/8192 of the step (`Simulator::step_exact`): the
//! production map jumps by up to 1e-5 of the cart's amplitude where those move, in steps
//! Newton cannot cross and whose slope is not the map's. [`tangent`] runs it in
//! [`Dual`] numbers seeded with the identity, which gives `DP^q` (the monodromy matrix) as the
//! exact derivative of the discrete map (crate::dual). Along the way the map records what the
//! orbit does: its impacts (arrivals through `δ = 0`, counted as the canonical protocol counts
//! them), its largest contact force, and the slowest arrival.

use nalgebra::Vector2;

use crate::analysis::SimSettings;
use crate::dual::Dual;
use crate::error::{ParamError, check_range};
use crate::integrate::{PhaseTable, Simulator, StepSample};
use crate::model::RigParams;
use crate::observe::impact::{ImpactEvent, ImpactTracker};
use crate::real::Real;

/// A parameter a branch of orbits is continued in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Param {
    /// `Ω/ω`.
    OmegaRatio,
    /// The gap, m.
    GapM,
}

impl Param {
    /// Its name in reports and CSV (`omega_ratio`, `gap_mm`).
    pub fn name(self) -> &'static str {
        match self {
            Param::OmegaRatio => "omega_ratio",
            Param::GapM => "gap_mm",
        }
    }
}

/// Where the map is evaluated: a rig, its numerics, a gap and an excitation frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapPoint {
    /// The rig.
    pub params: RigParams,
    /// Step plan, bands and protocol settings (the protocol's separation counts impacts).
    pub settings: SimSettings,
    /// Gap, m.
    pub gap_m: f64,
    /// `Ω/ω`.
    pub omega_ratio: f64,
}

impl MapPoint {
    /// The value of `param` here (gap in m).
    pub fn get(&self, param: Param) -> f64 {
        match param {
            Param::OmegaRatio => self.omega_ratio,
            Param::GapM => self.gap_m,
        }
    }

    /// This point with `param` set to `value` (gap in m).
    pub fn with(&self, param: Param, value: f64) -> MapPoint {
        let mut p = *self;
        match param {
            Param::OmegaRatio => p.omega_ratio = value,
            Param::GapM => p.gap_m = value,
        }
        p
    }

    /// The scales of the state's two components: the cart's amplitude and velocity amplitude
    /// in the state's units (wires: `A0/l` rad and `A0 Ω/l` rad/s; beams: `A0` m and `A0 Ω`
    /// m/s). Distances between states are measured in these units.
    pub fn scales(&self) -> [f64; 2] {
        let a0 = self.params.amplitude_m;
        let w = self.omega_ratio * self.params.omega_n();
        let per = match self.params.suspension {
            crate::model::Suspension::Wires { length_m, .. } => length_m,
            crate::model::Suspension::Beam { .. } => 1.0,
        };
        [a0 / per, a0 * w / per]
    }

    /// The map's simulator: the analyses' at this point, its switching events located to
    /// round-off ([`Simulator::locate_events_exactly`]) so that the map (run with
    /// `Simulator::step_exact`) is smooth where the orbit's impacts do not change.
    pub(crate) fn simulator<'t, U: Real>(
        &self,
        table: &'t PhaseTable<U>,
    ) -> Result<Simulator<'t, U>, ParamError> {
        let mut sim = crate::analysis::simulator_at(
            &self.params,
            self.gap_m,
            self.omega_ratio,
            &self.settings,
            table,
        )?;
        sim.locate_events_exactly();
        Ok(sim)
    }
}

/// What `q` periods of the map did besides moving the state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trace {
    /// Impacts (arrivals through `δ = 0`) in the `q` periods.
    pub impacts: u32,
    /// Largest contact force, N.
    pub max_force_n: f64,
    /// Slowest arrival, m/s (the penetration rate at the first sample of each impact; `∞`
    /// without impacts): it goes to 0 at a grazing.
    pub slowest_arrival_m_s: f64,
    /// Closest approach to the surface in free flight, outside every impact episode, m: the
    /// largest turning point (`δ̇` from + to −) of `δ`'s cubic Hermite interpolant between
    /// free-flight samples (`−∞` if the orbit never turns in free flight). Below 0, it goes to
    /// 0 where a new impact appears (a grazing).
    pub closest_free_m: f64,
}

/// The largest interior maximum over a segment of `dt` s of the cubic Hermite interpolant from
/// `a` (slope `da`, per s) to `b` (slope `db`), if it turns there.
fn hermite_turn(a: f64, da: f64, b: f64, db: f64, dt: f64) -> Option<f64> {
    // p(s) = h00 a + h10 dt da + h01 b + h11 dt db on s ∈ [0, 1]; p'(s) = c2 s² + c1 s + c0.
    let (ma, mb) = (dt * da, dt * db);
    let c2 = 6.0 * a + 3.0 * ma - 6.0 * b + 3.0 * mb;
    let c1 = -6.0 * a - 4.0 * ma + 6.0 * b - 2.0 * mb;
    let c0 = ma;
    let p = |s: f64| {
        let (s2, s3) = (s * s, s * s * s);
        (2.0 * s3 - 3.0 * s2 + 1.0) * a
            + (s3 - 2.0 * s2 + s) * ma
            + (3.0 * s2 - 2.0 * s3) * b
            + (s3 - s2) * mb
    };
    let mut best: Option<f64> = None;
    let slope = |s: f64| (c2 * s + c1) * s + c0;
    let mut consider = |s: f64| {
        // A maximum: the slope falls through zero there.
        if s > 0.0 && s < 1.0 && slope(s - 1e-6) > 0.0 && slope(s + 1e-6) < 0.0 {
            let v = p(s);
            best = Some(best.map_or(v, |b: f64| b.max(v)));
        }
    };
    if c2.abs() > 1e-300 {
        let disc = c1 * c1 - 4.0 * c2 * c0;
        if disc >= 0.0 {
            let r = libm::sqrt(disc);
            consider((-c1 + r) / (2.0 * c2));
            consider((-c1 - r) / (2.0 * c2));
        }
    } else if c1.abs() > 1e-300 {
        consider(-c0 / c1);
    }
    best
}

/// `P^q(x)` and what the orbit did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Image<T> {
    /// The state after `q` periods.
    pub x: Vector2<T>,
    /// What it did.
    pub trace: Trace,
}

/// Runs `q` periods of `sim` from `x0` (phase 0), feeding every sample to `each`.
pub(crate) fn run<U: Real>(
    sim: &mut Simulator<'_, U>,
    x0: Vector2<U>,
    q: u32,
    separation_m: f64,
    mut each: impl FnMut(&StepSample<U>),
) -> (Vector2<U>, Trace) {
    sim.reset_state(x0);
    let (delta0, _) = sim.hammer().penetration(&x0);
    let mut tracker = ImpactTracker::new(U::from_f64(separation_m), delta0);
    let mut trace = Trace {
        impacts: 0,
        max_force_n: 0.0,
        slowest_arrival_m_s: f64::INFINITY,
        closest_free_m: f64::NEG_INFINITY,
    };
    let step_s = sim.step_s();
    // The previous sample in free flight outside an episode: (time s, δ, δ̇).
    let (_, ddelta0) = sim.hammer().penetration(&x0);
    let mut free: Option<(f64, f64, f64)> = (!tracker.in_episode() && delta0 < U::zero())
        .then(|| (0.0, delta0.to_f64(), ddelta0.to_f64()));
    let mut periods = 0;
    while periods < q {
        sim.step_exact(&mut |s: &StepSample<U>| {
            if let Some(ImpactEvent::Arrival) = tracker.update(s.delta, s.delta_min, s.force) {
                trace.impacts += 1;
                trace.slowest_arrival_m_s = trace.slowest_arrival_m_s.min(s.delta_dot.to_f64());
            }
            trace.max_force_n = trace.max_force_n.max(s.force.to_f64());
            let flying = !tracker.in_episode() && s.force == U::zero() && s.delta < U::zero();
            let now = (s.time_s(step_s), s.delta.to_f64(), s.delta_dot.to_f64());
            if flying
                && let Some((t, a, da)) = free
                && let Some(turn) = hermite_turn(a, da, now.1, now.2, now.0 - t)
            {
                trace.closest_free_m = trace.closest_free_m.max(turn);
            }
            free = flying.then_some(now);
            if s.period_end {
                periods += 1;
            }
            each(s);
        });
    }
    (sim.state(), trace)
}

/// Checks `q`.
fn check_q(q: u32) -> Result<(), ParamError> {
    crate::error::check_count("q", q, 1, MAX_Q)?;
    Ok(())
}

/// Longest period of an orbit, excitation periods.
pub const MAX_Q: u32 = 256;

/// `P^q(x)` in `T`: `q` periods (1 ..= [`MAX_Q`]) of the simulator at `at` from state `x`.
///
/// # Errors
/// [`ParamError`]: invalid rig, numerics or point, `q` out of range, a non-finite state.
pub fn iterate<T: Real>(at: &MapPoint, q: u32, x: Vector2<T>) -> Result<Image<T>, ParamError> {
    check_q(q)?;
    check_state(&x)?;
    let table = PhaseTable::<T>::new(at.settings.steps.steps_per_period)?;
    let mut sim = at.simulator(&table)?;
    let (x, trace) = run(&mut sim, x, q, at.settings.protocol.separation_m, |_| {});
    Ok(Image { x, trace })
}

/// `P^q(x)` and its derivative `DP^q(x)` (the monodromy matrix, row-major: `m[i][j] =
/// ∂P_i/∂x_j`), from one run in `Dual<T, 2>` (values bit for bit [`iterate`]'s).
///
/// # Errors
/// As [`iterate`].
pub fn tangent<T: Real>(
    at: &MapPoint,
    q: u32,
    x: Vector2<T>,
) -> Result<(Image<T>, [[f64; 2]; 2]), ParamError> {
    check_q(q)?;
    check_state(&x)?;
    let table = PhaseTable::<Dual<T, 2>>::new(at.settings.steps.steps_per_period)?;
    let mut sim = at.simulator(&table)?;
    let seeded = Vector2::new(Dual::seed(x[0], 0), Dual::seed(x[1], 1));
    let (y, trace) = run(
        &mut sim,
        seeded,
        q,
        at.settings.protocol.separation_m,
        |_| {},
    );
    let m = [
        [y[0].d[0].to_f64(), y[0].d[1].to_f64()],
        [y[1].d[0].to_f64(), y[1].d[1].to_f64()],
    ];
    Ok((
        Image {
            x: Vector2::new(y[0].v, y[1].v),
            trace,
        },
        m,
    ))
}

/// `q` periods from `x` with every sample of the run handed to `each` (the orbit drawn, or
/// integrated along, by a caller).
///
/// # Errors
/// As [`iterate`].
pub fn samples<T: Real>(
    at: &MapPoint,
    q: u32,
    x: Vector2<T>,
    each: impl FnMut(&StepSample<T>),
) -> Result<Image<T>, ParamError> {
    check_q(q)?;
    check_state(&x)?;
    let table = PhaseTable::<T>::new(at.settings.steps.steps_per_period)?;
    let mut sim = at.simulator(&table)?;
    let (x, trace) = run(&mut sim, x, q, at.settings.protocol.separation_m, each);
    Ok(Image { x, trace })
}

fn check_state<T: Real>(x: &Vector2<T>) -> Result<(), ParamError> {
    check_range("x0", x[0].to_f64(), -1e3, 1e3)?;
    check_range("x1", x[1].to_f64(), -1e6, 1e6)?;
    Ok(())
}

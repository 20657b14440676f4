//! Many operating points on one core, interleaved.
//!
//! One protocol run is a chain of dependent floating-point operations (each RK4 stage needs the
//! previous one), so a single run leaves most of an out-of-order core idle. Stepping `L`
//! independent runs in turn lets the core overlap their chains. Each round first takes, for the
//! runs clear of the surface, whole free-flight steps in lockstep
//! ([`crate::integrate::lanes::free_flight`], vectorised across the lanes; only for observers
//! that ignore per-step samples), then one ordinary step of every run (Poincaré sections,
//! contact sub-steps). Results are exactly those of [`super::evaluate_point`] (each run is the
//! same computation, only the order of instructions between runs changes; tested). No
//! allocation; an in-order MCU gains nothing from it.

use super::response::{SimSettings, simulator_at};
use crate::error::ParamError;
use heapless::Vec;

use crate::integrate::lanes::free_flight;
use crate::integrate::{PhaseTable, Simulator};
use crate::model::RigParams;
use crate::observe::{Observer, PointResult, ProtocolRun};
use crate::real::Real;

/// Lanes that the host's analysis commands interleave per core.
pub const DEFAULT_LANES: usize = 8;

struct Lane<'t, T: Real, O> {
    index: usize,
    sim: Simulator<'t, T>,
    run: ProtocolRun<T>,
    obs: O,
}

/// A protocol run ready to go: the simulator at its initial state (at a period boundary), the
/// run, and the observer that will watch it.
pub type Started<'t, T, O> = (Simulator<'t, T>, ProtocolRun<T>, O);

/// Runs one protocol per item of `items`, `L` at a time interleaved step by step. `start` turns
/// an item into a [`Started`] run (or an error, emitted at once); `emit(i, result)` receives the
/// `i`-th item's result with its observer and final simulator as soon as it is done (so not in
/// order).
pub fn run_interleaved<'t, T, O, const L: usize, I, S, F>(items: I, mut start: S, mut emit: F)
where
    T: Real + 't,
    O: Observer<T>,
    I: IntoIterator,
    S: FnMut(I::Item) -> Result<Started<'t, T, O>, ParamError>,
    F: FnMut(usize, Result<(PointResult, O, &Simulator<'t, T>), ParamError>),
{
    let mut next = items.into_iter().enumerate();
    let mut launch = |emit: &mut F| -> Option<Lane<'t, T, O>> {
        for (index, item) in next.by_ref() {
            match start(item) {
                Ok((sim, run, obs)) => {
                    return Some(Lane {
                        index,
                        sim,
                        run,
                        obs,
                    });
                }
                Err(e) => emit(index, Err(e)),
            }
        }
        None
    };
    let mut lanes: [Option<Lane<'t, T, O>>; L] = core::array::from_fn(|_| None);
    for lane in lanes.iter_mut() {
        *lane = launch(&mut emit);
    }
    loop {
        // Whole free-flight steps in lockstep for the lanes clear of the surface.
        let mut taking_part = [false; L];
        let mut sims: Vec<&mut Simulator<'t, T>, L> = Vec::new();
        for (slot, part) in lanes.iter_mut().zip(taking_part.iter_mut()) {
            if let Some(lane) = slot
                && lane.run.free_flight_allowed::<O>()
            {
                *part = true;
                let _ = sims.push(&mut lane.sim);
            }
        }
        let taken = free_flight::<T, L>(&mut sims);
        drop(sims);
        let mut j = 0;
        for (slot, part) in lanes.iter_mut().zip(taking_part) {
            if let (Some(lane), true) = (slot, part) {
                if taken[j] > 0 {
                    lane.run.after_free_flight(&lane.sim);
                }
                j += 1;
            }
        }
        let mut active = false;
        for slot in lanes.iter_mut() {
            let done = match slot {
                Some(lane) => {
                    active = true;
                    lane.run
                        .step(&mut lane.sim, &mut lane.obs)
                        .map(|r| (lane.index, r))
                }
                None => None,
            };
            if let Some((index, result)) = done {
                if let Some(lane) = slot.take() {
                    emit(index, Ok((result, lane.obs, &lane.sim)));
                }
                *slot = launch(&mut emit);
            }
        }
        if !active {
            return;
        }
    }
}

/// Runs the canonical protocol from rest at every `(gap_m, omega_ratio)` of `points` (m, `Ω/ω`),
/// `L` at a time interleaved ([`run_interleaved`]), and calls `emit(i, result)` for the `i`-th
/// point as soon as it is done (so not in order; invalid points are emitted at once with their
/// error).
pub fn evaluate_interleaved<T: Real, const L: usize, I, F>(
    params: &RigParams,
    settings: &SimSettings,
    points: I,
    mut emit: F,
) where
    I: IntoIterator<Item = (f64, f64)>,
    F: FnMut(usize, Result<PointResult, ParamError>),
{
    let weight_n = params.weight_n();
    let phases = match PhaseTable::new(settings.steps.steps_per_period) {
        Ok(p) => p,
        Err(e) => {
            for (i, _) in points.into_iter().enumerate() {
                emit(i, Err(e));
            }
            return;
        }
    };
    run_interleaved::<T, (), L, _, _, _>(
        points,
        |(gap_m, omega_ratio)| {
            let sim = simulator_at::<T>(params, gap_m, omega_ratio, settings, &phases)?;
            let run = ProtocolRun::new(&sim, &settings.protocol, weight_n)?;
            Ok((sim, run, ()))
        },
        |i, r| emit(i, r.map(|(result, (), _)| result)),
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::evaluate_point;
    use crate::model::RigId;

    #[test]
    fn interleaved_results_equal_one_at_a_time() {
        let p = RigId::Wires.preset();
        let s = SimSettings::default();
        // 1/1, 1/2, a multi-impact point, no impact, and an invalid Ω/ω.
        let points = [
            (0.0, 2.0),
            (1.0e-3, 3.8),
            (0.0, 0.8),
            (3.2e-3, 0.58),
            (0.0, -1.0),
            (2.4e-3, 1.5),
        ];
        let mut got: [Option<Result<PointResult, ParamError>>; 6] = [None; 6];
        evaluate_interleaved::<f32, 3, _, _>(&p, &s, points, |i, r| got[i] = Some(r));
        for (i, &(g, r)) in points.iter().enumerate() {
            assert_eq!(
                got[i],
                Some(evaluate_point::<f32>(&p, g, r, &s)),
                "point {i}"
            );
        }
        assert!(matches!(
            got[4],
            Some(Err(ParamError::OutOfRange {
                field: "omega_ratio",
                ..
            }))
        ));
    }

    /// The lockstep free-flight lanes (`integrate::lanes`) take over most whole steps here; every
    /// result, including the RK4 step count, must be bit for bit the one-at-a-time protocol's,
    /// for both suspensions and both float types.
    fn lanes_match_scalar<T: Real>(rig: RigId, gaps_m: &[f64], ratios: &[f64]) {
        let p = rig.preset();
        let s = SimSettings::default();
        let points: std::vec::Vec<(f64, f64)> = gaps_m
            .iter()
            .flat_map(|&g| ratios.iter().map(move |&r| (g, r)))
            .collect();
        let mut got = std::vec![None; points.len()];
        evaluate_interleaved::<T, DEFAULT_LANES, _, _>(&p, &s, points.iter().copied(), |i, r| {
            got[i] = Some(r)
        });
        for (i, &(g, r)) in points.iter().enumerate() {
            assert_eq!(
                got[i],
                Some(evaluate_point::<T>(&p, g, r, &s)),
                "{rig:?} gap {g} Ω/ω {r}"
            );
        }
    }

    #[test]
    fn lockstep_lanes_equal_one_at_a_time() {
        let ratios = [0.55, 0.9, 1.4, 1.9, 2.0, 2.7, 3.3, 3.8, 4.6];
        lanes_match_scalar::<f32>(RigId::Wires, &[0.0, 1.0e-3, 2.4e-3, 3.4e-3], &ratios);
        lanes_match_scalar::<f64>(RigId::Wires, &[0.0, 2.4e-3], &ratios);
        lanes_match_scalar::<f32>(RigId::Beam170, &[0.0, 3.0e-3], &ratios);
    }
}

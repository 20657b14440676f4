//! Many operating points on one core, interleaved.
//!
//! One protocol run is a chain of dependent floating-point operations (each RK4 stage needs the
//! previous one), so a single run leaves most of an out-of-order core idle. Stepping `L`
//! independent runs in turn lets the core overlap their chains: on the development machine two
//! lanes run 1.9× the steps per second of one. Results are exactly those of
//! [`super::evaluate_point`] (each run is the same computation, only the order of
//! instructions between runs changes). No allocation; an in-order MCU gains nothing from it.

use super::response::{SimSettings, simulator_at};
use crate::error::ParamError;
use crate::integrate::Simulator;
use crate::model::RigParams;
use crate::observe::{PointResult, ProtocolRun};
use crate::real::Real;

/// Lanes that the host's analysis commands interleave per core.
pub const DEFAULT_LANES: usize = 4;

struct Lane<T: Real> {
    index: usize,
    sim: Simulator<T>,
    run: ProtocolRun<T>,
}

/// Runs the canonical protocol from rest at every `(gap_m, omega_ratio)` of `points` (m, `Ω/ω`),
/// `L` at a time interleaved step by step, and calls `emit(i, result)` for the `i`-th point
/// as soon as it is done (so not in order; invalid points are emitted at once with their error).
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
    let mut next = points.into_iter().enumerate();
    let mut lanes: [Option<Lane<T>>; L] = core::array::from_fn(|_| None);
    let start = |next: &mut core::iter::Enumerate<I::IntoIter>, emit: &mut F| -> Option<Lane<T>> {
        for (index, (gap_m, omega_ratio)) in next.by_ref() {
            let started = simulator_at::<T>(params, gap_m, omega_ratio, settings).and_then(|sim| {
                let run = ProtocolRun::new(&sim, &settings.protocol, weight_n)?;
                Ok(Lane { index, sim, run })
            });
            match started {
                Ok(lane) => return Some(lane),
                Err(e) => emit(index, Err(e)),
            }
        }
        None
    };
    for lane in lanes.iter_mut() {
        *lane = start(&mut next, &mut emit);
    }
    loop {
        let mut active = false;
        for slot in lanes.iter_mut() {
            if let Some(lane) = slot {
                active = true;
                if let Some(result) = lane.run.step(&mut lane.sim, &mut ()) {
                    emit(lane.index, Ok(result));
                    *slot = start(&mut next, &mut emit);
                }
            }
        }
        if !active {
            return;
        }
    }
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
}

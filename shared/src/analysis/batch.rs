//! Many operating points on one core, interleaved.
//!
//! One protocol run is a chain of dependent floating-point operations (each RK4 stage needs the
//! previous one), so a single run leaves most of an out-of-order core idle. `L` runs share the
//! core: those clear of the surface take their whole free-flight steps together in lockstep
//! lanes (`crate::integrate::lanes`, vectorised across the lanes; only for observers that
//! ignore per-step samples). As soon as one lane stops (at its period's end, where the run takes
//! its Poincaré section; near the surface; an angle the lanes' short sine does not cover), that
//! run alone takes ordinary steps ([`ProtocolRun::step`]; its ordinary contact sub-steps in the
//! contact lanes) until it can rejoin the lanes or is done, when the next point takes its lane;
//! the other lanes wait without losing their place. Results are exactly those of
//! [`super::evaluate_point`] (each run is the same computation, only the order of instructions
//! between runs changes; tested). No allocation; an in-order MCU gains nothing from it.

use nalgebra::Vector2;

use super::response::{SimSettings, simulator_at};
use crate::error::ParamError;

use crate::integrate::contact_lanes::{ContactLanes, LaneContact, RunLanes};
use crate::integrate::isa::wide_vectors;
use crate::integrate::lanes::Lockstep;
use crate::integrate::stepper::{Cursor, SubPlan};
use crate::integrate::{PhaseTable, Simulator};
use crate::model::RigParams;
use crate::model::hammer::{BeamFree, WiresFree};
use crate::observe::{Observer, PointResult, ProtocolRun};
use crate::real::Real;

/// Free-flight rounds between two rounds of contact sub-steps while lanes are in contact.
const FREE_ROUNDS: u64 = 4;

/// Lanes interleaved per core where the CPU's vector registers hold 8 `f32` or fewer (AVX2,
/// or the portable code).
pub const DEFAULT_LANES: usize = 8;

/// Lanes interleaved per core where they hold 16 (AVX-512: one register per lane array).
pub const WIDE_LANES: usize = 16;

/// The lanes the host's analysis commands interleave per core on this CPU: [`WIDE_LANES`]
/// with AVX-512 (`crate::integrate::isa`), else [`DEFAULT_LANES`]. The results do not
/// depend on it.
pub fn lanes_per_core() -> usize {
    if wide_vectors() {
        WIDE_LANES
    } else {
        DEFAULT_LANES
    }
}

struct Lane<'t, T: Real, O> {
    index: usize,
    sim: Simulator<'t, T>,
    run: ProtocolRun<T>,
    obs: O,
}

/// A protocol run ready to go: the simulator at its initial state (at a period boundary), the
/// run, and the observer that will watch it.
pub type Started<'t, T, O> = (Simulator<'t, T>, ProtocolRun<T>, O);

/// How full the lockstep lanes of an interleaved run were (cost diagnostics).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LaneStats {
    /// Lanes per round, `L`.
    pub lanes: u64,
    /// Lockstep rounds run (each offers `L` lane-steps).
    pub rounds: u64,
    /// Whole free-flight steps taken in them.
    pub lane_steps: u64,
    /// Rounds of contact sub-steps (each offers `L` lanes).
    pub contact_rounds: u64,
    /// Sub-steps taken in them.
    pub contact_steps: u64,
    /// Of those, the sub-steps the contact lanes ended themselves (committed, sampled and the
    /// next one set up without the simulator).
    pub contact_ended: u64,
}

impl core::ops::AddAssign for LaneStats {
    /// The counts of two interleaved runs with the same `L` added up (`lanes` kept: it is a
    /// width, not a count).
    fn add_assign(&mut self, o: LaneStats) {
        self.lanes = self.lanes.max(o.lanes);
        self.rounds += o.rounds;
        self.lane_steps += o.lane_steps;
        self.contact_rounds += o.contact_rounds;
        self.contact_steps += o.contact_steps;
        self.contact_ended += o.contact_ended;
    }
}

/// Runs one protocol per item of `items`, `L` at a time interleaved. `start` turns an item into
/// a [`Started`] run (or an error, emitted at once); `emit(i, result)` receives the `i`-th
/// item's result with its observer and final simulator as soon as it is done (so not in
/// order). Returns how full the lanes were.
pub fn run_interleaved<'t, T, O, const L: usize, I, S, F>(
    items: I,
    mut start: S,
    mut emit: F,
) -> LaneStats
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
    // The lockstep kernel's suspension is the first run's (runs of another one, if any, take
    // ordinary steps only).
    let wires = match lanes.iter().flatten().next() {
        Some(lane) => lane.sim.hammer().is_wires(),
        None => return LaneStats::default(),
    };
    let mut driver = Driver {
        lanes,
        launch,
        emit,
        mode: [Mode::Idle; L],
        cursor: [Default::default(); L],
        constants_set: [false; L],
        contact_ended: 0,
    };
    if wires {
        driver.drive::<WiresFree<T>>()
    } else {
        driver.drive::<BeamFree<T>>()
    }
}

/// [`run_interleaved`] with [`lanes_per_core`] lanes (the same results, in the same order of
/// `emit` calls only if the lane count is the same).
pub fn run_interleaved_native<'t, T, O, I, S, F>(items: I, start: S, emit: F) -> LaneStats
where
    T: Real + 't,
    O: Observer<T>,
    I: IntoIterator,
    S: FnMut(I::Item) -> Result<Started<'t, T, O>, ParamError>,
    F: FnMut(usize, Result<(PointResult, O, &Simulator<'t, T>), ParamError>),
{
    if wide_vectors() {
        run_interleaved::<T, O, WIDE_LANES, I, S, F>(items, start, emit)
    } else {
        run_interleaved::<T, O, DEFAULT_LANES, I, S, F>(items, start, emit)
    }
}

/// What a lane of [`run_interleaved`] is doing between two kernel calls.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// No run (the items are exhausted).
    Idle,
    /// Loaded into the free-flight lanes.
    Free,
    /// Its next segment is a sub-step set into the contact lanes.
    Contact,
}

/// The lanes of [`run_interleaved`] with its `launch` and `emit`.
struct Driver<'t, T: Real, O, const L: usize, N, F> {
    lanes: [Option<Lane<'t, T, O>>; L],
    launch: N,
    emit: F,
    mode: [Mode; L],
    /// Where each `Contact` lane stands in its step, and its sub-step (meaningless in the
    /// other modes).
    cursor: [(Cursor<T>, SubPlan<T>); L],
    /// Whether the contact lanes hold the constants of the lane's run.
    constants_set: [bool; L],
    /// Sub-steps the contact lanes ended themselves.
    contact_ended: u64,
}

impl<'t, T, O, const L: usize, N, F> Driver<'t, T, O, L, N, F>
where
    T: Real + 't,
    O: Observer<T>,
    N: FnMut(&mut F) -> Option<Lane<'t, T, O>>,
    F: FnMut(usize, Result<(PointResult, O, &Simulator<'t, T>), ParamError>),
{
    fn drive<K: LaneContact<T>>(&mut self) -> LaneStats {
        let Some(first) = self.lanes.iter().flatten().next() else {
            return LaneStats::default();
        };
        let mut free = Lockstep::<T, K, L>::for_simulator(&first.sim);
        let mut contact = Contact {
            lanes: ContactLanes::<T, K, L>::new(),
            runs: RunLanes::<T, L>::new(),
        };
        for i in 0..L {
            self.settle(i, &mut free, &mut contact, None, true);
        }
        let mut contact_rounds = 0u64;
        let mut contact_steps = 0u64;
        loop {
            let n_free = self.mode.iter().filter(|&&m| m == Mode::Free).count();
            let n_contact = self.mode.iter().filter(|&&m| m == Mode::Contact).count();
            if n_free == 0 && n_contact == 0 {
                break;
            }
            if n_contact > 0 {
                // One sub-step of every lane in contact; the lanes that could not end theirs
                // themselves end it here.
                contact.lanes.run::<ProtocolRun<T>>(&mut contact.runs);
                contact_rounds += 1;
                contact_steps += n_contact as u64;
                for i in 0..L {
                    if self.mode[i] == Mode::Contact && !contact.runs.continues(i) {
                        self.commit(i, &mut free, &mut contact);
                    }
                }
            }
            if n_free > 0 {
                // Whole free-flight steps until a lane stops, or (if lanes wait in contact)
                // for a few rounds.
                let max_rounds = if n_contact > 0 { FREE_ROUNDS } else { u64::MAX };
                let stopped = free.run_at_most(max_rounds);
                for (i, &s) in stopped.iter().enumerate() {
                    if !s {
                        continue;
                    }
                    let mut period_end = false;
                    if let Some(lane) = &mut self.lanes[i]
                        && free.unload(i, &mut lane.sim) > 0
                    {
                        lane.run.after_free_flight(&lane.sim);
                        period_end = lane.sim.at_period_start();
                    }
                    if period_end {
                        // The lane took its period's last step: the Poincaré section, then on.
                        self.end_step(i, true);
                        self.settle(i, &mut free, &mut contact, None, true);
                    } else {
                        // Its next step is one the free-flight lanes do not take.
                        self.settle(i, &mut free, &mut contact, None, false);
                    }
                }
            }
        }
        let (rounds, lane_steps) = free.stats();
        LaneStats {
            lanes: L as u64,
            rounds,
            lane_steps,
            contact_rounds,
            contact_steps,
            contact_ended: self.contact_ended,
        }
    }

    /// Ends the sub-step of `Contact` lane `i` with the contact lanes' result (after taking back
    /// the sub-steps the lane ended itself) and goes on.
    fn commit<K: LaneContact<T>>(
        &mut self,
        i: usize,
        free: &mut Lockstep<'t, T, K, L>,
        contact: &mut Contact<T, K, L>,
    ) {
        let Some(lane) = &mut self.lanes[i] else {
            self.mode[i] = Mode::Idle;
            return;
        };
        let (c, p) = &mut self.cursor[i];
        if let Some((resume, book)) = contact.lanes.resume(&contact.runs, i, p) {
            self.contact_ended += u64::from(resume.substeps);
            lane.sim.resume_substeps(c, &resume);
            lane.run.resume_book(&book);
        }
        let mut period_end = false;
        let done = lane
            .sim
            .commit_substep(c, p, contact.lanes.result(i), &mut |s| {
                period_end |= lane.run.sample(s, &mut lane.obs)
            });
        if done {
            self.end_step(i, period_end);
            self.settle(i, free, contact, None, true);
            return;
        }
        // Most often the next segment is another ordinary sub-step: straight back into the
        // contact lanes (what `settle` would do first, without its loop).
        // (A lane in contact holds its run's constants.)
        if let Some(next) = into_contact::<T, O, K, L>(i, lane, c, contact, false) {
            *p = next;
            return;
        }
        let c = *c;
        self.settle(i, free, contact, Some(c), true);
    }

    /// Ends the step of lane `i` for its protocol; a run that is done is emitted and the next
    /// item takes the lane.
    fn end_step(&mut self, i: usize, period_end: bool) {
        let Some(lane) = &mut self.lanes[i] else {
            return;
        };
        if let Some(result) = lane.run.end_step(&lane.sim, &mut lane.obs, period_end) {
            if let Some(lane) = self.lanes[i].take() {
                (self.emit)(lane.index, Ok((result, lane.obs, &lane.sim)));
            }
            self.lanes[i] = (self.launch)(&mut self.emit);
            self.constants_set[i] = false;
        }
    }

    /// Ordinary segments for the run in lane `i`, from inside its step at `cursor` or from a
    /// step boundary, until its next segment is one the lanes take: whole free-flight steps
    /// (then loaded into the free-flight lanes; not at once if `may_load` is false) or an
    /// ordinary sub-step (then set into the contact lanes). A run that is done is emitted and
    /// the next item takes the lane; the lane stays idle when the items are exhausted.
    fn settle<K: LaneContact<T>>(
        &mut self,
        i: usize,
        free: &mut Lockstep<'t, T, K, L>,
        contact: &mut Contact<T, K, L>,
        mut cursor: Option<Cursor<T>>,
        mut may_load: bool,
    ) {
        loop {
            let Some(lane) = &mut self.lanes[i] else {
                self.mode[i] = Mode::Idle;
                return;
            };
            let mut c = match cursor.take() {
                Some(c) => c,
                None => {
                    if may_load && lane.run.free_flight_allowed::<O>() && free.load(i, &lane.sim) {
                        self.mode[i] = Mode::Free;
                        return;
                    }
                    may_load = true;
                    lane.sim.begin_step()
                }
            };
            let mut period_end = false;
            loop {
                if let Some(p) =
                    into_contact::<T, O, K, L>(i, lane, &c, contact, !self.constants_set[i])
                {
                    self.constants_set[i] = true;
                    self.cursor[i] = (c, p);
                    self.mode[i] = Mode::Contact;
                    return;
                }
                if lane.sim.advance(&mut c, &mut |s| {
                    period_end |= lane.run.sample(s, &mut lane.obs)
                }) {
                    break;
                }
            }
            self.end_step(i, period_end);
        }
    }
}

/// The next segment of the run in `lane` `i`, from `c`, set into the contact lanes if it is an
/// ordinary sub-step they take (observers that ignore per-step samples only), with the
/// simulator's constants if `constants`: that sub-step, or `None` (nothing set).
#[inline(always)]
fn into_contact<T: Real, O: Observer<T>, K: LaneContact<T>, const L: usize>(
    i: usize,
    lane: &Lane<'_, T, O>,
    c: &Cursor<T>,
    contact: &mut Contact<T, K, L>,
    constants: bool,
) -> Option<SubPlan<T>> {
    if O::SAMPLES {
        return None;
    }
    let p = lane.sim.plain_substep(c)?;
    let book = lane.run.sample_book();
    let Contact { lanes, runs } = contact;
    lanes
        .set(runs, i, &lane.sim, &p, &book, constants)
        .then_some(p)
}

/// The contact lanes and what they carry of their runs (two objects: see [`RunLanes`]).
struct Contact<T: Real, K, const L: usize> {
    lanes: ContactLanes<T, K, L>,
    runs: RunLanes<T, L>,
}

/// Runs the canonical protocol from rest at every `(gap_m, omega_ratio)` of `points` (m, `Ω/ω`),
/// `L` at a time interleaved ([`run_interleaved`]), and calls `emit(i, result)` for the `i`-th
/// point as soon as it is done (so not in order; invalid points are emitted at once with their
/// error), each result with the state the run ended on (the simulator's, at phase 0: where
/// `crate::orbit` takes over). Returns how full the lanes were.
pub fn evaluate_interleaved<T: Real, const L: usize, I, F>(
    params: &RigParams,
    settings: &SimSettings,
    points: I,
    mut emit: F,
) -> LaneStats
where
    I: IntoIterator<Item = (f64, f64)>,
    F: FnMut(usize, Result<(PointResult, Vector2<T>), ParamError>),
{
    let weight_n = params.weight_n();
    let phases = match PhaseTable::new(settings.steps.steps_per_period) {
        Ok(p) => p,
        Err(e) => {
            for (i, _) in points.into_iter().enumerate() {
                emit(i, Err(e));
            }
            return LaneStats::default();
        }
    };
    run_interleaved::<T, (), L, _, _, _>(
        points,
        |(gap_m, omega_ratio)| {
            let sim = simulator_at::<T>(params, gap_m, omega_ratio, settings, &phases)?;
            let run = ProtocolRun::new(&sim, &settings.protocol, weight_n)?;
            Ok((sim, run, ()))
        },
        |i, r| emit(i, r.map(|(result, (), sim)| (result, sim.state()))),
    )
}

/// [`evaluate_interleaved`] with [`lanes_per_core`] lanes.
pub fn evaluate_interleaved_native<T: Real, I, F>(
    params: &RigParams,
    settings: &SimSettings,
    points: I,
    emit: F,
) -> LaneStats
where
    I: IntoIterator<Item = (f64, f64)>,
    F: FnMut(usize, Result<(PointResult, Vector2<T>), ParamError>),
{
    if wide_vectors() {
        evaluate_interleaved::<T, WIDE_LANES, I, F>(params, settings, points, emit)
    } else {
        evaluate_interleaved::<T, DEFAULT_LANES, I, F>(params, settings, points, emit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::evaluate_point;
    use crate::integrate::isa::{Isa, with_isa};
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
        evaluate_interleaved::<f32, 3, _, _>(&p, &s, points, |i, r| {
            got[i] = Some(r.map(|(result, _)| result))
        });
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
        let stats = evaluate_interleaved::<T, DEFAULT_LANES, _, _>(
            &p,
            &s,
            points.iter().copied(),
            |i, r| got[i] = Some(r.map(|(result, _)| result)),
        );
        // The paths under test were taken: whole free-flight steps in lanes, contact sub-steps
        // in lanes, most of them ended by the lanes themselves (the rest by the simulator).
        assert!(stats.lane_steps > 0, "{rig:?}: {stats:?}");
        assert!(
            stats.contact_ended > stats.contact_steps / 2
                && stats.contact_ended < stats.contact_steps,
            "{rig:?}: {stats:?}"
        );
        let mut wide = std::vec![None; points.len()];
        evaluate_interleaved::<T, WIDE_LANES, _, _>(&p, &s, points.iter().copied(), |i, r| {
            wide[i] = Some(r.map(|(result, _)| result))
        });
        assert_eq!(
            wide, got,
            "{rig:?}: {WIDE_LANES} lanes against {DEFAULT_LANES}"
        );
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
        // Every instruction set this CPU runs (the kernels' variants give the same bits).
        for isa in Isa::supported() {
            with_isa(isa, || {
                lanes_match_scalar::<f32>(RigId::Wires, &[0.0, 1.0e-3, 2.4e-3, 3.4e-3], &ratios);
                lanes_match_scalar::<f64>(RigId::Wires, &[0.0, 2.4e-3], &ratios);
                lanes_match_scalar::<f32>(RigId::Beam170, &[0.0, 3.0e-3], &ratios);
            });
        }
    }
}

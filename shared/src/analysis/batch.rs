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
//! the other lanes wait without losing their place; switching events and free-flight trials
//! that come near the surface wait to be searched `L` at a time (`integrate::switch_lanes`,
//! `integrate::near::NearLanes`). Results are exactly those of
//! [`super::evaluate_point`] (each run is the same computation, only the order of instructions
//! between runs changes; tested). No allocation; an in-order MCU gains nothing from it.

use nalgebra::Vector2;

use super::response::{SimSettings, simulator_at};
use crate::error::ParamError;

use crate::integrate::contact_lanes::{ContactLanes, RunLanes};
use crate::integrate::free::FreeState;
use crate::integrate::isa::wide_vectors;
use crate::integrate::lane_field::{LaneContact, LaneField};
use crate::integrate::lanes::Lockstep;
use crate::integrate::near::{NearLanes, NearTrial};
use crate::integrate::stepper::{Cursor, EventFound, LaneTrial, PendingSwitch, SubPlan};
use crate::integrate::switch_lanes::SwitchLanes;
use crate::integrate::{PhaseTable, Simulator};
use crate::model::RigParams;
use crate::model::hammer::{BeamFree, WiresFree};
use crate::observe::{Observer, PointResult, ProtocolRun};
use crate::real::Real;

/// Free-flight rounds between two looks at the contact lanes while runs are in contact.
const FREE_ROUNDS: u64 = 4;

/// The contact lanes take a round of sub-steps at once when this many quarters of them are
/// busy (12 of 16 with AVX-512, 6 of 8 otherwise). Fewer wait for others to come, until
/// [`CONTACT_WAIT_ROUNDS`] free-flight rounds have passed since the contact lanes' last round
/// or the free-flight lanes are less than half busy (their sub-steps are the same whenever
/// they are taken: the results do not change).
const CONTACT_CROWD_QUARTERS: usize = 3;

/// Free-flight rounds since the contact lanes' last round after which their busy lanes take a
/// round however few they are (see [`CONTACT_CROWD_QUARTERS`]). Chosen on the 15,300-point
/// grid on one core with AVX-512: a crowd of 12 of 16 lanes and 16 rounds 1.37–1.38 s, against
/// 1.44–1.48 s for a round whenever a lane is busy, 1.42 s for a crowd of 16 and 1.39–1.41 s
/// for a crowd of 8.
const CONTACT_WAIT_ROUNDS: u64 = 16;

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
    /// Switching events of the contact lanes' sub-steps located in the switching-event
    /// lanes, several at once (the rest, one at a time by the stepper).
    pub switches_in_lanes: u64,
    /// Of those, the events whose sub-step the lanes ended too (the state after the event,
    /// lane by lane); the rest the stepper ends from the located time.
    pub switches_ended: u64,
    /// Free-flight trials that came near the surface searched in the near-search lanes,
    /// several at once (the rest, one at a time by the stepper).
    pub nears_in_lanes: u64,
    /// Free-flight trials that came near the surface taken from a free-flight lane that
    /// stopped before that step (the lane's step, not computed again).
    pub lane_trials: u64,
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
        self.switches_in_lanes += o.switches_in_lanes;
        self.switches_ended += o.switches_ended;
        self.nears_in_lanes += o.nears_in_lanes;
        self.lane_trials += o.lane_trials;
    }
}

/// Runs one protocol per item of `items`, `4L` at a time interleaved on `L` free-flight lanes
/// and `L` contact lanes. `start` turns an item into a [`Started`] run (or an error, emitted at
/// once); `emit(i, result)` receives the `i`-th item's result with its observer and final
/// simulator as soon as it is done (so not in order). Returns how full the lanes were.
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
    let mut launch = |emit: &mut F| -> Option<Job<'t, T, O>> {
        for (index, item) in next.by_ref() {
            match start(item) {
                Ok((sim, run, obs)) => {
                    return Some(Job {
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
    let mut runs: [[Run<'t, T, O>; L]; RUNS_PER_LANE] =
        core::array::from_fn(|_| core::array::from_fn(|_| Run::idle()));
    for run in runs.iter_mut().flatten() {
        run.job = launch(&mut emit);
    }
    // The lanes' suspension is the first run's (runs of another one, if any, take ordinary
    // steps only).
    let wires = match runs.iter().flatten().find_map(|r| r.job.as_ref()) {
        Some(job) => job.sim.hammer().is_wires(),
        None => return LaneStats::default(),
    };
    let mut driver = Driver {
        runs,
        launch,
        emit,
        free_owner: [NONE; L],
        contact_owner: [NONE; L],
        contact_constants: [NONE; L],
        free_empty: Ids::new(),
        contact_empty: Ids::new(),
        waits_free: Ids::new(),
        waits_contact: Ids::new(),
        switches: [NONE; L],
        nears: [NONE; L],
        contact_ended: 0,
        switches_in_lanes: 0,
        switches_ended: 0,
        nears_in_lanes: 0,
        lane_trials: 0,
        near_since: 0,
    };
    for s in (0..L).rev() {
        driver.free_empty.push(s);
        driver.contact_empty.push(s);
    }
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

/// Protocol runs in flight per lane: four times as many runs as lanes of each kind, so that
/// the free-flight lanes and the contact lanes each find runs to fill them while runs wait for
/// their switching events and near searches. Chosen on the full thesis grid on 2 cores with
/// AVX-512 (`host-sim peterka`): 19.6–20.1 s CPU against 20.1–20.6 s with three, four pairs
/// of alternating runs; two: 17 % slower on the 15,300-point grid. (The basin-fraction
/// continuation of docs/analysis.md, whose runs are few and long, takes 2.5 % more CPU time
/// with four than with three.)
const RUNS_PER_LANE: usize = 4;

/// No run (an empty lane) or no lane.
const NONE: usize = usize::MAX;

/// How long runs waiting for a near search let the free-flight lanes idle at most: this many
/// rounds of `L` idle slots (a slot: a lane empty for one round) since the first came; then
/// they are searched.
///
/// Switching events are located, and free-flight trials that came near the surface searched,
/// as many at a time as there are lanes of a kind (`L`, one vector register of `f32` per
/// quantity: 16 with AVX-512, 8 otherwise). A contact lane's run whose sub-step holds an event
/// waits (its lane handed on) until `L` wait, or until no run is in contact; a run whose trial
/// comes near waits until `L` wait, until this wait is over, or until no lane is busy.
const NEAR_WAIT_ROUNDS: u64 = 4;

/// Fewer near searches than this, searched when no lane is busy, are searched one at a time
/// (the lanes' 18 rounds cost the same for one search as for `L`).
const NEAR_IN_LANES_AT_LEAST: usize = 3;

/// Fewer switching events than this, located when no run is in contact, are located one at a
/// time (the lanes' rounds cost the same for one search as for `L`).
const SWITCHES_IN_LANES_AT_LEAST: usize = 3;

/// One item's protocol run.
struct Job<'t, T: Real, O> {
    index: usize,
    sim: Simulator<'t, T>,
    run: ProtocolRun<T>,
    obs: O,
}

/// A place for a run in flight. Where it stands is in the lanes' owners (a run in a lane) and
/// the waiting lists (a run waiting for one).
struct Run<'t, T: Real, O> {
    job: Option<Job<'t, T, O>>,
    /// Where a run in the contact lanes or waiting for one stands in its step, and its
    /// sub-step.
    cursor: (Cursor<T>, SubPlan<T>),
    /// Whether the contact lanes take its sub-steps (the linear law, their suspension).
    contact_ok: bool,
    /// Its sub-step's switching event, waiting to be located (the run is in `switches`).
    pending: Option<PendingSwitch<T>>,
    /// Its free-flight trial that came near the surface, waiting to be searched (the run is in
    /// `nears`; its cursor where the trial starts).
    near: Option<NearTrial<T>>,
}

impl<T: Real, O> Run<'_, T, O> {
    fn idle() -> Self {
        Run {
            job: None,
            cursor: Default::default(),
            contact_ok: false,
            pending: None,
            near: None,
        }
    }
}

/// A stack of up to `RUNS_PER_LANE · L` run or lane numbers.
struct Ids<const L: usize> {
    ids: [[usize; L]; RUNS_PER_LANE],
    len: usize,
}

impl<const L: usize> Ids<L> {
    fn new() -> Self {
        Ids {
            ids: [[NONE; L]; RUNS_PER_LANE],
            len: 0,
        }
    }
    #[inline]
    fn push(&mut self, id: usize) {
        self.ids[self.len / L][self.len % L] = id;
        self.len += 1;
    }
    #[inline]
    fn pop(&mut self) -> Option<usize> {
        self.len = self.len.checked_sub(1)?;
        Some(self.ids[self.len / L][self.len % L])
    }
}

/// The runs and lanes of [`run_interleaved`] with its `launch` and `emit`.
struct Driver<'t, T: Real, O, const L: usize, N, F> {
    runs: [[Run<'t, T, O>; L]; RUNS_PER_LANE],
    launch: N,
    emit: F,
    /// The run in each free-flight and each contact lane (`NONE`: empty).
    free_owner: [usize; L],
    contact_owner: [usize; L],
    /// The run whose constants each contact lane holds.
    contact_constants: [usize; L],
    /// Empty lanes, and runs waiting for one.
    free_empty: Ids<L>,
    contact_empty: Ids<L>,
    waits_free: Ids<L>,
    waits_contact: Ids<L>,
    /// The run of each switching-event lane (those set: `SwitchLanes::len`).
    switches: [usize; L],
    /// The run of each near-search lane (those set: `NearLanes::len`).
    nears: [usize; L],
    /// Sub-steps the contact lanes ended themselves.
    contact_ended: u64,
    /// Switching events located in the switching-event lanes.
    switches_in_lanes: u64,
    /// Of those, the events whose sub-step the lanes ended too.
    switches_ended: u64,
    /// Near searches done in the near-search lanes.
    nears_in_lanes: u64,
    /// Near trials taken from the free-flight lanes.
    lane_trials: u64,
    /// The free-flight lanes' idle slots ([`idle_slots`]) when the first of the runs waiting
    /// for a near search came.
    near_since: u64,
}

impl<'t, T, O, const L: usize, N, F> Driver<'t, T, O, L, N, F>
where
    T: Real + 't,
    O: Observer<T>,
    N: FnMut(&mut F) -> Option<Job<'t, T, O>>,
    F: FnMut(usize, Result<(PointResult, O, &Simulator<'t, T>), ParamError>),
{
    #[inline(always)]
    fn run(&mut self, r: usize) -> &mut Run<'t, T, O> {
        &mut self.runs[r / L][r % L]
    }

    fn drive<K: LaneContact<T>>(&mut self) -> LaneStats {
        let Some(first) = self.runs.iter().flatten().find_map(|r| r.job.as_ref()) else {
            return LaneStats::default();
        };
        let mut free = Lockstep::<T, K, L>::for_simulator(&first.sim);
        let mut contact = Contact {
            lanes: ContactLanes::<T, K, L>::for_simulator(&first.sim),
            runs: RunLanes::<T, L>::new(),
            switches: SwitchLanes::new(),
            near: NearLanes::new(),
        };
        for r in 0..RUNS_PER_LANE * L {
            let run = self.run(r);
            run.contact_ok = contact_ok(run.job.as_ref(), &contact);
            self.settle(r, &mut free, &mut contact, false, true, NONE, NONE, None);
        }
        let mut contact_rounds = 0u64;
        let mut contact_steps = 0u64;
        let mut free_since = 0u64;
        loop {
            // Every lane is either held by a run or on its kind's empty stack.
            let n_free = L - self.free_empty.len;
            let n_contact = L - self.contact_empty.len;
            debug_assert_eq!(
                n_free,
                self.free_owner.iter().filter(|&&r| r != NONE).count()
            );
            debug_assert_eq!(
                n_contact,
                self.contact_owner.iter().filter(|&&r| r != NONE).count()
            );
            if n_contact == 0 && contact.switches.len() > 0 {
                // No run in contact to bring another event: those waiting go on now.
                self.locate_switches(&mut free, &mut contact);
                continue;
            }
            if n_free == 0 && n_contact == 0 {
                if contact.near.len() > 0 {
                    self.search_near(&mut free, &mut contact);
                    continue;
                }
                break;
            }
            // The contact lanes take a round when enough of them are busy, when the free-flight
            // lanes are less than half busy (most runs are in contact or waiting), or when
            // enough free-flight rounds have passed since their last; otherwise the free-flight
            // lanes go on.
            let contact_now = n_contact > 0
                && (4 * n_contact >= CONTACT_CROWD_QUARTERS * L
                    || 2 * n_free < L
                    || free_since >= CONTACT_WAIT_ROUNDS);
            if contact_now {
                free_since = 0;
                // One sub-step in every busy contact lane; the lanes that could not end theirs
                // themselves end it here (in the lanes as they were before: a lane set in
                // this pass waits for the next round).
                contact.lanes.run::<ProtocolRun<T>>(&mut contact.runs);
                contact_rounds += 1;
                contact_steps += n_contact as u64;
                // (A lane keeps its run until that run's own commit lets it go: the lanes still
                // to visit keep the owners they had before the pass.)
                let ends = lanes_where::<L>(|s| {
                    (self.contact_owner[s] != NONE) & !contact.runs.continues(s)
                });
                for s in ends {
                    self.commit(self.contact_owner[s], s, &mut free, &mut contact);
                }
            }
            if n_free > 0 {
                // Whole free-flight steps until a lane stops, or (if runs wait in contact)
                // for a few rounds.
                let max_rounds = if n_contact > 0 { FREE_ROUNDS } else { u64::MAX };
                let rounds_before = free.stats().0;
                let stopped = free.run_at_most(max_rounds);
                // (At least one: the wait is bounded even if no lane could step.)
                free_since += (free.stats().0 - rounds_before).max(1);
                for s in LaneMask(stopped) {
                    let r = self.free_owner[s];
                    let mut period_end = false;
                    if let Some(job) = &mut self.run(r).job
                        && free.unload(s, &mut job.sim) > 0
                    {
                        job.run.after_free_flight(&job.sim);
                        period_end = job.sim.at_period_start();
                    }
                    if period_end {
                        // The run took its period's last step: the Poincaré section, then on.
                        self.end_step(r, true, &contact);
                        self.settle(r, &mut free, &mut contact, false, true, s, NONE, None);
                    } else {
                        // Its next step is one the free-flight lanes do not take: a trial that
                        // comes near the surface (the lane's, where it was exact) or another.
                        let trial = free.take_trial(s);
                        self.lane_trials += u64::from(trial.is_some());
                        self.settle(r, &mut free, &mut contact, false, false, s, NONE, trial);
                    }
                }
            }
            if contact.near.len() > 0
                && idle_slots(&free) >= self.near_since + NEAR_WAIT_ROUNDS * L as u64
            {
                // The free-flight lanes have idled long enough while runs wait for their near
                // searches (near the surface is rare where most runs fly free: their empty
                // lanes cost more than searching the few waiting together saves).
                self.search_near(&mut free, &mut contact);
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
            switches_in_lanes: self.switches_in_lanes,
            switches_ended: self.switches_ended,
            nears_in_lanes: self.nears_in_lanes,
            lane_trials: self.lane_trials,
        }
    }

    /// Ends the sub-step of run `r` in contact lane `s` with the lane's result (after taking
    /// back the sub-steps the lane ended itself) and goes on. A sub-step with a switching event
    /// waits, its lane handed on, for its event to be located with others'.
    fn commit<K: LaneContact<T>>(
        &mut self,
        r: usize,
        s: usize,
        free: &mut Lockstep<'t, T, K, L>,
        contact: &mut Contact<T, K, L>,
    ) {
        let run = &mut self.runs[r / L][r % L];
        let Some(job) = &mut run.job else {
            self.settle(r, free, contact, false, true, NONE, s, None);
            return;
        };
        let (c, p) = &mut run.cursor;
        if let Some((resume, book)) = contact.lanes.resume(&contact.runs, s, p) {
            self.contact_ended += u64::from(resume.substeps);
            job.sim.resume_substeps(c, &resume);
            job.run.resume_book(&book);
        }
        let mut period_end = false;
        let done = match contact.lanes.result(&contact.runs, s) {
            LaneTrial::Switches { x, s_end } => {
                // (Built in its place: a copy from the stack, right after the stores that
                // wrote it, stalls on them.)
                let pending = run.pending.insert(job.sim.switch_begin(c, p, x, s_end));
                if let Some(lane) = contact.switches.push(&job.sim, pending) {
                    self.switches[lane] = r;
                    self.release(NONE, s, free, contact);
                    if contact.switches.len() == L {
                        self.locate_switches(free, contact);
                    }
                    return;
                }
                // (The lanes take every run of their suspension and law: not reached.)
                let pending = *pending;
                run.pending = None;
                job.sim
                    .switch_end(c, p, &pending, EventFound::Alone, &mut |smp| {
                        period_end |= job.run.sample(smp, &mut job.obs)
                    })
            }
            trial => job.sim.commit_substep(c, p, trial, &mut |smp| {
                period_end |= job.run.sample(smp, &mut job.obs)
            }),
        };
        self.after_substep(r, s, done, period_end, free, contact);
    }

    /// Locates the switching events of the runs waiting in `switches` (together, in the
    /// switching-event lanes; one alone where those cannot), ends their sub-steps and goes on
    /// with each.
    fn locate_switches<K: LaneContact<T>>(
        &mut self,
        free: &mut Lockstep<'t, T, K, L>,
        contact: &mut Contact<T, K, L>,
    ) {
        let n = contact.switches.len();
        // A few searches cost the lanes as much as a full set: those go alone.
        let found = if n >= SWITCHES_IN_LANES_AT_LEAST {
            contact.switches.locate()
        } else {
            contact.switches.clear();
            [EventFound::Alone; L]
        };
        self.switches_in_lanes += found[..n]
            .iter()
            .filter(|f| !matches!(f, EventFound::Alone))
            .count() as u64;
        self.switches_ended += found[..n]
            .iter()
            .filter(|f| matches!(f, EventFound::Ended(_)))
            .count() as u64;
        let ids = self.switches;
        self.go_on(&ids[..n], &found, free, contact, |run, found| {
            let (Some(job), Some(pending)) = (&mut run.job, run.pending.take()) else {
                return None;
            };
            let (c, p) = &mut run.cursor;
            let mut period_end = false;
            let done = job.sim.switch_end(c, p, &pending, found, &mut |smp| {
                period_end |= job.run.sample(smp, &mut job.obs)
            });
            Some((done, period_end))
        });
    }

    /// Searches the free-flight trials of the runs waiting in `nears` (together, in the
    /// near-search lanes; one alone where those cannot) and goes on with each.
    fn search_near<K: LaneContact<T>>(
        &mut self,
        free: &mut Lockstep<'t, T, K, L>,
        contact: &mut Contact<T, K, L>,
    ) {
        let n = contact.near.len();
        // A few searches cost the lanes as much as a full set: those go alone.
        let found = if n >= NEAR_IN_LANES_AT_LEAST {
            contact.near.search()
        } else {
            contact.near.clear();
            [None; L]
        };
        self.nears_in_lanes += found[..n].iter().filter(|t| t.is_some()).count() as u64;
        let ids = self.nears;
        self.go_on(&ids[..n], &found, free, contact, |run, t| {
            let (Some(job), Some(trial)) = (&mut run.job, run.near.take()) else {
                return None;
            };
            let t_near = t.unwrap_or_else(|| trial.search_alone(job.sim.hammer()));
            let mut period_end = false;
            let done =
                job.sim
                    .advance_near(&mut run.cursor.0, t_near, run.contact_ok, &mut |smp| {
                        period_end |= job.run.sample(smp, &mut job.obs)
                    });
            Some((done, period_end))
        });
    }

    /// Goes on with the runs `ids` after their searches in lanes (`found`, in their order):
    /// `segment` takes each run's segment with its search's result and says whether its step
    /// ended and with it a period (`None`: the run is gone), then [`Driver::after_substep`].
    #[inline(always)]
    fn go_on<K: LaneContact<T>, X: Copy>(
        &mut self,
        ids: &[usize],
        found: &[X],
        free: &mut Lockstep<'t, T, K, L>,
        contact: &mut Contact<T, K, L>,
        mut segment: impl FnMut(&mut Run<'t, T, O>, X) -> Option<(bool, bool)>,
    ) {
        for (&r, &x) in ids.iter().zip(found) {
            if let Some((done, period_end)) = segment(&mut self.runs[r / L][r % L], x) {
                self.after_substep(r, NONE, done, period_end, free, contact);
            }
        }
    }

    /// After run `r`'s sub-step (`done`: its step ended, with the protocol's `period_end`),
    /// holding contact lane `own` (`NONE`: none): its next ordinary sub-step into a contact
    /// lane, or on through [`Driver::settle`].
    fn after_substep<K: LaneContact<T>>(
        &mut self,
        r: usize,
        own: usize,
        done: bool,
        period_end: bool,
        free: &mut Lockstep<'t, T, K, L>,
        contact: &mut Contact<T, K, L>,
    ) {
        if done {
            self.end_step(r, period_end, contact);
            self.settle(r, free, contact, false, true, NONE, own, None);
            return;
        }
        let run = &mut self.runs[r / L][r % L];
        let Some(job) = &mut run.job else {
            self.settle(r, free, contact, false, true, NONE, own, None);
            return;
        };
        let (c, p) = &mut run.cursor;
        // Most often the next segment is another ordinary sub-step: straight into a contact
        // lane (what `settle` would do first, without its loop).
        if run.contact_ok
            && let Some(next) = job.sim.plain_substep(c)
        {
            *p = next;
            match lane_for(own, &mut self.contact_empty) {
                Some(s) => self.enter_contact(r, s, contact),
                None => self.waits_contact.push(r),
            }
            return;
        }
        // (The run's cursor read in `settle`, not copied here: its fields were just stored one by
        // one, and a copy of the whole right after them waits for them.)
        self.settle(r, free, contact, true, true, NONE, own, None);
    }

    /// Ends the step of run `r` for its protocol; a run that is done is emitted and the next
    /// item takes its place.
    fn end_step<K: LaneContact<T>>(
        &mut self,
        r: usize,
        period_end: bool,
        contact: &Contact<T, K, L>,
    ) {
        let run = &mut self.runs[r / L][r % L];
        let Some(job) = &mut run.job else {
            return;
        };
        if let Some(result) = job.run.end_step(&job.sim, &mut job.obs, period_end) {
            if let Some(job) = run.job.take() {
                (self.emit)(job.index, Ok((result, job.obs, &job.sim)));
            }
            run.job = (self.launch)(&mut self.emit);
            run.contact_ok = contact_ok(run.job.as_ref(), contact);
            for owner in self.contact_constants.iter_mut() {
                if *owner == r {
                    *owner = NONE;
                }
            }
        }
    }

    /// Ordinary segments for run `r`, from inside its step at its cursor (`in_step`) or from a step
    /// boundary, until its next segment is one the lanes take: whole free-flight steps (then
    /// loaded into a free-flight lane, or waiting for one; not at once if `may_load` is false)
    /// or an ordinary sub-step (then set into a contact lane, or waiting for one). A run that
    /// is done is emitted and the next item takes its place; the place stays idle when the
    /// items are exhausted. `own_free`, `own_contact`: the lanes the run held (`NONE`: none),
    /// kept if it goes on in one of them, else handed to a waiting run or left empty.
    /// `trial`: the free-flight trial from the step's start that came near the surface, taken
    /// by a lane that stopped before it (with `in_step` and `may_load` false; it stands
    /// for the run's first trial).
    #[allow(clippy::too_many_arguments)]
    fn settle<K: LaneContact<T>>(
        &mut self,
        r: usize,
        free: &mut Lockstep<'t, T, K, L>,
        contact: &mut Contact<T, K, L>,
        mut in_step: bool,
        mut may_load: bool,
        own_free: usize,
        own_contact: usize,
        mut trial: Option<FreeState<T>>,
    ) {
        loop {
            let run = &mut self.runs[r / L][r % L];
            let Some(job) = &mut run.job else {
                self.release(own_free, own_contact, free, contact);
                return;
            };
            let mut c = match core::mem::take(&mut in_step) {
                true => run.cursor.0,
                false => {
                    if may_load && job.run.free_flight_allowed::<O>() && free.accepts(&job.sim) {
                        match lane_for(own_free, &mut self.free_empty) {
                            Some(s) => {
                                free.load(s, &job.sim);
                                self.free_owner[s] = r;
                            }
                            None => self.waits_free.push(r),
                        }
                        self.release(NONE, own_contact, free, contact);
                        return;
                    }
                    may_load = true;
                    job.sim.begin_step()
                }
            };
            let mut period_end = false;
            loop {
                if run.contact_ok
                    && let Some(p) = job.sim.plain_substep(&c)
                {
                    run.cursor = (c, p);
                    match lane_for(own_contact, &mut self.contact_empty) {
                        Some(s) => self.enter_contact(r, s, contact),
                        None => self.waits_contact.push(r),
                    }
                    self.release(own_free, NONE, free, contact);
                    return;
                }
                let mut observe = |smp: &_| period_end |= job.run.sample(smp, &mut job.obs);
                let next = match trial.take() {
                    Some(end) => Err(job.sim.lane_trial(&end)),
                    None => job.sim.advance_until_near(&mut c, &mut observe),
                };
                let done = match next {
                    Ok(done) => done,
                    Err(trial) => {
                        // (Kept in its place at once: see `commit`.)
                        let trial = run.near.insert(trial);
                        if let Some(lane) = contact.near.push(job.sim.hammer(), trial) {
                            if lane == 0 {
                                self.near_since = idle_slots(free);
                            }
                            // (Samples before the trial end no period: the step goes on.)
                            run.cursor.0 = c;
                            self.nears[lane] = r;
                            self.release(own_free, own_contact, free, contact);
                            if contact.near.len() == L {
                                self.search_near(free, contact);
                            }
                            return;
                        }
                        let t_near = trial.search_alone(job.sim.hammer());
                        run.near = None;
                        job.sim
                            .advance_near(&mut c, t_near, run.contact_ok, &mut observe)
                    }
                };
                if done {
                    break;
                }
            }
            self.end_step(r, period_end, contact);
        }
    }

    /// Sets the sub-step in run `r`'s cursor into contact lane `s`.
    fn enter_contact<K: LaneContact<T>>(
        &mut self,
        r: usize,
        s: usize,
        contact: &mut Contact<T, K, L>,
    ) {
        let constants = self.contact_constants[s] != r;
        let run = &mut self.runs[r / L][r % L];
        if let Some(job) = &run.job {
            let book = job.run.sample_book();
            let set = contact.lanes.set(
                &mut contact.runs,
                s,
                &job.sim,
                &run.cursor.1,
                &book,
                constants,
            );
            // The lanes accept every run of their suspension and law (`contact_ok`).
            debug_assert!(set);
        }
        self.contact_owner[s] = r;
        self.contact_constants[s] = r;
    }

    /// Hands free-flight lane `free_lane` and contact lane `contact_lane` (`NONE`: none) to runs
    /// waiting for one, or leaves them empty.
    fn release<K: LaneContact<T>>(
        &mut self,
        free_lane: usize,
        contact_lane: usize,
        free: &mut Lockstep<'t, T, K, L>,
        contact: &mut Contact<T, K, L>,
    ) {
        if free_lane != NONE {
            self.free_owner[free_lane] = NONE;
            match self.waits_free.pop() {
                Some(w) => {
                    if let Some(job) = &self.runs[w / L][w % L].job {
                        free.load(free_lane, &job.sim);
                    }
                    self.free_owner[free_lane] = w;
                }
                None => self.free_empty.push(free_lane),
            }
        }
        if contact_lane != NONE {
            self.contact_owner[contact_lane] = NONE;
            match self.waits_contact.pop() {
                Some(w) => self.enter_contact(w, contact_lane, contact),
                None => self.contact_empty.push(contact_lane),
            }
        }
    }
}

/// The free-flight lanes' idle slots so far: lanes empty for a round, summed over the rounds.
fn idle_slots<T: Real, K: LaneField<T>, const L: usize>(free: &Lockstep<'_, T, K, L>) -> u64 {
    let (rounds, lane_steps) = free.stats();
    rounds * L as u64 - lane_steps
}

/// The lanes `s < L` where `at(s)` holds, in increasing order (taken as a bit mask at once,
/// branch-free, then walked bit by bit: most lanes of a round have nothing to do).
#[inline(always)]
fn lanes_where<const L: usize>(at: impl Fn(usize) -> bool) -> LaneMask {
    const { assert!(L <= 32) };
    let mut mask = 0u32;
    for s in 0..L {
        mask |= u32::from(at(s)) << s;
    }
    LaneMask(mask)
}

/// Lane numbers as the bits of a mask (bit `s`: lane `s`; [`lanes_where`], `Lockstep::run`).
struct LaneMask(u32);

impl Iterator for LaneMask {
    type Item = usize;
    #[inline(always)]
    fn next(&mut self) -> Option<usize> {
        if self.0 == 0 {
            return None;
        }
        let s = self.0.trailing_zeros() as usize;
        self.0 &= self.0 - 1;
        Some(s)
    }
}

/// The lane a run takes: the one it holds (`own`), or an empty one, or none (it waits).
#[inline]
fn lane_for<const L: usize>(own: usize, empty: &mut Ids<L>) -> Option<usize> {
    if own != NONE { Some(own) } else { empty.pop() }
}

/// Whether the contact lanes take `job`'s ordinary sub-steps: an observer that ignores
/// per-step samples, and a simulator of the lanes' suspension with the linear law.
fn contact_ok<T: Real, O: Observer<T>, K: LaneContact<T>, const L: usize>(
    job: Option<&Job<'_, T, O>>,
    contact: &Contact<T, K, L>,
) -> bool {
    job.is_some_and(|j| !O::SAMPLES && contact.lanes.accepts(&j.sim))
}

/// The contact lanes and what they carry of their runs (two objects: see [`RunLanes`]), the
/// switching events of their sub-steps waiting to be located, and the free-flight trials that
/// came near the surface waiting to be searched.
struct Contact<T: Real, K, const L: usize> {
    lanes: ContactLanes<T, K, L>,
    runs: RunLanes<T, L>,
    switches: SwitchLanes<T, K, L>,
    near: NearLanes<T, K, L>,
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
    fn lane_masks_name_the_lanes_in_order() {
        // Against the lanes listed one by one: every subset of 8 lanes, and the 16 of AVX-512.
        for m in 0u32..256 {
            let listed: std::vec::Vec<usize> = (0..8).filter(|&s| m >> s & 1 == 1).collect();
            let walked: std::vec::Vec<usize> = lanes_where::<8>(|s| m >> s & 1 == 1).collect();
            assert_eq!(walked, listed, "mask {m:#b}");
            assert_eq!(LaneMask(m).collect::<std::vec::Vec<_>>(), listed);
        }
        let all: std::vec::Vec<usize> = lanes_where::<16>(|_| true).collect();
        assert_eq!(all, (0..16).collect::<std::vec::Vec<_>>());
        assert_eq!(
            lanes_where::<16>(|s| s == 15).collect::<std::vec::Vec<_>>(),
            [15]
        );
    }

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

    /// The results of `points` on `L` lanes, and how full the lanes were. A function of its
    /// own, kept out of its caller: the drivers of both widths in one frame overflow a test
    /// thread's 2 MiB stack in the release profile.
    #[inline(never)]
    fn interleaved<T: Real, const L: usize>(
        p: &RigParams,
        s: &SimSettings,
        points: &[(f64, f64)],
    ) -> (
        std::vec::Vec<Option<Result<PointResult, ParamError>>>,
        LaneStats,
    ) {
        let mut got = std::vec![None; points.len()];
        let stats = evaluate_interleaved::<T, L, _, _>(p, s, points.iter().copied(), |i, r| {
            got[i] = Some(r.map(|(result, _)| result))
        });
        (got, stats)
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
        let (got, stats) = interleaved::<T, DEFAULT_LANES>(&p, &s, &points);
        let (wide, wide_stats) = interleaved::<T, WIDE_LANES>(&p, &s, &points);
        assert_eq!(
            wide, got,
            "{rig:?}: {WIDE_LANES} lanes against {DEFAULT_LANES}"
        );
        // The paths under test were taken, at both widths (the searches wait for as many runs
        // as there are lanes): whole free-flight steps in lanes, contact sub-steps in lanes,
        // most of them ended by the lanes themselves (the rest by the simulator), switching
        // events and near searches several at once.
        for stats in [stats, wide_stats] {
            assert!(stats.lane_steps > 0, "{rig:?}: {stats:?}");
            assert!(stats.switches_in_lanes > 0, "{rig:?}: {stats:?}");
            assert!(stats.switches_ended > 0, "{rig:?}: {stats:?}");
            assert!(
                stats.switches_ended <= stats.switches_in_lanes,
                "{rig:?}: {stats:?}"
            );
            assert!(stats.nears_in_lanes > 0, "{rig:?}: {stats:?}");
            assert!(stats.lane_trials > 0, "{rig:?}: {stats:?}");
            assert!(
                stats.contact_ended > stats.contact_steps / 2
                    && stats.contact_ended < stats.contact_steps,
                "{rig:?}: {stats:?}"
            );
        }
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

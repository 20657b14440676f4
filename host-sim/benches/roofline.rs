//! The roofline of the grid evaluation (docs/performance.md, "Roofline"): how fast the
//! free-flight kernel runs alone, how fast the grid runs, and where the difference goes. One
//! core, f32, the wire rig (not a criterion bench: each workload is long enough to time).
//!
//! 1. **Kernel**: whole free-flight steps `h = T/N` of as many simulators in lockstep as the
//!    grid interleaves on this CPU (`shared::analysis::lanes_per_core`: 16 with AVX-512, else 8;
//!    `shared::integrate::lanes::free_flight`), every lane busy: wire rig, gap 18 mm (never
//!    reached), Ω/ω from 2.0 in steps of 0.2, all lanes at the same phase, timed inside the
//!    kernel calls only. Lane-steps per second per core.
//! 2. **Grid**: every 49th gap of the thesis grid (gap 0.00–2.94 mm × 1.00–7.11 Hz: 4,284
//!    points, the grid of the instruction count in docs/performance.md) through the same
//!    streamed, interleaved evaluation as `host-sim peterka` on one core
//!    (`shared::analysis::run_interleaved_native` over every point, as
//!    `host_sim::grid::run_streamed` runs it on each core),
//!    on one core. RK4 steps per second per core, by kind ([`shared::integrate::StepCounts`]), and
//!    the lanes' occupancy.
//! 3. **Efficiency** = grid RK4 steps/s ÷ kernel lane-steps/s, and the grid's time split into
//!    the kernel's rounds (busy and idle lanes, at the kernel's measured speed per round) and
//!    the rest (one-at-a-time steps: trials, segments, contact sub-steps, Poincaré sections
//!    and event bookkeeping).
//!
//! Kernel (0.5 s) and grid alternate for a number of rounds (`-- --rounds N`, 1–100, default
//! 5), each round's efficiency its grid against its own kernel; it prints the medians and the
//! rounds' ranges (on a shared or virtual machine one run of either can be a third slower than the next).
//!
//! `cargo bench -p host-sim --bench roofline` (about 10 s after its build; with
//! `VIBRO_ISA=avx2` in the environment, the AVX2 kernels and 8 lanes on an AVX-512 CPU:
//! `shared::integrate::ISA_VAR`). The instruction
//! counts of the same workloads: `-- --kernel-only` or `-- --grid-only` under
//! `valgrind --tool=cachegrind` (docs/performance.md; valgrind hides AVX-512, so what it counts
//! is the 8-lane AVX2 code).

use std::time::Instant;

use shared::analysis::{
    DEFAULT_LANES, LaneStats, SimSettings, WIDE_LANES, lanes_per_core, run_interleaved_native,
    simulator_at,
};
use shared::integrate::lanes::free_flight;
use shared::integrate::{PhaseTable, Simulator, StepCounts};
use shared::model::RigId;
use shared::observe::ProtocolRun;

/// Whole free-flight lane-steps per second per core with every lane busy, and the lane-steps
/// taken (a round of `L` lanes takes `L / rate` seconds).
fn kernel<const L: usize>(seconds: f64) -> (f64, u64) {
    let p = RigId::Wires.preset();
    let s = SimSettings::default();
    let phases = PhaseTable::<f32>::new(s.steps.steps_per_period).expect("valid N");
    let mut sims: Vec<Simulator<f32>> = (0..L)
        .map(|i| {
            let ratio = 2.0 + 0.2 * i as f64;
            simulator_at::<f32>(&p, 0.018, ratio, &s, &phases).expect("valid point")
        })
        .collect();
    let (mut busy, mut steps) = (0.0f64, 0u64);
    let t0 = Instant::now();
    while t0.elapsed().as_secs_f64() < seconds {
        let mut refs: Vec<&mut Simulator<f32>> = sims.iter_mut().collect();
        let t = Instant::now();
        let taken = free_flight::<f32, L>(&mut refs);
        busy += t.elapsed().as_secs_f64();
        assert!(
            taken.iter().all(|&k| k == taken[0] && k > 0),
            "every lane busy: {taken:?}"
        );
        steps += taken.iter().map(|&k| u64::from(k)).sum::<u64>();
        // The period's last step, one at a time (not timed), back to phase 0.
        for sim in sims.iter_mut() {
            sim.step(&mut |_| {});
        }
    }
    (steps as f64 / busy, steps)
}

struct Grid {
    wall: f64,
    counts: StepCounts,
    lanes: LaneStats,
    points: usize,
}

/// The 4,284-point grid on one core.
fn grid() -> Grid {
    let p = RigId::Wires.preset();
    let s = SimSettings::default();
    let phases = PhaseTable::<f32>::new(s.steps.steps_per_period).expect("valid N");
    let fn_hz = p.natural_freq_hz();
    let points: Vec<(f64, f64)> = (0..343)
        .step_by(49)
        .flat_map(|i| {
            (0..612).map(move |j| (f64::from(i) * 1e-5, (1.0 + f64::from(j) * 0.01) / fn_hz))
        })
        .collect();
    // One core: `host-sim peterka` streams every point through one interleaved evaluation per
    // core (`host_sim::grid::run_streamed`).
    let t = Instant::now();
    let mut counts = StepCounts::default();
    let lanes = run_interleaved_native::<f32, (), _, _, _>(
        points.iter().copied(),
        |(gap_m, ratio)| {
            let sim = simulator_at::<f32>(&p, gap_m, ratio, &s, &phases)?;
            let run = ProtocolRun::new(&sim, &s.protocol, p.weight_n())?;
            Ok((sim, run, ()))
        },
        |_, r| {
            let (_, (), sim) = r.expect("valid point");
            counts += sim.counts();
        },
    );
    Grid {
        wall: t.elapsed().as_secs_f64(),
        counts,
        lanes,
        points: points.len(),
    }
}

/// The median of `xs` (the upper one of an even count: one of the values) and its range.
fn median_range(xs: &[f64]) -> (f64, f64, f64) {
    let mut v = xs.to_vec();
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[0], v[v.len() - 1])
}

/// [`kernel`] at the lanes the grid runs on this CPU ([`lanes_per_core`]).
fn native_kernel(seconds: f64) -> (f64, u64) {
    if lanes_per_core() == WIDE_LANES {
        kernel::<WIDE_LANES>(seconds)
    } else {
        kernel::<DEFAULT_LANES>(seconds)
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let kernel_only = args.iter().any(|a| a == "--kernel-only");
    let grid_only = args.iter().any(|a| a == "--grid-only");
    if kernel_only {
        let (_, steps) = native_kernel(0.5);
        println!("kernel: {steps} lane-steps");
        return;
    }
    if grid_only {
        let g = grid();
        println!(
            "grid: {} points, {} RK4 steps",
            g.points,
            g.counts.rk4_steps()
        );
        return;
    }
    // Kernel and grid alternate, so that each round's efficiency compares the two under the
    // same state of the machine (a shared or throttled core moves both); the medians are
    // reported, with the rounds' range.
    let rounds = args
        .iter()
        .position(|a| a == "--rounds")
        .map(
            |i| match args.get(i + 1).and_then(|v| v.parse::<usize>().ok()) {
                Some(n @ 1..=100) => n,
                _ => {
                    eprintln!("roofline: --rounds takes a whole number from 1 to 100");
                    std::process::exit(2);
                }
            },
        )
        .unwrap_or(5);
    let runs: Vec<((f64, u64), Grid)> = (0..rounds).map(|_| (native_kernel(0.5), grid())).collect();
    let lanes = lanes_per_core();
    let isa = shared::integrate::kernel_isa();
    let rates: Vec<f64> = runs.iter().map(|((r, _), _)| *r).collect();
    let walls: Vec<f64> = runs.iter().map(|(_, g)| g.wall).collect();
    let rk4 = runs[0].1.counts.rk4_steps() as f64;
    assert!(
        runs.iter().all(|(_, g)| g.counts == runs[0].1.counts),
        "every round's grid takes the same steps"
    );
    let effs: Vec<f64> = runs.iter().map(|((r, _), g)| rk4 / g.wall / r).collect();
    let (rate, rate_lo, rate_hi) = median_range(&rates);
    let (wall, wall_lo, wall_hi) = median_range(&walls);
    let (eff, eff_lo, eff_hi) = median_range(&effs);
    // The breakdown from the round whose grid took the median time (every round's grid takes
    // the same steps), at the median kernel's speed per round.
    let per_round = lanes as f64 / rate;
    let g = runs
        .into_iter()
        .map(|(_, g)| g)
        .find(|g| g.wall == wall)
        .expect("the median is one of the rounds");
    println!(
        "Kernel (whole free-flight steps, {lanes} lanes busy, {isa}, f32, one core; median of {rounds} rounds alternating with the grid): {:.1} M lane-steps/s ({:.1}–{:.1} M; {:.2} ns per lane-step, {:.1} ns per round)",
        rate / 1e6,
        rate_lo / 1e6,
        rate_hi / 1e6,
        1e9 / rate,
        1e9 * per_round
    );
    let achieved = rk4 / wall;
    println!(
        "Grid (wires, gap 0.00–2.94 mm every 0.49 × 1.00–7.11 Hz: {} points, f32, one core): {:.2} s ({:.2}–{:.2} s), {:.1} M RK4 steps/s ({:.0} ns per RK4 step, {:.0} µs per point)",
        g.points,
        wall,
        wall_lo,
        wall_hi,
        achieved / 1e6,
        1e9 / achieved,
        1e6 * wall / g.points as f64
    );
    println!(
        "Efficiency (grid RK4 steps/s ÷ kernel lane-steps/s, each round's grid against its own kernel): {:.1} % ({:.1}–{:.1} %)",
        100.0 * eff,
        100.0 * eff_lo,
        100.0 * eff_hi
    );
    let c = g.counts;
    let pct = |x: u64| 100.0 * x as f64 / rk4;
    println!(
        "  RK4 steps {:.3e}: lanes {:.1} %, one-at-a-time free-flight trials {:.1} % (of which split near the surface {:.1} %), segments before an arrival {:.1} %, contact sub-steps {:.1} % (+ {:.1} % second steps at switching events)",
        rk4,
        pct(c.lane_steps),
        pct(c.free_trials),
        pct(c.split_trials),
        pct(c.segments),
        pct(c.substeps),
        pct(c.events)
    );
    let slots = g.lanes.rounds * g.lanes.lanes;
    let busy = g.lanes.rounds as f64 * per_round;
    let useful = busy * g.lanes.lane_steps as f64 / slots.max(1) as f64;
    println!(
        "  lanes: {} rounds × {} lanes, {:.1} % of the lane slots busy",
        g.lanes.rounds,
        g.lanes.lanes,
        100.0 * g.lanes.lane_steps as f64 / slots.max(1) as f64
    );
    println!(
        "  time: kernel rounds {:.1} % (busy lanes {:.1} %, idle lanes {:.1} %), one-at-a-time steps and bookkeeping {:.1} %",
        100.0 * busy / g.wall,
        100.0 * useful / g.wall,
        100.0 * (busy - useful) / g.wall,
        100.0 * (g.wall - busy) / g.wall
    );
    println!(
        "  contact lanes: {} rounds × {} lanes, {:.1} % of the lane slots busy ({:.1} % of the sub-steps; {:.1} % of theirs ended by the lanes themselves)",
        g.lanes.contact_rounds,
        g.lanes.lanes,
        100.0 * g.lanes.contact_steps as f64
            / (g.lanes.contact_rounds * g.lanes.lanes).max(1) as f64,
        100.0 * g.lanes.contact_steps as f64 / c.substeps.max(1) as f64,
        100.0 * g.lanes.contact_ended as f64 / g.lanes.contact_steps.max(1) as f64
    );
    println!(
        "  switching events: {:.1} % of {} located several at once in the switching-event lanes, {:.1} % of them with their sub-step ended there too",
        100.0 * g.lanes.switches_in_lanes as f64 / c.events.max(1) as f64,
        c.events,
        100.0 * g.lanes.switches_ended as f64 / g.lanes.switches_in_lanes.max(1) as f64
    );
    println!(
        "  near the surface: {:.1} % of {} split trials searched several at once in the near-search lanes; {:.1} % of them taken from a free-flight lane that stopped before the step",
        100.0 * g.lanes.nears_in_lanes as f64 / c.split_trials.max(1) as f64,
        c.split_trials,
        100.0 * g.lanes.lane_trials as f64 / c.split_trials.max(1) as f64
    );
    let scalar_steps = c.rk4_steps() - c.lane_steps;
    println!(
        "  one at a time: {:.0} ns per RK4 step ({:.3e} steps) against {:.2} ns per lane-step in the kernel",
        1e9 * (g.wall - busy) / scalar_steps.max(1) as f64,
        scalar_steps as f64,
        1e9 / rate
    );
}

//! The grid and basin numbers of docs/performance.md, measured on this machine (not a
//! criterion bench: one run of each workload is long enough to time).
//!
//! 1. The thesis' Peterka grid (wire rig, gap 0.00–3.42 mm × 1.00–7.11 Hz, steps 0.01:
//!    209,916 points, canonical protocol, f32) through the same streamed,
//!    interleaved, parallel evaluation as `host-sim peterka`
//!    (`host_sim::grid::run_streamed`): wall time, points/s, µs per point, where the time goes
//!    (transient lengths, RK4 steps in whole steps vs contact sub-steps), and the peak RSS of
//!    the process.
//! 2. A 200 × 200 basin of attraction through the library path of `host-sim basins` (CSV + PNG
//!    into a temporary directory), with the attractor catalogue (early stop on a known
//!    attractor).
//! 3. Basin fractions of 2,000 random initial conditions through the library path of
//!    `host-sim fractions`: seconds per 1,000 initial conditions.
//!
//! `cargo bench -p host-sim --bench thesis_grid` (about 1 minute on 2 cores after its build);
//! `-- --quick` runs every 7th gap only.

use std::time::Instant;

use shared::analysis::SimSettings;
use shared::model::RigId;
use shared::observe::{PointResult, RecurrenceSettings};

use host_sim::attractors::{ATTRACTOR_STEADY_TOL, Catalogue};
use host_sim::config::Setup;
use host_sim::grid::basins::{self, Attractors, Basins, BasinsGrid, ColorBy};
use host_sim::grid::fractions::{Fractions, FractionsGrid, Parameter, StartBox};
use host_sim::grid::{self, CountSweep, Figures};
use host_sim::output::Outputs;
use host_sim::runner::{OperatingPoint, evaluate_keyed};

fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let setup = Setup::preset(RigId::Wires).expect("wire rig");
    assert_eq!(setup.settings, SimSettings::default());
    let fn_hz = RigId::Wires.preset().natural_freq_hz();
    let gaps: Vec<f64> = (0..343)
        .filter(|i| !quick || i % 7 == 0)
        .map(|i| f64::from(i) * 0.01)
        .collect();
    let points: Vec<OperatingPoint> = gaps
        .iter()
        .flat_map(|&g| {
            (0..612).map(move |j| OperatingPoint {
                gap_m: g * 1e-3,
                omega_ratio: (1.0 + f64::from(j) * 0.01) / fn_hz,
            })
        })
        .collect();
    let t = Instant::now();
    let mut results: Vec<PointResult> = Vec::with_capacity(points.len());
    grid::run_streamed(
        0..points.len(),
        points.len(),
        "",
        &|source: &mut dyn Iterator<Item = usize>, emit: &mut dyn FnMut(usize, _)| {
            evaluate_keyed(&setup, source.map(|i| (i, points[i])), emit)
        },
        |_, r| {
            results.push(r);
            Ok(())
        },
    )
    .expect("valid points");
    let wall = t.elapsed().as_secs_f64();
    let n = results.len() as f64;
    println!(
        "Peterka grid: {} points ({} gaps × 612 frequencies), f32, {} threads",
        results.len(),
        gaps.len(),
        rayon::current_num_threads()
    );
    println!(
        "  wall {wall:.1} s, {:.0} points/s, {:.0} µs per point (wall), {:.0} µs per point per core",
        n / wall,
        1e6 * wall / n,
        1e6 * wall * rayon::current_num_threads() as f64 / n
    );
    if !quick {
        println!("  thesis: 120 h → {:.0}× faster", 120.0 * 3600.0 / wall);
    }
    let observe = f64::from(setup.settings.protocol.observe_periods);
    let periods: f64 = results
        .iter()
        .map(|r| f64::from(r.transient_periods) + observe)
        .sum();
    let rk4: f64 = results.iter().map(|r| r.rk4_steps as f64).sum();
    let whole = periods * f64::from(setup.settings.steps.steps_per_period);
    println!(
        "  simulated periods {:.3e} ({:.0} per point), RK4 steps {:.3e} ({:.0} per period): {:.0} % whole steps h = T/N, {:.0} % free-flight segments and contact sub-steps",
        periods,
        periods / n,
        rk4,
        rk4 / periods,
        100.0 * whole / rk4,
        100.0 * (1.0 - whole / rk4)
    );
    let buckets: [(u32, u32, &str); 5] = [
        (0, 20, "≤ 20"),
        (21, 50, "21–50"),
        (51, 100, "51–100"),
        (101, 199, "101–199"),
        (200, u32::MAX, "200 (limit)"),
    ];
    for (lo, hi, label) in buckets {
        let sel: Vec<&PointResult> = results
            .iter()
            .filter(|r| (lo..=hi).contains(&r.transient_periods))
            .collect();
        let share_pts = sel.len() as f64 / n;
        let share_rk4 = sel.iter().map(|r| r.rk4_steps as f64).sum::<f64>() / rk4;
        println!(
            "  transient {label:>11} periods: {:5.1} % of points, {:5.1} % of RK4 steps",
            100.0 * share_pts,
            100.0 * share_rk4
        );
    }
    match peak_rss_kib() {
        Some(k) => println!(
            "  peak RSS of the benchmark process so far: {:.1} MiB",
            k as f64 / 1024.0
        ),
        None => println!("  peak RSS: not available"),
    }

    // The attractor commands' steady-state tolerance (`--steady-tol` default).
    let mut setup = setup;
    setup.settings.protocol.steady_tol = ATTRACTOR_STEADY_TOL;
    let dir = tempfile::tempdir().expect("temporary directory");
    let csv = dir.path().join("basins.csv");
    let png = dir.path().join("basins.png");
    let grid = BasinsGrid {
        gap_mm: 1.335,
        omega_ratio: 2.0,
        u0_mm: CountSweep::parse("--u0-mm", "-4:1.335:200", -20.0, 20.0).expect("u0 sweep"),
        v0_mm_s: CountSweep::parse("--v0-mm-s", "-100:100:200", -1e4, 1e4).expect("v0 sweep"),
        attractor_tol: 0.01,
        recurrence: RecurrenceSettings::default(),
        color_by: ColorBy::Attractor,
    };
    let catalogue = Catalogue::new(Attractors::scales(&setup.params, grid.omega_ratio), 0.01);
    let meta = grid::meta::<Basins>(&setup, &grid, grid.points()).expect("metadata");
    let t = Instant::now();
    let mut outputs = Outputs::new();
    let out = outputs.reserve(&csv).expect("writable CSV");
    let figures = Figures {
        plot: Some(&png),
        force_plot: None,
        boundaries: None,
        attractors: None,
    };
    grid::run::<Basins, _>(
        &mut outputs,
        &meta,
        &out,
        figures,
        grid::batches(|batch| basins::rows(&setup, &grid, &catalogue, batch)),
    )
    .expect("basins run");
    outputs.commit().expect("outputs");
    println!(
        "Basin of attraction 200 × 200 (wires, gap/A0 1.5, Ω/ω 2.0, Fig. 3.36b), CSV + PNG: {:.1} s",
        t.elapsed().as_secs_f64()
    );

    // 3. Basin fractions by random initial conditions (`host-sim fractions`): the beam rig
    //    (170 mm) at gap 3.0 mm, Ω/ω 1.45, inside its hysteresis (a 1/1 impacting orbit and a
    //    non-impacting one, 81 % / 19 %), 2,000 samples in the box of docs/analysis.md's figure
    //    (u0 −6–3 mm, u̇0 ±300 mm/s), transients up to 1,500 periods.
    let mut beam = Setup::preset(RigId::Beam170).expect("beam rig");
    beam.settings.protocol.max_transient_periods = 1500;
    beam.settings.protocol.steady_tol = ATTRACTOR_STEADY_TOL;
    let grid = FractionsGrid {
        points: vec![(3.0, 1.45)],
        parameter: Parameter::OmegaRatio,
        start: StartBox::Explicit {
            u0_mm: (-6.0, 3.0),
            v0_mm_s: (-300.0, 300.0),
        },
        seed: 1,
        samples: 2000,
        width: None,
        attractor_tol: 0.01,
        match_tol: 0.5,
        recurrence: RecurrenceSettings::default(),
    };
    let meta = grid::meta::<Fractions>(&beam, &grid, 2000).expect("metadata");
    let catalogues = grid.catalogues(&beam);
    let csv = dir.path().join("fractions.csv");
    let t = Instant::now();
    let mut outputs = Outputs::new();
    let out = outputs.reserve(&csv).expect("writable CSV");
    let figures = Figures {
        plot: None,
        force_plot: None,
        boundaries: None,
        attractors: None,
    };
    grid::run::<Fractions, _>(
        &mut outputs,
        &meta,
        &out,
        figures,
        grid::batches(|batch| grid.rows(&beam, &catalogues, batch)),
    )
    .expect("fractions run");
    outputs.commit().expect("outputs");
    let s = t.elapsed().as_secs_f64();
    println!(
        "Basin fractions, 2,000 random ICs (beam 170 mm, gap 3.0 mm, Ω/ω 1.45, two attractors): \
         {s:.2} s, {:.2} s per 1,000 ICs",
        s / 2.0
    );
}

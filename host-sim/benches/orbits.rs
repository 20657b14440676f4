//! The orbit instruments' cost, on one core (criterion, wall time):
//! - `band_edges`: the wire rig's 0.0 mm `1/1` branch continued both ways from its orbit at
//!   Ω/ω 2.0 over its whole band, both edges located (grazing below, period doubling above), in
//!   f32 and f64 — the budget is 1 s;
//! - `response_labelled`: the 1.0 mm response's 46 points (Ω/ω 0.5..5.0 step 0.1) by the
//!   protocol alone, and with the largest Lyapunov exponent labelling each point (periodic:
//!   the orbit's multipliers; otherwise a 64-period window, then an extended run of up to 2,000
//!   periods where it is negative or a confirmation run of up to 2,048 periods with the
//!   tangent where it is not);
//! - `boundaries`: the Peterka map's curves from two seeds (0.0 and 0.9 mm at Ω/ω 2.0).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use host_sim::config::Setup;
use host_sim::orbits::boundary_curves;
use host_sim::precision::Precision;
use host_sim::runner::{OperatingPoint, evaluate_batch, evaluate_batch_labelled};
use shared::Real;
use shared::model::RigId;
use shared::orbit::{
    ContinuationSettings, Edge, LabelSettings, MapPoint, Param, ShootSettings, band_edges,
    orbit_from,
};

fn point(setup: &Setup, gap_m: f64, omega_ratio: f64) -> MapPoint {
    MapPoint {
        params: setup.params,
        settings: setup.settings,
        gap_m,
        omega_ratio,
    }
}

fn bench_edges<T: Real>(c: &mut Criterion, setup: &Setup) {
    let at = point(setup, 0.0, 2.0);
    let (_, orbit) = orbit_from::<T>(&at, 0.0, 0.0, None, &ShootSettings::for_type::<T>()).unwrap();
    let settings = ContinuationSettings::new::<T>(Param::OmegaRatio, [0.5, 5.0]);
    let edges = band_edges(&orbit, &settings);
    for e in &edges {
        if let Edge::Event(ev) = e {
            eprintln!("{}: {} at Ω/ω {:.6}", T::NAME, ev.kind.name(), ev.value);
        }
    }
    let mut g = c.benchmark_group("band_edges/wires/gap0");
    g.sample_size(10);
    g.bench_function(T::NAME, |b| {
        b.iter(|| band_edges(black_box(&orbit), &settings))
    });
    g.finish();
}

fn benches(c: &mut Criterion) {
    // One core, as the budget is stated.
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    let mut setup = Setup::preset(RigId::Wires).unwrap();
    bench_edges::<f32>(c, &setup);
    bench_edges::<f64>(c, &setup);

    setup.precision = Precision::F32;
    let points: Vec<OperatingPoint> = (0..46)
        .map(|k| OperatingPoint {
            gap_m: 1.0e-3,
            omega_ratio: 0.5 + 0.1 * f64::from(k),
        })
        .collect();
    let mut g = c.benchmark_group("response_labelled/wires/gap1.0/46pts");
    g.sample_size(10);
    g.bench_function("protocol", |b| {
        b.iter(|| evaluate_batch(&setup, black_box(&points)))
    });
    g.bench_function("with_lyapunov", |b| {
        b.iter(|| evaluate_batch_labelled(&setup, black_box(&points), &LabelSettings::default()))
    });
    g.finish();

    let base = point(&setup, 0.0, 2.0);
    let seeds = [(0.0, 2.0), (0.9e-3, 1.77)];
    let mut g = c.benchmark_group("boundaries/wires");
    g.sample_size(10);
    g.bench_function("two_seeds_f32", |b| {
        b.iter(|| boundary_curves::<f32>(&base, black_box(&seeds), [0.55, 3.9], [0.0, 3.4e-3]))
    });
    g.finish();
}

criterion_group!(orbits, benches);
criterion_main!(orbits);

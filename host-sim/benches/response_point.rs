//! One frequency-response point (canonical protocol from rest) in f32 and f64:
//! wire rig, 0.0 mm gap, Ω/ω = 2.0 (the main job's 1/1 band) and Ω/ω = 0.6 (chattering
//! multi-impact regime, sub-step heavy). Throughput is in simulated excitation periods, so
//! criterion's `elem/s` reads as periods per second (µs per period = 1e6 / that).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use shared::Real;
use shared::analysis::{SimSettings, evaluate_point};
use shared::model::RigId;

fn bench_point<T: Real>(c: &mut Criterion, omega_ratio: f64) {
    let p = RigId::Wires.preset();
    let s = SimSettings::default();
    let r = evaluate_point::<T>(&p, 0.0, omega_ratio, &s).unwrap();
    let periods = u64::from(r.transient_periods + s.protocol.observe_periods);
    let mut g = c.benchmark_group(format!("response_point/wires/gap0/ratio{omega_ratio}"));
    g.throughput(Throughput::Elements(periods));
    g.sample_size(20);
    g.bench_function(T::NAME, |b| {
        b.iter(|| evaluate_point::<T>(&p, 0.0, std::hint::black_box(omega_ratio), &s).unwrap())
    });
    g.finish();
    eprintln!(
        "{} Ω/ω = {omega_ratio}: {} periods per point ({} transient), {} RK4 steps ({:.0} per period), regime {}",
        T::NAME,
        periods,
        r.transient_periods,
        r.rk4_steps,
        r.rk4_steps as f64 / periods as f64,
        r.regime
    );
}

fn benches(c: &mut Criterion) {
    for ratio in [2.0, 0.6] {
        bench_point::<f32>(c, ratio);
        bench_point::<f64>(c, ratio);
    }
}

criterion_group!(response, benches);
criterion_main!(response);

//! The wire pendulum's viscous damping ratio `ζ` (the project's term `−2ζω θ̇` added to the
//! thesis' Eq. 3-26, docs/model.md):
//! - a free decay of the damped pendulum (no excitation, the surface out of reach, small angle)
//!   follows the closed-form small-angle solution: maxima `θ0 e^{−ζω t_k}` at
//!   `t_k = k 2π/ω_d`, `ω_d = ω sqrt(1 − ζ²)`;
//! - the interleaved analyses (lockstep free-flight lanes and contact lanes, with their damped
//!   kernels) give the one-at-a-time protocol's results bit for bit on a damped wire rig, and
//!   the damping does change them.

use shared::analysis::drop::{DropRecord, DropSpec, run_drop};
use shared::analysis::{DEFAULT_LANES, SimSettings, evaluate_interleaved, evaluate_point};
use shared::integrate::StepSettings;
use shared::model::{RigId, Suspension, SwitchBands};

/// The maxima `(t, θ)` of `θ(t)` from samples `(t, θ, θ̇)`: where `θ̇` turns from positive to
/// non-positive, the stationary point of the cubic Hermite interpolant between the two samples
/// (error O(h⁴), far below the tolerances here).
fn maxima(samples: &[(f64, f64, f64)]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for w in samples.windows(2) {
        let ((t0, x0, v0), (t1, x1, v1)) = (w[0], w[1]);
        if !(v0 > 0.0 && v1 <= 0.0) {
            continue;
        }
        let h = t1 - t0;
        let (m0, m1) = (h * v0, h * v1);
        // p(s) = h00 x0 + h10 m0 + h01 x1 + h11 m1; p'(s) = a s² + b s + c.
        let a = 6.0 * x0 + 3.0 * m0 - 6.0 * x1 + 3.0 * m1;
        let b = -6.0 * x0 - 4.0 * m0 + 6.0 * x1 - 2.0 * m1;
        let c = m0;
        let s = if a.abs() < 1e-300 {
            -c / b
        } else {
            let d = (b * b - 4.0 * a * c).max(0.0).sqrt();
            let (r1, r2) = ((-b + d) / (2.0 * a), (-b - d) / (2.0 * a));
            if (0.0..=1.0).contains(&r1) { r1 } else { r2 }
        };
        let (s2, s3) = (s * s, s * s * s);
        let p = (2.0 * s3 - 3.0 * s2 + 1.0) * x0
            + (s3 - 2.0 * s2 + s) * m0
            + (-2.0 * s3 + 3.0 * s2) * x1
            + (s3 - s2) * m1;
        out.push((t0 + s * h, p));
    }
    out
}

#[test]
fn damped_free_pendulum_follows_the_small_angle_envelope() {
    // θ0 = 0.01 rad released at rest, the surface 18 mm away (the swing reaches 0.75 mm), no
    // excitation, ζ = 0.02 (large enough that ω_d differs from ω by 2e-4, twenty times the
    // tolerance), 12 periods, f64 at 512 steps per period (RK4's error ~1e-10).
    //
    // Tolerance from the small-angle error: sin θ = θ (1 − θ²/6 + …), so the restoring term is
    // off by at most θ0²/6 = 1.7e-5 of itself; the period of the pendulum lengthens by
    // θ_a²/16 ≤ 6.3e-6 (relative), so t_k within 1e-5 · t_k; the peaks within 2e-5 relative
    // (the amplitude-dependent part of the decay, O(θ0²) of ζω t_k ≤ 1.5, stays below it).
    let zeta = 0.02;
    let theta0: f64 = 0.01;
    let p = RigId::Wires.preset().with_damping_ratio(zeta);
    let Suspension::Wires { length_m: l, .. } = p.suspension else {
        unreachable!("the wire preset")
    };
    let gap_m = 0.018;
    let spec = DropSpec {
        gap_m,
        release_m: gap_m + l * theta0.sin(),
        duration_s: 12.2 * 2.0 * std::f64::consts::PI / p.omega_n(),
        max_impacts: 0,
    };
    let steps = StepSettings {
        steps_per_period: 512,
        substeps_per_contact: 16,
    };
    let mut samples: Vec<(f64, f64, f64)> = Vec::new();
    let summary = run_drop::<f64, _>(&p, &spec, &SwitchBands::default(), &steps, |r| {
        if let DropRecord::Sample(s) = r
            && samples.last().is_none_or(|&(t, _, _)| s.t_s > t)
        {
            // u = −l sin θ … the drop starts at u0 = gap − release = −l sin θ0: mirror it so
            // that θ starts at +θ0.
            let theta = -(s.u_m / l).asin();
            let theta_dot = -s.du_m_s / (l * theta.cos());
            samples.push((s.t_s, theta, theta_dot));
        }
    })
    .unwrap();
    assert_eq!(summary.impacts, 0, "the surface is out of reach");
    assert!((samples[0].1 - theta0).abs() < 1e-15);
    let w = p.omega_n();
    let wd = w * (1.0 - zeta * zeta).sqrt();
    let peaks = maxima(&samples);
    assert_eq!(peaks.len(), 12, "{peaks:?}");
    let (mut worst_t, mut worst_x) = (0.0f64, 0.0f64);
    for (k, &(t, x)) in peaks.iter().enumerate() {
        let tk = (k + 1) as f64 * 2.0 * std::f64::consts::PI / wd;
        let xk = theta0 * (-zeta * w * tk).exp();
        worst_t = worst_t.max((t - tk).abs() / tk);
        worst_x = worst_x.max((x - xk).abs() / xk);
        assert!((t - tk).abs() < 1e-5 * tk, "peak {k}: t {t} vs {tk}");
        assert!((x - xk).abs() < 2e-5 * xk, "peak {k}: θ {x} vs {xk}");
        // The undamped frequency would put the peak off by 2e-4 · t_k.
        let t_undamped = (k + 1) as f64 * 2.0 * std::f64::consts::PI / w;
        assert!((t - t_undamped).abs() > 1e-4 * tk);
    }
    // Measured: peak times within 6.1e-6, peaks within 2.6e-6 (relative).
    println!("ζ {zeta}: peak times within {worst_t:.1e}, peaks within {worst_x:.1e} (relative)");

    // `free_decay_periods` read against the simulated decay: the periods (of an excitation at
    // Ω/ω 1.3, none applied here) in which the envelope shrinks from the first peak to the
    // last, times the period, are the time between those peaks.
    let (first, last) = (peaks[0], peaks[peaks.len() - 1]);
    let ratio = 1.3;
    let periods = p.free_decay_periods(ratio, last.1 / first.1).unwrap();
    let elapsed = periods * 2.0 * std::f64::consts::PI / (ratio * w);
    assert!(
        (elapsed - (last.0 - first.0)).abs() < 5e-5 * (last.0 - first.0),
        "{elapsed} s against the peaks' {} s",
        last.0 - first.0
    );
    // Undamped, nothing decays; a factor that is not a shrinking has no answer.
    assert_eq!(RigId::Wires.preset().free_decay_periods(ratio, 0.5), None);
    assert_eq!(p.free_decay_periods(ratio, 1.5), None);
    assert_eq!(p.free_decay_periods(f64::NAN, 0.5), None);
}

#[test]
fn damped_wire_rig_interleaved_equals_one_at_a_time() {
    // The lockstep free-flight lanes and the contact lanes run their `Damped` kernels on a
    // damped pendulum; every result and final state must be the one-at-a-time protocol's
    // (which takes the viscous term through `AsSet`), bit for bit, in f32 and f64.
    fn check<T: shared::Real>(zeta: f64, gaps_m: &[f64], ratios: &[f64]) -> usize {
        let p = RigId::Wires.preset().with_damping_ratio(zeta);
        let s = SimSettings::default();
        let points: Vec<(f64, f64)> = gaps_m
            .iter()
            .flat_map(|&g| ratios.iter().map(move |&r| (g, r)))
            .collect();
        let mut got = vec![None; points.len()];
        let stats = evaluate_interleaved::<T, DEFAULT_LANES, _, _>(
            &p,
            &s,
            points.iter().copied(),
            |i, r| got[i] = Some(r.unwrap()),
        );
        assert!(stats.lane_steps > 0 && stats.contact_steps > 0, "{stats:?}");
        let undamped = RigId::Wires.preset();
        let mut changed = 0;
        for (i, &(g, r)) in points.iter().enumerate() {
            let (result, _) = got[i].unwrap();
            let one = evaluate_point::<T>(&p, g, r, &s).unwrap();
            assert_eq!(result, one, "ζ {zeta} gap {g} Ω/ω {r}");
            if one != evaluate_point::<T>(&undamped, g, r, &s).unwrap() {
                changed += 1;
            }
        }
        changed
    }
    let ratios = [0.55, 0.9, 1.4, 1.9, 2.0, 2.7, 3.3, 3.8, 4.6];
    let changed = check::<f32>(0.003, &[0.0, 1.0e-3, 2.4e-3, 3.4e-3], &ratios)
        + check::<f64>(0.003, &[0.0, 2.4e-3], &ratios);
    // The damping changes the results (else this test could not fail on a lost term).
    assert!(changed > 0, "ζ = 0.003 changed no result");
}

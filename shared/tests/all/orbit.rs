//! Evidence for the periodic-orbit tools (`shared::orbit`): the monodromy matrix from dual
//! numbers against finite differences of the stroboscopic map and against Liouville's formula,
//! the free linear oscillator against RK4's closed form, the located edges of the wire rig's
//! `1/1` band and the beam's fold and grazing against brute-force sweeps of the map, and the
//! f32 edges against f64.
//!
//! `cargo test --release -p vibro-shared --test all orbit:: -- --nocapture` prints every measured value.

use std::ops::ControlFlow;

use nalgebra::Vector2;
use shared::Real;
use shared::analysis::SimSettings;
use shared::integrate::{StepSample, StepSettings};
use shared::model::{ContactLaw, ContactLawKind, RigId, Suspension};
use shared::observe::Regime;
use shared::orbit::{
    BifEvent, BranchPoint, ContinuationSettings, Edge, EventKind, MapPoint, Orbit, OrbitError,
    Param, ShootSettings, SignChanges, Stability, band_edges, continue_branch, doubling_start,
    iterate, orbit_from, samples, shoot, tangent,
};

/// The map of `rig` with `law` at `gap_mm` and `omega_ratio`, host profile (`N = 64`, `K = 16`).
fn point(rig: RigId, law: ContactLawKind, gap_mm: f64, omega_ratio: f64) -> MapPoint {
    let mut params = rig.preset();
    params.contact = ContactLaw::preset(law);
    MapPoint {
        params,
        settings: SimSettings::default(),
        gap_m: gap_mm * 1e-3,
        omega_ratio,
    }
}

/// The orbit the protocol settles on from rest (its period), found by shooting; with the
/// protocol's regime.
fn orbit_at<T: Real>(at: &MapPoint) -> (Regime, Orbit<T>) {
    let (result, orbit) = orbit_from::<T>(at, 0.0, 0.0, None, &ShootSettings::for_type::<T>())
        .unwrap_or_else(|e| {
            panic!(
                "no orbit at Ω/ω {}, gap {} mm: {e}",
                at.omega_ratio,
                at.gap_m * 1e3
            )
        });
    (result.regime, orbit)
}

/// `m` in the cart's units `S⁻¹ M S` (`S = diag(scales)`): dimensionless entries.
fn scaled(at: &MapPoint, m: &[[f64; 2]; 2]) -> [[f64; 2]; 2] {
    let s = at.scales();
    let mut out = [[0.0; 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            out[i][j] = m[i][j] * s[j] / s[i];
        }
    }
    out
}

fn max_abs(m: &[[f64; 2]; 2]) -> f64 {
    m.iter().flatten().fold(0.0, |a: f64, v| a.max(v.abs()))
}

/// Column `j` of `DP^q(x)` (scaled) by finite differences of [`iterate`] in f64, and how well
/// the two finest-agreeing estimates agreed (scaled).
///
/// The map is piecewise smooth: its switching events and the split of a step that nears the
/// surface are located to round-off (`shared::orbit::map`), but its pieces meet at kinks and
/// jumps where the orbit's discretisation changes (a sub-step more or less; with Hunt–Crossley
/// near enough to stall Newton: [`newton_without_descent_stalls_and_says_so`]). Dual numbers
/// give the derivative of the smooth piece through `x`; the
/// differences are taken on it: one-sided (a jump lies on one side at most), Richardson-
/// extrapolated `2 D(h/2) − D(h)`, over a ladder of steps `h` from 1e-4 to 1e-8 of the scales on
/// both sides, keeping the estimate that agrees best with the next larger step (truncation
/// falls and rounding rises as `h` shrinks; an estimate across a jump disagrees with its
/// neighbour by the jump over `h`).
fn fd_column(at: &MapPoint, q: u32, x: Vector2<f64>, j: usize) -> ([f64; 2], f64) {
    let s = at.scales();
    let base = iterate(at, q, x).unwrap().x;
    let one_sided = |h: f64| {
        let mut xp = x;
        xp[j] += h * s[j];
        let dx = xp[j] - x[j];
        let y = iterate(at, q, xp).unwrap().x;
        [
            (y[0] - base[0]) / dx * s[j] / s[0],
            (y[1] - base[1]) / dx * s[j] / s[1],
        ]
    };
    let mut best = (f64::INFINITY, [f64::NAN; 2]);
    for side in [1.0, -1.0] {
        let mut coarser: Option<[f64; 2]> = None;
        for k in 0..13 {
            let h = side * 1e-4 * 10f64.powf(-f64::from(k) / 3.0);
            let (d1, d2) = (one_sided(h), one_sided(0.5 * h));
            let r = [2.0 * d2[0] - d1[0], 2.0 * d2[1] - d1[1]];
            if let Some(c) = coarser {
                let agree = (r[0] - c[0]).abs().max((r[1] - c[1]).abs());
                if agree < best.0 {
                    best = (agree, r);
                }
            }
            coarser = Some(r);
        }
    }
    (best.1, best.0)
}

/// The largest entry error of the dual-number monodromy of `o` against finite differences,
/// relative to its largest entry (both scaled), and the differences' own agreement likewise.
fn monodromy_vs_fd(o: &Orbit<f64>) -> (f64, f64) {
    let at = &o.at;
    let (_, m) = tangent(at, o.q, o.x).unwrap();
    assert_eq!(m, o.monodromy, "shooting's monodromy is the map's");
    let m = scaled(at, &m);
    let norm = max_abs(&m);
    let (mut err, mut agree) = (0.0f64, 0.0f64);
    let columns = [[m[0][0], m[1][0]], [m[0][1], m[1][1]]];
    for (j, column) in columns.iter().enumerate() {
        let (c, a) = fd_column(at, o.q, o.x, j);
        agree = agree.max(a / norm);
        for (ci, mi) in c.iter().zip(column) {
            err = err.max((ci - mi).abs() / norm);
        }
    }
    (err, agree)
}

#[test]
fn monodromy_equals_finite_differences_of_the_map() {
    // (rig, law, gap mm, Ω/ω, expected p/q). Hertz is taken on the beam: on the wire pendulum
    // (no viscous damping) the elastic law leaves the rig conservative and the protocol finds
    // no periodic orbit at Ω/ω 2.0 (nor from the other laws' orbits by Newton); the beam at
    // 0.0 mm and Ω/ω 0.5 settles on a 3/1 orbit.
    let cases = [
        (
            RigId::Wires,
            ContactLawKind::SpringDashpot,
            0.0,
            2.0,
            (1, 1),
        ),
        (
            RigId::Wires,
            ContactLawKind::SpringDashpot,
            0.0,
            2.75,
            (2, 2),
        ),
        (
            RigId::Beam170,
            ContactLawKind::SpringDashpot,
            3.0,
            1.35,
            (1, 1),
        ),
        (RigId::Wires, ContactLawKind::HuntCrossley, 0.0, 2.0, (1, 1)),
        (
            RigId::Wires,
            ContactLawKind::LankaraniNikravesh,
            0.0,
            2.0,
            (1, 1),
        ),
        (RigId::Beam170, ContactLawKind::Hertz, 0.0, 0.5, (3, 1)),
    ];
    for (rig, law, gap_mm, ratio, (p, q)) in cases {
        let at = point(rig, law, gap_mm, ratio);
        let (regime, o) = orbit_at::<f64>(&at);
        assert_eq!((o.p(), o.q), (p, q), "{rig} {law} Ω/ω {ratio}: {regime}");
        let (err, agree) = monodromy_vs_fd(&o);
        println!(
            "{rig} {law} {gap_mm} mm Ω/ω {ratio} ({p}/{q}, max|μ| {:.5}): dual vs FD {err:.2e}, \
             FD steps agree to {agree:.2e}",
            o.floquet.max_abs()
        );
        // Measured: 4.2e-7 (wires 1/1), 5.4e-8 (2/2), 1.9e-8 (beam), 3.0e-8 (Hunt–Crossley),
        // 4.4e-8 (Lankarani–Nikravesh), 1.8e-9 (Hertz, beam).
        assert!(
            agree < 1e-6,
            "{rig} {law} Ω/ω {ratio}: FD unconverged {agree:e}"
        );
        assert!(err < 1e-5, "{rig} {law} Ω/ω {ratio}: dual vs FD {err:e}");
    }
}

#[test]
fn the_2_2_orbit_lies_beyond_the_doubling() {
    // At Ω/ω 2.75 (wire rig, 0.0 mm) the protocol settles on 2/2, the period-2 orbit born at
    // the doubling at 2.66037; the 1/1 orbit is still there, with a multiplier beyond −1.
    let at = point(RigId::Wires, ContactLawKind::SpringDashpot, 0.0, 2.75);
    let (regime, o2) = orbit_at::<f64>(&at);
    assert_eq!(regime, Regime::Periodic { p: 2, q: 2 });
    assert!(o2.floquet.stable());
    let one = shoot(&at, 1, o2.x, &ShootSettings::for_type::<f64>()).unwrap();
    let mu = one.floquet.mu;
    println!(
        "Ω/ω 2.75: 2/2 max|μ| {:.4}; 1/1 μ {mu:?}",
        o2.floquet.max_abs()
    );
    assert_eq!(one.p(), 1);
    assert!(mu[0].im == 0.0 && mu[0].re < -1.0, "1/1 multipliers {mu:?}");
}

/// Just before the doubling (Ω/ω 2.66, the wire rig's 1/1 at 0.0 mm with μ = −0.998) the
/// protocol's window still alternates (`2/2`) and shooting at `q = 2` converges to the 1/1
/// orbit only as closely as `1/(1 − μ²)` allows, far above the tolerance: it is reported at
/// its minimal period all the same, the multiplier P's own (not its square, a "fold"); so in
/// f32 at Ω/ω 2.6 asked at q = 2 and 3 (μ = −0.656). Just past the doubling (2.661) the 2/2
/// orbit, 0.2 mm across, stays 2/2.
#[test]
fn an_orbit_near_a_doubling_is_reported_at_its_minimal_period() {
    let settings = ShootSettings::for_type::<f64>();
    let at = point(RigId::Wires, ContactLawKind::SpringDashpot, 0.0, 2.66);
    let (regime, o) = orbit_at::<f64>(&at);
    assert_eq!(regime, Regime::Periodic { p: 2, q: 2 });
    let one = shoot(&at, 1, o.x, &settings).unwrap();
    println!(
        "Ω/ω 2.66: reported q {} μ {:?}; P's own μ {:?}",
        o.q, o.floquet.mu, one.floquet.mu
    );
    assert_eq!((o.q, o.p()), (1, 1));
    assert_eq!(o.floquet.mu, one.floquet.mu);
    let mu = o.floquet.mu[0];
    assert!(mu.im == 0.0 && (-1.0..-0.99).contains(&mu.re), "{mu:?}");
    // The q = 2 orbit from the same start, left unreduced, is P's orbit twice: its points
    // within its error of each other, far outside the tolerance.
    let (_, x) = shared::orbit::settle::<f64>(&at, 0.0, 0.0).unwrap();
    let two = shoot(&at, 2, x, &settings).unwrap();
    let apart = scaled_distance(&at, &iterate(&at, 1, two.x).unwrap().x, &two.x);
    println!(
        "q = 2 orbit's points {apart:.2e} apart (scaled), μ {:?}",
        two.floquet.mu
    );
    assert!(apart > settings.tolerance && apart < 1e-6, "{apart:e}");
    let back = shared::orbit::minimal_period(&at, two, &settings);
    assert_eq!(back.q, 1);
    assert!(scaled_distance(&at, &back.x, &one.x) < 1e-10);

    let f32_settings = ShootSettings::for_type::<f32>();
    let at = point(RigId::Wires, ContactLawKind::SpringDashpot, 0.0, 2.6);
    for q in [2, 3] {
        let (_, o) = orbit_from::<f32>(&at, 0.0, 0.0, Some(q), &f32_settings).unwrap();
        assert_eq!((o.q, o.p()), (1, 1), "f32, asked q = {q}");
        assert!(
            (o.floquet.max_abs() - 0.6557).abs() < 1e-3,
            "{:?}",
            o.floquet.mu
        );
    }

    let at = point(RigId::Wires, ContactLawKind::SpringDashpot, 0.0, 2.661);
    let (_, o) = orbit_at::<f64>(&at);
    assert_eq!((o.q, o.p()), (2, 2));
    let across = scaled_distance(&at, &iterate(&at, 1, o.x).unwrap().x, &o.x);
    assert!(across > 0.1, "{across}");
}

#[test]
fn resting_orbit_forgets_its_state() {
    // Wire rig, 0.0 mm, Ω/ω 0.6: three impacts, then the hammer rests on the surface for a
    // quarter of the period before the cart pulls it off. While it rests, contact damping
    // contracts every perturbation by exp(−(c/m) t) (e^-900 over 0.22 s): the monodromy is
    // 0 to double precision, and the map is locally constant.
    let at = point(RigId::Wires, ContactLawKind::SpringDashpot, 0.0, 0.6);
    let (_, o) = orbit_at::<f64>(&at);
    assert_eq!((o.p(), o.q), (3, 1));
    let period = 2.0 * std::f64::consts::PI / (0.6 * at.params.omega_n());
    let h = period / f64::from(at.settings.steps.steps_per_period);
    let (mut prev, mut run, mut longest) = (None::<(f64, bool)>, 0.0, 0.0f64);
    samples(&at, 1, o.x, |s: &StepSample<f64>| {
        let (t, touching) = (s.time_s(h), s.region.touching());
        if let Some((t0, was)) = prev {
            run = if was && touching { run + t - t0 } else { 0.0 };
            longest = longest.max(run);
        }
        prev = Some((t, touching));
    })
    .unwrap();
    println!(
        "Ω/ω 0.6: longest touching interval {:.3} of the period; M = {:?}",
        longest / period,
        o.monodromy
    );
    // Measured: 0.246 of the period; |M| 2e-161.
    assert!(longest > 0.2 * period, "longest contact {longest} s");
    let m = scaled(&at, &o.monodromy);
    assert!(max_abs(&m) < 1e-100, "{m:?}");
    for j in 0..2 {
        let (c, _) = fd_column(&at, 1, o.x, j);
        assert!(c[0].abs() < 1e-9 && c[1].abs() < 1e-9, "column {j}: {c:?}");
    }
}

/// `∫ div f dt` over `q` periods of the spring–dashpot rig from `x` at `at`, from the simulator's
/// samples: `div f = ∂ẋ₂/∂x₂` is `−2ζω − c_i cos θ / m` in contact, `−2ζω` in free flight for
/// the wire pendulum (`θ̈ = … − F_i/(m l) − 2ζω θ̇`, `F_i = k δ + c δ̇`, `δ̇ = l θ̇ cos θ`;
/// Eq. 3-26/3-27 with the project's viscous term) and `−2ζω − c_i/m`
/// in contact, `−2ζω` in free flight for the beam (Eq. 3-36/3-37). The contact intervals run
/// from the arrival (`δ = 0`) to the departure (`h_β = k δ + c δ̇ = 0`), each located by linear
/// interpolation between the samples either side; `cos θ` is integrated by trapezoids over the
/// contact samples. The impacts' saltation matrices have determinant 1 (the arrival surface
/// `δ = 0` depends on the position alone and the velocity is continuous; at the departure the
/// force is continuous), so `det M = exp(∫ div f dt)` (Liouville). Returns the integral and
/// the contact intervals found.
fn divergence_integral(at: &MapPoint, q: u32, x: Vector2<f64>) -> (f64, u32) {
    let ContactLaw::SpringDashpot {
        stiffness_n_m: k,
        damping_n_s_m: c,
    } = at.params.contact
    else {
        panic!("spring–dashpot only")
    };
    let omega_exc = at.omega_ratio * at.params.omega_n();
    let period = 2.0 * std::f64::consts::PI / omega_exc;
    let h = period / f64::from(at.settings.steps.steps_per_period);
    let (wires, viscous) = match at.params.suspension {
        Suspension::Wires { damping_ratio, .. } => {
            (true, 2.0 * damping_ratio * at.params.omega_n())
        }
        Suspension::Beam { damping_ratio, .. } => {
            (false, 2.0 * damping_ratio * at.params.omega_n())
        }
    };
    // (time, touching, δ, h_β, cos θ)
    let mut prev: Option<(f64, bool, f64, f64, f64)> = None;
    let (mut cos_integral, mut contacts) = (0.0, 0);
    samples(at, q, x, |s: &StepSample<f64>| {
        let cos = if wires { s.x[0].cos() } else { 1.0 };
        let now = (
            s.time_s(h),
            s.region.touching(),
            s.delta,
            k * s.delta + c * s.delta_dot,
            cos,
        );
        if let Some(p) = prev {
            match (p.1, now.1) {
                (true, true) => cos_integral += 0.5 * (p.4 + now.4) * (now.0 - p.0),
                (false, true) => {
                    contacts += 1;
                    let t_arrival = p.0 + (now.0 - p.0) * (-p.2) / (now.2 - p.2);
                    cos_integral += now.4 * (now.0 - t_arrival);
                }
                (true, false) => {
                    let t_departure = p.0 + (now.0 - p.0) * p.3 / (p.3 - now.3);
                    cos_integral += p.4 * (t_departure - p.0);
                }
                (false, false) => {}
            }
        }
        prev = Some(now);
    })
    .unwrap();
    let m = at.params.mass_kg;
    (
        -(c / m) * cos_integral - viscous * f64::from(q) * period,
        contacts,
    )
}

/// `at` with `N` steps per period and `K` contact sub-steps.
fn with_steps(at: &MapPoint, n: u32, k: u32) -> MapPoint {
    let mut p = *at;
    p.settings.steps = StepSettings {
        steps_per_period: n,
        substeps_per_contact: k,
    };
    p
}

#[test]
fn det_monodromy_follows_liouville() {
    // The reference integral is taken along the orbit at the finest steps (N = 512, K = 1024:
    // sub-steps of 0.7 µs, where the interpolated contact ends are good to ~1e-9 s); at
    // N = 256, K = 512 it agrees within 2e-6. The production steps (N = 64, K = 16) and twice
    // them are compared with it: RK4's error in det M falls with the fourth power of the step.
    // (rig, ζ of the pendulum, gap, Ω/ω): the damped pendulum (the project's viscous term)
    // checks that the variational run carries −2ζω.
    let cases = [
        (RigId::Wires, 0.0, 0.0, 2.0),
        (RigId::Wires, 0.0, 0.0, 2.75),
        (RigId::Wires, 0.003, 0.0, 2.0),
        (RigId::Beam170, 0.004, 3.0, 1.35),
    ];
    let newton = ShootSettings::for_type::<f64>();
    for (rig, zeta, gap_mm, ratio) in cases {
        let mut at = point(rig, ContactLawKind::SpringDashpot, gap_mm, ratio);
        at.params = at.params.with_damping_ratio(zeta);
        let (_, o) = orbit_at::<f64>(&at);
        let reference = |n, k| {
            let fine = with_steps(&at, n, k);
            let of = shoot(&fine, o.q, o.x, &newton).unwrap();
            divergence_integral(&fine, o.q, of.x)
        };
        let ((div, contacts), (div_half, _)) = (reference(512, 1024), reference(256, 512));
        assert_eq!(contacts, o.p(), "one contact interval per impact");
        assert!(
            (div - div_half).abs() < 2e-6,
            "reference {div} vs {div_half}"
        );
        let ln_det = |n, k| {
            let a = with_steps(&at, n, k);
            shoot(&a, o.q, o.x, &newton).unwrap().floquet.det.ln()
        };
        let e1 = (ln_det(64, 16) - div).abs();
        let e2 = (ln_det(128, 32) - div).abs();
        println!(
            "{rig} ζ {zeta} {gap_mm} mm Ω/ω {ratio} ({}/{}): ∫div f dt = {div:.8}; ln det M − ∫div: \
             {e1:.2e} (N 64, K 16), {e2:.2e} (N 128, K 32): {:.0}× closer",
            o.p(),
            o.q,
            e1 / e2
        );
        // Measured: 7.8e-5 → 3.0e-6 (wires 1/1; damped ζ 0.003: 7.7e-5 → 3.3e-6, against
        // its −2ζωT = −0.019), 1.8e-4 → 1.2e-7 (2/2, two impacts),
        // 1.1e-4 → 4.2e-6 (beam): per impact within 1.1e-4, and 17–1400× closer.
        assert!(
            e1 < 1.5e-4 * f64::from(o.p()),
            "{rig} Ω/ω {ratio}: ln det M − ∫div = {e1:e}"
        );
        assert!(
            e2 < 0.1 * e1,
            "{rig} Ω/ω {ratio}: doubled steps {e2:e} vs {e1:e}"
        );
    }
}

#[test]
fn hertz_contact_conserves_phase_area() {
    // The Hertz law is elastic: its contacts add nothing to the divergence, and on the beam
    // det M → exp(−2ζω qT) as the steps shrink, whatever the impacts (beam-170, 0.0 mm,
    // Ω/ω 0.5, a 3/1 orbit with three impacts per period). The RK4 map's own determinant
    // differs from it by the integrator's error, which the stiff Hertz contact makes the
    // largest of the laws at the production steps.
    let at = point(RigId::Beam170, ContactLawKind::Hertz, 0.0, 0.5);
    let (_, o) = orbit_at::<f64>(&at);
    assert_eq!((o.p(), o.q), (3, 1));
    let Suspension::Beam { damping_ratio, .. } = at.params.suspension else {
        unreachable!()
    };
    let w = at.params.omega_n();
    let expect = -2.0 * damping_ratio * w * f64::from(o.q) * 2.0 * std::f64::consts::PI
        / (at.omega_ratio * w);
    let err = |n, k| {
        let a = with_steps(&at, n, k);
        let orbit = shoot(&a, o.q, o.x, &ShootSettings::for_type::<f64>()).unwrap();
        assert_eq!(orbit.p(), 3, "N {n}, K {k}");
        orbit.floquet.det.ln() - expect
    };
    let (e1, e2, e4) = (err(64, 16), err(128, 32), err(256, 64));
    println!(
        "Hertz, beam Ω/ω 0.5: −2ζωT = {expect:.8}; ln det M − it: {e1:.2e} (N 64, K 16), \
         {e2:.2e} (N 128, K 32), {e4:.2e} (N 256, K 64)"
    );
    // Measured: 4.1e-4, 3.9e-5, 1.3e-5.
    assert!(e1.abs() < 1e-3, "{e1:e}");
    assert!(e2.abs() < 0.2 * e1.abs(), "{e2:e} vs {e1:e}");
    assert!(e4.abs() < e2.abs(), "{e4:e} vs {e2:e}");
}

/// `a b` for 2 × 2 matrices.
fn mul(a: &[[f64; 2]; 2], b: &[[f64; 2]; 2]) -> [[f64; 2]; 2] {
    let mut c = [[0.0; 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j];
        }
    }
    c
}

/// Complex `(re, im)` product.
fn cmul(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}

#[test]
fn free_oscillator_multipliers_are_rk4s_closed_form() {
    // The beam far from the surface (50 mm gap) is the linear oscillator ü = −2ζω u̇ − ω² u
    // plus the cart's drive and the thesis' cubic term ω² u³ (Eq. 3-36), which `RigParams`
    // cannot switch off; with the cart's amplitude at its floor, 1e-7 m, u stays below 1e-6 m
    // and the cubic term shifts the stiffness by 3u² < 3e-12 relative. The simulator takes
    // N = 64 whole free-flight RK4 steps of h = T/N per period (StepPlan: h = 2π/Ω/N), so
    // M = R(hA)^N with R(z) = 1 + z + z²/2 + z³/6 + z⁴/24, A = [[0, 1], [−ω², −2ζω]], and the
    // multipliers are R(hλ±)^N, λ± = (−ζ ± i√(1 − ζ²)) ω.
    // (Ω/ω away from 2/k, where ωT is a multiple of 2π and the pair nearly a double root.)
    for ratio in [0.7, 1.35, 3.0] {
        let mut at = point(RigId::Beam170, ContactLawKind::SpringDashpot, 50.0, ratio);
        at.params.amplitude_m = 1e-7;
        let (regime, o) = orbit_at::<f64>(&at);
        assert_eq!(regime, Regime::NoImpact);
        let Suspension::Beam { damping_ratio, .. } = at.params.suspension else {
            unreachable!()
        };
        let (w, z) = (at.params.omega_n(), damping_ratio);
        let n = at.settings.steps.steps_per_period;
        let h = 2.0 * std::f64::consts::PI / (ratio * w) / f64::from(n);
        // R(hA) by Horner's rule on the matrix, then its N-th power.
        let ha = [[0.0, h], [-w * w * h, -2.0 * z * w * h]];
        let id = [[1.0, 0.0], [0.0, 1.0]];
        let mut r = id;
        for k in (1..=4).rev() {
            let t = mul(&ha, &r);
            for i in 0..2 {
                for j in 0..2 {
                    r[i][j] = id[i][j] + t[i][j] / f64::from(k);
                }
            }
        }
        let mut m_rk4 = id;
        for _ in 0..n {
            m_rk4 = mul(&m_rk4, &r);
        }
        let (ms, mr) = (scaled(&at, &o.monodromy), scaled(&at, &m_rk4));
        let norm = max_abs(&mr);
        let mut err_m = 0.0f64;
        for i in 0..2 {
            for j in 0..2 {
                err_m = err_m.max((ms[i][j] - mr[i][j]).abs() / norm);
            }
        }
        // The multipliers: R(hλ+)^N against the upper one found, and e^{λ+ T}.
        let lam = (-z * w, (1.0 - z * z).sqrt() * w);
        let zh = (lam.0 * h, lam.1 * h);
        let mut rz = (1.0, 0.0);
        for k in (1..=4).rev() {
            let t = cmul(zh, rz);
            rz = (1.0 + t.0 / f64::from(k), t.1 / f64::from(k));
        }
        let mut mu_rk4 = (1.0, 0.0);
        for _ in 0..n {
            mu_rk4 = cmul(mu_rk4, rz);
        }
        let period = f64::from(n) * h;
        let decay = (lam.0 * period).exp();
        let mu_exact = (
            decay * (lam.1 * period).cos(),
            decay * (lam.1 * period).sin(),
        );
        // The member of the conjugate pair on the same side of the real axis as e^{λ+ T}.
        let up = if o.floquet.mu[0].im * mu_exact.1 >= 0.0 {
            o.floquet.mu[0]
        } else {
            o.floquet.mu[1]
        };
        let err_mu = (up.re - mu_rk4.0).hypot(up.im - mu_rk4.1);
        // RK4's error: R(z) − e^z = −z⁵/120 + O(z⁶), so R^N − e^{Nz} ≈ −N z⁵/120 e^{Nz}.
        let predicted = f64::from(n) * zh.0.hypot(zh.1).powi(5) / 120.0 * decay;
        let err_exact = (up.re - mu_exact.0).hypot(up.im - mu_exact.1);
        println!(
            "free beam Ω/ω {ratio}: μ = {:.12} {:+.12}i; M vs R(hA)^N {err_m:.1e}, μ vs \
             R(hλ)^N {err_mu:.1e}; vs e^(λT) {err_exact:.3e} (N|hλ|⁵/120 |e^(λT)| = {predicted:.3e})",
            up.re, up.im
        );
        // Measured: 2e-14 to 1.7e-13 against the closed form; |μ − e^(λT)| (2.8e-5, 1.1e-6,
        // 2.0e-8) 1.0000–1.0004× the prediction.
        assert!(o.floquet.complex());
        assert!(err_m < 1e-12, "Ω/ω {ratio}: M vs R(hA)^N {err_m:e}");
        assert!(err_mu < 1e-12, "Ω/ω {ratio}: μ vs R(hλ)^N {err_mu:e}");
        assert!(
            err_exact > 0.9 * predicted && err_exact < 1.1 * predicted,
            "Ω/ω {ratio}: |μ − e^(λT)| {err_exact:e}, predicted {predicted:e}"
        );
    }
}

/// The scaled size of `a − b` (largest component over its scale).
fn scaled_distance(at: &MapPoint, a: &Vector2<f64>, b: &Vector2<f64>) -> f64 {
    let s = at.scales();
    ((a[0] - b[0]) / s[0])
        .abs()
        .max(((a[1] - b[1]) / s[1]).abs())
}

/// `periods` iterations of the map at `at` from `x`: the state reached, whether every period
/// had `p` impacts, and whether the iterates converge to a fixed point (the step
/// `|P(x_k) − x_k|` at the end smaller than halfway through — near a period doubling the
/// alternating deviation decays at rate `|μ|` on the stable side and grows on the other — or
/// below 1e-7 of the scales: a fixed point reached to round-off, or iterates that cycle across
/// a jump of the map ([`fd_column`]) narrower than that).
fn run_map(at: &MapPoint, x: Vector2<f64>, periods: u32, p: u32) -> (Vector2<f64>, bool, bool) {
    let mut x = x;
    let (mut same, mut half, mut last) = (true, 0.0, 0.0);
    for k in 0..periods {
        let img = iterate(at, 1, x).unwrap();
        same &= img.trace.impacts == p;
        last = scaled_distance(at, &img.x, &x);
        if k == periods / 2 {
            half = last;
        }
        x = img.x;
    }
    (x, same, last < 1e-7 || last < half)
}

/// Where a sweep left the orbit (the value before, the value), and the states it went through.
type SweepEnd = (Option<(f64, f64)>, Vec<(f64, Vector2<f64>)>);

/// A brute-force sweep of `Ω/ω` over `values` from state `x` (each value starting where the
/// previous one ended), `periods` map iterations at each: the first value where the orbit is
/// no longer a converging orbit of period 1 with `p` impacts every period (`None` if none), the
/// value before it, and the state at every value reached (value, state at its start).
fn sweep(at: &MapPoint, x: Vector2<f64>, values: &[f64], periods: u32, p: u32) -> SweepEnd {
    let mut x = x;
    let mut states = Vec::new();
    let mut before = f64::NAN;
    for &v in values {
        states.push((v, x));
        let (nx, same, converging) = run_map(&at.with(Param::OmegaRatio, v), x, periods, p);
        if !(same && converging) {
            return (Some((before, v)), states);
        }
        before = v;
        x = nx;
    }
    (None, states)
}

/// A brute-force sweep of `Ω/ω` over `values` from state `x` (each value starting where the
/// previous one ended) that asks only for the regime: the first value where some period of the
/// `periods` map iterations has other than `p` impacts (`None` if none), and the state at every
/// value reached (value, state at its start).
fn sweep_regime(
    at: &MapPoint,
    x: Vector2<f64>,
    values: &[f64],
    periods: u32,
    p: u32,
) -> (Option<f64>, Vec<(f64, Vector2<f64>)>) {
    let mut x = x;
    let mut states = Vec::new();
    for &v in values {
        states.push((v, x));
        let here = at.with(Param::OmegaRatio, v);
        for _ in 0..periods {
            let img = iterate(&here, 1, x).unwrap();
            if img.trace.impacts != p {
                return (Some(v), states);
            }
            x = img.x;
        }
    }
    (None, states)
}

/// `from`, `from ± step`, … up to `to` (inclusive, rounded to the step).
fn grid(from: f64, to: f64, step: f64) -> Vec<f64> {
    let n = ((to - from) / step).abs().round() as i64;
    let dir = (to - from).signum();
    (0..=n).map(|k| from + dir * step * k as f64).collect()
}

/// The state at the value of `states` nearest `v`.
fn state_near(states: &[(f64, Vector2<f64>)], v: f64) -> (f64, Vector2<f64>) {
    *states
        .iter()
        .min_by(|a, b| (a.0 - v).abs().total_cmp(&(b.0 - v).abs()))
        .unwrap()
}

fn event<T: Real>(e: &Edge<T>) -> BifEvent<T> {
    match e {
        Edge::Event(ev) => *ev,
        Edge::Open(end) => panic!("the band is open on one side: {end}"),
    }
}

/// The located edges of the wire rig's 1/1 band at 0.0 mm, from the orbit at Ω/ω 2.0.
fn wire_band_edges<T: Real>() -> (Orbit<T>, BifEvent<T>, BifEvent<T>) {
    let at = point(RigId::Wires, ContactLawKind::SpringDashpot, 0.0, 2.0);
    let (_, o) = orbit_at::<T>(&at);
    assert_eq!((o.p(), o.q), (1, 1));
    let settings = ContinuationSettings::new::<T>(Param::OmegaRatio, [0.5, 5.0]);
    let [lower, upper] = band_edges(&o, &settings);
    (o, event(&lower), event(&upper))
}

#[test]
fn wire_band_edges_agree_with_a_brute_force_sweep() {
    let (o, lower, upper) = wire_band_edges::<f64>();
    println!(
        "wires 0.0 mm, 1/1 band: lower {} at {:.7} (impacts beyond {}), upper {} at {:.7} \
         (critical μ {:.7} {:+.2e}i)",
        lower.kind,
        lower.value,
        lower.impacts_beyond,
        upper.kind,
        upper.value,
        upper.critical.re,
        upper.critical.im
    );
    // Measured: grazing at 1.1517026 (two impacts beyond), period doubling at 2.6603703 with
    // μ = −0.9999998.
    assert_eq!(lower.kind, EventKind::Grazing);
    assert_eq!(lower.impacts_beyond, 2);
    assert!((lower.value - 1.15170).abs() < 1e-4, "{}", lower.value);
    assert_eq!(upper.kind, EventKind::PeriodDoubling);
    assert!((upper.value - 2.66037).abs() < 1e-4, "{}", upper.value);
    assert!(
        (upper.critical.re + 1.0).abs() < 0.01 && upper.critical.im == 0.0,
        "{:?}",
        upper.critical
    );

    // The sweep: from the orbit at 2.0, in steps of 1e-4 (40 periods at each value; 400 in
    // the last 0.01 before the edge, where the doubling's multiplier nears −1 and the
    // deviations decay slowly), until the orbit stops being a converging 1/1 orbit.
    // The two directions are independent: each on its own thread.
    let at = o.at;
    let (up, down) = std::thread::scope(|s| {
        let up = s.spawn(|| {
            let (coarse, states) = sweep(&at, o.x, &grid(2.0, 2.65, 1e-4), 40, 1);
            assert!(coarse.is_none(), "the sweep up left 1/1 at {coarse:?}");
            let (v, x) = state_near(&states, 2.65);
            sweep(&at, x, &grid(v, 2.68, 1e-4), 400, 1).0
        });
        let (coarse, states) = sweep(&at, o.x, &grid(2.0, 1.16, 1e-4), 40, 1);
        assert!(coarse.is_none(), "the sweep down left 1/1 at {coarse:?}");
        let (v, x) = state_near(&states, 1.16);
        let down = sweep(&at, x, &grid(v, 1.14, 1e-4), 100, 1).0;
        let up = up
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (up, down)
    });
    let (up, down) = (up.unwrap(), down.unwrap());
    println!(
        "sweep: 1/1 up to {:.4}, not at {:.4}; down to {:.4}, not at {:.4}",
        up.0, up.1, down.0, down.1
    );
    // Measured: 1/1 from 1.1518 to 2.6603; at 2.6604 the alternating deviation grows, at
    // 1.1517 a second impact appears.
    assert!(
        up.0 < upper.value && upper.value < up.1,
        "{up:?} vs {}",
        upper.value
    );
    assert!(
        down.1 < lower.value && lower.value < down.0,
        "{down:?} vs {}",
        lower.value
    );
}

#[test]
fn f32_band_edges_agree_with_f64() {
    let (_, lower64, upper64) = wire_band_edges::<f64>();
    let (_, lower32, upper32) = wire_band_edges::<f32>();
    println!(
        "f32: {} {:.6}, {} {:.6}; f64: {:.6}, {:.6}",
        lower32.kind, lower32.value, upper32.kind, upper32.value, lower64.value, upper64.value
    );
    // Measured: f32 grazing 1.151689, doubling 2.660397 (f64: 1.151703, 2.660370).
    assert_eq!(
        (lower32.kind, upper32.kind),
        (EventKind::Grazing, EventKind::PeriodDoubling)
    );
    assert!((lower32.value - lower64.value).abs() < 1e-3);
    assert!((upper32.value - upper64.value).abs() < 1e-3);
    assert!((upper32.critical.re + 1.0).abs() < 0.01);
}

#[test]
fn beam_fold_and_grazing_bound_the_hysteresis() {
    // Beam-170 at 3.0 mm: the impacting 1/1 branch through Ω/ω 1.35 turns at a fold (μ → +1)
    // and comes back unstable to a grazing, where it meets the non-impacting branch through
    // 1.7; between them both stable branches coexist (the thesis' nonlinear jump).
    let at = point(RigId::Beam170, ContactLawKind::SpringDashpot, 3.0, 1.35);
    let (_, upper) = orbit_at::<f64>(&at);
    assert_eq!((upper.p(), upper.q), (1, 1));
    assert!(upper.floquet.stable());
    let settings = ContinuationSettings::new::<f64>(Param::OmegaRatio, [0.5, 5.0]);
    let (events, unstable_points, end) = branch_up(&upper, &settings);
    let kinds: Vec<_> = events.iter().map(|e| (e.kind, e.value)).collect();
    println!("from 1.35 up: {kinds:?}, {unstable_points} unstable points, ends at {end}");
    assert_eq!(events.len(), 2, "{kinds:?}");
    let (fold, graze_unstable) = (events[0], events[1]);
    assert_eq!(fold.kind, EventKind::Fold);
    assert!((fold.critical.re - 1.0).abs() < 0.01 && fold.critical.im == 0.0);
    assert!((fold.value - 1.500572).abs() < 1e-4, "{}", fold.value);
    assert_eq!(graze_unstable.kind, EventKind::Grazing);
    assert_eq!(graze_unstable.impacts_beyond, 0);
    assert!(unstable_points > 10 && !graze_unstable.orbit.floquet.stable());

    let at_low = at.with(Param::OmegaRatio, 1.7);
    let (regime, lower) = orbit_at::<f64>(&at_low);
    assert_eq!(regime, Regime::NoImpact);
    let mut graze = None;
    continue_branch(
        &lower,
        &settings,
        -1.0,
        None,
        |_| {},
        |e| {
            graze = Some(*e);
            ControlFlow::Break(())
        },
    );
    let graze = graze.expect("the non-impacting branch grazes");
    println!(
        "from 1.7 down: {} at {:.7} (impacts beyond {}); the unstable branch's end {:.7}",
        graze.kind, graze.value, graze.impacts_beyond, graze_unstable.value
    );
    // Measured: fold at 1.5005723 (μ = 0.99999), the unstable branch ends at 1.1922795 (its
    // grazing extrapolated from the monitors where Newton stalls), the non-impacting branch
    // grazes at 1.1923319 (located by bisection).
    assert_eq!(graze.kind, EventKind::Grazing);
    assert_eq!(graze.impacts_beyond, 1);
    assert!((graze.value - 1.1923).abs() < 1e-4, "{}", graze.value);
    assert!((graze.value - graze_unstable.value).abs() < 1e-4);

    // Brute-force sweeps from the previous state: up from the impacting orbit at 1.35 (200
    // periods at each value; 1000 within 0.004 of the fold, where the passage past the
    // saddle-node's ghost is slow), down from the non-impacting one at 1.7 (200 periods).
    let (jump, states) = sweep(&at, upper.x, &grid(1.35, 1.52, 1e-3), 200, 1);
    let up_coarse = jump.expect("the upper branch ends").1;
    let (v, x) = state_near(&states, fold.value - 4e-3);
    let (jump, _) = sweep(&at, x, &grid(v, 1.51, 1e-4), 1000, 1);
    let up_fine = jump.expect("the upper branch ends").1;
    let (jump, states) = sweep(&at, lower.x, &grid(1.7, 1.18, 1e-3), 200, 0);
    let down_coarse = jump.expect("the lower branch ends").1;
    let (v, x) = state_near(&states, graze.value + 4e-3);
    let (jump, _) = sweep(&at, x, &grid(v, 1.18, 1e-4), 200, 0);
    let down_fine = jump.expect("the lower branch ends").1;
    println!(
        "sweeps: up jumps at {up_coarse:.3} (step 1e-3), {up_fine:.4} (1e-4); down jumps at \
         {down_coarse:.3}, {down_fine:.4}"
    );
    // Measured: up 1.501 and 1.5006 (fold 1.50057); down 1.193 and 1.1924 (grazing 1.19233:
    // the step's transient reaches the surface one value early).
    assert!((up_coarse - fold.value).abs() < 1e-3 && up_coarse > fold.value);
    assert!((up_fine - fold.value).abs() < 1e-4 && up_fine > fold.value);
    assert!((down_coarse - graze.value).abs() < 1e-3);
    assert!((down_fine - graze.value).abs() < 1e-4);
}

// The orbit map locates switching events and the split of a step that nears the surface to
// round-off (`shared::orbit::map`), so where the orbit's discretisation does not change it is
// smooth and its slope is the dual numbers' monodromy (`orbit_map_secant_slope_equals_the_
// monodromy`). The grids' stepper, which splits such a step at a time bisected to 1/8192 of it
// (`Simulator::free_trial`), jumps where the split moves (up to 1e-5 of the cart's amplitude,
// `shared::orbit::map`): the tools below run the orbit map.

/// The guard against a monodromy that is not the map's slope (`Orbit::slope_mismatch`, which
/// `host-sim orbit` and `continue` report above 0.05): small at the main job's `1/1` orbit, at
/// the wire rig's `3/1` orbit at 0.0 mm, Ω/ω 0.9 (slow arrivals, where a split bisected to
/// 1/8192 of the step, the grids' stepper's, jumps by more than the map slopes) and at the f32
/// orbits of the
/// 170 mm beam rig at 3.0 mm, Ω/ω 1.45, and of Hunt–Crossley at the main job's point (whose
/// secants in f32 measured 5.1e-2 from f32's own rounding: a warning at a smooth orbit), and
/// large for a monodromy that is not the map's (the 3/1 orbit's, negated).
#[test]
fn slope_mismatch_flags_a_monodromy_that_is_not_the_maps_slope() {
    let mismatch = |o: &Orbit<f32>| o.slope_mismatch(1e-4).unwrap();
    let (_, main_job) = orbit_at::<f64>(&point(
        RigId::Wires,
        ContactLawKind::SpringDashpot,
        0.0,
        2.0,
    ));
    let (_, slow) = orbit_at::<f32>(&point(
        RigId::Wires,
        ContactLawKind::SpringDashpot,
        0.0,
        0.9,
    ));
    let (_, beam) = orbit_at::<f32>(&point(
        RigId::Beam170,
        ContactLawKind::SpringDashpot,
        3.0,
        1.45,
    ));
    let (_, hunt_crossley) =
        orbit_at::<f32>(&point(RigId::Wires, ContactLawKind::HuntCrossley, 0.0, 2.0));
    let a = main_job.slope_mismatch(1e-4).unwrap();
    let (b, d, e) = (mismatch(&slow), mismatch(&beam), mismatch(&hunt_crossley));
    let mut wrong = slow;
    for row in &mut wrong.monodromy {
        for m in row {
            *m = -*m;
        }
    }
    let c = mismatch(&wrong);
    println!(
        "slope mismatch: 1/1 at Ω/ω 2.0 {a:.2e}; 3/1 at 0.9 {b:.2e}; negated {c:.2}; \
         beam-170 f32 {d:.2e}; Hunt–Crossley f32 {e:.2e}"
    );
    // Measured: 3.0e-10, 2.4e-7, 0.83, 4.9e-6 and 6.8e-4 (Hunt–Crossley's kinks of the
    // discretised map: 3.3e-4 in f64).
    assert!(a < 1e-6, "{a}");
    assert!(b < 1e-5, "{b}");
    assert!(c > 0.5, "{c}");
    assert!(d < 1e-4, "{d}");
    assert!(e < 5e-3, "{e}");
}

#[test]
fn orbit_map_secant_slope_equals_the_monodromy() {
    let at = point(RigId::Wires, ContactLawKind::SpringDashpot, 0.0, 2.0);
    let (_, o) = orbit_at::<f64>(&at);
    let s = at.scales();
    let m = scaled(&at, &o.monodromy);
    let mut err = 0.0f64;
    for j in 0..2 {
        let image = |h: f64| {
            let mut x = o.x;
            x[j] += h * s[j];
            (iterate(&at, 1, x).unwrap().x, x[j])
        };
        let ((yp, xp), (ym, xm)) = (image(1e-4), image(-1e-4));
        for i in 0..2 {
            let secant = (yp[i] - ym[i]) / (xp - xm) * s[j] / s[i];
            err = err.max((secant - m[i][j]).abs() / max_abs(&m));
        }
    }
    println!("secant over ±1e-4 of the scales vs monodromy: {err:.2e}");
    // Measured: 9.3e-10.
    assert!(err < 1e-5, "secant slope vs monodromy {err:e}");
}

/// Newton's method from the orbit at Ω/ω 2.509 converges at 2.5091 (where the grids' stepper,
/// splitting a step near the surface at 1/8192 of it, puts the fixed point in one of its jumps)
/// to the orbit the protocol settles on there from rest, found independently.
#[test]
fn shooting_converges_along_the_1_1_band() {
    let at = point(RigId::Wires, ContactLawKind::SpringDashpot, 0.0, 2.509);
    let (_, o) = orbit_at::<f64>(&at);
    let there = at.with(Param::OmegaRatio, 2.5091);
    let settings = ShootSettings::for_type::<f64>();
    let next = shoot(&there, 1, o.x, &settings)
        .unwrap_or_else(|e| panic!("Ω/ω 2.5091 from 2.509's orbit: {e}"));
    assert!(next.residual <= settings.tolerance, "{:e}", next.residual);
    let (regime, from_rest) = orbit_at::<f64>(&there);
    assert_eq!(regime, Regime::Periodic { p: 1, q: 1 });
    let d = scaled_distance(&there, &next.x, &from_rest.x);
    println!("Ω/ω 2.5091: Newton from 2.509's orbit vs from rest: {d:.2e} of the scales");
    assert!(d < 1e-8, "{d:e}");
    assert_eq!(next.trace.impacts, 1);
}

/// Where the discretised map jumps between the start and the orbit, Newton's damped step finds
/// no descent and says so (`Stalled`), told apart from running out of iterations
/// (`NotConverged`): the Hunt–Crossley `1/1` orbit near Ω/ω 1.97 (`select --law
/// hunt-crossley`'s choice), where the orbit's force moves by up to 0.4 % between orbits 2e-5
/// of Ω/ω apart (docs/accuracy.md).
#[test]
fn newton_without_descent_stalls_and_says_so() {
    let at = |w: f64| point(RigId::Wires, ContactLawKind::HuntCrossley, 0.0, w);
    let settings = ShootSettings::for_type::<f64>();
    let (_, below) = orbit_at::<f64>(&at(1.96940));
    let (_, above) = orbit_at::<f64>(&at(1.96944));
    // At 1.96942 there is an orbit: Newton reaches it from the orbit at 1.96944 ...
    let o = shoot(&at(1.96942), 1, above.x, &settings).expect("from 1.96944");
    assert!(o.residual <= settings.tolerance);
    // ... but not from the one at 1.96940, which lies about as near (measured: 1.26e-2 of
    // the state's scales, against 7.9e-3).
    let near = |x: &Vector2<f64>| scaled_distance(&at(1.96942), x, &o.x);
    println!(
        "distance to the orbit at 1.96942: {:.2e} from 1.96940's, {:.2e} from 1.96944's",
        near(&below.x),
        near(&above.x)
    );
    assert!(near(&below.x) < 2e-2 && near(&above.x) < 2e-2);
    match shoot(&at(1.96942), 1, below.x, &settings) {
        Err(
            e @ OrbitError::Stalled {
                iterations,
                residual,
            },
        ) => {
            println!("{e}");
            assert!(iterations < settings.max_iterations);
            assert!(
                residual > settings.tolerance && residual < 1e-2,
                "{residual:e}"
            );
            assert!(e.to_string().contains("Newton stalled"), "{e}");
        }
        other => panic!("Ω/ω 1.96942 from 1.96940's orbit: {other:?}"),
    }
    // Out of iterations is told apart: one iteration from the orbit at 1.96944 for 1.9700.
    let one = ShootSettings {
        max_iterations: 1,
        ..settings
    };
    let e = shoot(&at(1.9700), 1, above.x, &one).unwrap_err();
    assert!(
        matches!(e, OrbitError::NotConverged { iterations: 1, .. }),
        "{e:?}"
    );
}

/// Step sizes that cannot make progress end the branch (`a step below the minimum`) at its
/// start instead of halving a NaN for ever: a NaN first step, a NaN smallest step. A smallest
/// step of 0 does not stop a branch whose steps converge: it runs to its point budget (and a
/// step halved to 0 is below it: `StepSizes::below_min`).
#[test]
fn continuation_with_unusable_steps_ends() {
    let at = point(RigId::Beam170, ContactLawKind::SpringDashpot, 0.0, 2.0);
    let (_, start) = orbit_at::<f64>(&at);
    for (first, min) in [
        (f64::NAN, 1e-6),
        (0.02, f64::NAN),
        (0.02, 0.0),
        (f64::NAN, 0.0),
    ] {
        let mut settings = ContinuationSettings::new::<f64>(Param::OmegaRatio, [0.5, 5.0]);
        settings.steps.first = first;
        settings.steps.min = min;
        settings.max_points = 3;
        let mut points = 0;
        let end = continue_branch(
            &start,
            &settings,
            1.0,
            None,
            |_| points += 1,
            |_| ControlFlow::Continue(()),
        );
        println!("first {first}, min {min}: {points} points, ends at {end:?}");
        if first.is_nan() || min.is_nan() {
            // Only the start.
            assert_eq!(points, 1, "{first} {min}");
            assert_eq!(
                end,
                shared::orbit::BranchEnd::StepTooSmall(2.0),
                "{first} {min}"
            );
        } else {
            // The start and the budget's 3 points, up from 2.0.
            assert_eq!(points, 4, "{first} {min}");
            assert!(
                matches!(end, shared::orbit::BranchEnd::MaxPoints(v) if v > 2.0),
                "{end}"
            );
        }
        assert!(settings.steps.below_min(0.0) && settings.steps.below_min(f64::NAN));
    }
}

/// From a gap of 0 (the field case, the edge of the gap's domain) the `1/1` branch is followed
/// up in the gap: the derivative in the gap is one-sided there (no gap below 0), and the
/// branch's first points have gaps above 0.
#[test]
fn the_gap_branch_starts_at_gap_zero() {
    let at = point(RigId::Wires, ContactLawKind::SpringDashpot, 0.0, 2.0);
    let (_, start) = orbit_at::<f64>(&at);
    let mut settings = ContinuationSettings::new::<f64>(Param::GapM, [0.0, 0.003]);
    settings.max_points = 6;
    let values = |points: &[BranchPoint<f64>]| points.iter().map(|p| p.value).collect::<Vec<_>>();
    let gaps = values(&branch_points(&start, &settings, 1.0).0);
    assert!(gaps.len() >= 3, "{gaps:?}");
    assert_eq!(gaps[0], 0.0);
    assert!(gaps[1..].iter().all(|&g| g > 0.0), "{gaps:?}");
    // Downwards from gap 0 the branch is at the range's end at once, and says so (the step to
    // the range's edge is 0).
    let (points, end) = branch_points(&start, &settings, -1.0);
    assert_eq!(end, shared::orbit::BranchEnd::RangeEnd(0.0));
    assert_eq!(values(&points), [0.0]);
}

/// Single shooting over 256 periods of the chaotic motion at the 1.0 mm response's Ω/ω 2.33
/// (largest Lyapunov exponent 0.3706 per period, tests/lyapunov.rs): `M` stretches by about
/// `e^(0.37 · 256)` ≈ 1e41, beyond f32 and, in f64, so far that `M − I` is singular to
/// rounding. The error says so, not "a fold".
#[test]
fn shooting_a_chaotic_motion_over_many_periods_says_it_is_too_unstable() {
    let at = point(RigId::Wires, ContactLawKind::SpringDashpot, 1.0, 2.33);
    let e32 = orbit_from::<f32>(&at, 0.0, 0.0, Some(256), &ShootSettings::for_type::<f32>());
    let e64 = orbit_from::<f64>(&at, 0.0, 0.0, Some(256), &ShootSettings::for_type::<f64>());
    for (e, finite) in [(e32.err(), false), (e64.err(), true)] {
        let Some(OrbitError::Singular { max_multiplier, .. }) = e else {
            panic!("{e:?}");
        };
        println!("max|μ| over 256 periods: {max_multiplier:e}");
        assert_eq!(max_multiplier.is_finite(), finite);
        let text = e.unwrap().to_string();
        assert!(
            text.contains("too unstable to shoot over that many"),
            "{text}"
        );
        if finite {
            // Measured: 1.34e40, 0.3609 per period.
            let per_period = max_multiplier.ln() / 256.0;
            assert!((per_period - 0.3706).abs() < 0.1 * 0.3706, "{per_period}");
        }
    }
}

/// A non-impacting orbit of the undamped wire rig is conservative: the free flight's map
/// preserves area (`det M = 1`, Liouville's formula), so its multipliers are a pair on the unit
/// circle at every point of its branch: neutral, with no Neimark–Sacker (`det M − 1` is zero
/// but for the integrator's error, whose sign flickers: in f32 the branch through Ω/ω 2.0 at
/// 18 mm reported eleven between 1.5 and 2.5). With the pendulum damped the same branch has
/// `det M = exp(−2ζωT) = exp(−4πζ/(Ω/ω))` and is stable.
#[test]
fn a_conservative_branch_is_neutral_without_neimark_sacker() {
    for zeta in [0.0, 0.003] {
        let mut at = point(RigId::Wires, ContactLawKind::SpringDashpot, 18.0, 2.0);
        at.params = at.params.with_damping_ratio(zeta);
        let (regime, start) = orbit_at::<f32>(&at);
        assert_eq!(regime, Regime::NoImpact);
        let settings = ContinuationSettings::new::<f32>(Param::OmegaRatio, [1.5, 2.5]);
        let (mut points, mut events) = (Vec::new(), Vec::new());
        for direction in [-1.0, 1.0] {
            continue_branch(
                &start,
                &settings,
                direction,
                None,
                |p| points.push(*p),
                |e| {
                    events.push((e.kind, e.value));
                    ControlFlow::Continue(())
                },
            );
        }
        let mut worst = 0.0f64;
        for p in &points {
            let o = &p.orbit;
            let det = (-4.0 * std::f64::consts::PI * zeta / p.value).exp();
            worst = worst.max((o.floquet.det - det).abs());
            assert_eq!(o.conservative(), zeta == 0.0, "Ω/ω {}", p.value);
            let expected = if zeta == 0.0 {
                Stability::Neutral
            } else {
                Stability::Stable
            };
            assert_eq!(o.stability(), expected, "ζ {zeta}, Ω/ω {}", p.value);
        }
        println!(
            "ζ {zeta}: {} points, det M within {worst:.1e} of exp(−4πζ/(Ω/ω)), events \
             {events:?}",
            points.len()
        );
        assert!(points.len() > 10);
        assert!(worst < 1e-5, "ζ {zeta}: det M off by {worst:e}");
        assert!(events.is_empty(), "ζ {zeta}: {events:?}");
    }
}

/// The points of the branch through `start` in `direction`, and its end.
fn branch_points(
    start: &Orbit<f64>,
    settings: &ContinuationSettings,
    direction: f64,
) -> (Vec<BranchPoint<f64>>, shared::orbit::BranchEnd) {
    let mut points = Vec::new();
    let end = continue_branch(
        start,
        settings,
        direction,
        None,
        |p| points.push(*p),
        |_| ControlFlow::Continue(()),
    );
    (points, end)
}

/// A branch that reaches its range's end lands on the edge: its last step is shortened to
/// end there and corrected at the edge's value, and that point is the orbit Newton's method
/// finds at the edge from the point before (in `Ω/ω` up to 2.3, and in the gap down to 0).
#[test]
fn a_branch_ends_on_its_range_edge() {
    for (gap_mm, param, range, direction, edge) in [
        (0.0, Param::OmegaRatio, [1.0, 2.3], 1.0, 2.3),
        (1.0, Param::GapM, [0.0, 0.003], -1.0, 0.0),
    ] {
        let at = point(RigId::Wires, ContactLawKind::SpringDashpot, gap_mm, 2.0);
        let (_, start) = orbit_at::<f64>(&at);
        let settings = ContinuationSettings::new::<f64>(param, range);
        let (points, end) = branch_points(&start, &settings, direction);
        let (last, before) = (&points[points.len() - 1], &points[points.len() - 2]);
        println!(
            "{param:?}: {} points, the last two at {} and {}",
            points.len(),
            before.value,
            last.value
        );
        assert_eq!(end, shared::orbit::BranchEnd::RangeEnd(last.value));
        assert!(
            (last.value - edge).abs() <= 1e-12 * range[1],
            "{}",
            last.value
        );
        assert!(
            (before.value - edge).abs() > 1e-6 * range[1],
            "{}",
            before.value
        );
        let newton = shoot(
            &at.with(param, last.value),
            1,
            before.orbit.x,
            &ShootSettings::for_type::<f64>(),
        )
        .expect("the orbit at the edge");
        let d = scaled_distance(&newton.at, &newton.x, &last.orbit.x);
        assert!(d < 1e-8, "{param:?}: {d:e}");
        assert_eq!(newton.trace.impacts, last.orbit.trace.impacts);
    }
}

/// The wire rig's `3/1` branch at 0.0 mm from Ω/ω 0.9 (slow arrivals) turns once: one fold
/// (`μ` through +1) where the brute-force sweep up leaves `3/1`, then the unstable branch ends
/// at a grazing.
#[test]
fn the_slow_arrival_3_1_branch_turns_once() {
    let at = point(RigId::Wires, ContactLawKind::SpringDashpot, 0.0, 0.9);
    let (_, start) = orbit_at::<f32>(&at);
    assert_eq!((start.p(), start.q), (3, 1));
    let settings = ContinuationSettings::new::<f32>(Param::OmegaRatio, [0.6, 1.4]);
    let (events, _, end) = branch_up(&start, &settings);
    let kinds: Vec<_> = events.iter().map(|e| (e.kind, e.value)).collect();
    println!("3/1 from 0.9 up: {kinds:?}, ends at {end}");
    assert_eq!(events.len(), 2, "{kinds:?}");
    assert_eq!(events[0].kind, EventKind::Fold);
    assert!((events[0].critical.re - 1.0).abs() < 0.01);
    assert_eq!(events[1].kind, EventKind::Grazing);
    assert!(events[1].value < events[0].value, "the branch turned back");

    // The sweep up from the orbit at 0.9 (200 periods at each value, steps of 1e-3; then 1000
    // periods in steps of 1e-4 from 1e-3 below where it left, where the passage past the
    // saddle-node's ghost is slow) leaves `3/1` (3 impacts every period) just past the fold.
    // (It asks only for the regime: on the way the iterates cycle across a jump of the map,
    // 5.8e-5 of the scales wide at 0.934, and do not converge.)
    let (_, x) = orbit_at::<f64>(&at);
    let (left, states) = sweep_regime(&at, x.x, &grid(0.9, 0.96, 1e-3), 200, 3);
    let coarse = left.expect("the 3/1 orbit ends");
    let (v, x) = state_near(&states, coarse - 1e-3);
    let (left, _) = sweep_regime(&at, x, &grid(v, coarse + 1e-3, 1e-4), 1000, 3);
    let fine = left.expect("the 3/1 orbit ends");
    println!("sweep up leaves 3/1 at {coarse:.3} (step 1e-3), {fine:.4} (1e-4)");
    // Measured: 0.947 and 0.9469 (fold 0.9468687).
    let fold = events[0].value;
    assert!(
        fine > fold && fine - fold <= 1e-4 + 1e-12,
        "fold {fold}, sweep {fine}"
    );
}

/// The 170 mm beam rig's `1/1` branch at 3.0 mm from Ω/ω 1.35 up, with the Lankarani–Nikravesh
/// and Hunt–Crossley laws: near its fold the discretised map's kinks make the branch zig-zag
/// (its multipliers jumping between a complex pair, two real ones and one past +1 from one
/// orbit to the next), and the fold test changes sign at every turn. One fold is told, where
/// the branch turns farthest, with the changes it stands for; f32 and f64 put it at the same
/// place. (Each change told as a fold, these branches reported 8 and 14 folds with
/// Lankarani–Nikravesh in f32 and f64 and 38 with Hunt–Crossley in f32.)
#[test]
fn a_fold_over_kinks_is_told_once_where_the_branch_turns_farthest() {
    // (The fold's value, its multiplier, its changes; the branch's farthest value.)
    fn fold_of<T: Real>(law: ContactLawKind) -> (f64, f64, SignChanges, f64) {
        let at = point(RigId::Beam170, law, 3.0, 1.35);
        let (_, start) = orbit_at::<T>(&at);
        let settings = ContinuationSettings::new::<T>(Param::OmegaRatio, [1.0, 2.0]);
        let mut events = Vec::new();
        let mut farthest = f64::NEG_INFINITY;
        continue_branch(
            &start,
            &settings,
            1.0,
            None,
            |p| farthest = farthest.max(p.value),
            |e| {
                events.push(*e);
                ControlFlow::Continue(())
            },
        );
        let folds: Vec<_> = events
            .iter()
            .filter(|e| e.kind == EventKind::Fold)
            .collect();
        let kinds: Vec<_> = events.iter().map(|e| (e.kind, e.value)).collect();
        assert_eq!(folds.len(), 1, "{law:?}: {kinds:?}");
        let changes = folds[0].changes.expect("a fold carries its changes");
        (folds[0].value, folds[0].critical.re, changes, farthest)
    }
    let ln32 = fold_of::<f32>(ContactLawKind::LankaraniNikravesh);
    let ln64 = fold_of::<f64>(ContactLawKind::LankaraniNikravesh);
    let hc32 = fold_of::<f32>(ContactLawKind::HuntCrossley);
    for (name, (value, mu, changes, farthest)) in
        [("LN f32", ln32), ("LN f64", ln64), ("HC f32", hc32)]
    {
        println!(
            "{name}: fold at {value} (μ {mu:+.6}), branch farthest {farthest}, {} changes over \
             {:?}",
            changes.count, changes.span
        );
        assert!((value - farthest).abs() < 1e-5, "{name}");
        assert!((mu - 1.0).abs() < 0.05, "{name}");
        assert!(changes.count > 1, "{name}: {changes:?}");
        assert_eq!(changes.span[1], value, "{name}");
    }
    // Measured: 1.7299771 (f32), 1.7300003 (f64); Hunt–Crossley 1.8278841.
    assert!((ln32.0 - ln64.0).abs() < 1e-4);
    assert!((ln64.0 - 1.7300).abs() < 1e-4);
    assert!((hc32.0 - 1.82788).abs() < 1e-4);
}

/// With Lankarani–Nikravesh the wire rig's `1/1` branch at 1.0 mm from Ω/ω 2.0 up loses its
/// stability near Ω/ω 2.1946 (its multiplier from −0.87 at 2.1925 to −1.46 at 2.2044 along the
/// branch), but the multiplier passes −1 by jumps of the discretised map (shot every 2e-5 of
/// Ω/ω: −0.9994 to −1.0141 at 2.19461, and between 2.1951 and 2.1956 Newton lands on orbits
/// with a complex pair near −0.60 ± 0.38i), and the doubling test's change is located at a jump
/// (μ there −0.60 ± 0.38i, far from −1). It is told as a period doubling across a jump, since
/// the test keeps its new sign; the branch was reported with no event before. No doubled branch
/// starts there.
#[test]
fn a_doubling_across_a_jump_of_the_map_is_told() {
    fn doubling<T: Real>() -> BifEvent<T> {
        let at = point(RigId::Wires, ContactLawKind::LankaraniNikravesh, 1.0, 2.0);
        let (_, start) = orbit_at::<T>(&at);
        let settings = ContinuationSettings::new::<T>(Param::OmegaRatio, [1.0, 2.3]);
        let (events, _, _) = branch_up(&start, &settings);
        let kinds: Vec<_> = events
            .iter()
            .map(|e| (e.kind, e.value, e.at_jump))
            .collect();
        println!("{}: {kinds:?}", core::any::type_name::<T>());
        assert_eq!(events.len(), 1, "{kinds:?}");
        events[0]
    }
    for (value, critical, at_jump, start) in [
        {
            let e = doubling::<f32>();
            (e.value, e.critical, e.at_jump, doubling_start(&e).is_some())
        },
        {
            let e = doubling::<f64>();
            (e.value, e.critical, e.at_jump, doubling_start(&e).is_some())
        },
    ] {
        // Measured: 2.19559 (f32) and 2.19545 (f64), μ −0.600 ± 0.377i.
        assert!((2.1925..2.2044).contains(&value), "{value}");
        assert!(at_jump);
        assert!(
            libm::hypot(critical.re + 1.0, critical.im) > 0.05,
            "{critical:?}"
        );
        assert!(!start, "no doubled branch from a doubling across a jump");
    }
}

/// With the Hunt–Crossley law (f64) the wire rig's `1/1` branch from Ω/ω 2.0 down meets the
/// rough stretch of the discretised map below 2.0: its fold test changes sign 86 times, in
/// pairs (106 of the 2,270 orbits have a multiplier just past +1), and the branch turns back at
/// 1.96988 onto the orbits it came by, stable but for those pokes. Four of the changes are
/// located as folds on their own (1.97021, 1.96988, 1.97014, 1.97041, `μ` 1.0008–1.0036), the
/// change that undoes each located away from +1; none is told, since a span past each the test
/// is back on its sign from before.
#[test]
fn a_fold_test_that_changes_sign_and_back_is_no_fold() {
    let at = point(RigId::Wires, ContactLawKind::HuntCrossley, 0.0, 2.0);
    let (_, start) = orbit_at::<f64>(&at);
    assert_eq!((start.p(), start.q), (1, 1));
    let settings = ContinuationSettings::new::<f64>(Param::OmegaRatio, [1.0, 3.0]);
    let mut events = Vec::new();
    let (mut lowest, mut unstable, mut points) = (f64::INFINITY, 0, 0);
    let end = continue_branch(
        &start,
        &settings,
        -1.0,
        None,
        |p| {
            lowest = lowest.min(p.value);
            unstable += usize::from(!p.orbit.floquet.stable());
            points += 1;
        },
        |e| {
            events.push(*e);
            ControlFlow::Continue(())
        },
    );
    let kinds: Vec<_> = events.iter().map(|e| (e.kind, e.value)).collect();
    println!(
        "HC 1/1 from 2.0 down: {kinds:?}, lowest {lowest}, {unstable} of {points} unstable, \
         ends at {end}"
    );
    assert!(events.is_empty(), "{kinds:?}");
    // The branch went down to the turn and back, stable (to the kinks' pokes past +1).
    assert!((lowest - 1.96988).abs() < 1e-4, "{lowest}");
    assert!(unstable * 10 < points, "{unstable} of {points}");
    assert!(
        matches!(end, shared::orbit::BranchEnd::StepTooSmall(v) if (1.9699..1.9712).contains(&v)),
        "{end}"
    );
}

/// The branch through `start` continued towards increasing values: its events, how many of its
/// points are unstable, and how it ended.
fn branch_up<T: Real>(
    start: &Orbit<T>,
    settings: &ContinuationSettings,
) -> (Vec<BifEvent<T>>, usize, shared::orbit::BranchEnd) {
    let mut events = Vec::new();
    let mut unstable_points = 0;
    let end = continue_branch(
        start,
        settings,
        1.0,
        None,
        |p| unstable_points += usize::from(!p.orbit.floquet.stable()),
        |e| {
            events.push(*e);
            ControlFlow::Continue(())
        },
    );
    (events, unstable_points, end)
}

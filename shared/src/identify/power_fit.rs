//! The Hunt–Crossley law (Eq. 3-4, `F = k_i δ^n (1 + λ_i δ̇)` while in contact) fitted to the
//! pulses by nonlinear least squares, where the spring–dashpot law ([`super::linear_fit`]) does
//! not fit.
//!
//! The kinematics are the linear fit's (the momentum balance `m δ̈ = −F`): with `I`, `II` the
//! force's running integrals from a pulse's first sample and `t` the time in samples of `Δt`
//! from the window's centre, `δ = Δt (v₀ (t − t₀) − Δt II / m)` and `δ̇ = v₀ − Δt I / m`, `v₀`
//! the penetration rate at the first sample and `t₀` the arrival. Unlike the spring–dashpot
//! law, the force is not linear in the law's parameters: the shared `(ln F_ref, n, λ_i)`, with
//! `F_ref = k_i δ_ref^n` the elastic force at a reference penetration near the first pulse's
//! deepest (which keeps `k_i` and `n` from moving together in the solve), and each pulse's
//! `(v₀, t₀)` are found together by Levenberg–Marquardt (Marquardt's scaling by the normal
//! matrix's diagonal). The normal matrix is block-arrowhead: each pulse's 2 × 2 block touches
//! only the shared 3 × 3, so the pulses' blocks are eliminated (the Schur complement, as in
//! bundle adjustment): a 3 × 3 solve per iteration, whatever the number of pulses, and one pass
//! over the samples. Started from the spring–dashpot fit's kinematics.
//!
//! Source of the method: K. Levenberg (1944), D. W. Marquardt (1963); the Schur complement of
//! the block-arrowhead normal equations: B. Triggs et al., "Bundle adjustment — a modern
//! synthesis" (2000), §6.1.

use crate::capture::SEGMENTS;

use super::linear_fit::centred;
use super::pulse::Pulse;
use super::record::SAMPLE_PERIOD_S;
use super::{DropRefusal, ln};
use crate::model::contact::{LawCoeffs, PowerDissipation, impact_restitution};

/// Most Levenberg–Marquardt iterations (a bound: the fit ends earlier, when an accepted step
/// lowers the residual by less than [`CONVERGED`] of it).
pub const MAX_ITERATIONS: u32 = 60;
/// The fit has converged when an accepted step lowers the residual by less than this fraction.
pub const CONVERGED: f32 = 1e-6;
/// Range of the exponent `n` the fit accepts (the model's: 1..=3).
pub const EXPONENT_RANGE: (f32, f32) = (1.0, 3.0);

/// A Hunt–Crossley law, `F = k δ^n (1 + λ δ̇)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HuntCrossley {
    /// `k_i`, N/m^n.
    pub stiffness: f32,
    /// `n`.
    pub exponent: f32,
    /// `λ_i`, s/m.
    pub lambda_s_m: f32,
}

/// RK4 steps per contact in [`HuntCrossley::restitution`].
pub const RESTITUTION_STEPS: u32 = 200;

impl HuntCrossley {
    /// The coefficient of restitution of one impact of a free mass `mass_kg` arriving at
    /// `speed_m_s` (> 0): the model's own impact ([`impact_restitution`], which
    /// [`crate::model::ContactLaw::restitution`] runs in `f64` at 4,000 steps per half period)
    /// in `f32`, at [`RESTITUTION_STEPS`] steps of the elastic impact's duration (estimated as
    /// `2.94 δ_max / v`, Hertz's for `n` = 1.5, whatever `n`: it only sets the step).
    /// Hunt–Crossley's `e` falls with `v` (`≈ 1 − 2λv/3` for small `λv`).
    ///
    /// `None` for a non-positive or non-finite mass or speed, or a contact that does not end
    /// within four times the estimate.
    pub fn restitution(&self, mass_kg: f32, speed_m_s: f32) -> Option<f32> {
        let usable = mass_kg > 0.0
            && speed_m_s > 0.0
            && mass_kg.is_finite()
            && speed_m_s.is_finite()
            && self.stiffness > 0.0
            && self.stiffness.is_finite();
        if !usable {
            return None;
        }
        let (k, n) = (self.stiffness, self.exponent);
        // The deepest penetration of the elastic impact: k δ^(n+1) / (n + 1) = m v² / 2.
        let delta_max = libm::powf(
            (n + 1.0) * mass_kg * speed_m_s * speed_m_s / (2.0 * k),
            1.0 / (n + 1.0),
        );
        let h = 2.94 * delta_max / speed_m_s / RESTITUTION_STEPS as f32;
        if !(h > 0.0 && h.is_finite()) {
            return None;
        }
        let law = LawCoeffs::Power {
            k,
            n,
            dissipation: PowerDissipation::HuntCrossley {
                lambda: self.lambda_s_m,
            },
        };
        impact_restitution(&law, mass_kg, speed_m_s, h, 4 * RESTITUTION_STEPS)
    }
}

/// Where the fit starts: the law (from the spring–dashpot fit) and each pulse's `(v₀, t₀)`.
#[derive(Debug, Clone, Copy)]
pub struct Start {
    /// The starting law.
    pub law: HuntCrossley,
    /// The reference penetration `δ_ref`, m (> 0).
    pub delta_ref_m: f32,
    /// Each pulse's `v₀` (m/s) and `t₀` (samples from its window's centre); `pulses` used.
    pub kinematics: [(f32, f32); SEGMENTS],
    /// Pulses.
    pub pulses: usize,
}

/// The fitted law and what it says of its quality.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerFit {
    /// The law.
    pub law: HuntCrossley,
    /// 95 % half-width of `k_i`, % of it.
    pub stiffness_pm_pct: f32,
    /// 95 % half-width of `n`.
    pub exponent_pm: f32,
    /// 95 % half-width of `λ_i`, % of it.
    pub lambda_pm_pct: f32,
    /// Residual sum of squares, N².
    pub rss: f32,
    /// Degrees of freedom of the residual (samples less the 3 shared and 2 per pulse).
    pub dof: u32,
    /// Iterations taken.
    pub iterations: u32,
    /// Each pulse's `v₀` (m/s) and `t₀` (samples from its window's centre).
    pub kinematics: [(f32, f32); SEGMENTS],
}

/// The shared parameters `(ln F_ref, n, λ)`.
type Shared = [f32; 3];

/// A symmetric 3 × 3 matrix by its upper triangle: `[00, 01, 02, 11, 12, 22]`.
type Sym3 = [f32; 6];

/// One pulse's share of the normal equations: its 2 × 2 block, its coupling to the shared
/// parameters and its gradients.
#[derive(Debug, Clone, Copy, Default)]
struct PulseBlock {
    /// `JₚᵀJₚ`: `[vv, vt, tt]`.
    d: [f32; 3],
    /// `JₛᵀJₚ`: row per shared parameter, column `v₀`, `t₀`.
    b: [[f32; 2]; 3],
    /// `Jₚᵀr`.
    g: [f32; 2],
}

/// The normal equations over all pulses at one point, with its residual.
#[derive(Debug, Clone, Copy)]
struct Normal {
    a: Sym3,
    g: [f32; 3],
    blocks: [PulseBlock; SEGMENTS],
    rss: f32,
    samples: u32,
}

/// The point of the parameter space the fit is at.
#[derive(Debug, Clone, Copy)]
struct Point {
    shared: Shared,
    kin: [(f32, f32); SEGMENTS],
}

/// Fits the Hunt–Crossley law to the `start.pulses` pulses that `pulse(k, buffer)` reads into
/// `buffer` (re-read at each pass into the one buffer `work`: no pulse is kept), for a hammer
/// of `mass_kg`.
///
/// # Errors
/// What `pulse` returns; [`DropRefusal::NotIdentifiable`] when the normal equations are
/// singular at the start, or the fit ends with `n` outside [`EXPONENT_RANGE`], a negative
/// `λ_i` or a non-finite value.
pub fn fit(
    start: &Start,
    mass_kg: f32,
    work: &mut Pulse,
    mut pulse: impl FnMut(usize, &mut Pulse) -> Result<(), DropRefusal>,
) -> Result<PowerFit, DropRefusal> {
    let pulses = start.pulses.min(SEGMENTS);
    let ln_ref = ln(start.delta_ref_m);
    let law = start.law;
    let mut at = Point {
        shared: [
            ln(law.stiffness) + law.exponent * ln_ref,
            law.exponent,
            law.lambda_s_m,
        ],
        kin: start.kinematics,
    };
    let mut normal = Normal::empty();
    pass(
        &mut normal,
        &at,
        pulses,
        mass_kg,
        start.delta_ref_m,
        work,
        &mut pulse,
    )?;
    let mut next = Normal::empty();
    let mut mu = 1e-3f32;
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        let Some(trial) = solve(&normal, &at, pulses, mu) else {
            mu *= 10.0;
            if mu > 1e10 {
                break;
            }
            continue;
        };
        pass(
            &mut next,
            &trial,
            pulses,
            mass_kg,
            start.delta_ref_m,
            work,
            &mut pulse,
        )?;
        if next.rss < normal.rss {
            let converged = normal.rss - next.rss <= CONVERGED * normal.rss;
            at = trial;
            core::mem::swap(&mut normal, &mut next);
            mu = (mu * 0.1).max(1e-9);
            if converged {
                break;
            }
        } else {
            mu *= 10.0;
            if mu > 1e10 {
                break;
            }
        }
    }
    let [ln_f_ref, n, lambda] = at.shared;
    let stiffness = libm::expf(ln_f_ref - n * ln_ref);
    let dof = normal.samples.saturating_sub(3 + 2 * pulses as u32);
    let fine = stiffness.is_finite()
        && stiffness > 0.0
        && (EXPONENT_RANGE.0..=EXPONENT_RANGE.1).contains(&n)
        && lambda >= 0.0
        && lambda.is_finite()
        && dof > 0;
    if !fine {
        return Err(DropRefusal::NotIdentifiable);
    }
    // The shared parameters' covariance: the inverse of the Schur complement (undamped), scaled
    // by the residual's variance.
    let s = schur(&normal, pulses, 0.0).ok_or(DropRefusal::NotIdentifiable)?;
    let inv = inverse(&s.0).ok_or(DropRefusal::NotIdentifiable)?;
    let var = normal.rss / dof as f32;
    // ln k = ln F_ref − n ln δ_ref.
    let var_ln_k = inv[0] + ln_ref * ln_ref * inv[3] - 2.0 * ln_ref * inv[1];
    let half = |v: f32| 1.96 * libm::sqrtf(v.max(0.0) * var);
    Ok(PowerFit {
        law: HuntCrossley {
            stiffness,
            exponent: n,
            lambda_s_m: lambda,
        },
        stiffness_pm_pct: 100.0 * half(var_ln_k),
        exponent_pm: half(inv[3]),
        lambda_pm_pct: 100.0 * half(inv[5]) / lambda,
        rss: normal.rss,
        dof,
        iterations,
        kinematics: at.kin,
    })
}

/// The force the law gives at sample `j` of pulse `p`, with its derivatives by the shared
/// parameters and the pulse's `(v₀, t₀)`: `(F̂, [∂ ln F_ref, ∂n, ∂λ], [∂v₀, ∂t₀])`. Zero where
/// the penetration is not positive.
#[inline(always)]
fn model(
    p: &Pulse,
    j: usize,
    shared: &Shared,
    (v0, t0): (f32, f32),
    dt_m: f32,
    ln_ref: f32,
) -> (f32, [f32; 3], [f32; 2]) {
    let dt = SAMPLE_PERIOD_S;
    let [ln_f_ref, n, lambda] = *shared;
    let since = centred(j, p.len) - t0;
    let delta = dt * (v0 * since - dt_m * p.int2[j]);
    if delta <= 0.0 || delta.is_nan() {
        return (0.0, [0.0; 3], [0.0; 2]);
    }
    let rate = v0 - dt_m * p.int1[j];
    let ln_rel = ln(delta) - ln_ref;
    let elastic = libm::expf(ln_f_ref + n * ln_rel);
    let factor = 1.0 + lambda * rate;
    let f = elastic * factor;
    // ∂F/∂δ and ∂F/∂δ̇.
    let by_delta = n * f / delta;
    let by_rate = elastic * lambda;
    (
        f,
        [f, f * ln_rel, elastic * rate],
        [by_delta * dt * since + by_rate, -by_delta * dt * v0],
    )
}

impl Normal {
    fn empty() -> Normal {
        Normal {
            a: [0.0; 6],
            g: [0.0; 3],
            blocks: [PulseBlock::default(); SEGMENTS],
            rss: 0.0,
            samples: 0,
        }
    }
}

/// The normal equations and the residual at `at`, into `out` (each pulse read into `p`).
fn pass(
    out: &mut Normal,
    at: &Point,
    pulses: usize,
    mass_kg: f32,
    delta_ref_m: f32,
    p: &mut Pulse,
    pulse: &mut impl FnMut(usize, &mut Pulse) -> Result<(), DropRefusal>,
) -> Result<(), DropRefusal> {
    let dt_m = SAMPLE_PERIOD_S / mass_kg;
    let ln_ref = ln(delta_ref_m);
    *out = Normal::empty();
    for (k, block) in out.blocks.iter_mut().enumerate().take(pulses) {
        pulse(k, p)?;
        let p = &*p;
        let mut rss = 0.0f32;
        for j in 0..p.len {
            let (f, js, jp) = model(p, j, &at.shared, at.kin[k], dt_m, ln_ref);
            let r = p.force[j] - f;
            rss += r * r;
            let mut idx = 0;
            for a in 0..3 {
                for b in a..3 {
                    out.a[idx] += js[a] * js[b];
                    idx += 1;
                }
                out.g[a] += js[a] * r;
                block.b[a][0] += js[a] * jp[0];
                block.b[a][1] += js[a] * jp[1];
            }
            block.d[0] += jp[0] * jp[0];
            block.d[1] += jp[0] * jp[1];
            block.d[2] += jp[1] * jp[1];
            block.g[0] += jp[0] * r;
            block.g[1] += jp[1] * r;
        }
        out.rss += rss;
        out.samples += p.len as u32;
    }
    if out.rss.is_finite() {
        Ok(())
    } else {
        Err(DropRefusal::NotIdentifiable)
    }
}

/// A 2 × 2 block damped by `mu` (Marquardt: its diagonal times `1 + mu`), inverted: `[vv, vt,
/// tt]`, or `None` when singular.
fn damped_inverse2(d: &[f32; 3], mu: f32) -> Option<[f32; 3]> {
    let (a, b, c) = (d[0] * (1.0 + mu), d[1], d[2] * (1.0 + mu));
    let det = a * c - b * b;
    (det > 0.0 && det.is_finite()).then(|| [c / det, -b / det, a / det])
}

/// The Schur complement of the pulses' blocks, `S = A − Σ B D⁻¹ Bᵀ`, and its right-hand side
/// `g − Σ B D⁻¹ gₚ`, all damped by `mu`.
fn schur(n: &Normal, pulses: usize, mu: f32) -> Option<(Sym3, [f32; 3])> {
    let mut s = n.a;
    for i in [0, 3, 5] {
        s[i] *= 1.0 + mu;
    }
    let mut rhs = n.g;
    for blk in n.blocks.iter().take(pulses) {
        let di = damped_inverse2(&blk.d, mu)?;
        // B D⁻¹, row per shared parameter.
        let bd: [[f32; 2]; 3] = core::array::from_fn(|a| {
            [
                blk.b[a][0] * di[0] + blk.b[a][1] * di[1],
                blk.b[a][0] * di[1] + blk.b[a][1] * di[2],
            ]
        });
        let mut idx = 0;
        for a in 0..3 {
            for b in a..3 {
                s[idx] -= bd[a][0] * blk.b[b][0] + bd[a][1] * blk.b[b][1];
                idx += 1;
            }
            rhs[a] -= bd[a][0] * blk.g[0] + bd[a][1] * blk.g[1];
        }
    }
    Some((s, rhs))
}

/// `at` moved by the damped Gauss–Newton step from `n`: the shared parameters' by the Schur
/// complement, then each pulse's by back-substitution. `None` when a system is singular.
fn solve(n: &Normal, at: &Point, pulses: usize, mu: f32) -> Option<Point> {
    let (s, rhs) = schur(n, pulses, mu)?;
    let inv = inverse(&s)?;
    let shared: Shared = [
        inv[0] * rhs[0] + inv[1] * rhs[1] + inv[2] * rhs[2],
        inv[1] * rhs[0] + inv[3] * rhs[1] + inv[4] * rhs[2],
        inv[2] * rhs[0] + inv[4] * rhs[1] + inv[5] * rhs[2],
    ];
    let mut out = *at;
    for (blk, kin) in n.blocks.iter().zip(out.kin.iter_mut()).take(pulses) {
        let di = damped_inverse2(&blk.d, mu)?;
        let r: [f32; 2] = core::array::from_fn(|c| {
            blk.g[c] - (0..3).map(|a| blk.b[a][c] * shared[a]).sum::<f32>()
        });
        kin.0 += di[0] * r[0] + di[1] * r[1];
        kin.1 += di[1] * r[0] + di[2] * r[1];
    }
    for (x, d) in out.shared.iter_mut().zip(shared) {
        *x += d;
    }
    Some(out)
}

/// The inverse of a symmetric 3 × 3 matrix (by cofactors, scaled by its diagonal so that the
/// parameters' different units do not cost precision), or `None` when it is not positive
/// definite.
fn inverse(m: &Sym3) -> Option<Sym3> {
    let d = [m[0], m[3], m[5]];
    if !d.iter().all(|&x| x > 0.0 && x.is_finite()) {
        return None;
    }
    let s = d.map(|x| 1.0 / libm::sqrtf(x));
    // The correlation-like matrix C = S M S (unit diagonal).
    let c = [
        1.0,
        m[1] * s[0] * s[1],
        m[2] * s[0] * s[2],
        1.0,
        m[4] * s[1] * s[2],
        1.0,
    ];
    let cof = [
        c[3] * c[5] - c[4] * c[4],
        c[2] * c[4] - c[1] * c[5],
        c[1] * c[4] - c[2] * c[3],
        c[0] * c[5] - c[2] * c[2],
        c[1] * c[2] - c[0] * c[4],
        c[0] * c[3] - c[1] * c[1],
    ];
    let det = c[0] * cof[0] + c[1] * cof[1] + c[2] * cof[2];
    if det.is_nan() || det <= 1e-7 {
        return None;
    }
    // M⁻¹ = S C⁻¹ S.
    let pair = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
    Some(core::array::from_fn(|i| {
        let (a, b) = pair[i];
        cof[i] / det * s[a] * s[b]
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The board's `f32` restitution against the model's `f64` one (RK4 at 4,000 steps per
    /// half period, the exit refined 64-fold): Fig. 3.3's law and others, at drop speeds.
    #[test]
    fn restitution_is_the_models() {
        for (k, n, lambda) in [(2.1e8, 1.6, 0.6), (5.5e6, 1.0, 68.0), (1e9, 2.2, 0.1)] {
            let law = crate::model::ContactLaw::HuntCrossley {
                stiffness: k,
                exponent: n,
                lambda_s_m: lambda,
            };
            let board = HuntCrossley {
                stiffness: k as f32,
                exponent: n as f32,
                lambda_s_m: lambda as f32,
            };
            for v in [0.01, 0.07, 0.3, 0.9] {
                let want = law.restitution(0.298, v).unwrap();
                let got = board.restitution(0.298, v as f32).unwrap();
                assert!(
                    (f64::from(got) - want).abs() < 2e-4,
                    "k {k} n {n} λ {lambda} v {v}: {got} vs {want}"
                );
            }
        }
        let board = HuntCrossley {
            stiffness: 2.1e8,
            exponent: 1.6,
            lambda_s_m: 0.6,
        };
        assert_eq!(board.restitution(0.0, 0.3), None);
        assert_eq!(board.restitution(0.298, f32::NAN), None);
        assert_eq!(board.restitution(0.298, -0.1), None);
    }

    #[test]
    fn the_symmetric_inverse_is_the_inverse() {
        // A matrix with very different scales, as the parameters' are.
        let m: Sym3 = [4e6, 3e3, -2e1, 9.0, 0.5, 0.25];
        let inv = inverse(&m).unwrap();
        const AT: [[usize; 3]; 3] = [[0, 1, 2], [1, 3, 4], [2, 4, 5]];
        let full = |x: &Sym3, a: usize, b: usize| x[AT[a][b]];
        // The f64 inverse by cofactors of the full matrix, independently.
        let f = |a: usize, b: usize| f64::from(full(&m, a, b));
        let cof = |a: usize, b: usize| {
            let (r0, r1) = ((a + 1) % 3, (a + 2) % 3);
            let (c0, c1) = ((b + 1) % 3, (b + 2) % 3);
            f(r0, c0) * f(r1, c1) - f(r0, c1) * f(r1, c0)
        };
        let det: f64 = (0..3).map(|c| f(0, c) * cof(0, c)).sum();
        for a in 0..3 {
            for b in 0..3 {
                let want = cof(b, a) / det;
                let scale = (cof(a, a) / det * cof(b, b) / det).sqrt();
                let got = f64::from(full(&inv, a, b));
                assert!(
                    (got - want).abs() < 1e-5 * scale,
                    "({a},{b}): {got} vs {want}"
                );
            }
        }
        assert!(inverse(&[1.0, 1.0, 0.0, 1.0, 0.0, 1.0]).is_none());
    }
}

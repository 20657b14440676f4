//! The spring–dashpot law (Table 3.1's, `F = k_i δ + c_i δ̇` while in contact) fitted to the
//! pulses by linear least squares.
//!
//! During contact the suspension's force is negligible beside the contact's (`m ω² / k_i ≈
//! 1e-5` on the thesis' rigs), so `m δ̈ = −F`: with `I`, `II` the force's first and second
//! integrals from a pulse's first sample (time `τ` in samples of `Δt`), the penetration is
//! `δ = v₀ Δt (τ − τ₀) − Δt² II / m` and its rate `δ̇ = v₀ − Δt I / m`, `v₀` the rate at the
//! first sample and `τ₀` the arrival. The law becomes
//!
//! `F + κ II + γ I = A τ + B`, with `κ = k_i Δt² / m`, `γ = c_i Δt / m`,
//! `A = k_i v₀ Δt`, `B = c_i v₀ − k_i v₀ Δt τ₀`,
//!
//! linear in the shared `(κ, γ)` and each pulse's `(A, B)`. Projecting every column on the
//! complement of `{1, τ}` within its pulse removes `(A, B)` (and any constant error of the
//! integrals at the pulse's onset, which the same line absorbs), leaving a 2 × 2 normal system
//! over all pulses. Only `k_i / m` and `c_i / m` follow from force alone: the mass is the
//! model's.

use super::pulse::Pulse;
use super::record::SAMPLE_PERIOD_S;

/// A pulse's columns reduced to what the fit needs: means and slopes against the centred time,
/// and the projected cross products.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PulseMoments {
    /// Means of `F`, `II`, `I`.
    pub mean: [f32; 3],
    /// Slopes of `F`, `II`, `I` against `τ − τ̄`, per sample.
    pub slope: [f32; 3],
}

/// The normal equations of `(κ, γ)` accumulated over pulses.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NormalEquations {
    /// `Σ (P II)², Σ (P II)(P I), Σ (P I)²`.
    pub g: [f32; 3],
    /// `−Σ (P II)(P F), −Σ (P I)(P F)`.
    pub h: [f32; 2],
    /// Samples used.
    pub samples: u32,
    /// Pulses used.
    pub pulses: u32,
}

/// Centred time of sample `j` of a window of `len`.
pub fn centred(j: usize, len: usize) -> f32 {
    j as f32 - 0.5 * (len as f32 - 1.0)
}

impl PulseMoments {
    /// The moments of `p`'s window.
    pub fn of(p: &Pulse) -> PulseMoments {
        let n = p.len as f32;
        let cols = [&p.force, &p.int2, &p.int1];
        let mut m = PulseMoments::default();
        let mut stt = 0.0f32;
        for j in 0..p.len {
            let t = centred(j, p.len);
            stt += t * t;
        }
        for (c, col) in cols.iter().enumerate() {
            let (mut s, mut st) = (0.0f32, 0.0f32);
            for (j, &x) in col.iter().take(p.len).enumerate() {
                s += x;
                st += centred(j, p.len) * x;
            }
            m.mean[c] = s / n;
            m.slope[c] = st / stt;
        }
        m
    }

    /// Sample `j` of the three columns projected out of `{1, τ}`.
    pub fn projected(&self, p: &Pulse, j: usize) -> [f32; 3] {
        let t = centred(j, p.len);
        let x = [p.force[j], p.int2[j], p.int1[j]];
        core::array::from_fn(|c| x[c] - self.mean[c] - self.slope[c] * t)
    }

    /// `A` and `B` of the pulse's line for the fitted `(κ, γ)`.
    pub fn line(&self, kappa: f32, gamma: f32) -> (f32, f32) {
        let comb = |v: &[f32; 3]| v[0] + kappa * v[1] + gamma * v[2];
        (comb(&self.slope), comb(&self.mean))
    }

    /// The pulse's `v₀` (the penetration rate at its first sample, m/s) and `t₀` (its arrival,
    /// samples from the window's centre) for the fitted `(κ, γ)` and the mass `mass_kg`: from
    /// its line, `v₀ = A / (k_i Δt)` and `t₀ = (c_i v₀ − B) / A`.
    pub fn start(&self, kappa: f32, gamma: f32, mass_kg: f32) -> (f32, f32) {
        let dt = SAMPLE_PERIOD_S;
        let (a, b) = self.line(kappa, gamma);
        let k_dt = kappa * mass_kg / dt;
        let c = gamma * mass_kg / dt;
        let v0 = a / k_dt;
        (v0, (c * v0 - b) / a)
    }
}

impl NormalEquations {
    /// Adds pulse `p` (with its moments `m`).
    pub fn add(&mut self, p: &Pulse, m: &PulseMoments) {
        for j in 0..p.len {
            let [f, ii, i] = m.projected(p, j);
            self.g[0] += ii * ii;
            self.g[1] += ii * i;
            self.g[2] += i * i;
            self.h[0] -= ii * f;
            self.h[1] -= i * f;
        }
        self.samples += p.len as u32;
        self.pulses += 1;
    }

    /// `(κ, γ)` and the inverse of the normal matrix (`[g⁻¹₀₀, g⁻¹₀₁, g⁻¹₁₁]`), or `None` when
    /// the system is singular (the pulses do not separate stiffness from damping).
    pub fn solve(&self) -> Option<([f32; 2], [f32; 3])> {
        let [a, b, d] = self.g;
        let det = a * d - b * b;
        if det.is_nan() || det <= 1e-6 * a * d || !det.is_finite() {
            return None;
        }
        let inv = [d / det, -b / det, a / det];
        let kappa = inv[0] * self.h[0] + inv[1] * self.h[1];
        let gamma = inv[1] * self.h[0] + inv[2] * self.h[1];
        Some(([kappa, gamma], inv))
    }

    /// Degrees of freedom of the residual: samples less `(κ, γ)` and each pulse's `(A, B)`.
    pub fn dof(&self) -> u32 {
        self.samples.saturating_sub(2 + 2 * self.pulses)
    }
}

/// Residual sum of squares of pulse `p` for the fitted `(κ, γ)`, N².
pub fn residual(p: &Pulse, m: &PulseMoments, kappa: f32, gamma: f32) -> f32 {
    (0..p.len)
        .map(|j| {
            let [f, ii, i] = m.projected(p, j);
            let r = f + kappa * ii + gamma * i;
            r * r
        })
        .sum()
}

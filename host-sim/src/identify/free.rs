//! Natural frequency and damping ratio from a free-decay record (thesis §3.3.3 and §3.4.1:
//! the suspension identified from its natural frequency, `k = m ω²`, Eq. 3-34, and a viscous
//! damping ratio, `c = 2 ζ m ω`).
//!
//! Model of the record (displacement, or acceleration: the second derivative of a damped
//! sinusoid is a damped sinusoid with the same `σ` and `ω_d`):
//! `y(t) = e^{−σ t} (a cos ω_d t + b sin ω_d t) + y_0`, with `σ = ζ ω_n`,
//! `ω_d = ω_n sqrt(1 − ζ²)`. For each `(σ, ω_d)` the amplitudes `a, b` and the offset `y_0`
//! come from linear least squares; Nelder–Mead (argmin) searches `(σ, ω_d)` (variable
//! projection). Start: `ω_d` from the mean spacing of the zero crossings, `σ` from a straight
//! line through the logarithms of the half-cycle amplitudes (logarithmic decrement).
//!
//! Uncertainty: the least-squares covariance of all five parameters `(σ, ω_d, a, b, y_0)`,
//! `s² (JᵀJ)⁻¹` (from the QR factors of `J`) with the residual variance `s² = RSS/(n − 5)` and the model's Jacobian `J` at
//! the fit (white noise on the samples), carried to `ω_n = sqrt(ω_d² + σ²)` and
//! `ζ = σ/ω_n` to first order; 95 % intervals `± 1.96` standard deviations.

use anyhow::{Result, bail, ensure};
use argmin::core::{CostFunction, Executor, State};
use argmin::solver::neldermead::NelderMead;
use serde::Serialize;
use shared::model::Suspension;

use nalgebra::{DMatrix, DVector};

use super::least_squares;
use crate::trace::Trace;

/// The identified free oscillation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FreeDecay {
    /// Undamped natural frequency `ω_n/2π`, Hz.
    pub natural_freq_hz: f64,
    /// Damped frequency `ω_d/2π`, Hz.
    pub damped_freq_hz: f64,
    /// Viscous damping ratio `ζ`.
    pub damping_ratio: f64,
    /// Initial amplitude `sqrt(a² + b²)` at the first sample, in the record's unit (SI).
    pub amplitude: f64,
    /// Offset `y_0`, SI.
    pub offset: f64,
    /// RMS of the fit residual over the RMS of the signal (about its offset).
    pub residual_rel: f64,
    /// Cycles in the record.
    pub cycles: f64,
    /// 95 % interval of `ω_n/2π`, Hz (linearised least squares, module docs).
    pub natural_freq_ci95_hz: [f64; 2],
    /// 95 % interval of `ζ`.
    pub damping_ratio_ci95: [f64; 2],
    /// Correlation of the `ω_n` and `ζ` estimates.
    pub correlation_fn_zeta: f64,
}

impl FreeDecay {
    /// Natural angular frequency `ω_n`, rad/s.
    pub fn omega_n(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.natural_freq_hz
    }
    /// Suspension stiffness `k = m ω_n²` (Eq. 3-34), N/m, for a mass `mass_kg`.
    pub fn stiffness_n_m(&self, mass_kg: f64) -> f64 {
        mass_kg * self.omega_n().powi(2)
    }
    /// Viscous damping `c = 2 ζ m ω_n`, N s/m.
    pub fn damping_n_s_m(&self, mass_kg: f64) -> f64 {
        2.0 * self.damping_ratio * mass_kg * self.omega_n()
    }
    /// Length of the pendulum with this natural frequency, `l = g/ω_n²`, m.
    pub fn pendulum_length_m(&self, gravity_m_s2: f64) -> f64 {
        gravity_m_s2 / self.omega_n().powi(2)
    }
    /// A suspension of the same kind as `like` with this decay's parameters: a beam's natural
    /// frequency and damping ratio, or the wires' pendulum length at gravity `gravity_m_s2`
    /// and the pendulum's damping ratio (the project's viscous term, docs/model.md).
    pub fn suspension(&self, like: &Suspension, gravity_m_s2: f64) -> Suspension {
        match like {
            Suspension::Beam { .. } => Suspension::Beam {
                natural_freq_hz: self.natural_freq_hz,
                damping_ratio: self.damping_ratio,
            },
            Suspension::Wires { .. } => Suspension::Wires {
                length_m: self.pendulum_length_m(gravity_m_s2),
                damping_ratio: self.damping_ratio,
            },
        }
    }
}

/// Least-squares `(a, b, y_0)` and the residual sum of squares at `(σ, ω_d)`.
fn project(t: &[f64], y: &[f64], sigma: f64, wd: f64) -> Option<([f64; 3], f64)> {
    let t0 = t[0];
    let design = DMatrix::from_fn(t.len(), 3, |i, c| {
        let s = t[i] - t0;
        let e = (-sigma * s).exp();
        match c {
            0 => e * (wd * s).cos(),
            1 => e * (wd * s).sin(),
            _ => 1.0,
        }
    });
    let x = least_squares(design, DVector::from_column_slice(y))?;
    let x = [x[0], x[1], x[2]];
    let mut rss = 0.0;
    for (&ti, &yi) in t.iter().zip(y) {
        let s = ti - t0;
        let e = (-sigma * s).exp();
        let (sn, cs) = (wd * s).sin_cos();
        rss += (yi - e * (x[0] * cs + x[1] * sn) - x[2]).powi(2);
    }
    Some((x, rss))
}

#[derive(Clone)]
struct Problem<'a> {
    t: &'a [f64],
    y: &'a [f64],
    wd0: f64,
    scale: f64,
}

impl CostFunction for Problem<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, x: &Vec<f64>) -> std::result::Result<f64, argmin::core::Error> {
        let (wd, sigma) = (x[0] * self.wd0, x[1] * self.wd0);
        if wd <= 0.0 || sigma < 0.0 {
            return Ok(1e3 * (1.0 + (-wd).max(0.0) + (-sigma).max(0.0)));
        }
        Ok(project(self.t, self.y, sigma, wd).map_or(1e3, |(_, rss)| rss / self.scale))
    }
}

/// Largest growth of the amplitude over a record taken as a free decay (10 %: noise on an
/// undamped pendulum's constant amplitude stays well below).
pub const MAX_GROWTH: f64 = 0.1;

/// Largest residual of the fit, over the record's rms, for a free decay of one mode (50 %; a
/// 1 % sensor noise leaves about 1 %).
pub const MAX_RESIDUAL_REL: f64 = 0.5;

/// Identifies `ω_n` and `ζ` from a free-decay trace (displacement or acceleration, SI).
///
/// # Errors
/// Fewer than 3 full cycles, a record that does not oscillate about a level, one whose
/// amplitude grows more than [`MAX_GROWTH`], or one a single damped oscillation fits worse than
/// [`MAX_RESIDUAL_REL`].
pub fn identify_free(trace: &Trace) -> Result<FreeDecay> {
    let (t, y) = (&trace.t_s, &trace.value);
    let n = y.len();
    let mean = y.iter().sum::<f64>() / n as f64;
    // Zero crossings about the mean, by linear interpolation.
    let mut crossings = Vec::new();
    for i in 1..n {
        let (a, b) = (y[i - 1] - mean, y[i] - mean);
        if (a < 0.0) != (b < 0.0) && a != b {
            crossings.push(t[i - 1] + (t[i] - t[i - 1]) * a / (a - b));
        }
    }
    ensure!(
        crossings.len() >= 7,
        "{} zero crossings: a free decay needs at least 3 full cycles",
        crossings.len()
    );
    let half = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    let wd0 = std::f64::consts::PI / half;
    // Half-cycle amplitudes → logarithmic decrement.
    let (mut sx, mut sy, mut sxx, mut sxy, mut m) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for w in crossings.windows(2) {
        let (lo, hi) = (
            t.partition_point(|&ti| ti < w[0]),
            t.partition_point(|&ti| ti <= w[1]),
        );
        let amp = y[lo..hi]
            .iter()
            .map(|v| (v - mean).abs())
            .fold(0.0, f64::max);
        if amp > 0.0 {
            let tm = 0.5 * (w[0] + w[1]);
            let la = amp.ln();
            sx += tm;
            sy += la;
            sxx += tm * tm;
            sxy += tm * la;
            m += 1.0;
        }
    }
    let slope = (m * sxy - sx * sy) / (m * sxx - sx * sx);
    let span = t[n - 1] - t[0];
    ensure!(
        !(slope.is_finite() && slope * span > MAX_GROWTH.ln_1p()),
        "the amplitude grows {:.0} % over the record's {span:.2} s: not a free decay (a drive \
         still on, or an unstable record)",
        100.0 * (slope * span).exp_m1()
    );
    let sigma0 = if slope.is_finite() {
        (-slope).max(0.0)
    } else {
        0.0
    };
    let scale = y.iter().map(|v| (v - mean).powi(2)).sum::<f64>();
    ensure!(scale > 0.0, "the record is constant");
    let problem = Problem { t, y, wd0, scale };
    let x0 = vec![1.0, sigma0 / wd0];
    let simplex = vec![
        x0.clone(),
        vec![x0[0] * 1.01, x0[1]],
        vec![x0[0], x0[1] + 0.002 + 0.2 * x0[1]],
    ];
    let solver = NelderMead::new(simplex)
        .with_sd_tolerance(1e-15)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let res = Executor::new(problem.clone(), solver)
        .configure(|s| s.max_iters(400))
        .run()
        .map_err(|e| anyhow::anyhow!("Nelder–Mead: {e}"))?;
    let Some(x) = res.state().get_best_param().cloned() else {
        bail!("the fit found no parameters");
    };
    let (wd, sigma) = (x[0] * wd0, x[1] * wd0);
    let Some((ab, rss)) = project(t, y, sigma, wd) else {
        bail!("the free-decay fit is singular");
    };
    let residual_rel = (rss / scale).sqrt();
    ensure!(
        residual_rel <= MAX_RESIDUAL_REL,
        "one damped oscillation leaves {:.0} % of the record's rms unexplained (at most {:.0} %): \
         not the free decay of one mode (a drive still on, beating between modes, or the wrong \
         column?)",
        100.0 * residual_rel,
        100.0 * MAX_RESIDUAL_REL
    );
    let wn = (wd * wd + sigma * sigma).sqrt();
    let two_pi = 2.0 * std::f64::consts::PI;
    let (sd_fn, sd_zeta, rho) = covariance(t, sigma, wd, ab, rss)?;
    let z95 = crate::stats::Z95;
    Ok(FreeDecay {
        natural_freq_ci95_hz: [(wn - z95 * sd_fn) / two_pi, (wn + z95 * sd_fn) / two_pi],
        damping_ratio_ci95: [
            (sigma / wn - z95 * sd_zeta).max(0.0),
            sigma / wn + z95 * sd_zeta,
        ],
        correlation_fn_zeta: rho,
        natural_freq_hz: wn / two_pi,
        damped_freq_hz: wd / two_pi,
        damping_ratio: sigma / wn,
        amplitude: ab[0].hypot(ab[1]),
        offset: ab[2],
        residual_rel,
        cycles: (t[n - 1] - t[0]) * wd / two_pi,
    })
}

/// Standard deviations of `ω_n` (rad/s) and `ζ` and their correlation at the fit `(σ, ω_d,
/// a, b, y_0)` with residual sum of squares `rss` (module docs).
fn covariance(t: &[f64], sigma: f64, wd: f64, ab: [f64; 3], rss: f64) -> Result<(f64, f64, f64)> {
    use nalgebra::Matrix2x5;
    let n = t.len();
    ensure!(n > 5, "too few samples for an uncertainty estimate");
    let t0 = t[0];
    let jac = DMatrix::from_fn(n, 5, |i, c| {
        let s = t[i] - t0;
        let e = (-sigma * s).exp();
        let (sn, cs) = (wd * s).sin_cos();
        match c {
            0 => -s * e * (ab[0] * cs + ab[1] * sn),
            1 => s * e * (-ab[0] * sn + ab[1] * cs),
            2 => e * cs,
            3 => e * sn,
            _ => 1.0,
        }
    });
    let s2 = rss / (n - 5) as f64;
    // (JᵀJ)⁻¹ = R⁻¹ R⁻ᵀ from the QR factors of J, without forming JᵀJ.
    let Some(r_inv) = jac.qr().r().try_inverse() else {
        bail!("the free-decay fit is singular: no uncertainty estimate");
    };
    let cov = &r_inv * r_inv.transpose() * s2;
    let wn = (wd * wd + sigma * sigma).sqrt();
    let wn3 = wn * wn * wn;
    // Rows: ∂ω_n/∂(σ, ω_d, …) and ∂ζ/∂(σ, ω_d, …).
    let g = Matrix2x5::new(
        sigma / wn,
        wd / wn,
        0.0,
        0.0,
        0.0,
        wd * wd / wn3,
        -sigma * wd / wn3,
        0.0,
        0.0,
        0.0,
    );
    let c = g * cov * g.transpose();
    let (a, b) = (c[(0, 0)].sqrt(), c[(1, 1)].sqrt());
    Ok((a, b, c[(0, 1)] / (a * b).max(1e-300)))
}

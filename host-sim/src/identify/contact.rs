//! Contact-law identification from a drop test (thesis §3.3.2, Figs. 3.8–3.10).
//!
//! The measured force–time trace of a drop test (the hammer released at rest `release` from
//! the surface; several impacts) is compared with the drop simulation of `shared`
//! ([`shared::analysis::drop`]) and the law's parameters are fitted by Nelder–Mead (argmin),
//! as the thesis did with MATLAB's `fminsearch`.
//!
//! ## Preprocessing of the measured trace
//! - Sensor offset: the median of the trace (most samples are free flight, `F = 0`); it is
//!   subtracted. Noise level `σ`: 1.4826 × the median absolute deviation.
//! - Impacts: runs of samples above `max(5σ, 3 % of the largest force)` with at least 3
//!   samples; runs closer than twice the previous run's length are one impact (re-contacts).
//!   At most `max_impacts`, in time order.
//! - Peak force of an impact: the vertex of a least-squares parabola through the 5 samples
//!   around the largest one (when all 5 are above 80 % of it), else the largest sample.
//! - Impact time: the force-weighted centroid `∫ t F dt / ∫ F dt` over the impact's window
//!   (the run plus half its length on each side): robust to noise, unlike the onset or the
//!   peak of a flat-topped pulse. Only differences to the first impact are used, so the trace's
//!   time origin need not be the release.
//!
//! ## The error (documented for `identify contact --error`)
//! With `F_ref` the largest measured peak, `τ_ref` the first impact's width at half maximum,
//! and `j` running over the `n` measured impacts matched in order to the simulated ones:
//! - `J_peak = Σ_j ((F̂_sim,j − F_meas,j)/F_ref)²` — the thesis' error, with the simulated
//!   peak as the sensor would report it: `F̂_sim,j` is the mean over [`PEAK_DRAWS`] fixed noise
//!   draws (the trace's `σ`) of the peak estimate of the simulated force at the run's sample
//!   times (aligned on the centroids). The estimate of a noisy peak is biased (the largest of
//!   noisy samples on a flat top lies above it; a coarse grid misses the top) and the
//!   simulated measurement has the same bias;
//! - `J_time = Σ_{j≥2} ((t_sim,j − t_sim,1) − (t_meas,j − t_meas,1))² / τ_ref²`;
//! - `J_profile = Σ_j Σ_{i ∈ window j} ((F_sim(t_i − t_meas,j + t_sim,j) − F_meas,i)/F_ref)²`
//!   (each simulated impact shifted onto the measured one's centroid). Sums, not means: with
//!   white sensor noise this is the least-squares (maximum-likelihood) weighting, so the
//!   profile's many samples outweigh the few peaks when it is switched on;
//! - `J = J_peak + w_time J_time + w_profile J_profile`; `--error peaks`: `w_profile = 0`,
//!   `--error profile`: `w_profile = 1`; `w_time` = `--time-weight` (default 1).
//!
//! A simulated impact that is missing counts with zero force and a time error of `τ_ref`.
//!
//! ## Several drop tests (joint fit, [`fit_law_joint`])
//! One parameter set is fitted to several drop tests (e.g. two release heights, as the thesis
//! did): `J = Σ_traces J_trace`, each trace's `J_trace` as above with its own `F_ref`, `τ_ref`,
//! release distance and impacts (so every trace counts alike, whatever its force level). With
//! one release height the impact speeds of a drop span a narrow range and a power law's `k` and
//! `n` trade off against each other; a second height separates them.
//!
//! ## Parameters searched (Nelder–Mead works on unbounded, similarly scaled coordinates)
//! - stiffness as the force at a reference penetration `δ_ref` (from the data:
//!   `F_1 / (m ω_c²)`, `ω_c` from the first impact's width), `ln(k δ_ref^n)`, so that `k` and
//!   `n` are not strongly correlated; damping `c_i` and `λ_i` by their logarithms; `n` and `e`
//!   directly, bounded to `1 ≤ n ≤ 3`, `0.01 ≤ e ≤ 1` by a penalty.

use anyhow::{Context, Result, bail, ensure};
use argmin::core::{CostFunction, Executor, State};
use argmin::solver::brent::BrentOpt;
use argmin::solver::neldermead::NelderMead;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use shared::analysis::drop::{DropRecord, DropSpec, run_drop};
use shared::integrate::StepSettings;
use shared::model::contact::spring_dashpot_restitution;
use shared::model::{ContactLaw, ContactLawKind, RigParams, SwitchBands};

use super::least_squares;
use crate::trace::Trace;

/// Which error the fit minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FitError {
    /// The profile where every trace resolves the contact (at least
    /// [`PROFILE_MIN_SAMPLES`] samples per contact), peaks and times otherwise.
    Auto,
    /// Peak forces and impact times (the thesis' error).
    Peaks,
    /// Peak forces, impact times and the whole force profile of every impact.
    Profile,
}

/// Samples per contact (the first impact's width at half maximum over the sampling step) from
/// which the profile error pays: a 0.57 ms contact sampled at 10 kHz has 4, at 50 kHz 19, at
/// the rig's 100 kHz capture 38.
pub const PROFILE_MIN_SAMPLES: f64 = 8.0;

impl DropData {
    /// Samples per contact: the first impact's width at half maximum over the sampling step.
    pub fn samples_per_contact(&self) -> f64 {
        let dt = self
            .t_s
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        self.impacts.first().map_or(0.0, |i| i.fwhm_s / dt)
    }
}

impl std::fmt::Display for FitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            FitError::Auto => "auto",
            FitError::Peaks => "peaks",
            FitError::Profile => "profile",
        })
    }
}

impl FitError {
    /// `Auto` resolved for traces with `samples_per_contact` (the fewest of them).
    pub fn resolve(self, samples_per_contact: f64) -> FitError {
        match self {
            FitError::Auto if samples_per_contact >= PROFILE_MIN_SAMPLES => FitError::Profile,
            FitError::Auto => FitError::Peaks,
            e => e,
        }
    }
}

/// One impact found in the measured trace.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredImpact {
    /// Peak force (offset removed), N.
    pub peak_n: f64,
    /// Force-weighted centroid time, s.
    pub centroid_s: f64,
    /// Width at half maximum, s.
    pub fwhm_s: f64,
    /// Sample index range `[first, last]` of the impact's window.
    pub window: (usize, usize),
    /// Sample index range `[first, last]` of the run above the threshold (the peak's search).
    pub run: (usize, usize),
}

/// A measured drop test after preprocessing.
#[derive(Debug, Clone)]
pub struct DropData {
    /// Sample times, s.
    pub t_s: Vec<f64>,
    /// Force with the offset removed, N.
    pub force_n: Vec<f64>,
    /// Removed sensor offset, N.
    pub offset_n: f64,
    /// Noise standard deviation, N.
    pub noise_n: f64,
    /// Impacts, in time order.
    pub impacts: Vec<MeasuredImpact>,
}

/// The median of `v` (reordered; selection, not a sort).
fn median(v: &mut [f64]) -> f64 {
    let n = v.len();
    let (below, mid, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    let mid = *mid;
    if n % 2 == 1 {
        mid
    } else {
        0.5 * (below.iter().copied().fold(f64::NEG_INFINITY, f64::max) + mid)
    }
}

/// Least-squares parabola through `(t, f)`: the vertex `(t*, f*)` if it opens downward.
fn parabola_vertex(t: &[f64], f: &[f64]) -> Option<(f64, f64)> {
    let t0 = t[t.len() / 2];
    // f = a + b x + c x², x = t − t0.
    let design = DMatrix::from_fn(t.len(), 3, |i, k| (t[i] - t0).powi(k as i32));
    let a = least_squares(design, DVector::from_column_slice(f))?;
    let (b, c) = (a[1], a[2]);
    if c >= 0.0 {
        return None;
    }
    let x = -b / (2.0 * c);
    Some((t0 + x, a[0] + b * x + c * x * x))
}

/// The peak force of the impact whose run above the threshold is samples `a..=b` of `f` (times
/// `t`): the vertex of a least-squares parabola through the 5 samples around the largest one,
/// when all 5 are above 80 % of it and the vertex lies between the largest one's neighbours;
/// else the largest sample.
pub(crate) fn peak_estimate(t: &[f64], f: &[f64], a: usize, b: usize) -> f64 {
    let imax = (a..=b).max_by(|&i, &j| f[i].total_cmp(&f[j])).unwrap_or(a);
    let mut peak = f[imax];
    if imax >= a + 2
        && imax + 2 <= b
        && (imax - 2..=imax + 2).all(|i| f[i] > 0.8 * f[imax])
        && let Some((tv, fv)) = parabola_vertex(&t[imax - 2..=imax + 2], &f[imax - 2..=imax + 2])
        && tv >= t[imax - 1]
        && tv <= t[imax + 1]
    {
        peak = fv;
    }
    peak
}

/// Finds the sensor offset, the noise level and the impacts of a measured drop test.
///
/// # Errors
/// No impact stands out of the noise (largest force below 10 σ).
pub fn analyse_drop(trace: &Trace, max_impacts: usize) -> Result<DropData> {
    let mut sorted = trace.value.clone();
    let offset = median(&mut sorted);
    let mut dev: Vec<f64> = trace.value.iter().map(|v| (v - offset).abs()).collect();
    let fmax = trace
        .value
        .iter()
        .map(|v| v - offset)
        .fold(f64::NEG_INFINITY, f64::max);
    let noise = (1.4826 * median(&mut dev)).max(1e-12 * fmax.abs());
    ensure!(
        fmax > 10.0 * noise,
        "no impact stands out of the noise: largest force {fmax:.4} N above the offset \
         {offset:.4} N, noise {noise:.4} N"
    );
    let f: Vec<f64> = trace.value.iter().map(|v| v - offset).collect();
    let t = &trace.t_s;
    let threshold = (5.0 * noise).max(0.03 * fmax);
    // Runs above the threshold.
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut start = None;
    for (i, &fi) in f.iter().enumerate() {
        match (fi > threshold, start) {
            (true, None) => start = Some(i),
            (false, Some(a)) => {
                runs.push((a, i - 1));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(a) = start {
        runs.push((a, f.len() - 1));
    }
    // Merge re-contacts, drop isolated noise spikes.
    let mut merged: Vec<(usize, usize)> = Vec::new();
    for r in runs {
        if let Some(last) = merged.last_mut() {
            let len = t[last.1] - t[last.0];
            if t[r.0] - t[last.1] < 2.0 * len.max(t[1] - t[0]) {
                last.1 = r.1;
                continue;
            }
        }
        merged.push(r);
    }
    merged.retain(|&(a, b)| b >= a + 2);
    let n = f.len();
    let mut impacts = Vec::new();
    for (a, b) in merged.into_iter().take(max_impacts) {
        let pad = (b - a).div_ceil(2).max(3);
        let window = (a.saturating_sub(pad), (b + pad).min(n - 1));
        let peak = peak_estimate(t, &f, a, b);
        let (mut sf, mut stf) = (0.0, 0.0);
        for i in window.0..=window.1 {
            sf += f[i];
            stf += t[i] * f[i];
        }
        let half: Vec<usize> = (a..=b).filter(|&i| f[i] > 0.5 * peak).collect();
        let dt = t[1] - t[0];
        let fwhm = match (half.first(), half.last()) {
            (Some(&i), Some(&j)) => t[j] - t[i] + dt,
            _ => dt,
        };
        impacts.push(MeasuredImpact {
            peak_n: peak,
            centroid_s: stf / sf,
            fwhm_s: fwhm,
            window,
            run: (a, b),
        });
    }
    ensure!(!impacts.is_empty(), "no impact found in the trace");
    Ok(DropData {
        t_s: t.clone(),
        force_n: f,
        offset_n: offset,
        noise_n: noise,
        impacts,
    })
}

/// One simulated impact: its peak, centroid and force samples.
#[derive(Debug, Clone, Default)]
pub struct SimImpact {
    /// Peak force, N.
    pub peak_n: f64,
    /// Force-weighted centroid time, s.
    pub centroid_s: f64,
    /// `(t, F)` samples of the episode, with the zero sample on each side.
    pub profile: Vec<(f64, f64)>,
}

impl SimImpact {
    /// Linear interpolation of the force at `t` (0 outside the episode).
    pub fn force_at(&self, t: f64) -> f64 {
        let p = &self.profile;
        if p.len() < 2 || t <= p[0].0 || t >= p[p.len() - 1].0 {
            return 0.0;
        }
        let i = p.partition_point(|s| s.0 <= t);
        let (t0, f0) = p[i - 1];
        let (t1, f1) = p[i];
        if t1 <= t0 {
            return f1;
        }
        f0 + (f1 - f0) * (t - t0) / (t1 - t0)
    }
}

/// Simulated drop test: its impacts and, if `keep_samples`, every `(t, F)` sample.
#[derive(Debug, Clone, Default)]
pub struct SimDrop {
    /// Impacts in time order.
    pub impacts: Vec<SimImpact>,
    /// All samples `(t_s, force_n)` (only with `keep_samples`).
    pub samples: Vec<(f64, f64)>,
}

/// Simulates the drop test `spec` for `params` (f64) and collects the impacts.
///
/// # Errors
/// Invalid parameters or spec.
pub fn simulate_drop(
    params: &RigParams,
    spec: &DropSpec,
    steps: &StepSettings,
    keep_samples: bool,
) -> Result<SimDrop> {
    let mut out = SimDrop::default();
    let mut pending: Vec<(f64, f64)> = Vec::new();
    let mut last_zero = (0.0, 0.0);
    let mut prev_force = 0.0;
    run_drop::<f64, _>(params, spec, &SwitchBands::default(), steps, |r| match r {
        DropRecord::Sample(s) => {
            if keep_samples {
                out.samples.push((s.t_s, s.force_n));
            }
            if s.force_n > 0.0 {
                if prev_force <= 0.0 && pending.is_empty() {
                    pending.push(last_zero);
                }
                pending.push((s.t_s, s.force_n));
            } else if prev_force > 0.0 {
                pending.push((s.t_s, 0.0));
            } else {
                last_zero = (s.t_s, 0.0);
            }
            prev_force = s.force_n;
        }
        DropRecord::Impact(i) => {
            let profile = std::mem::take(&mut pending);
            let (mut sf, mut stf) = (0.0, 0.0);
            for w in profile.windows(2) {
                let dt = w[1].0 - w[0].0;
                sf += 0.5 * dt * (w[0].1 + w[1].1);
                stf += 0.5 * dt * (w[0].0 * w[0].1 + w[1].0 * w[1].1);
            }
            out.impacts.push(SimImpact {
                peak_n: i.peak_n,
                centroid_s: if sf > 0.0 { stf / sf } else { i.arrival_s },
                profile,
            });
        }
    })
    .context("drop simulation")?;
    Ok(out)
}

/// One drop test of a (joint) fit: how it was made and what was measured.
#[derive(Debug, Clone)]
pub struct DropTest {
    /// Rig, release distance, gap and the fit's integrator settings.
    pub setup: DropSetup,
    /// The measured trace after preprocessing ([`analyse_drop`]).
    pub data: DropData,
}

/// The drop-test setup shared by the fit and the synthetic traces.
#[derive(Debug, Clone, Copy)]
pub struct DropSetup {
    /// Rig (mass, suspension; the contact law is replaced by the fit).
    pub params: RigParams,
    /// Gap, m.
    pub gap_m: f64,
    /// Release distance from the surface, m.
    pub release_m: f64,
    /// Integrator settings of the fit's simulations.
    pub steps: StepSettings,
}

/// The integrator settings of the fit: 256 steps per natural period, 64 sub-steps per contact
/// half-period (peaks within 0.03 % of the converged value).
pub const FIT_STEPS: StepSettings = StepSettings {
    steps_per_period: 256,
    substeps_per_contact: 64,
};

/// Weights of the error.
#[derive(Debug, Clone, Copy)]
pub struct Weights {
    /// `w_time`.
    pub time: f64,
    /// `w_profile`.
    pub profile: f64,
}

impl Weights {
    /// Peaks and impact times only (`w_profile = 0`).
    pub const PEAKS: Self = Self {
        time: 1.0,
        profile: 0.0,
    };
    /// Peaks, impact times and the force profile, equally weighted.
    pub const PROFILE: Self = Self {
        time: 1.0,
        profile: 1.0,
    };
}

/// The parts of the error at one parameter set.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct Residual {
    /// `J`.
    pub cost: f64,
    /// RMS of the peak errors, % of `F_ref`.
    pub peak_rms_pct: f64,
    /// RMS of the impact-time errors, µs.
    pub time_rms_us: f64,
    /// RMS of the profile errors, % of `F_ref`.
    pub profile_rms_pct: f64,
}

/// Unnormalised sums of one or several traces' errors, combined into a [`Residual`].
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    /// `Σ ((F_sim − F_meas)/F_ref)²` over the impacts, and their number.
    peak: f64,
    peaks_n: usize,
    /// `Σ (Δt/τ_ref)²`, `Σ Δt²` (s²) over the impacts after the first, and their number.
    time: f64,
    time_sq_s2: f64,
    times_n: usize,
    /// `Σ ((F_sim − F_meas)/F_ref)²` over the profile samples, and their number.
    profile: f64,
    profile_n: usize,
}

impl Sums {
    /// The sums of one trace's terms (`τ_ref` normalises its time errors).
    fn of(terms: &[Term], tau_ref: f64) -> Sums {
        let mut out = Sums::default();
        for t in terms {
            match *t {
                Term::Peak(v) => {
                    out.peak += v.powi(2);
                    out.peaks_n += 1;
                }
                Term::Time(dt) => {
                    out.time += (dt / tau_ref).powi(2);
                    out.time_sq_s2 += dt * dt;
                    out.times_n += 1;
                }
                Term::Profile(v) => {
                    out.profile += v.powi(2);
                    out.profile_n += 1;
                }
            }
        }
        out
    }

    fn add(&mut self, o: &Sums) {
        self.peak += o.peak;
        self.peaks_n += o.peaks_n;
        self.time += o.time;
        self.time_sq_s2 += o.time_sq_s2;
        self.times_n += o.times_n;
        self.profile += o.profile;
        self.profile_n += o.profile_n;
    }

    fn residual(&self, w: Weights) -> Residual {
        let rms = |sum: f64, n: usize| if n > 0 { (sum / n as f64).sqrt() } else { 0.0 };
        Residual {
            cost: self.peak + w.time * self.time + w.profile * self.profile,
            peak_rms_pct: 100.0 * rms(self.peak, self.peaks_n),
            time_rms_us: 1e6 * rms(self.time_sq_s2, self.times_n),
            profile_rms_pct: 100.0 * rms(self.profile, self.profile_n),
        }
    }
}

/// The least-squares misfit of a simulated impact shifted by `guess + u·spacing` onto measured
/// samples (the cost of [`TraceCtx::shift_onto`], in `u`).
struct Align<'a> {
    t: &'a [f64],
    f: &'a [f64],
    s: &'a SimImpact,
    guess: f64,
    spacing: f64,
}

impl CostFunction for Align<'_> {
    type Param = f64;
    type Output = f64;
    fn cost(&self, u: &f64) -> std::result::Result<f64, argmin::core::Error> {
        let d = self.guess + u * self.spacing;
        Ok(self
            .t
            .iter()
            .zip(self.f)
            .map(|(&t, &f)| (self.s.force_at(t + d) - f).powi(2))
            .sum())
    }
}

/// Noise draws of the simulated measurement of a peak (the sensor's peak estimate laid on the
/// measured samples).
pub const PEAK_DRAWS: usize = 32;

/// One drop test inside the fit, with its normalisations.
#[derive(Clone)]
struct TraceCtx<'a> {
    setup: &'a DropSetup,
    data: &'a DropData,
    f_ref: f64,
    tau_ref: f64,
    duration_s: f64,
    /// Per impact: [`PEAK_DRAWS`] draws of the sensor noise over its run, draw-major, N.
    peak_noise: Vec<Vec<f64>>,
}

impl<'a> TraceCtx<'a> {
    fn new(setup: &'a DropSetup, data: &'a DropData) -> Self {
        let i0 = &data.impacts[0];
        let span = data.impacts[data.impacts.len() - 1].centroid_s - i0.centroid_s;
        // Fixed draws (common to every parameter set, so the simulated peak is a smooth
        // function of the parameters), seeded per impact: the same on every machine.
        let peak_noise = data
            .impacts
            .iter()
            .enumerate()
            .map(|(j, m)| {
                let mut rng = ChaCha8Rng::seed_from_u64(j as u64);
                let n = PEAK_DRAWS * (m.run.1 + 1 - m.run.0);
                (0..n)
                    .map(|_| {
                        data.noise_n
                            * <StandardNormal as Distribution<f64>>::sample(
                                &StandardNormal,
                                &mut rng,
                            )
                    })
                    .collect()
            })
            .collect();
        TraceCtx {
            setup,
            data,
            f_ref: data.impacts.iter().map(|i| i.peak_n).fold(0.0, f64::max),
            tau_ref: i0.fwhm_s,
            duration_s: 1.25 * span + 2.0 * std::f64::consts::PI / setup.params.omega_n() + 0.01,
            peak_noise,
        }
    }

    /// The shift `δ`, s, that lays the simulated impact `s` on the samples of measured impact
    /// `j` (simulated time `t_i + δ`): least squares of `F_sim(t_i + δ) − F_i` over the
    /// impact's window, within 1.5 sample spacings of the centroids' alignment, to 1e-4 of a
    /// spacing (Brent's method, argmin). The centroids alone place a pulse with a jump (the
    /// spring–dashpot onset) only to a few µs, which moves the grid's samples across the jump.
    fn shift_onto(&self, j: usize, s: &SimImpact) -> f64 {
        let m = &self.data.impacts[j];
        let guess = s.centroid_s - m.centroid_s;
        let (a, b) = m.window;
        let spacing = if b > a {
            (self.data.t_s[b] - self.data.t_s[a]) / (b - a) as f64
        } else {
            return guess;
        };
        let cost = Align {
            t: &self.data.t_s[a..=b],
            f: &self.data.force_n[a..=b],
            s,
            guess,
            spacing,
        };
        let solver = BrentOpt::new(-1.5, 1.5).set_tolerance(1e-8, 1e-4);
        Executor::new(cost, solver)
            .configure(|st| st.max_iters(100))
            .run()
            .ok()
            .and_then(|r| r.state().get_best_param().copied())
            .map_or(guess, |u| guess + u * spacing)
    }

    /// The peak the sensor would report for the simulated impact `s` in the place of measured
    /// impact `j`: the simulated force at the run's sample times (shifted onto the measured
    /// samples, [`Self::shift_onto`]) plus each of the fixed noise draws, through [`peak_estimate`]; the mean over
    /// the draws, N. No simulated impact: zero force.
    fn sim_peak(&self, j: usize, s: Option<&SimImpact>) -> f64 {
        let Some(s) = s else {
            return 0.0;
        };
        let m = &self.data.impacts[j];
        let (a, b) = m.run;
        let t = &self.data.t_s[a..=b];
        let shift = self.shift_onto(j, s);
        let clean: Vec<f64> = t.iter().map(|&tk| s.force_at(tk + shift)).collect();
        let n = clean.len();
        let mut g = vec![0.0; n];
        let mut sum = 0.0;
        for noise in self.peak_noise[j].chunks_exact(n) {
            for ((gk, ck), ek) in g.iter_mut().zip(&clean).zip(noise) {
                *gk = ck + ek;
            }
            sum += peak_estimate(t, &g, 0, n - 1);
        }
        sum / PEAK_DRAWS as f64
    }

    fn spec(&self, max_impacts: u32) -> DropSpec {
        DropSpec {
            gap_m: self.setup.gap_m,
            release_m: self.setup.release_m,
            duration_s: self.duration_s,
            max_impacts,
        }
    }
}

/// The fit's problem: the traces, the law and the error's weights, in the search coordinates
/// of the module docs.
#[derive(Clone)]
pub(crate) struct Problem<'a> {
    traces: Vec<TraceCtx<'a>>,
    pub(crate) law: ContactLawKind,
    pub(crate) weights: Weights,
    /// `δ_ref`, m: the stiffness coordinate is the force at this penetration.
    pub(crate) delta_ref: f64,
    /// Scales of the search coordinates (see [`initial`]).
    pub(crate) x0_scale: [f64; 3],
}

/// One term of a trace's error (module docs), unweighted.
#[derive(Debug, Clone, Copy)]
enum Term {
    /// `(F̂_sim − F_meas)/F_ref` of one impact.
    Peak(f64),
    /// `Δt`, s: the time error of one impact after the first.
    Time(f64),
    /// `(F_sim − F_meas)/F_ref` of one profile sample.
    Profile(f64),
}

impl Problem<'_> {
    /// The law at search coordinates `x`, or `None` outside the bounds (with the distance).
    pub(crate) fn law_at(&self, x: &[f64]) -> Result<ContactLaw, f64> {
        let s = &self.x0_scale;
        let out = |v: f64, lo: f64, hi: f64| (lo - v).max(0.0) + (v - hi).max(0.0);
        // The bounds: the exponent n in [1, 3], Lankarani–Nikravesh's restitution in [0.01, 1].
        let d = match self.law {
            ContactLawKind::SpringDashpot => 0.0,
            ContactLawKind::Hertz | ContactLawKind::HuntCrossley => out(x[1], 1.0, 3.0),
            ContactLawKind::LankaraniNikravesh => out(x[1], 1.0, 3.0) + out(x[2], 0.01, 1.0),
        };
        if d > 0.0 {
            return Err(d);
        }
        // A power law's stiffness from its force at the reference penetration δ_ref.
        let stiffness = || s[0] * x[0].exp() / self.delta_ref.powf(x[1]);
        let law = match self.law {
            ContactLawKind::SpringDashpot => ContactLaw::SpringDashpot {
                stiffness_n_m: s[0] * x[0].exp(),
                damping_n_s_m: s[1] * x[1].exp(),
            },
            ContactLawKind::Hertz => ContactLaw::Hertz {
                stiffness: stiffness(),
                exponent: x[1],
            },
            ContactLawKind::HuntCrossley => ContactLaw::HuntCrossley {
                stiffness: stiffness(),
                exponent: x[1],
                lambda_s_m: s[2] * x[2].exp(),
            },
            ContactLawKind::LankaraniNikravesh => ContactLaw::LankaraniNikravesh {
                stiffness: stiffness(),
                exponent: x[1],
                restitution: x[2],
            },
        };
        law.validate().map_err(|_| 1.0)?;
        Ok(law)
    }

    /// The simulated drop of each trace for `law` (all samples kept with `keep_samples`).
    pub(crate) fn simulate(&self, law: &ContactLaw, keep_samples: bool) -> Result<Vec<SimDrop>> {
        self.traces
            .iter()
            .map(|tc| {
                let mut params = tc.setup.params;
                params.contact = *law;
                let spec = tc.spec(tc.data.impacts.len() as u32);
                simulate_drop(&params, &spec, &tc.setup.steps, keep_samples)
            })
            .collect()
    }

    /// The joint residual of `law` and each trace's (in order).
    fn residual(&self, law: &ContactLaw) -> Result<(Residual, Vec<Residual>)> {
        let sims = self.simulate(law, false)?;
        let mut total = Sums::default();
        let mut each = Vec::with_capacity(self.traces.len());
        for (tc, sim) in self.traces.iter().zip(&sims) {
            let sums = Sums::of(&Self::trace_terms(tc, sim, self.weights), tc.tau_ref);
            total.add(&sums);
            each.push(sums.residual(self.weights));
        }
        Ok((total.residual(self.weights), each))
    }

    /// The weighted terms `r̃` of the error (`J = Σ r̃²`) against the simulated drops `sims`
    /// (one per trace, [`Self::simulate`]): per impact of each trace in order, its peak term,
    /// its time term (`√w_time Δt/τ_ref`, impacts after the first, when `w_time > 0`) and its
    /// profile terms (`√w_profile`, one per window sample).
    pub(crate) fn terms(&self, sims: &[SimDrop]) -> Vec<f64> {
        let (wt, wp) = (self.weights.time.sqrt(), self.weights.profile.sqrt());
        let mut out = Vec::new();
        for (tc, sim) in self.traces.iter().zip(sims) {
            out.extend(
                Self::trace_terms(tc, sim, self.weights)
                    .into_iter()
                    .filter_map(|t| match t {
                        Term::Peak(v) => Some(v),
                        Term::Time(dt) => (wt > 0.0).then_some(wt * dt / tc.tau_ref),
                        Term::Profile(v) => Some(wp * v),
                    }),
            );
        }
        out
    }

    /// The same problem on other data (one [`DropData`] per trace, in order): the same law,
    /// weights and search coordinates.
    pub(crate) fn with_data<'b>(&'b self, data: &'b [DropData]) -> Problem<'b> {
        Problem {
            traces: self
                .traces
                .iter()
                .zip(data)
                .map(|(tc, d)| TraceCtx::new(tc.setup, d))
                .collect(),
            law: self.law,
            weights: self.weights,
            delta_ref: self.delta_ref,
            x0_scale: self.x0_scale,
        }
    }

    /// Drop data as the sensor would give them if `sims` (one per trace, with samples) were
    /// the truth: each simulated drop at the trace's sample times (aligned on the first
    /// impact's centroid) plus white noise of the trace's `σ` (ChaCha8 seeded with `seed` and
    /// the trace's index), preprocessed like the measurement. `None` if a trace does not show
    /// as many impacts as the measured one.
    pub(crate) fn synthetic_data(&self, sims: &[SimDrop], seed: u64) -> Option<Vec<DropData>> {
        self.traces
            .iter()
            .zip(sims)
            .enumerate()
            .map(|(i, (tc, sim))| {
                let n = tc.data.impacts.len();
                let shift = tc.shift_onto(0, sim.impacts.first()?);
                let clean =
                    super::synth::resample(&sim.samples, tc.data.t_s.iter().map(|t| t + shift));
                let mut rng =
                    ChaCha8Rng::seed_from_u64(seed.wrapping_mul(64).wrapping_add(i as u64));
                let value = clean
                    .iter()
                    .map(|f| {
                        f + tc.data.noise_n
                            * <StandardNormal as Distribution<f64>>::sample(
                                &StandardNormal,
                                &mut rng,
                            )
                    })
                    .collect();
                let trace = Trace {
                    t_s: tc.data.t_s.clone(),
                    value,
                };
                let d = analyse_drop(&trace, n).ok()?;
                (d.impacts.len() == n).then_some(d)
            })
            .collect()
    }

    /// The noise standard deviation of each trace's samples, N.
    pub(crate) fn noise_n(&self) -> Vec<f64> {
        self.traces.iter().map(|t| t.data.noise_n).collect()
    }

    /// Traces in the fit.
    pub(crate) fn trace_count(&self) -> usize {
        self.traces.len()
    }

    /// Samples per contact of the least resolved trace ([`DropData::samples_per_contact`]).
    pub(crate) fn samples_per_contact(&self) -> f64 {
        self.traces
            .iter()
            .map(|tc| tc.data.samples_per_contact())
            .fold(f64::INFINITY, f64::min)
    }

    /// The unweighted terms of one trace's error against its simulated drop (module docs;
    /// profile terms only when `w_profile > 0`).
    fn trace_terms(tc: &TraceCtx<'_>, sim: &SimDrop, weights: Weights) -> Vec<Term> {
        let meas = &tc.data.impacts;
        let mut out = Vec::new();
        let c_m0 = meas[0].centroid_s;
        let c_s0 = sim.impacts.first().map(|s| s.centroid_s);
        for (j, m) in meas.iter().enumerate() {
            let s = sim.impacts.get(j);
            out.push(Term::Peak((tc.sim_peak(j, s) - m.peak_n) / tc.f_ref));
            if j > 0 {
                out.push(Term::Time(match (s, c_s0) {
                    (Some(s), Some(c0)) => (s.centroid_s - c0) - (m.centroid_s - c_m0),
                    _ => tc.tau_ref,
                }));
            }
            if weights.profile > 0.0 {
                for i in m.window.0..=m.window.1 {
                    let fsim = s.map_or(0.0, |s| {
                        s.force_at(tc.data.t_s[i] - m.centroid_s + s.centroid_s)
                    });
                    out.push(Term::Profile((fsim - tc.data.force_n[i]) / tc.f_ref));
                }
            }
        }
        out
    }
}

impl CostFunction for Problem<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, x: &Vec<f64>) -> std::result::Result<f64, argmin::core::Error> {
        match self.law_at(x) {
            Err(d) => Ok(1e3 * (1.0 + d)),
            Ok(law) => match self.residual(&law) {
                Ok((r, _)) if r.cost.is_finite() => Ok(r.cost),
                _ => Ok(1e3),
            },
        }
    }
}

/// A fitted law.
#[derive(Debug, Clone)]
pub struct Fit {
    /// The law with its fitted parameters.
    pub law: ContactLaw,
    /// The error at the fit (all traces together: `J` is the sum of the traces' errors, the
    /// RMS values are over all their impacts and samples).
    pub residual: Residual,
    /// Cost evaluations (each one drop simulation per trace) spent.
    pub evaluations: u64,
    /// Per trace, in the order given: its own error and the simulated drop at the fit (all
    /// samples kept, for plots).
    pub traces: Vec<TraceFit>,
    /// The parameters' uncertainty at the fit, or why it could not be estimated.
    pub uncertainty: Result<super::uncertainty::Uncertainty, String>,
    /// Terms of the error (`J = Σ r̃²`): peaks, times and profile samples of all traces.
    pub terms: usize,
}

impl Fit {
    /// Akaike's information criterion on the error's terms, `n ln(J/n) + 2p` (`n` terms, `p`
    /// parameters): the same terms for every law of one identification, so laws with more
    /// parameters pay for them. Differences below 2 do not tell two laws apart.
    pub fn aic(&self) -> f64 {
        let n = self.terms.max(1) as f64;
        let p = match self.law.kind() {
            ContactLawKind::SpringDashpot | ContactLawKind::Hertz => 2.0,
            _ => 3.0,
        };
        n * (self.residual.cost / n).max(1e-300).ln() + 2.0 * p
    }
}

/// One trace's part of a [`Fit`].
#[derive(Debug, Clone)]
pub struct TraceFit {
    /// This trace's error at the fit.
    pub residual: Residual,
    /// The simulated drop of this trace's setup at the fit (all samples kept).
    pub sim: SimDrop,
}

/// Initial guesses from the data: `(x0 scales, δ_ref)` for the law, see the module docs.
fn initial(law: ContactLawKind, data: &DropData, mass_kg: f64) -> ([f64; 3], f64) {
    let i0 = &data.impacts[0];
    // Half-sine pulse: width at half maximum (2π/3)/ω_c.
    let wc = 2.0 * std::f64::consts::PI / (3.0 * i0.fwhm_s);
    let k_lin = mass_kg * wc * wc;
    let delta_ref = i0.peak_n / k_lin;
    let v1 = i0.peak_n / (mass_kg * wc);
    let ratio = data
        .impacts
        .get(1)
        .map_or(0.5, |i1| (i1.peak_n / i0.peak_n).clamp(0.02, 0.999));
    match law {
        ContactLawKind::SpringDashpot => {
            // e ≈ F2/F1 for the linear law; ζ from the closed-form restitution.
            let (mut lo, mut hi) = (0.0, 2.0 * (k_lin * mass_kg).sqrt() * 0.999);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                let e = spring_dashpot_restitution(k_lin, mid, mass_kg).map_or(0.0, |r| r.0);
                if e > ratio {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            ([k_lin, 0.5 * (lo + hi).max(1e-3), 0.0], delta_ref)
        }
        ContactLawKind::Hertz => ([i0.peak_n, 0.0, 0.0], delta_ref),
        ContactLawKind::HuntCrossley => {
            // e ≈ (F2/F1)^((n+1)/2n) at n = 1.5; λ ≈ 3(1 − e)/(2 v) (Hunt and Crossley).
            let e = ratio.powf(2.5 / 3.0);
            (
                [i0.peak_n, 0.0, (1.5 * (1.0 - e) / v1).max(1e-3)],
                delta_ref,
            )
        }
        ContactLawKind::LankaraniNikravesh => ([i0.peak_n, 0.0, 0.0], delta_ref),
    }
}

fn start_point(law: ContactLawKind, data: &DropData) -> Vec<f64> {
    let e = data
        .impacts
        .get(1)
        .map_or(0.5, |i1| {
            (i1.peak_n / data.impacts[0].peak_n).powf(2.5 / 3.0)
        })
        .clamp(0.05, 0.95);
    match law {
        ContactLawKind::SpringDashpot => vec![0.0, 0.0],
        ContactLawKind::Hertz => vec![0.0, 1.5],
        ContactLawKind::HuntCrossley => vec![0.0, 1.5, 0.0],
        ContactLawKind::LankaraniNikravesh => vec![0.0, 1.5, e],
    }
}

fn simplex(law: ContactLawKind, x0: &[f64]) -> Vec<Vec<f64>> {
    let steps: &[f64] = match law {
        ContactLawKind::SpringDashpot => &[0.4, 0.4],
        ContactLawKind::Hertz => &[0.3, 0.2],
        ContactLawKind::HuntCrossley => &[0.3, 0.2, 0.5],
        ContactLawKind::LankaraniNikravesh => &[0.3, 0.2, 0.1],
    };
    let mut s = vec![x0.to_vec()];
    for (i, &h) in steps.iter().enumerate() {
        let mut p = x0.to_vec();
        // Step inward for a bounded coordinate near its upper bound.
        p[i] += if law == ContactLawKind::LankaraniNikravesh && i == 2 && x0[2] + h > 1.0 {
            -h
        } else {
            h
        };
        s.push(p);
    }
    s
}

/// Fits `law` to the measured drop `data` with Nelder–Mead (argmin), restarting from the best
/// point with a fresh simplex until a restart improves the error by less than 0.1 % (at most 4
/// runs of at most `max_iters` iterations). One trace of [`fit_law_joint`].
///
/// # Errors
/// Invalid rig parameters or drop setup (checked with the preset law before fitting), or an
/// optimiser failure.
pub fn fit_law(
    setup: &DropSetup,
    data: &DropData,
    law: ContactLawKind,
    weights: Weights,
    max_iters: u64,
) -> Result<Fit> {
    let tests = [DropTest {
        setup: *setup,
        data: data.clone(),
    }];
    fit_law_joint(&tests, law, weights, max_iters)
}

fn problem(tests: &[DropTest], law: ContactLawKind, weights: Weights) -> Result<Problem<'_>> {
    ensure!(!tests.is_empty(), "no drop test to fit");
    for (i, t) in tests.iter().enumerate() {
        ensure!(
            !t.data.impacts.is_empty(),
            "drop test {}: no measured impact",
            i + 1
        );
    }
    // The search coordinates are scaled by the first trace.
    let (x0_scale, delta_ref) = initial(law, &tests[0].data, tests[0].setup.params.mass_kg);
    Ok(Problem {
        traces: tests
            .iter()
            .map(|t| TraceCtx::new(&t.setup, &t.data))
            .collect(),
        law,
        weights,
        delta_ref,
        x0_scale,
    })
}

/// Fits every law of `laws` to the drop tests `tests` jointly (one parameter set per law, the
/// error summed over the tests; at most `max_iters` Nelder–Mead iterations), the laws in
/// parallel; results in the order of `laws`.
///
/// # Errors
/// The first law whose fit fails (named).
pub fn fit_laws(
    tests: &[DropTest],
    laws: &[ContactLawKind],
    weights: Weights,
    max_iters: u64,
) -> Result<Vec<(ContactLawKind, Fit)>> {
    laws.par_iter()
        .map(|&k| {
            fit_law_joint(tests, k, weights, max_iters)
                .with_context(|| format!("fitting the {k} law"))
                .map(|f| (k, f))
        })
        .collect()
}

/// The law of `fits` with the lowest AIC (the same error terms for every law); `None` if
/// `fits` is empty.
pub fn best_by_aic(fits: &[(ContactLawKind, Fit)]) -> Option<ContactLawKind> {
    fits.iter()
        .min_by(|x, y| x.1.aic().total_cmp(&y.1.aic()))
        .map(|f| f.0)
}

/// Fits one parameter set of `law` to several drop tests at once (e.g. two release heights):
/// the error is the sum of the traces' errors (module docs). Nelder–Mead as in [`fit_law`],
/// started from the first trace's data-based guess.
///
/// # Errors
/// No test, a test without impacts, invalid rig parameters or drop setup of any test (checked
/// with the preset law before fitting, named with the test's number), or an optimiser failure.
pub fn fit_law_joint(
    tests: &[DropTest],
    law: ContactLawKind,
    weights: Weights,
    max_iters: u64,
) -> Result<Fit> {
    let problem = problem(tests, law, weights)?;
    // Fails early (with the field) if a rig or a drop setup is invalid.
    for (i, tc) in problem.traces.iter().enumerate() {
        let mut check = tc.setup.params;
        check.contact = ContactLaw::preset(law);
        check
            .validate()
            .with_context(|| format!("drop test {}: rig parameters", i + 1))?;
        tc.spec(1)
            .validate()
            .with_context(|| format!("drop test {}", i + 1))?;
    }

    let mut x = start_point(law, &tests[0].data);
    let mut best = problem.cost(&x).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut evaluations = 1u64;
    for _ in 0..4 {
        let solver = NelderMead::new(simplex(law, &x))
            .with_sd_tolerance(1e-12)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let res = Executor::new(problem.clone(), solver)
            .configure(|s| s.max_iters(max_iters).counting(true))
            .run()
            .map_err(|e| anyhow::anyhow!("Nelder–Mead: {e}"))?;
        evaluations += res
            .state()
            .get_func_counts()
            .get("cost_count")
            .copied()
            .unwrap_or(0);
        let cost = res.state().get_best_cost();
        let Some(p) = res.state().get_best_param().cloned() else {
            break;
        };
        let improved = cost < best * (1.0 - 1e-3);
        if cost < best {
            best = cost;
            x = p;
        }
        if !improved {
            break;
        }
    }
    let Ok(law_fit) = problem.law_at(&x) else {
        bail!("the fit left the parameter bounds");
    };
    let (residual, each) = problem.residual(&law_fit)?;
    let mut traces = Vec::with_capacity(each.len());
    for (tc, r) in problem.traces.iter().zip(each) {
        let mut params = tc.setup.params;
        params.contact = law_fit;
        let sim = simulate_drop(&params, &tc.spec(0), &tc.setup.steps, true)?;
        traces.push(TraceFit { residual: r, sim });
    }
    let uncertainty = super::uncertainty::estimate(&problem, &x);
    let terms = problem.terms(&problem.simulate(&law_fit, false)?).len();
    Ok(Fit {
        terms,
        law: law_fit,
        residual,
        evaluations,
        traces,
        uncertainty,
    })
}

//! The error a contact law makes on drop tests (thesis §3.3.2: the simulated drop against the
//! measured one), in the search coordinates of the fit: the drop simulation ([`simulate_drop`],
//! `shared`'s switch-model integrator with the excitation off), the terms of the error and
//! the data a sensor would give if a simulated drop were the truth (for the bootstrap).
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
//! ## Several drop tests (joint fit)
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

use anyhow::{Context, Result, ensure};
use argmin::core::{CostFunction, Executor, State};
use argmin::solver::brent::BrentOpt;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng as _;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use shared::analysis::drop::{DropRecord, DropSpec, run_drop};
use shared::integrate::StepSettings;
use shared::model::contact::spring_dashpot_restitution;
use shared::model::{ContactLaw, ContactLawKind, RigParams, SwitchBands};

use super::data::{DropData, analyse_redraw, peak_estimate};

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

/// One simulated impact: its peak, centroid and force samples.
#[derive(Debug, Clone, Default)]
pub struct SimImpact {
    /// Approach speed at the arrival, m/s.
    pub approach_speed_m_s: f64,
    /// Peak force, N.
    pub peak_n: f64,
    /// Force-weighted centroid time, s.
    pub centroid_s: f64,
    /// `(t, F)` samples of the episode, with the zero sample on each side.
    pub profile: Vec<(f64, f64)>,
}

impl SimImpact {
    /// How long the contact lasts, s (its profile's span).
    pub fn duration_s(&self) -> f64 {
        match (self.profile.first(), self.profile.last()) {
            (Some(a), Some(b)) => b.0 - a.0,
            _ => 0.0,
        }
    }

    /// Its width at half maximum, s (between the first and last profile samples above half the
    /// peak).
    pub fn fwhm_s(&self) -> f64 {
        let mut above = self
            .profile
            .iter()
            .filter(|(_, f)| *f > 0.5 * self.peak_n)
            .map(|(t, _)| *t);
        let first = above.next();
        first.map_or(0.0, |a| above.next_back().unwrap_or(a) - a)
    }

    /// Linear interpolation of the force at `t` (0 outside the episode, and at a NaN `t`).
    pub fn force_at(&self, t: f64) -> f64 {
        let p = &self.profile;
        if !within(p, t) {
            return 0.0;
        }
        interpolate(p, p.partition_point(|s| s.0 <= t), t)
    }

    /// [`Self::force_at`] at each of `times` (non-decreasing), the same values: one walk along
    /// the profile instead of a search for each time (the preprocessing's alignments and
    /// profile terms call it over every sample of an impact's window, for every redraw).
    pub fn forces_at(&self, times: impl Iterator<Item = f64>) -> impl Iterator<Item = f64> {
        let p = &self.profile;
        // The first sample after the last time seen (`partition_point`'s answer for it).
        let mut i = 0;
        let mut last = f64::NEG_INFINITY;
        times.map(move |t| {
            debug_assert!(
                t >= last || t.is_nan() || last.is_nan(),
                "times must not decrease: {t} after {last}"
            );
            last = t;
            if !within(p, t) {
                return 0.0;
            }
            while p[i].0 <= t {
                i += 1;
            }
            interpolate(p, i, t)
        })
    }
}

/// Whether `t` lies strictly inside `profile`'s span (false for a NaN `t`).
#[inline]
fn within(profile: &[(f64, f64)], t: f64) -> bool {
    profile.len() >= 2 && t > profile[0].0 && t < profile[profile.len() - 1].0
}

/// The force at `t` on the segment of `profile` that ends at sample `i` (`t` within it).
#[inline]
fn interpolate(profile: &[(f64, f64)], i: usize, t: f64) -> f64 {
    let (t0, f0) = profile[i - 1];
    let (t1, f1) = profile[i];
    if t1 <= t0 {
        return f1;
    }
    f0 + (f1 - f0) * (t - t0) / (t1 - t0)
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
                approach_speed_m_s: i.approach_speed_m_s,
                peak_n: i.peak_n,
                centroid_s: if sf > 0.0 { stf / sf } else { i.arrival_s },
                profile,
            });
        }
    })
    .context("drop simulation")?;
    Ok(out)
}

/// `(t, F)` samples (times increasing) linearly interpolated at `times` (increasing); the
/// first or last sample's force outside them.
pub(crate) fn resample(samples: &[(f64, f64)], times: impl Iterator<Item = f64>) -> Vec<f64> {
    let s = samples;
    let mut j = 0;
    times
        .map(|t| {
            while j + 1 < s.len() && s[j + 1].0 < t {
                j += 1;
            }
            if j + 1 < s.len() {
                let (t0, f0) = s[j];
                let (t1, f1) = s[j + 1];
                if t1 > t0 {
                    f0 + (f1 - f0) * ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
                } else {
                    f1
                }
            } else {
                s.last().map_or(0.0, |p| p.1)
            }
        })
        .collect()
}

/// One drop test of a (joint) fit: how it was made and what was measured.
#[derive(Debug, Clone)]
pub struct DropTest {
    /// Rig, release distance, gap and the fit's integrator settings.
    pub setup: DropSetup,
    /// The measured trace after preprocessing ([`super::data::analyse_drop`]).
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
            .s
            .forces_at(self.t.iter().map(|&t| t + d))
            .zip(self.f)
            .map(|(fs, &f)| (fs - f).powi(2))
            .sum())
    }
}

/// What a stream of seeded noise is for ([`noise_rng`]).
#[derive(Debug, Clone, Copy)]
pub(crate) enum Stream {
    /// The fixed draws of the simulated peak measurement ([`PEAK_DRAWS`] per impact).
    PeakDraws = 1,
    /// A noise redraw of the bootstrap ([`Problem::synthetic_data`]).
    Redraw = 2,
}

/// The ChaCha8 generator of `stream` for trace `trace` and index `index` (the impact, or the
/// redraw): the three make its 256-bit key, so no two streams share draws, and every machine
/// draws the same.
pub(crate) fn noise_rng(stream: Stream, trace: usize, index: u64) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&(stream as u64).to_le_bytes());
    key[8..16].copy_from_slice(&(trace as u64).to_le_bytes());
    key[16..24].copy_from_slice(&index.to_le_bytes());
    ChaCha8Rng::from_seed(key)
}

/// Why a noise redraw of the fitted drop gives no usable data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RedrawFailure {
    /// The simulated drop at the fit has no impact.
    NoSimulatedImpact,
    /// No impact stands out of the redrawn noise.
    NoImpact,
    /// The redrawn trace shows fewer impacts than the measured one (a small impact below the
    /// threshold, or two impacts merged).
    FewerImpacts,
    /// The simulated drops around the fit miss an impact of the redrawn trace.
    Terms,
    /// The error's Jacobian on the redrawn trace is not usable (singular or not finite).
    Singular,
    /// The redrawn trace's error after its step is beyond [`BROKEN_REDRAW`] times the median
    /// redraw's: its preprocessing broke down (an impact's window or peak taken from noise),
    /// and one such redraw would dominate the covariance.
    Broken,
}

/// A redraw whose error after its Gauss–Newton step exceeds this many times the median
/// redraw's is [`RedrawFailure::Broken`] (for `J ~ χ²_1`, 1 redraw in 400 passes 20× the
/// median; for more terms, far fewer).
pub const BROKEN_REDRAW: f64 = 20.0;

impl RedrawFailure {
    /// Words for a report.
    pub const fn describe(self) -> &'static str {
        match self {
            RedrawFailure::NoSimulatedImpact => "the fitted drop has no impact",
            RedrawFailure::NoImpact => "no impact stands out of the noise",
            RedrawFailure::FewerImpacts => {
                "fewer impacts than measured (a small one below the threshold or two merged)"
            }
            RedrawFailure::Terms => "the drops around the fit miss an impact",
            RedrawFailure::Singular => "singular Jacobian",
            RedrawFailure::Broken => "preprocessing broke down (error 20× the median redraw's)",
        }
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
    /// The trace's number in the fit.
    index: usize,
}

impl<'a> TraceCtx<'a> {
    /// The context of trace number `index` (which seeds its peak draws).
    fn new(setup: &'a DropSetup, data: &'a DropData, index: usize) -> Self {
        let i0 = &data.impacts[0];
        let span = data.impacts[data.impacts.len() - 1].centroid_s - i0.centroid_s;
        // Fixed draws (common to every parameter set, so the simulated peak is a smooth
        // function of the parameters), seeded per trace and impact: the same on every machine.
        let peak_noise = data
            .impacts
            .iter()
            .enumerate()
            .map(|(j, m)| {
                let mut rng = noise_rng(Stream::PeakDraws, index, j as u64);
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
            index,
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
        let clean: Vec<f64> = s.forces_at(t.iter().map(|&tk| tk + shift)).collect();
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

/// The part of the error a term belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Part {
    /// Peak forces.
    Peak,
    /// Impact times.
    Time,
    /// Force profiles.
    Profile,
}

impl Part {
    /// All parts, in the order of the terms.
    pub const ALL: [Part; 3] = [Part::Peak, Part::Time, Part::Profile];

    /// Its name in reports (`peaks`, `times`, `profile`).
    pub const fn name(self) -> &'static str {
        match self {
            Part::Peak => "peaks",
            Part::Time => "times",
            Part::Profile => "profile",
        }
    }
}

/// Where a term of the error comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct TermInfo {
    /// Its part of the error.
    pub part: Part,
    /// Trace index.
    pub trace: usize,
    /// Impact index within the trace.
    pub impact: usize,
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

    /// The whole simulated drop of each trace for `law` (every impact within the trace's
    /// duration, all samples kept: for plots).
    ///
    /// # Errors
    /// Invalid parameters.
    pub(crate) fn simulate_whole(&self, law: &ContactLaw) -> Result<Vec<SimDrop>> {
        self.traces
            .iter()
            .map(|tc| {
                let mut params = tc.setup.params;
                params.contact = *law;
                simulate_drop(&params, &tc.spec(0), &tc.setup.steps, true)
            })
            .collect()
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
    pub(crate) fn residual(&self, law: &ContactLaw) -> Result<(Residual, Vec<Residual>)> {
        let sims = self.simulate(law, false)?;
        let mut total = Sums::default();
        let mut each = Vec::with_capacity(self.traces.len());
        for (tc, sim) in self.traces.iter().zip(&sims) {
            let sums = Sums::of(
                &Self::trace_terms(tc, sim, self.weights.profile > 0.0),
                tc.tau_ref,
            );
            total.add(&sums);
            each.push(sums.residual(self.weights));
        }
        Ok((total.residual(self.weights), each))
    }

    /// Every term of the error, unweighted, against the simulated drops `sims` (one per trace,
    /// [`Self::simulate`]), in the order of [`Self::term_info`]: per impact of each trace, its
    /// peak term, its time term (`Δt/τ_ref`, impacts after the first, when `w_time > 0`) and
    /// its profile terms (one per window sample, whether or not `w_profile > 0`: the
    /// lack-of-fit check looks at the profile of a peaks fit too).
    pub(crate) fn terms_all(&self, sims: &[SimDrop]) -> Vec<f64> {
        let mut out = Vec::new();
        for (tc, sim) in self.traces.iter().zip(sims) {
            out.extend(
                Self::trace_terms(tc, sim, true)
                    .into_iter()
                    .filter_map(|t| match t {
                        Term::Peak(v) | Term::Profile(v) => Some(v),
                        Term::Time(dt) => (self.weights.time > 0.0).then_some(dt / tc.tau_ref),
                    }),
            );
        }
        out
    }

    /// What each term of [`Self::terms_all`] is: its part of the error, trace and impact.
    pub(crate) fn term_info(&self) -> Vec<TermInfo> {
        let mut out = Vec::new();
        for (trace, tc) in self.traces.iter().enumerate() {
            for (impact, m) in tc.data.impacts.iter().enumerate() {
                let mut push = |part| {
                    out.push(TermInfo {
                        part,
                        trace,
                        impact,
                    })
                };
                push(Part::Peak);
                if impact > 0 && self.weights.time > 0.0 {
                    push(Part::Time);
                }
                for _ in m.window.0..=m.window.1 {
                    push(Part::Profile);
                }
            }
        }
        out
    }

    /// The factor of each term of [`Self::terms_all`] in the error `J = Σ (w r)²`: 1 for a peak,
    /// `√w_time` for a time, `√w_profile` for a profile sample (0: not in the error).
    pub(crate) fn term_weights(&self, info: &[TermInfo]) -> Vec<f64> {
        info.iter()
            .map(|t| match t.part {
                Part::Peak => 1.0,
                Part::Time => self.weights.time.sqrt(),
                Part::Profile => self.weights.profile.sqrt(),
            })
            .collect()
    }

    /// The same problem on other data (one [`DropData`] per trace, in order): the same law,
    /// weights and search coordinates.
    pub(crate) fn with_data<'b>(&'b self, data: &'b [DropData]) -> Problem<'b> {
        Problem {
            traces: self
                .traces
                .iter()
                .zip(data)
                .map(|(tc, d)| TraceCtx::new(tc.setup, d, tc.index))
                .collect(),
            law: self.law,
            weights: self.weights,
            delta_ref: self.delta_ref,
            x0_scale: self.x0_scale,
        }
    }

    /// Drop data as the sensor would give them if `sims` (one per trace, with samples) were
    /// the truth: each simulated drop at the trace's sample times (aligned on the first
    /// impact) plus white noise of the trace's `σ` ([`noise_rng`] of the trace and `redraw`),
    /// preprocessed like the measurement.
    ///
    /// # Errors
    /// Why the redraw is not usable: a trace without the measured number of impacts.
    pub(crate) fn synthetic_data(
        &self,
        sims: &[SimDrop],
        redraw: u64,
    ) -> Result<Vec<DropData>, RedrawFailure> {
        self.traces
            .iter()
            .zip(sims)
            .map(|(tc, sim)| {
                let n = tc.data.impacts.len();
                let first = sim
                    .impacts
                    .first()
                    .ok_or(RedrawFailure::NoSimulatedImpact)?;
                let shift = tc.shift_onto(0, first);
                let mut value = resample(&sim.samples, tc.data.t_s.iter().map(|t| t + shift));
                let mut rng = noise_rng(Stream::Redraw, tc.index, redraw);
                for f in &mut value {
                    *f += tc.data.noise_n
                        * <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
                }
                let d = analyse_redraw(tc.data.t_s.clone(), &value, n)
                    .map_err(|_| RedrawFailure::NoImpact)?;
                if d.impacts.len() < n {
                    return Err(RedrawFailure::FewerImpacts);
                }
                Ok(d)
            })
            .collect()
    }

    /// The noise standard deviation of each trace's samples, N.
    pub(crate) fn noise_n(&self) -> Vec<f64> {
        self.traces.iter().map(|t| t.data.noise_n).collect()
    }

    /// Terms of the error (those of [`Self::terms_all`] with a non-zero weight).
    pub(crate) fn cost_term_count(&self) -> usize {
        let info = self.term_info();
        self.term_weights(&info)
            .iter()
            .filter(|w| **w > 0.0)
            .count()
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
    /// profile terms only with `profile`).
    fn trace_terms(tc: &TraceCtx<'_>, sim: &SimDrop, profile: bool) -> Vec<Term> {
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
            if profile {
                let (a, b) = m.window;
                let measured = &tc.data.force_n[a..=b];
                match s {
                    Some(s) => {
                        let times = tc.data.t_s[a..=b]
                            .iter()
                            .map(|t| t - m.centroid_s + s.centroid_s);
                        for (fsim, f) in s.forces_at(times).zip(measured) {
                            out.push(Term::Profile((fsim - f) / tc.f_ref));
                        }
                    }
                    None => {
                        out.extend(measured.iter().map(|f| Term::Profile((0.0 - f) / tc.f_ref)))
                    }
                }
            }
        }
        out
    }
}

/// The step of the central differences in the search coordinates ([`Problem::around`]).
pub(crate) const JACOBIAN_STEP: f64 = 1e-3;

/// The simulated drops at a point of the search and one [`JACOBIAN_STEP`] up and down each
/// coordinate (`None` beyond a bound): what [`Problem::linearise`] needs, for any data.
pub(crate) struct Around {
    /// At the point, all samples kept.
    pub center: Vec<SimDrop>,
    /// Per coordinate: one step up, one step down.
    pub steps: Vec<[Option<Vec<SimDrop>>; 2]>,
}

/// The error linearised at a point: every term ([`Problem::terms_all`]), its Jacobian in the
/// search coordinates, each term's part and weight in the error.
pub(crate) struct Linear {
    /// Terms, unweighted.
    pub r: DVector<f64>,
    /// `∂r/∂x`.
    pub jac: DMatrix<f64>,
    /// Each term's part.
    pub parts: Vec<Part>,
    /// Each term's factor in the error ([`Problem::term_weights`]).
    pub w: Vec<f64>,
}

/// `jac` with row `i` scaled by `w[i]`.
pub(crate) fn weighted(jac: &DMatrix<f64>, w: &[f64]) -> DMatrix<f64> {
    let mut jw = jac.clone();
    for (i, wi) in w.iter().enumerate() {
        jw.row_mut(i).scale_mut(*wi);
    }
    jw
}

impl Problem<'_> {
    /// The drops around `x` (whose law is `law`).
    ///
    /// # Errors
    /// A failed simulation at `x`.
    pub(crate) fn around(&self, x: &[f64], law: &ContactLaw) -> Result<Around> {
        let center = self.simulate(law, true)?;
        let steps = (0..x.len())
            .map(|j| {
                [1.0, -1.0].map(|sign| {
                    let mut xs = x.to_vec();
                    xs[j] += sign * JACOBIAN_STEP;
                    self.simulate(&self.law_at(&xs).ok()?, false).ok()
                })
            })
            .collect();
        Ok(Around { center, steps })
    }

    /// The error on this problem's data linearised with the drops `around` a point (central
    /// differences, one-sided next to a bound); `None` if a coordinate has no drop on either
    /// side or the terms do not match.
    pub(crate) fn linearise(&self, around: &Around) -> Option<Linear> {
        let info = self.term_info();
        let w = self.term_weights(&info);
        let r0 = self.terms_all(&around.center);
        let n = r0.len();
        if n != info.len() {
            return None;
        }
        let mut jac = DMatrix::<f64>::zeros(n, around.steps.len());
        for (j, [up, down]) in around.steps.iter().enumerate() {
            let at = |s: &Option<Vec<SimDrop>>| {
                s.as_ref()
                    .map(|s| self.terms_all(s))
                    .filter(|t| t.len() == n)
            };
            let (col, span): (Vec<f64>, f64) = match (at(up), at(down)) {
                (Some(u), Some(d)) => (u.iter().zip(&d).map(|(u, d)| u - d).collect(), 2.0),
                (Some(u), None) => (u.iter().zip(&r0).map(|(u, c)| u - c).collect(), 1.0),
                (None, Some(d)) => (r0.iter().zip(&d).map(|(c, d)| c - d).collect(), 1.0),
                (None, None) => return None,
            };
            for (i, v) in col.iter().enumerate() {
                jac[(i, j)] = v / (span * JACOBIAN_STEP);
            }
        }
        Some(Linear {
            r: DVector::from_vec(r0),
            jac,
            parts: info.iter().map(|t| t.part).collect(),
            w,
        })
    }

    /// The Gauss–Newton step from the point of `around` on this problem's data: `−(W R)⁺ W r`
    /// (pseudo-inverse by SVD, singular values below `1e-9` of the largest dropped).
    pub(crate) fn gauss_newton(&self, around: &Around) -> Option<Vec<f64>> {
        let l = self.linearise(around)?;
        let rw = DVector::from_iterator(l.r.len(), l.r.iter().zip(&l.w).map(|(v, w)| v * w));
        let svd = weighted(&l.jac, &l.w).svd(true, true);
        let tol = 1e-9 * svd.singular_values.max().max(1e-300);
        let step = -(svd.pseudo_inverse(tol).ok()? * rw);
        step.iter()
            .all(|v| v.is_finite())
            .then(|| step.iter().copied().collect())
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

impl<'a> Problem<'a> {
    /// The problem of fitting `law` to `tests` with `weights`, its search coordinates scaled by
    /// the first test's data ([`initial`]).
    ///
    /// # Errors
    /// No test, a test without impacts, or invalid rig parameters or drop setup of any test
    /// (checked with the preset law, named with the test's number).
    pub(crate) fn new(
        tests: &'a [DropTest],
        law: ContactLawKind,
        weights: Weights,
    ) -> Result<Self> {
        ensure!(!tests.is_empty(), "no drop test to fit");
        for (i, t) in tests.iter().enumerate() {
            ensure!(
                !t.data.impacts.is_empty(),
                "drop test {}: no measured impact",
                i + 1
            );
        }
        let (x0_scale, delta_ref) = initial(law, &tests[0].data, tests[0].setup.params.mass_kg);
        let problem = Problem {
            traces: tests
                .iter()
                .enumerate()
                .map(|(i, t)| TraceCtx::new(&t.setup, &t.data, i))
                .collect(),
            law,
            weights,
            delta_ref,
            x0_scale,
        };
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
        Ok(problem)
    }
}

//! Identification on the board: the contact law and the suspension's natural frequency from a
//! drop test's capture (thesis §3.3.2, Figs. 3.8–3.10), in f32, without allocation, in one pass
//! of a few reads over the segments — what the rig's commissioning runs after its drop.
//!
//! What a drop at 0.0 mm gap fixes, with the force sensor alone:
//! - **the contact law** from the pulses' shape: the spring–dashpot law (Table 3.1's) by linear
//!   least squares on the momentum balance ([`linear_fit`]), all pulses at once;
//! - **the natural frequency** from the impacts' spacing: released against the surface at its
//!   rest position, the free hammer leaves the surface and returns to it half a damped period
//!   `π / ω_d` later, whatever the rebound ([`spacing`]); the suspension's damping ratio from
//!   the speed lost over that half period (successive impulses over the law's restitution).
//!
//! Each result carries its quality: the fit's residual over the sensor noise measured before
//! the impacts (the reduced χ², 1 when the law fits), 95 % intervals of `k_i` and `c_i` from
//! the fit's covariance, the spread of the half periods. A capture that cannot fix them is
//! refused with the reason ([`DropRefusal`]).

pub mod linear_fit;
pub mod power_fit;
pub mod pulse;
pub mod record;
pub mod spacing;

pub use record::{CaptureOnChain, DropRecord, RecordedDrop, SegmentForce};

use crate::capture::SEGMENTS;
use crate::error::ParamError;
use crate::model::contact::spring_dashpot_restitution_in;
use crate::model::{ContactLaw, RigParams, Suspension};

use linear_fit::{NormalEquations, PulseMoments};
use pulse::Pulse;
use record::SAMPLE_PERIOD_S;
use spacing::{Kinematics, SuspensionId};

/// Fewest impacts a drop must give (two half periods to compare).
pub const MIN_IMPACTS: usize = 3;
/// Largest gap, m, at which the impacts' spacing gives the natural frequency (the surface at the
/// hammer's rest position).
pub const MAX_SPACING_GAP_M: f32 = 1e-5;
/// An impact is fitted when its peak is at least this many noise deviations (weaker ones, at
/// the train's end, are timed and shaped too poorly to help).
pub const MIN_PEAK_SIGMAS: f32 = 10.0;
/// The law fits when its residual is at most this many times what the sensor noise explains
/// (the desktop's lack-of-fit threshold).
pub const MAX_FIT_RATIO: f32 = 3.0;

/// Why a capture cannot be identified.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DropRefusal {
    /// Nothing crossed the trigger level: no drop.
    NoImpacts,
    /// Fewer impacts than [`MIN_IMPACTS`] of [`MIN_PEAK_SIGMAS`] or more (a drop from too low, or
    /// a contact that dissipates nearly all at once).
    TooFewImpacts {
        /// Strong impacts recorded.
        found: u16,
    },
    /// Samples were lost during the capture: impact times cannot be trusted.
    LostSamples {
        /// Samples lost.
        lost: u32,
    },
    /// A sample of an impact sat on an ADC rail: a drop from too high (or a sensor stuck).
    Saturated {
        /// Impact (0 for the first).
        impact: u16,
    },
    /// An impact's pulse runs past its segment (or into the baseline before it).
    Clipped {
        /// Impact.
        impact: u16,
    },
    /// An impact spans too few samples to be fitted.
    ShortPulse {
        /// Impact.
        impact: u16,
        /// Samples above the noise.
        samples: u16,
    },
    /// The force before an impact is not at rest (a rattling release, an impact inside the
    /// previous one's segment, a sensor that changed).
    RestlessBaseline {
        /// Impact.
        impact: u16,
        /// Its baseline's deviation, N.
        noise_n: f32,
        /// The capture's, N.
        typical_n: f32,
    },
    /// The impacts are not half a period apart (two drops, a rattling release).
    IrregularSpacing {
        /// The impact that arrived off time.
        impact: u16,
        /// Its spacing, ms.
        spacing_ms: f32,
        /// The spacing of the others (median), ms.
        expected_ms: f32,
    },
    /// The train of impacts stops while the capture ran on and the next impact should have
    /// crossed the trigger level (a sensor that went open).
    TrainStopped {
        /// Impacts recorded.
        impacts: u16,
        /// The next impact's expected peak, N.
        expected_n: f32,
    },
    /// A strong impact after the train had faded (a second drop, a rattling release).
    SecondTrain {
        /// The impact.
        impact: u16,
        /// Its peak, N.
        peak_n: f32,
    },
    /// The pulses do not separate stiffness from damping, or give one that is not positive.
    NotIdentifiable,
    /// The rig's mass in the model is not a positive finite number.
    BadMass,
}

/// What a drop test fixed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DropIdentification {
    /// Impacts used.
    pub impacts: u16,
    /// The sensor's offset at rest (mean of the baselines), N.
    pub offset_n: f32,
    /// The sensor's noise at rest (pooled deviation of the baselines), N.
    pub noise_n: f32,
    /// Peak force of the first impact, N.
    pub first_peak_n: f32,
    /// Approach speed of the first impact, m/s.
    pub approach_speed_m_s: f32,
    /// Its restitution (rebound over approach speed, at the surface).
    pub restitution: f32,
    /// The contact law the pulses fixed.
    pub law: DropLaw,
    /// Its residual over what the sensor noise explains (reduced χ², about 1 when the law
    /// fits).
    pub fit_ratio: f32,
    /// The suspension, when the gap lets the spacing fix it.
    pub suspension: Option<SuspensionId>,
}

/// The contact law a drop fixed, with the 95 % half-widths of its parameters (from the fit's
/// covariance scaled by its residual).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DropLaw {
    /// Table 3.1's law, Eq. (3-3): `F = k_i δ + c_i δ̇` ([`linear_fit`]).
    SpringDashpot {
        /// `k_i`, N/m.
        stiffness_n_m: f32,
        /// 95 % half-width of `k_i`, % of it.
        stiffness_pm_pct: f32,
        /// `c_i`, N s/m.
        damping_n_s_m: f32,
        /// 95 % half-width of `c_i`, % of it.
        damping_pm_pct: f32,
    },
    /// Hunt–Crossley, Eq. (3-4): `F = k_i δ^n (1 + λ_i δ̇)` ([`power_fit`]), where the
    /// spring–dashpot law does not fit.
    HuntCrossley {
        /// `k_i`, N/m^n.
        stiffness: f32,
        /// 95 % half-width of `k_i`, % of it (mostly `n`'s: the two move together).
        stiffness_pm_pct: f32,
        /// `n`.
        exponent: f32,
        /// 95 % half-width of `n`.
        exponent_pm: f32,
        /// `λ_i`, s/m.
        lambda_s_m: f32,
        /// 95 % half-width of `λ_i`, % of it.
        lambda_pm_pct: f32,
    },
}

impl DropLaw {
    /// The model's contact law, each parameter rounded to 7 significant digits (what an `f32`
    /// carries; the model reads as plain decimals).
    pub fn contact(&self) -> ContactLaw {
        let r = |x: f32| sig7(f64::from(x));
        match *self {
            DropLaw::SpringDashpot {
                stiffness_n_m,
                damping_n_s_m,
                ..
            } => ContactLaw::SpringDashpot {
                stiffness_n_m: r(stiffness_n_m),
                damping_n_s_m: r(damping_n_s_m),
            },
            DropLaw::HuntCrossley {
                stiffness,
                exponent,
                lambda_s_m,
                ..
            } => ContactLaw::HuntCrossley {
                stiffness: r(stiffness),
                exponent: r(exponent),
                lambda_s_m: r(lambda_s_m),
            },
        }
    }
}

impl DropIdentification {
    /// Whether the identified law fits the pulses (`fit_ratio ≤ MAX_FIT_RATIO`).
    pub fn law_fits(&self) -> bool {
        self.fit_ratio <= MAX_FIT_RATIO
    }

    /// `base` with the identified contact law, and the identified suspension (natural frequency
    /// and damping ratio; the pendulum's length `l = g / ω²`) where the drop fixed it. Each value
    /// is rounded to 7 significant digits (what an `f32` carries; the model reads as plain
    /// decimals).
    ///
    /// # Errors
    /// [`ParamError`] when the result is outside the model's ranges.
    pub fn applied_to(&self, base: &RigParams) -> Result<RigParams, ParamError> {
        let mut p = *base;
        p.contact = self.law.contact();
        if let Some(s) = self.suspension {
            let omega = 2.0 * core::f64::consts::PI * f64::from(s.natural_freq_hz);
            let zeta = sig7(f64::from(s.damping_ratio));
            p.suspension = match p.suspension {
                Suspension::Wires { .. } => Suspension::Wires {
                    length_m: sig7(p.gravity_m_s2 / (omega * omega)),
                    damping_ratio: zeta,
                },
                Suspension::Beam { .. } => Suspension::Beam {
                    natural_freq_hz: sig7(f64::from(s.natural_freq_hz)),
                    damping_ratio: zeta,
                },
            };
        }
        p.validate()?;
        Ok(p)
    }
}

/// Per impact, what the later passes need.
#[derive(Debug, Clone, Copy, Default)]
struct PulseSummary {
    start: u32,
    first: usize,
    len: usize,
    peak_n: f32,
    moments: PulseMoments,
    /// `F` at the first and last samples, `I`, `II` at the last, and the force after it.
    first_n: f32,
    last_n: f32,
    int1_last: f32,
    int2_last: f32,
    after_n: f32,
}

/// Identifies the spring–dashpot law (and, at a gap of at most [`MAX_SPACING_GAP_M`], the
/// suspension) from the drop test `rec`, for a hammer of `mass_kg` at `gap_m`.
///
/// # Errors
/// [`DropRefusal`]: why the capture cannot fix them.
#[inline(never)]
pub fn identify_drop(
    rec: &mut impl DropRecord,
    mass_kg: f32,
    gap_m: f32,
) -> Result<DropIdentification, DropRefusal> {
    if !(mass_kg.is_finite() && mass_kg > 0.0) {
        return Err(DropRefusal::BadMass);
    }
    let n = rec.segments().min(SEGMENTS);
    if rec.lost_samples() > 0 {
        return Err(DropRefusal::LostSamples {
            lost: rec.lost_samples(),
        });
    }
    if n == 0 {
        return Err(DropRefusal::NoImpacts);
    }
    // Pass 1: rails, baselines and peaks.
    let mut sd = [0.0f32; SEGMENTS];
    let mut peaks = [0.0f32; SEGMENTS];
    let mut starts = [0u32; SEGMENTS];
    let (mut offset, mut var) = (0.0f32, 0.0f32);
    for k in 0..n {
        let seg = rec.segment(k).ok_or(DropRefusal::NoImpacts)?;
        if seg.railed {
            return Err(DropRefusal::Saturated { impact: k as u16 });
        }
        let (m, v) = pulse::baseline(&seg);
        offset += m;
        var += v;
        sd[k] = libm::sqrtf(v);
        peaks[k] = seg.force_n.iter().fold(f32::MIN, |a, &f| a.max(f)) - m;
        starts[k] = seg.start;
    }
    let recorded = n;
    offset /= n as f32;
    // Quantisation alone: one code's force over √12.
    let sigma = libm::sqrtf(var / n as f32).max(rec.resolution_n() / libm::sqrtf(12.0));
    let mut sorted = sd;
    let typical = median(&mut sorted[..n]).max(rec.resolution_n());
    for (k, &s) in sd.iter().enumerate().take(n) {
        if s > 3.0 * typical {
            return Err(DropRefusal::RestlessBaseline {
                impact: k as u16,
                noise_n: s,
                typical_n: typical,
            });
        }
    }
    // The train's strong impacts: the first ones, until one is too weak to fit. A strong one
    // after a weak one belongs to something else, unless the weak ones between are noise that
    // crossed the trigger level: the strong one then arrives one spacing after the last.
    let strong = |k: usize| peaks[k] >= MIN_PEAK_SIGMAS * sigma;
    let mut train = [0usize; SEGMENTS];
    let mut n = 0;
    let mut k = 0;
    while k < recorded && strong(k) {
        train[n] = k;
        n += 1;
        k += 1;
        let Some(next) = (k..recorded).find(|&j| strong(j)) else {
            break;
        };
        if next > k && n >= 2 {
            let spacing = starts[train[n - 1]].wrapping_sub(starts[train[n - 2]]) as f32;
            let gap = starts[next].wrapping_sub(starts[train[n - 1]]) as f32;
            if libm::fabsf(gap - spacing) <= spacing::MAX_SPACING_DEVIATION * spacing {
                k = next;
            }
        }
    }
    if let Some(k) = (k..recorded).find(|&k| strong(k)) {
        return Err(DropRefusal::SecondTrain {
            impact: k as u16,
            peak_n: peaks[k],
        });
    }
    if n < MIN_IMPACTS {
        return Err(DropRefusal::TooFewImpacts { found: n as u16 });
    }
    // Pass 2: windows and the normal equations. A weak impact late in the train lasts longer
    // (a power law's contact time grows as the speed falls): where its pulse runs past its
    // segment, the train ends before it.
    let mut pulses = [PulseSummary::default(); SEGMENTS];
    let mut normal = NormalEquations::default();
    // One pulse buffer for every pass (and the power law's fit).
    let mut p = Pulse::empty();
    for (k, ps) in pulses.iter_mut().enumerate().take(n) {
        let seg = rec.segment(train[k]).ok_or(DropRefusal::NoImpacts)?;
        match p.read(&seg, train[k], offset, sigma) {
            Err(DropRefusal::Clipped { .. }) if k >= MIN_IMPACTS => {
                n = k;
                break;
            }
            r => r?,
        }
        let m = PulseMoments::of(&p);
        normal.add(&p, &m);
        let last = p.len - 1;
        *ps = PulseSummary {
            start: seg.start,
            first: p.first,
            len: p.len,
            peak_n: p.peak_n,
            moments: m,
            first_n: p.force[0],
            last_n: p.force[last],
            int1_last: p.int1[last],
            int2_last: p.int2[last],
            after_n: p.edges.1,
        };
    }
    let ([kappa, gamma], inv) = normal.solve().ok_or(DropRefusal::NotIdentifiable)?;
    if !(kappa > 0.0 && gamma > 0.0) {
        return Err(DropRefusal::NotIdentifiable);
    }
    // Pass 3: the residual.
    let mut rss = 0.0f32;
    for (k, ps) in pulses.iter().enumerate().take(n) {
        let seg = rec.segment(train[k]).ok_or(DropRefusal::NoImpacts)?;
        p.read(&seg, train[k], offset, sigma)?;
        rss += linear_fit::residual(&p, &ps.moments, kappa, gamma);
    }
    let dof = normal.dof().max(1) as f32;
    let resid_var = rss / dof;
    let dt = SAMPLE_PERIOD_S;
    let k_i = kappa * mass_kg / (dt * dt);
    let c_i = gamma * mass_kg / dt;
    // 95 %: 1.96 σ, the residual's own variance scaling the covariance.
    let pm = |var: f32, x: f32| 196.0 * libm::sqrtf(var.max(0.0) * resid_var) / x;
    let mut law = DropLaw::SpringDashpot {
        stiffness_n_m: k_i,
        stiffness_pm_pct: pm(inv[0], kappa),
        damping_n_s_m: c_i,
        damping_pm_pct: pm(inv[2], gamma),
    };
    let mut fit_ratio = resid_var / (sigma * sigma);
    let mut starts = [(0.0f32, 0.0f32); SEGMENTS];
    for (k, s) in starts.iter_mut().enumerate().take(n) {
        *s = pulses[k].moments.start(kappa, gamma, mass_kg);
    }
    // Where the spring–dashpot law does not fit: the Hunt–Crossley law, started from it, when
    // it fits better.
    if fit_ratio > MAX_FIT_RATIO {
        let start = hunt_crossley_start(&pulses[..n], &starts, k_i, mass_kg);
        let hc = power_fit::fit(&start, mass_kg, &mut p, |k, p| {
            let seg = rec.segment(train[k]).ok_or(DropRefusal::NoImpacts)?;
            p.read(&seg, train[k], offset, sigma)
        });
        if let Ok(f) = hc {
            let ratio = f.rss / f.dof as f32 / (sigma * sigma);
            if ratio < fit_ratio {
                fit_ratio = ratio;
                starts = f.kinematics;
                law = DropLaw::HuntCrossley {
                    stiffness: f.law.stiffness,
                    stiffness_pm_pct: f.stiffness_pm_pct,
                    exponent: f.law.exponent,
                    exponent_pm: f.exponent_pm,
                    lambda_s_m: f.law.lambda_s_m,
                    lambda_pm_pct: f.lambda_pm_pct,
                };
            }
        }
    }
    let mut kin = [Kinematics::default(); SEGMENTS];
    for (k, kn) in kin.iter_mut().enumerate().take(n) {
        *kn = Kinematics::of(&pulses[k], starts[k], mass_kg);
    }
    let suspension = if gap_m <= MAX_SPACING_GAP_M {
        // Each impact's restitution under the fitted law (the measured one where the law gives
        // none: an overdamped spring–dashpot fit has no closed form, the first impact's then).
        let mut restitution = [0.0f32; SEGMENTS];
        let measured = |k: &Kinematics| -k.v_out / k.v_arrival;
        match law {
            DropLaw::SpringDashpot { .. } => {
                let e = spring_dashpot_restitution_in(k_i, c_i, mass_kg)
                    .map_or(measured(&kin[0]), |(e, _)| e);
                restitution[..n].fill(e);
            }
            DropLaw::HuntCrossley {
                stiffness,
                exponent,
                lambda_s_m,
                ..
            } => {
                let hc = power_fit::HuntCrossley {
                    stiffness,
                    exponent,
                    lambda_s_m,
                };
                for (e, k) in restitution.iter_mut().zip(&kin[..n]) {
                    *e = hc.restitution(mass_kg, k.v_arrival).unwrap_or(measured(k));
                }
            }
        }
        Some(spacing::suspension(
            &kin[..n],
            &restitution[..n],
            (train[n - 1] + 1 == recorded).then(|| (rec.level_n(), rec.samples())),
        )?)
    } else {
        None
    };
    let first = &kin[0];
    Ok(DropIdentification {
        impacts: n as u16,
        offset_n: offset,
        noise_n: sigma,
        first_peak_n: pulses[0].peak_n,
        approach_speed_m_s: first.v_arrival,
        restitution: -first.v_out / first.v_arrival,
        law,
        fit_ratio,
        suspension,
    })
}

/// Where the Hunt–Crossley fit starts, from the spring–dashpot fit (`k_i` N/m, each pulse's
/// `(v₀, t₀)` in `starts`): `n` = 1.5 (Hertz's), the reference penetration the first impact's
/// deepest under the linear law (`v / ω_c`), the elastic force there the linear law's, and
/// `λ_i` from the first impact's restitution by Hunt and Crossley's `e ≈ 1 − 2λv/3`.
fn hunt_crossley_start(
    pulses: &[PulseSummary],
    starts: &[(f32, f32); SEGMENTS],
    k_i: f32,
    mass_kg: f32,
) -> power_fit::Start {
    let first = Kinematics::of(&pulses[0], starts[0], mass_kg);
    let delta_ref_m = first.v_arrival / libm::sqrtf(k_i / mass_kg);
    let e = (-first.v_out / first.v_arrival).clamp(0.05, 0.99);
    let exponent = 1.5;
    power_fit::Start {
        law: power_fit::HuntCrossley {
            stiffness: k_i * delta_ref_m / libm::powf(delta_ref_m, exponent),
            exponent,
            lambda_s_m: 1.5 * (1.0 - e) / first.v_arrival,
        },
        delta_ref_m,
        kinematics: *starts,
        pulses: pulses.len(),
    }
}

/// `ln x` (`libm::logf`), one copy: the identification calls it from several places, each of
/// which would otherwise inline its own.
#[inline(never)]
pub(crate) fn ln(x: f32) -> f32 {
    libm::logf(x)
}

/// `x` rounded to 7 significant digits: the `f64` nearest that decimal (0 and non-finite values
/// unchanged).
fn sig7(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let lead = libm::floor(libm::log10(libm::fabs(x))) as i32;
    let shift = 6 - lead;
    if shift >= 0 {
        let scale = libm::pow(10.0, f64::from(shift));
        libm::round(x * scale) / scale
    } else {
        let scale = libm::pow(10.0, f64::from(-shift));
        libm::round(x / scale) * scale
    }
}

/// Median of `xs` (sorted in place; an insertion sort: at most [`SEGMENTS`] values, and a
/// fraction of the flash of the library's sort).
fn median(xs: &mut [f32]) -> f32 {
    for i in 1..xs.len() {
        let mut j = i;
        while j > 0 && xs[j - 1].total_cmp(&xs[j]).is_gt() {
            xs.swap(j - 1, j);
            j -= 1;
        }
    }
    match xs.len() {
        0 => 0.0,
        l if l % 2 == 1 => xs[l / 2],
        l => 0.5 * (xs[l / 2 - 1] + xs[l / 2]),
    }
}

#[cfg(test)]
mod tests {
    use super::sig7;

    #[test]
    fn seven_significant_digits_read_as_their_decimal() {
        assert_eq!(sig7(f64::from(721.4777f32)), 721.4777);
        assert_eq!(sig7(11_009_862.0), 11_009_860.0);
        assert_eq!(sig7(0.000_031_431_628), 0.000_031_431_63);
        assert_eq!(sig7(0.064_211_287_3), 0.064_211_29);
        assert_eq!(sig7(-1.234_567_89), -1.234_568);
        assert_eq!(sig7(0.0), 0.0);
    }
}

//! Shooting: Newton's method on `P^q(x) − x = 0` for a periodic orbit of period `q` (a `p/q`
//! regime), from a state near it (Dankowicz & Schilder, *Recipes for Continuation*, SIAM 2013,
//! ch. 7). Each iteration runs `q` periods in dual numbers ([`super::map::tangent`]), which give
//! the residual and the Jacobian `M − I` together; steps that do not reduce the residual are
//! halved (at most four times).
//!
//! Distances are scaled by the cart's motion ([`MapPoint::scales`]): a residual of 1e-11 is
//! 1e-11 of `A0` (and of `A0 Ω` for the velocity).

use core::fmt;

use nalgebra::Vector2;

use super::floquet::Floquet;
use super::map::{Image, MapPoint, Trace, iterate, tangent};
use crate::error::ParamError;
use crate::real::Real;

/// Newton's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShootSettings {
    /// Iterations at most (20).
    pub max_iterations: u32,
    /// Scaled residual `|P^q(x) − x|` (largest component over its scale) that counts as
    /// converged: [`ShootSettings::for_type`].
    pub tolerance: f64,
}

impl ShootSettings {
    /// The defaults for the float type `T`: 20 iterations, a tolerance of 1e-11 in f64 and
    /// 1e-5 in f32 (a few hundred times the rounding of one period's map in each).
    pub fn for_type<T: Real>() -> Self {
        ShootSettings {
            max_iterations: 20,
            tolerance: if T::EPSILON < 1e-10 { 1e-11 } else { 1e-5 },
        }
    }
}

/// A periodic orbit: a fixed point of `P^q`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orbit<T> {
    /// Where it was found.
    pub at: MapPoint,
    /// Its period, excitation periods.
    pub q: u32,
    /// Its state on the stroboscopic section (phase 0).
    pub x: Vector2<T>,
    /// What one period `q` of it does: impacts `p`, largest force, slowest arrival.
    pub trace: Trace,
    /// The monodromy matrix `DP^q` (row-major).
    pub monodromy: [[f64; 2]; 2],
    /// Its multipliers.
    pub floquet: Floquet,
    /// Scaled residual at convergence.
    pub residual: f64,
    /// Newton iterations taken.
    pub iterations: u32,
}

impl<T: Real> Orbit<T> {
    /// How far the map's own slope departs from the monodromy here: the largest difference
    /// between a central secant of `P^q` over ±`h` of the state's scales ([`MapPoint::scales`])
    /// and the matching entry of the monodromy, both scaled, over the monodromy's largest
    /// entry or 1, whichever is larger (the scale on which multipliers are judged). The secant
    /// is the f64 map's (the same steps) at the orbit's state, whatever `T`: f32's own rounding
    /// over ±1e-4 of the scales is up to 5e-2 of a secant (a smooth orbit would look like one at
    /// a grazing), the f32 monodromy agrees with the f64 secant to 1e-3 or better. Small
    /// where the map is smooth over that span (3.0e-10 at `h` = 1e-4 at the wire rig's `1/1`
    /// orbit, 0.0 mm, Ω/ω 2.0, in f64; 8.2e-6 with the f32 orbit and monodromy). Large within
    /// `h` of a grazing (37 at that rig's `1/1` orbit at Ω/ω 1.15172, 3e-5 above the band's
    /// lower edge), where an impact appears or vanishes and the multipliers, the stability and
    /// the bifurcations located from them describe one side of the map only.
    ///
    /// # Errors
    /// [`ParamError`] where a displaced state is invalid.
    pub fn slope_mismatch(&self, h: f64) -> Result<f64, ParamError> {
        let s = self.at.scales();
        let m = &self.monodromy;
        let scaled = |i: usize, j: usize| m[i][j] * s[j] / s[i];
        let largest = (0..2)
            .flat_map(|i| (0..2).map(move |j| (i, j)))
            .fold(0.0f64, |a, (i, j)| a.max(scaled(i, j).abs()));
        let mut worst = 0.0f64;
        for j in 0..2 {
            let image = |sign: f64| -> Result<(Vector2<f64>, f64), ParamError> {
                let mut x = self.x.map(|v| v.to_f64());
                x[j] += sign * h * s[j];
                Ok((iterate::<f64>(&self.at, self.q, x)?.x, x[j]))
            };
            let ((yp, xp), (ym, xm)) = (image(1.0)?, image(-1.0)?);
            for i in 0..2 {
                let secant = (yp[i] - ym[i]) / (xp - xm) * s[j] / s[i];
                worst = worst.max((secant - scaled(i, j)).abs());
            }
        }
        Ok(worst / largest.max(1.0))
    }

    /// Impacts per `q` periods (`p` of `z = p/q`).
    pub fn p(&self) -> u32 {
        self.trace.impacts
    }

    /// Whether the orbit is conservative: no contact force anywhere along it, on a suspension
    /// whose free flight conserves area ([`crate::model::RigParams::free_flight_conservative`]):
    /// the multipliers are then a pair `μ, 1/μ` or a complex pair on the unit circle, whatever
    /// the parameters. The computed `det M` differs from 1 only by the integrator's error
    /// (RK4's, and f32's rounding).
    pub fn conservative(&self) -> bool {
        self.at.params.free_flight_conservative()
            && self.trace.impacts == 0
            && self.trace.max_force_n == 0.0
    }

    /// Its stability from its multipliers: [`Stability::Neutral`] for a conservative orbit
    /// ([`Orbit::conservative`]) with a complex pair (`|μ| = 1` exactly in the model, however
    /// the computed modulus rounds) or a real pair computed inside the unit circle (`μ₁ μ₂ = 1`
    /// allows that only at a double `±1`), else [`Stability::Stable`] where every `|μ| < 1` and
    /// [`Stability::Unstable`] otherwise (a conservative orbit's real pair `μ, 1/μ`: a saddle).
    pub fn stability(&self) -> Stability {
        if self.conservative() && (self.floquet.complex() || self.floquet.stable()) {
            Stability::Neutral
        } else if self.floquet.stable() {
            Stability::Stable
        } else {
            Stability::Unstable
        }
    }

    /// Largest impact force over `m g`.
    pub fn impact_force_mg(&self) -> f64 {
        self.trace.max_force_n / self.at.params.weight_n()
    }
}

/// How the motions near a periodic orbit behave, from its multipliers ([`Orbit::stability`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stability {
    /// Every `|μ| < 1`: nearby motions converge onto the orbit (an attractor).
    Stable,
    /// A conservative orbit whose multipliers lie on the unit circle (a complex pair: an
    /// elliptic point of an area-preserving map; or a double `±1`): nearby motions neither
    /// converge onto it nor leave it exponentially; it attracts nothing.
    Neutral,
    /// Some `|μ| ≥ 1`: nearby motions leave it.
    Unstable,
}

impl Stability {
    /// Its name in reports and CSV: `stable`, `neutral`, `unstable`.
    pub fn name(self) -> &'static str {
        match self {
            Stability::Stable => "stable",
            Stability::Neutral => "neutral",
            Stability::Unstable => "unstable",
        }
    }
}

/// Why shooting found no orbit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OrbitError {
    /// The point or the state is invalid.
    Param(ParamError),
    /// Newton did not converge: the iterations taken and the scaled residual reached.
    NotConverged {
        /// Iterations.
        iterations: u32,
        /// Scaled residual.
        residual: f64,
    },
    /// No step along Newton's direction, down to 1/16 of it, reduced the scaled residual: the
    /// map jumps or turns sharply between the iterate and the orbit (a kink or jump of the
    /// discretised map, docs/accuracy.md), or the start is too far from an orbit.
    Stalled {
        /// Newton steps taken before.
        iterations: u32,
        /// Scaled residual at the iterate.
        residual: f64,
    },
    /// `M − I` is singular to working precision at the iterate: no Newton step. Either a
    /// multiplier is at +1 (a fold), or the motion stretches so much over the `q` periods
    /// (`max |μ|` far above 1, or not finite) that the columns of `M` are parallel to rounding:
    /// an orbit too unstable to shoot over that many periods at once.
    Singular {
        /// Iterations before.
        iterations: u32,
        /// `max |μ|` of the monodromy at the iterate (infinite where `M` is not finite).
        max_multiplier: f64,
    },
    /// The protocol saw no period to shoot for (and none was given).
    NoPeriod {
        /// What it saw.
        regime: crate::observe::Regime,
    },
}

impl From<ParamError> for OrbitError {
    fn from(e: ParamError) -> Self {
        OrbitError::Param(e)
    }
}

impl fmt::Display for OrbitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OrbitError::Param(e) => write!(f, "{e}"),
            OrbitError::NotConverged {
                iterations,
                residual,
            } => write!(
                f,
                "Newton did not converge in {iterations} iterations (scaled residual {residual:.3e})"
            ),
            OrbitError::Stalled {
                iterations,
                residual,
            } => write!(
                f,
                "Newton stalled after {iterations} step(s): no step along its direction, down to \
                 1/16 of it, reduced the scaled residual {residual:.3e} (the discretised map jumps \
                 or kinks here, or the start is far from an orbit)"
            ),
            OrbitError::Singular {
                iterations,
                max_multiplier,
            } if *max_multiplier >= STRETCHED => {
                write!(
                    f,
                    "M − I is singular to working precision after {iterations} iterations: \
                     nearby motions separate by "
                )?;
                if max_multiplier.is_finite() {
                    write!(f, "a factor {max_multiplier:.1e}")?;
                } else {
                    f.write_str("more than the float type holds")?;
                }
                f.write_str(
                    " over the q periods, an orbit too unstable to shoot over that many at once \
                     (try a smaller q)",
                )
            }
            OrbitError::Singular { iterations, .. } => write!(
                f,
                "M − I is singular after {iterations} iterations (a multiplier at +1: a fold?)"
            ),
            OrbitError::NoPeriod { regime } => write!(
                f,
                "the protocol settled on no period (regime {regime}): give the period q"
            ),
        }
    }
}

/// Above this `max |μ|` a singular `M − I` is the motion's stretching, not a fold.
const STRETCHED: f64 = 1e3;

/// The scaled size `max_i |v_i| / s_i`.
pub(crate) fn scaled_norm(v: [f64; 2], s: [f64; 2]) -> f64 {
    (v[0] / s[0]).abs().max((v[1] / s[1]).abs())
}

/// The residual `P^q(x) − x` in f64.
fn residual<T: Real>(img: &Image<T>, x: &Vector2<T>) -> [f64; 2] {
    [
        img.x[0].to_f64() - x[0].to_f64(),
        img.x[1].to_f64() - x[1].to_f64(),
    ]
}

/// Solves `a z = b` (2 × 2); `None` if singular.
pub(crate) fn solve2(a: &[[f64; 2]; 2], b: [f64; 2]) -> Option<[f64; 2]> {
    let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
    let size = (a[0][0].abs() + a[0][1].abs()) * (a[1][0].abs() + a[1][1].abs());
    if det.abs().partial_cmp(&(1e-14 * size)) != Some(core::cmp::Ordering::Greater) {
        return None;
    }
    Some([
        (b[0] * a[1][1] - a[0][1] * b[1]) / det,
        (a[0][0] * b[1] - b[0] * a[1][0]) / det,
    ])
}

/// Finds the period-`q` orbit through a state near `x0` by Newton's method.
///
/// # Errors
/// [`OrbitError`]: an invalid point, no convergence within `settings.max_iterations` (with the
/// residual reached), a step that reduces the residual nowhere along Newton's direction
/// ([`OrbitError::Stalled`]), or a singular `M − I`.
pub fn shoot<T: Real>(
    at: &MapPoint,
    q: u32,
    x0: Vector2<T>,
    settings: &ShootSettings,
) -> Result<Orbit<T>, OrbitError> {
    let scales = at.scales();
    let mut x = x0;
    let (mut img, mut m) = tangent(at, q, x)?;
    let mut r = residual(&img, &x);
    let mut norm = scaled_norm(r, scales);
    for iteration in 0..=settings.max_iterations {
        if norm <= settings.tolerance {
            return Ok(Orbit {
                at: *at,
                q,
                x,
                trace: img.trace,
                monodromy: m,
                floquet: Floquet::of(&m),
                residual: norm,
                iterations: iteration,
            });
        }
        if iteration == settings.max_iterations {
            break;
        }
        let jac = [[m[0][0] - 1.0, m[0][1]], [m[1][0], m[1][1] - 1.0]];
        let Some(dx) = solve2(&jac, [-r[0], -r[1]]) else {
            let finite = m.iter().flatten().all(|v| v.is_finite());
            return Err(OrbitError::Singular {
                iterations: iteration,
                max_multiplier: if finite {
                    Floquet::of(&m).max_abs()
                } else {
                    f64::INFINITY
                },
            });
        };
        // Halve a step that does not reduce the residual (at most four times).
        let mut step = 1.0;
        let mut accepted = None;
        for _ in 0..5 {
            let trial = Vector2::new(
                T::from_f64(x[0].to_f64() + step * dx[0]),
                T::from_f64(x[1].to_f64() + step * dx[1]),
            );
            if let Ok((ti, tm)) = tangent(at, q, trial) {
                let tr = residual(&ti, &trial);
                let tn = scaled_norm(tr, scales);
                if tn.is_finite() && tn < norm {
                    accepted = Some((trial, ti, tm, tr, tn));
                    break;
                }
            }
            step *= 0.5;
        }
        let Some((nx, ni, nm, nr, nn)) = accepted else {
            return Err(OrbitError::Stalled {
                iterations: iteration,
                residual: norm,
            });
        };
        (x, img, m, r, norm) = (nx, ni, nm, nr, nn);
    }
    Err(OrbitError::NotConverged {
        iterations: settings.max_iterations,
        residual: norm,
    })
}

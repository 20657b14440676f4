//! The four contact laws of the thesis, Eq. (3-2)–(3-5), for penetration `δ > 0`.
//!
//! Each law splits into an elastic part and a dissipative part; the switch model's band
//! `Σ_α` keeps only the dissipative part (Eq. 3-28).

use core::fmt;
use core::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::{ParamError, check_range};
use crate::real::Real;

/// Contact law with its parameters (SI units; `k_i` in N/m^n).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum ContactLaw {
    /// Hertz, Eq. (3-2): `F = k δ^n`. Conservative (restitution 1).
    Hertz {
        /// `k_i`, N/m^n.
        stiffness: f64,
        /// `n` (dimensionless, 1..3; 1.5 for Hertzian spheres).
        exponent: f64,
    },
    /// Spring–dashpot (Kelvin–Voigt), Eq. (3-3): `F = k δ + c δ̇`. Identified for the rig (Table 3.1).
    SpringDashpot {
        /// `k_i`, N/m (Table 3.1: 5.5e6).
        stiffness_n_m: f64,
        /// `c_i`, N s/m (Table 3.1: 1.2e3).
        damping_n_s_m: f64,
    },
    /// Hunt–Crossley, Eq. (3-4): `F = k δ^n (1 + λ δ̇)`.
    HuntCrossley {
        /// `k_i`, N/m^n.
        stiffness: f64,
        /// `n`.
        exponent: f64,
        /// `λ_i = c_i / k_i`, s/m.
        lambda_s_m: f64,
    },
    /// Lankarani–Nikravesh, Eq. (3-5): `F = k δ^n [1 + 3(1 − e²)/4 · δ̇/δ̇⁻]`, `δ̇⁻` the approach speed.
    /// Valid near `e = 1` only (the damping term is derived for nearly elastic impacts): the
    /// impact rebounds at `e` within 1.5 % for `e ≥ 0.9`, but at 0.663 or more whatever `e`
    /// (0.687 for `e` = 0.317; [`ContactLaw::restitution`]).
    LankaraniNikravesh {
        /// `k_i`, N/m^n.
        stiffness: f64,
        /// `n`.
        exponent: f64,
        /// The coefficient of restitution `e` the law is built for (0.01..=1; the impact's
        /// rebound only near 1, see the variant's docs).
        restitution: f64,
    },
}

/// Declares [`ContactLawKind`] from one list of its variants and their names: the enum with its
/// serde names, [`ContactLawKind::ALL`] and [`ContactLawKind::name`] all come from the list, so
/// a law added to it is in each of them (and every `match` on the kind, [`ContactLaw::kind`] and
/// [`ContactLaw::preset`] among them, fails to compile until it handles the law).
macro_rules! law_kinds {
    ($($(#[doc = $doc:literal])* $variant:ident => $name:literal,)+) => {
        /// The law's name alone, for `--law`.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
        pub enum ContactLawKind {
            $($(#[doc = $doc])* #[serde(rename = $name)] $variant,)+
        }

        impl ContactLawKind {
            /// All laws.
            pub const ALL: [ContactLawKind; [$($name),+].len()] = [$(ContactLawKind::$variant),+];
            /// The names of [`ContactLawKind::ALL`], in its order.
            pub const NAMES: [&'static str; [$($name),+].len()] = [$($name),+];
            /// Command-line name (also the law's table in a config file: `[rig.contact.NAME]`).
            pub const fn name(self) -> &'static str {
                match self {
                    $(ContactLawKind::$variant => $name,)+
                }
            }
        }
    };
}

law_kinds! {
    /// See [`ContactLaw::Hertz`].
    Hertz => "hertz",
    /// See [`ContactLaw::SpringDashpot`].
    SpringDashpot => "spring-dashpot",
    /// See [`ContactLaw::HuntCrossley`].
    HuntCrossley => "hunt-crossley",
    /// See [`ContactLaw::LankaraniNikravesh`].
    LankaraniNikravesh => "lankarani-nikravesh",
}

impl fmt::Display for ContactLawKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Error of [`ContactLawKind::from_str`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnknownLaw;

impl fmt::Display for UnknownLaw {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("unknown contact law: expected one of ")?;
        for (i, k) in ContactLawKind::ALL.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            f.write_str(k.name())?;
        }
        Ok(())
    }
}

impl FromStr for ContactLawKind {
    type Err = UnknownLaw;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or(UnknownLaw)
    }
}

/// Hertz-type stiffness of the thesis' Fig. 3.3 illustration (Hunt–Crossley), N/m^1.6.
pub const FIG_3_3_STIFFNESS: f64 = 2.1e8;
/// Hertz-type exponent of the thesis' Fig. 3.3 illustration.
pub const FIG_3_3_EXPONENT: f64 = 1.6;
/// Hunt–Crossley `λ_i` of the thesis' Fig. 3.3 illustration, s/m.
pub const FIG_3_3_LAMBDA_S_M: f64 = 0.6;

impl ContactLaw {
    /// The law identified on the rig: spring–dashpot, `k_i = 5.5e6 N/m`, `c_i = 1.2e3 N s/m` (Table 3.1).
    pub const fn identified() -> Self {
        ContactLaw::SpringDashpot {
            stiffness_n_m: 5.5e6,
            damping_n_s_m: 1.2e3,
        }
    }

    /// Default parameters for each law. Only the spring–dashpot law was identified on the rig
    /// (Table 3.1); the power laws take the thesis' Fig. 3.3 values (`k_i = 2.1e8 N/m^1.6`,
    /// `n = 1.6`, `λ_i = 0.6 s/m`), and Lankarani–Nikravesh takes the parameter `e` = 0.317,
    /// the restitution of the identified spring–dashpot law ([`spring_dashpot_restitution`]) —
    /// but that law rebounds at 0.687 with it, not 0.317: its damping term holds near `e = 1`
    /// only ([`ContactLaw::restitution`]; docs/model.md lists every preset's).
    pub fn preset(kind: ContactLawKind) -> Self {
        match kind {
            ContactLawKind::SpringDashpot => Self::identified(),
            ContactLawKind::Hertz => ContactLaw::Hertz {
                stiffness: FIG_3_3_STIFFNESS,
                exponent: FIG_3_3_EXPONENT,
            },
            ContactLawKind::HuntCrossley => ContactLaw::HuntCrossley {
                stiffness: FIG_3_3_STIFFNESS,
                exponent: FIG_3_3_EXPONENT,
                lambda_s_m: FIG_3_3_LAMBDA_S_M,
            },
            ContactLawKind::LankaraniNikravesh => ContactLaw::LankaraniNikravesh {
                stiffness: FIG_3_3_STIFFNESS,
                exponent: FIG_3_3_EXPONENT,
                restitution: 0.317,
            },
        }
    }

    /// Which law this is.
    pub const fn kind(&self) -> ContactLawKind {
        match self {
            ContactLaw::Hertz { .. } => ContactLawKind::Hertz,
            ContactLaw::SpringDashpot { .. } => ContactLawKind::SpringDashpot,
            ContactLaw::HuntCrossley { .. } => ContactLawKind::HuntCrossley,
            ContactLaw::LankaraniNikravesh { .. } => ContactLawKind::LankaraniNikravesh,
        }
    }

    /// Checks the law's parameters.
    ///
    /// # Errors
    /// A [`ParamError`] naming the field (`contact.<law>.<field>`) and its allowed range.
    pub fn validate(&self) -> Result<(), ParamError> {
        match *self {
            ContactLaw::Hertz {
                stiffness,
                exponent,
            } => {
                check_range("contact.hertz.stiffness", stiffness, 1.0, 1e15)?;
                check_range("contact.hertz.exponent", exponent, 1.0, 3.0)?;
            }
            ContactLaw::SpringDashpot {
                stiffness_n_m,
                damping_n_s_m,
            } => {
                check_range(
                    "contact.spring-dashpot.stiffness_n_m",
                    stiffness_n_m,
                    1.0,
                    1e12,
                )?;
                check_range(
                    "contact.spring-dashpot.damping_n_s_m",
                    damping_n_s_m,
                    0.0,
                    1e8,
                )?;
            }
            ContactLaw::HuntCrossley {
                stiffness,
                exponent,
                lambda_s_m,
            } => {
                check_range("contact.hunt-crossley.stiffness", stiffness, 1.0, 1e15)?;
                check_range("contact.hunt-crossley.exponent", exponent, 1.0, 3.0)?;
                check_range("contact.hunt-crossley.lambda_s_m", lambda_s_m, 0.0, 1e3)?;
            }
            ContactLaw::LankaraniNikravesh {
                stiffness,
                exponent,
                restitution,
            } => {
                check_range(
                    "contact.lankarani-nikravesh.stiffness",
                    stiffness,
                    1.0,
                    1e15,
                )?;
                check_range("contact.lankarani-nikravesh.exponent", exponent, 1.0, 3.0)?;
                check_range(
                    "contact.lankarani-nikravesh.restitution",
                    restitution,
                    0.01,
                    1.0,
                )?;
            }
        }
        Ok(())
    }

    /// Estimated contact angular frequency `ω_c` (rad/s) of a mass `m` striking at
    /// `impact_speed` (m/s): `sqrt(k/m)` for the linear law; for the power laws the tangent
    /// stiffness `n k δ_m^(n−1)` at the Hertzian maximum penetration
    /// `δ_m = ((n+1) m v² / 2k)^(1/(n+1))`. Sets the integrator's contact sub-step.
    pub fn contact_omega(&self, mass_kg: f64, impact_speed: f64) -> f64 {
        let (k, n) = match *self {
            ContactLaw::SpringDashpot { stiffness_n_m, .. } => {
                return libm::sqrt(stiffness_n_m / mass_kg);
            }
            ContactLaw::Hertz {
                stiffness,
                exponent,
            }
            | ContactLaw::HuntCrossley {
                stiffness,
                exponent,
                ..
            }
            | ContactLaw::LankaraniNikravesh {
                stiffness,
                exponent,
                ..
            } => (stiffness, exponent),
        };
        let dm = libm::pow(
            (n + 1.0) * mass_kg * impact_speed * impact_speed / (2.0 * k),
            1.0 / (n + 1.0),
        );
        libm::sqrt(n * k * libm::pow(dm, n - 1.0) / mass_kg)
    }

    /// The law in the float type `T`, ready for the integrator, for a hammer of `mass_kg` (kg,
    /// > 0: Lankarani–Nikravesh's floor on the approach speed, [`PowerDissipation`]).
    pub fn compile<T: Real>(&self, mass_kg: f64) -> LawCoeffs<T> {
        let c = T::from_f64;
        match *self {
            ContactLaw::Hertz {
                stiffness,
                exponent,
            } => LawCoeffs::Power {
                k: c(stiffness),
                n: c(exponent),
                dissipation: PowerDissipation::None,
            },
            ContactLaw::SpringDashpot {
                stiffness_n_m,
                damping_n_s_m,
            } => LawCoeffs::Linear {
                k: c(stiffness_n_m),
                c: c(damping_n_s_m),
            },
            ContactLaw::HuntCrossley {
                stiffness,
                exponent,
                lambda_s_m,
            } => LawCoeffs::Power {
                k: c(stiffness),
                n: c(exponent),
                dissipation: PowerDissipation::HuntCrossley {
                    lambda: c(lambda_s_m),
                },
            },
            ContactLaw::LankaraniNikravesh {
                stiffness,
                exponent,
                restitution,
            } => LawCoeffs::Power {
                k: c(stiffness),
                n: c(exponent),
                dissipation: PowerDissipation::LankaraniNikravesh {
                    coef: c(0.75 * (1.0 - restitution * restitution)),
                    reach_speed_sq: c(2.0 / ((exponent + 1.0) * mass_kg)),
                },
            },
        }
    }
}

/// RK4 steps per contact half-period `π/ω_c` of [`ContactLaw::restitution`].
const RESTITUTION_STEPS: u32 = 4000;

impl ContactLaw {
    /// Effective coefficient of restitution of one impact of a free mass `mass_kg` arriving at
    /// `impact_speed_m_s` on a rigid surface, simulated: `m δ̈ = −F(δ, δ̇)` from `δ = 0`,
    /// `δ̇ = v` (RK4, `RESTITUTION_STEPS` steps per `π/ω_c`, [`ContactLaw::contact_omega`])
    /// until the force vanishes (the switch model's `h_β = 0`, Eq. 3-20; the last step
    /// refined 64-fold and the crossing interpolated linearly); `e = −δ̇_exit / v`.
    ///
    /// It is the restitution the law gives, whatever its parameters are called: the
    /// spring–dashpot law's does not depend on `v` ([`spring_dashpot_restitution`]), nor does
    /// Lankarani–Nikravesh's (nor on `k`, `n`), but the latter equals its parameter `e` only
    /// near `e = 1` (its damping term is derived for nearly elastic impacts): `e` = 0.9 rebounds
    /// at 0.913, 0.5 at 0.725, 0.317 at 0.687, and no `e` at less than 0.663; Hunt–Crossley's
    /// falls with `v` (`≈ 1 − 2λv/3` for small `λv`); Hertz gives 1.
    ///
    /// `None` for a non-positive or non-finite mass or speed, invalid parameters, or a contact
    /// that does not end within 100 half-periods.
    pub fn restitution(&self, mass_kg: f64, impact_speed_m_s: f64) -> Option<f64> {
        let usable = mass_kg > 0.0
            && impact_speed_m_s > 0.0
            && mass_kg.is_finite()
            && impact_speed_m_s.is_finite()
            && self.validate().is_ok();
        if !usable {
            return None;
        }
        let law = self.compile::<f64>(mass_kg);
        let wc = self.contact_omega(mass_kg, impact_speed_m_s);
        if !(wc > 0.0 && wc.is_finite()) {
            return None;
        }
        let h = core::f64::consts::PI / wc / f64::from(RESTITUTION_STEPS);
        impact_restitution(&law, mass_kg, impact_speed_m_s, h, 100 * RESTITUTION_STEPS)
    }
}

/// The coefficient of restitution of one impact of a free mass `mass_kg` arriving at `v0`
/// (m/s, positive) under the compiled law `law`, in any precision: `m δ̈ = −F(δ, δ̇)` from `δ = 0`,
/// `δ̇ = v0` by RK4 in steps of `h` s (at most `max_steps`) until the force vanishes on the way
/// out (the switch model's `h_β = 0`, Eq. 3-20; the last step refined 64-fold and the crossing
/// interpolated linearly in the force); `e = −δ̇_exit / v0`. [`ContactLaw::restitution`] runs it
/// in `f64`; the board's identification in `f32` for the law it fitted.
///
/// `None` when the contact does not end within `max_steps`.
pub fn impact_restitution<T: Real>(
    law: &LawCoeffs<T>,
    mass_kg: T,
    v0: T,
    h: T,
    max_steps: u32,
) -> Option<T> {
    let zero = T::zero();
    let force = |d: T, dd: T| impact_force(law, d, dd, v0);
    let accel = |d: T, dd: T| -force(d, dd) / mass_kg;
    let rk4 = |s: (T, T), h: T| impact_rk4(&accel, s, h);
    let mut s = (zero, v0);
    for _ in 0..max_steps {
        let next = rk4(s, h);
        // The force is positive from the first instant (δ̇ = v > 0); the contact ends at
        // its first zero once the hammer moves out.
        if next.1 < zero && force(next.0, next.1) <= zero {
            let mut a = s;
            for _ in 0..64 {
                let b = rk4(a, h / T::from_f64(64.0));
                let (fa, fb) = (force(a.0, a.1), force(b.0, b.1));
                if fb <= zero {
                    let w = if fa > fb {
                        fa / (fa - fb)
                    } else {
                        T::from_f64(1.0)
                    };
                    let exit = a.1 + w * (b.1 - a.1);
                    return Some(-exit / v0);
                }
                a = b;
            }
            return Some(-next.1 / v0);
        }
        s = next;
    }
    None
}

/// Closed-form coefficient of restitution of one spring–dashpot impact of a free mass `m` on a
/// fixed stop, with the force-vanish exit (`h_β`: contact ends when `k δ + c δ̇ = 0`, while
/// `δ > 0`). Independent of the impact speed.
///
/// Derivation (underdamped, `ζ = c / (2 sqrt(k m)) < 1`, `ω_n = sqrt(k/m)`, `ω_d = ω_n sqrt(1−ζ²)`):
/// from `δ(0) = 0`, `δ̇(0) = v`: `δ = (v/ω_d) e^{−ζω_n t} sin ω_d t`,
/// `δ̇ = v e^{−ζω_n t} (cos ω_d t − (ζω_n/ω_d) sin ω_d t)`. The force
/// `F = k δ + c δ̇ = v e^{−ζω_n t} [c cos ω_d t + ((k − c ζ ω_n)/ω_d) sin ω_d t]` vanishes first at
/// `tan(ω_d t_c) = −c ω_d / (k − c ζ ω_n)`, i.e. `ω_d t_c = π − atan2(2ζ sqrt(1−ζ²), 1 − 2ζ²)`.
/// Then `e = −δ̇(t_c)/v` (which is `e^{−ζ ω_n t_c}`: a function of `ζ` alone). Returns
/// `(e, t_c)` (s), or `None` for `ζ ≥ 1` or bad input.
///
/// For Table 3.1 with `m = 0.298 kg`: `ζ = 0.469`, `t_c ≈ 0.57 ms`, `e ≈ 0.317`.
pub fn spring_dashpot_restitution(
    stiffness_n_m: f64,
    damping_n_s_m: f64,
    mass_kg: f64,
) -> Option<(f64, f64)> {
    spring_dashpot_restitution_in(stiffness_n_m, damping_n_s_m, mass_kg)
}

/// [`spring_dashpot_restitution`] in any precision (the board's identification runs it in
/// `f32`; in `f64` it is that function, bit for bit).
pub fn spring_dashpot_restitution_in<T: Real>(
    stiffness_n_m: T,
    damping_n_s_m: T,
    mass_kg: T,
) -> Option<(T, T)> {
    let (zero, one, two) = (T::zero(), T::from_f64(1.0), T::from_f64(2.0));
    if !(stiffness_n_m > zero && mass_kg > zero && damping_n_s_m >= zero) {
        return None;
    }
    let wn = (stiffness_n_m / mass_kg).sqrt();
    let zeta = damping_n_s_m / (two * (stiffness_n_m * mass_kg).sqrt());
    if !zeta.is_finite() || zeta >= one {
        return None;
    }
    let s = (one - zeta * zeta).sqrt();
    let wd = wn * s;
    let phase =
        T::from_f64(core::f64::consts::PI) - (two * zeta * s).atan2(one - two * zeta * zeta);
    let tc = phase / wd;
    let decay = (-zeta * wn * tc).exp();
    let rate = decay * (phase.cos() - zeta / s * phase.sin());
    Some((-rate, tc))
}

/// The law's force in [`impact_restitution`], one copy (called from each RK4 stage).
#[inline(never)]
fn impact_force<T: Real>(law: &LawCoeffs<T>, d: T, dd: T, v0: T) -> T {
    law.unswitched_force(d, dd, v0)
}

/// One RK4 step over `h` s of a lone impact, `δ̈ = accel(δ, δ̇)`, from `(δ, δ̇)` (m, m/s)
/// ([`impact_restitution`]).
#[inline(never)]
fn impact_rk4<T: Real>(mut accel: impl FnMut(T, T) -> T, (d, dd): (T, T), h: T) -> (T, T) {
    let (half, two, six) = (T::from_f64(0.5), T::from_f64(2.0), T::from_f64(6.0));
    let (k1x, k1v) = (dd, accel(d, dd));
    let (k2x, k2v) = (
        dd + half * h * k1v,
        accel(d + half * h * k1x, dd + half * h * k1v),
    );
    let (k3x, k3v) = (
        dd + half * h * k2v,
        accel(d + half * h * k2x, dd + half * h * k2v),
    );
    let (k4x, k4v) = (dd + h * k3v, accel(d + h * k3x, dd + h * k3v));
    (
        d + h / six * (k1x + two * k2x + two * k3x + k4x),
        dd + h / six * (k1v + two * k2v + two * k3v + k4v),
    )
}

/// How a power law dissipates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PowerDissipation<T> {
    /// Hertz: none.
    None,
    /// Hunt–Crossley: `k δ^n λ δ̇`.
    HuntCrossley {
        /// `λ_i`, s/m.
        lambda: T,
    },
    /// Lankarani–Nikravesh: `k δ^n · coef · δ̇/v`, `coef = 3(1 − e²)/4`, `v` the approach
    /// speed `δ̇⁻`, but never below the speed at which an impact reaches the current
    /// penetration, `v_δ = √(2 k δ^(n+1) / ((n + 1) m))` (its elastic energy as kinetic energy).
    ///
    /// An impact alone never reaches a penetration beyond its approach speed's, so `v = δ̇⁻`
    /// there (the law's restitution is unchanged); the floor acts where other forces hold the
    /// hammer deeper than its arrival would (resting contact after a slow arrival). There the
    /// law's damping `k δ^n coef/δ̇⁻` would grow without bound as `δ̇⁻ → 0`, and with it the
    /// contact's fastest rate: beyond any fixed step's stability (an explicit RK4 sub-step
    /// diverged to NaN). With the floor the damping rate is at most
    /// `coef √((n + 1)/(2n)) ω_c(δ)`, of the order of the contact's own frequency.
    LankaraniNikravesh {
        /// `3(1 − e²)/4`.
        coef: T,
        /// `2/((n + 1) m)`, 1/kg: `v_δ² = reach_speed_sq · k δ^n · δ`.
        reach_speed_sq: T,
    },
}

/// A contact law compiled to the float type `T`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LawCoeffs<T> {
    /// `F = k δ + c δ̇` (also evaluated for `δ ≤ 0`, as the indicator `h_β` needs).
    Linear {
        /// `k_i`, N/m.
        k: T,
        /// `c_i`, N s/m.
        c: T,
    },
    /// `F = k δ^n (1 + dissipation)`; both parts are 0 for `δ ≤ 0`.
    Power {
        /// `k_i`, N/m^n.
        k: T,
        /// `n`.
        n: T,
        /// The dissipative factor.
        dissipation: PowerDissipation<T>,
    },
}

impl<T: Real> LawCoeffs<T> {
    /// `(elastic, dissipative)` parts of the contact force, N, at penetration `delta` (m),
    /// rate `delta_dot` (m/s) and approach speed `approach_speed` (m/s, > 0; used by
    /// Lankarani–Nikravesh only). Their sum is the indicator `h_β` (Eq. 3-20).
    #[inline(always)]
    pub fn parts(&self, delta: T, delta_dot: T, approach_speed: T) -> (T, T) {
        match *self {
            LawCoeffs::Linear { k, c } => (k * delta, c * delta_dot),
            LawCoeffs::Power { k, n, dissipation } => {
                if delta <= T::zero() {
                    return (T::zero(), T::zero());
                }
                let elastic = k * delta.powf(n);
                let dissipative = match dissipation {
                    PowerDissipation::None => T::zero(),
                    PowerDissipation::HuntCrossley { lambda } => elastic * lambda * delta_dot,
                    PowerDissipation::LankaraniNikravesh {
                        coef,
                        reach_speed_sq,
                    } => {
                        // `approach_speed` itself wherever it is the larger (the same bits).
                        let v = approach_speed.max_of((reach_speed_sq * elastic * delta).sqrt());
                        elastic * coef * delta_dot / v
                    }
                };
                (elastic, dissipative)
            }
        }
    }
}

impl<T: Real> LawCoeffs<T> {
    /// The law's force formula continued past the switching surfaces (the indicator `h_β`
    /// without any switching): power laws use `sign(δ)|δ|^n` so that the force crosses 0 where
    /// contact is lost. Used only to locate the end of a contact inside a step.
    #[inline]
    pub fn unswitched_force(&self, delta: T, delta_dot: T, approach_speed: T) -> T {
        match *self {
            LawCoeffs::Linear { .. } => {
                let (e, d) = self.parts(delta, delta_dot, approach_speed);
                e + d
            }
            LawCoeffs::Power { .. } => {
                let (e, d) = self.parts(delta.abs(), delta_dot, approach_speed);
                if delta < T::zero() { -(e + d) } else { e + d }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_restitution_of_table_3_1() {
        // ζ = 0.469, contact time ≈ 0.57 ms, e ≈ 0.317 (not exp(-πζ/√(1-ζ²)) ≈ 0.19: the
        // contact ends where the force returns to zero, before the spring does).
        let (e, tc) = spring_dashpot_restitution(5.5e6, 1.2e3, 0.298).unwrap();
        assert!((e - 0.317).abs() < 0.002, "e = {e}");
        assert!((tc - 0.57e-3).abs() < 0.01e-3, "t_c = {tc}");
        // Undamped limit: a full half-oscillation, e = 1, t_c = π/ω_n.
        let (e0, tc0) = spring_dashpot_restitution(1e6, 0.0, 1.0).unwrap();
        assert!((e0 - 1.0).abs() < 1e-12);
        assert!((tc0 - core::f64::consts::PI / 1e3).abs() < 1e-12);
        assert!(spring_dashpot_restitution(1e6, 1e4, 1.0).is_none());
    }

    /// The closed form against the RK4 impact of a unit mass (an independent computation) over
    /// the underdamped range, as `e^{−ζ ω_n t_c}`, and in `f32` (the board's) against `f64`.
    /// (That the `f64` results kept their bits was checked by hand: the desktop's `identify
    /// contact --law all --json`, whose starting point they feed, byte-identical on the docs'
    /// drop before and after the function became generic.)
    #[test]
    fn restitution_in_any_precision() {
        for zeta in [0.0, 0.05, 0.2, 0.469, 0.7, 0.95] {
            let (k, c, m) = (1e6, 2.0 * zeta * 1e3, 1.0);
            let (e, tc) = spring_dashpot_restitution_in(k, c, m).unwrap();
            let law = ContactLaw::SpringDashpot {
                stiffness_n_m: k,
                damping_n_s_m: c,
            };
            let simulated = law.restitution(m, 0.1).unwrap();
            assert!(
                (e - simulated).abs() < 1e-9,
                "ζ = {zeta}: {e} vs {simulated}"
            );
            assert!((e - (-zeta * 1e3 * tc).exp()).abs() < 1e-12, "ζ = {zeta}");
            let (e32, _) = spring_dashpot_restitution_in(k as f32, c as f32, m as f32).unwrap();
            // A few ulps of the exponent's argument `ln e`, and of `e`.
            let rel = (f64::from(e32) / e - 1.0).abs() / f64::from(f32::EPSILON);
            let bound = 4.0 * (1.0 + e.ln().abs());
            assert!(rel < bound, "ζ = {zeta}: f32 {e32}, f64 {e}: {rel} ε");
        }
        assert!(spring_dashpot_restitution_in(1e6f32, 2e3, 1.0).is_none());
        assert!(spring_dashpot_restitution_in(1e6f32, -1.0, 1.0).is_none());
        assert!(spring_dashpot_restitution_in(f32::NAN, 1.0, 1.0).is_none());
    }

    #[test]
    fn laws_parse_and_validate() {
        for k in ContactLawKind::ALL {
            assert_eq!(k.name().parse::<ContactLawKind>(), Ok(k));
            let law = ContactLaw::preset(k);
            assert_eq!(law.kind(), k);
            law.validate().unwrap();
        }
        let bad = ContactLaw::HuntCrossley {
            stiffness: 1e8,
            exponent: 0.5,
            lambda_s_m: 0.6,
        };
        assert!(matches!(
            bad.validate(),
            Err(ParamError::OutOfRange {
                field: "contact.hunt-crossley.exponent",
                ..
            })
        ));
    }

    /// Every law's field names, in its validation errors, are under its name's table
    /// (`contact.NAME.FIELD`, as a config file gives them), field by field: each law with one
    /// parameter NaN at a time.
    #[test]
    fn each_laws_errors_name_its_table() {
        let nan = f64::NAN;
        for k in ContactLawKind::ALL {
            let one_nan: Vec<ContactLaw> = match ContactLaw::preset(k) {
                ContactLaw::Hertz {
                    stiffness,
                    exponent,
                } => vec![
                    ContactLaw::Hertz {
                        stiffness: nan,
                        exponent,
                    },
                    ContactLaw::Hertz {
                        stiffness,
                        exponent: nan,
                    },
                ],
                ContactLaw::SpringDashpot {
                    stiffness_n_m,
                    damping_n_s_m,
                } => vec![
                    ContactLaw::SpringDashpot {
                        stiffness_n_m: nan,
                        damping_n_s_m,
                    },
                    ContactLaw::SpringDashpot {
                        stiffness_n_m,
                        damping_n_s_m: nan,
                    },
                ],
                ContactLaw::HuntCrossley {
                    stiffness,
                    exponent,
                    lambda_s_m,
                } => vec![
                    ContactLaw::HuntCrossley {
                        stiffness: nan,
                        exponent,
                        lambda_s_m,
                    },
                    ContactLaw::HuntCrossley {
                        stiffness,
                        exponent: nan,
                        lambda_s_m,
                    },
                    ContactLaw::HuntCrossley {
                        stiffness,
                        exponent,
                        lambda_s_m: nan,
                    },
                ],
                ContactLaw::LankaraniNikravesh {
                    stiffness,
                    exponent,
                    restitution,
                } => vec![
                    ContactLaw::LankaraniNikravesh {
                        stiffness: nan,
                        exponent,
                        restitution,
                    },
                    ContactLaw::LankaraniNikravesh {
                        stiffness,
                        exponent: nan,
                        restitution,
                    },
                    ContactLaw::LankaraniNikravesh {
                        stiffness,
                        exponent,
                        restitution: nan,
                    },
                ],
            };
            let mut fields = Vec::new();
            for law in one_nan {
                match law.validate() {
                    Err(ParamError::NotFinite { field }) => fields.push(field),
                    other => panic!("{law:?}: {other:?}"),
                }
            }
            let table = format!("contact.{}.", k.name());
            for f in &fields {
                assert!(f.starts_with(&table), "{k}: {f}");
            }
            fields.dedup();
            assert!(fields.len() >= 2, "{k}: {fields:?}");
        }
        // The unknown name's error lists every law.
        let said = "x".parse::<ContactLawKind>().unwrap_err().to_string();
        for k in ContactLawKind::ALL {
            assert!(said.contains(k.name()), "{said}");
        }
    }

    #[test]
    fn power_law_parts() {
        let law = ContactLaw::preset(ContactLawKind::HuntCrossley).compile::<f64>(1.0);
        let (e, d) = law.parts(1e-5, 0.1, 0.1);
        let expect = 2.1e8 * libm::pow(1e-5, 1.6);
        assert!((e - expect).abs() < 1e-9 * expect);
        assert!((d - expect * 0.6 * 0.1).abs() < 1e-9 * expect);
        assert_eq!(law.parts(-1e-6, 0.1, 0.1), (0.0, 0.0));
    }

    #[test]
    fn simulated_restitution_of_each_law() {
        let m = 0.298;
        // Spring–dashpot: the closed form, at any speed.
        let (e, _) = spring_dashpot_restitution(5.5e6, 1.2e3, m).unwrap();
        for v in [0.01, 0.03, 0.3, 1.0] {
            let got = ContactLaw::identified().restitution(m, v).unwrap();
            assert!((got - e).abs() < 1e-9, "v = {v}: {got} vs {e}");
        }
        let overdamped = ContactLaw::SpringDashpot {
            stiffness_n_m: 1e6,
            damping_n_s_m: 2.5e3,
        };
        let e_over = overdamped.restitution(1.0, 0.1).unwrap();
        assert!(e_over > 0.0 && e_over < 0.1, "{e_over}");
        // Hertz: elastic.
        let hertz = ContactLaw::preset(ContactLawKind::Hertz);
        assert!((hertz.restitution(m, 0.05).unwrap() - 1.0).abs() < 1e-9);
        // Hunt–Crossley: 1 − 2λv/3 to second order in λv.
        let hc = ContactLaw::preset(ContactLawKind::HuntCrossley);
        for v in [0.01, 0.03, 0.1] {
            let lv = FIG_3_3_LAMBDA_S_M * v;
            let got = hc.restitution(m, v).unwrap();
            assert!(
                (got - (1.0 - 2.0 * lv / 3.0)).abs() < lv * lv,
                "v = {v}: {got}"
            );
        }
        // Lankarani–Nikravesh: its e near 1, not below; the same for every speed and exponent.
        let ln = |e, n| ContactLaw::LankaraniNikravesh {
            stiffness: 2.1e8,
            exponent: n,
            restitution: e,
        };
        let near = ln(0.99, 1.6).restitution(m, 0.03).unwrap();
        assert!((near - 0.99).abs() < 1e-3, "{near}");
        let preset = ContactLaw::preset(ContactLawKind::LankaraniNikravesh)
            .restitution(m, 0.03)
            .unwrap();
        assert!((preset - 0.687).abs() < 1e-3, "{preset}");
        let lowest = ln(0.01, 1.5).restitution(m, 0.3).unwrap();
        assert!((lowest - 0.663).abs() < 1e-3, "{lowest}");
        assert!((ln(0.317, 3.0).restitution(m, 1.0).unwrap() - preset).abs() < 1e-6);
        assert_eq!(hc.restitution(m, 0.0), None);
        assert_eq!(hc.restitution(f64::NAN, 0.1), None);
    }

    /// Lankarani–Nikravesh's floor on the approach speed (`v_δ`, the speed that reaches the
    /// penetration) never acts in an impact alone: along a whole impact (RK4 in f64, 2,000
    /// steps per `π/ω_c`), at every speed from the floor of the integrator (1e-4 m/s) to 1 m/s
    /// and every mass, `v_δ ≤ δ̇⁻` at every stage (energy: the dissipation only takes), so the
    /// force is the law's own, bit for bit.
    #[test]
    fn lankarani_nikravesh_floor_stays_below_the_approach_speed_in_an_impact() {
        for n in [1.0, 1.5, 3.0] {
            let law = ContactLaw::LankaraniNikravesh {
                stiffness: 2.1e8,
                exponent: n,
                restitution: 0.317,
            };
            for m in [0.02, 0.12, 2.0] {
                let coeffs = law.compile::<f64>(m);
                let LawCoeffs::Power {
                    dissipation: PowerDissipation::LankaraniNikravesh { reach_speed_sq, .. },
                    ..
                } = coeffs
                else {
                    panic!("not a power law");
                };
                for v0 in [1e-4, 1e-3, 0.03, 1.0] {
                    let h = core::f64::consts::PI / law.contact_omega(m, v0) / 2000.0;
                    let mut worst: f64 = 0.0;
                    let mut accel = |d: f64, dd: f64| {
                        let (elastic, dissipative) = coeffs.parts(d, dd, v0);
                        if d > 0.0 {
                            worst = worst.max(libm::sqrt(reach_speed_sq * elastic * d) / v0);
                        }
                        -(elastic + dissipative) / m
                    };
                    let mut s = (0.0, v0);
                    for _ in 0..20_000 {
                        s = impact_rk4(&mut accel, s, h);
                        if s.0 < 0.0 {
                            break;
                        }
                    }
                    assert!(s.0 < 0.0, "n {n} m {m} v0 {v0}: the impact did not end");
                    // Near 1 at the deepest point, never above: the compression dissipates.
                    assert!(
                        worst > 0.5 && worst <= 1.0,
                        "n {n} m {m} v0 {v0}: v_δ/δ̇⁻ {worst}"
                    );
                }
            }
        }
    }
}

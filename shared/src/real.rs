//! The float type the model runs in: `f32` on the MCU (and by default on the host),
//! `f64` on the host as a convergence reference.
//!
//! All transcendental functions come from `libm`, so the MCU and the host compute
//! bit-identical results for the same inputs (no dependence on the platform's libm).

use core::fmt::Debug;
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// A real scalar usable by the model: implemented for `f32` and `f64`.
pub trait Real:
    nalgebra::Scalar
    + Copy
    + Debug
    + Default
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Send
    + Sync
{
    /// Short name for reports (`"f32"` / `"f64"`).
    const NAME: &'static str;
    /// The type's machine epsilon (`f32::EPSILON`, `f64::EPSILON`), as an `f64`.
    const EPSILON: f64;
    /// Converts from `f64` (rounding to nearest for `f32`).
    fn from_f64(x: f64) -> Self;
    /// Widens to `f64` (exact).
    fn to_f64(self) -> f64;
    /// `libm` sine.
    fn sin(self) -> Self;
    /// `libm` cosine.
    fn cos(self) -> Self;
    /// `(sin x, cos x)` by the short Taylor tier of [`Real::sin_cos`], without a branch: exact
    /// to the type's precision for `|x| ≤ 1/8` only (the caller checks the range; used where
    /// several lanes are evaluated in step, `crate::integrate::lanes`). Bit for bit what
    /// [`Real::sin_cos`] returns on that range.
    fn sin_cos_small(self) -> (Self, Self);
    /// `(sin x, cos x, exact)` by [`Real::sin_cos`]'s two Taylor tiers, both evaluated and one
    /// chosen without a branch: bit for bit [`Real::sin_cos`] where `exact` (`|x| ≤ 1/2`; used
    /// where several lanes are evaluated in step, `crate::integrate::contact_lanes`).
    #[inline(always)]
    fn sin_cos_lane(self) -> (Self, Self, bool) {
        let (s, c) = self.sin_cos();
        (s, c, self.abs() <= Self::from_f64(0.5))
    }
    /// `(sin x, cos x)`: a Taylor polynomial accurate to the type's precision for
    /// `|x| ≤ 0.5` rad (the wire pendulum's angles stay below 0.1 rad), `libm` elsewhere.
    /// Only `+` and `×`, so the MCU and the host agree bit for bit.
    fn sin_cos(self) -> (Self, Self);
    /// `libm` square root.
    fn sqrt(self) -> Self;
    /// `libm` arc sine.
    fn asin(self) -> Self;
    /// `libm` exponential `e^self`.
    fn exp(self) -> Self;
    /// `libm` four-quadrant arc tangent of `self / x`.
    fn atan2(self, x: Self) -> Self;
    /// `libm` power `self^e`.
    fn powf(self, e: Self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// Whether the value is neither NaN nor infinite.
    fn is_finite(self) -> bool;

    /// Zero.
    #[inline(always)]
    fn zero() -> Self {
        Self::default()
    }
    /// `x` as this type (exact below 2^24 for `f32`).
    fn from_u32(x: u32) -> Self;
    /// The larger of two values (`self` if they compare equal or one is NaN).
    #[inline(always)]
    fn max_of(self, other: Self) -> Self {
        if other > self { other } else { self }
    }
    /// The smaller of two values.
    #[inline(always)]
    fn min_of(self, other: Self) -> Self {
        if other < self { other } else { self }
    }
    /// A root `self` of `g(t) = 0` located by iteration, with `residual = g(self)` (≈ 0) and
    /// `slope = ∂g/∂t` there: plain floats return it as it is; a [`crate::dual::Dual`] takes the
    /// implicit derivative `−(∂g/∂s)/(∂g/∂t)` (the sensitivity of a switching event's time,
    /// whatever iteration found the root).
    #[inline(always)]
    fn root_derivative(self, residual: Self, slope: Self) -> Self {
        let _ = (residual, slope);
        self
    }
}

/// Taylor coefficients `(-1)^k/(2k+1)!` of `sin x / x` and `(-1)^k/(2k)!` of `cos x` in `x²`,
/// highest order first (Horner), as many as double precision needs on `|x| ≤ 0.5`.
const SIN_TAYLOR: [f64; 8] = [
    -1.0 / 1_307_674_368_000.0,
    1.0 / 6_227_020_800.0,
    -1.0 / 39_916_800.0,
    1.0 / 362_880.0,
    -1.0 / 5_040.0,
    1.0 / 120.0,
    -1.0 / 6.0,
    1.0,
];
const COS_TAYLOR: [f64; 8] = [
    -1.0 / 87_178_291_200.0,
    1.0 / 479_001_600.0,
    -1.0 / 3_628_800.0,
    1.0 / 40_320.0,
    -1.0 / 720.0,
    1.0 / 24.0,
    -1.0 / 2.0,
    1.0,
];

/// The last `$k` coefficients of a Taylor table as a `[$t; $k]` constant.
macro_rules! tail {
    ($t:ty, $k:expr, $table:expr) => {{
        let mut out = [0.0 as $t; $k];
        let mut i = 0;
        while i < $k {
            out[i] = $table[8 - $k + i] as $t;
            i += 1;
        }
        out
    }};
}

/// Horner evaluation of `(x · S(x²), C(x²))`.
#[inline(always)]
fn horner<T: Copy + Add<Output = T> + Mul<Output = T>, const K: usize>(
    x: T,
    s_c: &[T; K],
    c_c: &[T; K],
) -> (T, T) {
    let x2 = x * x;
    let (mut s, mut c) = (s_c[0], c_c[0]);
    let mut i = 1;
    while i < K {
        s = s * x2 + s_c[i];
        c = c * x2 + c_c[i];
        i += 1;
    }
    (x * s, c)
}

macro_rules! impl_real {
    ($t:ty, $name:literal, $sin:path, $cos:path, $sqrt:path, $asin:path, $exp:path, $atan2:path, $pow:path, $fabs:path, $short:literal, $long:literal) => {
        impl Real for $t {
            const NAME: &'static str = $name;
            const EPSILON: f64 = <$t>::EPSILON as f64;
            #[inline(always)]
            fn from_f64(x: f64) -> Self {
                x as $t
            }
            #[inline(always)]
            fn from_u32(x: u32) -> Self {
                x as $t
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline(always)]
            fn sin(self) -> Self {
                $sin(self)
            }
            #[inline(always)]
            fn cos(self) -> Self {
                $cos(self)
            }
            #[inline(always)]
            fn sin_cos_small(self) -> (Self, Self) {
                // Taylor tiers truncated below half an ulp: this one for |x| ≤ 1/8 (the
                // pendulum's angles, the excitation inside a step), the long one in `sin_cos`
                // for |x| ≤ 1/2.
                const S: [$t; $short] = tail!($t, $short, SIN_TAYLOR);
                const C: [$t; $short] = tail!($t, $short, COS_TAYLOR);
                horner(self, &S, &C)
            }
            #[inline(always)]
            fn sin_cos_lane(self) -> (Self, Self, bool) {
                const S: [$t; $long] = tail!($t, $long, SIN_TAYLOR);
                const C: [$t; $long] = tail!($t, $long, COS_TAYLOR);
                let a = $fabs(self);
                let (s_short, c_short) = self.sin_cos_small();
                let (s_long, c_long) = horner(self, &S, &C);
                let short = a <= 0.125;
                (
                    if short { s_short } else { s_long },
                    if short { c_short } else { c_long },
                    a <= 0.5,
                )
            }
            #[inline(always)]
            fn sin_cos(self) -> (Self, Self) {
                let a = $fabs(self);
                if a <= 0.125 {
                    self.sin_cos_small()
                } else if a <= 0.5 {
                    const S: [$t; $long] = tail!($t, $long, SIN_TAYLOR);
                    const C: [$t; $long] = tail!($t, $long, COS_TAYLOR);
                    horner(self, &S, &C)
                } else {
                    ($sin(self), $cos(self))
                }
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                $sqrt(self)
            }
            #[inline(always)]
            fn asin(self) -> Self {
                $asin(self)
            }
            #[inline(always)]
            fn exp(self) -> Self {
                $exp(self)
            }
            #[inline(always)]
            fn atan2(self, x: Self) -> Self {
                $atan2(self, x)
            }
            #[inline(always)]
            fn powf(self, e: Self) -> Self {
                $pow(self, e)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                $fabs(self)
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
        }
    };
}

impl_real!(
    f32,
    "f32",
    libm::sinf,
    libm::cosf,
    libm::sqrtf,
    libm::asinf,
    libm::expf,
    libm::atan2f,
    libm::powf,
    libm::fabsf,
    3,
    5
);
impl_real!(
    f64,
    "f64",
    libm::sin,
    libm::cos,
    libm::sqrt,
    libm::asin,
    libm::exp,
    libm::atan2,
    libm::pow,
    libm::fabs,
    6,
    8
);

#[cfg(test)]
mod tests {
    use super::*;

    /// `x.sin_cos_lane()` is exact there and bit for bit `x.sin_cos()` (compared as widened
    /// f64 bits: exact, sign of zero included).
    fn lane_equals_sin_cos<T: Real>(x: T) {
        let (s, c, exact) = x.sin_cos_lane();
        let (s0, c0) = x.sin_cos();
        let bits = |v: T| v.to_f64().to_bits();
        assert!(exact, "{x:?}");
        assert_eq!((bits(s), bits(c)), (bits(s0), bits(c0)), "{x:?}");
    }

    #[test]
    fn lane_sin_cos_is_sin_cos_bit_for_bit_on_its_range() {
        // Both tiers and the boundary between them (1/8), up to the range's end (1/2).
        for i in -5000..=5000 {
            let x = f64::from(i) * 1e-4;
            lane_equals_sin_cos(x);
            lane_equals_sin_cos(x as f32);
        }
        for x in [0.125f32, -0.125, 0.5, -0.5] {
            lane_equals_sin_cos(x);
        }
        assert!(!Real::sin_cos_lane(0.5001f32).2 && !Real::sin_cos_lane(-0.6f64).2);
    }

    #[test]
    fn sin_cos_polynomial_matches_libm() {
        for i in -1000..=1000 {
            let x = f64::from(i) * 6e-4;
            let (s, c) = Real::sin_cos(x);
            assert!((s - libm::sin(x)).abs() <= 2.0 * f64::EPSILON, "sin {x}");
            assert!((c - libm::cos(x)).abs() <= 2.0 * f64::EPSILON, "cos {x}");
            let xf = x as f32;
            let (sf, cf) = Real::sin_cos(xf);
            assert!(
                (sf - libm::sinf(xf)).abs() <= 2.0 * f32::EPSILON,
                "sinf {xf}"
            );
            assert!(
                (cf - libm::cosf(xf)).abs() <= 2.0 * f32::EPSILON,
                "cosf {xf}"
            );
        }
        // Outside the polynomial's range: libm.
        assert_eq!(Real::sin_cos(2.0f32), (libm::sinf(2.0), libm::cosf(2.0)));
    }
}

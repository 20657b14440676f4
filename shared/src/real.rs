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
    /// Converts from `f64` (rounding to nearest for `f32`).
    fn from_f64(x: f64) -> Self;
    /// Widens to `f64` (exact).
    fn to_f64(self) -> f64;
    /// `libm` sine.
    fn sin(self) -> Self;
    /// `libm` cosine.
    fn cos(self) -> Self;
    /// `libm` square root.
    fn sqrt(self) -> Self;
    /// `libm` arc sine.
    fn asin(self) -> Self;
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
}

macro_rules! impl_real {
    ($t:ty, $name:literal, $sin:path, $cos:path, $sqrt:path, $asin:path, $pow:path, $fabs:path) => {
        impl Real for $t {
            const NAME: &'static str = $name;
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
            fn sqrt(self) -> Self {
                $sqrt(self)
            }
            #[inline(always)]
            fn asin(self) -> Self {
                $asin(self)
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
    libm::powf,
    libm::fabsf
);
impl_real!(
    f64,
    "f64",
    libm::sin,
    libm::cos,
    libm::sqrt,
    libm::asin,
    libm::pow,
    libm::fabs
);

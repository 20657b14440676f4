//! Forward-mode dual numbers: a value and its derivatives with respect to `N` seeds, carried
//! through the same code as plain floats (the simulator is generic over [`Real`]). Running the
//! simulator in `Dual<T, 2>` from a state seeded with the identity gives the state after any
//! number of steps together with its derivative with respect to the initial state: each RK4
//! step differentiated as it is computed, which is RK4 applied to the variational equations
//! `Φ' = (∂f/∂x) Φ` with the step's own stages ("internal differentiation", the exact derivative
//! of the discrete map), and every switching event's time differentiated through
//! [`Real::root_derivative`] (the saltation of the jump it causes).
//!
//! The value part is computed by exactly the operations the plain type performs, so a dual run
//! takes the same steps, sub-steps and events, bit for bit, as the plain run it differentiates.

use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use crate::real::Real;

/// A value `v` and its derivatives `d[k] = ∂v/∂s_k` with respect to `N` seeds.
#[derive(Debug, Clone, Copy)]
pub struct Dual<T, const N: usize> {
    /// The value.
    pub v: T,
    /// The derivatives.
    pub d: [T; N],
}

impl<T: Real, const N: usize> Default for Dual<T, N> {
    fn default() -> Self {
        Dual::constant(T::zero())
    }
}

impl<T: Real, const N: usize> Dual<T, N> {
    /// A constant (zero derivatives).
    #[inline(always)]
    pub fn constant(v: T) -> Self {
        Dual {
            v,
            d: [T::zero(); N],
        }
    }

    /// The seed `k`: value `v`, derivative 1 with respect to itself, 0 to the others.
    #[inline(always)]
    pub fn seed(v: T, k: usize) -> Self {
        let mut d = [T::zero(); N];
        if let Some(slot) = d.get_mut(k) {
            *slot = T::from_f64(1.0);
        }
        Dual { v, d }
    }

    /// `f(v)` with derivative `f'(v) d`.
    #[inline(always)]
    fn chain(self, value: T, slope: T) -> Self {
        let mut d = self.d;
        for x in &mut d {
            *x = slope * *x;
        }
        Dual { v: value, d }
    }
}

/// Comparisons look at the value only: a dual run branches exactly as the plain run.
impl<T: PartialEq, const N: usize> PartialEq for Dual<T, N> {
    fn eq(&self, other: &Self) -> bool {
        self.v == other.v
    }
}

impl<T: PartialOrd, const N: usize> PartialOrd for Dual<T, N> {
    fn partial_cmp(&self, other: &Self) -> Option<core::cmp::Ordering> {
        self.v.partial_cmp(&other.v)
    }
}

/// `f(a_i, b_i)` for every component of two derivative parts.
#[inline(always)]
fn zip_with<T: Copy, const N: usize>(a: [T; N], b: [T; N], f: impl Fn(T, T) -> T) -> [T; N] {
    let mut d = a;
    for (x, y) in d.iter_mut().zip(b) {
        *x = f(*x, y);
    }
    d
}

impl<T: Real, const N: usize> Add for Dual<T, N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Dual {
            v: self.v + o.v,
            d: zip_with(self.d, o.d, |x, y| x + y),
        }
    }
}

impl<T: Real, const N: usize> Sub for Dual<T, N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Dual {
            v: self.v - o.v,
            d: zip_with(self.d, o.d, |x, y| x - y),
        }
    }
}

impl<T: Real, const N: usize> Mul for Dual<T, N> {
    type Output = Self;
    #[inline(always)]
    #[allow(clippy::suspicious_arithmetic_impl)] // the product rule
    fn mul(self, o: Self) -> Self {
        Dual {
            v: self.v * o.v,
            d: zip_with(self.d, o.d, |x, y| x * o.v + self.v * y),
        }
    }
}

impl<T: Real, const N: usize> Div for Dual<T, N> {
    type Output = Self;
    #[inline(always)]
    #[allow(clippy::suspicious_arithmetic_impl)] // the quotient rule
    fn div(self, o: Self) -> Self {
        let v = self.v / o.v;
        Dual {
            v,
            d: zip_with(self.d, o.d, |x, y| (x - v * y) / o.v),
        }
    }
}

impl<T: Real, const N: usize> Neg for Dual<T, N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        let mut d = self.d;
        for x in &mut d {
            *x = -*x;
        }
        Dual { v: -self.v, d }
    }
}

macro_rules! assign_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl<T: Real, const N: usize> $tr for Dual<T, N> {
            #[inline(always)]
            fn $f(&mut self, o: Self) {
                *self = *self $op o;
            }
        }
    };
}
assign_op!(AddAssign, add_assign, +);
assign_op!(SubAssign, sub_assign, -);
assign_op!(MulAssign, mul_assign, *);
assign_op!(DivAssign, div_assign, /);

impl<T: Real, const N: usize> Real for Dual<T, N> {
    const NAME: &'static str = "dual";
    const EPSILON: f64 = T::EPSILON;

    #[inline(always)]
    fn from_f64(x: f64) -> Self {
        Dual::constant(T::from_f64(x))
    }
    #[inline(always)]
    fn from_u32(x: u32) -> Self {
        Dual::constant(T::from_u32(x))
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self.v.to_f64()
    }
    #[inline(always)]
    fn sin(self) -> Self {
        self.chain(self.v.sin(), self.v.cos())
    }
    #[inline(always)]
    fn cos(self) -> Self {
        self.chain(self.v.cos(), -self.v.sin())
    }
    #[inline(always)]
    fn sin_cos_small(self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos_small();
        (self.chain(s, c), self.chain(c, -s))
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos();
        (self.chain(s, c), self.chain(c, -s))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let r = self.v.sqrt();
        self.chain(r, T::from_f64(0.5) / r)
    }
    #[inline(always)]
    fn asin(self) -> Self {
        let one = T::from_f64(1.0);
        self.chain(self.v.asin(), one / (one - self.v * self.v).sqrt())
    }
    #[inline(always)]
    fn exp(self) -> Self {
        let r = self.v.exp();
        self.chain(r, r)
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        // d atan2(y, x) = (x dy − y dx) / (x² + y²).
        let r2 = x.v * x.v + self.v * self.v;
        let mut out = Dual::constant(self.v.atan2(x.v));
        for ((o, dy), dx) in out.d.iter_mut().zip(self.d).zip(x.d) {
            *o = (x.v * dy - self.v * dx) / r2;
        }
        out
    }
    #[inline(always)]
    fn powf(self, e: Self) -> Self {
        // d(x^e) = e x^(e−1) dx + x^e ln x de; the exponents of the contact laws are constants.
        let value = self.v.powf(e.v);
        let mut out = if self.v == T::zero() {
            Dual::constant(value)
        } else {
            self.chain(value, e.v * value / self.v)
        };
        if e.d.iter().any(|&x| x != T::zero()) && self.v > T::zero() {
            let ln = T::from_f64(libm::log(self.v.to_f64()));
            for (x, y) in out.d.iter_mut().zip(e.d) {
                *x += value * ln * y;
            }
        }
        out
    }
    #[inline(always)]
    fn abs(self) -> Self {
        if self.v < T::zero() { -self } else { self }
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        self.v.is_finite() && self.d.iter().all(|x| x.is_finite())
    }
    #[inline(always)]
    fn root_derivative(self, residual: Self, slope: Self) -> Self {
        // t* solves g(x, t*) = 0: ∂t*/∂s = −(∂g/∂s)/(∂g/∂t) at the located root, whatever the
        // iteration that found its value.
        if slope.v == T::zero() || !slope.v.is_finite() {
            return self;
        }
        // The residual's derivative holds the iterate's own through g's slope: take it out.
        let mut d = self.d;
        for (x, r) in d.iter_mut().zip(residual.d.iter()) {
            *x -= *r / slope.v;
        }
        Dual { v: self.v, d }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type D = Dual<f64, 2>;
    /// A function written twice: on duals and on plain floats.
    type Pair<'a> = (&'a dyn Fn(D) -> D, &'a dyn Fn(f64) -> f64);

    /// Central differences of `f` at `x` (step `h`).
    fn fd(f: impl Fn(f64) -> f64, x: f64, h: f64) -> f64 {
        (f(x + h) - f(x - h)) / (2.0 * h)
    }

    #[test]
    fn derivatives_match_central_differences() {
        let x = 0.37;
        let cases: [Pair; 8] = [
            (&|a: D| a * a * a - a / (a + D::from_f64(2.0)), &|a: f64| {
                a * a * a - a / (a + 2.0)
            }),
            (&|a: D| a.sin() * a.cos(), &|a: f64| a.sin() * a.cos()),
            (&|a: D| a.sin_cos().0 + a.sin_cos().1, &|a: f64| {
                a.sin() + a.cos()
            }),
            (&|a: D| a.sqrt().asin(), &|a: f64| a.sqrt().asin()),
            (&|a: D| a.powf(D::from_f64(1.6)), &|a: f64| a.powf(1.6)),
            (&|a: D| (-a * a).exp(), &|a: f64| (-a * a).exp()),
            (&|a: D| (a * a).atan2(D::from_f64(1.0) - a), &|a: f64| {
                (a * a).atan2(1.0 - a)
            }),
            (&|a: D| (-a).abs() * D::from_f64(3.0), &|a: f64| {
                a.abs() * 3.0
            }),
        ];
        for (k, (dual, plain)) in cases.iter().enumerate() {
            let r = dual(D::seed(x, 0));
            assert_eq!(r.v, plain(x), "case {k}: value");
            let slope = fd(plain, x, 1e-6);
            assert!(
                (r.d[0] - slope).abs() < 1e-8 * slope.abs().max(1.0),
                "case {k}: {} vs {slope}",
                r.d[0]
            );
            assert_eq!(r.d[1], 0.0, "case {k}: the other seed");
        }
    }

    #[test]
    fn a_located_root_gets_the_implicit_derivative() {
        // g(s, t) = t² − s: the root t* = √s has ∂t*/∂s = 1/(2√s), whatever found its value.
        let s = D::seed(2.0, 0);
        let t = D::from_f64(libm::sqrt(2.0));
        let g = t * t - s;
        let root = t.root_derivative(g, D::from_f64(2.0 * t.v));
        assert!((root.d[0] - 0.5 / libm::sqrt(2.0)).abs() < 1e-15);
        assert_eq!(root.v, t.v);
        // An iterate that carries a derivative of its own (a regula falsi's last point): the
        // result is the root's, not the iterate's.
        let mut t_iter = D::from_f64(libm::sqrt(2.0));
        t_iter.d[0] = 7.0;
        let g_iter = t_iter * t_iter - s;
        let root_iter = t_iter.root_derivative(g_iter, D::from_f64(2.0 * t_iter.v));
        assert!((root_iter.d[0] - 0.5 / libm::sqrt(2.0)).abs() < 1e-15);
        // Plain floats ignore it.
        assert_eq!(Real::root_derivative(1.5f64, 3.0, 2.0), 1.5);
    }
}

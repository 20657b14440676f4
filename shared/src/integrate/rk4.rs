//! Classical fourth-order Runge–Kutta step for `ẋ = f(x, s)` where `s = sin(Ω t)` is supplied
//! by the caller at the step's start, midpoint and end (the excitation is the only explicit
//! time dependence of the hammer models).

use nalgebra::Vector2;

use crate::real::Real;

/// One RK4 step of size `h` from `x`, given the first stage `k1 = f(x, s_start)` (the caller
/// usually has it from the previous step's end) and a field `f(x, s)`.
/// Returns `x(t + h)`.
#[inline(always)]
pub fn rk4_step<T: Real, F: FnMut(&Vector2<T>, T) -> Vector2<T>>(
    x: &Vector2<T>,
    k1: &Vector2<T>,
    h: T,
    s_mid: T,
    s_end: T,
    mut f: F,
) -> Vector2<T> {
    let half = T::from_f64(0.5);
    let sixth = T::from_f64(1.0 / 6.0);
    let two = T::from_f64(2.0);
    let hh = h * half;
    let k2 = f(&(x + k1 * hh), s_mid);
    let k3 = f(&(x + k2 * hh), s_mid);
    let k4 = f(&(x + k3 * h), s_end);
    x + (k1 + k2 * two + k3 * two + k4) * (h * sixth)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fourth_order_on_harmonic_oscillator() {
        // ẍ = −x from (1, 0): exact x(t) = cos t. Global error scales as h⁴.
        let err = |n: u32| {
            let h = 1.0 / f64::from(n);
            let mut x = Vector2::new(1.0, 0.0);
            for _ in 0..n {
                let k1 = Vector2::new(x[1], -x[0]);
                x = rk4_step(&x, &k1, h, 0.0, 0.0, |y, _| Vector2::new(y[1], -y[0]));
            }
            (x[0] - libm::cos(1.0)).abs()
        };
        let (e1, e2) = (err(10), err(20));
        let order = libm::log2(e1 / e2);
        assert!((order - 4.0).abs() < 0.1, "observed order {order}");
    }
}

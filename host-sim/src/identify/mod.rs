//! Parameter identification and comparison with measurements (thesis §3.3.2–3.3.4, §3.4.1).
//!
//! The contact law from drop tests, by concern (each module uses only those listed before it):
//! - [`data`]: the measured drop test — offset, noise, impacts, their peaks and times;
//! - [`cost`]: the simulated drop and the error a law makes on the measured ones, in the search
//!   coordinates of the fit;
//! - [`uncertainty`]: the fitted parameters' intervals and the lack-of-fit check (bootstrap);
//! - [`fit`]: Nelder–Mead on the error, several laws compared;
//! - [`synth`]: synthetic drop tests made by the plant simulation, for tests and examples.
//!
//! The suspension from a free decay: [`free`].

pub mod cost;
pub mod data;
pub mod fit;
pub mod free;
pub mod synth;
pub mod uncertainty;

use nalgebra::{DMatrix, DVector};

/// The least-squares solution of `a x ≈ b` (`a`: n × p design matrix, n ≥ p; `b`: n) by
/// Householder QR of `a` (`x = R⁻¹ Qᵀ b`, no normal equations); `None` if `a` is numerically
/// rank-deficient (a pivot of `R` within `n·ε` of the largest) or `x` is not finite.
pub(crate) fn least_squares(a: DMatrix<f64>, b: DVector<f64>) -> Option<DVector<f64>> {
    let p = a.ncols();
    if a.nrows() < p || b.len() != a.nrows() {
        return None;
    }
    let n = a.nrows() as f64;
    let qr = a.qr();
    let r = qr.r();
    let pivots = r.diagonal().map(f64::abs);
    if pivots.iter().any(|&d| d <= n * f64::EPSILON * pivots.max()) {
        return None;
    }
    let mut qtb = b;
    qr.q_tr_mul(&mut qtb);
    let x = r.solve_upper_triangular(&qtb.rows(0, p).into_owned())?;
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_squares_recovers_an_exact_fit_and_refuses_a_rank_deficient_one() {
        let xs: [f64; 5] = [-2.0, -1.0, 0.0, 1.0, 2.0];
        let a = DMatrix::from_fn(5, 3, |i, k| xs[i].powi(k as i32));
        let b = DVector::from_iterator(5, xs.iter().map(|x| 1.0 + 2.0 * x - 3.0 * x * x));
        let x = least_squares(a, b).unwrap();
        for (got, want) in x.iter().zip([1.0, 2.0, -3.0]) {
            assert!((got - want).abs() < 1e-12, "{x}");
        }
        let flat = DMatrix::from_fn(5, 2, |_, _| 1.0);
        assert!(least_squares(flat, DVector::from_element(5, 1.0)).is_none());
    }
}

//! Floquet multipliers of a periodic orbit: the eigenvalues `μ` of its monodromy matrix
//! `M = DP^q` (2 × 2: a stroboscopically sampled, non-autonomous system has no trivial
//! multiplier at 1), and the test functions whose sign changes locate the codimension-one
//! bifurcations along a branch (Kuznetsov, *Elements of Applied Bifurcation Theory*, ch. 10):
//!
//! | event | multiplier | test function | for `M` 2 × 2 |
//! |---|---|---|---|
//! | fold | a real `μ` through +1 | `det(M − I) = (1 − μ₁)(1 − μ₂)` | `det M − tr M + 1` |
//! | period doubling | a real `μ` through −1 | `det(M + I) = (1 + μ₁)(1 + μ₂)` | `det M + tr M + 1` |
//! | Neimark–Sacker | a complex pair through `|μ| = 1` | `|μ|² − 1` | `det M − 1` (complex pair) |

/// A multiplier `re + i im`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Multiplier {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
}

impl Multiplier {
    /// `|μ|`.
    pub fn abs(self) -> f64 {
        libm::hypot(self.re, self.im)
    }
}

/// The two multipliers of a 2 × 2 monodromy matrix and its test functions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Floquet {
    /// The multipliers, the larger modulus first (a complex pair: `im ≥ 0` first).
    pub mu: [Multiplier; 2],
    /// `tr M`.
    pub trace: f64,
    /// `det M` (`μ₁ μ₂`).
    pub det: f64,
}

impl Floquet {
    /// The multipliers of `m` (row-major).
    pub fn of(m: &[[f64; 2]; 2]) -> Floquet {
        let trace = m[0][0] + m[1][1];
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        let disc = trace * trace - 4.0 * det;
        let mu = if disc >= 0.0 {
            // Real: the larger root without cancellation, the other from the product.
            let r = libm::sqrt(disc);
            let big = 0.5 * (trace + if trace >= 0.0 { r } else { -r });
            let small = if big != 0.0 { det / big } else { 0.0 };
            let (a, b) = if libm::fabs(big) >= libm::fabs(small) {
                (big, small)
            } else {
                (small, big)
            };
            [Multiplier { re: a, im: 0.0 }, Multiplier { re: b, im: 0.0 }]
        } else {
            let im = 0.5 * libm::sqrt(-disc);
            [
                Multiplier {
                    re: 0.5 * trace,
                    im,
                },
                Multiplier {
                    re: 0.5 * trace,
                    im: -im,
                },
            ]
        };
        Floquet { mu, trace, det }
    }

    /// `max |μ|`.
    pub fn max_abs(&self) -> f64 {
        self.mu[0].abs().max(self.mu[1].abs())
    }

    /// Whether the orbit is stable (every `|μ| < 1`).
    pub fn stable(&self) -> bool {
        self.max_abs() < 1.0
    }

    /// The stability margin `1 − max |μ|` (negative when unstable).
    pub fn margin(&self) -> f64 {
        1.0 - self.max_abs()
    }

    /// Whether the multipliers are a complex pair.
    pub fn complex(&self) -> bool {
        self.mu[0].im != 0.0
    }

    /// Fold test function `det(M − I)`.
    pub fn fold_test(&self) -> f64 {
        self.det - self.trace + 1.0
    }

    /// Period-doubling test function `det(M + I)`.
    pub fn doubling_test(&self) -> f64 {
        self.det + self.trace + 1.0
    }

    /// Neimark–Sacker test function `det M − 1`, meaningful while the pair is complex.
    pub fn torus_test(&self) -> f64 {
        self.det - 1.0
    }

    /// A unit eigenvector of `m` for the real multiplier `mu` (`None` if `mu` is not one).
    pub fn eigenvector(m: &[[f64; 2]; 2], mu: f64) -> Option<[f64; 2]> {
        // (M − μI) v = 0: v is orthogonal to the larger row of M − μI.
        let a = [m[0][0] - mu, m[0][1]];
        let b = [m[1][0], m[1][1] - mu];
        let row = if a[0].abs() + a[1].abs() >= b[0].abs() + b[1].abs() {
            a
        } else {
            b
        };
        let v = [-row[1], row[0]];
        let n = libm::hypot(v[0], v[1]);
        (n > 0.0 && n.is_finite()).then(|| [v[0] / n, v[1] / n])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn multipliers_of_known_matrices() {
        // diag(0.5, −2): real, the larger modulus first; PD test negative (μ = −2 < −1).
        let f = Floquet::of(&[[0.5, 0.0], [0.0, -2.0]]);
        assert_eq!((f.mu[0].re, f.mu[1].re), (-2.0, 0.5));
        assert!(!f.stable() && f.doubling_test() < 0.0 && f.fold_test() > 0.0);
        // A rotation by 0.3 rad scaled by 0.9: a complex pair of modulus 0.9.
        let (c, s) = (0.9 * libm::cos(0.3), 0.9 * libm::sin(0.3));
        let f = Floquet::of(&[[c, -s], [s, c]]);
        assert!(f.complex());
        assert!((f.max_abs() - 0.9).abs() < 1e-15);
        assert!((f.torus_test() - (0.81 - 1.0)).abs() < 1e-15);
        assert!((f.margin() - 0.1).abs() < 1e-15);
        // The eigenvector of μ = 3 of [[1, 2], [0, 3]] is (1, 1)/√2.
        let v = Floquet::eigenvector(&[[1.0, 2.0], [0.0, 3.0]], 3.0).unwrap();
        assert!(
            (v[0].abs() - v[1].abs()).abs() < 1e-15
                && (v[0] * v[0] + v[1] * v[1] - 1.0).abs() < 1e-15
        );
    }
}

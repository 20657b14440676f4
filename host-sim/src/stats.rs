//! The statistics of the host's intervals: the normal quantile of a 95 % interval, and
//! Wilson's score interval of a fraction (basin fractions).

/// The normal quantile of a two-sided 95 % interval.
pub const Z95: f64 = 1.959_963_984_540_054;

/// Wilson's 95 % score interval of a fraction `k/n` (E. B. Wilson, J. Am. Stat. Assoc. 22,
/// 209, 1927): `[lo, hi]` within `[0, 1]`; `[0, 1]` when `n = 0`.
pub fn wilson(k: u64, n: u64) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let (n, p, z2) = (n as f64, k as f64 / n as f64, Z95 * Z95);
    let centre = (p + z2 / (2.0 * n)) / (1.0 + z2 / n);
    let half = Z95 / (1.0 + z2 / n) * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt();
    // Exactly 0 at k = 0 and 1 at k = n (the closed form, free of the round-off).
    let lo = if k == 0 {
        0.0
    } else {
        (centre - half).max(0.0)
    };
    let hi = if k as f64 == n {
        1.0
    } else {
        (centre + half).min(1.0)
    };
    (lo, hi)
}

/// The widest Wilson interval over all `k` at `n` samples (at `k = n/2`).
pub fn widest_interval(n: u64) -> f64 {
    let (lo, hi) = wilson(n / 2, n);
    hi - lo
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wilson_matches_the_closed_form() {
        // k = 0: [0, z²/(n + z²)].
        let (lo, hi) = wilson(0, 100);
        assert_eq!(lo, 0.0);
        assert!((hi - Z95 * Z95 / (100.0 + Z95 * Z95)).abs() < 1e-15);
        // Symmetric about 1/2 at k = n/2, the normal interval's width over sqrt(1 + z²/n).
        let (lo, hi) = wilson(5000, 10_000);
        assert!((lo + hi - 1.0).abs() < 1e-12);
        let width = 2.0 * Z95 * 0.005 / (1.0 + Z95 * Z95 / 10_000.0).sqrt();
        assert!(((hi - lo) - width).abs() < 1e-12, "{}", hi - lo);
        // k = 8 of n = 10, by hand: centre 0.71674, half-width 0.22658.
        let (lo, hi) = wilson(8, 10);
        assert!(
            (lo - 0.4902).abs() < 1e-4 && (hi - 0.9433).abs() < 1e-4,
            "{lo} {hi}"
        );
        assert!((widest_interval(10_000) - 0.0196).abs() < 1e-4);
    }
}

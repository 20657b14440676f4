//! The smallest repeating period of a sequence: the one search behind the Poincaré section's
//! steady-state test ([`super::poincare::SectionHistory::repeating_period`]), the regime
//! classification ([`super::regime::classify`]) and the controller's online regime meter
//! (`crate::control::meter`).

/// The smallest `q` in `1 ..= max_q` such that items `j` and `j + q` are the `same` for every
/// `j < span(q) − q`: the sequence repeats with period `q` over its first `span(q)` items (in
/// whatever order the caller indexes them). `span(q)` is `None` when there are not enough
/// items for `q`, which is then skipped. `None` when no `q` repeats.
#[inline]
pub fn smallest_period(
    max_q: usize,
    span: impl Fn(usize) -> Option<usize>,
    same: impl Fn(usize, usize) -> bool,
) -> Option<usize> {
    (1..=max_q).find(|&q| span(q).is_some_and(|n| (0..n.saturating_sub(q)).all(|j| same(j, j + q))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_smallest_period_over_the_span() {
        let seq = [1, 2, 1, 2, 1, 2, 1, 2];
        let all = |q: usize| (2 * q <= seq.len()).then_some(seq.len());
        assert_eq!(smallest_period(4, all, |a, b| seq[a] == seq[b]), Some(2));
        // A period longer than max_q is not found.
        assert_eq!(smallest_period(1, all, |a, b| seq[a] == seq[b]), None);
        // Over a span of 3 items, 1, 2, 1 repeats with period 2.
        let first3 = |_: usize| Some(3);
        let odd = [1, 2, 1, 3];
        assert_eq!(smallest_period(4, first3, |a, b| odd[a] == odd[b]), Some(2));
        // Not enough items for any q.
        assert_eq!(smallest_period(4, |_| None, |_, _| true), None);
    }
}

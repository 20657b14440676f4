//! The edges of the band of parameter over which a stable periodic orbit keeps its regime: from
//! the orbit, its branch is continued both ways to the first bifurcation that ends it — a loss
//! of stability (fold, period doubling, Neimark–Sacker) or a grazing (its impact count changes).
//! These are the located edges of a `1/1` band that the selection's margins are measured to.

use core::ops::ControlFlow;

use super::continuation::{BifEvent, BranchEnd, ContinuationSettings, continue_branch};
use super::shooting::Orbit;
use crate::real::Real;

/// One edge of a band.
// The event carries its orbit by value: `shared` has no allocator to box it, and an edge is
// made twice per band.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Edge<T> {
    /// The bifurcation that ends the band there.
    Event(BifEvent<T>),
    /// No bifurcation on that side: how the branch ended (the range's end, a step below the
    /// minimum, the point budget), with the last value.
    Open(BranchEnd),
}

impl<T: Real> Edge<T> {
    /// The parameter's value at the edge (gap in m).
    pub fn value(&self) -> f64 {
        match self {
            Edge::Event(e) => e.value,
            Edge::Open(
                BranchEnd::RangeEnd(v)
                | BranchEnd::Grazing(v)
                | BranchEnd::StepTooSmall(v)
                | BranchEnd::MaxPoints(v)
                | BranchEnd::Stopped(v),
            ) => *v,
        }
    }
}

/// The band of `orbit` (stable or not: the first event either way ends it) in
/// `settings.param` over `settings.range`: its lower and upper edges.
pub fn band_edges<T: Real>(orbit: &Orbit<T>, settings: &ContinuationSettings) -> [Edge<T>; 2] {
    let side = |direction: f64| {
        let mut first = None;
        let end = continue_branch(
            orbit,
            settings,
            direction,
            None,
            |_| {},
            |e| {
                first = Some(*e);
                ControlFlow::Break(())
            },
        );
        match first {
            Some(e) => Edge::Event(e),
            None => Edge::Open(end),
        }
    };
    [side(-1.0), side(1.0)]
}

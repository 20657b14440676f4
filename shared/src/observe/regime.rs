//! The impact regime `z = p/q` (Peterka): `p` impacts per `q` excitation periods on a periodic
//! steady state; `no impact`; `irregular` (no period `q ≤ 16` found in the protocol's window);
//! or `chaotic` (irregular with a positive largest Lyapunov exponent, `crate::orbit::label`).

use core::fmt;
use core::str::FromStr;

use super::period::smallest_period;
use super::poincare::StroboPoint;
use crate::real::Real;

/// An impact regime.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Regime {
    /// No impact in the observation window.
    NoImpact,
    /// `p` impacts every `q` periods (kept unreduced: `2/2` is a period-2 orbit, not `1/1`).
    Periodic {
        /// Impacts per `q` periods.
        p: u16,
        /// Period of the orbit in excitation periods.
        q: u16,
    },
    /// Impacts, but no period `q ≤ max_q`.
    Irregular,
    /// Irregular with a largest Lyapunov exponent positive beyond its uncertainty.
    Chaotic,
}

impl Regime {
    /// `z = 1/1`: one impact per excitation period, the rig's working regime.
    pub const ONE_ONE: Regime = Regime::Periodic { p: 1, q: 1 };

    /// Whether the steady state impacts.
    pub fn impacts(self) -> bool {
        self != Regime::NoImpact
    }
}

impl fmt::Display for Regime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Regime::NoImpact => f.write_str("no impact"),
            Regime::Periodic { p, q } => write!(f, "{p}/{q}"),
            Regime::Irregular => f.write_str("irregular"),
            Regime::Chaotic => f.write_str("chaotic"),
        }
    }
}

/// Error of [`Regime::from_str`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BadRegime;

impl fmt::Display for BadRegime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("regime must be `p/q` (1 ≤ q ≤ 65535), `no impact`, `irregular` or `chaotic`")
    }
}

impl FromStr for Regime {
    type Err = BadRegime;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "no impact" => Ok(Regime::NoImpact),
            "irregular" => Ok(Regime::Irregular),
            "chaotic" => Ok(Regime::Chaotic),
            other => {
                let (p, q) = other.split_once('/').ok_or(BadRegime)?;
                let p: u16 = p.trim().parse().map_err(|_| BadRegime)?;
                let q: u16 = q.trim().parse().map_err(|_| BadRegime)?;
                if q == 0 {
                    return Err(BadRegime);
                }
                Ok(Regime::Periodic { p, q })
            }
        }
    }
}

/// Classifies an observation window: `section[j]` is the Poincaré point at the end of period `j`
/// and `impacts[j]` the arrivals during period `j` (equal lengths). The regime is `p/q` for the
/// smallest `q ≤ max_q` such that both sequences repeat with period `q` over the whole window
/// (points within `tol` in the scaled distance of [`StroboPoint::distance`]), `p` the impacts of
/// one such cycle; `no impact` when the window has no arrival; `irregular` otherwise.
pub fn classify<T: Real>(
    section: &[StroboPoint<T>],
    impacts: &[u16],
    max_q: usize,
    tol: T,
    u_scale: T,
    v_scale: T,
) -> Regime {
    let n = section.len().min(impacts.len());
    if impacts[..n].iter().all(|&c| c == 0) {
        return Regime::NoImpact;
    }
    // No q beyond half the window repeats in it, nor one that a regime cannot state.
    let max_q = max_q.min(n / 2).min(usize::from(u16::MAX));
    let period = smallest_period(
        max_q,
        |q| (2 * q <= n).then_some(n),
        |a, b| {
            impacts[a] == impacts[b] && section[b].distance(&section[a], u_scale, v_scale) <= tol
        },
    );
    match period {
        Some(q) => {
            let p: u32 = impacts[n - q..n].iter().map(|&c| u32::from(c)).sum();
            Regime::Periodic {
                p: u16::try_from(p).unwrap_or(u16::MAX),
                q: u16::try_from(q).unwrap_or(u16::MAX),
            }
        }
        None => Regime::Irregular,
    }
}

impl serde::Serialize for Regime {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

impl<'de> serde::Deserialize<'de> for Regime {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct V;
        impl serde::de::Visitor<'_> for V {
            type Value = Regime;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a regime: `p/q`, `no impact` or `irregular`")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Regime, E> {
                v.parse().map_err(|_| E::custom(BadRegime))
            }
        }
        deserializer.deserialize_str(V)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_and_parse_round_trip() {
        for r in [
            Regime::NoImpact,
            Regime::Irregular,
            Regime::ONE_ONE,
            Regime::Periodic { p: 2, q: 2 },
            Regime::Periodic { p: 1, q: 3 },
        ] {
            let s = std::format!("{r}");
            assert_eq!(s.parse::<Regime>(), Ok(r));
        }
        assert!("1/0".parse::<Regime>().is_err());
        assert!("one".parse::<Regime>().is_err());
    }

    /// A `max_q` beyond what the window can show costs no more than half the window, and a
    /// period beyond what a regime can state (`q ≤ 65,535`) is `irregular`, not a wrapped `q`.
    #[test]
    fn huge_periods_neither_hang_nor_wrap() {
        let pts: std::vec::Vec<_> = (0..10)
            .map(|j| StroboPoint {
                u: j as f32,
                du: 0.0,
            })
            .collect();
        let imp = [1u16; 10];
        assert_eq!(
            classify(&pts, &imp, usize::MAX, 1e-6, 1.0, 1.0),
            Regime::Irregular
        );
        // Period 65,536 over 131,072 points: one impact per cycle.
        let n = 131_072;
        let pts: std::vec::Vec<_> = (0..n)
            .map(|j| StroboPoint {
                u: (j % 65_536) as f32,
                du: 0.0,
            })
            .collect();
        let imp: std::vec::Vec<u16> = (0..n).map(|j| u16::from(j % 65_536 == 0)).collect();
        assert_eq!(
            classify(&pts, &imp, usize::MAX, 1e-6, 1.0, 1.0),
            Regime::Irregular
        );
        assert_eq!(
            classify(&pts[..n - 2], &imp[..n - 2], usize::MAX, 1e-6, 1.0, 1.0),
            Regime::Irregular
        );
    }

    #[test]
    fn classifies_period_two_orbit_with_one_impact() {
        let pts: std::vec::Vec<_> = (0..64)
            .map(|j| StroboPoint {
                u: if j % 2 == 0 { 1.0 } else { -1.0 },
                du: 0.5,
            })
            .collect();
        let imp: std::vec::Vec<u16> = (0..64).map(|j| (j % 2) as u16).collect();
        assert_eq!(
            classify(&pts, &imp, 16, 1e-6, 1.0, 1.0),
            Regime::Periodic { p: 1, q: 2 }
        );
        let none = [0u16; 64];
        assert_eq!(classify(&pts, &none, 16, 1e-6, 1.0, 1.0), Regime::NoImpact);
        let noisy: std::vec::Vec<_> = (0..64)
            .map(|j| StroboPoint {
                u: libm::sin(f64::from(j) * 1.234),
                du: 0.0,
            })
            .collect();
        assert_eq!(
            classify(&noisy, &imp, 16, 1e-6, 1.0, 1.0),
            Regime::Irregular
        );
    }
}

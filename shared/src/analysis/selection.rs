//! Operating-frequency selection (the rig's main job).
//!
//! For a rig and gap, given the frequency response at the nominal gap and at the perturbed gaps
//! ([`perturbed_gaps`]) over the same `Ω/ω` sweep, choose the frequency that maximises `F_i/mg`
//! among the points that are robustly `z = 1/1`: every grid point within `±freq_margin_pct` of
//! the candidate frequency (widened outward to the next grid points, so the check is
//! conservative) is `1/1` at the nominal gap **and** at `gap ± gap_margin_mm`. A window that
//! leaves the sweep cannot be verified and disqualifies the point.
//!
//! Pure function of the responses: the host computes them in parallel, the MCU in sequence;
//! both call [`select`].

use core::fmt;

use heapless::Vec;
use serde::{Deserialize, Serialize};

use super::response::{ResponseSample, SimSettings, evaluate_point_on};
use super::sweep::Sweep;
use crate::error::{ParamError, check_range};
use crate::integrate::PhaseTable;
use crate::model::RigParams;
use crate::observe::Regime;
use crate::real::Real;

/// Most `1/1` bands reported.
pub const MAX_BANDS: usize = 8;

/// What the selection must guarantee.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SelectionSpec {
    /// Frequency-ratio sweep `Ω/ω` searched (default 0.5:5.0:0.01).
    pub omega_ratio: Sweep,
    /// Required robustness in frequency, ± % of the chosen frequency (default 5).
    pub freq_margin_pct: f64,
    /// Required robustness in gap, ± mm (default 0.1; the lower side is clipped at 0 mm).
    pub gap_margin_mm: f64,
    /// Place the target between grid points where `F_i/mg` peaks inside the robust points: the
    /// vertex of the parabola through the best point and its two neighbours, when both are
    /// robust (default false: the grid point; the embedded profile's coarse sweep sets it).
    #[serde(default)]
    pub refine_peak: bool,
}

impl Default for SelectionSpec {
    fn default() -> Self {
        SelectionSpec {
            omega_ratio: Sweep {
                lo: 0.5,
                hi: 5.0,
                step: 0.01,
            },
            freq_margin_pct: 5.0,
            gap_margin_mm: 0.1,
            refine_peak: false,
        }
    }
}

impl SelectionSpec {
    /// The on-target selection (with [`SimSettings::embedded`]): `Ω/ω` 1.0:3.6:0.1 (27
    /// frequencies; for all four rigs at 0 and 1 mm the target is the same as with 1.0:4.0, the
    /// `1/2` band above Ω/ω ≈ 3.4 being left to the host), ±5 % and ±0.1 mm as the default, the
    /// peak placed between grid points (`refine_peak`: a step of 0.1 is 5 % at Ω/ω = 2).
    pub fn embedded() -> Self {
        SelectionSpec {
            omega_ratio: Sweep {
                lo: 1.0,
                hi: 3.6,
                step: 0.1,
            },
            refine_peak: true,
            ..SelectionSpec::default()
        }
    }

    /// Checks the spec.
    ///
    /// # Errors
    /// [`ParamError`] naming `omega_ratio`, `freq_margin_pct` (0..=50) or `gap_margin_mm` (0..=10).
    pub fn validate(&self) -> Result<(), ParamError> {
        Sweep::new(
            "omega_ratio",
            self.omega_ratio.lo,
            self.omega_ratio.hi,
            self.omega_ratio.step,
        )?;
        check_range("freq_margin_pct", self.freq_margin_pct, 0.0, 50.0)?;
        check_range("gap_margin_mm", self.gap_margin_mm, 0.0, 10.0)?;
        Ok(())
    }
}

/// The gaps (m) besides the nominal one at which the response must also be computed:
/// `gap − margin` (clipped at 0 and dropped if it equals the nominal gap) and `gap + margin`.
pub fn perturbed_gaps(gap_m: f64, gap_margin_mm: f64) -> Vec<f64, 2> {
    let margin = gap_margin_mm * 1e-3;
    let mut out = Vec::new();
    if margin > 0.0 {
        let lo = (gap_m - margin).max(0.0);
        if lo < gap_m {
            let _ = out.push(lo);
        }
        let _ = out.push(gap_m + margin);
    }
    out
}

/// One point of the sweep (or, for a refined peak, between two of its points).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Index in the sweep (a refined peak: the grid point it was refined from).
    pub index: usize,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Excitation frequency, Hz.
    pub freq_hz: f64,
    /// Regime at the nominal gap.
    pub regime: Regime,
    /// Predicted maximum impact force, `F_i/mg` (a refined peak: the parabola's vertex value).
    pub impact_force_mg: f64,
}

/// The chosen operating point and its guarantees.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Selection {
    /// The chosen point (`z = 1/1`).
    pub best: Candidate,
    /// Edges of the `1/1` band holding it (first and last `1/1` grid points), `Ω/ω`.
    pub band_ratio: [f64; 2],
    /// The same in Hz.
    pub band_hz: [f64; 2],
    /// Distance from the chosen frequency to the nearer band edge, % of the chosen frequency.
    pub margin_freq_pct: f64,
    /// Gap robustness verified, ± mm (lower side clipped at 0).
    pub margin_gap_mm: f64,
    /// Lowest `F_i/mg` over the robustness box (±freq margin × the checked gaps).
    pub worst_impact_force_mg: f64,
    /// Grid points that passed the robustness check.
    pub robust_points: usize,
    /// Every `1/1` band at the nominal gap, `Ω/ω` edges (at most [`MAX_BANDS`]).
    pub bands_ratio: Vec<[f64; 2], MAX_BANDS>,
    /// For information: the strongest point of any other periodic impacting regime.
    pub other_best: Option<Candidate>,
}

/// Why no operating point could be chosen.
#[derive(Debug, Clone, PartialEq)]
pub enum SelectionError {
    /// A response does not have one sample per sweep point.
    LengthMismatch {
        /// Sweep points.
        expected: usize,
        /// Samples given.
        got: usize,
    },
    /// No `1/1` point at all at the nominal gap.
    NoOneToOneBand,
    /// `1/1` exists but no point is robust to the margins; the strongest `1/1` point is given.
    NoRobustPoint {
        /// Strongest `1/1` point (not robust).
        strongest: Candidate,
    },
    /// Invalid spec.
    Param(ParamError),
}

impl fmt::Display for SelectionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SelectionError::LengthMismatch { expected, got } => {
                write!(f, "response has {got} samples, the sweep has {expected}")
            }
            SelectionError::NoOneToOneBand => {
                f.write_str("no z = 1/1 point in the swept frequency range")
            }
            SelectionError::NoRobustPoint { strongest } => write!(
                f,
                "no z = 1/1 point is robust to the required margins; strongest 1/1 point: {:.3} Hz (Ω/ω = {:.3}), F_i/mg = {:.2}",
                strongest.freq_hz, strongest.omega_ratio, strongest.impact_force_mg
            ),
            SelectionError::Param(e) => write!(f, "{e}"),
        }
    }
}

impl core::error::Error for SelectionError {}

impl From<ParamError> for SelectionError {
    fn from(e: ParamError) -> Self {
        SelectionError::Param(e)
    }
}

/// Chooses the operating frequency. `nominal` is the response at the nominal gap and
/// `perturbed` the responses at [`perturbed_gaps`], all over `spec.omega_ratio`.
///
/// # Errors
/// [`SelectionError`]: mismatched lengths, no `1/1` point, or no robust `1/1` point.
pub fn select(
    params: &RigParams,
    spec: &SelectionSpec,
    nominal: &[ResponseSample],
    perturbed: &[&[ResponseSample]],
) -> Result<Selection, SelectionError> {
    spec.validate()?;
    let sweep = spec.omega_ratio;
    let n = sweep.len();
    for r in core::iter::once(nominal).chain(perturbed.iter().copied()) {
        if r.len() != n {
            return Err(SelectionError::LengthMismatch {
                expected: n,
                got: r.len(),
            });
        }
    }
    let one_one = |j: usize| nominal[j].regime == Regime::ONE_ONE;
    let robust_at =
        |j: usize| one_one(j) && perturbed.iter().all(|r| r[j].regime == Regime::ONE_ONE);
    // Point `j`'s robustness window when every point in it is `1/1` at every gap checked (the
    // window holds `j`, so `j` itself is `1/1`).
    let robust_window =
        |j: usize| robustness_window(spec, j).filter(|&(a, b)| (a..=b).all(robust_at));
    let candidate = |j: usize| {
        let r = sweep.value(j);
        Candidate {
            index: j,
            omega_ratio: r,
            freq_hz: params.freq_hz_from_ratio(r),
            regime: nominal[j].regime,
            impact_force_mg: f64::from(nominal[j].impact_force_mg),
        }
    };

    let mut best: Option<(usize, usize, usize)> = None; // (index, box lo, box hi)
    let mut strongest: Option<usize> = None;
    let mut robust_points = 0;
    for i in (0..n).filter(|&i| one_one(i)) {
        if strongest.is_none_or(|s| nominal[i].impact_force_mg > nominal[s].impact_force_mg) {
            strongest = Some(i);
        }
        let Some((j_lo, j_hi)) = robust_window(i) else {
            continue;
        };
        robust_points += 1;
        if best.is_none_or(|(b, _, _)| nominal[i].impact_force_mg > nominal[b].impact_force_mg) {
            best = Some((i, j_lo, j_hi));
        }
    }
    let Some(strongest) = strongest else {
        return Err(SelectionError::NoOneToOneBand);
    };
    let Some((i, j_lo, j_hi)) = best else {
        return Err(SelectionError::NoRobustPoint {
            strongest: candidate(strongest),
        });
    };

    // The chosen point, between grid points where the peak is refined.
    let force = |j: usize| f64::from(nominal[j].impact_force_mg);
    let mut chosen = candidate(i);
    let (mut w_lo, mut w_hi) = (j_lo, j_hi);
    if spec.refine_peak
        && i > 0
        && i + 1 < n
        && robust_window(i - 1).is_some()
        && robust_window(i + 1).is_some()
    {
        let (fm, f0, fp) = (force(i - 1), force(i), force(i + 1));
        if let Some((offset, peak)) = parabola_vertex(fm, f0, fp) {
            chosen.omega_ratio = sweep.value(i) + offset * sweep.step;
            chosen.freq_hz = params.freq_hz_from_ratio(chosen.omega_ratio);
            chosen.impact_force_mg = peak;
            // Its window lies within the union of the two robust grid points' around it.
            if let Some(w) = ratio_window(spec, chosen.omega_ratio) {
                (w_lo, w_hi) = w;
            }
        }
    }

    // Band at the nominal gap around the chosen point.
    let mut b_lo = i;
    while b_lo > 0 && one_one(b_lo - 1) {
        b_lo -= 1;
    }
    let mut b_hi = i;
    while b_hi + 1 < n && one_one(b_hi + 1) {
        b_hi += 1;
    }
    let (r, r_lo, r_hi) = (chosen.omega_ratio, sweep.value(b_lo), sweep.value(b_hi));
    let margin_freq_pct = (r - r_lo).min(r_hi - r) / r * 100.0;

    let worst = (w_lo..=w_hi)
        .flat_map(|j| core::iter::once(nominal[j]).chain(perturbed.iter().map(move |resp| resp[j])))
        .map(|s| f64::from(s.impact_force_mg))
        .fold(f64::INFINITY, f64::min);

    let mut bands_ratio = Vec::new();
    let mut j = 0;
    while j < n {
        if one_one(j) {
            let start = j;
            while j + 1 < n && one_one(j + 1) {
                j += 1;
            }
            let _ = bands_ratio.push([sweep.value(start), sweep.value(j)]);
        }
        j += 1;
    }

    let other_best = (0..n)
        .filter(|&j| matches!(nominal[j].regime, Regime::Periodic { .. }) && !one_one(j))
        .max_by(|&a, &b| {
            nominal[a]
                .impact_force_mg
                .total_cmp(&nominal[b].impact_force_mg)
        })
        .map(candidate);

    let gaps_checked = !perturbed.is_empty();
    Ok(Selection {
        best: chosen,
        band_ratio: [r_lo, r_hi],
        band_hz: [
            params.freq_hz_from_ratio(r_lo),
            params.freq_hz_from_ratio(r_hi),
        ],
        margin_freq_pct,
        margin_gap_mm: if gaps_checked {
            spec.gap_margin_mm
        } else {
            0.0
        },
        worst_impact_force_mg: worst,
        robust_points,
        bands_ratio,
        other_best,
    })
}

/// The vertex of the parabola through `(−1, fm)`, `(0, f0)`, `(1, fp)`: its abscissa (in grid
/// steps, within ±1/2 when `f0` is the largest) and value; `None` unless the three make a
/// strict maximum at the middle point.
fn parabola_vertex(fm: f64, f0: f64, fp: f64) -> Option<(f64, f64)> {
    let curvature = fm - 2.0 * f0 + fp;
    if !(curvature < 0.0 && f0 >= fm && f0 >= fp) {
        return None;
    }
    let offset = 0.5 * (fm - fp) / curvature;
    Some((offset, f0 - 0.25 * (fm - fp) * offset))
}

/// The sweep indices `j_lo ..= j_hi` whose frequencies cover `±freq_margin_pct` around sweep
/// point `i` (widened outward to the next grid points), or `None` when that window leaves the
/// sweep (the point cannot be verified): the points [`select`] asks to be `1/1` at every gap
/// checked for `i` to be robust.
pub fn robustness_window(spec: &SelectionSpec, i: usize) -> Option<(usize, usize)> {
    ratio_window(spec, spec.omega_ratio.value(i))
}

/// [`robustness_window`] around any ratio `r` of the sweep's range.
fn ratio_window(spec: &SelectionSpec, r: f64) -> Option<(usize, usize)> {
    let sweep = spec.omega_ratio;
    let n = sweep.len();
    let p = spec.freq_margin_pct / 100.0;
    let eps = 1e-9 * sweep.step;
    let (lo, hi) = (r * (1.0 - p), r * (1.0 + p));
    if n == 0 || lo < sweep.lo - eps || hi > sweep.value(n - 1) + eps {
        return None;
    }
    let j_lo = libm::floor((lo - sweep.lo) / sweep.step + 1e-9).max(0.0) as usize;
    let j_hi = (libm::ceil((hi - sweep.lo) / sweep.step - 1e-9) as usize).min(n - 1);
    Some((j_lo, j_hi))
}

/// Largest sweep [`select_sequential`] holds (three responses of this many samples live on the stack).
pub const MAX_SEQUENTIAL_POINTS: usize = 512;

/// The whole selection computed in sequence with fixed-capacity buffers (no allocation): the
/// path the firmware runs. Gives the same result as computing the responses elsewhere (in
/// parallel on the host) and calling [`select`].
///
/// The firmware's on-target selection for the wire rig at 0.0 mm gap: 3.665 Hz (the peak
/// between the grid's 2.0 and 2.1), inside the `1/1` band of 2.1–4.7 Hz.
/// ```
/// use shared::analysis::{SelectionSpec, SimSettings, select_sequential};
/// use shared::model::RigId;
/// let p = RigId::Wires.preset();
/// let s = select_sequential::<f32>(&p, 0.0, &SelectionSpec::embedded(), &SimSettings::embedded())
///     .expect("a robust 1/1 point");
/// assert!((s.best.freq_hz - 3.6650).abs() < 1e-3);
/// assert!(s.band_hz[0] < 2.2 && s.band_hz[1] > 4.6);
/// ```
///
/// # Errors
/// [`SelectionError::Param`] for invalid input or a sweep longer than
/// [`MAX_SEQUENTIAL_POINTS`]; otherwise as [`select`].
pub fn select_sequential<T: Real>(
    params: &RigParams,
    gap_m: f64,
    spec: &SelectionSpec,
    settings: &SimSettings,
) -> Result<Selection, SelectionError> {
    spec.validate()?;
    let sweep = spec.omega_ratio;
    if sweep.len() > MAX_SEQUENTIAL_POINTS {
        return Err(ParamError::BadRange {
            field: "omega_ratio",
            reason: "too many points for the on-target selection (at most 512)",
        }
        .into());
    }
    let gaps = perturbed_gaps(gap_m, spec.gap_margin_mm);
    let phases = PhaseTable::<T>::new(settings.steps.steps_per_period)?;
    let point = |gap_m: f64, ratio: f64| {
        evaluate_point_on::<T, ()>(params, gap_m, ratio, settings, &phases, &mut ())
    };
    let mut nominal: Vec<ResponseSample, MAX_SEQUENTIAL_POINTS> = Vec::new();
    for i in 0..sweep.len() {
        let res = point(gap_m, sweep.value(i))?;
        let _ = nominal.push(ResponseSample::from(&res));
    }
    // [`select`] reads the perturbed responses only inside the robustness windows of the
    // nominal `1/1` points: compute those and leave the rest as `no impact` (never read), which
    // gives the same selection for a fraction of the work.
    let mut needed = [false; MAX_SEQUENTIAL_POINTS];
    for i in
        (0..sweep.len()).filter(|&i| nominal.get(i).is_some_and(|s| s.regime == Regime::ONE_ONE))
    {
        if let Some((j_lo, j_hi)) = robustness_window(spec, i) {
            for flag in needed.iter_mut().take(j_hi + 1).skip(j_lo) {
                *flag = true;
            }
        }
    }
    let unread = ResponseSample {
        regime: Regime::NoImpact,
        impact_force_mg: 0.0,
    };
    let mut responses: Vec<Vec<ResponseSample, MAX_SEQUENTIAL_POINTS>, 2> = Vec::new();
    for &g in &gaps {
        let mut r = Vec::new();
        for (i, &need) in needed.iter().enumerate().take(sweep.len()) {
            let sample = if need {
                ResponseSample::from(&point(g, sweep.value(i))?)
            } else {
                unread
            };
            let _ = r.push(sample);
        }
        let _ = responses.push(r);
    }
    let mut perturbed: Vec<&[ResponseSample], 2> = Vec::new();
    for r in &responses {
        let _ = perturbed.push(r.as_slice());
    }
    select(params, spec, &nominal, &perturbed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::RigId;

    fn s(regime: Regime, f: f32) -> ResponseSample {
        ResponseSample {
            regime,
            impact_force_mg: f,
        }
    }

    fn spec() -> SelectionSpec {
        SelectionSpec {
            omega_ratio: Sweep::new("omega_ratio", 1.0, 2.99, 0.01).unwrap(),
            freq_margin_pct: 5.0,
            gap_margin_mm: 0.1,
            refine_peak: false,
        }
    }

    /// The response `at(Ω/ω)` at every ratio of `sp`'s sweep.
    fn response(
        sp: &SelectionSpec,
        at: impl Fn(f64) -> ResponseSample,
    ) -> std::vec::Vec<ResponseSample> {
        (0..sp.omega_ratio.len())
            .map(|j| at(sp.omega_ratio.value(j)))
            .collect()
    }

    /// `nominal` with every point above `Ω/ω = r_max` irregular: a perturbed gap whose `1/1`
    /// band ends at `r_max`.
    fn irregular_above(
        sp: &SelectionSpec,
        nominal: &[ResponseSample],
        r_max: f64,
    ) -> std::vec::Vec<ResponseSample> {
        nominal
            .iter()
            .enumerate()
            .map(|(j, x)| {
                if sp.omega_ratio.value(j) > r_max + 1e-9 {
                    s(Regime::Irregular, 0.0)
                } else {
                    *x
                }
            })
            .collect()
    }

    #[test]
    fn picks_the_strongest_robust_point_not_the_band_edge() {
        let p = RigId::Wires.preset();
        let sp = spec();
        // 1/1 on ratios [1.20, 2.00]; force grows with frequency, 1/2 above with a larger force.
        let nominal = response(&sp, |r| {
            if (1.2 - 1e-9..=2.0 + 1e-9).contains(&r) {
                s(Regime::ONE_ONE, r as f32)
            } else if r > 2.0 {
                s(Regime::Periodic { p: 1, q: 2 }, 5.0)
            } else {
                s(Regime::NoImpact, 0.0)
            }
        });
        let sel = select(&p, &sp, &nominal, &[&nominal]).unwrap();
        // r (1 + 0.05) must stay ≤ 2.00 with the next grid point included: r ≤ 1.90.
        assert!((sel.best.omega_ratio - 1.90).abs() < 1e-9, "{:?}", sel.best);
        assert!((sel.band_ratio[0] - 1.2).abs() < 1e-9 && (sel.band_ratio[1] - 2.0).abs() < 1e-9);
        assert!(sel.margin_freq_pct >= 5.0);
        assert!((sel.worst_impact_force_mg - 1.80).abs() < 1e-6);
        assert_eq!(
            sel.other_best.unwrap().regime,
            Regime::Periodic { p: 1, q: 2 }
        );
        // A perturbed gap whose band ends at 1.7 moves the choice down to 1.61.
        let shifted = irregular_above(&sp, &nominal, 1.7);
        let sel2 = select(&p, &sp, &nominal, &[&shifted]).unwrap();
        assert!(
            (sel2.best.omega_ratio - 1.61).abs() < 1e-9,
            "{:?}",
            sel2.best
        );
    }

    /// On a coarse sweep a parabolic peak is placed where it is (the vertex of a parabola is
    /// exact for a parabola), its force the peak's; where a neighbour is not robust the grid
    /// point stays, and without `refine_peak` it always does.
    #[test]
    fn a_refined_peak_lies_between_grid_points() {
        let p = RigId::Wires.preset();
        let coarse = |refine_peak| SelectionSpec {
            omega_ratio: Sweep::new("omega_ratio", 1.0, 3.0, 0.1).unwrap(),
            refine_peak,
            ..spec()
        };
        let peak = |r: f64| 30.0 - 40.0 * (r - 2.037) * (r - 2.037);
        let sp = coarse(true);
        let nominal = response(&sp, |r| {
            if (1.3 - 1e-9..=2.8 + 1e-9).contains(&r) {
                s(Regime::ONE_ONE, peak(r) as f32)
            } else {
                s(Regime::NoImpact, 0.0)
            }
        });
        let sel = select(&p, &sp, &nominal, &[&nominal]).unwrap();
        // f32 samples: the vertex to their rounding.
        assert!(
            (sel.best.omega_ratio - 2.037).abs() < 1e-5,
            "{:?}",
            sel.best
        );
        assert!((sel.best.impact_force_mg - 30.0).abs() < 1e-5);
        assert!((sel.best.freq_hz - p.freq_hz_from_ratio(sel.best.omega_ratio)).abs() < 1e-12);
        assert_eq!(sel.best.index, 10);
        let r = sel.best.omega_ratio;
        assert!((sel.margin_freq_pct - (r - 1.3) / r * 100.0).abs() < 1e-9);
        // Its own window, 1.935 ..= 2.139, widened to the grid: the worst over 1.9 ..= 2.2.
        assert!((sel.worst_impact_force_mg - f64::from(peak(2.2) as f32)).abs() < 1e-9);
        let grid = select(&p, &coarse(false), &nominal, &[&nominal]).unwrap();
        assert!((grid.best.omega_ratio - 2.0).abs() < 1e-12);
        assert_eq!(grid.best.impact_force_mg, f64::from(peak(2.0) as f32));
        // A perturbed gap whose band ends at 2.2: 2.1 is not robust (its window reaches 2.3),
        // so 2.0 is the best robust point and stays on the grid.
        let shifted = irregular_above(&sp, &nominal, 2.2);
        let kept = select(&p, &sp, &nominal, &[&shifted]).unwrap();
        assert!(
            (kept.best.omega_ratio - 2.0).abs() < 1e-12,
            "{:?}",
            kept.best
        );
    }

    #[test]
    fn parabola_vertex_only_at_a_strict_maximum() {
        let (x, y) = parabola_vertex(1.0, 2.0, 1.5).unwrap();
        // y = 2 + 0.25 x − 0.75 x²: vertex at x = 1/6, y = 2 + 1/48.
        assert!((x - 1.0 / 6.0).abs() < 1e-15 && (y - (2.0 + 1.0 / 48.0)).abs() < 1e-15);
        assert_eq!(parabola_vertex(1.0, 1.0, 1.0), None);
        assert_eq!(parabola_vertex(1.0, 2.0, 3.0), None);
        assert_eq!(parabola_vertex(f64::NAN, 2.0, 1.0), None);
    }

    #[test]
    fn reports_when_nothing_is_robust() {
        let p = RigId::Wires.preset();
        let sp = spec();
        let narrow = response(&sp, |r| {
            if (1.5..1.55).contains(&r) {
                s(Regime::ONE_ONE, 2.0)
            } else {
                s(Regime::NoImpact, 0.0)
            }
        });
        assert!(matches!(
            select(&p, &sp, &narrow, &[]),
            Err(SelectionError::NoRobustPoint { .. })
        ));
        let none = response(&sp, |_| s(Regime::NoImpact, 0.0));
        assert_eq!(
            select(&p, &sp, &none, &[]),
            Err(SelectionError::NoOneToOneBand)
        );
        assert!(matches!(
            select(&p, &sp, &none[..3], &[]),
            Err(SelectionError::LengthMismatch { .. })
        ));
    }

    #[test]
    fn perturbed_gaps_clip_at_zero() {
        assert_eq!(perturbed_gaps(0.0, 0.1).as_slice(), &[1e-4]);
        let g = perturbed_gaps(1e-3, 0.1);
        assert!((g[0] - 0.9e-3).abs() < 1e-12 && (g[1] - 1.1e-3).abs() < 1e-12);
        assert!(perturbed_gaps(1e-3, 0.0).is_empty());
    }
}

//! The operating-frequency selection on the desktop (the main job): the responses at the
//! nominal and perturbed gaps in parallel, then `shared::analysis::select`, as a report.

use anyhow::{Result, anyhow};
use serde::{Serialize, Serializer};
use shared::analysis::{
    ResponseSample, Selection, SelectionError, perturbed_gaps, robustness_window, select,
};
use shared::model::ContactLaw;
use shared::model::rig::IMPACT_SPEEDS_M_S;
use shared::observe::{PointResult, Protocol, Regime};

use shared::Real;
use shared::orbit::{BranchEnd, ContinuationSettings, Edge, EventKind, Orbit, Param, band_edges};

use crate::config::Setup;
use crate::orbits::{self, Crossings, OrbitReport, Start};
use crate::precision::Precision;
use crate::response;

/// The JSON report.
#[derive(Debug, Serialize)]
pub struct SelectReport {
    /// Rig name.
    pub rig: String,
    /// Contact law.
    pub law: String,
    /// Float type.
    pub precision: Precision,
    /// Gap, mm.
    pub gap_mm: f64,
    /// Natural frequency `ω/2π`, Hz.
    pub natural_freq_hz: f64,
    /// Chosen excitation frequency, Hz.
    pub freq_hz: f64,
    /// Chosen `Ω/ω`.
    pub omega_ratio: f64,
    /// Regime at the chosen point (`1/1`).
    pub regime: String,
    /// Predicted max impact force, `F_i/mg`.
    pub impact_force_mg: f64,
    /// Edges of its `1/1` band as the sweep found them (its last `1/1` points), Hz; the edges
    /// located on the orbit's branch are `band_check`'s `lower` and `upper`.
    pub band_hz: [f64; 2],
    /// The same in `Ω/ω`.
    pub band_omega_ratio: [f64; 2],
    /// Distance to the nearer band edge, % of the chosen frequency: to the edges located on the
    /// orbit's branch once [`check_band`] ran (`band_check`), else to the sweep's.
    pub margin_freq_pct: f64,
    /// Frequency robustness required and verified, ± %.
    pub required_margin_freq_pct: f64,
    /// Gap robustness verified, ± mm.
    pub margin_gap_mm: f64,
    /// Gaps at which the response was checked, mm.
    pub gaps_checked_mm: Vec<f64>,
    /// Lowest `F_i/mg` over the robustness box.
    pub worst_impact_force_mg: f64,
    /// Sweep points that passed the robustness check.
    pub robust_points: usize,
    /// Every `1/1` band at the nominal gap, `Ω/ω`.
    pub bands_omega_ratio: Vec<[f64; 2]>,
    /// Strongest point of another periodic regime, for information.
    pub other_best: Option<OtherBest>,
    /// The chosen orbit and its band's edges located on its branch ([`check_band`]); absent
    /// until checked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub band_check: Option<BandCheck>,
    /// The chosen orbit's basin fraction among start-up conditions ([`check_basin`]); absent
    /// until checked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub basin_check: Option<BasinCheck>,
    /// What the answer rests on that the user should know (a contact law its identification
    /// flagged); absent when empty.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// The chosen point's periodic orbit and the edges of its `1/1` band located on its branch
/// (`shared::orbit::band_edges`), against the sweep's.
#[derive(Debug, Clone, Serialize)]
pub struct BandCheck {
    /// The orbit: multipliers, stability margin `1 − max|μ|`.
    pub orbit: OrbitReport,
    /// The lower edge.
    pub lower: EdgeReport,
    /// The upper edge.
    pub upper: EdgeReport,
    /// Distance from the chosen frequency to the nearer located edge, % (the report's
    /// `margin_freq_pct` is this one).
    pub margin_freq_pct: f64,
    /// The same to the sweep's band edges (the cross-check).
    pub sweep_margin_freq_pct: f64,
    /// The sweep's step in `Ω/ω`.
    pub sweep_step: f64,
}

/// What bounds the band on one side ([`EdgeReport::kind`]), written by its name
/// ([`EdgeKind::name`]) in the report and its JSON.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeKind {
    /// A bifurcation or a grazing located on the orbit's branch.
    Event(EventKind),
    /// None within the sweep's range: the edge is the range's end.
    Open,
    /// The continuation could not follow the branch: no edge located on this side, which keeps
    /// the sweep's edge.
    Stalled,
}

impl EdgeKind {
    /// `grazing`, `period-doubling`, `fold`, `neimark-sacker`, `open` or `stalled`.
    pub fn name(self) -> &'static str {
        match self {
            EdgeKind::Event(k) => k.name(),
            EdgeKind::Open => "open",
            EdgeKind::Stalled => "stalled",
        }
    }
}

impl std::fmt::Display for EdgeKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Serialize for EdgeKind {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

/// One located edge of the band.
#[derive(Debug, Clone, Serialize)]
pub struct EdgeReport {
    /// What bounds the band here.
    pub kind: EdgeKind,
    /// Where, `Ω/ω` (`stalled`: the sweep's last `1/1` point on that side).
    pub omega_ratio: f64,
    /// Where, Hz.
    pub freq_hz: f64,
    /// The critical multiplier `(re, im)` (a period doubling's is −1), if a bifurcation.
    pub multiplier: Option<[f64; 2]>,
    /// The sweep's edge: its last `1/1` point on that side, `Ω/ω`.
    pub sweep_omega_ratio: f64,
    /// Whether the located edge lies within one sweep step of the sweep's edge (midway between
    /// its last `1/1` point and the next).
    pub agrees: bool,
    /// If not, what the sweep shows there and why.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub disagreement: Option<String>,
    /// `stalled`: where the continuation stopped, `Ω/ω`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stalled_at: Option<f64>,
    /// A period doubling or Neimark–Sacker edge whose test function changes sign other than
    /// once among the probes along the branch ([`orbits::crossings`]): the edge lies in that
    /// span; absent where it changes sign once.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smeared: Option<Crossings>,
    /// A period doubling across a jump of the discretised map
    /// ([`shared::orbit::BifEvent::at_jump`]: the multiplier passes −1 by the jump,
    /// `multiplier` is the one located on the near side); absent otherwise.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub at_jump: bool,
    /// A grazing extrapolated past the branch's last orbit
    /// ([`shared::orbit::BifEvent::extrapolated`]): that orbit's `Ω/ω`, whose `multiplier`
    /// this is; absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub multiplier_at: Option<f64>,
}

/// The strongest non-`1/1` periodic point.
#[derive(Debug, Serialize)]
pub struct OtherBest {
    /// Its regime.
    pub regime: String,
    /// Hz.
    pub freq_hz: f64,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// `F_i/mg`.
    pub impact_force_mg: f64,
}

/// The report of selection `sel` at `gap_mm` (responses checked at `gaps_mm`).
fn report(setup: &Setup, gap_mm: f64, gaps_mm: Vec<f64>, sel: &Selection) -> SelectReport {
    SelectReport {
        rig: setup.rig.to_string(),
        law: setup.params.contact.kind().to_string(),
        precision: setup.precision,
        gap_mm,
        natural_freq_hz: setup.params.natural_freq_hz(),
        freq_hz: sel.best.freq_hz,
        omega_ratio: sel.best.omega_ratio,
        regime: sel.best.regime.to_string(),
        impact_force_mg: sel.best.impact_force_mg,
        band_hz: sel.band_hz,
        band_omega_ratio: sel.band_ratio,
        margin_freq_pct: sel.margin_freq_pct,
        required_margin_freq_pct: setup.selection.freq_margin_pct,
        margin_gap_mm: sel.margin_gap_mm,
        gaps_checked_mm: gaps_mm,
        worst_impact_force_mg: sel.worst_impact_force_mg,
        robust_points: sel.robust_points,
        bands_omega_ratio: sel.bands_ratio.iter().copied().collect(),
        other_best: sel.other_best.map(|c| OtherBest {
            regime: c.regime.to_string(),
            freq_hz: c.freq_hz,
            omega_ratio: c.omega_ratio,
            impact_force_mg: c.impact_force_mg,
        }),
        band_check: None,
        basin_check: None,
        warnings: Vec::new(),
    }
}

/// One side's edge report: `edge` located, `sweep_edge` the sweep's last `1/1` point on
/// that side, `outward` +1 (upper) or −1 (lower).
fn edge_report<T: Real>(
    setup: &Setup,
    edge: &Edge<T>,
    sweep_edge: f64,
    outward: f64,
    step: f64,
) -> EdgeReport {
    let located = edge.value();
    let smeared = match edge {
        Edge::Event(e) => orbits::crossings(e, Param::OmegaRatio).filter(Crossings::smeared),
        Edge::Open(_) => None,
    };
    let (kind, multiplier) = match edge {
        Edge::Event(e) => (
            EdgeKind::Event(e.kind),
            Some([e.critical.re, e.critical.im]),
        ),
        Edge::Open(BranchEnd::RangeEnd(_)) => (EdgeKind::Open, None),
        Edge::Open(BranchEnd::Grazing(_)) => (EdgeKind::Event(EventKind::Grazing), None),
        // Newton could not follow the branch (or the budget ran out): not an edge.
        Edge::Open(_) => (EdgeKind::Stalled, None),
    };
    if kind == EdgeKind::Stalled {
        // No edge on this side: the sweep's stands, and the report says why.
        return EdgeReport {
            kind,
            omega_ratio: sweep_edge,
            freq_hz: setup.params.freq_hz_from_ratio(sweep_edge),
            multiplier: None,
            sweep_omega_ratio: sweep_edge,
            agrees: false,
            disagreement: Some(format!(
                "the continuation could not follow the orbit's branch beyond Ω/ω {located:.5} \
                 (Newton failed at the smallest step, or the point budget ran out): no edge is \
                 located on this side, and the sweep's last 1/1 point {sweep_edge:.4} stands there"
            )),
            stalled_at: Some(located),
            smeared: None,
            at_jump: false,
            multiplier_at: None,
        };
    }
    let value = located;
    // The sweep's edge is midway between its last 1/1 point and the next: the located edge
    // agrees within one step of it.
    let beyond = (value - sweep_edge) * outward;
    let agrees = (beyond - 0.5 * step).abs() <= step;
    let disagreement = (!agrees).then(|| {
        let why = match kind {
            EdgeKind::Event(EventKind::PeriodDoubling) => {
                "near a period doubling the orbit's multiplier nears −1: its transient \
                 alternates slowly, and the protocol's window reads it as 2/2 or runs out"
            }
            EdgeKind::Event(EventKind::Grazing) => {
                "near a grazing the orbit's new impact is shallow and slow to settle"
            }
            EdgeKind::Event(EventKind::Fold) => {
                "near a fold the orbit's basin shrinks (a coexisting attractor takes the run \
                 from rest) and its multiplier nears +1 (its transient is slow)"
            }
            EdgeKind::Open => {
                "the branch goes on beyond the sweep's edge: the protocol from rest \
                 settles on another attractor there (coexistence)"
            }
            _ => "the protocol's label depends on its transient there",
        };
        format!(
            "the located {kind} at Ω/ω {value:.5} lies {:.4} {} the sweep's last 1/1 point \
             {sweep_edge:.4} (step {step}): {why}",
            beyond.abs(),
            if beyond >= 0.0 { "beyond" } else { "inside" },
        )
    });
    EdgeReport {
        kind,
        omega_ratio: value,
        freq_hz: setup.params.freq_hz_from_ratio(value),
        multiplier,
        sweep_omega_ratio: sweep_edge,
        agrees,
        disagreement,
        stalled_at: None,
        smeared,
        at_jump: matches!(edge, Edge::Event(e) if e.at_jump),
        multiplier_at: match edge {
            Edge::Event(e) if e.extrapolated => Some(e.orbit.at.omega_ratio),
            _ => None,
        },
    }
}

/// Finds the chosen point's orbit (shooting from where the protocol settles at rest), locates
/// its band's edges on its branch over the sweep's range, and measures the report's frequency
/// margin to them (the sweep's margin stays as the cross-check).
///
/// # Errors
/// No orbit at the chosen point (the reason).
pub fn check_band(setup: &Setup, rep: &mut SelectReport) -> Result<()> {
    let gap_m = setup.gap_m("--gap-mm", rep.gap_mm)?;
    let at = orbits::map_point(setup, gap_m, rep.omega_ratio);
    let sweep = setup.selection.omega_ratio;
    let range = [sweep.lo, sweep.hi];
    let check = crate::with_precision!(setup.precision, T => {
        let (_, orbit): (_, Orbit<T>) = orbits::find::<T>(&at, Start::Rest, Some(1))?;
        let edges = band_edges(&orbit, &ContinuationSettings::new::<T>(Param::OmegaRatio, range));
        let lower = edge_report(setup, &edges[0], rep.band_omega_ratio[0], -1.0, sweep.step);
        let upper = edge_report(setup, &edges[1], rep.band_omega_ratio[1], 1.0, sweep.step);
        let r = rep.omega_ratio;
        let pct = |lo: f64, hi: f64| 100.0 * ((r - lo).min(hi - r)) / r;
        BandCheck {
            orbit: orbits::report(&orbit)?,
            margin_freq_pct: pct(lower.omega_ratio, upper.omega_ratio),
            sweep_margin_freq_pct: rep.margin_freq_pct,
            lower,
            upper,
            sweep_step: sweep.step,
        }
    });
    rep.margin_freq_pct = check.margin_freq_pct;
    rep.band_check = Some(check);
    Ok(())
}

/// Whether the protocol ended `r`'s transient on its length limit while the hammer still
/// impacts: its window may label a motion that is still settling (a motion without impacts on
/// an undamped suspension never settles, whatever the transient).
fn unsettled_impacting(r: &PointResult) -> bool {
    !r.settled && r.regime != Regime::NoImpact
}

/// Warnings for the band's sides where the sweep's edge stands (no edge located on the orbit's
/// branch, or no orbit check): where the sweep's next point beyond its last `1/1` point ended
/// its transient unsettled while impacting, a longer transient may carry the band further (a
/// weakly dissipating law settles slowly: docs/accuracy.md). `nominal` is the response at the
/// nominal gap over the selection's sweep.
pub fn unsettled_beyond_edges(
    setup: &Setup,
    rep: &SelectReport,
    nominal: &[PointResult],
) -> Vec<String> {
    let sweep = setup.selection.omega_ratio;
    let stands = |side: usize| {
        rep.band_check.as_ref().is_none_or(|c| {
            let e = if side == 0 { &c.lower } else { &c.upper };
            e.stalled_at.is_some()
        })
    };
    let transient = setup.settings.protocol.max_transient_periods;
    [(0, "lower", -1i64), (1, "upper", 1)]
        .into_iter()
        .filter(|&(side, ..)| stands(side))
        .filter_map(|(side, name, outward)| {
            let edge = rep.band_omega_ratio[side];
            let i = ((edge - sweep.lo) / sweep.step).round() as i64;
            let j = usize::try_from(i + outward).ok()?;
            let r = nominal.get(j)?;
            unsettled_impacting(r).then(|| {
                format!(
                    "band edge: the sweep's point beyond its {name} 1/1 point {edge:.4}, Ω/ω \
                     {:.4}, ended its transient of {transient} periods unsettled ({}): a longer \
                     transient ([settings.protocol] max_transient_periods) may carry the band \
                     further",
                    sweep.value(j),
                    r.regime
                )
            })
        })
        .collect()
}

/// The warning for a config whose `[uncertainty]` table carries a lack-of-fit verdict
/// (`identify contact` found that the law does not fit its drop tests); `None` otherwise.
pub fn lack_of_fit_warning(setup: &Setup, config: &str) -> Option<String> {
    let l = setup.uncertainty.as_ref()?.lack_of_fit.as_ref()?;
    Some(format!(
        "{config} was flagged by identify contact ({:.1}× the noise): {}; this answer rests on \
         a law that does not fit its drop test",
        l.residual_over_noise, l.note
    ))
}

/// Why the responses of [`compute_parts`] (`responses[0]` at `gap_mm`, then the perturbed
/// gaps of [`perturbed_gaps`]) hold no robust `1/1` point, as measured, one reason a line:
/// - the `1/1` bands: none in the sweep (with its most common regimes); or the widest band's
///   half-width about its centre where no `1/1` point's margin window ([`robustness_window`])
///   lies inside its band; or the points such windows ask that a perturbed gap leaves in
///   another regime;
/// - a transient too short: where it is shorter than the canonical protocol's
///   ([`Protocol::default`]) and at least half the sweep's points ended it unsettled while
///   impacting (the window then labels a motion that may still be settling);
/// - the contact law: its effective restitution at the rigs' impact speeds
///   ([`IMPACT_SPEEDS_M_S`], one simulated impact each) against the rig's identified law
///   (Table 3.1), where it differs from that law's or is nearly elastic.
pub fn no_robust_point_diagnosis(
    setup: &Setup,
    gap_mm: f64,
    responses: &[Vec<PointResult>],
) -> Vec<String> {
    let Some(nominal) = responses.first() else {
        return Vec::new();
    };
    [
        Some(band_diagnosis(setup, gap_mm, responses)),
        transient_diagnosis(setup, nominal),
        contact_law_diagnosis(setup),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// The `1/1` bands' part of [`no_robust_point_diagnosis`] (`responses` not empty).
fn band_diagnosis(setup: &Setup, gap_mm: f64, responses: &[Vec<PointResult>]) -> String {
    let nominal = &responses[0];
    let (sweep, spec) = (setup.selection.omega_ratio, &setup.selection);
    let one_one = |r: &PointResult| r.regime == Regime::ONE_ONE;
    // The 1/1 bands as index ranges, in the sweep's order.
    let mut bands: Vec<(usize, usize)> = Vec::new();
    for (j, r) in nominal.iter().enumerate() {
        match bands.last_mut() {
            Some((_, hi)) if one_one(r) && *hi + 1 == j => *hi = j,
            _ if one_one(r) => bands.push((j, j)),
            _ => {}
        }
    }
    let half_width_pct = |&(a, b): &(usize, usize)| {
        let (lo, hi) = (sweep.value(a), sweep.value(b));
        (hi - lo) / (hi + lo) * 100.0
    };
    let widest = bands
        .iter()
        .copied()
        .max_by(|x, y| half_width_pct(x).total_cmp(&half_width_pct(y)));
    let Some(band @ (a, b)) = widest else {
        let mut counts: Vec<(String, usize)> = Vec::new();
        for r in nominal {
            let name = r.regime.to_string();
            match counts.iter_mut().find(|(n, _)| *n == name) {
                Some((_, c)) => *c += 1,
                None => counts.push((name, 1)),
            }
        }
        counts.sort_by_key(|c| core::cmp::Reverse(c.1));
        let common: Vec<String> = counts
            .iter()
            .take(4)
            .map(|(n, c)| format!("{n} at {c}"))
            .collect();
        return format!(
            "the sweep Ω/ω {}–{} (step {}) at {gap_mm} mm holds no 1/1 point; its {} points: \
             {}{}",
            sweep.lo,
            sweep.value(sweep.len().saturating_sub(1)),
            sweep.step,
            nominal.len(),
            common.join(", "),
            if counts.len() > 4 { ", …" } else { "" }
        );
    };
    let head = format!(
        "the widest 1/1 band at {gap_mm} mm, Ω/ω {:.3}–{:.3} ({} point{}), spans ±{:.1} % \
         about its centre",
        sweep.value(a),
        sweep.value(b),
        b - a + 1,
        if a == b { "" } else { "s" },
        half_width_pct(&band)
    );
    // The margin windows that lie in their band: the points robust at the nominal gap.
    let windows: Vec<(usize, usize)> = bands
        .iter()
        .flat_map(|&(a, b)| {
            (a..=b)
                .filter_map(move |i| robustness_window(spec, i).filter(|&(l, h)| a <= l && h <= b))
        })
        .collect();
    let margin = spec.freq_margin_pct;
    if windows.is_empty() {
        return format!(
            "{head}: no 1/1 point has its ±{margin} % window (the frequency margin, widened to \
             the sweep's points, step {}, and within its range) inside its band{}",
            sweep.step,
            if half_width_pct(&band) >= margin {
                ": a finer or wider --omega-ratio may find one"
            } else {
                ""
            }
        );
    }
    // Each of them has a point that a perturbed gap leaves in another regime.
    let gaps = perturbed_gaps(gap_mm * 1e-3, spec.gap_margin_mm);
    let broken: Vec<String> = responses[1..]
        .iter()
        .zip(&gaps)
        .filter_map(|(resp, g)| {
            let mut off: Vec<usize> = windows
                .iter()
                .flat_map(|&(l, h)| l..=h)
                .filter(|&j| !one_one(&resp[j]))
                .collect();
            off.sort_unstable();
            off.dedup();
            let &first = off.first()?;
            Some(format!(
                "at {} mm {} of the points asked {} not 1/1 (Ω/ω {:.3}: {})",
                g * 1e3,
                off.len(),
                if off.len() == 1 { "is" } else { "are" },
                sweep.value(first),
                resp[first].regime
            ))
        })
        .collect();
    format!(
        "{head}; {} point{} of the bands meet the frequency margin at {gap_mm} mm, but the gap \
         margin (±{} mm) breaks {}: {}",
        windows.len(),
        if windows.len() == 1 { "" } else { "s" },
        spec.gap_margin_mm,
        if windows.len() == 1 { "it" } else { "each" },
        broken.join("; ")
    )
}

/// The transient's part of [`no_robust_point_diagnosis`]: said where it is shorter than the
/// canonical protocol's and at least half of `nominal` ended it unsettled while impacting.
fn transient_diagnosis(setup: &Setup, nominal: &[PointResult]) -> Option<String> {
    let transient = setup.settings.protocol.max_transient_periods;
    let canonical = Protocol::default().max_transient_periods;
    let unsettled = nominal.iter().filter(|r| unsettled_impacting(r)).count();
    (transient < canonical && 2 * unsettled >= nominal.len()).then(|| {
        format!(
            "{unsettled} of the {} points ended their transient of {transient} periods (the \
             canonical protocol's: {canonical}) unsettled while impacting: the window labelled a \
             motion that may still be settling; a longer transient ([settings.protocol] \
             max_transient_periods) may label them",
            nominal.len()
        )
    })
}

/// The contact law's part of [`no_robust_point_diagnosis`]: its effective restitution at the
/// rigs' impact speeds against Table 3.1's identified law, and what a nearly elastic contact
/// does; `None` where it rebounds as that law does (to the three decimals said).
fn contact_law_diagnosis(setup: &Setup) -> Option<String> {
    let m = setup.params.mass_kg;
    let es = |law: &ContactLaw| -> Vec<Option<f64>> {
        IMPACT_SPEEDS_M_S
            .iter()
            .map(|&v| law.restitution(m, v))
            .collect()
    };
    let text = |v: &[Option<f64>]| {
        v.iter()
            .map(|e| e.map_or_else(|| "–".to_string(), |e| format!("{e:.3}")))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let speeds: Vec<String> = IMPACT_SPEEDS_M_S
        .iter()
        .map(|v| format!("{:.0}", 1e3 * v))
        .collect();
    let law = setup.params.contact;
    let (own, reference) = (es(&law), es(&ContactLaw::identified()));
    let lowest = own.iter().flatten().copied().fold(f64::INFINITY, f64::min);
    let elastic = lowest >= ELASTIC_RESTITUTION;
    if !elastic && text(&own) == text(&reference) {
        return None;
    }
    let mut s = format!(
        "the {} law rebounds at e = {} at the rig's impact speeds {} mm/s (one simulated \
         impact each; Table 3.1's identified law: {})",
        law.kind(),
        text(&own),
        speeds.join(", "),
        text(&reference)
    );
    if elastic {
        s.push_str(&format!(
            ": a contact this elastic leaves the hammer no steady one-impact-per-period motion \
             near the surface (on the wire rig at 0.0 mm gap a spring–dashpot law with e ≥ \
             0.96 has no robust 1/1 point, with e = 0.92 a band: docs/identification.md); check \
             the law's dissipation ({})",
            match law.kind() {
                shared::model::ContactLawKind::SpringDashpot => "c_i",
                shared::model::ContactLawKind::HuntCrossley => "λ_i",
                shared::model::ContactLawKind::LankaraniNikravesh => "e",
                shared::model::ContactLawKind::Hertz => "none: Hertz is elastic",
            }
        ));
    }
    Some(s)
}

/// A contact whose restitution is at least this at every impact speed is called nearly
/// elastic by [`no_robust_point_diagnosis`].
pub const ELASTIC_RESTITUTION: f64 = 0.95;

/// Computes the selection (responses at the nominal and perturbed gaps, in parallel).
///
/// # Errors
/// Bad input, or no robust `1/1` point.
pub fn compute(setup: &Setup, gap_mm: f64) -> Result<(SelectReport, Vec<PointResult>)> {
    compute_with(setup, gap_mm, "select")
}

/// [`compute`] with the progress bar's label (`""`: no bar, e.g. for one draw of many).
///
/// # Errors
/// As [`compute`].
pub fn compute_with(
    setup: &Setup,
    gap_mm: f64,
    what: &str,
) -> Result<(SelectReport, Vec<PointResult>)> {
    let (selection, mut responses) = compute_parts(setup, gap_mm, what)?;
    let report = selection.map_err(|e| anyhow!(selection_failure(setup, gap_mm, &e)))?;
    Ok((report, responses.swap_remove(0)))
}

/// The message of a selection that failed: the rig, the gap and the margins asked, then `e`.
pub fn selection_failure(setup: &Setup, gap_mm: f64, e: &SelectionError) -> String {
    let spec = setup.selection;
    format!(
        "{} rig at {gap_mm} mm gap (±{} % frequency, ±{} mm gap): {e}",
        setup.rig, spec.freq_margin_pct, spec.gap_margin_mm
    )
}

/// The frequency responses a selection reads, one per gap: at the nominal gap first, then at
/// the perturbed gaps of [`perturbed_gaps`].
pub type GapResponses = Vec<Vec<PointResult>>;

/// The selection's two results apart: the report, or why the responses hold no robust `1/1`
/// point ([`SelectionError`]); and the responses, which exist either way: at the nominal gap
/// first, then at the perturbed gaps of [`perturbed_gaps`] (lower, upper; the lower one left out
/// at 0.0 mm).
///
/// # Errors
/// Bad input or a failed response computation.
pub fn compute_parts(
    setup: &Setup,
    gap_mm: f64,
    what: &str,
) -> Result<(Result<SelectReport, SelectionError>, GapResponses)> {
    let gap_m = setup.gap_m("--gap-mm", gap_mm)?;
    let spec = setup.selection;
    let sweep = spec.omega_ratio;
    let mut gaps = vec![gap_m];
    gaps.extend(perturbed_gaps(gap_m, spec.gap_margin_mm));
    let responses = response::compute(setup, &gaps, &sweep, what)?;
    let samples: Vec<Vec<ResponseSample>> = responses
        .iter()
        .map(|r| r.iter().map(ResponseSample::from).collect())
        .collect();
    let perturbed: Vec<&[ResponseSample]> = samples[1..].iter().map(Vec::as_slice).collect();
    let gaps_mm = gaps.iter().map(|g| g * 1e3).collect();
    let report = select(&setup.params, &spec, &samples[0], &perturbed)
        .map(|sel| report(setup, gap_mm, gaps_mm, &sel));
    Ok((report, responses))
}

/// Default random start-up conditions of the basin check.
pub const BASIN_SAMPLES: u32 = 1000;

/// Default transient limit of the basin check, excitation periods: the beam rigs' lightly
/// damped non-impacting orbits take up to about a thousand periods to settle (a lighter damping
/// raises it: [`crate::attractors::transient_periods`]).
pub const BASIN_MAX_PERIODS: u32 = 2000;

/// Default basin-fraction threshold below which the chosen point is flagged.
pub const BASIN_THRESHOLD: f64 = 0.5;

/// How likely the chosen `1/1` orbit is from a realistic start ([`check_basin`]): the basin
/// fractions of the attractors at the chosen point for random initial conditions in the start-up
/// box (relative to the cart, at phase 0 of the excitation): `u0 ∈ [−max(gap, A0), gap]`
/// (from the hammer pulled back by the cart's amplitude up to the surface) and
/// `u̇0 ∈ [−A0 Ω, A0 Ω]` (up to the cart's velocity amplitude), and from rest.
#[derive(Debug, Clone, Serialize)]
pub struct BasinCheck {
    /// The box's `u0`, mm.
    pub u0_mm: [f64; 2],
    /// The box's `u̇0`, mm/s.
    pub v0_mm_s: [f64; 2],
    /// Random initial conditions drawn in the box.
    pub samples: u32,
    /// Their seed.
    pub seed: u64,
    /// Transient limit per initial condition, excitation periods (a trajectory that has not
    /// recurred by then counts as no attractor).
    pub max_transient_periods: u32,
    /// The attractor reached from rest (the sweep's start): its label (`1/1 A`).
    pub from_rest: String,
    /// Id of the chosen `1/1` orbit among the attractors (`None`: not found from the box).
    pub chosen: Option<String>,
    /// Its basin fraction in the box.
    pub fraction: f64,
    /// Wilson 95 % interval of the fraction.
    pub ci95: [f64; 2],
    /// The largest competing attractor (by fraction), if any.
    pub competitor: Option<BasinShare>,
    /// Every attractor found, and the initial conditions without one (id `-`).
    pub attractors: Vec<BasinShare>,
    /// Threshold on the fraction.
    pub threshold: f64,
    /// The fraction lies below the threshold.
    pub flagged: bool,
}

/// One attractor's share of the start-up box.
#[derive(Debug, Clone, Serialize)]
pub struct BasinShare {
    /// Id (`A`, `B`, …; `-` for the initial conditions without an attractor).
    pub id: String,
    /// Regime `p/q`, `no impact`, `chaotic`… (`-` without an attractor).
    pub regime: String,
    /// Peak `F_i/mg` on it.
    pub impact_force_mg: f64,
    /// Basin fraction.
    pub fraction: f64,
    /// Wilson 95 % interval.
    pub ci95: [f64; 2],
}

/// Measures the basin fraction of the chosen `1/1` orbit in the start-up box ([`BasinCheck`]):
/// `samples` random initial conditions (seed `seed`) and rest, attractors found by recurrence
/// on the stroboscopic map (`crate::attractors`) within the setup's transient limit. The chosen
/// orbit is the `1/1` attractor reached from rest (the sweep's start), else the `1/1` attractor
/// whose `F_i/mg` is nearest the report's. Flags a fraction below `threshold`.
///
/// # Errors
/// `samples` outside `1 ..= 10⁶`, `threshold` outside `[0, 1]`, a failing initial condition, or
/// Ctrl-C.
pub fn check_basin(
    setup: &Setup,
    rep: &SelectReport,
    samples: u32,
    seed: u64,
    threshold: f64,
) -> Result<BasinCheck> {
    use crate::grid::basins::{Attractors, Grouping};
    use crate::grid::fractions::{FractionsGrid, Parameter, StartBox};
    use shared::observe::RecurrenceSettings;

    if !(1..=1_000_000).contains(&samples) {
        return Err(anyhow!(
            "--basin-samples {samples}: out of range: allowed 1 ..= 1000000"
        ));
    }
    if !(0.0..=1.0).contains(&threshold) {
        return Err(anyhow!(
            "--basin-threshold {threshold}: out of range: allowed 0 ..= 1"
        ));
    }
    let attractor_tol = crate::attractors::ATTRACTOR_TOL;
    let grid = FractionsGrid {
        points: vec![(rep.gap_mm, rep.omega_ratio)],
        parameter: Parameter::OmegaRatio,
        start: StartBox::Startup,
        seed,
        samples,
        width: None,
        attractor_tol,
        match_tol: crate::attractors::MATCH_TOL,
        recurrence: RecurrenceSettings::default(),
    };
    let catalogues = grid.catalogues(setup);
    let scales = Attractors::scales(&setup.params, rep.omega_ratio);
    // Rest first: its attractor is catalogued before the box's trajectories run.
    let rest = Attractors {
        setup,
        gap_mm: rep.gap_mm,
        omega_ratio: rep.omega_ratio,
        recurrence: grid.recurrence,
        catalogue: &catalogues[0],
    }
    .rows(&[(u64::from(samples), 0.0, 0.0)])
    .pop()
    .ok_or_else(|| anyhow!("internal: no row from rest"))??;
    let mut grouping = Grouping::new(scales, attractor_tol);
    crate::grid::run_chunked(
        0..samples as usize,
        samples as usize,
        "",
        |b| grid.rows(setup, &catalogues, b),
        |_, [row]| {
            grouping.add(&row);
            Ok(())
        },
    )?;
    let (list, ids) = grouping.attractors();
    let rest_id = grouping.id(&rest, &ids);
    let rest_attractor = rest_id.map(|k| &list[k as usize]);
    let from_rest = match rest_attractor {
        Some(a) => a.label.clone(),
        // Rest reaches an attractor none of the box's trajectories reached.
        None if rest.recurrence.attracted() => {
            format!("{} (not reached from the box)", rest.regime)
        }
        None => "no attractor".into(),
    };
    let one_one = |a: &&crate::grid::basins::Attractor| {
        a.recurrent && a.regime == shared::observe::Regime::ONE_ONE
    };
    let chosen = rest_attractor.filter(one_one).or_else(|| {
        list.iter().filter(one_one).min_by(|a, b| {
            (a.impact_force_mg - rep.impact_force_mg)
                .abs()
                .total_cmp(&(b.impact_force_mg - rep.impact_force_mg).abs())
        })
    });
    let share = |a: &crate::grid::basins::Attractor| BasinShare {
        id: a.id.clone(),
        regime: a.regime_text(),
        impact_force_mg: a.impact_force_mg,
        fraction: a.fraction,
        ci95: [a.ci95.0, a.ci95.1],
    };
    let (fraction, ci95) = match chosen {
        Some(a) => (a.fraction, [a.ci95.0, a.ci95.1]),
        None => {
            let (lo, hi) = crate::stats::wilson(0, u64::from(samples));
            (0.0, [lo, hi])
        }
    };
    let competitor = list
        .iter()
        .filter(|a| a.recurrent && chosen.is_none_or(|c| c.id != a.id))
        .max_by(|a, b| a.cells.cmp(&b.cells))
        .map(share);
    let ((u_lo, u_hi), (v_lo, v_hi)) =
        grid.start
            .bounds(&setup.params, rep.gap_mm, rep.omega_ratio);
    Ok(BasinCheck {
        u0_mm: [u_lo, u_hi],
        v0_mm_s: [v_lo, v_hi],
        samples,
        seed,
        max_transient_periods: setup.settings.protocol.max_transient_periods,
        from_rest,
        chosen: chosen.map(|a| a.id.clone()),
        fraction,
        ci95,
        competitor,
        attractors: list.iter().map(share).collect(),
        threshold,
        flagged: fraction < threshold,
    })
}

//! The branch figure of `continue`: branches of periodic orbits over a parameter (stable solid,
//! neutral dotted, unstable dashed, coloured by regime), their located bifurcations marked,
//! over the brute-force bifurcation diagram of the same range (grey dots); Poincaré `u` on top,
//! `F_i/mg` below.

use std::path::Path;

use anyhow::Result;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use shared::observe::Regime;
use shared::orbit::{Param, Stability};

use super::{
    Backend, Chart, Frame, LEGEND_PLACES, LegendCover, canvas, least_covered, legend_size,
    line_key, panel, regime_classes, regime_color, series_legend,
};
use crate::orbits::{BranchOut, OrbitReport, param_value};

const TOP: Frame = Frame::new(10, 40, 70, 15).desc_font(17);
const BOTTOM: Frame = Frame::new(10, 45, 70, 15).desc_font(17);

/// Dots of a brute-force diagram behind the branches.
#[derive(Debug, Clone)]
pub struct Dots {
    /// Legend label.
    pub label: String,
    /// Colour.
    pub color: RGBColor,
    /// Poincaré points `(parameter, u mm)`.
    pub strobes: Vec<(f64, f64)>,
    /// Impact peaks `(parameter, F_i/mg)`.
    pub impacts: Vec<(f64, f64)>,
}

fn regime_of(o: &OrbitReport) -> Regime {
    o.regime()
}

/// A marker of a bifurcation type: its shape drawn at a pixel, and its legend label.
fn event_mark(kind: &str) -> (&'static str, RGBColor) {
    match kind {
        "fold" => ("fold (μ = +1)", RGBColor(0, 0, 0)),
        "period-doubling" => ("period doubling (μ = −1)", RGBColor(120, 0, 160)),
        "neimark-sacker" => ("Neimark–Sacker (|μ| = 1)", RGBColor(0, 110, 0)),
        _ => ("grazing (impact appears/vanishes)", RGBColor(0, 90, 200)),
    }
}

/// Draws the marker of a bifurcation type at `at` on `chart`.
fn marker(chart: &mut Chart<'_, '_>, kind: &str, at: (f64, f64), color: RGBColor) -> Result<()> {
    let style = ShapeStyle::from(color).stroke_width(2);
    match kind {
        "fold" => chart.draw_series([TriangleMarker::new(at, 8, style)])?,
        "grazing" => {
            chart.draw_series([EmptyElement::at(at) + Rectangle::new([(-6, -6), (6, 6)], style)])?
        }
        "neimark-sacker" => chart.draw_series([Cross::new(at, 7, style)])?,
        _ => chart.draw_series([Circle::new(at, 7, style)])?,
    };
    Ok(())
}

/// A legend entry's key.
enum Key {
    /// A line in this style.
    Line(ShapeStyle),
    /// A dot of this colour (a brute-force sweep).
    Dot(RGBColor),
    /// Black strokes and gaps of this pattern ([`DOTS`], [`DASHES`]).
    Dash((i32, i32)),
    /// The marker of this event type, in this colour.
    Marker(String, RGBColor),
}

/// The legend's font size, px.
const LEGEND_PX: u32 = 14;

/// The width, px, of the white line under every branch.
const HALO_PX: u32 = 6;

/// The strokes and gaps, px, of a neutral branch (dotted) and an unstable one (dashed).
const DOTS: (i32, i32) = (2, 4);
const DASHES: (i32, i32) = (6, 5);

/// `line` drawn 2 px wide in `c`, in strokes and gaps of `pattern` px (`DOTS`, `DASHES`).
fn dashed(
    line: Vec<(f64, f64)>,
    (stroke, gap): (i32, i32),
    c: RGBColor,
) -> DashedLineSeries<std::vec::IntoIter<(f64, f64)>, i32> {
    DashedLineSeries::new(line, stroke, gap, c.stroke_width(2))
}

/// A legend key: 16 px of black 2 px strokes and gaps of `pattern` px.
fn dash_key(
    (stroke, gap): (i32, i32),
) -> impl Fn((i32, i32)) -> DashedPathElement<std::array::IntoIter<(i32, i32), 2>, i32> {
    move |(x, y)| DashedPathElement::new([(x, y), (x + 16, y)], stroke, gap, BLACK.stroke_width(2))
}

/// Draws the runs of `pts` (`(x, y, stability, regime)`) with equal stability and regime:
/// solid (2 px) where stable, dotted where neutral, dashed where unstable.
fn draw_runs(chart: &mut Chart<'_, '_>, pts: &[(f64, f64, Stability, Regime)]) -> Result<()> {
    let mut start = 0;
    while start + 1 < pts.len() {
        let (stability, regime) = (pts[start + 1].2, pts[start + 1].3);
        let mut end = start + 1;
        while end + 1 < pts.len() && pts[end + 1].2 == stability && pts[end + 1].3 == regime {
            end += 1;
        }
        let line: Vec<(f64, f64)> = pts[start..=end].iter().map(|p| (p.0, p.1)).collect();
        let c = regime_color(regime);
        match stability {
            Stability::Stable => chart.draw_series(LineSeries::new(line, c.stroke_width(2)))?,
            Stability::Neutral => chart.draw_series(dashed(line, DOTS, c))?,
            Stability::Unstable => chart.draw_series(dashed(line, DASHES, c))?,
        };
        start = end;
    }
    Ok(())
}

/// The figure: `branches` over `param` with `background` behind, the impact surface at
/// `surface_mm` (a line on the top panel, for `Ω/ω` branches).
///
/// # Errors
/// Drawing or file errors.
pub fn branches(
    path: &Path,
    title: &str,
    param: Param,
    x_label: &str,
    surface_mm: Option<f64>,
    branches: &[BranchOut],
    background: &[Dots],
) -> Result<()> {
    let value = |o: &OrbitReport| param_value(param, o);
    let mut xr = (f64::INFINITY, f64::NEG_INFINITY);
    let mut ur = (f64::INFINITY, f64::NEG_INFINITY);
    let mut fmax: f64 = 0.0;
    let mut grow = |x: f64, u: Option<f64>, f: Option<f64>| {
        xr = (xr.0.min(x), xr.1.max(x));
        if let Some(u) = u {
            ur = (ur.0.min(u), ur.1.max(u));
        }
        if let Some(f) = f {
            fmax = fmax.max(f);
        }
    };
    for b in branches {
        for p in &b.points {
            for s in &p.orbit.section {
                grow(value(&p.orbit), Some(s[0]), Some(p.orbit.impact_force_mg));
            }
        }
    }
    for d in background {
        for &(x, u) in &d.strobes {
            grow(x, Some(u), None);
        }
        for &(x, f) in &d.impacts {
            grow(x, None, Some(f));
        }
    }
    if let Some(s) = surface_mm {
        ur = (ur.0.min(s), ur.1.max(s));
    }
    if !xr.0.is_finite() {
        xr = (0.0, 1.0);
    }
    if !ur.0.is_finite() {
        ur = (-1.0, 1.0);
    }
    let pad = |(a, b): (f64, f64)| {
        let d = ((b - a) * 0.04).max(1e-3);
        (a - d, b + d)
    };
    let (x0, x1) = pad(xr);
    let (u0, u1) = pad(ur);
    let root = canvas(path, (1100, 950), Some((title, 20)))?;
    let (top, bottom) = root.split_vertically(470);
    let mut ct = panel(&top, TOP, x0..x1, u0..u1, (x_label, "Poincaré u (mm)"))?;
    let mut cb = panel(
        &bottom,
        BOTTOM,
        x0..x1,
        0.0..(fmax * 1.06).max(1.0),
        (x_label, "impact peak F_i/mg"),
    )?;
    let surface = surface_mm.map(|s| [(x0, s), (x1, s)]);
    if let Some(line) = surface {
        ct.draw_series(LineSeries::new(line, BLACK.mix(0.4)))?;
    }
    for d in background {
        let c = d.color;
        ct.draw_series(
            d.strobes
                .iter()
                .map(|&p| Circle::new(p, 1, c.mix(0.8).filled())),
        )?;
        cb.draw_series(
            d.impacts
                .iter()
                .map(|&p| Circle::new(p, 1, c.mix(0.8).filled())),
        )?;
    }
    // Every branch line over a white halo, all halos first, so that a branch reads over the
    // brute-force cloud and where it crosses another branch.
    let mut top_lines = Vec::new();
    let mut bottom_lines = Vec::new();
    for b in branches {
        let q = b.points.first().map_or(0, |p| p.orbit.section.len());
        for k in 0..q {
            top_lines.push(
                b.points
                    .iter()
                    .filter_map(|p| {
                        p.orbit.section.get(k).map(|s| {
                            (
                                value(&p.orbit),
                                s[0],
                                p.orbit.stability,
                                regime_of(&p.orbit),
                            )
                        })
                    })
                    .collect::<Vec<_>>(),
            );
        }
        bottom_lines.push(
            b.points
                .iter()
                .map(|p| {
                    (
                        value(&p.orbit),
                        p.orbit.impact_force_mg,
                        p.orbit.stability,
                        regime_of(&p.orbit),
                    )
                })
                .collect::<Vec<_>>(),
        );
    }
    for (chart, lines) in [(&mut ct, &top_lines), (&mut cb, &bottom_lines)] {
        for pts in lines {
            chart.draw_series(LineSeries::new(
                pts.iter().map(|p| (p.0, p.1)),
                WHITE.stroke_width(HALO_PX),
            ))?;
        }
        for pts in lines {
            draw_runs(chart, pts)?;
        }
    }
    let mut kinds: Vec<&str> = Vec::new();
    for b in branches {
        for e in &b.events {
            if !kinds.contains(&e.kind.as_str()) {
                kinds.push(&e.kind);
            }
            let (_, c) = event_mark(&e.kind);
            let x = e.value;
            for s in &e.orbit.section {
                marker(&mut ct, &e.kind, (x, s[0]), c)?;
            }
            marker(&mut cb, &e.kind, (x, e.orbit.impact_force_mg), c)?;
        }
    }
    // Legend: the surface, the brute-force sweeps, the regimes of the branches, the line
    // styles and the event types present.
    let mut legend: Vec<(String, Key)> = Vec::new();
    if let Some(s) = surface_mm {
        legend.push((
            format!("impact surface u = gap = {s} mm"),
            Key::Line(BLACK.mix(0.4).into()),
        ));
    }
    for d in background {
        legend.push((d.label.clone(), Key::Dot(d.color)));
    }
    let regimes = regime_classes(
        branches
            .iter()
            .flat_map(|b| b.points.iter().map(|p| regime_of(&p.orbit))),
    );
    for (name, c) in regimes {
        legend.push((format!("{name} branch"), Key::Line(c.stroke_width(3))));
    }
    let present = |s: Stability| {
        branches
            .iter()
            .any(|b| b.points.iter().any(|p| p.orbit.stability == s))
    };
    for (stability, label, key) in [
        (
            Stability::Stable,
            "stable orbit",
            Key::Line(BLACK.stroke_width(2)),
        ),
        (
            Stability::Neutral,
            "neutral orbit (no impact, undamped)",
            Key::Dash(DOTS),
        ),
        (Stability::Unstable, "unstable orbit", Key::Dash(DASHES)),
    ] {
        if present(stability) {
            legend.push((label.to_string(), key));
        }
    }
    for kind in kinds {
        let (label, c) = event_mark(kind);
        legend.push((label.to_string(), Key::Marker(kind.to_string(), c)));
    }
    // Where it covers the least of the data, in either panel (the top panel's
    // upper left where that covers nothing).
    let labels: Vec<String> = legend.iter().map(|(l, _)| l.clone()).collect();
    let size = legend_size(&labels, LEGEND_PX)?;
    let mut top_cover = LegendCover::new(&ct, size);
    let mut bottom_cover = LegendCover::new(&cb, size);
    if let Some(line) = surface {
        top_cover.line(line);
    }
    for d in background {
        top_cover.dots(d.strobes.iter().copied());
        bottom_cover.dots(d.impacts.iter().copied());
    }
    for pts in &top_lines {
        top_cover.line(pts.iter().map(|p| (p.0, p.1)));
    }
    for pts in &bottom_lines {
        bottom_cover.line(pts.iter().map(|p| (p.0, p.1)));
    }
    for e in branches.iter().flat_map(|b| &b.events) {
        top_cover.dots(e.orbit.section.iter().map(|s| (e.value, s[0])));
        bottom_cover.dots([(e.value, e.orbit.impact_force_mg)]);
    }
    let (panel_at, place) = least_covered(&[top_cover, bottom_cover]);
    let chart = if panel_at == 0 { &mut ct } else { &mut cb };
    for (label, key) in legend {
        let entry = chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
            .label(label);
        match key {
            Key::Line(style) => entry.legend(line_key(style)),
            Key::Dot(c) => entry.legend(move |(x, y)| Circle::new((x + 8, y), 3, c.filled())),
            Key::Dash(pattern) => entry.legend(dash_key(pattern)),
            Key::Marker(kind, c) => entry.legend(move |(x, y)| marker_px(&kind, (x + 8, y), c)),
        };
    }
    series_legend(chart, Some(LEGEND_PLACES[place].clone()), LEGEND_PX)?;
    root.present()?;
    Ok(())
}

/// [`marker`] as a legend key at pixel `at`.
fn marker_px<'b>(
    kind: &str,
    at: (i32, i32),
    color: RGBColor,
) -> DynElement<'static, Backend<'b>, (i32, i32)> {
    let style = ShapeStyle::from(color).stroke_width(2);
    match kind {
        "fold" => TriangleMarker::new(at, 6, style).into_dyn(),
        "grazing" => Rectangle::new([(at.0 - 5, at.1 - 5), (at.0 + 5, at.1 + 5)], style).into_dyn(),
        "neimark-sacker" => Cross::new(at, 5, style).into_dyn(),
        _ => Circle::new(at, 5, style).into_dyn(),
    }
}

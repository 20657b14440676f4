//! Figures of the grid commands (Peterka map, force map, basins of attraction, bifurcation
//! diagram). Maps are drawn from fixed-size rasters filled cell by cell while the CSV is read,
//! so memory does not grow with the grid; colours are fixed functions of the regime (or of the
//! sorted attractor id), so a one-run figure and a figure merged from shards are identical.

use std::path::Path;

use anyhow::{Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;
use shared::observe::Regime;

use crate::grid::basins::{Attractor, Basins, BasinsGrid, BasinsSummary, ColorBy};
use crate::grid::bifurcation::{BifRow, Bifurcation};
use crate::grid::fractions::{Fractions, FractionsGrid, FractionsSummary, Parameter};
use crate::grid::peterka::{Peterka, PeterkaRow};
use crate::grid::raster::Raster;
use crate::grid::{Figures, Finish, GridFigures};
use crate::orbits::CurveOut;
use crate::shard::{open_csv, title_prefix};

use super::{
    Backend, Chart, Frame, LEGEND_PLACES, LegendCover, SANS, canvas, least_covered, legend_size,
    level_line, line_key, panel, regime_class, regime_classes, regime_color, series_legend, tick,
};

/// Paints `raster` onto `area` (its full pixel extent, `y` up), colour by `color`, as one
/// bitmap (in an SVG, one embedded PNG image rather than an element per pixel).
fn blit<T: Copy>(
    raster: &Raster<T>,
    area: &DrawingArea<Backend<'_>, Shift>,
    color: impl Fn(T) -> RGBColor,
) -> Result<()> {
    let (pw, ph) = area.dim_in_pixel();
    let (w, h) = (pw as usize, ph as usize);
    let (rx, ry) = raster.raster_size();
    let mut rgb = Vec::with_capacity(3 * w * h);
    for py in 0..h {
        let cy = ((h - 1 - py) * ry / h).min(ry - 1);
        for px in 0..w {
            let cx = (px * rx / w).min(rx - 1);
            let RGBColor(r, g, b) = color(raster.raster_cell(cx, cy));
            rgb.extend([r, g, b]);
        }
    }
    let image = BitMapElement::with_owned_buffer((0, 0), (pw, ph), rgb)
        .ok_or_else(|| anyhow::anyhow!("a map's bitmap of {pw} × {ph} px"))?;
    area.draw(&image)?;
    Ok(())
}

/// An axis of a map: cell centres `lo + i·step`, `n` cells.
#[derive(Debug, Clone)]
pub struct MapAxis {
    /// First cell centre.
    pub lo: f64,
    /// Spacing between cell centres.
    pub step: f64,
    /// Number of cells.
    pub n: usize,
    /// Label of the axis, with its unit.
    pub label: String,
}

impl MapAxis {
    fn range(&self) -> (f64, f64) {
        let half = 0.5 * self.step;
        let hi = self.lo + (self.n.max(1) - 1) as f64 * self.step;
        (self.lo - half, hi + half)
    }
}

/// Swatch or marker in a legend panel.
#[derive(Debug, Clone)]
pub enum LegendMark {
    /// A filled square.
    Swatch(RGBColor),
    /// A filled square with a black ring: an attractor whose Poincaré point is marked.
    Dot(RGBColor),
    /// No mark: a smaller continuation line of the entry above.
    Text,
    /// A short thick line: a computed curve.
    Line(RGBColor),
}

const EMPTY: RGBColor = RGBColor(255, 255, 255);
const NOT_ONE_ONE: RGBColor = RGBColor(228, 228, 228);

/// The bifurcation diagram's panels: Poincaré `u` above, the impact peaks below.
const BIF_TOP: Frame = Frame::new(10, 40, 70, 15).desc_font(17);

const BIF_BOTTOM: Frame = Frame::new(10, 45, 70, 15).desc_font(17);

/// A map cell of a Peterka grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Cell {
    /// Not computed (cannot happen in a complete grid).
    Empty,
    /// A regime (and its `F_i/mg`).
    Regime(Regime, f32),
}

fn figure_with_panel<'a>(
    path: &'a Path,
    title: &str,
) -> Result<(
    DrawingArea<Backend<'a>, Shift>,
    DrawingArea<Backend<'a>, Shift>,
)> {
    let root = canvas(path, (1280, 860), Some((title, 20)))?;
    let (left, right) = root.split_horizontally(1030);
    Ok((left, right))
}

fn map_chart<'a, 'b>(
    area: &'a DrawingArea<Backend<'b>, Shift>,
    x: &MapAxis,
    y: &MapAxis,
) -> Result<Chart<'a, 'b>> {
    let (x0, x1) = x.range();
    let (y0, y1) = y.range();
    let mut chart = ChartBuilder::on(area)
        .margin(10)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(x.label.as_str())
        .y_desc(y.label.as_str())
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .label_style((SANS, 15))
        .axis_desc_style((SANS, 17))
        .draw()?;
    Ok(chart)
}

fn legend_panel(
    area: &DrawingArea<Backend<'_>, Shift>,
    heading: &str,
    entries: &[(String, LegendMark)],
) -> Result<()> {
    let x = 10;
    let mut y = 70;
    area.draw(&Text::new(
        heading.to_string(),
        (x, y),
        (SANS, 17).into_font(),
    ))?;
    y += 30;
    for (name, mark) in entries {
        let square = [(x, y), (x + 18, y + 18)];
        match mark {
            LegendMark::Swatch(c) => {
                area.draw(&Rectangle::new(square, c.filled()))?;
                area.draw(&Rectangle::new(square, BLACK.stroke_width(1)))?;
            }
            LegendMark::Dot(c) => {
                area.draw(&Rectangle::new(square, c.filled()))?;
                area.draw(&Circle::new((x + 9, y + 9), 5, BLACK.stroke_width(2)))?;
            }
            LegendMark::Text => {}
            LegendMark::Line(c) => {
                area.draw(&PathElement::new(
                    [(x, y + 9), (x + 18, y + 9)],
                    c.stroke_width(3),
                ))?;
            }
        }
        let (dy, size) = match mark {
            LegendMark::Text => (-4, 13),
            _ => (1, 15),
        };
        let room = area.dim_in_pixel().0.saturating_sub(x as u32 + 28 + 6);
        let (lines, size) = fit_text(area, name, size, room)?;
        for (k, line) in lines.iter().enumerate() {
            area.draw(&Text::new(
                line.clone(),
                (x + 28, y + dy + k as i32 * (size as i32 + 3)),
                (SANS, size).into_font(),
            ))?;
        }
        let extra = (lines.len() as i32 - 1) * (size as i32 + 3);
        y += extra
            + match mark {
                LegendMark::Text => 22,
                _ => 26,
            };
    }
    Ok(())
}

/// `text` set to fit `room` pixels across: at `size`, else a smaller size down to 11, else
/// broken at spaces into lines of that size (a word wider than `room` stands alone).
fn fit_text(
    area: &DrawingArea<Backend<'_>, Shift>,
    text: &str,
    size: u32,
    room: u32,
) -> Result<(Vec<String>, u32)> {
    let width = |t: &str, size: u32| -> Result<u32> {
        Ok(area
            .estimate_text_size(t, &(SANS, size).into_text_style(area))
            .map_err(|e| anyhow::anyhow!("legend text: {e}"))?
            .0)
    };
    let smallest = size.min(11);
    for s in (smallest..=size).rev() {
        if width(text, s)? <= room {
            return Ok((vec![text.to_string()], s));
        }
    }
    let mut lines: Vec<String> = Vec::new();
    for word in text.split(' ') {
        match lines.last_mut() {
            Some(line) if width(&format!("{line} {word}"), smallest)? <= room => {
                line.push(' ');
                line.push_str(word);
            }
            _ => lines.push(word.to_string()),
        }
    }
    Ok((lines, smallest))
}

/// Regime over `x × y` cells with a legend of the regimes present (thesis Fig. 3.24).
///
/// # Errors
/// Drawing or file errors.
pub fn regime_map(
    path: &Path,
    title: &str,
    x: &MapAxis,
    y: &MapAxis,
    cells: &Raster<Cell>,
    curves: &[Curve],
) -> Result<()> {
    let (left, right) = figure_with_panel(path, title)?;
    let mut chart = map_chart(&left, x, y)?;
    blit(
        cells,
        &chart.plotting_area().strip_coord_spec(),
        |c| match c {
            Cell::Empty => EMPTY,
            Cell::Regime(r, _) => regime_color(r),
        },
    )?;
    for c in curves {
        let style = curve_style(&c.kind);
        chart.draw_series(LineSeries::new(
            c.points.iter().copied(),
            WHITE.stroke_width(5),
        ))?;
        chart.draw_series(LineSeries::new(
            c.points.iter().copied(),
            style.stroke_width(3),
        ))?;
    }
    drop(chart);
    let mut classes: Vec<(usize, String, RGBColor)> = Vec::new();
    for c in cells.values() {
        if let Cell::Regime(r, _) = c {
            let (k, name) = regime_class(r);
            if !classes.iter().any(|(j, _, _)| *j == k) {
                classes.push((k, name, regime_color(r)));
            }
        }
    }
    classes.sort_by_key(|(k, _, _)| *k);
    let entries: Vec<(String, LegendMark)> = classes
        .into_iter()
        .map(|(_, n, c)| (n, LegendMark::Swatch(c)))
        .collect();
    let mut entries = entries;
    let mut kinds: Vec<&str> = Vec::new();
    for c in curves {
        if !kinds.contains(&c.kind.as_str()) {
            kinds.push(&c.kind);
            entries.push((
                format!("curve: {}", c.label),
                LegendMark::Line(curve_style(&c.kind)),
            ));
        }
    }
    legend_panel(&right, "regime", &entries)?;
    left.present()?;
    Ok(())
}

/// A computed curve drawn on a map: its points in the map's coordinates.
#[derive(Debug, Clone)]
pub struct Curve {
    /// Legend label.
    pub label: String,
    /// Bifurcation type (its colour).
    pub kind: String,
    /// Points `(x, y)` in the map's axes.
    pub points: Vec<(f64, f64)>,
}

/// The colour of a bifurcation curve by type.
fn curve_style(kind: &str) -> RGBColor {
    match kind {
        "period-doubling" => RGBColor(120, 0, 160),
        "fold" => RGBColor(0, 0, 0),
        "neimark-sacker" => RGBColor(0, 110, 0),
        _ => RGBColor(0, 90, 200),
    }
}

/// The `z = 1/1` cells coloured by `F_i/mg` with a colour bar, other cells light grey
/// (thesis Fig. 3.26). `range` is the `F_i/mg` span of the `1/1` cells.
///
/// # Errors
/// Drawing or file errors.
pub fn force_map(
    path: &Path,
    title: &str,
    x: &MapAxis,
    y: &MapAxis,
    cells: &Raster<Cell>,
    range: Option<(f64, f64)>,
) -> Result<()> {
    let (left, right) = figure_with_panel(path, title)?;
    let chart = map_chart(&left, x, y)?;
    let (lo, hi) = range.unwrap_or((0.0, 1.0));
    let hi = if hi > lo { hi } else { lo + 1.0 };
    let color =
        |f: f64| -> RGBColor { ViridisRGB::get_color_normalized(f as f32, lo as f32, hi as f32) };
    blit(
        cells,
        &chart.plotting_area().strip_coord_spec(),
        |c| match c {
            Cell::Regime(Regime::Periodic { p: 1, q: 1 }, f) => color(f64::from(f)),
            Cell::Empty => EMPTY,
            Cell::Regime(..) => NOT_ONE_ONE,
        },
    )?;
    drop(chart);
    // Colour bar.
    let (bx, by0, by1) = (20, 110, 560);
    right.draw(&Text::new(
        "F_i/mg (z = 1/1)",
        (10, 70),
        (SANS, 17).into_font(),
    ))?;
    if range.is_some() {
        for py in by0..=by1 {
            let f = hi - (hi - lo) * f64::from(py - by0) / f64::from(by1 - by0);
            right.draw(&Rectangle::new(
                [(bx, py), (bx + 30, py + 1)],
                color(f).filled(),
            ))?;
        }
        right.draw(&Rectangle::new(
            [(bx, by0), (bx + 30, by1 + 1)],
            BLACK.stroke_width(1),
        ))?;
        for k in 0..=5 {
            let f = lo + (hi - lo) * f64::from(k) / 5.0;
            let py = by1 - (by1 - by0) * k / 5;
            right.draw(&PathElement::new([(bx + 30, py), (bx + 36, py)], BLACK))?;
            right.draw(&Text::new(
                format!("{f:.1}"),
                (bx + 40, py - 8),
                (SANS, 15).into_font(),
            ))?;
        }
    } else {
        right.draw(&Text::new(
            "no z = 1/1 cell",
            (10, 110),
            (SANS, 15).into_font(),
        ))?;
    }
    legend_panel(
        &right.clone().shrink((0, 560), (250, 300)),
        "",
        &[("other regimes".into(), LegendMark::Swatch(NOT_ONE_ONE))],
    )?;
    left.present()?;
    Ok(())
}

/// Colours of attractors (`(regime, recurrent)` in id order): each its regime's colour
/// ([`regime_color`], the same in every figure), the second, third, … attractor of the same
/// regime class ([`regime_class`]) in a lighter, darker, … shade of it ([`shade`]);
/// [`NO_ATTRACTOR`] for a set that never recurred.
pub fn attractor_palette(attractors: impl Iterator<Item = (Regime, bool)>) -> Vec<RGBColor> {
    let mut seen: Vec<usize> = Vec::new();
    attractors
        .map(|(regime, recurrent)| {
            if !recurrent {
                return NO_ATTRACTOR;
            }
            let class = regime_class(regime).0;
            let k = seen.iter().filter(|&&c| c == class).count();
            seen.push(class);
            shade(regime_color(regime), k)
        })
        .collect()
}

/// The `k`-th shade of `c`: `c` itself, then alternately mixed with white and with black,
/// 40 % then 65 % (beyond, dark grey).
pub fn shade(c: RGBColor, k: usize) -> RGBColor {
    let mix = |to: u8, t: f64| {
        let m = |v: u8| (f64::from(v) + (f64::from(to) - f64::from(v)) * t).round() as u8;
        RGBColor(m(c.0), m(c.1), m(c.2))
    };
    match k {
        0 => c,
        1 => mix(255, 0.4),
        2 => mix(0, 0.4),
        3 => mix(255, 0.65),
        4 => mix(0, 0.65),
        _ => OTHERS,
    }
}

/// Attractors beyond those a legend names, or beyond a regime's shades.
const OTHERS: RGBColor = RGBColor(80, 80, 80);

/// How many attractors the legend names one by one; the others share [`OTHERS`].
const LEGEND_ATTRACTORS: usize = 12;

/// Cells whose trajectory reached no attractor (never recurred, or conservative).
pub const NO_ATTRACTOR: RGBColor = RGBColor(238, 226, 200);

/// Colours of the attractors (indexed like `attractors`) in the view `color_by`, and the
/// legend's entries. By attractor: [`attractor_palette`] (its regime's colour, a shade of it for
/// a further attractor of the same regime);
/// by regime: the regime's colour; by impact: impacting black, not impacting white (the
/// legend is then [`basins_map`]'s). Cells without an attractor are [`NO_ATTRACTOR`].
pub fn attractor_colors(
    attractors: &[Attractor],
    color_by: ColorBy,
) -> (Vec<RGBColor>, Vec<(String, LegendMark)>) {
    let colors: Vec<RGBColor> = match color_by {
        // Beyond the legend's named ones, one "other attractors" grey.
        ColorBy::Attractor => attractor_palette(attractors.iter().map(|a| (a.regime, a.recurrent)))
            .into_iter()
            .enumerate()
            .map(|(i, c)| {
                if i >= LEGEND_ATTRACTORS && c != NO_ATTRACTOR {
                    OTHERS
                } else {
                    c
                }
            })
            .collect(),
        _ => attractors
            .iter()
            .map(|a| match (a.recurrent, color_by) {
                (false, _) => NO_ATTRACTOR,
                (true, ColorBy::Impact) if a.regime.impacts() => BLACK,
                (true, ColorBy::Impact) => WHITE,
                (true, _) => regime_color(a.regime),
            })
            .collect(),
    };
    let total: u64 = attractors.iter().map(|a| a.cells).sum();
    let share = |n: u64| percent(n, total);
    let mut entries: Vec<(String, LegendMark)> = Vec::new();
    match color_by {
        ColorBy::Attractor => {
            let mut others = 0u64;
            for (i, (a, c)) in attractors.iter().zip(&colors).enumerate() {
                if !a.recurrent {
                    continue;
                }
                if i >= LEGEND_ATTRACTORS {
                    others += a.cells;
                    continue;
                }
                let name = format!("{} ({})", a.label, share(a.cells));
                match a.point {
                    Some((u, v)) => {
                        entries.push((name, LegendMark::Dot(*c)));
                        entries.push((
                            format!(
                                "F_i/mg {:.2} at ({u:.2} mm, {v:.0} mm/s)",
                                a.impact_force_mg
                            ),
                            LegendMark::Text,
                        ));
                    }
                    None => {
                        entries.push((name, LegendMark::Swatch(*c)));
                        entries.push((
                            format!("F_i/mg up to {:.2}", a.impact_force_mg),
                            LegendMark::Text,
                        ));
                    }
                }
            }
            if others > 0 {
                entries.push((
                    format!("other attractors ({})", share(others)),
                    LegendMark::Swatch(OTHERS),
                ));
            }
        }
        ColorBy::Regime => {
            for (name, c) in
                regime_classes(attractors.iter().filter(|a| a.recurrent).map(|a| a.regime))
            {
                let n: u64 = attractors
                    .iter()
                    .filter(|a| a.recurrent && regime_class(a.regime).1 == name)
                    .map(|a| a.cells)
                    .sum();
                entries.push((format!("{name} ({})", share(n)), LegendMark::Swatch(c)));
            }
        }
        // The impact view colours each run's own window ([`basins_map`]), not attractors.
        ColorBy::Impact => return (colors, entries),
    }
    let never: u64 = attractors
        .iter()
        .filter(|a| !a.recurrent)
        .map(|a| a.cells)
        .sum();
    if never > 0 {
        entries.push((
            format!("no attractor ({})", share(never)),
            LegendMark::Swatch(NO_ATTRACTOR),
        ));
    }
    (colors, entries)
}

/// `n` of `total` as a percentage to one decimal, never rounded to `0.0 %` or `100.0 %` while
/// some are in or out (`< 0.1 %`, `> 99.9 %`).
fn percent(n: u64, total: u64) -> String {
    let p = 100.0 * n as f64 / total.max(1) as f64;
    if n > 0 && p < 0.05 {
        "< 0.1 %".into()
    } else if n < total && p >= 99.95 {
        "> 99.9 %".into()
    } else {
        format!("{p:.1} %")
    }
}

/// Basins of attraction over `(u0, u̇0)` cells (thesis Figs. 3.36–3.38): cells hold the sorted
/// attractor id (`u32::MAX` for none), coloured as `color_by` says (the impact view: whether
/// each run impacts in its observed window, as the thesis draws them); in the attractor view
/// the attractors' canonical Poincaré points are marked.
///
/// # Errors
/// Drawing or file errors.
pub fn basins_map(
    path: &Path,
    title: &str,
    axes: (&MapAxis, &MapAxis),
    summary: &BasinsSummary,
    color_by: ColorBy,
) -> Result<()> {
    let (x, y) = axes;
    let attractors = &summary.attractors;
    let (left, right) = figure_with_panel(path, title)?;
    let (colors, mut entries) = attractor_colors(attractors, color_by);
    let mut chart = map_chart(&left, x, y)?;
    if color_by == ColorBy::Impact {
        blit(
            &summary.impacting,
            &chart.plotting_area().strip_coord_spec(),
            |i| if i { BLACK } else { WHITE },
        )?;
        let total: u64 = attractors.iter().map(|a| a.cells).sum();
        let never: u64 = attractors
            .iter()
            .filter(|a| !a.recurrent)
            .map(|a| a.cells)
            .sum();
        let share = |n: u64| percent(n, total);
        entries = vec![
            (
                format!("impacting ({})", share(summary.impacting_count)),
                LegendMark::Swatch(BLACK),
            ),
            (
                format!("no impact ({})", share(total - summary.impacting_count)),
                LegendMark::Swatch(WHITE),
            ),
        ];
        entries.push(("in each run's last window".into(), LegendMark::Text));
        if never > 0 {
            entries.push((format!("no attractor: {}", share(never)), LegendMark::Text));
        }
    } else {
        blit(
            &summary.cells,
            &chart.plotting_area().strip_coord_spec(),
            |id| colors.get(id as usize).copied().unwrap_or(EMPTY),
        )?;
    }
    let (x0, x1) = x.range();
    let (y0, y1) = y.range();
    if color_by == ColorBy::Attractor {
        for (a, c) in attractors.iter().zip(&colors) {
            for &(u, v) in &a.points {
                if (x0..=x1).contains(&u) && (y0..=y1).contains(&v) {
                    chart.draw_series([
                        Circle::new((u, v), 7, c.filled()),
                        Circle::new((u, v), 7, BLACK.stroke_width(2)),
                    ])?;
                }
            }
        }
    }
    let heading = match color_by {
        ColorBy::Attractor => "attractor (basin share)",
        ColorBy::Regime => "regime (basin share)",
        ColorBy::Impact => "impact (share of starts)",
    };
    legend_panel(&right, heading, &entries)?;
    left.present()?;
    Ok(())
}

/// Basin fractions against a parameter, stacked (one band per attractor, kept along the
/// parameter), each operating point a column of width `step` (one point alone: a bar a fifth
/// of its axis wide).
///
/// # Errors
/// Drawing or file errors.
pub fn fractions_stack(
    path: &Path,
    title: &str,
    x_label: &str,
    summary: &FractionsSummary,
) -> Result<()> {
    let (left, right) = figure_with_panel(path, title)?;
    let xs: Vec<f64> = summary.points.iter().map(|p| p.value).collect();
    let step = xs
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(f64::INFINITY, f64::min);
    let step = if step.is_finite() && step > 0.0 {
        step
    } else {
        1.0
    };
    let lo = xs.iter().copied().fold(f64::INFINITY, f64::min) - 0.5 * step;
    let hi = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max) + 0.5 * step;
    // One operating point: a bar a fifth of the axis wide, not a block filling it (which read
    // as fractions over the whole axis).
    let half = if xs.len() == 1 {
        0.1 * step
    } else {
        0.5 * step
    };
    let colors = attractor_palette(summary.ids.iter().map(|(_, r, recurrent)| (*r, *recurrent)));
    // Each band (one per attractor, stacked in id order), and its fraction's 95 % interval on
    // its top edge; the top band's (whose top is 1) on its bottom edge, where it is not the
    // band below's already (two bands: the same interval, Wilson's being symmetric).
    let mut rects: Vec<([(f64, f64); 2], RGBColor)> = Vec::new();
    let mut bars: Vec<[(f64, f64); 2]> = Vec::new();
    for p in &summary.points {
        let mut base = 0.0;
        let mut bands: Vec<&(usize, crate::grid::basins::Attractor)> =
            p.attractors.iter().collect();
        bands.sort_by_key(|(id, _)| *id);
        let n = bands.len();
        for (i, (id, a)) in bands.into_iter().enumerate() {
            let top = base + a.fraction;
            rects.push(([(p.value - half, base), (p.value + half, top)], colors[*id]));
            let (l, h) = a.ci95;
            // Three bands or more: their bars side by side across the column.
            let x = if n > 2 {
                p.value + (i as f64 - 0.5 * (n - 1) as f64) * 0.5 * half / (n - 1) as f64
            } else {
                p.value
            };
            let bar = if i + 1 == n && i > 0 {
                [(x, base - (h - a.fraction)), (x, base + (a.fraction - l))]
            } else {
                [(x, top - (a.fraction - l)), (x, top + (h - a.fraction))]
            };
            let same = |b: &[(f64, f64); 2]| {
                (b[0].1 - bar[0].1).abs() < 1e-9 && (b[1].1 - bar[1].1).abs() < 1e-9
            };
            if !(i > 0 && bars.last().is_some_and(same)) {
                bars.push(bar);
            }
            base = top;
        }
    }
    // An interval reaching above 1: the axis goes as far, its ticks to 1 only.
    let y_top = bars.iter().map(|b| b[1].1).fold(1.0, f64::max).min(1.25);
    let mut chart = ChartBuilder::on(&left)
        .margin(10)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(lo..hi, 0.0..y_top)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(x_label)
        .y_desc("basin fraction")
        .x_label_formatter(&tick)
        .y_label_formatter(&|v: &f64| {
            if *v > 1.0 + 1e-9 {
                String::new()
            } else {
                tick(v)
            }
        })
        .label_style((SANS, 15))
        .axis_desc_style((SANS, 17))
        .draw()?;
    chart.draw_series(rects.iter().map(|(r, c)| Rectangle::new(*r, c.filled())))?;
    // The intervals after every band, so that no band covers one, white-edged to show on any
    // colour.
    for (width, color) in [(4, WHITE), (2, BLACK)] {
        chart.draw_series(
            bars.iter()
                .map(|b| PathElement::new(b.to_vec(), color.stroke_width(width))),
        )?;
    }
    let mut entries: Vec<(String, LegendMark)> = Vec::new();
    for (i, ((name, regime, recurrent), c)) in summary.ids.iter().zip(&colors).enumerate() {
        if i >= 16 {
            break;
        }
        let force = summary
            .points
            .iter()
            .flat_map(|p| p.attractors.iter())
            .filter(|(id, _)| *id == i)
            .map(|(_, a)| a.impact_force_mg)
            .fold(0.0, f64::max);
        let label = if *recurrent && regime.impacts() {
            format!("{name}: {regime}, F_i/mg ≤ {force:.1}")
        } else if *recurrent {
            format!("{name}: {regime}")
        } else {
            "no attractor".into()
        };
        entries.push((label, LegendMark::Swatch(*c)));
    }
    entries.push(("bar: 95 % interval".into(), LegendMark::Line(BLACK)));
    legend_panel(&right, "attractor", &entries)?;
    left.present()?;
    Ok(())
}

/// A dot of a bifurcation diagram.
#[derive(Debug, Clone, Copy)]
pub enum BifDot {
    /// A Poincaré point: `Ω/ω`, `u` (mm).
    Strobe(f64, f64),
    /// An impact: `Ω/ω`, `F_i/mg`.
    Impact(f64, f64),
}

/// Colour of a bifurcation branch (`rest`, `up`, `down`).
pub fn branch_color(branch: &str) -> RGBColor {
    match branch {
        "up" => RGBColor(215, 25, 28),
        "down" => RGBColor(43, 131, 186),
        _ => RGBColor(20, 20, 20),
    }
}

/// Font size of the bifurcation diagram's legend, px.
const BIF_LEGEND_PX: u32 = 14;

/// Axis spans of a bifurcation diagram.
#[derive(Debug, Clone, Copy)]
pub struct BifRanges {
    /// `Ω/ω` span.
    pub x: (f64, f64),
    /// `u` span, mm.
    pub u: (f64, f64),
    /// Largest `F_i/mg`.
    pub force_max: f64,
}

/// Two panels over `Ω/ω` (thesis Figs. 3.27/3.30): Poincaré `u` (mm) on top, impact peaks
/// `F_i/mg` below, small dots coloured by branch. `feed` streams the dots of each branch:
/// it is called with a drawing function taking `(branch, dot)`.
///
/// # Errors
/// Drawing, file or `feed` errors.
pub fn bifurcation(
    path: &Path,
    title: &str,
    ranges: BifRanges,
    gap_mm: f64,
    branches: &[&str],
    feed: impl FnOnce(&mut dyn FnMut(&str, BifDot) -> Result<()>) -> Result<()>,
) -> Result<()> {
    let root = canvas(path, (1100, 950), Some((title, 20)))?;
    let (top, bottom) = root.split_vertically(470);
    let pad = |(a, b): (f64, f64)| {
        let d = ((b - a) * 0.04).max(1e-3);
        (a - d, b + d)
    };
    let (x0, x1) = pad(ranges.x);
    let (u0, u1) = pad((ranges.u.0.min(gap_mm), ranges.u.1.max(gap_mm)));
    let mut ct = panel(&top, BIF_TOP, x0..x1, u0..u1, ("Ω/ω", "Poincaré u (mm)"))?;
    let surface = format!("impact surface u = gap = {gap_mm} mm");
    let surface_style = BLACK.mix(0.4);
    level_line(&mut ct, (x0, x1), gap_mm, surface_style, surface.clone())?;
    let mut cb = panel(
        &bottom,
        BIF_BOTTOM,
        x0..x1,
        0.0..(ranges.force_max * 1.06).max(1.0),
        ("Ω/ω", "impact peak F_i/mg"),
    )?;
    let names: Vec<(&str, &str)> = branches
        .iter()
        .map(|&b| {
            let name = match b {
                "up" => "continuation, Ω increasing",
                "down" => "continuation, Ω decreasing",
                _ => "from rest at each Ω",
            };
            (b, name)
        })
        .collect();
    // The legend where it covers the fewest dots, in either panel (the top panel's upper left
    // where that covers none).
    let labels: Vec<String> = std::iter::once(surface)
        .chain(names.iter().map(|n| n.1.to_string()))
        .collect();
    let size = legend_size(&labels, BIF_LEGEND_PX)?;
    let mut covers = [LegendCover::new(&ct, size), LegendCover::new(&cb, size)];
    covers[0].line([(x0, gap_mm), (x1, gap_mm)]);
    feed(&mut |branch: &str, dot: BifDot| {
        let c = branch_color(branch).mix(0.75).filled();
        match dot {
            BifDot::Strobe(x, u) => {
                ct.draw_series([Circle::new((x, u), 1, c)])?;
                covers[0].dots([(x, u)]);
            }
            BifDot::Impact(x, f) => {
                cb.draw_series([Circle::new((x, f), 1, c)])?;
                covers[1].dots([(x, f)]);
            }
        }
        Ok(())
    })?;
    let (panel_at, place) = least_covered(&covers);
    let chart = if panel_at == 0 { &mut ct } else { &mut cb };
    if panel_at == 1 {
        // The surface's key goes with the legend; its line stays in the top panel.
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
            .label(&labels[0])
            .legend(line_key(surface_style));
    }
    for (b, name) in names {
        let c = branch_color(b);
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
            .label(name)
            .legend(move |(x, y)| Circle::new((x + 8, y), 4, c.filled()));
    }
    series_legend(chart, Some(LEGEND_PLACES[place].clone()), BIF_LEGEND_PX)?;
    root.present()?;
    Ok(())
}

impl GridFigures for Peterka {
    fn draw(job: &mut Finish<'_>, curves: Vec<CurveOut>) -> Result<()> {
        let (outputs, meta, csv, figures) = (&mut *job.outputs, job.meta, job.rows, job.figures);
        let Figures {
            plot, force_plot, ..
        } = figures;
        if plot.is_none() && force_plot.is_none() {
            return Ok(());
        }
        let grid = meta.grid::<Self::Grid>()?;
        let a0_mm = meta.params.amplitude_m * 1e3;
        let fn_hz = meta.params.natural_freq_hz();
        let (nf, ng) = (grid.freq.sweep.len(), grid.gap.sweep.len());
        let mut cells = Raster::new(nf, ng, Cell::Empty);
        let mut force: Option<(f64, f64)> = None;
        let mut rdr = open_csv::<PeterkaRow>(csv)?;
        for row in rdr.deserialize::<PeterkaRow>() {
            let row = row.with_context(|| format!("{}: malformed row", csv.display()))?;
            let (ig, jf) = grid.split(row.index as usize);
            cells.set(jf, ig, Cell::Regime(row.regime, row.impact_force_mg as f32));
            if row.regime == Regime::ONE_ONE {
                let f = row.impact_force_mg;
                force = Some(force.map_or((f, f), |(lo, hi)| (lo.min(f), hi.max(f))));
            }
        }
        let (x0, _) = grid.freq(0, fn_hz);
        let (x1, _) = grid.freq(1, fn_hz);
        let x = MapAxis {
            lo: x0,
            step: if nf > 1 { x1 - x0 } else { 0.02 },
            n: nf,
            label: format!("Ω/ω (excitation / natural frequency; f = Ω/ω × {fn_hz:.4} Hz)"),
        };
        let y = MapAxis {
            lo: grid.gap(0, a0_mm).1,
            step: if ng > 1 {
                grid.gap(1, a0_mm).1 - grid.gap(0, a0_mm).1
            } else {
                0.02
            },
            n: ng,
            label: format!("gap/A0 (A0 = {a0_mm:.3} mm)"),
        };
        if let Some(p) = plot {
            let tmp = outputs.reserve(p)?;
            let title = format!(
                "{} — impact regime z = p/q (Peterka map)",
                title_prefix(meta)
            );
            let curves: Vec<Curve> = curves
                .iter()
                .map(|c| Curve {
                    label: format!(
                        "{} of {}",
                        c.kind.replace("period-doubling", "doubling"),
                        c.regime
                    ),
                    kind: c.kind.clone(),
                    points: c.points.iter().map(|p| (p[0], p[1] / a0_mm)).collect(),
                })
                .collect();
            regime_map(&tmp, &title, &x, &y, &cells, &curves)?;
        }
        if let Some(p) = force_plot {
            let tmp = outputs.reserve(p)?;
            let title = format!(
                "{} — max impact force F_i/mg in the z = 1/1 region",
                title_prefix(meta)
            );
            force_map(&tmp, &title, &x, &y, &cells, force)?;
        }
        Ok(())
    }
}

impl GridFigures for Bifurcation {
    /// Draws the figure from the complete CSV, reading it twice (spans, then dots): memory
    /// does not grow with the sweep.
    fn draw(job: &mut Finish<'_>, _summary: ()) -> Result<()> {
        let (outputs, meta, csv, figures) = (&mut *job.outputs, job.meta, job.rows, job.figures);
        let Some(plot) = figures.plot else {
            return Ok(());
        };
        let grid = meta.grid::<Self::Grid>()?;
        let mut ranges = BifRanges {
            x: (
                grid.omega_ratio.value(0),
                grid.omega_ratio.value(grid.omega_ratio.len() - 1),
            ),
            u: (f64::INFINITY, f64::NEG_INFINITY),
            force_max: 0.0,
        };
        let mut present = [false; 3];
        const BRANCHES: [&str; 3] = ["rest", "up", "down"];
        for row in open_csv::<BifRow>(csv)?.deserialize::<BifRow>() {
            let row = row.with_context(|| format!("{}: malformed row", csv.display()))?;
            if let Some(k) = BRANCHES.iter().position(|b| *b == row.branch) {
                present[k] = true;
            }
            if let Some(u) = row.u_mm {
                ranges.u = (ranges.u.0.min(u), ranges.u.1.max(u));
            }
            if let Some(f) = row.impact_force_mg {
                ranges.force_max = ranges.force_max.max(f);
            }
        }
        if !ranges.u.0.is_finite() {
            ranges.u = (0.0, grid.gap_mm);
        }
        let branches: Vec<&str> = BRANCHES
            .iter()
            .zip(present)
            .filter(|(_, p)| *p)
            .map(|(b, _)| *b)
            .collect();
        let tmp = outputs.reserve(plot)?;
        let title = format!(
            "{} — bifurcation diagram, gap {} mm{}",
            title_prefix(meta),
            grid.gap_mm,
            match grid.continuation {
                None => ", from rest at each Ω",
                Some(_) => ", continuation",
            }
        );
        bifurcation(&tmp, &title, ranges, grid.gap_mm, &branches, |draw| {
            for row in open_csv::<BifRow>(csv)?.deserialize::<BifRow>() {
                let row = row.with_context(|| format!("{}: malformed row", csv.display()))?;
                let dot = match (row.u_mm, row.impact_force_mg) {
                    (Some(u), _) => BifDot::Strobe(row.omega_ratio, u),
                    (None, Some(f)) => BifDot::Impact(row.omega_ratio, f),
                    _ => continue,
                };
                draw(&row.branch, dot)?;
            }
            Ok(())
        })
    }
}

impl GridFigures for Basins {
    fn draw(job: &mut Finish<'_>, summary: BasinsSummary) -> Result<()> {
        let (outputs, meta, figures) = (&mut *job.outputs, job.meta, job.figures);
        let grid = meta.grid::<BasinsGrid>()?;
        let (nu, nv) = (grid.u0_mm.len(), grid.v0_mm_s.len());
        if let Some(p) = figures.plot {
            let tmp = outputs.reserve(p)?;
            let x = MapAxis {
                lo: grid.u0_mm.start,
                step: grid.u0_mm.spacing(),
                n: nu,
                label: "initial displacement u0 (mm)".into(),
            };
            let y = MapAxis {
                lo: grid.v0_mm_s.start,
                step: grid.v0_mm_s.spacing(),
                n: nv,
                label: "initial velocity du/dt (mm/s)".into(),
            };
            let title = format!(
                "{} — basins of attraction, gap {} mm, Ω/ω = {} ({:.3} Hz)",
                title_prefix(meta),
                grid.gap_mm,
                grid.omega_ratio,
                meta.params.freq_hz_from_ratio(grid.omega_ratio)
            );
            basins_map(&tmp, &title, (&x, &y), &summary, grid.color_by)?;
        }
        Ok(())
    }
}

impl GridFigures for Fractions {
    fn draw(job: &mut Finish<'_>, summary: FractionsSummary) -> Result<()> {
        let (outputs, meta, figures) = (&mut *job.outputs, job.meta, job.figures);
        let Some(p) = figures.plot else {
            return Ok(());
        };
        let grid = meta.grid::<FractionsGrid>()?;
        let tmp = outputs.reserve(p)?;
        let (gap_mm, ratio) = grid.points[0];
        let (x_label, fixed) = match grid.parameter {
            Parameter::OmegaRatio => ("Ω/ω".to_string(), format!("gap {gap_mm} mm")),
            Parameter::GapMm => ("gap (mm)".to_string(), format!("Ω/ω = {ratio}")),
        };
        let title = format!(
            "{} — basin fractions, {fixed}, {} initial conditions per point (seed {})",
            title_prefix(meta),
            summary.points.iter().map(|p| p.samples).max().unwrap_or(0),
            grid.seed
        );
        fractions_stack(&tmp, &title, &x_label, &summary)
    }
}

#[cfg(test)]
mod tests {
    use super::percent;

    #[test]
    fn a_share_is_never_rounded_away() {
        assert_eq!(percent(6, 40_000), "< 0.1 %");
        assert_eq!(percent(39_994, 40_000), "> 99.9 %");
        assert_eq!(percent(0, 40_000), "0.0 %");
        assert_eq!(percent(40_000, 40_000), "100.0 %");
        assert_eq!(percent(141, 40_000), "0.4 %");
        assert_eq!(percent(0, 0), "0.0 %");
    }
}

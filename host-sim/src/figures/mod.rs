//! Figures with plotters, as PNG or SVG by the file name ([`backend`]; bundled DejaVu Sans: no
//! system font needed for a PNG): the common canvas, panels, legend keys and the one regime
//! palette here; the figures of each kind of result in the submodules. Figures read the
//! computations' results; no computation imports a figure.

pub mod backend;
pub mod identify;
pub mod maps;
pub mod orbits;
pub mod response;
pub mod rig_log;

use std::ops::Range;
use std::path::Path;
use std::sync::Once;

use anyhow::Result;
use plotters::coord::CoordTranslate;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use shared::observe::Regime;

pub use backend::Backend;

const FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
/// Family name of the bundled font.
pub(crate) const SANS: &str = "sans-serif";

/// Registers the bundled font (once).
pub(crate) fn ensure_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bundled font is valid TTF; a failure would only show as missing text.
        let _ = plotters::style::register_font(SANS, FontStyle::Normal, FONT);
    });
}

/// A chart with linear `f64` axes on a figure.
pub(crate) type Chart<'a, 'b> =
    ChartContext<'a, Backend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// The drawing area of a figure: a white `size` px canvas written to `path` (SVG if its name
/// ends in `.svg`, else PNG: [`Backend::for_path`]), with `title` at `title_px` across the top
/// if given (the area below it is returned).
///
/// # Errors
/// Drawing errors.
pub(crate) fn canvas<'a>(
    path: &'a Path,
    size: (u32, u32),
    title: Option<(&str, u32)>,
) -> Result<DrawingArea<Backend<'a>, Shift>> {
    ensure_font();
    let root = Backend::for_path(path, size).into_drawing_area();
    root.fill(&WHITE)?;
    Ok(match title {
        Some((text, px)) => root.titled(text, (SANS, px))?,
        None => root,
    })
}

/// How a panel is framed, px: the outer margin, the x- and y-label areas, the tick-label font
/// and, if set, a larger font for the axis descriptions.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Frame {
    pub margin: u32,
    pub x_area: u32,
    pub y_area: u32,
    pub font: u32,
    pub desc_font: Option<u32>,
}

impl Frame {
    /// A frame with the tick labels and axis descriptions at `font` px.
    pub(crate) const fn new(margin: u32, x_area: u32, y_area: u32, font: u32) -> Frame {
        Frame {
            margin,
            x_area,
            y_area,
            font,
            desc_font: None,
        }
    }

    /// The same frame with the axis descriptions at `px`.
    pub(crate) const fn desc_font(self, px: u32) -> Frame {
        Frame {
            desc_font: Some(px),
            ..self
        }
    }
}

/// A panel on `area`: `x` × `y` framed by `frame`, its mesh drawn with the axis descriptions
/// `desc` (x, y).
///
/// # Errors
/// Drawing errors.
pub(crate) fn panel<'a, 'b>(
    area: &'a DrawingArea<Backend<'b>, Shift>,
    frame: Frame,
    x: Range<f64>,
    y: Range<f64>,
    desc: (&str, &str),
) -> Result<Chart<'a, 'b>> {
    let mut chart = ChartBuilder::on(area)
        .margin(frame.margin)
        .x_label_area_size(frame.x_area)
        .y_label_area_size(frame.y_area)
        .build_cartesian_2d(x, y)?;
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(desc.0)
        .y_desc(desc.1)
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .label_style((SANS, frame.font));
    if let Some(px) = frame.desc_font {
        mesh.axis_desc_style((SANS, px));
    }
    mesh.draw()?;
    Ok(chart)
}

/// An axis' tick label: plotters' own (the shortest decimal within 1e-5, at least one
/// decimal), but a tick that lands within that of zero (`-1e-17` from `lo + k·step`) reads
/// `0.0`, not `-0.0`.
pub(crate) fn tick(v: &f64) -> String {
    let v = if v.abs() < 1e-5 { 0.0 } else { *v };
    plotters::data::float::FloatPrettyPrinter {
        allow_scientific: false,
        min_decimal: 1,
        max_decimal: 5,
    }
    .print(v)
}

/// A legend key: a 14 × 10 px swatch in `style`.
pub(crate) fn swatch_key<S: Into<ShapeStyle> + Clone>(
    style: S,
) -> impl Fn((i32, i32)) -> Rectangle<(i32, i32)> {
    move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], style.clone())
}

/// A legend key: a 16 px line in `style`.
pub(crate) fn line_key<S: Into<ShapeStyle> + Clone>(
    style: S,
) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new([(x, y), (x + 16, y)], style.clone())
}

/// Draws the line through `points` on `chart` in `style`, with the legend entry `label`.
///
/// # Errors
/// Drawing errors.
pub(crate) fn labelled_line(
    chart: &mut Chart<'_, '_>,
    points: impl IntoIterator<Item = (f64, f64)>,
    style: impl Into<ShapeStyle>,
    label: impl Into<String>,
) -> Result<()> {
    let style: ShapeStyle = style.into();
    chart
        .draw_series(LineSeries::new(points, style))?
        .label(label)
        .legend(line_key(style));
    Ok(())
}

/// Draws a reference level of `chart` (the impact surface, a limit): a horizontal line at `y`
/// from `x0` to `x1` in `style`, with its legend entry `label`.
///
/// # Errors
/// Drawing errors.
pub(crate) fn level_line(
    chart: &mut Chart<'_, '_>,
    (x0, x1): (f64, f64),
    y: f64,
    style: impl Into<ShapeStyle>,
    label: impl Into<String>,
) -> Result<()> {
    labelled_line(chart, [(x0, y), (x1, y)], style, label)
}

/// Draws the series legend of `chart`: at `position` (plotters' default if `None`), on a
/// translucent white box with a black border, labels in [`SANS`] at `font_size` px.
///
/// # Errors
/// Drawing errors.
pub(crate) fn series_legend<'a, 'b: 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, Backend<'b>, CT>,
    position: Option<SeriesLabelPosition>,
    font_size: u32,
) -> Result<()> {
    let mut labels = chart.configure_series_labels();
    if let Some(p) = position {
        labels.position(p);
    }
    labels
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((SANS, font_size))
        .draw()?;
    Ok(())
}

/// The places a legend may take ([`least_covered`]): the corners, then the middles of the
/// edges, in the order taken when they cover as much.
pub(crate) const LEGEND_PLACES: [SeriesLabelPosition; 8] = [
    SeriesLabelPosition::UpperLeft,
    SeriesLabelPosition::UpperRight,
    SeriesLabelPosition::LowerLeft,
    SeriesLabelPosition::LowerRight,
    SeriesLabelPosition::UpperMiddle,
    SeriesLabelPosition::LowerMiddle,
    SeriesLabelPosition::MiddleLeft,
    SeriesLabelPosition::MiddleRight,
];

/// The size `(w, h)`, px, of the legend [`series_legend`] draws for `labels` at `font_size` px:
/// plotters' layout, the text block with a 30 px key column and 10 px margins.
///
/// # Errors
/// Font errors.
pub(crate) fn legend_size(labels: &[String], font_size: u32) -> Result<(i32, i32)> {
    ensure_font();
    let style: TextStyle = (SANS, font_size).into();
    let mut text = MultiLineText::<(i32, i32), &str>::new((0, 0), style);
    for label in labels {
        text.push_line(label.as_str());
    }
    let (w, h) = text
        .estimate_dimension()
        .map_err(|e| anyhow::anyhow!("legend text: {e:?}"))?;
    Ok((w + 30 + 20, h + 20))
}

/// How much of a panel's data a legend of a given size would cover at each of
/// [`LEGEND_PLACES`] (where plotters puts it: 5 px from the plotting area's edges, or centred
/// along one): the points
/// of its lines, taken every 4 px along each segment, and its dots and markers, that fall within
/// 6 px of the legend's box (a line's width, a marker's size).
pub(crate) struct LegendCover {
    coord: Cartesian2d<RangedCoordf64, RangedCoordf64>,
    /// The boxes' upper left corners, px.
    boxes: [(i32, i32); 8],
    size: (i32, i32),
    counts: [usize; 8],
}

impl LegendCover {
    const STEP_PX: f64 = 4.0;
    const PAD_PX: i32 = 6;

    /// Nothing covered yet, for a legend of `size` px ([`legend_size`]) on `chart`.
    pub(crate) fn new(chart: &Chart<'_, '_>, size: (i32, i32)) -> LegendCover {
        let (xs, ys) = chart.plotting_area().get_pixel_range();
        let (left, right) = (xs.start + 5, xs.end - size.0 - 5);
        let (top, bottom) = (ys.start + 5, ys.end - size.1 - 5);
        // Plotters centres in integer pixels.
        let centre = xs.start + (xs.end - xs.start - size.0) / 2;
        let middle = ys.start + (ys.end - ys.start - size.1) / 2;
        LegendCover {
            coord: chart.as_coord_spec().clone(),
            boxes: [
                (left, top),
                (right, top),
                (left, bottom),
                (right, bottom),
                (centre, top),
                (centre, bottom),
                (left, middle),
                (right, middle),
            ],
            size,
            counts: [0; 8],
        }
    }

    fn pixel(&self, p: (f64, f64)) -> (f64, f64) {
        let (x, y) = self.coord.translate(&p);
        (f64::from(x), f64::from(y))
    }

    fn count(&mut self, (px, py): (f64, f64)) {
        let (w, h) = self.size;
        for (c, &(bx, by)) in self.counts.iter_mut().zip(&self.boxes) {
            let inside_x =
                px >= f64::from(bx - Self::PAD_PX) && px <= f64::from(bx + w + Self::PAD_PX);
            let inside_y =
                py >= f64::from(by - Self::PAD_PX) && py <= f64::from(by + h + Self::PAD_PX);
            *c += usize::from(inside_x && inside_y);
        }
    }

    /// Adds the line through `points` (data coordinates; points not finite skipped).
    pub(crate) fn line(&mut self, points: impl IntoIterator<Item = (f64, f64)>) {
        let mut last: Option<(f64, f64)> = None;
        for p in points
            .into_iter()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
        {
            let b = self.pixel(p);
            match last {
                None => self.count(b),
                Some(a) => {
                    let pieces = ((b.0 - a.0).hypot(b.1 - a.1) / Self::STEP_PX).ceil();
                    // (Capped: a segment far outside the panel is not walked pixel by pixel.)
                    let pieces = pieces.clamp(1.0, 4096.0) as u32;
                    for i in 1..=pieces {
                        let t = f64::from(i) / f64::from(pieces);
                        self.count((a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)));
                    }
                }
            }
            last = Some(b);
        }
    }

    /// Adds dots or markers at `points` (data coordinates).
    pub(crate) fn dots(&mut self, points: impl IntoIterator<Item = (f64, f64)>) {
        for p in points
            .into_iter()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
        {
            let b = self.pixel(p);
            self.count(b);
        }
    }

    /// The points covered at each of [`LEGEND_PLACES`].
    #[cfg(test)]
    pub(crate) fn counts(&self) -> [usize; 8] {
        self.counts
    }
}

/// The place on one panel's `chart` ([`LEGEND_PLACES`]) where the legend of `labels` at
/// `font_size` px covers the least of the data `fill` adds to its cover (the upper left on a
/// tie).
///
/// # Errors
/// Font errors.
pub(crate) fn legend_place(
    chart: &Chart<'_, '_>,
    labels: &[String],
    font_size: u32,
    fill: impl FnOnce(&mut LegendCover),
) -> Result<SeriesLabelPosition> {
    let mut cover = LegendCover::new(chart, legend_size(labels, font_size)?);
    fill(&mut cover);
    Ok(LEGEND_PLACES[least_covered(&[cover]).1].clone())
}

/// The `y` range of a [`panel`] in `frame` on `area` over `x` that leaves the legend of `labels`
/// at `font_size` px a place clear of the data `fill` adds to its cover ([`legend_place`]):
/// `y` itself where one of [`LEGEND_PLACES`] covers none, else `y` raised at its top by the
/// legend's height and margins, so that the upper places are clear (a long time series fills
/// the panel edge to edge).
///
/// # Errors
/// Font or layout errors.
pub(crate) fn room_for_legend(
    area: &DrawingArea<Backend<'_>, Shift>,
    frame: Frame,
    x: Range<f64>,
    y: Range<f64>,
    (labels, font_size): (&[String], u32),
    fill: impl FnOnce(&mut LegendCover),
) -> Result<Range<f64>> {
    // The panel's layout without drawing it (the mesh is drawn by `panel`).
    let probe = ChartBuilder::on(area)
        .margin(frame.margin)
        .x_label_area_size(frame.x_area)
        .y_label_area_size(frame.y_area)
        .build_cartesian_2d(x, y.clone())?;
    let size = legend_size(labels, font_size)?;
    let mut cover = LegendCover::new(&probe, size);
    fill(&mut cover);
    if cover.counts.contains(&0) {
        return Ok(y);
    }
    let (_, ys) = probe.plotting_area().get_pixel_range();
    let height = f64::from(ys.end - ys.start);
    // The legend's box 5 px below the top, and the cover's padding below it.
    let needed = f64::from(size.1 + 5 + LegendCover::PAD_PX);
    if needed >= 0.5 * height {
        return Ok(y);
    }
    let span = y.end - y.start;
    Ok(y.start..y.start + span * height / (height - needed))
}

/// Where a legend covers the least of its figure's data: `(panel, place)`, the index of the
/// panel's cover in `covers` and of the place in [`LEGEND_PLACES`]; on a tie the first panel,
/// then the first place (the upper left).
pub(crate) fn least_covered(covers: &[LegendCover]) -> (usize, usize) {
    (0..covers.len())
        .flat_map(|p| (0..LEGEND_PLACES.len()).map(move |c| (p, c)))
        .min_by_key(|&(p, c)| covers[p].counts[c])
        .unwrap_or((0, 0))
}

/// Colours of the named regimes, in legend order: `1/1` red and `1/2` green (the thesis' Peterka
/// colours), then the other regimes the maps of this rig show; every other periodic regime is
/// [`OTHER_PERIODIC`]. The one palette of every figure.
pub const NAMED_REGIMES: [(u16, u16, RGBColor); 11] = [
    (1, 1, RGBColor(215, 25, 28)),
    (1, 2, RGBColor(26, 150, 65)),
    (2, 2, RGBColor(253, 174, 97)),
    (1, 3, RGBColor(117, 112, 179)),
    (2, 1, RGBColor(166, 86, 40)),
    (3, 3, RGBColor(231, 41, 138)),
    (2, 3, RGBColor(0, 160, 160)),
    (3, 1, RGBColor(128, 128, 0)),
    (1, 4, RGBColor(31, 60, 140)),
    (4, 4, RGBColor(240, 200, 0)),
    (3, 2, RGBColor(190, 120, 220)),
];
/// A periodic regime not in [`NAMED_REGIMES`].
pub const OTHER_PERIODIC: RGBColor = RGBColor(43, 131, 186);
/// No impact.
pub const NO_IMPACT: RGBColor = RGBColor(190, 190, 190);
/// Irregular (no period found).
pub const IRREGULAR: RGBColor = RGBColor(0, 0, 0);
/// Chaotic (irregular with a positive largest Lyapunov exponent).
pub const CHAOTIC: RGBColor = RGBColor(120, 0, 90);

/// Colour of a regime in every figure (a fixed function of the regime: [`NAMED_REGIMES`],
/// [`OTHER_PERIODIC`], [`IRREGULAR`], [`CHAOTIC`], [`NO_IMPACT`]).
pub fn regime_color(r: Regime) -> RGBColor {
    match r {
        Regime::Periodic { p, q } => NAMED_REGIMES
            .iter()
            .find(|&&(a, b, _)| a == p && b == q)
            .map_or(OTHER_PERIODIC, |&(_, _, c)| c),
        Regime::Irregular => IRREGULAR,
        Regime::Chaotic => CHAOTIC,
        Regime::NoImpact => NO_IMPACT,
    }
}

/// Legend class of a regime in every figure: its position in the legend order and its label
/// (`z = p/q` for a named regime, `other periodic`, `irregular`, `chaotic`, `no impact`).
pub fn regime_class(r: Regime) -> (usize, String) {
    match r {
        Regime::Periodic { p, q } => {
            match NAMED_REGIMES.iter().position(|&(a, b, _)| a == p && b == q) {
                Some(k) => (k, format!("z = {p}/{q}")),
                None => (NAMED_REGIMES.len(), "other periodic".into()),
            }
        }
        Regime::Irregular => (NAMED_REGIMES.len() + 1, "irregular".into()),
        Regime::Chaotic => (NAMED_REGIMES.len() + 2, "chaotic".into()),
        Regime::NoImpact => (NAMED_REGIMES.len() + 3, "no impact".into()),
    }
}

/// The legend classes present among `regimes`, in legend order: `(label, colour)`, each once.
pub fn regime_classes(regimes: impl Iterator<Item = Regime>) -> Vec<(String, RGBColor)> {
    let mut seen: Vec<(usize, String, RGBColor)> = Vec::new();
    for r in regimes {
        let (k, name) = regime_class(r);
        if !seen.iter().any(|(j, _, _)| *j == k) {
            seen.push((k, name, regime_color(r)));
        }
    }
    seen.sort_by_key(|(k, _, _)| *k);
    seen.into_iter().map(|(_, n, c)| (n, c)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ticks of `-0.6..0.6` in steps of 0.2 as plotters places them (`lo + k·step`, so the
    /// middle one is 1.1e-16, and `-0.2 + 0.2` gives -2.8e-17 in other ranges): plotters'
    /// labels but for the sign of zero.
    #[test]
    fn a_tick_at_zero_reads_without_a_sign() {
        let ticks: Vec<String> = (0..7).map(|k| tick(&(-0.6 + 0.2 * f64::from(k)))).collect();
        assert_eq!(ticks, ["-0.6", "-0.4", "-0.2", "0.0", "0.2", "0.4", "0.6"]);
        assert_eq!(tick(&-2.8e-17), "0.0");
        assert_eq!(
            (tick(&-0.00002), tick(&1234.5)),
            ("-0.00002".into(), "1234.5".into())
        );
    }

    /// A legend of 100 × 60 px on a 400 × 300 px plotting area over `[0, 1]²`: its boxes span
    /// x 5–105 px (data 0.0125–0.2625), 150–250 px (0.375–0.625) or 295–395 px (0.7375–0.9875),
    /// y 5–65 px from the top (data 0.783–0.983), 120–180 px (0.4–0.6) or 235–295 px
    /// (0.017–0.217), and cover what lies within 6 px of them.
    #[test]
    fn a_legend_covers_the_dots_and_the_segments_that_cross_its_box() {
        let mut buf = vec![0u8; 400 * 300 * 3];
        let area =
            Backend::Bitmap(BitMapBackend::with_buffer(&mut buf, (400, 300))).into_drawing_area();
        let chart = ChartBuilder::on(&area)
            .build_cartesian_2d(0.0..1.0, 0.0..1.0)
            .unwrap();
        let mut cover = LegendCover::new(&chart, (100, 60));
        // One dot in the upper left box, one just outside it (13 px below), one in no box.
        cover.dots([(0.1, 0.9), (0.1, 0.74), (0.5, 0.5), (f64::NAN, 0.9)]);
        assert_eq!(cover.counts(), [1, 0, 0, 0, 0, 0, 0, 0]);
        // Its middle (0.8, 0.2) crosses the lower right box; its ends lie within 6 px of the
        // lower middle one (x 150–250, y 235–295 px) and the middle right one (x 295–395,
        // y 120–180 px).
        cover.line([(0.6, 0.0), (1.0, 0.4)]);
        let [ul, ur, ll, lr, um, lm, ml, mr] = cover.counts();
        assert_eq!((ul, ur, ll, um, ml), (1, 0, 0, 0, 0));
        assert!(lm >= 1 && mr >= 1, "{lm} {mr}");
        // The segment, 200 px long, in 50 pieces of 4 px: 57 px of it (t 0.31–0.59) lie within
        // 6 px of the box, the ends of 14 pieces.
        assert!((13..=15).contains(&lr), "{lr}");

        // Two panels: the first panel's upper left on a tie, else the fewest covered anywhere.
        let empty = || LegendCover::new(&chart, (100, 60));
        assert_eq!(least_covered(&[empty(), empty()]), (0, 0));
        // `cover` is covered at its upper left, not its upper right: that wins.
        assert_eq!(least_covered(&[cover, empty()]), (0, 1));
        // Every place of the first panel covered, the second's upper left: its upper right.
        let (mut first, mut second) = (empty(), empty());
        first.dots([(0.1, 0.9), (0.9, 0.9), (0.1, 0.1), (0.9, 0.1)]);
        first.dots([(0.5, 0.9), (0.5, 0.1), (0.1, 0.5), (0.9, 0.5)]);
        second.dots([(0.1, 0.9)]);
        assert_eq!(least_covered(&[first, second]), (1, 1));
        // The corners covered, the edges' middles free: the upper middle.
        let mut corners = empty();
        corners.dots([(0.1, 0.9), (0.9, 0.9), (0.1, 0.1), (0.9, 0.1)]);
        assert_eq!(least_covered(&[corners]), (0, 4));
    }

    /// A curve that fills its panel edge to edge (a sine over 40 turns between −1 and 1 on a
    /// 400 × 300 px panel) leaves the legend no clear place: the panel's top is raised by the
    /// legend's height and margins, and then its upper places are clear; a curve that leaves
    /// a place clear keeps its range.
    #[test]
    fn a_full_panel_is_raised_to_leave_its_legend_room() {
        let mut buf = vec![0u8; 400 * 300 * 3];
        let area =
            Backend::Bitmap(BitMapBackend::with_buffer(&mut buf, (400, 300))).into_drawing_area();
        let frame = Frame::new(0, 0, 0, 14);
        let labels = [
            "u (relative to cart)".to_string(),
            "x (absolute)".to_string(),
        ];
        let sine = |lo: f64, hi: f64| {
            move |cover: &mut LegendCover| {
                cover.line((0..=4000).map(|k| {
                    let t = f64::from(k) / 4000.0;
                    let s = (80.0 * std::f64::consts::PI * t).sin();
                    (t, lo + (hi - lo) * 0.5 * (1.0 + s))
                }))
            }
        };
        let y = -1.05..1.05;
        let raised = room_for_legend(
            &area,
            frame,
            0.0..1.0,
            y.clone(),
            (&labels, 14),
            sine(-1.0, 1.0),
        )
        .unwrap();
        let (_, h) = legend_size(&labels, 14).unwrap();
        let needed = f64::from(h + 11);
        assert_eq!(raised.start, y.start);
        let expect = -1.05 + 2.1 * 300.0 / (300.0 - needed);
        assert!((raised.end - expect).abs() < 1e-12, "{raised:?} {expect}");
        let chart = ChartBuilder::on(&area)
            .build_cartesian_2d(0.0..1.0, raised)
            .unwrap();
        let mut cover = LegendCover::new(&chart, legend_size(&labels, 14).unwrap());
        sine(-1.0, 1.0)(&mut cover);
        let c = cover.counts();
        assert_eq!((c[0], c[1], c[4]), (0, 0, 0), "{c:?}");
        assert!(c[2] > 0 && c[3] > 0, "{c:?}");
        // In the lower half only: the upper places are clear already.
        let kept = room_for_legend(
            &area,
            frame,
            0.0..1.0,
            y.clone(),
            (&labels, 14),
            sine(-1.0, 0.0),
        )
        .unwrap();
        assert_eq!(kept, y);
    }
}

//! PNG figures with plotters (bitmap backend, bundled DejaVu Sans: no system font needed).

use std::ops::Range;
use std::path::Path;
use std::sync::Once;

use anyhow::Result;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use shared::observe::Regime;

const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
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

/// A chart with linear `f64` axes on a bitmap.
pub(crate) type Chart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// The response figures' chart on `root`: `F_i/mg` from 0 to `ymax` over `Ω/ω` in `x`, the
/// title at `title_px`, axes labelled.
///
/// # Errors
/// Drawing errors.
fn force_chart<'a, 'b>(
    root: &'a DrawingArea<BitMapBackend<'b>, Shift>,
    title: &str,
    title_px: u32,
    x: Range<f64>,
    ymax: f64,
) -> Result<Chart<'a, 'b>> {
    let mut chart = ChartBuilder::on(root)
        .caption(title, (SANS, title_px))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(x, 0.0..ymax)?;
    chart
        .configure_mesh()
        .x_desc("Ω/ω")
        .y_desc("max impact force F_i/mg")
        .label_style((SANS, 15))
        .draw()?;
    Ok(chart)
}

/// Draws the series legend of `chart`: at `position` (plotters' default if `None`), on a
/// translucent white box with a black border, labels in [`SANS`] at `font_size` px.
///
/// # Errors
/// Drawing errors.
pub(crate) fn series_legend<'a, 'b: 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, CT>,
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

/// Colour of a regime in every figure: `1/1` red, `1/2` green (the thesis' Peterka colours),
/// `2/2` orange, other periodic blue, irregular black, no impact grey.
pub fn regime_color(r: Regime) -> RGBColor {
    match r {
        Regime::NoImpact => RGBColor(170, 170, 170),
        Regime::Irregular => RGBColor(0, 0, 0),
        Regime::Periodic { p: 1, q: 1 } => RGBColor(215, 25, 28),
        Regime::Periodic { p: 1, q: 2 } => RGBColor(26, 150, 65),
        Regime::Periodic { p: 2, q: 2 } => RGBColor(253, 174, 97),
        Regime::Periodic { .. } => RGBColor(43, 131, 186),
    }
}

/// Legend classes of regimes, in legend order.
pub const CLASSES: [&str; 6] = [
    "z = 1/1",
    "z = 1/2",
    "z = 2/2",
    "other p/q",
    "irregular",
    "no impact",
];

/// The legend class of a regime.
pub fn regime_class(r: Regime) -> &'static str {
    match r {
        Regime::Periodic { p: 1, q: 1 } => CLASSES[0],
        Regime::Periodic { p: 1, q: 2 } => CLASSES[1],
        Regime::Periodic { p: 2, q: 2 } => CLASSES[2],
        Regime::Periodic { .. } => CLASSES[3],
        Regime::Irregular => CLASSES[4],
        Regime::NoImpact => CLASSES[5],
    }
}

fn class_color(name: &str) -> RGBColor {
    let r = match name {
        "z = 1/1" => Regime::ONE_ONE,
        "z = 1/2" => Regime::Periodic { p: 1, q: 2 },
        "z = 2/2" => Regime::Periodic { p: 2, q: 2 },
        "other p/q" => Regime::Periodic { p: 3, q: 1 },
        "irregular" => Regime::Irregular,
        _ => Regime::NoImpact,
    };
    regime_color(r)
}

/// One point of a frequency-response figure.
#[derive(Debug, Clone, Copy)]
pub struct ResponsePoint {
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// `F_i/mg`.
    pub impact_force_mg: f64,
    /// Regime.
    pub regime: Regime,
}

/// What to mark on a response figure.
#[derive(Debug, Clone, Copy)]
pub struct Highlight {
    /// Chosen `Ω/ω` and its `F_i/mg`.
    pub chosen: (f64, f64),
    /// The `1/1` band holding it, `Ω/ω`.
    pub band: [f64; 2],
    /// The robustness window, `Ω/ω`.
    pub window: [f64; 2],
}

/// Max `F_i/mg` vs `Ω/ω`, dots coloured by regime (thesis Figs. 3.12–3.14).
///
/// # Errors
/// Drawing or file errors.
pub fn response(
    path: &Path,
    title: &str,
    pts: &[ResponsePoint],
    highlight: Option<Highlight>,
) -> Result<()> {
    ensure_font();
    let root = BitMapBackend::new(path, (1000, 620)).into_drawing_area();
    root.fill(&WHITE)?;
    let x0 = pts.first().map_or(0.0, |p| p.omega_ratio);
    let x1 = pts.last().map_or(1.0, |p| p.omega_ratio).max(x0 + 1e-6);
    let ymax = pts.iter().map(|p| p.impact_force_mg).fold(1.0, f64::max) * 1.08;
    let mut chart = force_chart(&root, title, 22, x0..x1, ymax)?;
    if let Some(h) = highlight {
        chart
            .draw_series([Rectangle::new(
                [(h.band[0], 0.0), (h.band[1], ymax)],
                RGBColor(215, 25, 28).mix(0.08).filled(),
            )])?
            .label("z = 1/1 band")
            .legend(|(x, y)| {
                Rectangle::new(
                    [(x, y - 5), (x + 14, y + 5)],
                    RGBColor(215, 25, 28).mix(0.2).filled(),
                )
            });
        chart
            .draw_series([Rectangle::new(
                [(h.window[0], 0.0), (h.window[1], ymax)],
                RGBColor(43, 131, 186).mix(0.15).filled(),
            )])?
            .label("±margin window")
            .legend(|(x, y)| {
                Rectangle::new(
                    [(x, y - 5), (x + 14, y + 5)],
                    RGBColor(43, 131, 186).mix(0.3).filled(),
                )
            });
    }
    chart.draw_series(LineSeries::new(
        pts.iter().map(|p| (p.omega_ratio, p.impact_force_mg)),
        RGBColor(120, 120, 120).stroke_width(1),
    ))?;
    let mut seen: Vec<&'static str> = Vec::new();
    for p in pts {
        let name = regime_class(p.regime);
        if !seen.contains(&name) {
            seen.push(name);
        }
    }
    seen.sort_by_key(|n| CLASSES.iter().position(|c| c == n));
    for name in seen {
        let c = class_color(name);
        chart
            .draw_series(
                pts.iter()
                    .filter(|p| regime_class(p.regime) == name)
                    .map(|p| Circle::new((p.omega_ratio, p.impact_force_mg), 3, c.filled())),
            )?
            .label(name)
            .legend(move |(x, y)| Circle::new((x + 7, y), 4, c.filled()));
    }
    if let Some(h) = highlight {
        chart
            .draw_series([Cross::new(h.chosen, 9, BLACK.stroke_width(3))])?
            .label(format!(
                "chosen: Ω/ω = {:.2}, F_i/mg = {:.1}",
                h.chosen.0, h.chosen.1
            ))
            .legend(|(x, y)| Cross::new((x + 7, y), 5, BLACK.stroke_width(2)));
    }
    series_legend(&mut chart, Some(SeriesLabelPosition::UpperLeft), 14)?;
    root.present()?;
    Ok(())
}

/// The nominal response with the 95 % range of `F_i/mg` over the draws of an identified law
/// (`select --uncertainty`), the chosen point and the robust recommendation.
///
/// # Errors
/// Drawing or file errors.
pub fn response_band(
    path: &Path,
    title: &str,
    spread: &crate::propagate::Propagation,
    nominal: &[ResponsePoint],
    chosen: &crate::selection::SelectReport,
) -> Result<()> {
    ensure_font();
    let root = BitMapBackend::new(path, (1000, 620)).into_drawing_area();
    root.fill(&WHITE)?;
    // The fitted law's 1/1 band holding the chosen point, widened by a fifth on each side.
    let [b0, b1] = chosen.band_omega_ratio;
    let pad = 0.2 * (b1 - b0);
    let (x0, x1) = (b0 - pad, b1 + pad);
    let inside = |r: f64| r >= x0 && r <= x1;
    let band: Vec<&crate::propagate::BandPoint> = spread
        .band
        .iter()
        .filter(|p| inside(p.omega_ratio))
        .collect();
    let nominal: Vec<&ResponsePoint> = nominal.iter().filter(|p| inside(p.omega_ratio)).collect();
    let ymax = band
        .iter()
        .map(|p| p.impact_force_mg.hi95)
        .chain(nominal.iter().map(|p| p.impact_force_mg))
        .fold(1.0, f64::max)
        * 1.15;
    let mut chart = force_chart(&root, title, 20, x0..x1, ymax)?;
    let blue = RGBColor(43, 131, 186);
    let area: Vec<(f64, f64)> = band
        .iter()
        .map(|p| (p.omega_ratio, p.impact_force_mg.hi95))
        .chain(
            band.iter()
                .rev()
                .map(|p| (p.omega_ratio, p.impact_force_mg.lo95)),
        )
        .collect();
    chart
        .draw_series([Polygon::new(area, blue.mix(0.3).filled())])?
        .label(format!("95 % range over {} draws", spread.draws))
        .legend(move |(x, y)| {
            Rectangle::new([(x, y - 5), (x + 14, y + 5)], blue.mix(0.3).filled())
        });
    chart
        .draw_series(LineSeries::new(
            band.iter()
                .map(|p| (p.omega_ratio, p.impact_force_mg.median)),
            blue.stroke_width(2),
        ))?
        .label("median over the draws")
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], blue.stroke_width(2)));
    let red = RGBColor(215, 25, 28);
    chart
        .draw_series(
            nominal
                .iter()
                .filter(|p| p.regime == Regime::ONE_ONE)
                .map(|p| Circle::new((p.omega_ratio, p.impact_force_mg), 2, red.filled())),
        )?
        .label("the fitted law, z = 1/1")
        .legend(move |(x, y)| Circle::new((x + 7, y), 3, red.filled()));
    chart
        .draw_series([Cross::new(
            (chosen.omega_ratio, chosen.impact_force_mg),
            9,
            BLACK.stroke_width(3),
        )])?
        .label(format!(
            "chosen: {:.3} Hz (draws: {:.3} – {:.3})",
            chosen.freq_hz, spread.freq_hz.lo95, spread.freq_hz.hi95
        ))
        .legend(|(x, y)| Cross::new((x + 7, y), 5, BLACK.stroke_width(2)));
    if let Some(r) = spread.robust {
        let green = RGBColor(26, 150, 65);
        chart
            .draw_series([TriangleMarker::new(
                (r.omega_ratio, r.worst_impact_force_mg),
                8,
                green.filled(),
            )])?
            .label(format!(
                "robust: {:.3} Hz, F_i/mg ≥ {:.1} in every draw",
                r.freq_hz, r.worst_impact_force_mg
            ))
            .legend(move |(x, y)| TriangleMarker::new((x + 7, y), 5, green.filled()));
    }
    series_legend(&mut chart, Some(SeriesLabelPosition::UpperLeft), 14)?;
    root.present()?;
    Ok(())
}

/// Samples of a time series for [`time_series`].
#[derive(Debug, Clone, Copy)]
pub struct TsPoint {
    /// Time, s.
    pub t_s: f64,
    /// Relative displacement `u`, mm.
    pub u_mm: f64,
    /// Relative velocity `u̇`, mm/s.
    pub du_mm_s: f64,
    /// Absolute hammer displacement `x`, mm.
    pub x_mm: f64,
    /// `F_i/mg`.
    pub force_mg: f64,
}

fn span(it: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = it.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-6);
    (lo - pad, hi + pad)
}

/// Three panels: `u` and `x` vs time; `F_i/mg` vs time; phase plane `(u, u̇)` with the Poincaré
/// points (thesis Figs. 3.16–3.23).
///
/// # Errors
/// Drawing or file errors.
pub fn time_series(
    path: &Path,
    title: &str,
    ts: &[TsPoint],
    strobes: &[(f64, f64)],
    gap_mm: f64,
) -> Result<()> {
    ensure_font();
    let root = BitMapBackend::new(path, (1000, 1100)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, (SANS, 22))?;
    let panels = root.split_evenly((3, 1));
    let (t0, t1) = (
        ts.first().map_or(0.0, |p| p.t_s),
        ts.last().map_or(1.0, |p| p.t_s),
    );
    let t1 = t1.max(t0 + 1e-9);

    let (ylo, yhi) = span(ts.iter().flat_map(|p| [p.u_mm, p.x_mm]).chain([gap_mm]));
    let mut c = ChartBuilder::on(&panels[0])
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(t0..t1, ylo..yhi)?;
    c.configure_mesh()
        .x_desc("t (s)")
        .y_desc("displacement (mm)")
        .label_style((SANS, 14))
        .draw()?;
    c.draw_series(LineSeries::new(ts.iter().map(|p| (p.t_s, p.u_mm)), BLUE))?
        .label("u (relative to cart)")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLUE));
    c.draw_series(LineSeries::new(
        ts.iter().map(|p| (p.t_s, p.x_mm)),
        RGBColor(220, 120, 0),
    ))?
    .label("x (absolute)")
    .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], RGBColor(220, 120, 0)));
    c.draw_series(LineSeries::new(
        [(t0, gap_mm), (t1, gap_mm)],
        BLACK.mix(0.5),
    ))?
    .label("impact surface (u = gap)")
    .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK.mix(0.5)));
    series_legend(&mut c, None, 13)?;

    let fmax = ts.iter().map(|p| p.force_mg).fold(1.0, f64::max) * 1.08;
    let mut c = ChartBuilder::on(&panels[1])
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(t0..t1, 0.0..fmax)?;
    c.configure_mesh()
        .x_desc("t (s)")
        .y_desc("impact force F_i/mg")
        .label_style((SANS, 14))
        .draw()?;
    c.draw_series(LineSeries::new(ts.iter().map(|p| (p.t_s, p.force_mg)), RED))?;

    let (ulo, uhi) = span(ts.iter().map(|p| p.u_mm));
    let (vlo, vhi) = span(ts.iter().map(|p| p.du_mm_s));
    let mut c = ChartBuilder::on(&panels[2])
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(ulo..uhi, vlo..vhi)?;
    c.configure_mesh()
        .x_desc("u (mm)")
        .y_desc("u̇ (mm/s)")
        .label_style((SANS, 14))
        .draw()?;
    c.draw_series(LineSeries::new(
        ts.iter().map(|p| (p.u_mm, p.du_mm_s)),
        BLUE.mix(0.6),
    ))?
    .label("phase plane")
    .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLUE));
    c.draw_series(
        strobes
            .iter()
            .map(|&(u, v)| Circle::new((u, v), 4, RED.filled())),
    )?
    .label("Poincaré section (t = kT)")
    .legend(|(x, y)| Circle::new((x + 7, y), 4, RED.filled()));
    series_legend(&mut c, None, 13)?;
    root.present()?;
    Ok(())
}

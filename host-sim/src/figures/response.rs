//! Frequency responses (thesis Figs. 3.12–3.14), the response under parameter uncertainty, and
//! time series with their phase plane.

use std::ops::Range;
use std::path::Path;

use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;
use shared::observe::Regime;

use shared::analysis::Sweep;
use shared::observe::PointResult;

use crate::config::Setup;

use super::{
    Backend, Chart, Frame, LegendCover, SANS, canvas, legend_place, level_line, line_key, panel,
    regime_classes, room_for_legend, series_legend, swatch_key, tick,
};

/// Font size of the response figure's legend, px.
const LEGEND_PX: u32 = 14;
/// Font size of the time series' legends, px.
const STACKED_LEGEND_PX: u32 = 13;
/// The legend's entries of a [`Highlight`]'s band and window.
const HIGHLIGHT_LABELS: [&str; 2] = ["z = 1/1 band", "±margin window"];

/// The time-series figure's three stacked panels.
const STACKED: Frame = Frame::new(10, 35, 60, 14);

/// What a simulated response's force axis shows: the observation window's largest peak.
pub const MAX_FORCE: &str = "max impact force F_i/mg";
/// What a measured sweep's force axis shows (`rig sweep`): the dwell's mean peak.
pub const MEAN_PEAK_FORCE: &str = "impact force F_i/mg (mean peak over the dwell)";

/// The response figures' chart on `root`: `F_i/mg` (`y_label`) from 0 to `ymax` over `Ω/ω` in
/// `x`, the title at `title_px`, axes labelled.
///
/// # Errors
/// Drawing errors.
fn force_chart<'a, 'b>(
    root: &'a DrawingArea<Backend<'b>, Shift>,
    title: &str,
    title_px: u32,
    x: Range<f64>,
    ymax: f64,
    y_label: &str,
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
        .y_desc(y_label)
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .label_style((SANS, 15))
        .draw()?;
    Ok(chart)
}

/// The points of a response figure (`results[i]` at `sweep.value(i)`).
pub fn points(sweep: &Sweep, results: &[PointResult]) -> Vec<ResponsePoint> {
    results
        .iter()
        .enumerate()
        .map(|(i, r)| ResponsePoint {
            omega_ratio: sweep.value(i),
            impact_force_mg: r.impact_force_mg,
            regime: r.regime,
        })
        .collect()
}

/// Title line of a response figure at gap `gap_mm`, mm.
pub fn title(setup: &Setup, gap_mm: f64) -> String {
    format!(
        "{} rig, gap {:.2} mm, {} law, {} — frequency response",
        setup.rig,
        gap_mm,
        setup.params.contact.kind(),
        setup.precision.name()
    )
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

/// `F_i/mg` vs `Ω/ω`, dots coloured by regime (thesis Figs. 3.12–3.14), the force axis labelled
/// `y_label` ([`MAX_FORCE`] for a simulation, [`MEAN_PEAK_FORCE`] for a measured sweep).
///
/// # Errors
/// Drawing or file errors.
pub fn response(
    path: &Path,
    title: &str,
    pts: &[ResponsePoint],
    highlight: Option<Highlight>,
    y_label: &str,
) -> Result<()> {
    let root = canvas(path, (1000, 620), None)?;
    let x0 = pts.first().map_or(0.0, |p| p.omega_ratio);
    let x1 = pts.last().map_or(1.0, |p| p.omega_ratio);
    // One frequency: centred on an axis 10 % of it wide (a span of none has no ticks).
    let (x0, x1) = if x1 - x0 > 1e-9 {
        (x0, x1)
    } else {
        let pad = 0.05 * x0.abs().max(0.1);
        (x0 - pad, x0 + pad)
    };
    let ymax = pts.iter().map(|p| p.impact_force_mg).fold(1.0, f64::max) * 1.08;
    let mut chart = force_chart(&root, title, 22, x0..x1, ymax, y_label)?;
    if let Some(h) = highlight {
        let red = RGBColor(215, 25, 28);
        let blue = RGBColor(43, 131, 186);
        for (x, color, fill, key, label) in [
            (h.band, red, 0.08, 0.2, HIGHLIGHT_LABELS[0]),
            (h.window, blue, 0.15, 0.3, HIGHLIGHT_LABELS[1]),
        ] {
            chart
                .draw_series([Rectangle::new(
                    [(x[0], 0.0), (x[1], ymax)],
                    color.mix(fill).filled(),
                )])?
                .label(label)
                .legend(swatch_key(color.mix(key).filled()));
        }
    }
    chart.draw_series(LineSeries::new(
        pts.iter().map(|p| (p.omega_ratio, p.impact_force_mg)),
        RGBColor(120, 120, 120).stroke_width(1),
    ))?;
    let classes = regime_classes(pts.iter().map(|p| p.regime));
    for (name, c) in &classes {
        let c = *c;
        chart
            .draw_series(
                pts.iter()
                    .filter(|p| super::regime_class(p.regime).1 == *name)
                    .map(|p| Circle::new((p.omega_ratio, p.impact_force_mg), 3, c.filled())),
            )?
            .label(name)
            .legend(move |(x, y)| Circle::new((x + 7, y), 4, c.filled()));
    }
    let chosen = highlight.map(|h| {
        (
            h.chosen,
            format!(
                "chosen: Ω/ω = {:.2}, F_i/mg = {:.1}",
                h.chosen.0, h.chosen.1
            ),
        )
    });
    if let Some((at, label)) = &chosen {
        chart
            .draw_series([Cross::new(*at, 9, BLACK.stroke_width(3))])?
            .label(label)
            .legend(|(x, y)| Cross::new((x + 7, y), 5, BLACK.stroke_width(2)));
    }
    // The legend where it covers the fewest points of the response (the upper
    // left where that covers none).
    let labels: Vec<String> = highlight
        .iter()
        .flat_map(|_| HIGHLIGHT_LABELS.map(String::from))
        .chain(classes.into_iter().map(|c| c.0))
        .chain(chosen.iter().map(|c| c.1.clone()))
        .collect();
    let xy = || pts.iter().map(|p| (p.omega_ratio, p.impact_force_mg));
    let place = legend_place(&chart, &labels, LEGEND_PX, |cover| {
        cover.line(xy());
        cover.dots(xy().chain(chosen.iter().map(|c| c.0)));
    })?;
    series_legend(&mut chart, Some(place), LEGEND_PX)?;
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
    let root = canvas(path, (1000, 620), None)?;
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
    let mut chart = force_chart(&root, title, 20, x0..x1, ymax, MAX_FORCE)?;
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
        .legend(swatch_key(blue.mix(0.3).filled()));
    chart
        .draw_series(LineSeries::new(
            band.iter()
                .map(|p| (p.omega_ratio, p.impact_force_mg.median)),
            blue.stroke_width(2),
        ))?
        .label("median over the draws")
        .legend(line_key(blue.stroke_width(2)));
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
    let root = canvas(path, (1000, 1100), Some((title, 22)))?;
    let panels = root.split_evenly((3, 1));
    let (t0, t1) = (
        ts.first().map_or(0.0, |p| p.t_s),
        ts.last().map_or(1.0, |p| p.t_s),
    );
    let t1 = t1.max(t0 + 1e-9);

    let (ylo, yhi) = span(ts.iter().flat_map(|p| [p.u_mm, p.x_mm]).chain([gap_mm]));
    let labels = [
        "u (relative to cart)",
        "x (absolute)",
        "impact surface (u = gap)",
    ]
    .map(String::from);
    let u = || ts.iter().map(|p| (p.t_s, p.u_mm));
    let x = || ts.iter().map(|p| (p.t_s, p.x_mm));
    let curves = |cover: &mut LegendCover| {
        cover.line(u());
        cover.line(x());
        cover.line([(t0, gap_mm), (t1, gap_mm)]);
    };
    // Where the curves fill the panel, room above them for the legend.
    let y = room_for_legend(
        &panels[0],
        STACKED,
        t0..t1,
        ylo..yhi,
        (&labels, STACKED_LEGEND_PX),
        curves,
    )?;
    let mut c = panel(
        &panels[0],
        STACKED,
        t0..t1,
        y,
        ("t (s)", "displacement (mm)"),
    )?;
    c.draw_series(LineSeries::new(u(), BLUE))?
        .label(&labels[0])
        .legend(line_key(BLUE));
    c.draw_series(LineSeries::new(x(), RGBColor(220, 120, 0)))?
        .label(&labels[1])
        .legend(line_key(RGBColor(220, 120, 0)));
    level_line(&mut c, (t0, t1), gap_mm, BLACK.mix(0.5), &labels[2])?;
    // Each legend where it covers the least of its panel's curves.
    let place = legend_place(&c, &labels, STACKED_LEGEND_PX, curves)?;
    series_legend(&mut c, Some(place), STACKED_LEGEND_PX)?;

    let fmax = ts.iter().map(|p| p.force_mg).fold(1.0, f64::max) * 1.08;
    let mut c = panel(
        &panels[1],
        STACKED,
        t0..t1,
        0.0..fmax,
        ("t (s)", "impact force F_i/mg"),
    )?;
    c.draw_series(LineSeries::new(ts.iter().map(|p| (p.t_s, p.force_mg)), RED))?;

    let (ulo, uhi) = span(ts.iter().map(|p| p.u_mm));
    let (vlo, vhi) = span(ts.iter().map(|p| p.du_mm_s));
    let labels = ["phase plane", "Poincaré section (t = kT)"].map(String::from);
    let phase = || ts.iter().map(|p| (p.u_mm, p.du_mm_s));
    let cloud = |cover: &mut LegendCover| {
        cover.line(phase());
        cover.dots(strobes.iter().copied());
    };
    let v = room_for_legend(
        &panels[2],
        STACKED,
        ulo..uhi,
        vlo..vhi,
        (&labels, STACKED_LEGEND_PX),
        cloud,
    )?;
    let mut c = panel(&panels[2], STACKED, ulo..uhi, v, ("u (mm)", "du/dt (mm/s)"))?;
    c.draw_series(LineSeries::new(phase(), BLUE.mix(0.6)))?
        .label(&labels[0])
        .legend(line_key(BLUE));
    c.draw_series(
        strobes
            .iter()
            .map(|&(u, v)| Circle::new((u, v), 4, RED.filled())),
    )?
    .label(&labels[1])
    .legend(|(x, y)| Circle::new((x + 7, y), 4, RED.filled()));
    let place = legend_place(&c, &labels, STACKED_LEGEND_PX, cloud)?;
    series_legend(&mut c, Some(place), STACKED_LEGEND_PX)?;
    root.present()?;
    Ok(())
}

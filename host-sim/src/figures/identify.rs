//! Figures of the identification: a drop test and its fitted simulations (thesis Figs.
//! 3.9–3.10), and the comparison of a measured record with the simulation.

use std::path::Path;

use anyhow::Result;
use plotters::prelude::*;
use shared::model::ContactLawKind;

use super::{
    Backend, Chart, Frame, LegendCover, SANS, canvas, labelled_line, legend_place, line_key, panel,
    room_for_legend, series_legend, tick,
};
use crate::comparison::{ResponseOverlay, TsOverlay};
use crate::identify::cost::SimDrop;
use crate::identify::data::DropData;
use crate::identify::fit::Fit;

/// The time-series comparison's panels.
const TRACE: Frame = Frame::new(12, 40, 60, 14);
/// Font size of the drop figure's legends, px.
const LEGEND_PX: u32 = 14;
/// Font size of the time-series comparison's legends, px.
const TRACE_LEGEND_PX: u32 = 13;

/// Colour of a contact law's curves.
pub fn law_color(name: &str) -> RGBColor {
    match name.parse::<ContactLawKind>() {
        Ok(ContactLawKind::SpringDashpot) => RGBColor(215, 25, 28),
        Ok(ContactLawKind::Hertz) => RGBColor(43, 131, 186),
        Ok(ContactLawKind::HuntCrossley) => RGBColor(26, 150, 65),
        Ok(ContactLawKind::LankaraniNikravesh) => RGBColor(230, 120, 0),
        Err(_) => RGBColor(120, 60, 160),
    }
}

/// The measured drop tests (offset removed) with the simulated drop of each fit, one band per
/// test (`tests`: caption and data; `fits[k].1.traces[i]` is law `k`'s simulation of test `i`):
/// the whole record on top (each simulation shifted so that its first impact's centroid falls
/// on the measured one), and up to four impacts below, each simulated impact shifted onto the
/// measured impact's centroid (as in the profile error).
///
/// # Errors
/// Drawing or file errors.
pub fn drop_fit(
    path: &Path,
    title: &str,
    tests: &[(String, &DropData)],
    fits: &[(String, &Fit)],
) -> Result<()> {
    let bands = tests.len().max(1);
    let root = canvas(path, (1300, 30 + 870 * bands as u32), Some((title, 22)))?;
    let areas = root.split_evenly((bands, 1));
    for (i, ((caption, data), area)) in tests.iter().zip(areas.iter()).enumerate() {
        let sims: Vec<(String, &SimDrop)> = fits
            .iter()
            .filter_map(|(name, fit)| fit.traces.get(i).map(|t| (name.clone(), &t.sim)))
            .collect();
        let area = if tests.len() > 1 {
            area.titled(caption, (SANS, 18))?
        } else {
            area.clone()
        };
        drop_panel(&area, data, &sims)?;
    }
    root.present()?;
    Ok(())
}

/// One drop test and its simulations (see [`drop_fit`]).
fn drop_panel(
    area: &DrawingArea<Backend<'_>, plotters::coord::Shift>,
    data: &DropData,
    fits: &[(String, &SimDrop)],
) -> Result<()> {
    let (top, bottom) = area.split_vertically(430);
    let t = &data.t_s;
    let f = &data.force_n;
    let m0 = data.impacts[0].centroid_s;
    let fmax = f.iter().copied().fold(0.0, f64::max).max(
        fits.iter()
            .flat_map(|(_, fit)| fit.impacts.iter().map(|i| i.peak_n))
            .fold(0.0, f64::max),
    ) * 1.1;
    let fmin = f.iter().copied().fold(0.0, f64::min).min(0.0) * 1.1;
    let (t0, t1) = (t[0], t[t.len() - 1]);
    let mut c = panel(
        &top,
        Frame::new(12, 40, 60, 15),
        t0..t1,
        fmin..fmax,
        ("t (s)", "impact force F_i (N)"),
    )?;
    // Decimate the measured trace to at most ~4000 points per pixel column group (min/max).
    let cols = 1200usize;
    let per = (t.len() / cols).max(1);
    let mut env = Vec::with_capacity(2 * cols + 2);
    for chunk in (0..t.len()).collect::<Vec<_>>().chunks(per) {
        let (lo, hi) = chunk
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, &i| {
                (a.0.min(f[i]), a.1.max(f[i]))
            });
        env.push((t[chunk[0]], lo));
        env.push((t[chunk[0]], hi));
    }
    let mut labels = vec!["measured (offset removed)".to_string()];
    c.draw_series(LineSeries::new(env.iter().copied(), RGBColor(90, 90, 90)))?
        .label(&labels[0])
        .legend(line_key(RGBColor(90, 90, 90)));
    let mut simulated: Vec<Vec<(f64, f64)>> = Vec::new();
    for (name, fit) in fits {
        let Some(s0) = fit.impacts.first() else {
            continue;
        };
        let shift = m0 - s0.centroid_s;
        let col = law_color(name);
        let line: Vec<(f64, f64)> = fit
            .samples
            .iter()
            .map(|&(ts, fs)| (ts + shift, fs))
            .filter(|p| p.0 >= t0 && p.0 <= t1)
            .collect();
        labels.push(format!("simulated, {name}"));
        c.draw_series(LineSeries::new(line.iter().copied(), col.stroke_width(1)))?
            .label(&labels[labels.len() - 1])
            .legend(line_key(col.stroke_width(2)));
        simulated.push(line);
    }
    // The legend where it covers the least of the traces (between the impacts, as a rule).
    let place = legend_place(&c, &labels, LEGEND_PX, |cover| {
        cover.line(env);
        for line in simulated {
            cover.line(line);
        }
    })?;
    series_legend(&mut c, Some(place), LEGEND_PX)?;

    let shown: Vec<_> = data.impacts.iter().take(4).collect();
    let panels = bottom.split_evenly((1, shown.len().max(1)));
    for (j, (imp, area)) in shown.iter().zip(panels.iter()).enumerate() {
        // The impact's window, widened to hold every fit's simulated pulse whole (a weak
        // impact's window ends where its tail sinks into the noise), with the samples there.
        let (mut lo_ms, mut hi_ms) = (
            (t[imp.window.0] - imp.centroid_s) * 1e3,
            (t[imp.window.1] - imp.centroid_s) * 1e3,
        );
        for s in fits.iter().filter_map(|(_, fit)| fit.impacts.get(j)) {
            if let (Some(first), Some(last)) = (s.profile.first(), s.profile.last()) {
                let pad = 0.1 * (last.0 - first.0) * 1e3;
                lo_ms = lo_ms.min((first.0 - s.centroid_s) * 1e3 - pad);
                hi_ms = hi_ms.max((last.0 - s.centroid_s) * 1e3 + pad);
            }
        }
        let a = t.partition_point(|&ti| (ti - imp.centroid_s) * 1e3 < lo_ms);
        let b = t
            .partition_point(|&ti| (ti - imp.centroid_s) * 1e3 <= hi_ms)
            .saturating_sub(1)
            .max(a);
        let ymax = fits
            .iter()
            .filter_map(|(_, fit)| fit.impacts.get(j).map(|s| s.peak_n))
            .fold(imp.peak_n, f64::max)
            .max(1e-9)
            * 1.15;
        let mut c = ChartBuilder::on(area)
            .caption(format!("impact {}", j + 1), (SANS, 16))
            .margin(8)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(lo_ms..hi_ms, (-0.1 * ymax)..ymax)?;
        c.configure_mesh()
            .x_desc("t − t_impact (ms)")
            .y_desc(if j == 0 { "F_i (N)" } else { "" })
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .label_style((SANS, 13))
            .x_labels(5)
            .draw()?;
        c.draw_series((a..=b).map(|i| {
            Circle::new(
                ((t[i] - imp.centroid_s) * 1e3, f[i]),
                2,
                RGBColor(60, 60, 60).filled(),
            )
        }))?;
        for (name, fit) in fits {
            let Some(s) = fit.impacts.get(j) else {
                continue;
            };
            let col = law_color(name);
            let mut pts: Vec<(f64, f64)> = Vec::new();
            let n = 400;
            for k in 0..=n {
                let x = lo_ms + (hi_ms - lo_ms) * k as f64 / n as f64;
                pts.push((x, s.force_at(x * 1e-3 + s.centroid_s)));
            }
            c.draw_series(LineSeries::new(pts, col.stroke_width(2)))?;
        }
    }
    Ok(())
}

/// Measured max `F_i/mg` (black crosses) over the simulated response (grey line, dots by
/// regime), with the error summary under the title (thesis Figs. 3.12–3.14).
///
/// # Errors
/// Drawing or file errors.
pub fn response_compare(
    path: &Path,
    title: &str,
    summary: &str,
    o: &ResponseOverlay,
) -> Result<()> {
    let root = canvas(path, (1100, 680), Some((title, 21)))?;
    let (head, body) = root.split_vertically(28);
    head.draw_text(summary, &(SANS, 14).into_text_style(&head), (12, 4))?;
    let x0 = o.sim.first().map_or(0.0, |p| p.0);
    let x1 = o.sim.last().map_or(1.0, |p| p.0).max(x0 + 1e-6);
    let ymax = o
        .sim
        .iter()
        .map(|p| p.1)
        .chain(o.measured.iter().map(|p| p.1))
        .fold(1.0, f64::max)
        * 1.08;
    let classes = super::regime_classes(o.sim.iter().map(|p| p.2));
    let labels: Vec<String> = std::iter::once("simulated".to_string())
        .chain(classes.iter().map(|(name, _)| format!("simulated, {name}")))
        .chain(["measured".to_string()])
        .collect();
    let sim = || o.sim.iter().map(|p| (p.0, p.1));
    let data = |cover: &mut LegendCover| {
        cover.line(sim());
        cover.dots(sim().chain(o.measured.iter().copied()));
    };
    let frame = Frame::new(12, 45, 60, 15);
    // The legend where it covers the least of the data, with room above the data if it
    // would cover some everywhere.
    let y = room_for_legend(&body, frame, x0..x1, 0.0..ymax, (&labels, 14), data)?;
    let mut c = panel(&body, frame, x0..x1, y, ("Ω/ω", "max impact force F_i/mg"))?;
    c.draw_series(LineSeries::new(sim(), RGBColor(150, 150, 150)))?
        .label(&labels[0])
        .legend(line_key(RGBColor(150, 150, 150)));
    for (name, col) in classes {
        c.draw_series(
            o.sim
                .iter()
                .filter(|p| super::regime_class(p.2).1 == name)
                .map(|p| Circle::new((p.0, p.1), 2, col.filled())),
        )?
        .label(format!("simulated, {name}"))
        .legend(move |(x, y)| Circle::new((x + 7, y), 4, col.filled()));
    }
    measured_crosses(&mut c, &o.measured, "measured")?;
    let place = legend_place(&c, &labels, 14, data)?;
    series_legend(&mut c, Some(place), 14)?;
    root.present()?;
    Ok(())
}

/// Draws the measured points `points` on `chart` as black crosses (the comparison figures'
/// marker for the experiment), with the legend entry `label`.
///
/// # Errors
/// Drawing errors.
fn measured_crosses(chart: &mut Chart<'_, '_>, points: &[(f64, f64)], label: &str) -> Result<()> {
    chart
        .draw_series(
            points
                .iter()
                .map(|&p| Cross::new(p, 6, BLACK.stroke_width(2))),
        )?
        .label(label)
        .legend(|(x, y)| Cross::new((x + 7, y), 5, BLACK.stroke_width(2)));
    Ok(())
}

/// Absolute displacement vs time, and the phase plane `(x, ẋ)` with the Poincaré points:
/// measured in black, simulated in blue/red (thesis Figs. 3.16–3.23).
///
/// # Errors
/// Drawing or file errors.
pub fn time_series_compare(path: &Path, title: &str, summary: &str, o: &TsOverlay) -> Result<()> {
    let root = canvas(path, (1100, 1000), Some((title, 21)))?;
    let (head, body) = root.split_vertically(28);
    head.draw_text(summary, &(SANS, 14).into_text_style(&head), (12, 4))?;
    let (top, bottom) = body.split_vertically(430);
    let span = |it: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = it.fold((f64::INFINITY, f64::NEG_INFINITY), |a, v| {
            (a.0.min(v), a.1.max(v))
        });
        if lo.is_finite() {
            let pad = ((hi - lo) * 0.06).max(1e-6);
            (lo - pad, hi + pad)
        } else {
            (0.0, 1.0)
        }
    };
    let t1 = o.measured.last().map_or(1.0, |p| p.0).max(1e-9);
    let (xlo, xhi) = span(&mut o.measured.iter().chain(&o.sim).map(|p| p.1));
    let mut c = panel(
        &top,
        TRACE,
        0.0..t1,
        xlo..xhi,
        ("t (s)", "absolute displacement x (mm)"),
    )?;
    let labels = ["measured", "simulated"];
    let measured = || o.measured.iter().map(|p| (p.0, p.1));
    let sim = || o.sim.iter().map(|p| (p.0, p.1));
    labelled_line(&mut c, measured(), BLACK, labels[0])?;
    labelled_line(&mut c, sim(), BLUE.stroke_width(2), labels[1])?;
    // Each legend where it covers the least of its panel's curves.
    let place = legend_place(&c, &labels.map(String::from), TRACE_LEGEND_PX, |cover| {
        cover.line(measured());
        cover.line(sim());
    })?;
    series_legend(&mut c, Some(place), TRACE_LEGEND_PX)?;
    let (vlo, vhi) = span(&mut o.measured.iter().chain(&o.sim).map(|p| p.2));
    let mut c = panel(&bottom, TRACE, xlo..xhi, vlo..vhi, ("x (mm)", "ẋ (mm/s)"))?;
    let labels = [
        "measured phase plane",
        "simulated phase plane",
        "measured Poincaré (t = kT)",
        "simulated Poincaré (t = kT)",
    ];
    let measured = || o.measured.iter().map(|p| (p.1, p.2));
    let sim = || o.sim.iter().map(|p| (p.1, p.2));
    labelled_line(&mut c, measured(), BLACK.mix(0.5), labels[0])?;
    c.draw_series(LineSeries::new(sim(), BLUE.mix(0.7)))?
        .label(labels[1])
        .legend(line_key(BLUE));
    measured_crosses(&mut c, &o.strobe_measured, labels[2])?;
    c.draw_series(
        o.strobe_sim
            .iter()
            .map(|&p| Circle::new(p, 4, RED.filled())),
    )?
    .label(labels[3])
    .legend(|(x, y)| Circle::new((x + 7, y), 4, RED.filled()));
    let place = legend_place(&c, &labels.map(String::from), TRACE_LEGEND_PX, |cover| {
        cover.line(measured());
        cover.line(sim());
        cover.dots(o.strobe_measured.iter().chain(&o.strobe_sim).copied());
    })?;
    series_legend(&mut c, Some(place), TRACE_LEGEND_PX)?;
    root.present()?;
    Ok(())
}

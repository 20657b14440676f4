//! The `hil` figure: drive frequency, impact force (measured and true) and controller state
//! against rig time.

use std::path::Path;

use anyhow::Result;
use plotters::prelude::*;
use shared::console::Token;
use shared::control::{State, Target};

use super::{
    Frame, LegendCover, SANS, canvas, legend_place, level_line, line_key, panel, room_for_legend,
    series_legend, tick,
};
use crate::virtual_rig::CycleRow;

/// The state panel's level of the controller state named `token` (its place in `State::ALL`;
/// 0 for a name that is none).
fn level(token: &str) -> f64 {
    State::ALL
        .iter()
        .position(|s| s.token() == token)
        .unwrap_or(0) as f64
}

/// The stacked panels (wide y labels: the state names).
const PANEL: Frame = Frame::new(10, 35, 80, 14);

/// Three panels over time: frequency (with the model's target and band where `model` is
/// given), per-cycle peak forces (measured by the controller, true from the plant where the
/// rows have it, the force limit), and the state.
///
/// # Errors
/// Drawing or file errors.
pub fn draw(
    path: &Path,
    title: &str,
    rows: &[CycleRow],
    model: Option<&Target>,
    force_limit_n: f64,
) -> Result<()> {
    let root = canvas(path, (1000, 1000), Some((title, 22)))?;
    let panels = root.split_evenly((3, 1));
    // From the first logged cycle's whole second (a rig log starts mid-session).
    let t0 = rows.first().map_or(0.0, |r| r.t_s.floor());
    let t1 = rows.last().map_or(1.0, |r| r.t_s).max(t0 + 1e-3);

    // Frequency.
    // The drive idles at the window's lowest frequency, and a fault or a stop ends at zero
    // amplitude at the last one: show the frequency while the shaker is driven.
    let driving = |r: &&CycleRow| r.state != "idle" && r.amp_cmd_mm > 0.0;
    let fvals = rows
        .iter()
        .filter(driving)
        .map(|r| r.freq_hz)
        .chain(model.into_iter().flat_map(|p| {
            [
                f64::from(p.target_hz),
                f64::from(p.band_hz[0]),
                f64::from(p.band_hz[1]),
            ]
        }));
    let (flo, fhi) = fvals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    let (flo, fhi) = if flo.is_finite() {
        let pad = 0.08 * (fhi - flo).max(0.5);
        (flo - pad, fhi + pad)
    } else {
        (0.0, 10.0)
    };
    // Each legend where it covers the least of its panel's data, with room above the data
    // where it would cover some everywhere.
    let mut labels = vec!["drive frequency (per cycle)".to_string()];
    if model.is_some() {
        labels.extend(["model target", "model 1/1 band edges"].map(String::from));
    }
    let freq = |cover: &mut LegendCover| {
        cover.dots(rows.iter().filter(driving).map(|r| (r.t_s, r.freq_hz)));
        if let Some(p) = model {
            for v in [p.target_hz, p.band_hz[0], p.band_hz[1]] {
                cover.line([(t0, f64::from(v)), (t1, f64::from(v))]);
            }
        }
    };
    let y = room_for_legend(&panels[0], PANEL, t0..t1, flo..fhi, (&labels, 13), freq)?;
    let mut c = panel(
        &panels[0],
        PANEL,
        t0..t1,
        y,
        ("t (s)", "drive frequency (Hz)"),
    )?;
    c.draw_series(
        rows.iter()
            .filter(driving)
            .map(|r| Circle::new((r.t_s, r.freq_hz), 2, BLUE.filled())),
    )?
    .label(&labels[0])
    .legend(|(x, y)| Circle::new((x + 8, y), 2, BLUE.filled()));
    if let Some(p) = model {
        let grey = BLACK.mix(0.5);
        let target = f64::from(p.target_hz);
        c.draw_series(LineSeries::new(
            [(t0, target), (t1, target)],
            RED.stroke_width(1),
        ))?
        .label("model target")
        .legend(line_key(RED));
        for edge in p.band_hz {
            let e = f64::from(edge);
            c.draw_series(LineSeries::new([(t0, e), (t1, e)], grey))?;
        }
        c.draw_series(std::iter::empty::<PathElement<(f64, f64)>>())?
            .label("model 1/1 band edges")
            .legend(line_key(grey));
    }
    let place = legend_place(&c, &labels, 13, freq)?;
    series_legend(&mut c, Some(place), 13)?;

    // Forces.
    let fmax = rows
        .iter()
        .flat_map(|r| [r.measured_peak_n, r.true_peak_n])
        .flatten()
        .fold(force_limit_n, f64::max)
        * 1.08;
    let has_true = rows.iter().any(|r| r.true_peak_n.is_some());
    let labels: Vec<String> = has_true
        .then_some("true (plant)")
        .into_iter()
        .chain(["measured (controller)", "force limit"])
        .map(String::from)
        .collect();
    let forces = |cover: &mut LegendCover| {
        cover.dots(rows.iter().flat_map(|r| {
            [r.true_peak_n, r.measured_peak_n]
                .into_iter()
                .flatten()
                .map(|f| (r.t_s, f))
        }));
        cover.line([(t0, force_limit_n), (t1, force_limit_n)]);
    };
    let y = room_for_legend(&panels[1], PANEL, t0..t1, 0.0..fmax, (&labels, 13), forces)?;
    let mut c = panel(
        &panels[1],
        PANEL,
        t0..t1,
        y,
        ("t (s)", "peak impact force per cycle (N)"),
    )?;
    let orange = RGBColor(230, 120, 0);
    if has_true {
        c.draw_series(rows.iter().filter_map(|r| {
            r.true_peak_n
                .map(|f| Circle::new((r.t_s, f), 3, orange.filled()))
        }))?
        .label("true (plant)")
        .legend(move |(x, y)| Circle::new((x + 8, y), 3, orange.filled()));
    }
    c.draw_series(
        rows.iter()
            .filter_map(|r| r.measured_peak_n.map(|f| Cross::new((r.t_s, f), 4, BLUE))),
    )?
    .label("measured (controller)")
    .legend(|(x, y)| Cross::new((x + 8, y), 4, BLUE));
    level_line(&mut c, (t0, t1), force_limit_n, RED.mix(0.6), "force limit")?;
    let place = legend_place(&c, &labels, 13, forces)?;
    series_legend(&mut c, Some(place), 13)?;

    // State.
    let top = (State::ALL.len() - 1) as f64;
    let mut c = ChartBuilder::on(&panels[2])
        .margin(PANEL.margin)
        .x_label_area_size(PANEL.x_area)
        .y_label_area_size(PANEL.y_area)
        .build_cartesian_2d(t0..t1, -0.5..top + 0.5)?;
    c.configure_mesh()
        .x_desc("t (s)")
        .x_label_formatter(&tick)
        .y_desc("controller state")
        .y_labels(State::ALL.len())
        .y_label_formatter(&|y: &f64| {
            let i = y.round();
            if (y - i).abs() < 1e-6 && (0.0..=top).contains(&i) {
                State::ALL[i as usize].token().to_string()
            } else {
                String::new()
            }
        })
        .label_style((SANS, PANEL.font))
        .draw()?;
    let mut steps = Vec::with_capacity(rows.len() * 2);
    let mut prev: Option<f64> = None;
    for r in rows {
        let y = level(r.state);
        if let Some(p) = prev {
            steps.push((r.t_s, p));
        }
        steps.push((r.t_s, y));
        prev = Some(y);
    }
    c.draw_series(LineSeries::new(steps, BLACK.stroke_width(2)))?;
    root.present()?;
    Ok(())
}

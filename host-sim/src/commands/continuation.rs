//! `host-sim continue`: a branch of periodic orbits continued in `Ω/ω` or the gap from the
//! orbit at a point, its bifurcations located (the computation: [`crate::orbits`]).

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use shared::analysis::response::OMEGA_RATIO_RANGE;
use shared::error::{check_count, check_range};
use shared::orbit::{Orbit, Param};

use super::orbit::PointArgs;
use crate::figures::orbits::{Dots, branches as branch_figure};
use crate::orbits::{
    self, Background, BranchOut, BranchSpec, Crossings, Direction, mm, param_value,
};
use crate::output::{Outputs, write_csv};

/// The continuation parameter on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ParamArg {
    /// `Ω/ω`.
    OmegaRatio,
    /// The gap, mm.
    GapMm,
}

/// Arguments of `continue`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct ContinueArgs {
    /// The starting point (the orbit found there starts the branch).
    #[command(flatten)]
    pub point: PointArgs,
    /// The parameter continued.
    #[arg(long, value_enum, default_value = "omega-ratio")]
    pub param: ParamArg,
    /// Its range, LO:HI (Ω/ω within 0.05..=50, default the whole range; the gap in mm within
    /// the rig's range, 0..=50 and for the wire pendulum at most l/4 (18.75 mm for the thesis'
    /// wires), default 0:10). The branch ends where it leaves the range.
    #[arg(long)]
    pub range: Option<String>,
    /// More starting points, in the parameter's units (Ω/ω, or the gap in mm), comma-separated:
    /// the orbit the protocol settles on from the same start at each begins more branches
    /// (e.g. the non-impacting branch beside an impacting one).
    #[arg(long, value_delimiter = ',')]
    pub also_at: Vec<f64>,
    /// Which ways to follow the branch from its start.
    #[arg(long, value_enum, default_value = "both")]
    pub direction: Direction,
    /// Switch onto the doubled orbit at each period doubling, this many times in cascade
    /// (0..=6).
    #[arg(long, default_value_t = 0)]
    pub follow_doublings: u32,
    /// CSV: one row per orbit of each branch, then its located bifurcations: branch, parent,
    /// direction, omega_ratio, freq_hz, gap_mm, u_mm, du_mm_s, regime, impact_force_mg,
    /// mu1_re, mu1_im, mu2_re, mu2_im, max_abs_mu, stable, stability (stable, neutral: no
    /// impact on an undamped suspension, or unstable), event (empty for an orbit; fold,
    /// period-doubling, neimark-sacker or grazing).
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: Option<PathBuf>,
    /// PNG or SVG: the branches (stable solid, neutral dotted, unstable dashed, coloured by
    /// regime; bifurcations marked) over a brute-force bifurcation diagram of the same range.
    #[arg(long, value_parser = crate::output::figure_target)]
    pub plot: Option<PathBuf>,
    /// The brute-force diagram behind the figure.
    #[arg(long, value_enum, default_value = "sweeps")]
    pub background: Background,
    /// Values of the brute-force diagram across the branches' span (10..=5000).
    #[arg(long, default_value_t = 300)]
    pub background_points: usize,
    /// Print one JSON object (the branches, their points and events) instead of the report.
    #[arg(long)]
    pub json: bool,
}

/// Parses `LO:HI` for `flag` within `[min, max]`.
fn parse_range(flag: &str, text: &str, min: f64, max: f64) -> Result<[f64; 2]> {
    let Some((a, b)) = text.split_once(':') else {
        bail!("{flag} {text}: expected LO:HI, e.g. 1.0:3.0");
    };
    let lo: f64 = a
        .trim()
        .parse()
        .with_context(|| format!("{flag} {text}: LO is not a number"))?;
    let hi: f64 = b
        .trim()
        .parse()
        .with_context(|| format!("{flag} {text}: HI is not a number"))?;
    check_range("lo", lo, min, max).with_context(|| flag.to_string())?;
    check_range("hi", hi, min, max).with_context(|| flag.to_string())?;
    if lo >= hi {
        bail!("{flag} {text}: LO must be below HI");
    }
    Ok([lo, hi])
}

/// The text report of the branches.
pub fn describe(param: Param, branches: &[BranchOut]) -> String {
    let unit = |v: f64| match param {
        Param::OmegaRatio => format!("Ω/ω {v:.8}"),
        Param::GapM => format!("gap {v:.6} mm"),
    };
    let mut s = String::new();
    for b in branches {
        let (first, last) = match (b.points.first(), b.points.last()) {
            (Some(f), Some(l)) => (f, l),
            _ => continue,
        };
        let (from, to) = (
            param_value(param, &first.orbit),
            param_value(param, &last.orbit),
        );
        // Where the branch turned (a fold, a kink), its span is wider than its ends'.
        let (lo, hi) = b
            .points
            .iter()
            .fold((from.min(to), from.max(to)), |(lo, hi), p| {
                let v = param_value(param, &p.orbit);
                (lo.min(v), hi.max(v))
            });
        s += &format!(
            "branch {} ({}{}), period {}: {} orbits from {} to {}{}\n",
            b.id,
            b.direction,
            b.parent
                .map(|p| format!(" from branch {p}"))
                .unwrap_or_default(),
            b.q,
            b.points.len(),
            unit(from),
            unit(to),
            if lo < from.min(to) || hi > from.max(to) {
                format!(", over {} – {}", unit(lo), unit(hi))
            } else {
                String::new()
            }
        );
        for e in &b.events {
            let crit = if e.critical[1] == 0.0 {
                format!("μ = {:+.6}", e.critical[0])
            } else {
                format!(
                    "μ = {:+.6} ± {:.6}i (|μ| = {:.6})",
                    e.critical[0],
                    e.critical[1].abs(),
                    e.critical[0].hypot(e.critical[1])
                )
            };
            let beyond = if e.kind == "grazing" {
                let per = if b.q == 1 {
                    "period".to_string()
                } else {
                    format!("{} periods", b.q)
                };
                let n = e.impacts_beyond;
                // Where Newton stalled before it, the grazing is extrapolated from the last
                // orbit reached, whose multiplier the line gives.
                let extrapolated = if let Some(x) = e.extrapolation {
                    format!(
                        " (extrapolated {:.4} from the branch's last orbit, at {}, whose \
                         multiplier this is; error ≲ {:.4}{})",
                        x.distance,
                        unit(param_value(param, &e.orbit)),
                        x.error_bound,
                        if x.placed {
                            String::new()
                        } else {
                            format!(": not placed to {}", orbits::PLACED_TO)
                        }
                    )
                } else {
                    String::new()
                };
                format!(
                    ", {n} impact{} per {per} beyond{extrapolated}",
                    if n == 1 { "" } else { "s" }
                )
            } else {
                String::new()
            };
            s += &format!(
                "  {} at {}{}: {} orbit, {}{}\n",
                e.kind,
                unit(e.value),
                match param {
                    Param::OmegaRatio => {
                        format!(
                            " ({:.4} Hz)",
                            e.orbit.freq_hz * e.value / e.orbit.omega_ratio
                        )
                    }
                    Param::GapM => String::new(),
                },
                e.orbit.regime,
                crit,
                beyond
            );
            if e.at_jump {
                s += "    across a jump of the discretised map: the doubling test changes sign where \
                      the monodromy jumps and keeps its new sign (the multiplier passes −1 by the \
                      jump; not followed by --follow-doublings)\n";
            }
            if let Some(c) = e.crossings.filter(Crossings::smeared) {
                let (what, mm) = match param {
                    Param::OmegaRatio => ("Ω/ω", ""),
                    Param::GapM => ("gap", " mm"),
                };
                s += &format!("    {}\n", c.describe(what, mm));
            }
        }
        if !b.bridges.is_empty() {
            let shown: Vec<String> = b
                .bridges
                .iter()
                .take(3)
                .map(|[a, z]| format!("{} → {}", unit(*a), unit(*z)))
                .collect();
            s += &format!(
                "  stepped over {} jump{} of the discretised map where Newton could not follow \
                 the branch ({}{}; no fold or doubling test changes sign across them)\n",
                b.bridges.len(),
                if b.bridges.len() == 1 { "" } else { "s" },
                shown.join(", "),
                if b.bridges.len() > 3 { ", …" } else { "" },
            );
        }
        if let Some(v) = b.turned_back {
            s += &format!(
                "  turned back at {} without a fold (no multiplier through +1 there: a kink of \
                 the discretised map)\n",
                unit(v)
            );
        }
        s += &format!("  ended at {}\n", b.end);
    }
    s
}

/// Runs `continue`.
///
/// # Errors
/// Bad input, no orbit at the start, I/O failure or Ctrl-C; nothing is half-written.
pub fn run(a: &ContinueArgs) -> Result<()> {
    a.point
        .rig
        .check_outputs(&[("--out", a.out.as_deref()), ("--plot", a.plot.as_deref())])?;
    crate::interrupt::install();
    let (setup, at, start) = a.point.resolve()?;
    check_count("follow_doublings", a.follow_doublings, 0, 6).context("--follow-doublings")?;
    check_count(
        "background_points",
        u32::try_from(a.background_points).unwrap_or(u32::MAX),
        10,
        5000,
    )
    .context("--background-points")?;
    let (param, range) = match a.param {
        ParamArg::OmegaRatio => (
            Param::OmegaRatio,
            match &a.range {
                Some(t) => parse_range("--range", t, OMEGA_RATIO_RANGE.0, OMEGA_RATIO_RANGE.1)?,
                None => [OMEGA_RATIO_RANGE.0, OMEGA_RATIO_RANGE.1],
            },
        ),
        ParamArg::GapMm => {
            let mm = match &a.range {
                Some(t) => parse_range("--range", t, 0.0, setup.max_gap_mm())?,
                None => [0.0, setup.max_gap_mm().min(10.0)],
            };
            (Param::GapM, [mm[0] * 1e-3, mm[1] * 1e-3])
        }
    };
    let value = at.get(param);
    if value < range[0] || value > range[1] {
        bail!(
            "--range: the start ({}) lies outside {}..{}",
            param_value_shown(param, value),
            param_value_shown(param, range[0]),
            param_value_shown(param, range[1])
        );
    }
    let spec = BranchSpec {
        param,
        range,
        direction: a.direction,
        follow_doublings: a.follow_doublings,
    };
    let shown = |v: f64| orbits::report_value(param, v);
    let mut starts = vec![at];
    for &v in &a.also_at {
        let si = match param {
            Param::OmegaRatio => v,
            Param::GapM => v * 1e-3,
        };
        if !(si >= range[0] && si <= range[1]) {
            bail!(
                "--also-at {v}: outside the range {}..{}",
                shown(range[0]),
                shown(range[1])
            );
        }
        starts.push(at.with(param, si));
    }
    let (protocol, branches) = crate::with_precision!(setup.precision, T => {
        let mut regimes = Vec::new();
        let mut all: Vec<BranchOut> = Vec::new();
        for p in &starts {
            let (r, o): (_, Orbit<T>) = orbits::find::<T>(p, start, a.point.q)?;
            if let (_, Some(w)) = orbits::slope_check(&o)? {
                eprintln!("{w} (the branch's start)");
            }
            regimes.push(format!("{} at {}", r.regime, param_value_shown(param, p.get(param))));
            let base = all.len();
            for mut b in orbits::branches(&o, &spec)? {
                b.id += base;
                b.parent = b.parent.map(|q| q + base);
                all.push(b);
            }
        }
        (regimes.join("; "), all)
    });
    let mut outputs = Outputs::new();
    if let Some(p) = &a.out {
        let tmp = outputs.reserve(p)?;
        write_csv(&tmp, orbits::rows(param, &branches))?;
    }
    if let Some(p) = &a.plot {
        let values = background_values(param, &branches, a.background_points, setup.max_gap_mm());
        let runs = crate::with_precision!(setup.precision, T => {
            orbits::background::<T>(&at, param, &values, a.background)?
        });
        let dots: Vec<Dots> = runs
            .into_iter()
            .map(|r| Dots {
                label: match r.branch {
                    "up" => "brute force, sweep up".to_string(),
                    "down" => "brute force, sweep down".to_string(),
                    _ => "brute force, from rest".to_string(),
                },
                color: match r.branch {
                    "down" => plotters::style::RGBColor(120, 170, 230),
                    _ => plotters::style::RGBColor(150, 150, 150),
                },
                strobes: r.strobes,
                impacts: r.impacts,
            })
            .collect();
        let tmp = outputs.reserve(p)?;
        let title = format!(
            "{} rig, {} law, {} — periodic orbits continued in {}{}",
            setup.rig,
            setup.params.contact.kind(),
            setup.precision.name(),
            match param {
                Param::OmegaRatio => "Ω/ω".to_string(),
                Param::GapM => "the gap".to_string(),
            },
            match param {
                Param::OmegaRatio => format!(", gap {} mm", mm(at.gap_m)),
                Param::GapM => format!(", Ω/ω {}", at.omega_ratio),
            }
        );
        let (x_label, surface) = match param {
            Param::OmegaRatio => ("Ω/ω".to_string(), Some(mm(at.gap_m))),
            Param::GapM => ("gap (mm)".to_string(), None),
        };
        branch_figure(&tmp, &title, param, &x_label, surface, &branches, &dots)?;
    }
    outputs.commit()?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&branches)?);
    } else {
        println!(
            "{} rig, {}: the protocol settled on {}",
            setup.rig,
            setup.precision.name(),
            protocol
        );
        print!("{}", describe(param, &branches));
        let unplaced = branches
            .iter()
            .flat_map(|b| &b.events)
            .any(|e| e.extrapolation.is_some_and(|x| !x.placed));
        if unplaced && setup.precision == crate::precision::Precision::F32 {
            println!(
                "note: a grazing extrapolated in f32 past where Newton stalled is not placed to \
                 {}; `--precision f64` follows the branch closer to it",
                orbits::PLACED_TO
            );
        }
    }
    Ok(())
}

fn param_value_shown(param: Param, v: f64) -> String {
    let v = orbits::report_value(param, v);
    match param {
        Param::OmegaRatio => format!("Ω/ω {v}"),
        Param::GapM => format!("gap {v} mm"),
    }
}

/// `n` values of `param` evenly over the span of `branches` (gap in m), padded 4 % (the gap
/// within the rig's `max_gap_mm`).
fn background_values(param: Param, branches: &[BranchOut], n: usize, max_gap_mm: f64) -> Vec<f64> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for b in branches {
        for p in &b.points {
            let v = param_value(param, &p.orbit);
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if !lo.is_finite() {
        return Vec::new();
    }
    let pad = (hi - lo).max(1e-3) * 0.04;
    let (lo, hi) = (lo - pad, hi + pad);
    let (lo, hi) = match param {
        Param::OmegaRatio => (lo.max(OMEGA_RATIO_RANGE.0), hi.min(OMEGA_RATIO_RANGE.1)),
        Param::GapM => (lo.max(0.0) * 1e-3, hi.min(max_gap_mm) * 1e-3),
    };
    (0..n)
        .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
        .collect()
}

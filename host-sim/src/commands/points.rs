//! `host-sim points`: batch evaluation of `(gap_mm, omega_ratio)` rows in parallel.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use serde::{Deserialize, Serialize};
use shared::analysis::response::OMEGA_RATIO_RANGE;
use shared::error::check_range;
use shared::observe::PointResult;
use shared::orbit::{Label, LabelSettings};

use crate::config::RigOpts;
use crate::config::Setup;
use crate::output::{distinct_files, given, write_csv, write_whole};
use crate::response::LabelCells;
use crate::runner::{OperatingPoint, evaluate_all, evaluate_all_labelled};

/// Arguments of `points`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct PointsArgs {
    /// Rig and numerics.
    #[command(flatten)]
    pub rig: RigOpts,
    /// Input CSV with header columns `gap_mm` and `omega_ratio` (other columns are ignored).
    #[arg(long)]
    pub input: PathBuf,
    /// Output CSV: gap_mm, omega_ratio, freq_hz, regime, impacts, impact_force_mg,
    /// lyapunov_per_period, lyapunov_uncertainty, window_regime, extra_periods (the last four
    /// empty without --lyapunov).
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: PathBuf,
    /// Refine each point's label by its largest Lyapunov exponent, as `response` does by
    /// default: `chaotic` where positive beyond its uncertainty; where negative but no period
    /// showed, the run goes on (up to 2,000 periods) until a period q ≤ 64 shows
    /// (`window_regime` then gives the protocol window's label).
    #[arg(long)]
    pub lyapunov: bool,
}

#[derive(Debug, Deserialize)]
struct InRow {
    gap_mm: f64,
    omega_ratio: f64,
}

/// One output row.
#[derive(Debug, Serialize)]
pub struct OutRow {
    /// Gap, mm.
    pub gap_mm: f64,
    /// `Ω/ω`.
    pub omega_ratio: f64,
    /// Hz.
    pub freq_hz: f64,
    /// Regime.
    pub regime: String,
    /// Impacts in the observation window.
    pub impacts: u32,
    /// Max `F_i/mg` over the window.
    pub impact_force_mg: f64,
    /// Largest Lyapunov exponent, per period (`--lyapunov`).
    pub lyapunov_per_period: Option<f64>,
    /// Its uncertainty, per period.
    pub lyapunov_uncertainty: Option<f64>,
    /// The protocol window's regime, where the exponent changed the label.
    pub window_regime: Option<String>,
    /// Periods run after the window to find a period.
    pub extra_periods: Option<u32>,
}

/// Reads and validates the input points (gaps within `setup`'s rig range).
///
/// # Errors
/// Unreadable file, missing columns, unparsable or out-of-range values (row number named).
pub fn read_points(setup: &Setup, path: &PathBuf) -> Result<Vec<(f64, f64)>> {
    let mut rdr = csv::Reader::from_path(path)
        .with_context(|| format!("cannot read --input {}", path.display()))?;
    // A header without the columns (another separator, other names) is told as such, not as
    // a missing field on the first row.
    let header = rdr
        .headers()
        .with_context(|| format!("cannot read --input {}", path.display()))?
        .clone();
    let missing: Vec<&str> = ["gap_mm", "omega_ratio"]
        .into_iter()
        .filter(|c| !header.iter().any(|h| h == *c))
        .collect();
    if !header.is_empty() && !missing.is_empty() {
        bail!(
            "{}: the header `{}` lacks the column{} {} (a comma-separated file with the header \
             `gap_mm,omega_ratio`)",
            path.display(),
            header.iter().collect::<Vec<_>>().join(","),
            if missing.len() == 1 { "" } else { "s" },
            missing.join(", ")
        );
    }
    let mut out = Vec::new();
    for (i, rec) in rdr.deserialize::<InRow>().enumerate() {
        let line = i + 2;
        let r = rec.with_context(|| {
            format!(
                "{} line {line}: expected numeric columns gap_mm, omega_ratio",
                path.display()
            )
        })?;
        setup
            .gap_m("gap_mm", r.gap_mm)
            .with_context(|| format!("{} line {line}", path.display()))?;
        check_range(
            "omega_ratio",
            r.omega_ratio,
            OMEGA_RATIO_RANGE.0,
            OMEGA_RATIO_RANGE.1,
        )
        .with_context(|| format!("{} line {line}", path.display()))?;
        out.push((r.gap_mm, r.omega_ratio));
    }
    if out.is_empty() {
        bail!(
            "{}: no points (need a header `gap_mm,omega_ratio` and at least one row)",
            path.display()
        );
    }
    Ok(out)
}

/// Runs `points`.
///
/// # Errors
/// Bad input or I/O failure; the output appears only when every point succeeded.
pub fn run(a: &PointsArgs) -> Result<()> {
    distinct_files(
        &given(&[
            ("--input", Some(a.input.as_path())),
            ("--config", a.rig.config.as_deref()),
        ]),
        &[("--out", a.out.as_path())],
    )?;
    let setup = Setup::from_opts(&a.rig)?;
    let pts = read_points(&setup, &a.input)?;
    let ops: Vec<OperatingPoint> = pts
        .iter()
        .map(|&(g, r)| OperatingPoint {
            gap_m: g * 1e-3,
            omega_ratio: r,
        })
        .collect();
    let (results, labels): (Vec<PointResult>, Option<Vec<Label>>) = if a.lyapunov {
        let (r, l) = evaluate_all_labelled(&setup, &ops, "points", &LabelSettings::default())?
            .into_iter()
            .map(|(r, l)| {
                (
                    PointResult {
                        regime: l.regime,
                        ..r
                    },
                    l,
                )
            })
            .unzip();
        (r, Some(l))
    } else {
        (evaluate_all(&setup, &ops, "points")?, None)
    };
    let rows = pts
        .iter()
        .zip(&results)
        .enumerate()
        .map(|(i, (&(g, r), res))| {
            let LabelCells {
                lyapunov_per_period,
                lyapunov_uncertainty,
                window_regime,
                extra_periods,
            } = LabelCells::of(labels.as_ref().and_then(|l| l.get(i)));
            OutRow {
                gap_mm: g,
                omega_ratio: r,
                freq_hz: setup.params.freq_hz_from_ratio(r),
                regime: res.regime.to_string(),
                impacts: res.impacts,
                impact_force_mg: res.impact_force_mg,
                lyapunov_per_period,
                lyapunov_uncertainty,
                window_regime,
                extra_periods,
            }
        });
    write_whole(&a.out, |tmp| write_csv(tmp, rows))?;
    let n = crate::output::count(pts.len() as u64, "point");
    eprintln!("points: {n} → {}", a.out.display());
    Ok(())
}

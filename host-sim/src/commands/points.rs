//! `host-sim points`: batch evaluation of `(gap_mm, omega_ratio)` rows in parallel.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use serde::Serialize;
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
    /// Input table with a header naming the columns `gap_mm` and `omega_ratio` (other columns
    /// ignored): cells separated by `,`, `;`, a tab or spaces; `#` and `%` lines are comments.
    #[arg(long)]
    pub input: PathBuf,
    /// Output CSV: gap_mm, omega_ratio, freq_hz, regime, impacts, impact_force_mg,
    /// lyapunov_per_period, lyapunov_uncertainty, window_regime, extra_periods,
    /// chaotic_transient_periods (the last five empty without --lyapunov).
    #[arg(long, value_parser = crate::output::out_target)]
    pub out: PathBuf,
    /// Refine each point's label by its largest Lyapunov exponent, as `response` does by
    /// default (docs/analysis.md): where it is negative over 64 periods after the protocol,
    /// the run goes on (up to 2,000 periods) until a period q ≤ 64 shows; otherwise a
    /// confirmation run of up to 2,048 periods labels the point by what it settles on, or
    /// `chaotic` where the exponent stays positive over its 32 windows, else `irregular`
    /// (`window_regime` then gives the protocol window's label).
    #[arg(long)]
    pub lyapunov: bool,
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
    /// Periods run after the exponent's first window (extended or confirmation run).
    pub extra_periods: Option<u32>,
    /// The chaotic transient's length after the protocol, periods, where the motion settled
    /// after a positive first window.
    pub chaotic_transient_periods: Option<u32>,
}

/// Reads and validates the input points (gaps within `setup`'s rig range): a lab file as
/// [`crate::trace::LabTable`] reads it (`,`, `;`, tab or spaces between the cells, `#`/`%`
/// comment lines, spaces round the cells), with a header naming `gap_mm` and `omega_ratio`
/// (other columns are ignored).
///
/// # Errors
/// Unreadable file, missing columns, unparsable or out-of-range values (line named).
pub fn read_points(setup: &Setup, path: &PathBuf) -> Result<Vec<(f64, f64)>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read --input {}", path.display()))?;
    let table = crate::trace::LabTable::parse(&text)
        .with_context(|| format!("--input {}", path.display()))?;
    let need = "a header `gap_mm,omega_ratio` and at least one row";
    let Some(header) = &table.header else {
        bail!(
            "--input {}: no header line: the file needs {need}",
            path.display()
        );
    };
    // A header without the columns (another separator, other names) is told as such, not as
    // a missing field on the first row.
    let missing: Vec<&str> = ["gap_mm", "omega_ratio"]
        .into_iter()
        .filter(|c| table.find(c).is_none())
        .collect();
    if !missing.is_empty() {
        bail!(
            "--input {}: the header `{}` lacks the column{} {} (a header `gap_mm,omega_ratio`, \
             the cells separated by `,`, `;`, a tab or spaces)",
            path.display(),
            header.join(","),
            if missing.len() == 1 { "" } else { "s" },
            missing.join(", ")
        );
    }
    let (gap_col, ratio_col) = (
        table.column("gap_mm", "gap")?,
        table.column("omega_ratio", "Ω/ω")?,
    );
    let mut out = Vec::with_capacity(table.rows().len());
    for row in table.rows() {
        let at = || format!("--input {}: line {}", path.display(), row.line);
        let gap_mm = row
            .number(gap_col, "gap, mm")
            .with_context(|| format!("--input {}", path.display()))?;
        let omega_ratio = row
            .number(ratio_col, "Ω/ω")
            .with_context(|| format!("--input {}", path.display()))?;
        setup.gap_m("gap_mm", gap_mm).with_context(at)?;
        check_range(
            "omega_ratio",
            omega_ratio,
            OMEGA_RATIO_RANGE.0,
            OMEGA_RATIO_RANGE.1,
        )
        .with_context(at)?;
        out.push((gap_mm, omega_ratio));
    }
    if out.is_empty() {
        bail!("--input {}: no points (need {need})", path.display());
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
    super::warn_coarse_steps(
        &setup,
        pts.iter().map(|p| p.1).fold(f64::INFINITY, f64::min),
    );
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
                chaotic_transient_periods,
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
                chaotic_transient_periods,
            }
        });
    write_whole(&a.out, |tmp| write_csv(tmp, rows))?;
    let n = crate::output::count(pts.len() as u64, "point");
    eprintln!("points: {n} → {}", a.out.display());
    Ok(())
}

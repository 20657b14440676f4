//! How two Peterka maps of the same grid differ, point by point: the regimes that change, how
//! many of them at points the first map found settled, the commonest changes, and the `1/1`
//! forces that move. Made for the stopping-rule check of docs/performance.md (the canonical
//! 200-period transient against a shorter one):
//!
//! ```sh
//! printf '[settings.protocol]\nmax_transient_periods = 100\n' > /tmp/t100.toml
//! target/release/host-sim peterka --rig wires --gap-mm 0:2.94:0.49 --freq-hz 1:7.11:0.01 --out /tmp/t200.csv
//! target/release/host-sim peterka --rig wires --gap-mm 0:2.94:0.49 --freq-hz 1:7.11:0.01 \
//!   --config /tmp/t100.toml --out /tmp/t100.csv
//! cargo run --release -p host-sim --example regime_changes -- /tmp/t200.csv /tmp/t100.csv
//! ```
//!
//! Both files are `host-sim peterka --out` CSVs (or merged shards) of the same points; a file
//! that cannot be read, a malformed row, or two grids with different points is an error naming
//! the file and the row.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result, bail};
use host_sim::grid::peterka::PeterkaRow;
use shared::observe::Regime;

fn read(path: &Path) -> Result<Vec<PeterkaRow>> {
    let mut reader =
        csv::Reader::from_path(path).with_context(|| format!("{}: cannot open", path.display()))?;
    let mut rows = Vec::new();
    for (i, row) in reader.deserialize().enumerate() {
        // Line 1 is the header.
        rows.push(row.with_context(|| format!("{}: line {}", path.display(), i + 2))?);
    }
    if rows.is_empty() {
        bail!("{}: no grid points", path.display());
    }
    Ok(rows)
}

fn run(a: &Path, b: &Path) -> Result<()> {
    let (ra, rb) = (read(a)?, read(b)?);
    if ra.len() != rb.len() {
        bail!(
            "{} has {} points, {} has {}: not the same grid",
            a.display(),
            ra.len(),
            b.display(),
            rb.len()
        );
    }
    let (mut changed, mut changed_settled) = (0, 0);
    let (mut one_one, mut one_one_lost, mut force_moved) = (0, 0, 0);
    let mut kinds: BTreeMap<(Regime, Regime), usize> = BTreeMap::new();
    for (i, (x, y)) in ra.iter().zip(&rb).enumerate() {
        if x.index != y.index || x.gap_mm != y.gap_mm || x.freq_hz != y.freq_hz {
            bail!(
                "row {}: point {} ({} mm, {} Hz) against point {} ({} mm, {} Hz): not the same grid",
                i + 1,
                x.index,
                x.gap_mm,
                x.freq_hz,
                y.index,
                y.gap_mm,
                y.freq_hz
            );
        }
        if x.regime != y.regime {
            changed += 1;
            changed_settled += usize::from(x.settled);
            *kinds.entry((x.regime, y.regime)).or_default() += 1;
        }
        if x.regime == Regime::ONE_ONE {
            one_one += 1;
            if y.regime != x.regime {
                one_one_lost += 1;
            } else if y.impact_force_mg != x.impact_force_mg {
                force_moved += 1;
            }
        }
    }
    let n = ra.len();
    let unsettled = ra.iter().filter(|r| !r.settled).count();
    println!("{n} points; {unsettled} not settled in {}", a.display());
    println!(
        "regimes changed: {changed} ({:.1} %), {changed_settled} of them at points settled in {}",
        100.0 * changed as f64 / n as f64,
        a.display()
    );
    let mut kinds: Vec<_> = kinds.into_iter().collect();
    kinds.sort_by(|p, q| q.1.cmp(&p.1).then(p.0.cmp(&q.0)));
    for ((from, to), count) in kinds.iter().take(12) {
        println!("  {from} → {to}: {count}");
    }
    println!(
        "1/1 points of {}: {one_one}; {one_one_lost} not 1/1 in {}, {force_moved} with another force",
        a.display(),
        b.display()
    );
    Ok(())
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [a, b] = args.as_slice() else {
        eprintln!(
            "usage: regime_changes FIRST.csv SECOND.csv (two `host-sim peterka --out` files)"
        );
        std::process::exit(2);
    };
    if let Err(e) = run(Path::new(a), Path::new(b)) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

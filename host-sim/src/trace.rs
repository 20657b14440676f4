//! Measured traces from lab files: a time column (or a sample rate) and one value column.
//!
//! What is tolerated, because real acquisition software writes it:
//! - comment/metadata lines starting with `#` or `%` anywhere (a metadata line
//!   `# sample_rate_hz = 50000` or `# sample_rate_hz: 50000` gives the rate);
//! - a header line naming the columns (recognised because a cell is not a number), or none
//!   (columns are then addressed by number, 1-based);
//! - `,`, `;` or tab as the delimiter, or runs of spaces;
//! - the time as a column (`--time-col`, in `--time-unit`), as a fixed rate
//!   (`--sample-rate-hz`), or as a `sample_rate_hz` column (constant down the file).
//!
//! What is rejected, with the line number: a value that is not a number or not finite, a
//! line with too few cells or with more than the first line (empty trailing cells aside: a
//! decimal comma in a `,`-separated file splits every number in two), a time that does not increase, a sample-rate column that changes;
//! a time column whose median step is not the period of the rate the file states (a
//! `sample_rate_hz` column or metadata line; within [`RATE_TOLERANCE`], naming the
//! `--time-unit` that would explain the difference); and files with fewer than
//! [`MIN_SAMPLES`] samples.
//!
//! [`LabTable`] is the one reader of such files (traces here, measured responses in
//! [`crate::comparison`]).

use std::path::Path;

use anyhow::{Context, Result, bail, ensure};
use clap::ValueEnum;

/// Fewest samples a trace must have.
pub const MIN_SAMPLES: usize = 16;

/// Unit of a time column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TimeUnit {
    /// Seconds.
    S,
    /// Milliseconds.
    Ms,
    /// Microseconds.
    Us,
}

impl TimeUnit {
    /// Factor to seconds.
    pub fn to_s(self) -> f64 {
        match self {
            TimeUnit::S => 1.0,
            TimeUnit::Ms => 1e-3,
            TimeUnit::Us => 1e-6,
        }
    }

    /// The unit as `--time-unit` names it.
    pub fn name(self) -> &'static str {
        match self {
            TimeUnit::S => "s",
            TimeUnit::Ms => "ms",
            TimeUnit::Us => "us",
        }
    }
}

/// Unit of a force column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ForceUnit {
    /// Newtons.
    #[value(name = "N")]
    N,
    /// Kilonewtons.
    #[value(name = "kN")]
    KN,
    /// Pounds-force.
    #[value(name = "lbf")]
    Lbf,
}

impl ForceUnit {
    /// Factor to newtons.
    pub fn to_n(self) -> f64 {
        match self {
            ForceUnit::N => 1.0,
            ForceUnit::KN => 1e3,
            ForceUnit::Lbf => 4.448_221_615_260_5,
        }
    }
}

/// Unit of a displacement or acceleration column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MotionUnit {
    /// Metres.
    M,
    /// Millimetres.
    Mm,
    /// Micrometres.
    Um,
    /// Metres per second squared.
    #[value(name = "m/s2")]
    MS2,
    /// Standard gravities (9.80665 m/s²).
    G,
}

impl MotionUnit {
    /// Factor to SI (m or m/s²).
    pub fn to_si(self) -> f64 {
        match self {
            MotionUnit::M | MotionUnit::MS2 => 1.0,
            MotionUnit::Mm => 1e-3,
            MotionUnit::Um => 1e-6,
            MotionUnit::G => 9.806_65,
        }
    }
    /// Whether this is an acceleration unit.
    pub fn is_acceleration(self) -> bool {
        matches!(self, MotionUnit::MS2 | MotionUnit::G)
    }
}

/// How to read one trace.
#[derive(Debug, Clone)]
pub struct TraceFormat {
    /// Time column: a header name or a 1-based column number.
    pub time_col: String,
    /// Value column: a header name or a 1-based column number; `None`: column 2, or the only
    /// column of a file of one.
    pub value_col: Option<String>,
    /// Unit of the time column → s.
    pub time_to_s: f64,
    /// Unit of the value column → SI.
    pub value_to_si: f64,
    /// Fixed sample rate, Hz (overrides any time column).
    pub sample_rate_hz: Option<f64>,
}

/// A trace in SI units: strictly increasing times and one value per time.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// Sample times, s (strictly increasing).
    pub t_s: Vec<f64>,
    /// Values (N, m or m/s²).
    pub value: Vec<f64>,
}

/// The delimiter of a lab file, detected once from its first data line: the first of `,`,
/// `;` and tab that the line contains, else runs of spaces.
fn detect_delimiter(line: &str) -> Option<u8> {
    [b',', b';', b'\t']
        .into_iter()
        .find(|&d| line.as_bytes().contains(&d))
}

/// A lab file as a table of text cells (module docs: what is tolerated). Comment and metadata
/// lines (`#`, `%`) and blank lines are set apart; the first data line is the header if one of
/// its cells is not a number. Read by `csv::ReaderBuilder` with the detected delimiter.
#[derive(Debug, Clone)]
pub struct LabTable {
    /// Column names, if the file has a header line.
    pub header: Option<Vec<String>>,
    /// The comment and metadata lines, trimmed, in file order.
    pub comments: Vec<String>,
    /// Cells of the first data line (or of the header).
    pub width: usize,
    /// Data rows with their 1-based line number in the file.
    rows: Vec<(usize, csv::StringRecord)>,
}

/// One data row of a [`LabTable`].
#[derive(Debug, Clone, Copy)]
pub struct LabRow<'a> {
    /// 1-based line number in the file.
    pub line: usize,
    record: &'a csv::StringRecord,
    table: &'a LabTable,
}

impl LabTable {
    /// Reads the lab file at `path`.
    ///
    /// # Errors
    /// Unreadable file, or as [`LabTable::parse`].
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        Self::parse(&text).with_context(|| format!("{}", path.display()))
    }

    /// Parses the text of a lab file.
    ///
    /// # Errors
    /// A line the CSV reader rejects (unbalanced quotes), with its line number.
    pub fn parse(text: &str) -> Result<Self> {
        let mut comments = Vec::new();
        let mut data = String::new();
        let mut lines = Vec::new();
        let mut delimiter: Option<Option<u8>> = None;
        for (i, raw) in text.lines().enumerate() {
            let line = raw.trim().trim_start_matches('\u{feff}');
            if line.is_empty() {
                continue;
            }
            if line.starts_with('#') || line.starts_with('%') {
                comments.push(line.to_string());
                continue;
            }
            match *delimiter.get_or_insert_with(|| detect_delimiter(line)) {
                Some(_) => data.push_str(line),
                None => data.push_str(&line.split_whitespace().collect::<Vec<_>>().join(" ")),
            }
            data.push('\n');
            lines.push(i + 1);
        }
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .trim(csv::Trim::All)
            .delimiter(delimiter.flatten().unwrap_or(b' '))
            .from_reader(data.as_bytes());
        let line_of = |p: Option<&csv::Position>| {
            p.and_then(|p| usize::try_from(p.line()).ok())
                .and_then(|l| lines.get(l.wrapping_sub(1)).copied())
                .unwrap_or(0)
        };
        let mut rows = Vec::with_capacity(lines.len());
        for rec in reader.records() {
            let rec = rec.map_err(|e| anyhow::anyhow!("line {}: {e}", line_of(e.position())))?;
            rows.push((line_of(rec.position()), rec));
        }
        let mut header = None;
        let width = rows.first().map_or(0, |r| r.1.len());
        for (line, rec) in &rows {
            if rec.iter().skip(width).any(|c| !c.is_empty()) {
                let hint = if delimiter.flatten() == Some(b',') {
                    " (a decimal comma? in a `,`-separated file it splits each number in two: \
                     separate the columns with `;` or a tab)"
                } else {
                    ""
                };
                bail!(
                    "line {line}: {} cells, more than the first line's {width}{hint}",
                    rec.len()
                );
            }
        }
        if let Some((_, first)) = rows.first()
            && first.iter().any(|c| c.parse::<f64>().is_err())
        {
            header = Some(first.iter().map(str::to_string).collect());
            rows.remove(0);
        }
        Ok(LabTable {
            header,
            comments,
            width,
            rows,
        })
    }

    /// The data rows, in file order.
    pub fn rows(&self) -> impl ExactSizeIterator<Item = LabRow<'_>> {
        self.rows.iter().map(|(line, record)| LabRow {
            line: *line,
            record,
            table: self,
        })
    }

    /// Index of the header column named `name` (ASCII case ignored).
    pub fn find(&self, name: &str) -> Option<usize> {
        self.header
            .as_ref()?
            .iter()
            .position(|c| c.eq_ignore_ascii_case(name))
    }

    /// Index of column `spec`: a header name, or a 1-based number; `what` names the column in
    /// messages.
    ///
    /// # Errors
    /// No such column (the header's names listed), or a name given to a file without header.
    pub fn column(&self, spec: &str, what: &str) -> Result<usize> {
        if let Some(i) = self.find(spec) {
            return Ok(i);
        }
        if let Ok(n) = spec.parse::<usize>() {
            ensure!(
                (1..=self.width).contains(&n),
                "{what} column {n} does not exist: the file has {}{}; give it by name or number",
                crate::output::count(self.width as u64, "column"),
                self.header
                    .as_ref()
                    .map_or(String::new(), |h| format!(" ({})", h.join(", ")))
            );
            return Ok(n - 1);
        }
        match &self.header {
            Some(h) => bail!(
                "no {what} column `{spec}` in the header ({}); give it by name or number",
                h.join(", ")
            ),
            None => {
                bail!("the file has no header line: give the {what} column by number (1-based)")
            }
        }
    }

    /// The name of column `c` (its header name, or its 1-based number).
    pub fn name(&self, c: usize) -> String {
        self.header
            .as_ref()
            .and_then(|h| h.get(c).cloned())
            .unwrap_or_else(|| format!("{}", c + 1))
    }
}

impl LabRow<'_> {
    /// Checks that the row has cells up to column `c`.
    ///
    /// # Errors
    /// A short line, with its line number.
    pub fn reaches(&self, c: usize) -> Result<()> {
        ensure!(
            self.record.len() > c,
            "line {}: {} cells, expected {}",
            self.line,
            self.record.len(),
            self.table.width
        );
        Ok(())
    }

    /// Cell `c` as a finite number; `what` names the quantity in messages.
    ///
    /// # Errors
    /// A short line, or a cell that is not a number or not finite (line and column named).
    pub fn number(&self, c: usize, what: &str) -> Result<f64> {
        self.reaches(c)?;
        let cell = &self.record[c];
        let col = self.table.name(c);
        let line = self.line;
        let v: f64 = cell.parse().map_err(|_| {
            anyhow::anyhow!("line {line}, column `{col}` ({what}): `{cell}` is not a number")
        })?;
        ensure!(
            v.is_finite(),
            "line {line}, column `{col}` ({what}): `{cell}` is not finite"
        );
        Ok(v)
    }
}

fn metadata_rate(line: &str) -> Option<f64> {
    let body = line.trim_start_matches(['#', '%']).trim();
    let (key, value) = body.split_once(['=', ':'])?;
    let key = key.trim().to_ascii_lowercase();
    if key == "sample_rate_hz" || key == "sample rate (hz)" || key == "sample_rate" {
        value.split_whitespace().next()?.parse().ok()
    } else {
        None
    }
}

/// Reads a trace from `path` as `format` says; `what` names the value in messages
/// (`force`, `displacement`).
///
/// # Errors
/// Unreadable file, missing columns, malformed lines (with their line number), non-increasing
/// time, fewer than [`MIN_SAMPLES`] samples, or a missing time base.
pub fn read_trace(path: &Path, format: &TraceFormat, what: &str) -> Result<Trace> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the trace {}", path.display()))?;
    parse_trace(&text, format, what).with_context(|| format!("trace {}", path.display()))
}

/// [`read_trace`] on the file's text.
///
/// # Errors
/// As [`read_trace`].
pub fn parse_trace(text: &str, format: &TraceFormat, what: &str) -> Result<Trace> {
    trace_from_table(&LabTable::parse(text)?, format, what)
}

/// The trace in a lab file already read as a table ([`read_trace`]).
///
/// # Errors
/// As [`read_trace`].
pub fn trace_from_table(table: &LabTable, format: &TraceFormat, what: &str) -> Result<Trace> {
    if let Some(r) = format.sample_rate_hz {
        shared::error::check_range("sample_rate_hz", r, 1e-3, 1e9).context("--sample-rate-hz")?;
    }
    let meta_rate = table.comments.iter().rev().find_map(|l| metadata_rate(l));
    let value_col = match &format.value_col {
        Some(spec) => table.column(spec, what)?,
        None => usize::from(table.width >= 2),
    };
    let rate_col = table.find("sample_rate_hz");
    let time_col = if format.sample_rate_hz.is_some() {
        None
    } else {
        match table.column(&format.time_col, "time") {
            Ok(c) => Some(c),
            Err(e) => {
                if rate_col.is_none() && meta_rate.is_none() {
                    return Err(e.context(
                        "no time base: give a time column, --sample-rate-hz, a \
                         `sample_rate_hz` column or a `# sample_rate_hz = …` line",
                    ));
                }
                None
            }
        }
    };
    let needed = [Some(value_col), time_col, rate_col]
        .into_iter()
        .flatten()
        .max()
        .unwrap_or(0);
    let mut rate_from_col: Option<f64> = None;
    let mut t = Vec::new();
    let mut v = Vec::with_capacity(table.rows().len());
    for row in table.rows() {
        row.reaches(needed)?;
        let line_no = row.line;
        v.push(row.number(value_col, what)? * format.value_to_si);
        if let Some(tc) = time_col {
            let ts = row.number(tc, "time")? * format.time_to_s;
            if let Some(&prev) = t.last() {
                ensure!(
                    ts > prev,
                    "line {line_no}: time {} s does not increase (previous sample {} s)",
                    ts,
                    prev
                );
            }
            t.push(ts);
        }
        if let Some(rc) = rate_col {
            let r = row.number(rc, "sample rate")?;
            match rate_from_col {
                None => {
                    shared::error::check_range("sample_rate_hz", r, 1e-3, 1e9)
                        .with_context(|| format!("line {line_no}"))?;
                    rate_from_col = Some(r);
                }
                Some(r0) => ensure!(
                    r == r0,
                    "line {line_no}: sample_rate_hz changes from {r0} to {r} (one rate per file)"
                ),
            }
        }
    }
    ensure!(
        v.len() >= MIN_SAMPLES,
        "{} samples: at least {MIN_SAMPLES} are needed",
        v.len()
    );
    let stated = rate_from_col
        .map(|r| (r, "the `sample_rate_hz` column"))
        .or(meta_rate.map(|r| (r, "the `# sample_rate_hz` line")));
    if let (Some((rate, source)), false) = (stated, t.is_empty()) {
        check_time_step(&t, rate, source, format.time_to_s)?;
    }
    if t.is_empty() {
        let rate = format
            .sample_rate_hz
            .or(rate_from_col)
            .or(meta_rate)
            .context("no time base")?;
        shared::error::check_range("sample_rate_hz", rate, 1e-3, 1e9)?;
        t = (0..v.len()).map(|i| i as f64 / rate).collect();
    }
    Ok(Trace { t_s: t, value: v })
}

/// Largest relative difference between a time column's median step and the file's stated
/// sample period that [`trace_from_table`] accepts.
pub const RATE_TOLERANCE: f64 = 0.01;

/// Checks that the median step of the time column `t` (s, read with `time_to_s` s per unit)
/// is the period of the `rate` (Hz) that `source` states, within [`RATE_TOLERANCE`]; a
/// mismatch by a factor that another [`TimeUnit`] explains names that unit.
fn check_time_step(t: &[f64], rate: f64, source: &str, time_to_s: f64) -> Result<()> {
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if steps.is_empty() {
        return Ok(());
    }
    let mid = steps.len() / 2;
    let (_, &mut median, _) = steps.select_nth_unstable_by(mid, f64::total_cmp);
    let factor = median * rate;
    if (factor - 1.0).abs() <= RATE_TOLERANCE {
        return Ok(());
    }
    let unit = [TimeUnit::S, TimeUnit::Ms, TimeUnit::Us]
        .into_iter()
        .find(|u| (u.to_s() / (time_to_s / factor) - 1.0).abs() <= RATE_TOLERANCE);
    let hint = match unit {
        Some(u) => format!(
            "the time column reads as if it were in {} (--time-unit {})",
            u.name(),
            u.name()
        ),
        None => "is the time column in the unit --time-unit says (s, ms or us), and is the \
                 stated rate this file's?"
            .to_string(),
    };
    bail!(
        "the time column steps {median:.3e} s (median) but {source} says {rate} Hz, a period of \
         {:.3e} s ({factor:.3}× apart, more than {} %): {hint}",
        1.0 / rate,
        RATE_TOLERANCE * 100.0
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fmt(time: &str, value: &str, rate: Option<f64>) -> TraceFormat {
        TraceFormat {
            time_col: time.into(),
            value_col: Some(value.into()),
            time_to_s: 1.0,
            value_to_si: 1.0,
            sample_rate_hz: rate,
        }
    }

    fn body(n: usize, f: impl Fn(usize) -> String) -> String {
        (0..n).map(f).collect::<Vec<_>>().join("\n")
    }

    #[test]
    fn header_comments_delimiters_and_units() {
        let text = format!(
            "# rig: wires\n# exported by DAQ\ntime_ms;force_kN;ch2\n{}\n",
            body(20, |i| format!("{};{};0", i as f64 * 0.02, i as f64 * 1e-3))
        );
        let mut f = fmt("time_ms", "force_kN", None);
        f.time_to_s = 1e-3;
        f.value_to_si = 1e3;
        let tr = parse_trace(&text, &f, "force").unwrap();
        assert_eq!(tr.t_s.len(), 20);
        assert!((tr.t_s[3] - 60e-6).abs() < 1e-15);
        assert!((tr.value[5] - 5.0).abs() < 1e-12);
        // No header, columns by number, whitespace-separated.
        let text = body(20, |i| format!("{}   {}", i, 2 * i));
        let tr = parse_trace(&text, &fmt("1", "2", None), "force").unwrap();
        assert_eq!(tr.value[4], 8.0);
    }

    #[test]
    fn sample_rate_from_option_column_or_metadata() {
        let text = format!("force_n\n{}", body(20, |i| format!("{i}")));
        let tr = parse_trace(&text, &fmt("t_s", "force_n", Some(1000.0)), "force").unwrap();
        assert!((tr.t_s[10] - 0.01).abs() < 1e-15);
        let text = format!(
            "# sample_rate_hz = 500\nforce_n\n{}",
            body(20, |i| format!("{i}"))
        );
        let tr = parse_trace(&text, &fmt("t_s", "force_n", None), "force").unwrap();
        assert!((tr.t_s[10] - 0.02).abs() < 1e-15);
        let text = format!(
            "force_n,sample_rate_hz\n{}",
            body(20, |i| format!("{i},250"))
        );
        let tr = parse_trace(&text, &fmt("t_s", "force_n", None), "force").unwrap();
        assert!((tr.t_s[10] - 0.04).abs() < 1e-15);
        let text = format!("force_n\n{}", body(20, |i| format!("{i}")));
        let e = parse_trace(&text, &fmt("t_s", "force_n", None), "force").unwrap_err();
        assert!(format!("{e:#}").contains("no time base"), "{e:#}");
    }

    #[test]
    fn a_time_column_must_step_at_the_stated_rate() {
        // 20 samples 1 ms apart, the time in ms, and a stated rate of 1 kHz.
        let ms = |rate_line: &str, rate_cell: &str| {
            format!(
                "{rate_line}t,force_n{}\n{}",
                if rate_cell.is_empty() {
                    ""
                } else {
                    ",sample_rate_hz"
                },
                body(20, |i| format!("{i},{i}{rate_cell}"))
            )
        };
        let mut f = fmt("t", "force_n", None);
        f.time_to_s = 1e-3;
        let tr = parse_trace(&ms("# sample_rate_hz = 1000\n", ""), &f, "force").unwrap();
        assert_eq!(tr.t_s[19], 19e-3);
        parse_trace(&ms("", ",1000"), &f, "force").unwrap();
        // Read as s: 1000× the period, named as ms.
        let error = |text: &str, f: &TraceFormat| {
            format!("{:#}", parse_trace(text, f, "force").unwrap_err())
        };
        let s = fmt("t", "force_n", None);
        let e = error(&ms("# sample_rate_hz = 1000\n", ""), &s);
        for said in [
            "steps 1.000e0 s (median)",
            "the `# sample_rate_hz` line says 1000 Hz, a period of 1.000e-3 s",
            "(1000.000× apart",
            "(--time-unit ms)",
        ] {
            assert!(e.contains(said), "{said:?} not in {e}");
        }
        let e = error(&ms("", ",1000"), &s);
        assert!(
            e.contains("the `sample_rate_hz` column says 1000 Hz"),
            "{e}"
        );
        // In µs read as ms: named as us.
        let e = error(&ms("# sample_rate_hz = 1e6\n", ""), &f);
        assert!(e.contains("(--time-unit us)"), "{e}");
        // 2 % off: no unit explains it.
        let e = error(&ms("# sample_rate_hz = 1020\n", ""), &f);
        assert!(e.contains("is the stated rate this file's?"), "{e}");
        // Within 1 %, and an explicit --sample-rate-hz (the time column unread): accepted.
        parse_trace(&ms("# sample_rate_hz = 1005\n", ""), &f, "force").unwrap();
        let tr = parse_trace(
            &ms("# sample_rate_hz = 1020\n", ""),
            &fmt("t", "force_n", Some(1020.0)),
            "force",
        )
        .unwrap();
        assert_eq!(tr.t_s[1], 1.0 / 1020.0);
    }

    #[test]
    fn malformed_lines_are_named() {
        let error = |text: &str| {
            format!(
                "{:#}",
                parse_trace(text, &fmt("t_s", "force_n", None), "force").unwrap_err()
            )
        };
        // Line 9 of the file (the header, then samples 0..20) broken each way in turn.
        for (bad, expect) in [
            ("7,abc", &["line 9", "force_n", "abc"][..]),
            ("3,7", &["line 9", "does not increase"]),
            ("7,NaN", &["line 9", "not finite"]),
            ("7", &["line 9"]),
            // A decimal comma: three cells where the header has two.
            ("7,0,5", &["line 9", "3 cells", "decimal comma"]),
        ] {
            let mut lines: Vec<String> = (0..20).map(|i| format!("{},{}", i, i)).collect();
            lines[7] = bad.into();
            let e = error(&format!("t_s,force_n\n{}", lines.join("\n")));
            assert!(expect.iter().all(|x| e.contains(x)), "{bad}: {e}");
        }
        // Empty trailing cells are tolerated (a delimiter at the end of the line).
        let lines: Vec<String> = (0..20).map(|i| format!("{i},{i},")).collect();
        let tr = parse_trace(
            &format!("t_s,force_n\n{}", lines.join("\n")),
            &fmt("t_s", "force_n", None),
            "force",
        )
        .unwrap();
        assert_eq!(tr.value[19], 19.0);
        let e = error("t_s,force_n\n0,1\n1,2");
        assert!(e.contains("at least"), "{e}");
        let e = error("t_s,f\n0,1\n1,2");
        assert!(e.contains("no force column `force_n`"), "{e}");
    }
}

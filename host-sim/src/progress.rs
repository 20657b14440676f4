//! The progress of a long run on stderr: indicatif's bar on a terminal; without one (stderr
//! redirected: a cluster job's log, a script) a line at the first 5 % step after 2 s — the
//! estimate of the whole run — then at each 5 % step and at least once a minute (the command's
//! own last line says how it ended). A run shorter than 2 s writes nothing.
//!
//! A line: `peterka: 35 % (7,315,000 of 20,900,000 points) in 12 minutes, 10,114 points/s,
//! about 22 minutes left`.

use std::time::Duration;

use indicatif::{HumanCount, HumanDuration, ProgressBar, ProgressDrawTarget, ProgressStyle};

/// No line before this much time has passed (a short run stays silent).
pub const FIRST_LINE_AFTER: Duration = Duration::from_secs(2);
/// A line at least this often, whatever the progress.
pub const LINE_AT_LEAST_EVERY: Duration = Duration::from_secs(60);
/// A line at each step of this many percent.
pub const STEP_PERCENT: u64 = 5;
/// How often the line writer looks at the bar.
const POLL: Duration = Duration::from_millis(250);

/// A progress bar for `len` points on stderr, with rate and ETA (hidden when `what` is empty,
/// e.g. for one computation of many that have their own bar); lines instead of a bar when
/// stderr is not a terminal (the module's rules).
pub fn progress(len: usize, what: &str) -> ProgressBar {
    progress_of(len, what, "points")
}

/// [`progress`] counting `unit` (plural, e.g. `"draws"`).
pub fn progress_of(len: usize, what: &str, unit: &'static str) -> ProgressBar {
    if what.is_empty() {
        return ProgressBar::hidden();
    }
    if ProgressDrawTarget::stderr().is_hidden() {
        let bar = ProgressBar::with_draw_target(Some(len as u64), ProgressDrawTarget::hidden());
        let weak = bar.downgrade();
        let mut lines = Lines::new(what, len as u64, unit);
        // The writer ends with the bar (finished or dropped): at most `POLL` later.
        let _ = std::thread::Builder::new()
            .name("progress".into())
            .spawn(move || {
                loop {
                    std::thread::sleep(POLL);
                    let Some(bar) = weak.upgrade() else { break };
                    if bar.is_finished() {
                        break;
                    }
                    if let Some(line) = lines.observe(bar.position(), bar.elapsed()) {
                        eprintln!("{line}");
                    }
                }
            });
        return bar;
    }
    let bar = ProgressBar::new(len as u64);
    let template = format!(
        "{{msg}} [{{bar:30}}] {{human_pos}}/{{human_len}} {unit}, {{rate}} {unit}/s, ETA {{eta}}"
    );
    bar.set_style(
        ProgressStyle::with_template(&template)
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            // indicatif's own `{per_sec}` prints four decimals ("6,226.2903/s").
            .with_key(
                "rate",
                |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                    let _ = write!(w, "{:.0}", s.per_sec());
                },
            )
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// When to write a progress line and what it says, from the count done and the time elapsed.
#[derive(Debug, Clone)]
pub struct Lines {
    what: String,
    len: u64,
    unit: &'static str,
    /// The step (in [`STEP_PERCENT`]s) of the last line, and its time.
    last: Option<(u64, Duration)>,
}

impl Lines {
    /// Lines for a run of `len` `unit` named `what`.
    pub fn new(what: &str, len: u64, unit: &'static str) -> Lines {
        Lines {
            what: what.to_string(),
            len,
            unit,
            last: None,
        }
    }

    /// The line to write now that `pos` are done after `elapsed`, if one is due.
    pub fn observe(&mut self, pos: u64, elapsed: Duration) -> Option<String> {
        if elapsed < FIRST_LINE_AFTER || pos == 0 {
            return None;
        }
        let step = self.step(pos);
        let due = match self.last {
            None => true,
            Some((s, at)) => step > s || elapsed >= at + LINE_AT_LEAST_EVERY,
        };
        if !due {
            return None;
        }
        self.last = Some((step, elapsed));
        Some(self.line(pos, elapsed))
    }

    fn step(&self, pos: u64) -> u64 {
        (100 * pos.min(self.len) / self.len.max(1)) / STEP_PERCENT
    }

    fn line(&self, pos: u64, elapsed: Duration) -> String {
        let secs = elapsed.as_secs_f64();
        let rate = pos as f64 / secs;
        let left = Duration::from_secs_f64(self.len.saturating_sub(pos) as f64 / rate);
        format!(
            "{}: {} % ({} of {} {}) in {}, {} {}/s, about {} left",
            self.what,
            100 * pos.min(self.len) / self.len.max(1),
            HumanCount(pos),
            HumanCount(self.len),
            self.unit,
            HumanDuration(elapsed),
            HumanCount(rate as u64),
            self.unit,
            HumanDuration(left)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(x: f64) -> Duration {
        Duration::from_secs_f64(x)
    }

    #[test]
    fn a_short_run_is_silent_and_a_long_one_says_its_estimate_then_each_step() {
        let mut l = Lines::new("grid", 1000, "points");
        // Before 2 s: nothing, whatever the progress.
        assert_eq!(l.observe(900, s(1.9)), None);
        // The first line after 2 s: 250 points in 2 s = 125 points/s, 750 left = 6 s.
        assert_eq!(
            l.observe(250, s(2.0)).as_deref(),
            Some(
                "grid: 25 % (250 of 1,000 points) in 2 seconds, 125 points/s, about 6 seconds left"
            )
        );
        // Within the same 5 % step: nothing; the next step: a line.
        assert_eq!(l.observe(299, s(2.9)), None);
        let next = l.observe(300, s(3.0)).unwrap();
        assert!(
            next.starts_with("grid: 30 % (300 of 1,000 points)"),
            "{next}"
        );
        // No step for a minute: a line anyway.
        assert_eq!(l.observe(320, s(62.9)), None);
        assert!(l.observe(320, s(63.0)).is_some());
    }

    #[test]
    fn the_estimate_is_the_rate_so_far_over_what_is_left() {
        // 20.9 M points, 1 % in 21 s: 99 % left at 9,952 points/s, 2,079 s = 34.65 minutes.
        let mut l = Lines::new("peterka", 20_900_000, "points");
        let line = l.observe(209_000, s(21.0)).unwrap();
        assert!(
            line.ends_with("in 21 seconds, 9,952 points/s, about 35 minutes left"),
            "{line}"
        );
    }
}

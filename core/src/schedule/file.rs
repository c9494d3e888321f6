//! `schedule.toml`, the file people edit. Parsed on the host only: by the core's build script
//! (included with `#[path]`) and, behind the `schedule-file` feature, by
//! `skyframe check-schedule`.

use super::analysis::{ExecutiveInput, OverrunPolicy, RENAMED_TASKS, TaskInput};
use serde::Deserialize;
use std::string::{String, ToString};
use std::vec::Vec;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScheduleFile {
    pub executive: ExecutiveSection,
    pub tasks: Vec<TaskEntry>,
    /// One line per old task name this file used and [`ScheduleFile::parse`] renamed (see
    /// [`RENAMED_TASKS`]), for the reader to print as a warning.
    #[serde(skip)]
    pub renamed: Vec<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExecutiveSection {
    /// Time every minor frame keeps free for the executive and jitter (µs).
    pub margin_us: u64,
    /// Start latency above which a frame counts as late (µs).
    pub late_start_us: u64,
    /// Minor frame length; the gcd of the periods when absent.
    #[serde(default)]
    pub minor_frame_ms: Option<u64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaskEntry {
    pub name: String,
    pub period_ms: u64,
    #[serde(default)]
    pub offset_ms: u64,
    pub budget_us: u64,
    pub on_overrun: String,
    #[serde(default)]
    pub after: Vec<String>,
}

const MS: u64 = 1_000_000;
const US: u64 = 1_000;

/// The longest period (and offset) a task may have: an hour. Longer is a typo, and times in
/// ns must not overflow when the analysis adds them up.
pub const MAX_PERIOD_MS: u64 = 3_600_000;
/// The longest budget, margin or late-start threshold: 10 s.
pub const MAX_BUDGET_US: u64 = 10_000_000;

impl ScheduleFile {
    /// Parses the text of a schedule file; the error says the line and column.
    pub fn parse(text: &str) -> Result<Self, String> {
        let mut file: Self = toml::from_str(text).map_err(|e| toml_error_line(&e, text))?;
        file.rename_old_tasks();
        let e = &file.executive;
        for (key, value, max) in [
            ("margin_us", e.margin_us, MAX_BUDGET_US),
            ("late_start_us", e.late_start_us, MAX_BUDGET_US),
            (
                "minor_frame_ms",
                e.minor_frame_ms.unwrap_or(1),
                MAX_PERIOD_MS,
            ),
        ] {
            if value > max {
                return Err(std::format!(
                    "[executive] {key} = {value} is out of range (at most {max})"
                ));
            }
        }
        if e.minor_frame_ms == Some(0) {
            return Err("[executive] minor_frame_ms = 0: a minor frame takes time".to_string());
        }
        for t in &file.tasks {
            for (key, value, low, high) in [
                ("period_ms", t.period_ms, 1, MAX_PERIOD_MS),
                ("offset_ms", t.offset_ms, 0, MAX_PERIOD_MS),
                ("budget_us", t.budget_us, 0, MAX_BUDGET_US),
            ] {
                if !(low..=high).contains(&value) {
                    return Err(std::format!(
                        "task `{}`: {key} = {value} is out of range ({low}..={high})",
                        t.name
                    ));
                }
            }
            if OverrunPolicy::parse(&t.on_overrun).is_none() {
                return Err(std::format!(
                    "task `{}`: on_overrun = \"{}\" is not one of log, skip, reset",
                    t.name,
                    t.on_overrun
                ));
            }
        }
        Ok(file)
    }

    /// A file written before [`RENAMED_TASKS`] names `logging` and no `watchdog`: in it, and
    /// only in it, `health` is the watchdog. Every name and `after` entry is renamed at once,
    /// so `logging` → `health` and `health` → `watchdog` do not run into each other.
    fn rename_old_tasks(&mut self) {
        let names_old = |old: &str| self.tasks.iter().any(|t| t.name == old);
        if !names_old("logging") || names_old("watchdog") {
            return;
        }
        let rename = |name: &mut String| {
            if let Some((_, new)) = RENAMED_TASKS.iter().find(|(old, _)| name == old) {
                *name = new.to_string();
            }
        };
        for t in &mut self.tasks {
            let old = t.name.clone();
            rename(&mut t.name);
            if t.name != old {
                self.renamed.push(std::format!(
                    "task `{old}` is now called `{}`: rename it (the old names are read until \
                     the release after next)",
                    t.name
                ));
            }
            t.after.iter_mut().for_each(rename);
        }
    }

    pub fn executive_input(&self) -> ExecutiveInput {
        ExecutiveInput {
            margin_ns: self.executive.margin_us.saturating_mul(US),
            late_start_ns: self.executive.late_start_us.saturating_mul(US),
            minor_frame_ns: self.executive.minor_frame_ms.map(|m| m.saturating_mul(MS)),
        }
    }

    /// Calls `f` with the tasks in the analysis' terms (times in ns).
    pub fn with_inputs<R>(&self, f: impl FnOnce(&[TaskInput<'_>]) -> R) -> R {
        let afters: Vec<Vec<&str>> = self
            .tasks
            .iter()
            .map(|t| t.after.iter().map(String::as_str).collect())
            .collect();
        let inputs: Vec<TaskInput<'_>> = self
            .tasks
            .iter()
            .zip(&afters)
            .map(|(t, after)| TaskInput {
                name: &t.name,
                period_ns: t.period_ms.saturating_mul(MS),
                offset_ns: t.offset_ms.saturating_mul(MS),
                budget_ns: t.budget_us.saturating_mul(US),
                on_overrun: OverrunPolicy::parse(&t.on_overrun).unwrap_or(OverrunPolicy::Log),
                after,
            })
            .collect();
        f(&inputs)
    }
}

/// One line for a TOML error: `line L, column C: reason` (toml's own text spans several lines
/// with a caret drawing, which build output and stderr mangle).
pub fn toml_error_line(e: &toml::de::Error, text: &str) -> String {
    let message = e.message().trim();
    match e.span() {
        Some(span) => {
            let (line, column) = line_column(text, span.start);
            std::format!("line {line}, column {column}: {message}")
        }
        None => message.to_string(),
    }
}

/// The 1-based line and column (in characters, as an editor counts) of byte `offset` of
/// `text`: the one rule for every file skyframe reads (schedule, vehicle, scenario, mission).
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

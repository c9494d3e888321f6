//! The end-of-run summary, for people and as JSON.

use crate::host::{RunSummary, StopReason, TimerCheck};
use crate::platform::RtReport;
use serde::Serialize;
use skyframe_core::tasks::watchdog::WatchdogReport;

/// One task's health at the end of a run.
#[derive(Debug, Serialize)]
pub struct TaskReport {
    pub name: &'static str,
    pub budget_us: u64,
    pub initialised: bool,
    pub running: bool,
    pub releases: u64,
    pub steps: u64,
    pub exec_min_us: f64,
    pub exec_mean_us: f64,
    pub exec_max_us: f64,
    pub overruns_budget: u32,
    pub overruns_frame: u32,
    pub overruns_missed: u32,
    pub skipped: u32,
    pub resets: u32,
    pub faults: u32,
    pub init_failures: u32,
    pub last_fault: Option<&'static str>,
    /// Execution-time histogram: tenths of the budget, then 100-200 %, then >= 200 %.
    pub exec_histogram: Vec<u32>,
    /// Watchdog checks at which the task had been released but had not completed a step.
    pub watchdog_misses: u32,
    /// Log records the task's ring could not take.
    pub log_dropped: u32,
    /// What the task last said was wrong with its inputs (e.g. "device stale").
    pub degraded: Option<&'static str>,
}

#[derive(Debug, Serialize)]
pub struct SummaryReport {
    pub stop_reason: StopReason,
    pub elapsed_s: f64,
    pub frames: u64,
    pub frames_late: u64,
    pub frames_missed: u64,
    pub frames_overrun: u64,
    pub max_start_latency_us: f64,
    pub max_frame_work_us: f64,
    pub timing_records_dropped: u64,
    pub realtime: RtReport,
    /// The start-up timer check, when it ran.
    pub timer_check: Option<TimerCheck>,
    pub watchdog_checks: u32,
    pub tasks: Vec<TaskReport>,
}

impl SummaryReport {
    /// Adds what the health task's watchdog counted.
    pub fn set_watchdog(&mut self, report: &WatchdogReport) {
        self.watchdog_checks = report.checks;
        for (task, misses) in self.tasks.iter_mut().zip(report.misses) {
            task.watchdog_misses = misses;
        }
    }
}

impl From<&RunSummary> for SummaryReport {
    fn from(s: &RunSummary) -> Self {
        let us = |ns: u64| ns as f64 / 1e3;
        Self {
            stop_reason: s.stop_reason,
            elapsed_s: s.elapsed_ns as f64 / 1e9,
            frames: s.frames.frames,
            frames_late: s.frames.late,
            frames_missed: s.frames.missed,
            frames_overrun: s.frames.overrun,
            max_start_latency_us: us(s.frames.max_start_latency_ns),
            max_frame_work_us: us(s.frames.max_frame_work_ns),
            timing_records_dropped: s.frames.timing_records_dropped,
            realtime: s.realtime.clone(),
            timer_check: s.timer_check.clone(),
            watchdog_checks: 0,
            tasks: s
                .table
                .tasks
                .iter()
                .zip(&s.tasks)
                .map(|(slot, end)| (slot, &end.health, end.log_dropped, end.degraded))
                .map(|(slot, h, log_dropped, degraded)| TaskReport {
                    name: slot.name,
                    budget_us: slot.budget_ns / 1000,
                    initialised: h.initialised,
                    running: h.running,
                    releases: h.releases,
                    steps: h.exec.count,
                    exec_min_us: us(h.exec.min_ns),
                    exec_mean_us: us(h.exec.mean_ns()),
                    exec_max_us: us(h.exec.max_ns),
                    overruns_budget: h.overruns.budget,
                    overruns_frame: h.overruns.frame,
                    overruns_missed: h.overruns.missed,
                    skipped: h.skipped,
                    resets: h.resets,
                    faults: h.faults,
                    init_failures: h.init_failures,
                    last_fault: h.last_fault,
                    exec_histogram: h.exec.histogram.to_vec(),
                    watchdog_misses: 0,
                    log_dropped,
                    degraded,
                })
                .collect(),
        }
    }
}

/// The end-of-run summary for people: how the run ended, frame statistics, one row per task.
pub fn render_summary(s: &SummaryReport) -> String {
    let mut out = format!(
        "run ended ({}) after {:.2} s: {} frames, {} late, {} missed, {} overrun; max start \
         latency {:.0} us; timing records dropped {}\n",
        match s.stop_reason {
            StopReason::Duration => "programmed duration",
            StopReason::Requested => "stop requested",
        },
        s.elapsed_s,
        s.frames,
        s.frames_late,
        s.frames_missed,
        s.frames_overrun,
        s.max_start_latency_us,
        s.timing_records_dropped,
    );
    if let Some(c) = &s.timer_check {
        out += &format!(
            "timer check: wake-up latency p50 {:.0} us, p99 {:.0} us, max {:.0} us against a {:.0} us margin{}\n",
            c.wakeup_latency_us.p50,
            c.wakeup_latency_us.p99,
            c.wakeup_latency_us.max,
            c.margin_us,
            if c.over_margin { " (OVER)" } else { "" }
        );
    }
    out += &format!(
        "{:<10} {:>8} {:>9} {:>9} {:>9} {:>7} {:>6} {:>7} {:>7} {:>6} {:>6} {:>8}\n",
        "task",
        "releases",
        "mean us",
        "max us",
        "budget",
        "budget!",
        "frame!",
        "missed",
        "skipped",
        "resets",
        "faults",
        "watchdog"
    );
    for t in &s.tasks {
        out += &format!(
            "{:<10} {:>8} {:>9.1} {:>9.1} {:>9} {:>7} {:>6} {:>7} {:>7} {:>6} {:>6} {:>8}\n",
            t.name,
            t.releases,
            t.exec_mean_us,
            t.exec_max_us,
            t.budget_us,
            t.overruns_budget,
            t.overruns_frame,
            t.overruns_missed,
            t.skipped,
            t.resets,
            t.faults,
            t.watchdog_misses,
        );
    }
    out += "budget! = over budget, frame! = ran into the next frame, missed = releases in \
            frames the executive missed whole, watchdog = checks that found the task released \
            but not completing a step\n";
    out
}

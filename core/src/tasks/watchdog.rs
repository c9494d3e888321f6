//! The watchdog task.
//!
//! The seed's watchdog cancelled threads that had not set their "alive" flag since its last
//! check. Here nothing can be stuck inside a step (the executive measures every step and
//! applies overrun policies), so the watchdog's job is to notice tasks that were *released*
//! since the last check but never *completed* a step: init failing over and over, every
//! release skipped, every step faulting. It counts those as misses, keeps the alive light for
//! telemetry, and publishes a report into a latest-value slot.

use crate::comm::LatestSlot;
use crate::executive::{Task, TaskContext, TaskFault};
use crate::logfmt::{NoLog, RecordSink};
use crate::schedule::analysis::MAX_TASKS;
use crate::tasks::task_log::TaskLog;

crate::log_record! {
    /// Each watchdog check: which tasks are alive and which stalled, as bit masks.
    pub struct WatchdogLog {
        checks: u32 = "%u",
        alive_mask: u32 = "%u",
        stalled_mask: u32 = "%u",
        misses_total: u32 = "%u",
        period_ms: u32 = "%u",
    }
}
const WATCHDOG_INDEX: u8 = 1;

/// What the watchdog saw at its last check.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WatchdogReport {
    /// When the check ran (executive clock, ns).
    pub checked_at_ns: u64,
    /// Checks done so far.
    pub checks: u32,
    /// Tasks that completed a step since the previous check (bit per table index).
    pub alive: u32,
    /// Tasks released since the previous check that never completed a step.
    pub stalled: u32,
    /// Per task: checks at which it was released but never completed a step.
    pub misses: [u32; MAX_TASKS],
}

pub struct WatchdogTask<'a, S: RecordSink = NoLog> {
    report: WatchdogReport,
    log: TaskLog<S>,
    /// The log is declared once, by the first init (a reset does not restart it).
    declared: bool,
    /// Release counts at the previous check.
    releases_seen: [u64; MAX_TASKS],
    out: &'a LatestSlot<WatchdogReport>,
    /// Minimum time between checks (ms), changeable over the link; 0: every release.
    period_ms: Option<&'a core::cell::Cell<u32>>,
    last_check_ns: Option<u64>,
}

impl<'a> WatchdogTask<'a, NoLog> {
    pub fn new(out: &'a LatestSlot<WatchdogReport>) -> Self {
        Self {
            report: WatchdogReport::default(),
            log: TaskLog::new(NoLog),
            declared: false,
            releases_seen: [0; MAX_TASKS],
            out,
            period_ms: None,
            last_check_ns: None,
        }
    }

    /// Logs every check into `sink` (`watchdog.bin`).
    pub fn logging_to<S: RecordSink>(self, sink: S) -> WatchdogTask<'a, S> {
        WatchdogTask {
            report: self.report,
            log: TaskLog::new(sink),
            declared: self.declared,
            releases_seen: self.releases_seen,
            out: self.out,
            period_ms: self.period_ms,
            last_check_ns: self.last_check_ns,
        }
    }
}

impl<'a, S: RecordSink> WatchdogTask<'a, S> {
    /// Checks at most every `period_ms` (the ground's "health-check period"); the task still
    /// runs at its frame-table period.
    pub fn with_period(mut self, period_ms: &'a core::cell::Cell<u32>) -> Self {
        self.period_ms = Some(period_ms);
        self
    }

    pub fn report(&self) -> &WatchdogReport {
        &self.report
    }
}

impl<S: RecordSink> Task for WatchdogTask<'_, S> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        if !self.declared {
            self.log
                .declare::<WatchdogLog>(cx, WATCHDOG_INDEX)
                .map_err(|_| TaskFault::new("watchdog log format"))?;
            self.declared = true;
            self.log.begin(cx);
        }
        // Start counting from now: releases before (re)initialisation are not held against
        // anyone.
        for (index, seen) in self.releases_seen.iter_mut().enumerate() {
            *seen = cx.health.task(index).map_or(0, |h| h.releases);
        }
        Ok(())
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let period_ns = u64::from(self.period_ms.map_or(0, core::cell::Cell::get)) * 1_000_000;
        if let Some(last) = self.last_check_ns
            && cx.now_ns < last.saturating_add(period_ns)
        {
            return Ok(());
        }
        self.last_check_ns = Some(cx.now_ns);
        let health = cx.health;
        let mut alive = 0u32;
        let mut stalled = 0u32;
        for (index, seen) in self
            .releases_seen
            .iter_mut()
            .enumerate()
            .take(health.task_count())
        {
            let bit = 1u32 << index;
            let was_alive = health.take_alive(index);
            let releases = health.task(index).map_or(0, |h| h.releases);
            if index == cx.task {
                // The watchdog is running, so it is alive; its own step completes after this.
                alive |= bit;
            } else if was_alive {
                alive |= bit;
            } else if releases > *seen {
                stalled |= bit;
                if let Some(m) = self.report.misses.get_mut(index) {
                    *m = m.saturating_add(1);
                }
            }
            *seen = releases;
        }
        self.report.checked_at_ns = cx.now_ns;
        self.report.checks = self.report.checks.saturating_add(1);
        self.report.alive = alive;
        self.report.stalled = stalled;
        self.out.publish(self.report);
        let r = self.report;
        let misses_total = r.misses.iter().fold(0u32, |sum, m| sum.saturating_add(*m));
        let period_ms = u32::try_from(period_ns / 1_000_000).unwrap_or(u32::MAX);
        let record = WatchdogLog {
            checks: r.checks,
            alive_mask: r.alive,
            stalled_mask: r.stalled,
            misses_total,
            period_ms,
        };
        self.log.log(cx, WATCHDOG_INDEX, &record);
        Ok(())
    }

    fn shutdown(&mut self, cx: &mut TaskContext<'_>) {
        self.log.end(cx);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::executive::Executive;
    use crate::schedule::{FrameTable, TaskSlot};
    use crate::tasks::test_support::{MS, SetClock, run_frames, slot};
    use core::cell::Cell;

    /// Completes its steps only while `healthy` is set; otherwise its step fails.
    struct Flaky<'a>(&'a Cell<bool>);
    impl Task for Flaky<'_> {
        fn init(&mut self, _: &mut TaskContext<'_>) -> Result<(), TaskFault> {
            Ok(())
        }
        fn step(&mut self, _: &mut TaskContext<'_>) -> Result<(), TaskFault> {
            if self.0.get() {
                Ok(())
            } else {
                Err(TaskFault::new("sensor silent"))
            }
        }
    }

    static SLOTS: [TaskSlot; 3] = [
        slot("imu", 10, 0),
        slot("gps", 100, 20),
        slot("watchdog", 50, 40),
    ];
    static TABLE: FrameTable = FrameTable {
        minor_frame_ns: 10 * MS,
        margin_ns: MS,
        late_start_ns: MS,
        tasks: &SLOTS,
        // imu every frame; gps in frame 2; the watchdog in frames 4 and 9.
        frames: &[
            0b001, 0b001, 0b011, 0b001, 0b101, 0b001, 0b001, 0b001, 0b001, 0b101,
        ],
        utilisation_ppm: 0,
    };

    #[test]
    fn watchdog_counts_released_tasks_that_never_complete_and_ignores_ones_not_released() {
        let clock = SetClock(Cell::new(0));
        let imu_ok = Cell::new(true);
        let gps_ok = Cell::new(true);
        let slot = LatestSlot::new();
        let mut imu = Flaky(&imu_ok);
        let mut gps = Flaky(&gps_ok);
        let mut watchdog = WatchdogTask::new(&slot);
        let mut exec = Executive::new(&TABLE, &clock);
        {
            let mut tasks: [&mut dyn Task; 3] = [&mut imu, &mut gps, &mut watchdog];
            exec.start(&mut tasks, 0).expect("start");
            let mut run = |frames: u64| run_frames(&mut exec, &clock, &mut tasks, frames);
            run(5); // frames 0-4: check at frame 4, all fine (gps ran in frame 2)
            let r = slot.peek().expect("report");
            assert_eq!((r.checks, r.alive, r.stalled), (1, 0b111, 0));
            run(5); // frames 5-9: gps not released since the last check: not a miss
            let r = slot.peek().expect("report");
            assert_eq!((r.checks, r.alive, r.stalled), (2, 0b101, 0));
            imu_ok.set(false);
            gps_ok.set(false);
            run(5); // frames 10-14: imu and gps (frame 12) fail every step
            let r = slot.peek().expect("report");
            assert_eq!((r.alive, r.stalled), (0b100, 0b011));
            imu_ok.set(true);
            run(5);
            let r = slot.peek().expect("report");
            assert_eq!((r.alive, r.stalled), (0b101, 0));
            assert_eq!(r.misses[..3], [1, 1, 0]);
        }
    }
}

//! Health of every task, in fixed-size storage: the seed's four lights and the counters the
//! ground station and the overrun report show.

use crate::schedule::analysis::MAX_TASKS;
use core::cell::Cell;

/// Execution-time histogram buckets, as a share of the task's budget: `<10%`, `<20%`, …
/// `<100%` (ten buckets), `<200%`, and `≥200%`. Relative to the budget because "how close
/// to its budget does this task run" is the question people ask.
pub const HISTOGRAM_BUCKETS: usize = 12;

/// Bucket index of an execution time against a budget.
pub fn histogram_bucket(exec_ns: u64, budget_ns: u64) -> usize {
    if budget_ns == 0 {
        return HISTOGRAM_BUCKETS - 1;
    }
    let tenths = exec_ns.saturating_mul(10) / budget_ns;
    match tenths {
        0..=9 => tenths as usize,
        10..=19 => 10,
        _ => 11,
    }
}

/// Execution-time statistics of a task's steps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ExecTime {
    pub count: u64,
    pub min_ns: u64,
    pub max_ns: u64,
    pub total_ns: u64,
    pub histogram: [u32; HISTOGRAM_BUCKETS],
}

impl ExecTime {
    pub fn record(&mut self, exec_ns: u64, budget_ns: u64) {
        if self.count == 0 || exec_ns < self.min_ns {
            self.min_ns = exec_ns;
        }
        self.max_ns = self.max_ns.max(exec_ns);
        self.total_ns = self.total_ns.saturating_add(exec_ns);
        self.count += 1;
        if let Some(b) = self.histogram.get_mut(histogram_bucket(exec_ns, budget_ns)) {
            *b = b.saturating_add(1);
        }
    }

    pub fn mean_ns(&self) -> u64 {
        self.total_ns.checked_div(self.count).unwrap_or(0)
    }
}

/// Overruns of one task, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OverrunCounts {
    /// Steps that took longer than the task's budget.
    pub budget: u32,
    /// Frames whose work ran into the next frame while this task was running.
    pub frame: u32,
    /// Releases that fell in frames the executive missed entirely (woke up too late).
    pub missed: u32,
}

impl OverrunCounts {
    pub fn total(&self) -> u32 {
        self.budget
            .saturating_add(self.frame)
            .saturating_add(self.missed)
    }
}

/// Health of one task.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaskHealth {
    /// Light 1: `init` has succeeded (and the task was not shut down since).
    pub initialised: bool,
    /// Light 2: the executive has started the task and not yet shut it down.
    pub running: bool,
    /// Light 3: the task's last release ran to completion inside its budget and frame (no
    /// overrun, skip or pending reset).
    pub in_frame: bool,
    /// Releases the table gave the task (including skipped and missed ones).
    pub releases: u64,
    pub overruns: OverrunCounts,
    /// Releases dropped by the `skip` policy.
    pub skipped: u32,
    /// `recover` → `init` cycles (overrun with `reset`, or a fault).
    pub resets: u32,
    /// Steps that returned an error.
    pub faults: u32,
    /// `init` calls that failed.
    pub init_failures: u32,
    /// Reason of the last fault or failed init.
    pub last_fault: Option<&'static str>,
    pub exec: ExecTime,
}

/// Executive-wide frame statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrameStats {
    /// Minor frames executed.
    pub frames: u64,
    /// Minor frames skipped whole because the executive woke up after they had ended.
    pub missed: u64,
    /// Frames that started later than the late-start threshold.
    pub late: u64,
    /// Frames whose work ran past the start of the next frame.
    pub overrun: u64,
    pub max_start_latency_ns: u64,
    pub max_frame_work_ns: u64,
    /// Timing records the sink refused (its consumer fell behind).
    pub timing_records_dropped: u64,
}

/// Health of all tasks of one executive. Tasks get a shared reference; only the alive flags
/// can be changed through it, by the watchdog.
pub struct HealthBoard {
    tasks: [TaskHealth; MAX_TASKS],
    alive: [Cell<bool>; MAX_TASKS],
    /// Log records each task could not hand to its log ring (full).
    log_dropped: [Cell<u32>; MAX_TASKS],
    /// What a task reports is wrong with what it depends on (a stale device), if anything.
    degraded: [Cell<Option<&'static str>>; MAX_TASKS],
    count: usize,
    pub frames: FrameStats,
}

impl HealthBoard {
    pub fn new(count: usize) -> Self {
        Self {
            tasks: [TaskHealth::default(); MAX_TASKS],
            alive: [const { Cell::new(false) }; MAX_TASKS],
            log_dropped: [const { Cell::new(0) }; MAX_TASKS],
            degraded: [const { Cell::new(None) }; MAX_TASKS],
            count: count.min(MAX_TASKS),
            frames: FrameStats::default(),
        }
    }

    pub fn task_count(&self) -> usize {
        self.count
    }

    pub fn task(&self, index: usize) -> Option<&TaskHealth> {
        self.tasks.get(index).filter(|_| index < self.count)
    }

    pub(crate) fn task_mut(&mut self, index: usize) -> Option<&mut TaskHealth> {
        let count = self.count;
        self.tasks.get_mut(index).filter(|_| index < count)
    }

    /// Light 4: set by each completed step, cleared by [`take_alive`](Self::take_alive).
    pub fn alive(&self, index: usize) -> bool {
        self.alive.get(index).is_some_and(Cell::get)
    }

    /// The watchdog's check: was the task alive since the last check? Clears the flag.
    pub fn take_alive(&self, index: usize) -> bool {
        self.alive.get(index).is_some_and(|a| a.replace(false))
    }

    /// Counts a log record task `index` had to drop (its ring was full).
    pub fn note_log_drop(&self, index: usize) {
        if let Some(c) = self.log_dropped.get(index) {
            c.set(c.get().saturating_add(1));
        }
    }

    pub fn log_dropped(&self, index: usize) -> u32 {
        self.log_dropped.get(index).map_or(0, Cell::get)
    }

    /// A task says what is wrong with its inputs (`Some("device stale")`) or that all is well
    /// again (`None`). The task keeps running; people and the ground station see why its
    /// data may be old.
    pub fn set_degraded(&self, index: usize, reason: Option<&'static str>) {
        if let Some(c) = self.degraded.get(index) {
            c.set(reason);
        }
    }

    pub fn degraded(&self, index: usize) -> Option<&'static str> {
        self.degraded.get(index).and_then(Cell::get)
    }

    pub(crate) fn mark_alive(&self, index: usize) {
        if let Some(a) = self.alive.get(index) {
            a.set(true);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_buckets_are_tenths_of_budget_then_double() {
        assert_eq!(histogram_bucket(0, 1000), 0);
        assert_eq!(histogram_bucket(99, 1000), 0);
        assert_eq!(histogram_bucket(100, 1000), 1);
        assert_eq!(histogram_bucket(999, 1000), 9);
        assert_eq!(histogram_bucket(1000, 1000), 10);
        assert_eq!(histogram_bucket(1999, 1000), 10);
        assert_eq!(histogram_bucket(2000, 1000), 11);
        assert_eq!(histogram_bucket(5, 0), 11);
    }

    #[test]
    fn exec_time_tracks_min_mean_max() {
        let mut e = ExecTime::default();
        for t in [300, 100, 200] {
            e.record(t, 1000);
        }
        assert_eq!(
            (e.min_ns, e.mean_ns(), e.max_ns, e.count),
            (100, 200, 300, 3)
        );
        assert_eq!(e.histogram[1] + e.histogram[2] + e.histogram[3], 3);
    }

    #[test]
    fn alive_is_taken_once() {
        let board = HealthBoard::new(2);
        board.mark_alive(1);
        assert!(!board.take_alive(0));
        assert!(board.take_alive(1));
        assert!(!board.take_alive(1));
        assert!(!board.take_alive(40));
    }
}

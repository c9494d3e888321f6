//! The cyclic executive.
//!
//! Every minor frame it looks up which tasks the frame table releases, steps them in order,
//! measures each step with the [`Clock`], and checks the four timing faults:
//!
//! | fault | detected when | charged to |
//! |---|---|---|
//! | budget overrun | a step takes longer than the task's `budget_us` | that task |
//! | frame overrun | the frame's work is still running when the next frame is due | the task running then |
//! | late start | the frame starts more than `late_start_us` after its release | the frame |
//! | missed frames | the executive wakes up after a whole frame has passed | every release in those frames |
//!
//! An overrun then gets the task's `on_overrun` policy: `log` only counts it, `skip` drops the
//! task's next release, `reset` runs `recover` → `init` before its next release. Nothing is
//! cancelled: a task always returns from `step`, and the executive only acts between steps.
//!
//! Each frame ends with one [`FrameRecord`] pushed into a [`Sink`] (never waiting: a full
//! sink counts a dropped record).

pub mod clock;
pub mod faults;
pub mod health;
pub mod task;
pub mod timing;

pub use clock::{Clock, FrameTimer};
pub use faults::{FaultPlan, OverrunInjection};
pub use health::{FrameStats, HealthBoard, TaskHealth};
pub use task::{Task, TaskContext, TaskFault};
pub use timing::FrameRecord;

use crate::comm::Sink;
use crate::schedule::analysis::MAX_TASKS;
use crate::schedule::{FrameTable, OverrunPolicy};
use timing::{clamp_u32, flags};

/// What must happen before a task's next release, decided by an overrun policy or a fault.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Pending {
    skip: bool,
    reset: bool,
}

/// Why the executive cannot start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StartError {
    /// The caller gave a different number of tasks than the frame table has.
    TaskCountMismatch { table: usize, given: usize },
    /// The frame table is unusable (no frames, zero minor frame or too many tasks).
    BadTable,
}

pub struct Executive<C: Clock> {
    table: &'static FrameTable,
    clock: C,
    health: HealthBoard,
    pending: [Pending; MAX_TASKS],
    faults: FaultPlan,
    /// Release time of frame 0.
    origin_ns: u64,
    /// The next frame to run, counted since the start.
    next_frame: u64,
    started: bool,
    log_time_origin_ns: u64,
}

impl<C: Clock> Executive<C> {
    pub fn new(table: &'static FrameTable, clock: C) -> Self {
        Self {
            table,
            clock,
            health: HealthBoard::new(table.tasks.len()),
            pending: [Pending::default(); MAX_TASKS],
            faults: FaultPlan::new(),
            origin_ns: 0,
            next_frame: 0,
            started: false,
            log_time_origin_ns: 0,
        }
    }

    /// Log TIME of clock zero: the wall clock at start on a vehicle (the shell knows it),
    /// 0 in a simulation.
    pub fn set_log_time_origin(&mut self, ns: u64) {
        self.log_time_origin_ns = ns;
    }

    /// Injects overruns (tests, simulator scenarios, `--inject-overrun`).
    pub fn set_faults(&mut self, plan: FaultPlan) {
        self.faults = plan;
    }

    pub fn table(&self) -> &'static FrameTable {
        self.table
    }

    pub fn clock(&self) -> &C {
        &self.clock
    }

    pub fn health(&self) -> &HealthBoard {
        &self.health
    }

    /// The frame `run_frame` will execute next, counted since the start.
    pub fn next_frame(&self) -> u64 {
        self.next_frame
    }

    /// When the next frame is due.
    pub fn next_release_ns(&self) -> u64 {
        self.release_of(self.next_frame)
    }

    fn release_of(&self, frame: u64) -> u64 {
        self.origin_ns
            .saturating_add(frame.saturating_mul(self.table.minor_frame_ns))
    }

    /// Initialises every task, in table order, and sets frame 0 due at `first_release_ns`.
    pub fn start(
        &mut self,
        tasks: &mut [&mut dyn Task],
        first_release_ns: u64,
    ) -> Result<(), StartError> {
        let table = self.table;
        if table.frames.is_empty() || table.minor_frame_ns == 0 || table.tasks.len() > MAX_TASKS {
            return Err(StartError::BadTable);
        }
        if tasks.len() != table.tasks.len() {
            return Err(StartError::TaskCountMismatch {
                table: table.tasks.len(),
                given: tasks.len(),
            });
        }
        for (index, task) in tasks.iter_mut().enumerate() {
            self.init_task(index, &mut **task, 0);
            if let Some(h) = self.health.task_mut(index) {
                h.running = true;
            }
        }
        self.origin_ns = first_release_ns;
        self.next_frame = 0;
        self.started = true;
        Ok(())
    }

    fn context(&self, index: usize, frame: u64) -> TaskContext<'_> {
        self.context_at(index, frame, self.clock.now_ns())
    }

    /// A task's context at a clock reading the caller already has: each clock read costs tens
    /// of nanoseconds, and the frame's overhead is counted in them.
    fn context_at(&self, index: usize, frame: u64, now_ns: u64) -> TaskContext<'_> {
        TaskContext {
            now_ns,
            frame,
            task: index,
            health: &self.health,
            log_time_origin_ns: self.log_time_origin_ns,
        }
    }

    fn init_task(&mut self, index: usize, task: &mut dyn Task, frame: u64) -> bool {
        let result = task.init(&mut self.context(index, frame));
        if let Some(h) = self.health.task_mut(index) {
            match result {
                Ok(()) => h.initialised = true,
                Err(fault) => {
                    h.initialised = false;
                    h.init_failures = h.init_failures.saturating_add(1);
                    h.last_fault = Some(fault.reason);
                }
            }
        }
        result.is_ok()
    }

    fn apply_policy(&mut self, index: usize) {
        let Some(slot) = self.table.tasks.get(index) else {
            return;
        };
        if let Some(p) = self.pending.get_mut(index) {
            match slot.on_overrun {
                OverrunPolicy::Log => {}
                OverrunPolicy::Skip => p.skip = true,
                OverrunPolicy::Reset => p.reset = true,
            }
        }
    }

    /// Counts the releases of every task in frames `from..to`, which were missed whole.
    fn count_missed_releases(&mut self, from: u64, to: u64) {
        let minor = self.table.minor_frame_ns;
        for (index, slot) in self.table.tasks.iter().enumerate() {
            let period = (slot.period_ns / minor).max(1);
            let offset = slot.offset_ns / minor;
            let upto = |n: u64| {
                if n > offset {
                    (n - offset - 1) / period + 1
                } else {
                    0
                }
            };
            let missed = upto(to).saturating_sub(upto(from));
            if missed == 0 {
                continue;
            }
            if let Some(h) = self.health.task_mut(index) {
                h.releases = h.releases.saturating_add(missed);
                let missed = u32::try_from(missed).unwrap_or(u32::MAX);
                h.overruns.missed = h.overruns.missed.saturating_add(missed);
                h.in_frame = false;
            }
        }
    }

    /// Runs the frame that is due now (skipping, and counting, frames that have passed
    /// whole), then emits its timing record into `sink`.
    ///
    /// Call it when the next frame is due (see [`FrameTimer`]); calling it early runs the
    /// frame early, which shows as zero latency.
    pub fn run_frame<S: Sink<FrameRecord> + ?Sized>(
        &mut self,
        tasks: &mut [&mut dyn Task],
        sink: &mut S,
    ) -> FrameRecord {
        let minor = self.table.minor_frame_ns;
        let start = self.clock.now_ns();
        let mut frame = self.next_frame;
        let mut release = self.release_of(frame);
        let mut record = FrameRecord::empty();

        let behind = start.saturating_sub(release) / minor;
        if behind > 0 {
            self.count_missed_releases(frame, frame.saturating_add(behind));
            frame = frame.saturating_add(behind);
            release = self.release_of(frame);
            record.missed_before = clamp_u32(behind);
            record.flags |= flags::AFTER_MISSED;
            self.health.frames.missed = self.health.frames.missed.saturating_add(behind);
        }
        let latency = start.saturating_sub(release);
        let deadline = release.saturating_add(minor);
        if latency > self.table.late_start_ns {
            record.flags |= flags::LATE;
            self.health.frames.late += 1;
        }

        let released = self.table.released(frame);
        let mut tasks_ns = 0u64;
        for (index, task) in tasks.iter_mut().enumerate().take(self.table.tasks.len()) {
            let bit = 1u32 << index;
            if released & bit == 0 {
                continue;
            }
            let (exec, ended) = self.release_task(index, &mut **task, frame, &mut record);
            tasks_ns = tasks_ns.saturating_add(exec);
            if record.flags & flags::OVERRUN == 0 && ended > deadline {
                // The next frame became due while this task ran.
                record.flags |= flags::OVERRUN;
                record.over_frame |= bit;
                self.health.frames.overrun += 1;
                if let Some(h) = self.health.task_mut(index) {
                    h.overruns.frame = h.overruns.frame.saturating_add(1);
                    h.in_frame = false;
                }
                self.apply_policy(index);
            }
        }

        let end = self.clock.now_ns();
        let work = end.saturating_sub(start);
        record.frame = frame;
        record.release_ns = release;
        record.start_latency_ns = clamp_u32(latency);
        record.work_ns = clamp_u32(work);
        record.overhead_ns = clamp_u32(work.saturating_sub(tasks_ns));

        let stats = &mut self.health.frames;
        stats.frames += 1;
        stats.max_start_latency_ns = stats.max_start_latency_ns.max(latency);
        stats.max_frame_work_ns = stats.max_frame_work_ns.max(work);
        if sink.try_send(record).is_err() {
            stats.timing_records_dropped += 1;
        }
        self.next_frame = frame.saturating_add(1);
        record
    }

    /// One release of one task: pending skip or reset, init retry, the step itself, budget
    /// check. Returns the time spent on the task and the clock when it was done.
    fn release_task(
        &mut self,
        index: usize,
        task: &mut dyn Task,
        frame: u64,
        record: &mut FrameRecord,
    ) -> (u64, u64) {
        let bit = 1u32 << index;
        let budget = self.table.tasks.get(index).map_or(0, |s| s.budget_ns);
        if let Some(h) = self.health.task_mut(index) {
            h.releases = h.releases.saturating_add(1);
        }
        let pending = self.pending.get(index).copied().unwrap_or_default();
        if let Some(p) = self.pending.get_mut(index) {
            *p = Pending::default();
        }
        if pending.skip {
            record.skipped |= bit;
            if let Some(h) = self.health.task_mut(index) {
                h.skipped = h.skipped.saturating_add(1);
                h.in_frame = false;
            }
            return (0, self.clock.now_ns());
        }

        let t0 = self.clock.now_ns();
        let mut step_at = t0;
        if pending.reset {
            task.recover(&mut self.context(index, frame));
            record.reset |= bit;
            if let Some(h) = self.health.task_mut(index) {
                h.resets = h.resets.saturating_add(1);
                h.initialised = false;
            }
        }
        let initialised = self.health.task(index).is_some_and(|h| h.initialised);
        let ready = initialised || self.init_task(index, task, frame);
        if !initialised || pending.reset {
            // Recovery and init took time of their own: the step starts later.
            step_at = self.clock.now_ns();
        }
        let mut result = Ok(());
        let mut ended = step_at;
        if ready {
            result = task.step(&mut self.context_at(index, frame, step_at));
            ended = self.clock.now_ns();
            let extra = self.faults.extra_ns(index, frame);
            if extra > 0 {
                self.clock.spin_until(ended.saturating_add(extra));
                ended = self.clock.now_ns();
            }
            record.ran |= bit;
        }
        let exec = ended.saturating_sub(t0);
        if let Some(slot) = record.exec_ns.get_mut(index) {
            *slot = clamp_u32(exec);
        }

        let over_budget = ready && exec > budget;
        if let Some(h) = self.health.task_mut(index) {
            if ready {
                h.exec.record(exec, budget);
            }
            h.in_frame = ready && result.is_ok() && !over_budget;
            if over_budget {
                h.overruns.budget = h.overruns.budget.saturating_add(1);
            }
            if let Err(fault) = result {
                h.faults = h.faults.saturating_add(1);
                h.last_fault = Some(fault.reason);
            }
        }
        if ready && result.is_ok() {
            self.health.mark_alive(index);
        }
        if over_budget {
            record.over_budget |= bit;
            self.apply_policy(index);
        }
        if result.is_err()
            && let Some(p) = self.pending.get_mut(index)
        {
            p.reset = true;
        }
        (exec, ended)
    }

    /// Shuts every task down, in table order, and clears the running lights.
    pub fn shutdown(&mut self, tasks: &mut [&mut dyn Task]) {
        let frame = self.next_frame;
        for (index, task) in tasks.iter_mut().enumerate().take(self.table.tasks.len()) {
            task.shutdown(&mut self.context(index, frame));
            if let Some(h) = self.health.task_mut(index) {
                h.running = false;
                h.initialised = false;
                h.in_frame = false;
            }
        }
        self.started = false;
    }

    pub fn is_started(&self) -> bool {
        self.started
    }
}

impl<T: FrameTimer> Executive<T> {
    /// The frame loop: sleep until the next frame is due, run it, until `stop` says so
    /// (checked between frames). Returns the number of frames run.
    pub fn run_until<S: Sink<FrameRecord> + ?Sized>(
        &mut self,
        tasks: &mut [&mut dyn Task],
        sink: &mut S,
        mut stop: impl FnMut(&Self) -> bool,
    ) -> u64 {
        let mut frames = 0;
        while !stop(self) {
            self.clock.sleep_until(self.next_release_ns());
            self.run_frame(tasks, sink);
            frames += 1;
        }
        frames
    }
}

#[cfg(test)]
mod tests;

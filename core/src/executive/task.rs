//! The task state machine every scheduled task implements.

use super::health::HealthBoard;

/// Why a task asks to be reset. The executive counts it and runs `recover` → `init`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaskFault {
    /// A short reason for people (health, logs).
    pub reason: &'static str,
}

impl TaskFault {
    pub const fn new(reason: &'static str) -> Self {
        Self { reason }
    }
}

/// What a task sees of the executive while it runs.
pub struct TaskContext<'a> {
    /// The executive's clock when the call began (ns since start of run).
    pub now_ns: u64,
    /// The minor frame being executed, counted from the start of the run.
    pub frame: u64,
    /// This task's index in the frame table.
    pub task: usize,
    /// Every task's health; a watchdog takes the alive flags through it.
    pub health: &'a HealthBoard,
    /// Log TIME of `now_ns = 0`: the wall clock at start on a vehicle, 0 in a simulation.
    pub log_time_origin_ns: u64,
}

impl TaskContext<'_> {
    /// The TIME to stamp on a log record made now (`log-format.md`).
    pub fn log_time_ns(&self) -> u64 {
        self.log_time_origin_ns.saturating_add(self.now_ns)
    }
}

/// A periodic task: init → step (once per release) → recover → shutdown.
///
/// No method may block: device input arrives in rings the shell fills, output leaves through
/// rings the shell drains. The executive measures `step` against the task's budget.
pub trait Task {
    /// Prepares the task; called before its first release and after `recover`. A task whose
    /// init fails is not stepped; init is tried again at its next release.
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault>;

    /// One release of the periodic work. `Err` asks the executive for a reset.
    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault>;

    /// Puts the task back into a state `init` can start from, after an overrun with the
    /// `reset` policy or a fault. Replaces the seed's thread cancellation.
    fn recover(&mut self, _cx: &mut TaskContext<'_>) {}

    /// Called once when the run ends: flush, close, say goodbye.
    fn shutdown(&mut self, _cx: &mut TaskContext<'_>) {}
}

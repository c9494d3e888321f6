//! The per-frame timing record: what the frame-overrun report tool and the logs read.

use crate::schedule::analysis::MAX_TASKS;

/// Frame flags.
pub mod flags {
    /// The frame started later than the late-start threshold.
    pub const LATE: u8 = 1 << 0;
    /// The frame's work ran past the start of the next frame.
    pub const OVERRUN: u8 = 1 << 1;
    /// Whole frames were missed just before this one (`missed_before` > 0).
    pub const AFTER_MISSED: u8 = 1 << 2;
}

/// One minor frame, as measured. Task sets are bit masks in frame-table order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrameRecord {
    /// Minor frame number since the start of the run.
    pub frame: u64,
    /// When the frame was due (ns since the clock's origin).
    pub release_ns: u64,
    /// Actual start − release.
    pub start_latency_ns: u32,
    /// From the frame's start to the end of its last task.
    pub work_ns: u32,
    /// The executive's own time in the frame: `work_ns` − the tasks' execution times.
    pub overhead_ns: u32,
    /// Whole frames skipped just before this one.
    pub missed_before: u32,
    /// Tasks stepped.
    pub ran: u32,
    /// Tasks over their budget.
    pub over_budget: u32,
    /// The task running when the next frame became due.
    pub over_frame: u32,
    /// Releases dropped by the `skip` policy.
    pub skipped: u32,
    /// Tasks reset (recover → init) in this frame.
    pub reset: u32,
    pub flags: u8,
    /// Execution time of each stepped task (0 for tasks not stepped), table order.
    pub exec_ns: [u32; MAX_TASKS],
}

impl FrameRecord {
    pub const fn empty() -> Self {
        Self {
            frame: 0,
            release_ns: 0,
            start_latency_ns: 0,
            work_ns: 0,
            overhead_ns: 0,
            missed_before: 0,
            ran: 0,
            over_budget: 0,
            over_frame: 0,
            skipped: 0,
            reset: 0,
            flags: 0,
            exec_ns: [0; MAX_TASKS],
        }
    }
}

/// Saturating u64 → u32 for durations stored in records (4.29 s is far past any frame).
pub(crate) fn clamp_u32(ns: u64) -> u32 {
    u32::try_from(ns).unwrap_or(u32::MAX)
}

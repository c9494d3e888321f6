//! The static schedule: the frame table the executive steps through.
//!
//! `schedule.toml` at the repository root is the source; `build.rs` validates it with
//! [`analysis`] and writes [`SHIPPED`] as a `const`. Nothing here allocates or parses at run
//! time.

pub mod analysis;
#[cfg(feature = "schedule-file")]
pub mod file;

pub use analysis::OverrunPolicy;

/// One task's slot in the frame table, times in nanoseconds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TaskSlot {
    pub name: &'static str,
    pub period_ns: u64,
    pub offset_ns: u64,
    pub budget_ns: u64,
    pub on_overrun: OverrunPolicy,
}

/// A cyclic-executive frame table.
///
/// `tasks` is in execution order; `frames[k]` has bit `i` set when `tasks[i]` is released in
/// minor frame `k` of the major frame.
#[derive(Clone, Copy, Debug)]
pub struct FrameTable {
    pub minor_frame_ns: u64,
    pub margin_ns: u64,
    pub late_start_ns: u64,
    pub tasks: &'static [TaskSlot],
    pub frames: &'static [u32],
    /// Sum of budget/period in parts per million, as computed at build time.
    pub utilisation_ppm: u64,
}

impl FrameTable {
    pub fn minor_frames(&self) -> usize {
        self.frames.len()
    }

    pub fn major_frame_ns(&self) -> u64 {
        self.minor_frame_ns * self.frames.len() as u64
    }

    /// The tasks released in minor frame `frame` of the major frame (any frame count: it
    /// wraps).
    pub fn released(&self, frame: u64) -> u32 {
        if self.frames.is_empty() {
            return 0;
        }
        let index = (frame % self.frames.len() as u64) as usize;
        self.frames.get(index).copied().unwrap_or(0)
    }

    pub fn task_index(&self, name: &str) -> Option<usize> {
        self.tasks.iter().position(|t| t.name == name)
    }
}

include!(concat!(env!("OUT_DIR"), "/frame_table.rs"));

#[cfg(test)]
mod tests;

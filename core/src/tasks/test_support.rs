//! What task tests share: a clock the test sets, a frame-record sink that keeps nothing, an
//! idle task, a frame-table slot, and a helper that runs frames at their release times.

use crate::comm::Sink;
use crate::executive::{Clock, Executive, FrameRecord, Task, TaskContext, TaskFault};
use crate::schedule::{OverrunPolicy, TaskSlot};
use core::cell::Cell;

pub const MS: u64 = 1_000_000;

/// A frame-table slot: `period_ms` and `offset_ms`, a 1 ms budget, overruns only logged.
pub const fn slot(name: &'static str, period_ms: u64, offset_ms: u64) -> TaskSlot {
    TaskSlot {
        name,
        period_ns: period_ms * MS,
        offset_ns: offset_ms * MS,
        budget_ns: MS,
        on_overrun: OverrunPolicy::Log,
    }
}

/// Time that stands still until the test moves it.
pub struct SetClock(pub Cell<u64>);

impl Clock for SetClock {
    fn now_ns(&self) -> u64 {
        self.0.get()
    }
}

/// Accepts every frame record and keeps none (these tests look at health, not timing).
pub struct Discard;

impl Sink<FrameRecord> for Discard {
    fn try_send(&mut self, _: FrameRecord) -> Result<(), FrameRecord> {
        Ok(())
    }
}

/// A task that always succeeds and does nothing.
pub struct Idle;

impl Task for Idle {
    fn init(&mut self, _: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        Ok(())
    }
    fn step(&mut self, _: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        Ok(())
    }
}

/// Runs `frames` frames, each exactly at its release time.
pub fn run_frames(
    exec: &mut Executive<&SetClock>,
    clock: &SetClock,
    tasks: &mut [&mut dyn Task],
    frames: u64,
) {
    for _ in 0..frames {
        clock.0.set(exec.next_release_ns());
        exec.run_frame(tasks, &mut Discard);
    }
}

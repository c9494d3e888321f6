//! Idle tasks: fill every slot of the frame table with a task that does nothing, so the
//! executive itself can be measured (`skyframe bench`) and run before the real tasks exist.

use skyframe_core::executive::{Task, TaskContext, TaskFault};

/// A task whose step does no work beyond being called and measured.
#[derive(Default)]
pub struct IdleTask {
    steps: u64,
}

impl IdleTask {
    pub fn steps(&self) -> u64 {
        self.steps
    }
}

impl Task for IdleTask {
    fn init(&mut self, _cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        Ok(())
    }

    fn step(&mut self, _cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        // black_box keeps the call from being optimised into nothing.
        self.steps = std::hint::black_box(self.steps + 1);
        Ok(())
    }
}

/// One idle task per slot of a table with `count` tasks.
pub fn idle_tasks(count: usize) -> Vec<IdleTask> {
    (0..count).map(|_| IdleTask::default()).collect()
}

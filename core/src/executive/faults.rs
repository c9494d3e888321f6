//! Fault injection: make a task overrun on purpose, so every detection path can be exercised
//! on the real binary and in the simulator.

use heapless::Vec;

/// Most injections one run can carry.
pub const MAX_INJECTIONS: usize = 8;

/// Task `task` spends `extra_ns` more in each of its steps in minor frames
/// `from_frame..to_frame` (frame numbers since the start of the run), and again every
/// `repeat_every_frames` frames when that is not 0 (a soak loops its faults).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OverrunInjection {
    pub task: usize,
    pub extra_ns: u64,
    pub from_frame: u64,
    pub to_frame: u64,
    pub repeat_every_frames: u64,
}

#[derive(Clone, Debug, Default)]
pub struct FaultPlan {
    injections: Vec<OverrunInjection, MAX_INJECTIONS>,
}

impl FaultPlan {
    pub const fn new() -> Self {
        Self {
            injections: Vec::new(),
        }
    }

    /// Adds an injection; `Err` when the plan is full.
    pub fn push(&mut self, injection: OverrunInjection) -> Result<(), OverrunInjection> {
        self.injections.push(injection)
    }

    /// Extra time for `task` stepping in `frame`.
    pub fn extra_ns(&self, task: usize, frame: u64) -> u64 {
        self.injections
            .iter()
            .filter(|i| {
                let frame = match i.repeat_every_frames {
                    0 => frame,
                    period => frame % period,
                };
                i.task == task && (i.from_frame..i.to_frame).contains(&frame)
            })
            .map(|i| i.extra_ns)
            .fold(0, u64::saturating_add)
    }

    pub fn is_empty(&self) -> bool {
        self.injections.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_injection_repeats_every_period_when_asked() {
        let mut plan = FaultPlan::new();
        let once = OverrunInjection {
            task: 1,
            extra_ns: 5,
            from_frame: 10,
            to_frame: 12,
            repeat_every_frames: 0,
        };
        plan.push(once).expect("room");
        plan.push(OverrunInjection {
            task: 2,
            repeat_every_frames: 100,
            ..once
        })
        .expect("room");
        let hits = |task| {
            (0..400)
                .filter(|&f| plan.extra_ns(task, f) > 0)
                .collect::<std::vec::Vec<u64>>()
        };
        assert_eq!(hits(1), [10, 11]);
        assert_eq!(hits(2), [10, 11, 110, 111, 210, 211, 310, 311]);
    }
}

//! The simulation platform.
//!
//! [`VirtualClock`] is time that moves only when the executive sleeps or a task is made to
//! spin: a run is deterministic and as fast as the machine allows.
//!
//! [`plant`] is the simulated airplane: 6-DOF dynamics, wind, ground contact and the sensor
//! models, all in virtual time and deterministic for a seed.

pub mod plant;

use skyframe_core::executive::{Clock, FrameTimer};
use std::sync::atomic::{AtomicU64, Ordering};

/// Virtual time in ns. Sleeping jumps to the wake-up time; `advance` models work that takes
/// time (a simulated task's cost, an injected overrun).
#[derive(Debug, Default)]
pub struct VirtualClock {
    now_ns: AtomicU64,
}

impl VirtualClock {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn advance(&self, ns: u64) {
        self.now_ns.fetch_add(ns, Ordering::Relaxed);
    }
}

impl Clock for VirtualClock {
    fn now_ns(&self) -> u64 {
        self.now_ns.load(Ordering::Relaxed)
    }

    fn spin_until(&self, t_ns: u64) {
        self.now_ns.fetch_max(t_ns, Ordering::Relaxed);
    }
}

impl FrameTimer for VirtualClock {
    fn sleep_until(&self, t_ns: u64) {
        self.now_ns.fetch_max(t_ns, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_moves_only_forward_and_only_when_told() {
        let c = VirtualClock::new();
        assert_eq!(c.now_ns(), 0);
        c.sleep_until(10);
        c.sleep_until(5);
        assert_eq!(c.now_ns(), 10);
        c.advance(3);
        c.spin_until(12);
        assert_eq!(c.now_ns(), 13);
    }
}

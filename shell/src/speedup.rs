//! `skyframe sim --speedup N`: virtual time paced at N× real time (ArduPilot SITL's
//! `--speedup`), so a ground station on the link or on MAVLink watches an accelerated flight
//! instead of one that is over in seconds (`--fast`) or takes its full length (real time).
//!
//! The flight is the virtual-time flight, frame for frame: the executive's clock is a
//! [`VirtualClock`] that jumps to each frame's release, and the timer then sleeps until that
//! release's place on the real clock (`start + t / N`). A frame whose work takes longer than
//! its paced slot simply makes the run slower than N×; virtual time never misses a frame.

use crate::platform::{Platform, RtConfig, RtReport};
use skyframe_core::executive::{Clock, FrameTimer};
use skyframe_sim::VirtualClock;
use std::time::{Duration, Instant};

/// The range `--speedup` takes: slower than real time makes no sense for a simulator on a
/// link, and beyond 1000× a ground station sees nothing but jumps.
pub const SPEEDUP_RANGE: std::ops::RangeInclusive<f64> = 1.0..=1000.0;

/// Virtual time paced at `speedup` × real time.
pub struct PacedTime {
    pub speedup: f64,
}

pub struct PacedClock {
    clock: VirtualClock,
    start: Instant,
    speedup: f64,
}

impl Clock for PacedClock {
    fn now_ns(&self) -> u64 {
        self.clock.now_ns()
    }

    fn spin_until(&self, t_ns: u64) {
        self.clock.spin_until(t_ns);
    }
}

impl FrameTimer for PacedClock {
    fn sleep_until(&self, t_ns: u64) {
        let real = Duration::from_secs_f64(t_ns as f64 * 1e-9 / self.speedup);
        let due = self.start + real;
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        self.clock.sleep_until(t_ns);
    }
}

impl Platform for PacedTime {
    type Timer = PacedClock;

    fn name(&self) -> &'static str {
        "virtual (paced)"
    }

    fn virtual_time(&self) -> bool {
        true
    }

    fn timer(&self) -> PacedClock {
        PacedClock {
            clock: VirtualClock::new(),
            start: Instant::now(),
            speedup: self.speedup,
        }
    }

    fn make_realtime(&self, _config: &RtConfig) -> RtReport {
        RtReport::none()
    }

    fn serial_opener(&self) -> crate::serial::SerialOpener {
        crate::serial::no_serial_ports
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn virtual_time_keeps_pace_with_the_real_clock_times_n() {
        let timer = PacedTime { speedup: 10.0 }.timer();
        let start = Instant::now();
        // 300 ms of virtual time in 10 ms frames: 30 ms of real time at 10×.
        for frame in 1..=30u64 {
            timer.sleep_until(frame * 10_000_000);
        }
        let took = start.elapsed();
        assert_eq!(timer.now_ns(), 300_000_000);
        assert!(took >= Duration::from_millis(29), "{took:?}");
        assert!(took < Duration::from_millis(200), "{took:?}");
    }
}

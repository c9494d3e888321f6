//! Time, as the platform provides it.

/// A monotonic clock in nanoseconds since an arbitrary origin (the executive's `t_ns`).
pub trait Clock {
    fn now_ns(&self) -> u64;

    /// Spends time until `t_ns` without giving up the CPU. Only fault injection uses this (a
    /// task "forced to overrun"); a virtual clock overrides it to jump ahead.
    fn spin_until(&self, t_ns: u64) {
        while self.now_ns() < t_ns {
            core::hint::spin_loop();
        }
    }
}

/// What the frame loop waits on between frames. Blocking is allowed here, and only here:
/// the executive calls it between frames, never inside a task.
pub trait FrameTimer: Clock {
    /// Returns at (or as soon as possible after) the absolute time `t_ns`.
    fn sleep_until(&self, t_ns: u64);
}

impl<C: Clock + ?Sized> Clock for &C {
    fn now_ns(&self) -> u64 {
        (**self).now_ns()
    }
    fn spin_until(&self, t_ns: u64) {
        (**self).spin_until(t_ns)
    }
}

impl<T: FrameTimer + ?Sized> FrameTimer for &T {
    fn sleep_until(&self, t_ns: u64) {
        (**self).sleep_until(t_ns)
    }
}

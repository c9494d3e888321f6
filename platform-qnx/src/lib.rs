//! QNX Neutrino back ends for the shell: the frame timer, the real-time settings (clock
//! period, `SCHED_FIFO`, `mlockall`) and termios serial ports.
//!
//! Only the calls that exist on QNX alone (`ClockPeriod`, `ThreadCtl`) sit under
//! `cfg(target_os = "nto")`. The rest is POSIX, compiles on Linux and is tested there: the
//! termios port against real pseudo-terminals, the timer against the real clock, the choice
//! of clock period as a pure function.

use skyframe_core::executive::{Clock, FrameTimer};
use skyframe_shell::platform::{Platform, RtConfig, RtReport};
use skyframe_shell::serial::SerialOpener;

pub mod clock_period;
pub mod realtime;
pub mod serial;

/// `CLOCK_MONOTONIC`, counted from when the timer was made; frames are released on absolute
/// deadlines with `clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME)`, so a late wake-up never
/// shifts the following frames.
///
/// The same timer as platform-linux's `LinuxTimer`, on libc instead of nix (nix does not
/// build for QNX). platform-linux keeps its own copy rather than depend on this crate.
pub struct QnxTimer {
    origin_ns: u64,
}

/// The monotonic clock in nanoseconds.
#[allow(unsafe_code)]
fn monotonic_ns() -> u64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `t` is a valid timespec for the call to write; the call keeps no pointer.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut t) };
    // CLOCK_MONOTONIC cannot fail with a valid pointer; 0 keeps the type total.
    if rc != 0 {
        return 0;
    }
    (t.tv_sec as u64)
        .saturating_mul(1_000_000_000)
        .saturating_add(t.tv_nsec as u64)
}

impl QnxTimer {
    pub fn new() -> Self {
        Self {
            origin_ns: monotonic_ns(),
        }
    }
}

impl Default for QnxTimer {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for QnxTimer {
    fn now_ns(&self) -> u64 {
        monotonic_ns().saturating_sub(self.origin_ns)
    }
}

impl FrameTimer for QnxTimer {
    #[allow(unsafe_code)]
    fn sleep_until(&self, t_ns: u64) {
        let absolute = self.origin_ns.saturating_add(t_ns);
        let deadline = libc::timespec {
            tv_sec: (absolute / 1_000_000_000) as libc::time_t,
            tv_nsec: (absolute % 1_000_000_000) as libc::c_long,
        };
        // A signal interrupts the sleep (EINTR); sleep again to the same absolute time. The
        // frame loop sees a stop request once the frame has run.
        loop {
            // SAFETY: `deadline` is a valid timespec that outlives the call; the remaining
            // time is not wanted with TIMER_ABSTIME, and a null pointer says so.
            let rc = unsafe {
                libc::clock_nanosleep(
                    libc::CLOCK_MONOTONIC,
                    libc::TIMER_ABSTIME as _,
                    &deadline,
                    std::ptr::null_mut(),
                )
            };
            // clock_nanosleep returns the error number instead of setting errno.
            if rc != libc::EINTR {
                break;
            }
        }
    }
}

/// The QNX Neutrino platform.
#[derive(Default)]
pub struct Qnx;

impl Platform for Qnx {
    type Timer = QnxTimer;

    fn name(&self) -> &'static str {
        "qnx"
    }

    fn timer(&self) -> QnxTimer {
        QnxTimer::new()
    }

    fn make_realtime(&self, config: &RtConfig) -> RtReport {
        realtime::apply(config)
    }

    fn serial_opener(&self) -> SerialOpener {
        serial::open
    }

    fn free_space_probe(&self) -> Option<skyframe_shell::platform::FreeSpaceProbe> {
        Some(free_space)
    }
}

/// Bytes an unprivileged process may still write where `path` is: POSIX `statvfs`
/// (available blocks × fragment size), through libc as everything here.
#[allow(unsafe_code)]
#[allow(clippy::useless_conversion)] // the field types differ between targets
fn free_space(path: &std::path::Path) -> std::io::Result<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c_path = std::ffi::CString::new(path.as_os_str().as_bytes())
        .map_err(|_| std::io::Error::from(std::io::ErrorKind::InvalidInput))?;
    let mut stat = std::mem::MaybeUninit::<libc::statvfs>::zeroed();
    // SAFETY: `c_path` is a NUL-terminated string that outlives the call; `stat` points to
    // writable memory of the struct's size, which statvfs fills on success (zeroed before).
    let rc = unsafe { libc::statvfs(c_path.as_ptr(), stat.as_mut_ptr()) };
    if rc != 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: statvfs returned 0, so it wrote the struct (and it was zeroed before anyway).
    let stat = unsafe { stat.assume_init() };
    Ok(u64::from(stat.f_bavail).saturating_mul(u64::from(stat.f_frsize)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_space_is_measured_and_a_missing_path_is_an_error() {
        let free = free_space(&std::env::temp_dir()).expect("statvfs");
        assert!(free > 0);
        assert!(free_space(std::path::Path::new("/nonexistent/dir")).is_err());
    }

    #[test]
    fn the_timer_wakes_at_the_absolute_deadline_not_before() {
        let timer = QnxTimer::new();
        for frame in 1..=20u64 {
            let deadline = frame * 2_000_000;
            timer.sleep_until(deadline);
            let now = timer.now_ns();
            assert!(now >= deadline, "woke at {now} ns before {deadline} ns");
        }
        // Deadlines are absolute: 20 frames of 2 ms end at 40 ms plus one wake-up's lateness,
        // not 20 of them (a loaded CI machine may be late, but not by a whole frame each).
        let end = timer.now_ns();
        assert!(end < 40_000_000 + 20_000_000, "drifted to {end} ns");
    }

    #[test]
    fn a_deadline_in_the_past_returns_at_once() {
        let timer = QnxTimer::new();
        timer.sleep_until(5_000_000);
        let before = timer.now_ns();
        timer.sleep_until(1_000_000);
        assert!(timer.now_ns() - before < 5_000_000);
    }
}

//! Linux back ends for the shell: the frame timer and the real-time settings.
//!
//! Frames are released on absolute deadlines with `clock_nanosleep(CLOCK_MONOTONIC,
//! TIMER_ABSTIME)`, so a late wake-up never shifts the following frames (relative sleeps
//! would accumulate drift).

use nix::sys::time::TimeSpec;
use nix::time::{ClockId, ClockNanosleepFlags, clock_gettime, clock_nanosleep};
use skyframe_core::executive::{Clock, FrameTimer};
use skyframe_shell::platform::{Platform, RtConfig, RtReport};
use skyframe_shell::serial::SerialOpener;

/// `CLOCK_MONOTONIC`, counted from when the timer was made.
pub struct LinuxTimer {
    origin_ns: u64,
}

fn monotonic_ns() -> u64 {
    // CLOCK_MONOTONIC cannot fail on Linux with a valid pointer; 0 keeps the type total.
    clock_gettime(ClockId::CLOCK_MONOTONIC).map_or(0, |t| {
        (t.tv_sec() as u64)
            .saturating_mul(1_000_000_000)
            .saturating_add(t.tv_nsec() as u64)
    })
}

impl LinuxTimer {
    pub fn new() -> Self {
        Self {
            origin_ns: monotonic_ns(),
        }
    }
}

impl Default for LinuxTimer {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for LinuxTimer {
    fn now_ns(&self) -> u64 {
        monotonic_ns().saturating_sub(self.origin_ns)
    }
}

impl FrameTimer for LinuxTimer {
    fn sleep_until(&self, t_ns: u64) {
        let absolute = self.origin_ns.saturating_add(t_ns);
        let deadline = TimeSpec::new(
            (absolute / 1_000_000_000) as libc::time_t,
            (absolute % 1_000_000_000) as libc::c_long,
        );
        // A signal interrupts the sleep (EINTR); sleep again to the same absolute time. The
        // frame loop sees a stop request once the frame has run.
        while let Err(nix::errno::Errno::EINTR) = clock_nanosleep(
            ClockId::CLOCK_MONOTONIC,
            ClockNanosleepFlags::TIMER_ABSTIME,
            &deadline,
        ) {}
    }
}

pub mod realtime;
pub mod serial;

/// The Linux platform.
#[derive(Default)]
pub struct Linux;

impl Platform for Linux {
    type Timer = LinuxTimer;

    fn name(&self) -> &'static str {
        "linux"
    }

    fn timer(&self) -> LinuxTimer {
        LinuxTimer::new()
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

/// Bytes an unprivileged process may still write where `path` is (`statvfs`: available
/// blocks × fragment size).
// The counts are u64 on 64-bit Linux and u32 on some 32-bit targets: the conversion is
// needed there.
#[allow(clippy::useless_conversion)]
fn free_space(path: &std::path::Path) -> std::io::Result<u64> {
    let stat = nix::sys::statvfs::statvfs(path).map_err(std::io::Error::from)?;
    Ok(u64::from(stat.blocks_available()).saturating_mul(u64::from(stat.fragment_size())))
}

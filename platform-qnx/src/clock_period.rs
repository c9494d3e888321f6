//! The system clock period: QNX's tick, on which every timer expiry and sleep ends.
//!
//! QNX's default tick is 1 ms, so an absolute `clock_nanosleep` wakes on the first tick
//! after its deadline: up to a millisecond late, and a 10 ms frame's wake-ups jitter with
//! it. A shorter period that divides the minor frame puts every release on a tick. The
//! period is system-wide (`ClockPeriod(CLOCK_REALTIME)`): it is set at start and the old one
//! given back at exit ([`restore`], called by the binary's `main`).

use skyframe_shell::platform::{RtConfig, Setting};

/// The shortest period QNX accepts on any machine (ClockPeriod() documentation: "the lowest
/// clock period that can currently be set on any machine is 10 microseconds").
pub const MIN_PERIOD_NS: u64 = 10_000;
/// The longest we ask for: QNX's default tick on CPUs of 40 MHz and more. A coarser tick
/// would only make wake-ups later.
pub const MAX_PERIOD_NS: u64 = 1_000_000;

/// The period to ask for: the longest one no longer than `requested_ns` that divides the
/// minor frame (so every frame boundary falls on a tick) and that QNX allows.
pub fn choose(requested_ns: u64, minor_frame_ns: Option<u64>) -> Result<u64, String> {
    if !(MIN_PERIOD_NS..=MAX_PERIOD_NS).contains(&requested_ns) {
        return Err(format!(
            "{requested_ns} ns is outside {MIN_PERIOD_NS}..={MAX_PERIOD_NS} ns"
        ));
    }
    let Some(minor) = minor_frame_ns else {
        return Ok(requested_ns);
    };
    if minor == 0 {
        return Err("the minor frame is 0 ns".to_string());
    }
    // The periods dividing the minor frame are minor / k; the first k whose quotient is no
    // longer than the request gives the longest such period.
    let first_k = minor.div_ceil(requested_ns);
    (first_k..=minor / MIN_PERIOD_NS)
        .find(|k| minor % k == 0)
        .map(|k| minor / k)
        .ok_or_else(|| {
            format!(
                "no period from {MIN_PERIOD_NS} to {requested_ns} ns divides the {minor} ns \
                 minor frame"
            )
        })
}

/// Sets the clock period `config` asks for (see [`choose`]); reports the period the kernel
/// then runs with (it may round to what the timer hardware can do).
pub fn apply(config: &RtConfig) -> Setting<u64> {
    Setting::attempt(config.clock_period_ns, |requested| {
        let period = choose(requested, config.minor_frame_ns)?;
        set(period)
    })
}

#[cfg(not(target_os = "nto"))]
fn set(_period_ns: u64) -> Result<u64, String> {
    Err("ClockPeriod exists on QNX only".to_string())
}

/// Gives the system back the clock period it had before [`apply`] (nothing if it was never
/// changed).
#[cfg(not(target_os = "nto"))]
pub fn restore() {}

#[cfg(target_os = "nto")]
pub use nto::restore;
#[cfg(target_os = "nto")]
use nto::set;

/// The QNX kernel calls. libc declares `ClockPeriod` and `struct _clockperiod` for nto.
#[cfg(target_os = "nto")]
#[allow(unsafe_code)]
mod nto {
    use std::sync::atomic::{AtomicU32, Ordering};

    /// The period before the first change, in ns (0: never changed).
    static ORIGINAL_NS: AtomicU32 = AtomicU32::new(0);

    fn clock_period(new: Option<u32>) -> Result<u32, String> {
        let new = new.map(|nsec| libc::_clockperiod { nsec, fract: 0 });
        let mut old = libc::_clockperiod { nsec: 0, fract: 0 };
        let new_ptr = new.as_ref().map_or(std::ptr::null(), |p| p as *const _);
        // SAFETY: `new_ptr` is null (only read the period) or points at `new`, and `old` is
        // a valid _clockperiod to write; both outlive the call, which keeps no pointer.
        let rc = unsafe { libc::ClockPeriod(libc::CLOCK_REALTIME, new_ptr, &mut old, 0) };
        if rc == -1 {
            return Err(std::io::Error::last_os_error().to_string());
        }
        Ok(old.nsec)
    }

    pub(super) fn set(period_ns: u64) -> Result<u64, String> {
        let nsec = u32::try_from(period_ns).map_err(|_| format!("{period_ns} ns is too long"))?;
        let old = clock_period(Some(nsec))?;
        // Only the first change remembers: a second run in the same process (bench) must
        // not take our own period for the system's.
        let _ = ORIGINAL_NS.compare_exchange(0, old, Ordering::Relaxed, Ordering::Relaxed);
        clock_period(None).map(u64::from)
    }

    pub fn restore() {
        let old = ORIGINAL_NS.swap(0, Ordering::Relaxed);
        if old != 0 {
            if let Err(e) = clock_period(Some(old)) {
                log::warn!("cannot restore the clock period to {old} ns: {e}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    #[test]
    fn a_request_that_divides_the_frame_is_taken_as_is() {
        assert_eq!(choose(100_000, Some(10 * MS)), Ok(100_000));
        assert_eq!(choose(MS, Some(10 * MS)), Ok(MS));
        assert_eq!(choose(10_000, Some(10 * MS)), Ok(10_000));
    }

    #[test]
    fn otherwise_the_longest_divisor_below_the_request() {
        // 10 ms / 300 us is not whole; 10 ms / 34 = 294.1 us is not either; 10 ms / 40 =
        // 250 us is the longest whole divisor under 300 us.
        assert_eq!(choose(300_000, Some(10 * MS)), Ok(250_000));
        // A 7 ms frame: 7 ms / 8 = 875 us.
        assert_eq!(choose(900_000, Some(7 * MS)), Ok(875_000));
        // A frame shorter than the request is its own period.
        assert_eq!(choose(MS, Some(500_000)), Ok(500_000));
    }

    #[test]
    fn every_choice_divides_the_frame_and_stays_in_range() {
        for minor in [2 * MS, 5 * MS, 10 * MS, 20 * MS, 3_333_333, 12_345_678] {
            for requested in [10_000, 33_333, 100_000, 250_000, 999_999, MS] {
                match choose(requested, Some(minor)) {
                    Ok(p) => {
                        assert_eq!(minor % p, 0, "{p} does not divide {minor}");
                        assert!((MIN_PERIOD_NS..=requested).contains(&p));
                    }
                    // Only when no divisor of the frame lies in range.
                    Err(_) => assert!(
                        (MIN_PERIOD_NS..=requested).all(|p| minor % p != 0),
                        "{requested} for {minor}"
                    ),
                }
            }
        }
    }

    #[test]
    fn out_of_range_requests_and_frames_without_a_divisor_are_refused() {
        assert!(choose(5_000, Some(10 * MS)).is_err());
        assert!(choose(2 * MS, Some(10 * MS)).is_err());
        assert!(choose(100_000, Some(0)).is_err());
        // 1_000_003 ns is prime: no period from 10 to 20 us divides it.
        assert!(
            choose(20_000, Some(1_000_003)).is_err_and(|e| e.contains("divides the 1000003 ns"))
        );
    }

    #[test]
    fn without_a_frame_the_request_stands() {
        assert_eq!(choose(123_456, None), Ok(123_456));
    }

    #[cfg(not(target_os = "nto"))]
    #[test]
    fn off_qnx_the_setting_is_refused_not_faked() {
        let config = RtConfig {
            minor_frame_ns: Some(10 * MS),
            ..RtConfig::default()
        };
        assert!(apply(&config).refusal().is_some_and(|e| e.contains("QNX")));
        let none = RtConfig {
            clock_period_ns: None,
            ..config
        };
        assert_eq!(apply(&none), Setting::NotAsked);
    }
}

//! Real-time settings of the executive thread on QNX, each best effort.
//!
//! POSIX calls (pthread_setschedparam, mlockall) compile and run on Linux too; the QNX-only
//! ones (ClockPeriod, ThreadCtl) are under `cfg(target_os = "nto")`.

use crate::clock_period;
use skyframe_shell::platform::{RtConfig, RtReport, Setting};

/// Applies `config` to the calling thread and the process; reports what each setting came to.
pub fn apply(config: &RtConfig) -> RtReport {
    RtReport {
        clock_period_ns: clock_period::apply(config),
        sched_fifo_priority: Setting::attempt(config.fifo_priority, set_fifo),
        mlockall: Setting::attempt(config.lock_memory.then_some(()), |()| lock_memory()),
        cpu: Setting::attempt(config.cpu, pin_to_cpu),
        // Linux knobs with no QNX counterpart: QNX timers expire on the tick (the clock
        // period above), not within a slack, and it has no PM QoS file. Not refusals: a
        // start on QNX should not warn about settings that do not exist there.
        timer_slack_ns: Setting::NotAsked,
        cpu_dma_latency_us: Setting::NotAsked,
    }
}

/// `SCHED_FIFO` at `priority` for the calling thread.
///
/// pthread_setschedparam, not sched_setscheduler: QNX schedules threads, and its
/// sched_setscheduler(0, ..) sets the calling thread but sched_setscheduler(pid, ..) sets
/// thread 1 of the process — the thread-level call says what is meant on every system.
/// Priorities above 63 need the PROCMGR_AID_PRIORITY ability on QNX (root has it).
#[allow(unsafe_code)]
pub fn set_fifo(priority: u8) -> Result<u8, String> {
    // QNX's sched_param has more (sporadic scheduling, private) fields; zero is "unused".
    let mut param = zeroed_sched_param();
    param.sched_priority = libc::c_int::from(priority);
    // SAFETY: pthread_self() is the calling thread, alive during the call; `param` is a
    // valid, initialised sched_param that outlives it; the call keeps no pointer.
    let rc = unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
    // pthread functions return the error number instead of setting errno.
    if rc == 0 {
        Ok(priority)
    } else {
        Err(std::io::Error::from_raw_os_error(rc).to_string())
    }
}

/// A sched_param of zeros, whatever fields the platform's has.
#[allow(unsafe_code)]
fn zeroed_sched_param() -> libc::sched_param {
    // SAFETY: sched_param is a plain C struct of integers (and, on QNX, a union of them and
    // timespecs), for which all-zero bytes are a valid value.
    unsafe { std::mem::zeroed() }
}

/// Locks all current and future pages: no page fault (or lazy allocation) stalls a frame.
/// QNX needs the PROCMGR_AID_MEM_LOCK ability for it (root has it).
#[allow(unsafe_code)]
fn lock_memory() -> Result<String, String> {
    // SAFETY: mlockall takes flags only and touches no memory of ours.
    let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if rc == 0 {
        Ok("current and future pages".to_string())
    } else {
        Err(std::io::Error::last_os_error().to_string())
    }
}

/// Pins the calling thread to `cpu` with its run mask (`ThreadCtl(_NTO_TCTL_RUNMASK)`: one
/// bit per CPU, so CPUs 0 to 31).
#[cfg(target_os = "nto")]
#[allow(unsafe_code)]
fn pin_to_cpu(cpu: usize) -> Result<usize, String> {
    let mask = u32::try_from(cpu)
        .ok()
        .and_then(|c| 1u32.checked_shl(c))
        .ok_or_else(|| format!("CPU {cpu}: the run mask reaches CPU 31"))?;
    // SAFETY: with _NTO_TCTL_RUNMASK the data argument is the mask itself, passed in the
    // pointer's bits and never dereferenced; the call affects only the calling thread.
    let rc = unsafe {
        libc::ThreadCtl(
            libc::_NTO_TCTL_RUNMASK as libc::c_int,
            std::ptr::without_provenance_mut(mask as usize),
        )
    };
    if rc == -1 {
        Err(format!("CPU {cpu}: {}", std::io::Error::last_os_error()))
    } else {
        Ok(cpu)
    }
}

/// Off QNX this crate only runs in tests; skyframe-linux pins with sched_setaffinity.
#[cfg(not(target_os = "nto"))]
fn pin_to_cpu(cpu: usize) -> Result<usize, String> {
    Err(format!(
        "CPU {cpu}: pinning is implemented for QNX only (ThreadCtl)"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// In a thread of its own, so the test process keeps its scheduler whatever happens.
    #[test]
    #[allow(unsafe_code)]
    fn fifo_is_set_on_the_calling_thread_or_refused_with_the_reason() {
        let outcome = std::thread::spawn(|| {
            let result = set_fifo(10);
            let mut policy = 0;
            let mut param = zeroed_sched_param();
            // SAFETY: valid out-pointers for the calling thread's own policy and parameters.
            let rc = unsafe {
                libc::pthread_getschedparam(libc::pthread_self(), &mut policy, &mut param)
            };
            assert_eq!(rc, 0);
            (result, policy, param.sched_priority)
        })
        .join()
        .expect("thread");
        match outcome {
            (Ok(10), policy, priority) => {
                assert_eq!(policy, libc::SCHED_FIFO);
                assert_eq!(priority, 10);
            }
            (Err(why), policy, _) => {
                // Unprivileged: EPERM, said as the OS says it, and nothing changed.
                assert!(!why.is_empty());
                assert_ne!(policy, libc::SCHED_FIFO);
            }
            other => panic!("unexpected {other:?}"),
        }
    }

    #[test]
    fn linux_only_settings_are_not_asked_and_nothing_is_faked() {
        let report = apply(&RtConfig {
            fifo_priority: None,
            lock_memory: false,
            cpu: Some(0),
            clock_period_ns: None,
            ..RtConfig::default()
        });
        assert_eq!(report.timer_slack_ns, Setting::NotAsked);
        assert_eq!(report.cpu_dma_latency_us, Setting::NotAsked);
        assert_eq!(report.sched_fifo_priority, Setting::NotAsked);
        assert_eq!(report.mlockall, Setting::NotAsked);
        assert_eq!(report.clock_period_ns, Setting::NotAsked);
        #[cfg(not(target_os = "nto"))]
        assert!(report.cpu.refusal().is_some_and(|e| e.contains("QNX only")));
    }
}

//! Real-time settings of the executive thread, each best effort.

use nix::sched::{CpuSet, sched_setaffinity};
use nix::sys::mman::{MlockAllFlags, mlockall};
use nix::sys::resource::{Resource, getrlimit};
use nix::unistd::Pid;
use skyframe_shell::platform::{RtConfig, RtReport, Setting};

/// Applies `config` to the calling thread and the process; reports what each setting came to.
pub fn apply(config: &RtConfig) -> RtReport {
    RtReport {
        sched_fifo_priority: Setting::attempt(config.fifo_priority, set_fifo),
        mlockall: Setting::attempt(config.lock_memory.then_some(()), |()| lock_memory()),
        cpu: Setting::attempt(config.cpu, pin_to_cpu),
        cpu_dma_latency_us: Setting::attempt(config.cpu_dma_latency_us, hold_cpu_dma_latency),
        timer_slack_ns: Setting::attempt(config.timer_slack_ns, |ns| {
            nix::sys::prctl::set_timerslack(ns as libc::c_ulong)
                .map(|()| ns)
                .map_err(|e| e.desc().to_string())
        }),
        // Linux sleeps on hrtimers, not on a tick: there is no clock period to set.
        clock_period_ns: Setting::NotAsked,
    }
}

/// Locks the process's pages. Future pages too only when nothing limits locking: with
/// `MCL_FUTURE` under a finite `RLIMIT_MEMLOCK`, the next thread stack or heap growth past
/// the limit fails (a thread spawn returns EAGAIN), which would break the run we are trying
/// to protect.
fn lock_memory() -> Result<String, String> {
    let unlimited = getrlimit(Resource::RLIMIT_MEMLOCK)
        .map(|(soft, _)| soft == libc::RLIM_INFINITY)
        .unwrap_or(false);
    let future_too = unlimited || has_cap_ipc_lock();
    let flags = if future_too {
        MlockAllFlags::MCL_CURRENT | MlockAllFlags::MCL_FUTURE
    } else {
        MlockAllFlags::MCL_CURRENT
    };
    mlockall(flags).map_err(|e| e.desc().to_string())?;
    Ok(if future_too {
        "current and future pages".to_string()
    } else {
        "current pages only (RLIMIT_MEMLOCK is finite and CAP_IPC_LOCK is missing)".to_string()
    })
}

/// CAP_IPC_LOCK (bit 14) in the effective set, read from /proc/self/status.
fn has_cap_ipc_lock() -> bool {
    const CAP_IPC_LOCK: u32 = 14;
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            let hex = status.lines().find_map(|l| l.strip_prefix("CapEff:"))?;
            u64::from_str_radix(hex.trim(), 16).ok()
        })
        .is_some_and(|caps| caps & (1 << CAP_IPC_LOCK) != 0)
}

/// The open `/dev/cpu_dma_latency`: the request lasts while the file stays open, so it is
/// kept for the life of the process.
static CPU_DMA_LATENCY: std::sync::Mutex<Option<std::fs::File>> = std::sync::Mutex::new(None);

fn hold_cpu_dma_latency(us: u32) -> Result<u32, String> {
    use std::io::Write;
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/cpu_dma_latency")
        .map_err(|e| format!("/dev/cpu_dma_latency: {e}"))?;
    // The PM QoS interface takes a native-endian 32-bit integer.
    let value = i32::try_from(us).unwrap_or(i32::MAX);
    file.write_all(&value.to_ne_bytes())
        .map_err(|e| format!("/dev/cpu_dma_latency: {e}"))?;
    let mut held = CPU_DMA_LATENCY.lock().unwrap_or_else(|p| p.into_inner());
    *held = Some(file);
    Ok(us)
}

fn pin_to_cpu(cpu: usize) -> Result<usize, String> {
    let mut set = CpuSet::new();
    set.set(cpu)
        .map_err(|e| format!("CPU {cpu}: {}", e.desc()))?;
    sched_setaffinity(Pid::from_raw(0), &set)
        .map(|()| cpu)
        .map_err(|e| format!("CPU {cpu}: {}", e.desc()))
}

/// `SCHED_FIFO` at `priority` for the calling thread. nix has no `sched_setscheduler`, so this
/// is the one place the platform calls libc directly.
#[allow(unsafe_code)]
fn set_fifo(priority: u8) -> Result<u8, String> {
    let param = libc::sched_param {
        sched_priority: libc::c_int::from(priority),
    };
    // SAFETY: `param` is a valid, initialised sched_param that outlives the call; pid 0 means
    // the calling thread; the call has no other memory effects.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(priority)
    } else {
        Err(std::io::Error::last_os_error().to_string())
    }
}

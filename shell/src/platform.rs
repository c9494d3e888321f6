//! What a platform crate provides to the shell.

use crate::serial::SerialOpener;
use skyframe_core::executive::FrameTimer;

/// Real-time settings asked of the executive thread. Each is best effort: where the OS
/// refuses (no permission, no such CPU), the run goes on and the refusal is reported once.
#[derive(Clone, Debug)]
pub struct RtConfig {
    /// `SCHED_FIFO` priority (1..=99); `None` leaves the default scheduler.
    pub fifo_priority: Option<u8>,
    /// Lock all current and future pages in RAM (`mlockall`), so no page fault stalls a frame.
    pub lock_memory: bool,
    /// Pin the executive thread to one CPU.
    pub cpu: Option<usize>,
    /// Timer slack of the executive thread (Linux coalesces wake-ups within it; 1 ns asks
    /// for none).
    pub timer_slack_ns: Option<u64>,
    /// Ask the kernel to keep CPUs out of idle states slower to leave than this (Linux
    /// `/dev/cpu_dma_latency`, held for the whole run). 0 keeps them awake: the lowest
    /// wake-up latency, at the cost of power.
    pub cpu_dma_latency_us: Option<u32>,
    /// The system clock period (the tick) to ask for, on systems whose sleeps end on ticks
    /// (QNX `ClockPeriod`: its default 1 ms tick quantises every wake-up). The platform
    /// picks the largest period at most this long that divides the minor frame. Linux has
    /// no such tick (hrtimers) and ignores it.
    pub clock_period_ns: Option<u64>,
    /// The minor frame of the table about to run, for settings that must fit it (the clock
    /// period). Filled in by the shell from the frame table, not by the user.
    pub minor_frame_ns: Option<u64>,
}

impl Default for RtConfig {
    fn default() -> Self {
        Self {
            fifo_priority: Some(80),
            lock_memory: true,
            cpu: None,
            timer_slack_ns: Some(1),
            cpu_dma_latency_us: Some(0),
            clock_period_ns: Some(100_000),
            minor_frame_ns: None,
        }
    }
}

/// What one real-time setting came to.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(tag = "status", content = "value", rename_all = "snake_case")]
pub enum Setting<T> {
    NotAsked,
    Granted(T),
    /// The OS said no; the reason as it said it.
    Refused(String),
}

impl<T> Setting<T> {
    /// `NotAsked` for `None`, else what the attempt returned.
    pub fn attempt<A>(asked: Option<A>, f: impl FnOnce(A) -> Result<T, String>) -> Self {
        match asked.map(f) {
            None => Self::NotAsked,
            Some(Ok(v)) => Self::Granted(v),
            Some(Err(e)) => Self::Refused(e),
        }
    }

    pub fn refusal(&self) -> Option<&str> {
        match self {
            Self::Refused(why) => Some(why),
            _ => None,
        }
    }
}

/// What each real-time setting came to.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RtReport {
    pub sched_fifo_priority: Setting<u8>,
    /// Which pages were locked.
    pub mlockall: Setting<String>,
    pub cpu: Setting<usize>,
    pub timer_slack_ns: Setting<u64>,
    pub cpu_dma_latency_us: Setting<u32>,
    /// The system clock period now in force (QNX; `NotAsked` where there is no tick).
    pub clock_period_ns: Setting<u64>,
}

impl RtReport {
    /// Nothing asked (a platform without real-time controls).
    pub fn none() -> Self {
        Self {
            sched_fifo_priority: Setting::NotAsked,
            mlockall: Setting::NotAsked,
            cpu: Setting::NotAsked,
            timer_slack_ns: Setting::NotAsked,
            cpu_dma_latency_us: Setting::NotAsked,
            clock_period_ns: Setting::NotAsked,
        }
    }

    /// One line per refused setting, for stderr at start.
    pub fn refusals(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(e) = self.sched_fifo_priority.refusal() {
            out.push(format!(
                "SCHED_FIFO refused ({e}): running with the default scheduler"
            ));
        }
        if let Some(e) = self.mlockall.refusal() {
            out.push(format!(
                "mlockall refused ({e}): pages may fault during frames"
            ));
        }
        if let Some(e) = self.cpu.refusal() {
            out.push(format!(
                "CPU pinning refused ({e}): the executive may migrate"
            ));
        }
        if let Some(e) = self.timer_slack_ns.refusal() {
            out.push(format!("timer slack refused ({e})"));
        }
        if let Some(e) = self.cpu_dma_latency_us.refusal() {
            out.push(format!(
                "cpu_dma_latency refused ({e}): CPUs may sleep deeply between frames"
            ));
        }
        if let Some(e) = self.clock_period_ns.refusal() {
            out.push(format!(
                "clock period refused ({e}): wake-ups are quantised to the default tick"
            ));
        }
        out
    }
}

/// An operating system the executive can run on.
pub trait Platform {
    type Timer: FrameTimer;

    /// Short name for reports (`linux`, `qnx`, `sim`).
    fn name(&self) -> &'static str;

    /// True when time is simulated: the executive may then wait for slow consumers instead
    /// of dropping what they cannot take (there is no deadline to miss).
    fn virtual_time(&self) -> bool {
        false
    }

    /// A frame timer whose clock starts at zero now.
    fn timer(&self) -> Self::Timer;

    /// Applies `config` to the calling thread (the executive thread) and the process.
    fn make_realtime(&self, config: &RtConfig) -> RtReport;

    /// How this platform opens serial ports (see [`SerialOpener`]); platforms without any
    /// give [`crate::serial::no_serial_ports`].
    fn serial_opener(&self) -> SerialOpener;

    /// How to measure the free space where a directory is (`statvfs`), for the log's space
    /// check and its health; `None` where the platform has no way (the check is skipped
    /// and the space reported unknown).
    fn free_space_probe(&self) -> Option<FreeSpaceProbe> {
        None
    }
}

/// Bytes free (for an unprivileged writer) on the file system holding a path.
pub type FreeSpaceProbe = fn(&std::path::Path) -> std::io::Result<u64>;

//! What a platform crate provides to the shell.

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
}

impl Default for RtConfig {
    fn default() -> Self {
        Self {
            fifo_priority: Some(80),
            lock_memory: true,
            cpu: None,
            timer_slack_ns: Some(1),
        }
    }
}

/// What each real-time setting came to.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RtReport {
    /// `Some(Ok(priority))` when granted, `Some(Err(why))` when refused, `None` when not asked.
    pub sched_fifo: Option<Result<u8, String>>,
    pub mlockall: Option<Result<(), String>>,
    pub cpu: Option<Result<usize, String>>,
    pub timer_slack_ns: Option<Result<u64, String>>,
}

impl RtReport {
    /// One line per refused setting, for stderr at start.
    pub fn refusals(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(Err(e)) = &self.sched_fifo {
            out.push(format!("SCHED_FIFO refused ({e}): running with the default scheduler"));
        }
        if let Some(Err(e)) = &self.mlockall {
            out.push(format!("mlockall refused ({e}): pages may fault during frames"));
        }
        if let Some(Err(e)) = &self.cpu {
            out.push(format!("CPU pinning refused ({e}): the executive may migrate"));
        }
        if let Some(Err(e)) = &self.timer_slack_ns {
            out.push(format!("timer slack refused ({e})"));
        }
        out
    }
}

/// An operating system the executive can run on.
pub trait Platform {
    type Timer: FrameTimer;

    /// Short name for reports (`linux`, `qnx`, `sim`).
    fn name(&self) -> &'static str;

    /// A frame timer whose clock starts at zero now.
    fn timer(&self) -> Self::Timer;

    /// Applies `config` to the calling thread (the executive thread) and the process.
    fn make_realtime(&self, config: &RtConfig) -> RtReport;
}

//! Runs the executive on the calling thread, hands its timing records to a consumer thread,
//! and ends the run cleanly on a stop request, a signal or the programmed duration.

use crate::platform::{Platform, RtConfig, RtReport};
use crate::ring::RingSink;
use skyframe_core::executive::{
    Executive, FaultPlan, FrameRecord, FrameStats, StartError, Task, TaskHealth,
};
use skyframe_core::schedule::FrameTable;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Timing records buffered between the executive and their consumer: 10 s of 10 ms frames.
const TIMING_RING: usize = 1024;

/// Why a run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The programmed duration elapsed.
    Duration,
    /// SIGINT/SIGTERM or a stop command.
    Requested,
}

pub struct RunOptions<'a> {
    pub duration: Option<Duration>,
    pub faults: FaultPlan,
    pub realtime: RtConfig,
    /// Set by signal handlers or a stop command; checked between frames.
    pub stop: &'a AtomicBool,
}

/// Why a run could not start.
#[derive(Debug)]
pub enum HostError {
    /// The executive refused the task list or the table.
    Start(StartError),
    /// The OS would not give us a thread (e.g. memory limits).
    Spawn(std::io::Error),
}

impl std::fmt::Display for HostError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Start(e) => write!(f, "the executive did not start: {e:?}"),
            Self::Spawn(e) => write!(f, "cannot start a shell thread: {e}"),
        }
    }
}

/// What a run leaves behind for the summary.
#[derive(Clone, Debug)]
pub struct RunSummary {
    pub table: &'static FrameTable,
    pub realtime: RtReport,
    pub stop_reason: StopReason,
    /// Time from the first release to the end of the last frame.
    pub elapsed_ns: u64,
    pub frames: FrameStats,
    pub tasks: Vec<TaskHealth>,
}

/// Runs `tasks` (one per slot of `table`, in table order) until the duration elapses or
/// `stop` is set. Each frame's timing record reaches `on_record` on a separate thread; all of
/// them, in order, before this function returns.
pub fn run_executive<P: Platform>(
    platform: &P,
    table: &'static FrameTable,
    tasks: &mut [&mut dyn Task],
    options: RunOptions<'_>,
    on_record: impl FnMut(&FrameRecord) + Send,
) -> Result<RunSummary, HostError> {
    let realtime = platform.make_realtime(&options.realtime);
    for refusal in realtime.refusals() {
        log::warn!("{refusal}");
    }
    let timer = platform.timer();
    let (producer, consumer) = rtrb::RingBuffer::<FrameRecord>::new(TIMING_RING);
    let executive_done = AtomicBool::new(false);

    std::thread::scope(|scope| {
        std::thread::Builder::new()
            .name("timing-drain".into())
            .stack_size(256 * 1024)
            .spawn_scoped(scope, || {
                drain_records(consumer, &executive_done, on_record)
            })
            .map_err(HostError::Spawn)?;

        let sink = if platform.virtual_time() {
            RingSink::waiting(producer)
        } else {
            RingSink::new(producer)
        };
        let result = fly(table, &timer, tasks, &options, sink);
        executive_done.store(true, Ordering::Release);
        result
            .map_err(HostError::Start)
            .map(|(stop_reason, elapsed_ns, frames, health)| RunSummary {
                table,
                realtime,
                stop_reason,
                elapsed_ns,
                frames,
                tasks: health,
            })
    })
}

type Flown = (StopReason, u64, FrameStats, Vec<TaskHealth>);

fn fly<T: skyframe_core::executive::FrameTimer>(
    table: &'static FrameTable,
    timer: &T,
    tasks: &mut [&mut dyn Task],
    options: &RunOptions<'_>,
    mut sink: RingSink<FrameRecord>,
) -> Result<Flown, StartError> {
    let mut executive = Executive::new(table, timer);
    executive.set_faults(options.faults.clone());
    // Frame 0 one minor frame from now: init has had its time, the first frame starts clean.
    let first_release = timer.now_ns() + table.minor_frame_ns;
    executive.start(tasks, first_release)?;
    let end = options
        .duration
        .map(|d| first_release.saturating_add(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)));
    let mut reason = StopReason::Requested;
    executive.run_until(tasks, &mut sink, |e| {
        if options.stop.load(Ordering::Relaxed) {
            reason = StopReason::Requested;
            return true;
        }
        if end.is_some_and(|end| e.next_release_ns() >= end) {
            reason = StopReason::Duration;
            return true;
        }
        false
    });
    let elapsed = timer.now_ns().saturating_sub(first_release);
    executive.shutdown(tasks);
    let health = executive.health();
    let tasks = (0..health.task_count())
        .filter_map(|i| health.task(i).copied())
        .collect();
    Ok((reason, elapsed, health.frames, tasks))
}

/// Empties the ring until the executive is done and the ring is empty.
fn drain_records(
    mut consumer: rtrb::Consumer<FrameRecord>,
    executive_done: &AtomicBool,
    mut on_record: impl FnMut(&FrameRecord),
) {
    loop {
        // Read the flag first: records pushed before it was set are then certain to be seen.
        let done = executive_done.load(Ordering::Acquire);
        while let Ok(record) = consumer.pop() {
            on_record(&record);
        }
        if done {
            return;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Registers SIGINT and SIGTERM to set `flag` (checked by the frame loop between frames).
pub fn stop_on_signals(flag: &std::sync::Arc<AtomicBool>) -> std::io::Result<()> {
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, std::sync::Arc::clone(flag))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::idle::idle_tasks;
    use crate::platform::{RtReport, Setting};
    use skyframe_core::executive::{OverrunInjection, TaskContext, TaskFault};
    use skyframe_core::schedule::SHIPPED;
    use skyframe_sim::VirtualClock;
    use std::sync::Arc;

    /// Virtual time: a run of any length finishes at once and is exactly repeatable.
    struct Virtual;

    impl Platform for Virtual {
        type Timer = VirtualClock;
        fn name(&self) -> &'static str {
            "virtual"
        }
        fn timer(&self) -> VirtualClock {
            VirtualClock::new()
        }
        fn virtual_time(&self) -> bool {
            true
        }
        fn make_realtime(&self, _config: &RtConfig) -> RtReport {
            RtReport {
                sched_fifo_priority: Setting::Refused("virtual time".into()),
                ..RtReport::none()
            }
        }
    }

    fn options(stop: &AtomicBool, seconds: u64, faults: FaultPlan) -> RunOptions<'_> {
        RunOptions {
            duration: Some(Duration::from_secs(seconds)),
            faults,
            realtime: RtConfig::default(),
            stop,
        }
    }

    #[test]
    fn every_timing_record_reaches_the_consumer_in_order() {
        let stop = AtomicBool::new(false);
        let mut idle = idle_tasks(SHIPPED.tasks.len());
        let mut tasks: Vec<&mut dyn Task> = idle.iter_mut().map(|t| t as &mut dyn Task).collect();
        let mut seen = Vec::new();
        let summary = run_executive(
            &Virtual,
            &SHIPPED,
            &mut tasks,
            options(&stop, 60, FaultPlan::new()),
            |r| seen.push(r.frame),
        )
        .expect("starts");
        assert_eq!(summary.stop_reason, StopReason::Duration);
        assert_eq!(seen.len(), 6000, "60 s of 10 ms frames, none dropped");
        assert!(seen.windows(2).all(|w| w[1] == w[0] + 1));
        assert_eq!(summary.frames.timing_records_dropped, 0);
        assert_eq!(summary.tasks[0].releases, 6000);
        assert!(
            summary.tasks.iter().all(|t| !t.running),
            "every task was shut down"
        );
        assert_eq!(summary.realtime.refusals().len(), 1);
        drop(tasks);
        assert!(idle.iter().all(|t| t.steps() > 0));
    }

    #[test]
    fn a_stop_request_ends_the_run_between_frames() {
        struct Stopper<'a>(&'a AtomicBool, u32);
        impl Task for Stopper<'_> {
            fn init(&mut self, _: &mut TaskContext<'_>) -> Result<(), TaskFault> {
                Ok(())
            }
            fn step(&mut self, _: &mut TaskContext<'_>) -> Result<(), TaskFault> {
                self.1 += 1;
                if self.1 == 25 {
                    self.0.store(true, Ordering::Relaxed);
                }
                Ok(())
            }
        }
        let stop = Arc::new(AtomicBool::new(false));
        let mut stopper = Stopper(&stop, 0);
        let mut idle = idle_tasks(SHIPPED.tasks.len() - 1);
        let mut tasks: Vec<&mut dyn Task> = vec![&mut stopper];
        tasks.extend(idle.iter_mut().map(|t| t as &mut dyn Task));
        let mut frames = 0;
        let summary = run_executive(
            &Virtual,
            &SHIPPED,
            &mut tasks,
            options(&stop, 3600, FaultPlan::new()),
            |_| frames += 1,
        )
        .expect("starts");
        assert_eq!(summary.stop_reason, StopReason::Requested);
        assert_eq!((summary.frames.frames, frames), (25, 25));
    }

    #[test]
    fn injected_faults_reach_the_executive_under_virtual_time() {
        let stop = AtomicBool::new(false);
        let mut plan = FaultPlan::new();
        let gps = SHIPPED.task_index("gps").expect("gps");
        plan.push(OverrunInjection {
            task: gps,
            extra_ns: 1_000_000,
            from_frame: 0,
            to_frame: 1000,
        })
        .expect("room");
        let mut idle = idle_tasks(SHIPPED.tasks.len());
        let mut tasks: Vec<&mut dyn Task> = idle.iter_mut().map(|t| t as &mut dyn Task).collect();
        let summary = run_executive(
            &Virtual,
            &SHIPPED,
            &mut tasks,
            options(&stop, 5, plan),
            |_| {},
        )
        .expect("starts");
        // gps (budget 500 us, policy reset) runs every 10th frame: 50 releases in 5 s, each
        // 1 ms over. Every overrun resets it before its next release, which overruns again;
        // the last overrun has no next release to reset.
        let h = &summary.tasks[gps];
        assert_eq!(h.releases, 50);
        assert_eq!(h.overruns.budget, 50);
        assert_eq!(h.resets, 49);
    }
}

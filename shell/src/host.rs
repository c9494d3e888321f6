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
) -> Result<RunSummary, StartError> {
    let realtime = platform.make_realtime(&options.realtime);
    for refusal in realtime.refusals() {
        log::warn!("{refusal}");
    }
    let timer = platform.timer();
    let (producer, consumer) = rtrb::RingBuffer::<FrameRecord>::new(TIMING_RING);
    let executive_done = AtomicBool::new(false);

    std::thread::scope(|scope| {
        scope.spawn(|| drain_records(consumer, &executive_done, on_record));

        let result = fly(table, &timer, tasks, &options, RingSink(producer));
        executive_done.store(true, Ordering::Release);
        result.map(|(stop_reason, elapsed_ns, frames, health)| RunSummary {
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

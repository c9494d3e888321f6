//! Runs the executive on the calling thread, hands its timing records to a consumer thread,
//! and ends the run cleanly on a stop request, a signal or the programmed duration.

use crate::platform::{Platform, RtConfig, RtReport};
use crate::ring::RingSink;
use crate::stats::Distribution;
use skyframe_core::executive::FrameTimer;
use skyframe_core::executive::{
    Executive, FaultPlan, FrameRecord, FrameStats, StartError, Task, TaskHealth,
};
use skyframe_core::schedule::FrameTable;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

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

/// The start-up check of the timer: sleep to absolute deadlines for a moment before the
/// first frame and see how late the wake-ups are, against the frame margin.
#[derive(Clone, Debug)]
pub struct TimerCheckConfig {
    /// How long to measure; zero skips the check.
    pub duration: Duration,
    /// Refuse to fly (instead of warning) when the latency eats the frame margin.
    pub refuse_if_over_margin: bool,
}

impl Default for TimerCheckConfig {
    fn default() -> Self {
        Self {
            duration: Duration::from_millis(200),
            refuse_if_over_margin: false,
        }
    }
}

/// What the timer check measured.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TimerCheck {
    pub period_us: u64,
    pub wakeup_latency_us: Distribution,
    /// The frame margin the latency is compared against.
    pub margin_us: f64,
    /// True when the worst wake-up ate the whole margin.
    pub over_margin: bool,
}

/// Period of the timer check's wake-ups: fast, to get a few hundred samples in a moment.
const TIMER_CHECK_PERIOD_NS: u64 = 1_000_000;

fn check_timer<T: FrameTimer>(
    timer: &T,
    table: &FrameTable,
    config: &TimerCheckConfig,
) -> Option<TimerCheck> {
    if config.duration.is_zero() {
        return None;
    }
    let never = AtomicBool::new(false);
    let mut samples = bare_sleep_loop(timer, TIMER_CHECK_PERIOD_NS, config.duration, &never);
    let latency = Distribution::of(&mut samples).scaled(1e-3);
    let margin_us = table.margin_ns as f64 / 1e3;
    Some(TimerCheck {
        period_us: TIMER_CHECK_PERIOD_NS / 1000,
        wakeup_latency_us: latency,
        margin_us,
        over_margin: latency.max > margin_us,
    })
}

pub struct RunOptions<'a> {
    pub duration: Option<Duration>,
    pub timer_check: TimerCheckConfig,
    pub faults: FaultPlan,
    pub realtime: RtConfig,
    /// Set by signal handlers or a stop command; checked between frames.
    pub stop: &'a AtomicBool,
    /// Log TIME of the executive's clock zero (wall clock on a vehicle, 0 in simulation).
    pub log_time_origin_ns: u64,
    /// Called (on a guard thread) when `stop` has been set for [`STOP_GRACE`] and the
    /// executive has still not finished its frame: a task is stuck in its step. The executive
    /// never cancels a task, so the process must end around it: the callback closes what
    /// must be closed and exits. `None`: wait for the task, however long.
    pub on_stuck_stop: Option<&'a (dyn Fn(Duration) + Sync)>,
}

/// How long a stop request waits for the running frame to end before the process is ended
/// around a stuck task: the rest of the 1 s a stop may take is for closing the logs.
pub const STOP_GRACE: Duration = Duration::from_millis(400);
/// How long the log writer gets to close every file after [`STOP_GRACE`].
pub const STOP_CLOSE_WAIT: Duration = Duration::from_millis(500);
/// The exit code of a run ended around a task stuck in its step (README: exit codes).
pub const EXIT_STOPPED_STUCK: i32 = 4;

impl<'a> RunOptions<'a> {
    /// A run of `duration` with default real-time settings, timer check and no faults.
    pub fn new(duration: Option<Duration>, stop: &'a AtomicBool) -> Self {
        Self {
            duration,
            timer_check: TimerCheckConfig::default(),
            faults: FaultPlan::new(),
            realtime: RtConfig::default(),
            stop,
            log_time_origin_ns: 0,
            on_stuck_stop: None,
        }
    }
}

/// Why a run could not start.
#[derive(Debug)]
pub enum HostError {
    /// The executive refused the task list or the table.
    Start(StartError),
    /// The OS would not give us a thread (e.g. memory limits).
    Spawn(std::io::Error),
    /// The timer check found wake-ups later than the frame margin and the run was told to
    /// refuse in that case.
    TimerTooLate(TimerCheck),
}

impl std::fmt::Display for HostError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Start(e) => write!(f, "the executive did not start: {e:?}"),
            Self::Spawn(e) => write!(f, "cannot start a shell thread: {e}"),
            Self::TimerTooLate(c) => write!(
                f,
                "refusing to fly: timer wake-ups up to {:.0} us late exceed the {:.0} us frame \
                 margin (p99 {:.0} us)",
                c.wakeup_latency_us.max, c.margin_us, c.wakeup_latency_us.p99
            ),
        }
    }
}

/// What a run leaves behind for the summary.
#[derive(Clone, Debug)]
pub struct RunSummary {
    pub table: &'static FrameTable,
    pub realtime: RtReport,
    pub timer_check: Option<TimerCheck>,
    pub stop_reason: StopReason,
    /// Time from the first release to the end of the last frame.
    pub elapsed_ns: u64,
    pub frames: FrameStats,
    pub tasks: Vec<TaskAtEnd>,
}

/// A task's health when the run ended, with what the health board keeps beside it.
#[derive(Clone, Debug)]
pub struct TaskAtEnd {
    pub health: TaskHealth,
    /// Log records its ring could not take.
    pub log_dropped: u32,
    /// What it last said was wrong with its inputs (a stale device), if anything.
    pub degraded: Option<&'static str>,
}

/// Where a run's timing goes: every frame's record, and first the start-up timer check (so a
/// flight's log says how late its timer was, even if the flight dies). A closure taking
/// `&FrameRecord` is a sink that ignores the check.
pub trait TimingSink: Send {
    fn frame(&mut self, record: &FrameRecord);
    fn timer_check(&mut self, _check: &TimerCheck) {}
}

impl<F: FnMut(&FrameRecord) + Send> TimingSink for F {
    fn frame(&mut self, record: &FrameRecord) {
        self(record);
    }
}

/// Runs `tasks` (one per slot of `table`, in table order) until the duration elapses or
/// `stop` is set. The timer check reaches `timing` first; then each frame's timing record, on
/// a separate thread; all of them, in order, before this function returns.
pub fn run_executive<P: Platform>(
    platform: &P,
    table: &'static FrameTable,
    tasks: &mut [&mut dyn Task],
    options: RunOptions<'_>,
    mut timing: impl TimingSink,
) -> Result<RunSummary, HostError> {
    let realtime = platform.make_realtime(&RtConfig {
        minor_frame_ns: Some(table.minor_frame_ns),
        ..options.realtime.clone()
    });
    for refusal in realtime.refusals() {
        log::warn!("{refusal}");
    }
    let timer = platform.timer();
    let timer_check = check_timer(&timer, table, &options.timer_check);
    if let Some(check) = timer_check.as_ref().filter(|c| c.over_margin) {
        if options.timer_check.refuse_if_over_margin {
            return Err(HostError::TimerTooLate(check.clone()));
        }
        log::warn!(
            "timer wake-ups up to {:.0} us late (p99 {:.0} us) exceed the {:.0} us frame margin: \
             frames may start late",
            check.wakeup_latency_us.max,
            check.wakeup_latency_us.p99,
            check.margin_us
        );
    }
    if let Some(check) = &timer_check {
        timing.timer_check(check);
    }
    let (producer, consumer) = rtrb::RingBuffer::<FrameRecord>::new(TIMING_RING);
    let executive_done = AtomicBool::new(false);

    std::thread::scope(|scope| {
        std::thread::Builder::new()
            .name("timing-drain".into())
            .stack_size(256 * 1024)
            .spawn_scoped(scope, || {
                drain_records(consumer, &executive_done, |r| timing.frame(r))
            })
            .map_err(HostError::Spawn)?;

        if let Some(on_stuck) = options.on_stuck_stop {
            let (stop, done) = (options.stop, &executive_done);
            std::thread::Builder::new()
                .name("stop-guard".into())
                .stack_size(64 * 1024)
                .spawn_scoped(scope, move || guard_stop(stop, done, on_stuck))
                .map_err(HostError::Spawn)?;
        }
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
                timer_check,
                stop_reason,
                elapsed_ns,
                frames,
                tasks: health,
            })
    })
}

type Flown = (StopReason, u64, FrameStats, Vec<TaskAtEnd>);

fn fly<T: FrameTimer>(
    table: &'static FrameTable,
    timer: &T,
    tasks: &mut [&mut dyn Task],
    options: &RunOptions<'_>,
    mut sink: RingSink<FrameRecord>,
) -> Result<Flown, StartError> {
    let mut executive = Executive::new(table, timer);
    executive.set_faults(options.faults.clone());
    // The timer's clock starts now-ish; the caller measured the wall clock just before.
    executive.set_log_time_origin(options.log_time_origin_ns);
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
        .filter_map(|i| {
            health.task(i).map(|h| TaskAtEnd {
                health: *h,
                log_dropped: health.log_dropped(i),
                degraded: health.degraded(i),
            })
        })
        .collect();
    Ok((reason, elapsed, health.frames, tasks))
}

/// Watches for a stop request that the executive does not answer within [`STOP_GRACE`]
/// (it checks between frames, so only a task stuck in its step delays it), then hands over
/// to `on_stuck`. Returns once the executive is done.
fn guard_stop(stop: &AtomicBool, done: &AtomicBool, on_stuck: &(dyn Fn(Duration) + Sync)) {
    let mut stop_seen: Option<Instant> = None;
    while !done.load(Ordering::Acquire) {
        if stop_seen.is_none() && stop.load(Ordering::Relaxed) {
            stop_seen = Some(Instant::now());
        }
        if let Some(since) = stop_seen
            && since.elapsed() >= STOP_GRACE
            && !done.load(Ordering::Acquire)
        {
            on_stuck(since.elapsed());
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
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

/// Sleeps to each absolute release `period_ns` apart for `duration` and records how late each
/// wake-up was, in ns.
pub fn bare_sleep_loop<T: FrameTimer>(
    timer: &T,
    period_ns: u64,
    duration: Duration,
    stop: &AtomicBool,
) -> Vec<u64> {
    let start = timer.now_ns() + period_ns;
    let end = start.saturating_add(u64::try_from(duration.as_nanos()).unwrap_or(u64::MAX));
    let mut latencies =
        Vec::with_capacity((duration.as_nanos() / u128::from(period_ns.max(1))) as usize + 1);
    let mut release = start;
    while release < end && !stop.load(Ordering::Relaxed) {
        timer.sleep_until(release);
        latencies.push(timer.now_ns().saturating_sub(release));
        release += period_ns;
    }
    latencies
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
        fn serial_opener(&self) -> crate::serial::SerialOpener {
            crate::serial::no_serial_ports
        }
    }

    fn options(stop: &AtomicBool, seconds: u64, faults: FaultPlan) -> RunOptions<'_> {
        RunOptions {
            faults,
            ..RunOptions::new(Some(Duration::from_secs(seconds)), stop)
        }
    }

    /// Virtual time whose every wake-up is 3 ms late (more than the shipped 2 ms margin).
    struct Oversleeping;
    struct LateClock(VirtualClock);
    impl skyframe_core::executive::Clock for LateClock {
        fn now_ns(&self) -> u64 {
            self.0.now_ns()
        }
    }
    impl FrameTimer for LateClock {
        fn sleep_until(&self, t_ns: u64) {
            self.0.sleep_until(t_ns + 3_000_000);
        }
    }
    impl Platform for Oversleeping {
        type Timer = LateClock;
        fn name(&self) -> &'static str {
            "oversleeping"
        }
        fn timer(&self) -> LateClock {
            LateClock(VirtualClock::new())
        }
        fn virtual_time(&self) -> bool {
            true
        }
        fn make_realtime(&self, _config: &RtConfig) -> RtReport {
            RtReport::none()
        }
        fn serial_opener(&self) -> crate::serial::SerialOpener {
            crate::serial::no_serial_ports
        }
    }

    #[test]
    fn timer_check_refuses_or_warns_when_wakeups_eat_the_margin() {
        let stop = AtomicBool::new(false);
        let mut idle = idle_tasks(SHIPPED.tasks.len());
        let mut tasks: Vec<&mut dyn Task> = idle.iter_mut().map(|t| t as &mut dyn Task).collect();
        let refuse = RunOptions {
            timer_check: TimerCheckConfig {
                refuse_if_over_margin: true,
                ..TimerCheckConfig::default()
            },
            ..RunOptions::new(Some(Duration::from_secs(1)), &stop)
        };
        match run_executive(
            &Oversleeping,
            &SHIPPED,
            &mut tasks,
            refuse,
            |_: &FrameRecord| {},
        ) {
            Err(HostError::TimerTooLate(check)) => {
                assert_eq!(check.wakeup_latency_us.max, 3000.0);
                assert_eq!(check.margin_us, 2000.0);
            }
            other => panic!("expected a refusal, got {other:?}"),
        }
        let warn = RunOptions::new(Some(Duration::from_secs(1)), &stop);
        let summary = run_executive(
            &Oversleeping,
            &SHIPPED,
            &mut tasks,
            warn,
            |_: &FrameRecord| {},
        )
        .expect("flies");
        let check = summary.timer_check.expect("checked");
        assert!(check.over_margin);
        assert_eq!(
            check.wakeup_latency_us.count, 200,
            "200 ms of 1 ms wake-ups"
        );
        assert_eq!(
            summary.frames.late, summary.frames.frames,
            "every frame starts 3 ms late"
        );
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
            |r: &FrameRecord| seen.push(r.frame),
        )
        .expect("starts");
        assert_eq!(summary.stop_reason, StopReason::Duration);
        assert_eq!(seen.len(), 6000, "60 s of 10 ms frames, none dropped");
        assert!(seen.windows(2).all(|w| w[1] == w[0] + 1));
        assert_eq!(summary.frames.timing_records_dropped, 0);
        assert_eq!(summary.tasks[0].health.releases, 6000);
        assert!(
            summary.tasks.iter().all(|t| !t.health.running),
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
            |_: &FrameRecord| frames += 1,
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
            repeat_every_frames: 0,
        })
        .expect("room");
        let mut idle = idle_tasks(SHIPPED.tasks.len());
        let mut tasks: Vec<&mut dyn Task> = idle.iter_mut().map(|t| t as &mut dyn Task).collect();
        let summary = run_executive(
            &Virtual,
            &SHIPPED,
            &mut tasks,
            options(&stop, 5, plan),
            |_: &FrameRecord| {},
        )
        .expect("starts");
        // gps (budget 500 us, policy reset) runs every 10th frame: 50 releases in 5 s, each
        // 1 ms over. Every overrun resets it before its next release, which overruns again;
        // the last overrun has no next release to reset.
        let h = &summary.tasks[gps].health;
        assert_eq!(h.releases, 50);
        assert_eq!(h.overruns.budget, 50);
        assert_eq!(h.resets, 49);
    }
}

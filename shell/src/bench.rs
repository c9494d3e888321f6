//! `skyframe bench`: what the executive costs, measured against the bare timer.
//!
//! Two runs in one command, on the same thread with the same real-time settings and period:
//! a bare loop that only sleeps to each absolute release and records how late it woke, and
//! the executive flying the shipped frame table with idle tasks. The ratio of their wake-up
//! latencies shows what the executive adds over the machine's floor; the executive's own time
//! per frame (frame work less the tasks' time) shows its overhead.

use crate::cyclictest::CyclictestFigures;
use crate::host::{RunOptions, TimerCheckConfig, bare_sleep_loop, run_executive};
use crate::idle::idle_tasks;
use crate::platform::{Platform, RtConfig, RtReport};
use crate::stats::{Distribution, ratio};
use serde::Serialize;
use skyframe_core::executive::{FaultPlan, Task};
use skyframe_core::schedule::FrameTable;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

#[derive(Debug, Serialize)]
pub struct ExecutiveFigures {
    pub frames: u64,
    pub wakeup_latency_us: Distribution,
    pub overhead_ns_per_frame: Distribution,
    pub overruns: OverrunFigures,
    pub timing_records_dropped: u64,
}

#[derive(Debug, Default, Serialize)]
pub struct OverrunFigures {
    pub budget: u64,
    pub frame: u64,
    pub late_frames: u64,
    pub missed_frames: u64,
}

#[derive(Debug, Serialize)]
pub struct BareFigures {
    pub wakeups: u64,
    pub wakeup_latency_us: Distribution,
}

#[derive(Debug, Serialize)]
pub struct LatencyRatio {
    pub p50: Option<f64>,
    pub p99: Option<f64>,
    pub p999: Option<f64>,
    pub max: Option<f64>,
}

#[derive(Debug, Serialize)]
pub struct BenchReport {
    pub platform: &'static str,
    pub seconds_each: f64,
    pub minor_frame_us: u64,
    pub tasks: usize,
    pub realtime: RtReport,
    pub bare_clock_nanosleep: BareFigures,
    pub executive: ExecutiveFigures,
    /// Executive wake-up latency / bare loop wake-up latency.
    pub latency_ratio_executive_to_bare: LatencyRatio,
    /// With `--compare-cyclictest`: cyclictest at the same period, priority and CPU.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cyclictest: Option<CyclictestFigures>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub latency_ratio_executive_to_cyclictest: Option<LatencyRatio>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub latency_ratio_bare_to_cyclictest: Option<LatencyRatio>,
}

impl LatencyRatio {
    pub fn of(a: &Distribution, b: &Distribution) -> Self {
        Self {
            p50: ratio(a.p50, b.p50),
            p99: ratio(a.p99, b.p99),
            p999: ratio(a.p999, b.p999),
            max: ratio(a.max, b.max),
        }
    }
}

/// What to measure.
pub struct BenchOptions<'a> {
    pub seconds: f64,
    pub realtime: RtConfig,
    pub faults: FaultPlan,
    pub compare_cyclictest: bool,
    pub stop: &'a AtomicBool,
}

pub fn run<P: Platform>(
    platform: &P,
    table: &'static FrameTable,
    options: BenchOptions<'_>,
) -> Result<BenchReport, String> {
    let BenchOptions {
        seconds,
        realtime,
        faults,
        compare_cyclictest,
        stop,
    } = options;
    let realtime = &realtime;
    let each = Duration::from_secs_f64(seconds.max(0.0));
    let rt_report = platform.make_realtime(&RtConfig {
        minor_frame_ns: Some(table.minor_frame_ns),
        ..realtime.clone()
    });

    let timer = platform.timer();
    let mut bare = bare_sleep_loop(&timer, table.minor_frame_ns, each, stop);
    let bare_latency = Distribution::of(&mut bare).scaled(1e-3);

    let mut idle = idle_tasks(table.tasks.len());
    let mut tasks: Vec<&mut dyn Task> = idle.iter_mut().map(|t| t as &mut dyn Task).collect();
    let mut latencies = Vec::new();
    let mut overheads = Vec::new();
    let summary = run_executive(
        platform,
        table,
        &mut tasks,
        RunOptions {
            faults,
            realtime: realtime.clone(),
            // The bench measures the timer itself (the bare loop above).
            timer_check: TimerCheckConfig {
                duration: Duration::ZERO,
                ..TimerCheckConfig::default()
            },
            ..RunOptions::new(Some(each), stop)
        },
        |record: &skyframe_core::executive::FrameRecord| {
            latencies.push(u64::from(record.start_latency_ns));
            overheads.push(u64::from(record.overhead_ns));
        },
    )
    .map_err(|e| e.to_string())?;
    let exec_latency = Distribution::of(&mut latencies).scaled(1e-3);
    let cyclictest = if compare_cyclictest {
        Some(crate::cyclictest::run(
            table.minor_frame_ns,
            each,
            realtime.fifo_priority,
            realtime.cpu,
            realtime.lock_memory,
            &std::env::temp_dir(),
        )?)
    } else {
        None
    };

    let overruns = summary
        .tasks
        .iter()
        .fold(OverrunFigures::default(), |mut o, t| {
            o.budget += u64::from(t.health.overruns.budget);
            o.frame += u64::from(t.health.overruns.frame);
            o
        });
    Ok(BenchReport {
        platform: platform.name(),
        seconds_each: each.as_secs_f64(),
        minor_frame_us: table.minor_frame_ns / 1000,
        tasks: table.tasks.len(),
        realtime: rt_report,
        bare_clock_nanosleep: BareFigures {
            wakeups: bare_latency.count as u64,
            wakeup_latency_us: bare_latency,
        },
        executive: ExecutiveFigures {
            frames: summary.frames.frames,
            wakeup_latency_us: exec_latency,
            overhead_ns_per_frame: Distribution::of(&mut overheads),
            overruns: OverrunFigures {
                late_frames: summary.frames.late,
                missed_frames: summary.frames.missed,
                ..overruns
            },
            timing_records_dropped: summary.frames.timing_records_dropped,
        },
        latency_ratio_executive_to_bare: LatencyRatio::of(&exec_latency, &bare_latency),
        latency_ratio_executive_to_cyclictest: cyclictest
            .as_ref()
            .map(|c| LatencyRatio::of(&exec_latency, &c.wakeup_latency_us)),
        latency_ratio_bare_to_cyclictest: cyclictest
            .as_ref()
            .map(|c| LatencyRatio::of(&bare_latency, &c.wakeup_latency_us)),
        cyclictest,
    })
}

/// The report for people.
pub fn render_text(r: &BenchReport) -> String {
    let d = |x: &Distribution| {
        format!(
            "p50 {:.1}  p99 {:.1}  p99.9 {:.1}  max {:.1}",
            x.p50, x.p99, x.p999, x.max
        )
    };
    let refusals = r.realtime.refusals();
    let mut s = format!(
        "platform {}, minor frame {} us, {} tasks, {:.1} s per run\n",
        r.platform, r.minor_frame_us, r.tasks, r.seconds_each
    );
    if !refusals.is_empty() {
        s += &format!("real-time settings: {}\n", refusals.join("; "));
    }
    s += &format!(
        "bare clock_nanosleep  wake-up latency us: {}  ({} wake-ups)\n",
        d(&r.bare_clock_nanosleep.wakeup_latency_us),
        r.bare_clock_nanosleep.wakeups
    );
    s += &format!(
        "executive             wake-up latency us: {}  ({} frames)\n",
        d(&r.executive.wakeup_latency_us),
        r.executive.frames
    );
    s += &format!(
        "executive overhead ns per frame: mean {:.0}  {}\n",
        r.executive.overhead_ns_per_frame.mean,
        d(&r.executive.overhead_ns_per_frame)
    );
    let o = &r.executive.overruns;
    s += &format!(
        "overruns: budget {}  frame {}  late frames {}  missed frames {}\n",
        o.budget, o.frame, o.late_frames, o.missed_frames
    );
    let f = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.2}"));
    let ratio_line = |label: &str, q: &LatencyRatio| {
        format!(
            "latency ratio {label}: p50 {}  p99 {}  p99.9 {}  max {}\n",
            f(q.p50),
            f(q.p99),
            f(q.p999),
            f(q.max)
        )
    };
    s += &ratio_line("executive/bare", &r.latency_ratio_executive_to_bare);
    if let Some(c) = &r.cyclictest {
        s += &format!(
            "cyclictest            wake-up latency us: {}  ({} wake-ups, {} overflows)\n  {}\n",
            d(&c.wakeup_latency_us),
            c.wakeup_latency_us.count,
            c.overflows,
            c.command
        );
    }
    if let Some(q) = &r.latency_ratio_executive_to_cyclictest {
        s += &ratio_line("executive/cyclictest", q);
    }
    if let Some(q) = &r.latency_ratio_bare_to_cyclictest {
        s += &ratio_line("bare/cyclictest", q);
    }
    s
}

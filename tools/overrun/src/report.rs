//! The report's figures, from frame records, and its text table.
//!
//! Percentiles are by nearest rank: the p-th percentile of n sorted values is the value of
//! rank ⌈p·n/100⌉ (1-based, at least 1). Times are integer nanoseconds in the JSON, except
//! means (f64) and device periods (f64 milliseconds).

use std::fmt::Write as _;

use serde::Serialize;
use skyframe_core::executive::FrameRecord;
use skyframe_core::executive::timing::flags;
use skyframe_core::schedule::{FrameTable, SHIPPED};

/// The end-to-end latency's definition, printed with it.
pub const END_TO_END_DEFINITION: &str = "in each frame where both imu and servo ran: \
start_latency_ns + the exec_ns of every task that ran up to and including servo in \
frame-table order + overhead_ns x (those tasks / all tasks that ran in the frame), rounded \
down: from the frame's release (when the IMU sample is due) to the end of servo's step";

pub use skyframe_core::stats::percentile;

#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Stats {
    pub count: usize,
    pub min: u64,
    pub mean: f64,
    pub p25: u64,
    pub p50: u64,
    pub p75: u64,
    pub p99: u64,
    pub p999: u64,
    pub max: u64,
}

impl Stats {
    /// `None` without values.
    pub fn of(mut values: Vec<u64>) -> Option<Stats> {
        values.sort_unstable();
        let count = values.len();
        let sum: u128 = values.iter().map(|&v| u128::from(v)).sum();
        Some(Stats {
            count,
            min: *values.first()?,
            mean: sum as f64 / count as f64,
            p25: percentile(&values, 25, 100)?,
            p50: percentile(&values, 50, 100)?,
            p75: percentile(&values, 75, 100)?,
            p99: percentile(&values, 99, 100)?,
            p999: percentile(&values, 999, 1000)?,
            max: *values.last()?,
        })
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct TaskReport {
    pub name: String,
    /// Frames where the task ran or was skipped, plus its releases in missed frames.
    pub releases: u64,
    pub ran: u64,
    /// Releases in frames the executive missed whole; `None` when the frame table is unknown.
    pub missed: Option<u64>,
    /// Execution times (ns) of the frames where it ran.
    pub exec_ns: Option<Stats>,
    /// `None`: budget unknown (the log's tasks are not the shipped schedule's).
    pub budget_ns: Option<u64>,
    pub over_budget: u64,
    pub over_frame: u64,
    pub skipped: u64,
    pub resets: u64,
    /// budget − max execution time (ns).
    pub slack_ns: Option<i64>,
}

#[derive(Clone, Debug, Serialize)]
pub struct FrameTask {
    pub name: String,
    pub exec_ns: u32,
    pub ran: bool,
    pub over_budget: bool,
    pub over_frame: bool,
    pub skipped: bool,
    pub reset: bool,
}

#[derive(Clone, Debug, Serialize)]
pub struct WorstFrame {
    pub frame: u64,
    pub release_ns: u64,
    pub start_latency_ns: u32,
    pub work_ns: u32,
    pub overhead_ns: u32,
    /// start latency + work: how long after its release the frame's work ended.
    pub end_ns: u64,
    pub missed_before: u32,
    pub flags: Vec<&'static str>,
    /// The tasks that ran or were skipped, in table order.
    pub tasks: Vec<FrameTask>,
}

#[derive(Clone, Debug, Serialize)]
pub struct FramesReport {
    pub count: usize,
    pub first: Option<u64>,
    pub last: Option<u64>,
    pub start_latency_ns: Option<Stats>,
    pub work_ns: Option<Stats>,
    pub late: u64,
    /// Sum of missed_before: whole frames the executive missed.
    pub missed: u64,
    pub overrun: u64,
    pub after_missed: u64,
}

#[derive(Clone, Debug, Serialize)]
pub struct EndToEnd {
    pub definition: &'static str,
    /// Why there is no figure (no imu or servo task).
    pub unavailable: Option<String>,
    pub latency_ns: Option<Stats>,
}

#[derive(Clone, Debug, Serialize)]
pub struct DevicePeriod {
    pub device: String,
    pub samples: usize,
    pub intervals: usize,
    pub mean_ms: Option<f64>,
    pub p99_ms: Option<f64>,
    pub max_ms: Option<f64>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub source: String,
    pub budgets: &'static str,
    pub tasks: Vec<TaskReport>,
    pub frames: FramesReport,
    /// Ranked by start latency + work (the frame's end after its release), worst first.
    pub worst_frames: Vec<WorstFrame>,
    pub end_to_end: EndToEnd,
    pub device_periods: Vec<DevicePeriod>,
    /// Problems were found reading the logs (listed on stderr).
    pub damaged: bool,
}

fn bit(mask: u32, i: usize) -> bool {
    i < 32 && mask & (1 << i) != 0
}

fn count(frames: &[FrameRecord], mask: impl Fn(&FrameRecord) -> u32, i: usize) -> u64 {
    frames.iter().filter(|f| bit(mask(f), i)).count() as u64
}

/// The shipped frame table when the log's tasks are its tasks, in its order.
pub fn matching_table(tasks: &[String]) -> Option<&'static FrameTable> {
    let same = SHIPPED.tasks.len() == tasks.len()
        && SHIPPED.tasks.iter().zip(tasks).all(|(t, n)| t.name == n);
    same.then_some(&SHIPPED)
}

fn flag_names(f: u8) -> Vec<&'static str> {
    let mut names = Vec::new();
    if f & flags::LATE != 0 {
        names.push("LATE");
    }
    if f & flags::OVERRUN != 0 {
        names.push("OVERRUN");
    }
    if f & flags::AFTER_MISSED != 0 {
        names.push("AFTER_MISSED");
    }
    names
}

/// How many times task `i` is released in frames `from..to` (whole major frames counted
/// at once, so a damaged `missed_before` cannot make this slow).
pub fn released_between(table: &FrameTable, i: usize, from: u64, to: u64) -> u64 {
    let per = table.frames.len() as u64;
    if per == 0 || to <= from {
        return 0;
    }
    let in_major = table.frames.iter().filter(|&&m| bit(m, i)).count() as u64;
    let len = to - from;
    let whole = len / per;
    let rest = (from + whole * per..to)
        .filter(|&k| bit(table.released(k), i))
        .count() as u64;
    whole * in_major + rest
}

pub fn end_ns(f: &FrameRecord) -> u64 {
    u64::from(f.start_latency_ns) + u64::from(f.work_ns)
}

/// The frame's IMU-to-servo latency (see [`END_TO_END_DEFINITION`]); `None` unless both ran.
pub fn end_to_end_ns(f: &FrameRecord, imu: usize, servo: usize) -> Option<u64> {
    if !(bit(f.ran, imu) && bit(f.ran, servo)) {
        return None;
    }
    let mut before = 0u64;
    let mut exec = 0u64;
    for i in 0..=servo {
        if bit(f.ran, i) {
            before += 1;
            exec += u64::from(f.exec_ns.get(i).copied().unwrap_or(0));
        }
    }
    let all = u64::from(f.ran.count_ones()).max(1);
    let overhead = u64::from(f.overhead_ns) * before / all;
    Some(u64::from(f.start_latency_ns) + exec + overhead)
}

/// Sample intervals of one device, in ms.
pub fn device_period(device: &str, times_ns: &[i64]) -> DevicePeriod {
    let intervals: Vec<u64> = times_ns
        .windows(2)
        .filter_map(|w| match w {
            [a, b] => u64::try_from(b - a).ok(),
            _ => None,
        })
        .collect();
    let stats = Stats::of(intervals.clone());
    let ms = |ns: u64| ns as f64 / 1e6;
    DevicePeriod {
        device: device.to_string(),
        samples: times_ns.len(),
        intervals: intervals.len(),
        mean_ms: stats.as_ref().map(|s| s.mean / 1e6),
        p99_ms: stats.as_ref().map(|s| ms(s.p99)),
        max_ms: stats.as_ref().map(|s| ms(s.max)),
    }
}

pub struct Input<'a> {
    pub source: String,
    pub tasks: &'a [String],
    pub frames: &'a [FrameRecord],
    pub devices: &'a [(String, Vec<i64>)],
    pub worst: usize,
    pub damaged: bool,
}

pub fn build(input: &Input<'_>) -> Report {
    let frames = input.frames;
    let table = matching_table(input.tasks);
    let tasks = input
        .tasks
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let ran = count(frames, |f| f.ran, i);
            let skipped = count(frames, |f| f.skipped, i);
            let missed = table.map(|t| {
                frames
                    .iter()
                    .map(|f| {
                        let from = f.frame.saturating_sub(u64::from(f.missed_before));
                        released_between(t, i, from, f.frame)
                    })
                    .sum::<u64>()
            });
            let exec = Stats::of(
                frames
                    .iter()
                    .filter(|f| bit(f.ran, i))
                    .map(|f| u64::from(f.exec_ns.get(i).copied().unwrap_or(0)))
                    .collect(),
            );
            let budget_ns = table.and_then(|t| t.tasks.get(i)).map(|t| t.budget_ns);
            let slack_ns = match (budget_ns, &exec) {
                (Some(b), Some(e)) => Some(b as i64 - e.max as i64),
                _ => None,
            };
            TaskReport {
                name: name.clone(),
                releases: ran + skipped + missed.unwrap_or(0),
                ran,
                missed,
                exec_ns: exec,
                budget_ns,
                over_budget: count(frames, |f| f.over_budget, i),
                over_frame: count(frames, |f| f.over_frame, i),
                skipped,
                resets: count(frames, |f| f.reset, i),
                slack_ns,
            }
        })
        .collect();
    let flagged = |flag: u8| frames.iter().filter(|f| f.flags & flag != 0).count() as u64;
    let frames_report = FramesReport {
        count: frames.len(),
        first: frames.first().map(|f| f.frame),
        last: frames.last().map(|f| f.frame),
        start_latency_ns: Stats::of(
            frames
                .iter()
                .map(|f| u64::from(f.start_latency_ns))
                .collect(),
        ),
        work_ns: Stats::of(frames.iter().map(|f| u64::from(f.work_ns)).collect()),
        late: flagged(flags::LATE),
        missed: frames.iter().map(|f| u64::from(f.missed_before)).sum(),
        overrun: flagged(flags::OVERRUN),
        after_missed: flagged(flags::AFTER_MISSED),
    };
    let worst_frames = worst(frames, input.worst)
        .into_iter()
        .map(|f| WorstFrame {
            frame: f.frame,
            release_ns: f.release_ns,
            start_latency_ns: f.start_latency_ns,
            work_ns: f.work_ns,
            overhead_ns: f.overhead_ns,
            end_ns: end_ns(f),
            missed_before: f.missed_before,
            flags: flag_names(f.flags),
            tasks: input
                .tasks
                .iter()
                .enumerate()
                .filter(|&(i, _)| bit(f.ran | f.skipped, i))
                .map(|(i, name)| FrameTask {
                    name: name.clone(),
                    exec_ns: f.exec_ns.get(i).copied().unwrap_or(0),
                    ran: bit(f.ran, i),
                    over_budget: bit(f.over_budget, i),
                    over_frame: bit(f.over_frame, i),
                    skipped: bit(f.skipped, i),
                    reset: bit(f.reset, i),
                })
                .collect(),
        })
        .collect();
    let position = |name: &str| input.tasks.iter().position(|t| t == name);
    let end_to_end = match (position("imu"), position("servo")) {
        (Some(imu), Some(servo)) => EndToEnd {
            definition: END_TO_END_DEFINITION,
            unavailable: None,
            latency_ns: Stats::of(
                frames
                    .iter()
                    .filter_map(|f| end_to_end_ns(f, imu, servo))
                    .collect(),
            ),
        },
        _ => EndToEnd {
            definition: END_TO_END_DEFINITION,
            unavailable: Some("the log has no imu or no servo task".into()),
            latency_ns: None,
        },
    };
    Report {
        source: input.source.clone(),
        budgets: if table.is_some() {
            "shipped schedule (skyframe_core::schedule::SHIPPED)"
        } else {
            "budget unknown: the log's tasks are not the shipped schedule's"
        },
        tasks,
        frames: frames_report,
        worst_frames,
        end_to_end,
        device_periods: input
            .devices
            .iter()
            .map(|(d, t)| device_period(d, t))
            .collect(),
        damaged: input.damaged,
    }
}

/// The `n` worst frames by start latency + work, worst first (earlier frame on ties).
pub fn worst(frames: &[FrameRecord], n: usize) -> Vec<&FrameRecord> {
    let mut sorted: Vec<&FrameRecord> = frames.iter().collect();
    sorted.sort_by(|a, b| end_ns(b).cmp(&end_ns(a)).then(a.frame.cmp(&b.frame)));
    sorted.truncate(n);
    sorted
}

/// The `n` worst major frames (of `minor_frames` minor frames each): ranked by their worst
/// minor frame's start latency + work, worst first (earlier on ties); each with its frames.
pub fn worst_major(
    frames: &[FrameRecord],
    minor_frames: usize,
    n: usize,
) -> Vec<(u64, Vec<&FrameRecord>)> {
    let per = (minor_frames as u64).max(1);
    let mut majors: Vec<(u64, u64, Vec<&FrameRecord>)> = Vec::new();
    for f in frames {
        let major = f.frame / per;
        match majors.last_mut() {
            Some((m, score, members)) if *m == major => {
                *score = (*score).max(end_ns(f));
                members.push(f);
            }
            _ => majors.push((major, end_ns(f), vec![f])),
        }
    }
    majors.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    majors.truncate(n);
    majors.into_iter().map(|(m, _, f)| (m, f)).collect()
}

fn us(ns: u64) -> String {
    format!("{:.1}", ns as f64 / 1000.0)
}

fn opt_us(ns: Option<u64>) -> String {
    ns.map_or_else(|| "-".into(), us)
}

/// The text table.
pub fn text(r: &Report) -> String {
    let mut out = String::new();
    let f = &r.frames;
    let span = match (f.first, f.last) {
        (Some(a), Some(b)) => format!(" (frames {a}..={b})"),
        _ => String::new(),
    };
    let _ = writeln!(out, "{}: {} frame records{span}", r.source, f.count);
    let _ = writeln!(out, "budgets: {}", r.budgets);
    let _ = writeln!(
        out,
        "{:<12} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>7} {:>6} {:>6} {:>6}",
        "task",
        "releases",
        "min us",
        "mean us",
        "p99 us",
        "p99.9 us",
        "max us",
        "budget us",
        "slack us",
        "budget!",
        "frame!",
        "skips",
        "resets",
        "missed"
    );
    for t in &r.tasks {
        let e = t.exec_ns.as_ref();
        let _ = writeln!(
            out,
            "{:<12} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>7} {:>6} {:>6} {:>6}",
            t.name,
            t.releases,
            opt_us(e.map(|e| e.min)),
            e.map_or_else(|| "-".into(), |e| format!("{:.1}", e.mean / 1000.0)),
            opt_us(e.map(|e| e.p99)),
            opt_us(e.map(|e| e.p999)),
            opt_us(e.map(|e| e.max)),
            t.budget_ns.map_or_else(|| "unknown".into(), us),
            t.slack_ns
                .map_or_else(|| "-".into(), |s| format!("{:.1}", s as f64 / 1000.0)),
            t.over_budget,
            t.over_frame,
            t.skipped,
            t.resets,
            t.missed.map_or_else(|| "-".into(), |m| m.to_string()),
        );
    }
    let _ = writeln!(
        out,
        "budget! = over budget, frame! = ran into the next frame, slack = budget - max, missed = releases in frames missed whole"
    );
    let _ = writeln!(out);
    if let Some(l) = &f.start_latency_ns {
        let _ = writeln!(
            out,
            "frame start latency: p50 {} us, p99 {} us, p99.9 {} us, max {} us",
            us(l.p50),
            us(l.p99),
            us(l.p999),
            us(l.max)
        );
    }
    let _ = writeln!(
        out,
        "frames: {} late, {} missed, {} overrun, {} after missed frames",
        f.late, f.missed, f.overrun, f.after_missed
    );
    if !r.worst_frames.is_empty() {
        let _ = writeln!(
            out,
            "worst frames (by start latency + work, from the release to the end of the frame's work):"
        );
    }
    for w in &r.worst_frames {
        let flags = if w.flags.is_empty() {
            String::new()
        } else {
            format!(" [{}]", w.flags.join(","))
        };
        let tasks: Vec<String> = w
            .tasks
            .iter()
            .map(|t| {
                let mut marks = String::new();
                if t.over_budget {
                    marks.push('!');
                }
                if t.over_frame {
                    marks.push('>');
                }
                if t.skipped {
                    marks.push_str(" skipped");
                }
                if t.reset {
                    marks.push_str(" reset");
                }
                format!("{} {}{marks}", t.name, us(u64::from(t.exec_ns)))
            })
            .collect();
        let _ = writeln!(
            out,
            "  frame {:>7} at {:.3} s: latency {} us + work {} us (overhead {} us) = {} us{flags}: {}",
            w.frame,
            w.release_ns as f64 / 1e9,
            us(u64::from(w.start_latency_ns)),
            us(u64::from(w.work_ns)),
            us(u64::from(w.overhead_ns)),
            us(w.end_ns),
            tasks.join(", ")
        );
    }
    let _ = writeln!(out);
    let e = &r.end_to_end;
    match (&e.unavailable, &e.latency_ns) {
        (Some(why), _) => {
            let _ = writeln!(out, "end-to-end IMU -> servo latency: unavailable: {why}");
        }
        (None, None) => {
            let _ = writeln!(
                out,
                "end-to-end IMU -> servo latency: no frame where both ran"
            );
        }
        (None, Some(l)) => {
            let _ = writeln!(
                out,
                "end-to-end IMU -> servo latency over {} frames: mean {:.1} us, p50 {} us, p99 {} us, p99.9 {} us, max {} us",
                l.count,
                l.mean / 1000.0,
                us(l.p50),
                us(l.p99),
                us(l.p999),
                us(l.max)
            );
        }
    }
    let _ = writeln!(out, "  ({})", e.definition);
    if !r.device_periods.is_empty() {
        let _ = writeln!(out, "device sample periods (intervals between log TIMEs):");
    }
    for d in &r.device_periods {
        let ms = |v: Option<f64>| v.map_or_else(|| "-".into(), |v| format!("{v:.2}"));
        let _ = writeln!(
            out,
            "  {:<6} {:>7} samples: mean {} ms, p99 {} ms, max {} ms",
            d.device,
            d.samples,
            ms(d.mean_ms),
            ms(d.p99_ms),
            ms(d.max_ms)
        );
    }
    if r.damaged {
        let _ = writeln!(
            out,
            "the logs are damaged: figures are from the readable records (problems on stderr)"
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank() {
        let v: Vec<u64> = (1..=1000).collect();
        assert_eq!(percentile(&v, 99, 100), Some(990));
        assert_eq!(percentile(&v, 999, 1000), Some(999));
        assert_eq!(percentile(&[5], 999, 1000), Some(5));
        assert_eq!(percentile::<u64>(&[], 50, 100), None);
        let v: Vec<u64> = (1..=10).collect();
        assert_eq!(percentile(&v, 50, 100), Some(5));
        assert_eq!(percentile(&v, 99, 100), Some(10));
    }

    #[test]
    fn end_to_end_sums_up_to_servo() {
        let mut f = FrameRecord::empty();
        f.ran = 0b1011; // tasks 0, 1, 3
        f.exec_ns[0] = 100;
        f.exec_ns[1] = 200;
        f.exec_ns[3] = 400;
        f.start_latency_ns = 50;
        f.overhead_ns = 30;
        // servo = task 1: tasks 0 and 1 ran up to it, 3 ran in all: overhead 30*2/3 = 20.
        assert_eq!(end_to_end_ns(&f, 0, 1), Some(50 + 300 + 20));
        assert_eq!(end_to_end_ns(&f, 0, 2), None);
    }

    #[test]
    fn releases_between_frames_match_counting_them() {
        let t = &SHIPPED;
        for i in 0..t.tasks.len() {
            for (from, to) in [(0, 0), (3, 4), (7, 35), (1, 1000), (998, 1000)] {
                let counted = (from..to).filter(|&k| bit(t.released(k), i)).count() as u64;
                assert_eq!(
                    released_between(t, i, from, to),
                    counted,
                    "{i} {from}..{to}"
                );
            }
        }
        // A damaged missed_before is quick.
        assert!(released_between(t, 0, 0, u64::from(u32::MAX)) > 0);
    }

    #[test]
    fn worst_major_frames_rank_by_their_worst_minor_frame() {
        let frames: Vec<FrameRecord> = (0..30u64)
            .map(|k| {
                let mut f = FrameRecord::empty();
                f.frame = k;
                f.work_ns = match k {
                    3 => 500,
                    25 => 900,
                    17 => 500,
                    _ => 10,
                };
                f
            })
            .collect();
        let worst = worst_major(&frames, 10, 2);
        let majors: Vec<u64> = worst.iter().map(|(m, _)| *m).collect();
        assert_eq!(majors, [2, 0]);
        assert_eq!(worst.first().map(|(_, f)| f.len()), Some(10));
    }
}

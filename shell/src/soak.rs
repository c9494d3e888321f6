//! `skyframe soak`: hours of virtual flight with a scenario's faults on a loop, watching the
//! process from outside the flight (resident memory and open files, sampled every wall
//! second) and checking the flight's own counters against each other at the end. What a
//! research flight of an afternoon would find out too late: a leak, a file left open, a
//! counter that drifts.

use crate::flight::FlightReport;
use serde::Serialize;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The process as the OS sees it at one moment.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Sample {
    pub wall_s: f64,
    /// Resident set size (`VmRSS`), kB.
    pub rss_kb: u64,
    pub open_files: u64,
}

/// Samples the process every `every` on a thread of its own until stopped.
pub struct Sampler {
    stop: Arc<AtomicBool>,
    join: Option<std::thread::JoinHandle<Vec<Sample>>>,
}

impl Sampler {
    /// `None` where `/proc/self` cannot be read (not Linux): the soak then says so.
    pub fn start(every: Duration) -> Option<Self> {
        sample(Instant::now())?;
        let stop = Arc::new(AtomicBool::new(false));
        let thread_stop = Arc::clone(&stop);
        let join = std::thread::Builder::new()
            .name("soak-sampler".into())
            .spawn(move || {
                let started = Instant::now();
                let mut samples = Vec::new();
                while !thread_stop.load(Ordering::Relaxed) {
                    if let Some(s) = sample(started) {
                        samples.push(s);
                    }
                    let next = Instant::now() + every;
                    while Instant::now() < next && !thread_stop.load(Ordering::Relaxed) {
                        std::thread::sleep(Duration::from_millis(20));
                    }
                }
                samples.extend(sample(started));
                samples
            })
            .ok()?;
        Some(Self {
            stop,
            join: Some(join),
        })
    }

    pub fn finish(mut self) -> Vec<Sample> {
        self.stop.store(true, Ordering::Relaxed);
        self.join
            .take()
            .and_then(|j| j.join().ok())
            .unwrap_or_default()
    }
}

fn sample(started: Instant) -> Option<Sample> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let rss_kb = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|kb| kb.parse().ok())?;
    let open_files = std::fs::read_dir("/proc/self/fd").ok()?.count() as u64;
    Some(Sample {
        wall_s: started.elapsed().as_secs_f64(),
        rss_kb,
        open_files,
    })
}

/// One check of the soak: what was compared, and whether it held.
#[derive(Debug, Serialize)]
pub struct Check {
    pub name: String,
    pub ok: bool,
    pub detail: String,
}

fn check(name: &str, ok: bool, detail: String) -> Check {
    Check {
        name: name.to_string(),
        ok,
        detail,
    }
}

/// Resident memory may grow this much from the first quarter of the run to its end (the
/// allocator's and the page cache's noise; a leak of one allocation per frame over hours is
/// far beyond it).
pub const RSS_GROWTH_LIMIT_KB: u64 = 4 * 1024;

/// Memory and files: flat from the end of the first quarter (start-up is over) to the end.
pub fn process_checks(samples: &[Sample]) -> Vec<Check> {
    let Some(last) = samples.last() else {
        return vec![check(
            "process sampled",
            false,
            "no sample of /proc/self".into(),
        )];
    };
    let settled = samples.get(samples.len() / 4).copied().unwrap_or(*last);
    let max_rss = samples.iter().map(|s| s.rss_kb).max().unwrap_or(0);
    let max_files = samples.iter().map(|s| s.open_files).max().unwrap_or(0);
    let growth = last.rss_kb.saturating_sub(settled.rss_kb);
    vec![
        check(
            "resident memory flat",
            growth <= RSS_GROWTH_LIMIT_KB,
            format!(
                "{} kB at {:.0} s, {} kB at the end ({:.0} s), max {max_rss} kB; growth {growth} kB \
                 (limit {RSS_GROWTH_LIMIT_KB})",
                settled.rss_kb, settled.wall_s, last.rss_kb, last.wall_s
            ),
        ),
        check(
            "open files flat",
            // The last sample is taken after the flight closed its files.
            samples
                .iter()
                .skip(samples.len() / 4)
                .all(|s| s.open_files <= settled.open_files),
            format!(
                "{} open at {:.0} s, max {max_files}, {} after the flight",
                settled.open_files, settled.wall_s, last.open_files
            ),
        ),
    ]
}

/// The flight's counters against each other and against what the loop put in.
pub fn counter_checks(
    report: &FlightReport,
    duration_s: f64,
    minor_frame_ns: u64,
    expected_silences: &[(&str, u64)],
) -> Vec<Check> {
    let s = &report.summary;
    let frames_expected = (duration_s * 1e9 / minor_frame_ns as f64).round() as u64;
    let mut checks = vec![
        check(
            "every minor frame ran",
            s.frames.abs_diff(frames_expected) <= 1 && s.frames_missed == 0,
            format!(
                "{} frames of {frames_expected}, {} missed",
                s.frames, s.frames_missed
            ),
        ),
        check(
            "no timing record dropped",
            s.timing_records_dropped == 0,
            format!("{} dropped", s.timing_records_dropped),
        ),
    ];
    for stream in &report.log_streams {
        checks.push(check(
            &format!("log {} complete", stream.name),
            stream.records_dropped == 0 && stream.records_lost == 0 && !stream.failed,
            format!(
                "{} written, {} dropped, {} lost{}",
                stream.records_written,
                stream.records_dropped,
                stream.records_lost,
                if stream.failed { ", FAILED" } else { "" }
            ),
        ));
    }
    for task in &s.tasks {
        checks.push(check(
            &format!("task {} never dropped a log record", task.name),
            task.log_dropped == 0,
            format!("{} dropped", task.log_dropped),
        ));
    }
    for &(device, expected) in expected_silences {
        let stale = report
            .devices
            .iter()
            .find(|d| d.name == device)
            .map_or(0, |d| u64::from(d.decoder.stale_events));
        checks.push(check(
            &format!("{device} went stale once per silence"),
            stale == expected,
            format!("{stale} stale events, {expected} silences flown"),
        ));
    }
    if let Some(link) = &report.link {
        checks.push(check(
            "every telemetry datagram handed over was sent or refused by the OS",
            link.datagrams_out + link.send_errors == u64::from(link.telemetry_sent),
            format!(
                "task handed over {}, socket sent {} and refused {}",
                link.telemetry_sent, link.datagrams_out, link.send_errors
            ),
        ));
    }
    checks
}

/// Removes a soak's flight directory (hours of logs) unless asked to keep it.
pub fn discard_logs(dir: &Path) {
    if let Err(e) = std::fs::remove_dir_all(dir) {
        log::warn!("soak: could not remove {}: {e}", dir.display());
    }
}

#[derive(Debug, Serialize)]
pub struct SoakReport {
    pub virtual_hours: f64,
    pub wall_s: f64,
    pub fault_period_s: f64,
    pub fault_loops: u64,
    pub flight_dir: std::path::PathBuf,
    pub logs_kept: bool,
    pub samples: usize,
    pub checks: Vec<Check>,
    pub ok: bool,
}

pub fn render(report: &SoakReport) -> String {
    let mut out = format!(
        "soak: {:.2} h of virtual flight in {:.0} s, faults looped {} times (every {:.0} s)\n",
        report.virtual_hours, report.wall_s, report.fault_loops, report.fault_period_s
    );
    for c in &report.checks {
        out += &format!(
            "{} {}: {}\n",
            if c.ok { "ok    " } else { "FAILED" },
            c.name,
            c.detail
        );
    }
    out += &format!(
        "logs {} {}\n",
        if report.logs_kept {
            "kept in"
        } else {
            "removed from"
        },
        report.flight_dir.display()
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(wall_s: f64, rss_kb: u64, open_files: u64) -> Sample {
        Sample {
            wall_s,
            rss_kb,
            open_files,
        }
    }

    #[test]
    fn memory_that_keeps_growing_or_files_left_open_fail_the_soak() {
        let flat: Vec<Sample> = (0..20)
            .map(|i| s(f64::from(i), 50_000 + (i % 3) as u64, 12))
            .collect();
        assert!(process_checks(&flat).iter().all(|c| c.ok));
        let leaking: Vec<Sample> = (0..20)
            .map(|i| s(f64::from(i), 50_000 + 1000 * i as u64, 12))
            .collect();
        assert!(!process_checks(&leaking)[0].ok);
        let mut files = flat.clone();
        files[15].open_files = 13;
        assert!(!process_checks(&files)[1].ok);
        assert!(!process_checks(&[])[0].ok);
    }
}

//! One flight: a directory for its files, the log writer, the executive and its tasks, and the
//! report at the end. Device, estimation, control and link tasks join here as their issues
//! land; until then every slot but the watchdog holds an idle task.

use crate::host::{HostError, RunOptions, run_executive};
use crate::idle::{IdleTask, idle_tasks};
use crate::logwriter::{LogWriter, WriterConfig};
use crate::platform::Platform;
use crate::summary::SummaryReport;
use crate::timing_log::TimingLog;
use serde::Serialize;
use skyframe_core::comm::LatestSlot;
use skyframe_core::executive::Task;
use skyframe_core::schedule::FrameTable;
use skyframe_core::tasks::health::HealthTask;
use skyframe_core::tasks::logging::LoggingTask;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{SystemTime, UNIX_EPOCH};

/// Ring of the executive's timing stream: ~100 B a frame, so several seconds of backlog.
const TIMING_RING_BYTES: usize = 256 * 1024;
/// Ring of the health snapshots: one snapshot of every task is ~1.5 kB.
const HEALTH_RING_BYTES: usize = 64 * 1024;
/// Health snapshots once a second.
const HEALTH_SNAPSHOT_NS: u64 = 1_000_000_000;

/// What happened to one log stream.
#[derive(Debug, Serialize)]
pub struct StreamReport {
    pub name: String,
    pub records_written: u64,
    pub records_dropped: u64,
    pub records_lost: u64,
    pub failed: bool,
}

#[derive(Debug, Serialize)]
pub struct FlightReport {
    #[serde(flatten)]
    pub summary: SummaryReport,
    pub flight_dir: PathBuf,
    pub log_files: Vec<PathBuf>,
    pub log_streams: Vec<StreamReport>,
}

/// Flies `table` with the watchdog in the `health` slot, health snapshots in the `logging`
/// slot and idle tasks elsewhere, logging the executive's timing records and the snapshots
/// under `log_dir/<start time>/`.
pub fn fly_idle<P: Platform>(
    platform: &P,
    table: &'static FrameTable,
    log_dir: &std::path::Path,
    options: RunOptions<'_>,
) -> Result<FlightReport, String> {
    let started = SystemTime::now();
    let flight_dir = crate::flightdir::create(log_dir, started).map_err(|e| {
        format!(
            "cannot create a flight directory in {}: {e}",
            log_dir.display()
        )
    })?;
    let mut writer = LogWriter::new(WriterConfig::new(flight_dir.clone()));
    let timing_stream = writer.stream("executive", TIMING_RING_BYTES);
    let health_stream = writer.stream("health", HEALTH_RING_BYTES);
    let statuses = [
        ("executive", std::sync::Arc::clone(&timing_stream.status)),
        ("health", std::sync::Arc::clone(&health_stream.status)),
    ];
    let writer = writer.start().map_err(|e| {
        format!(
            "cannot start the log writer in {}: {e}",
            flight_dir.display()
        )
    })?;

    // Log TIME is wall-clock time on a vehicle and the virtual clock in a simulation.
    let time_origin_ns = if platform.virtual_time() {
        0
    } else {
        started
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(0))
    };
    let mut timing = TimingLog::start(timing_stream, table, time_origin_ns, 0)?;

    let watchdog_out = LatestSlot::new();
    let mut watchdog = HealthTask::new(&watchdog_out);
    let mut logging = LoggingTask::new(health_stream, HEALTH_SNAPSHOT_NS);
    let mut idle = idle_tasks(table.tasks.len());
    let mut tasks = assemble(
        table,
        &mut idle,
        vec![("health", &mut watchdog), ("logging", &mut logging)],
    );
    let options = RunOptions {
        log_time_origin_ns: time_origin_ns,
        ..options
    };
    let result = run_executive(platform, table, &mut tasks, options, |r| timing.record(r));
    drop(tasks);
    timing.finish();
    let log_files = writer.finish();
    let summary = result.map_err(|e: HostError| e.to_string())?;

    let mut report = SummaryReport::from(&summary);
    report.set_watchdog(watchdog.report());
    Ok(FlightReport {
        summary: report,
        flight_dir,
        log_files,
        log_streams: statuses
            .iter()
            .map(|(name, status)| StreamReport {
                name: (*name).into(),
                records_written: status.records_written.load(Ordering::Relaxed),
                records_dropped: status.records_dropped.load(Ordering::Relaxed),
                records_lost: status.records_lost.load(Ordering::Relaxed),
                failed: status.failed.load(Ordering::Relaxed),
            })
            .collect(),
    })
}

/// One task per slot of `table`: the named real tasks where given, idle ones elsewhere.
fn assemble<'a>(
    table: &FrameTable,
    idle: &'a mut [IdleTask],
    mut real: Vec<(&'static str, &'a mut dyn Task)>,
) -> Vec<&'a mut dyn Task> {
    idle.iter_mut()
        .zip(table.tasks)
        .map(
            |(idle, slot)| match real.iter().position(|(name, _)| *name == slot.name) {
                Some(found) => real.swap_remove(found).1,
                None => idle as &mut dyn Task,
            },
        )
        .collect()
}

/// The flight summary for people: the run, then where its files are.
pub fn render_flight(report: &FlightReport) -> String {
    let mut out = crate::summary::render_summary(&report.summary);
    out += &format!("flight directory: {}\n", report.flight_dir.display());
    for s in &report.log_streams {
        out += &format!(
            "log {}: {} records written, {} dropped (ring full), {} lost{}\n",
            s.name,
            s.records_written,
            s.records_dropped,
            s.records_lost,
            if s.failed {
                " — WRITE FAILED, logging stopped"
            } else {
                ""
            }
        );
    }
    for f in &report.log_files {
        out += &format!("  {}\n", f.display());
    }
    out
}

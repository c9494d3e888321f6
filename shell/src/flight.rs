//! One flight: a directory for its files, the log writer, the device I/O, the executive and
//! its tasks, and the report at the end. Slots whose task does not exist yet (estimator,
//! control, telemetry until their issues land) hold idle tasks.

use crate::host::{HostError, RunOptions, run_executive};
use crate::idle::{IdleTask, idle_tasks};
use crate::logwriter::{LogStream, LogWriter, StreamStatus, WriterConfig};
use crate::platform::Platform;
use crate::serial::{DevicePort, PortConfig, PortState, PortStatus, check_opens, spawn_port};
use crate::summary::SummaryReport;
use crate::timing_log::TimingLog;
use crate::vehicle::VehicleConfig;
use serde::Serialize;
use skyframe_core::comm::LatestSlot;
use skyframe_core::devices::DecoderStats;
use skyframe_core::devices::gps::{GpsConfig, GpsFix};
use skyframe_core::devices::imu::ImuSample;
use skyframe_core::executive::Task;
use skyframe_core::schedule::FrameTable;
use skyframe_core::tasks::gps::GpsTask;
use skyframe_core::tasks::health::HealthTask;
use skyframe_core::tasks::imu::ImuTask;
use skyframe_core::tasks::logging::LoggingTask;
use skyframe_core::tasks::servo::{ComputerCommand, PilotInput, ServoTask};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

/// Ring of the executive's timing stream: ~100 B a frame, so several seconds of backlog.
const TIMING_RING_BYTES: usize = 256 * 1024;
/// Ring of each task's log stream: seconds of its heaviest output (IMU: ~5 kB/s).
const TASK_RING_BYTES: usize = 128 * 1024;
/// Health snapshots once a second.
const HEALTH_SNAPSHOT_NS: u64 = 1_000_000_000;
const MS: u64 = 1_000_000;

/// Where the flight's devices are.
pub enum Devices<'a> {
    /// None: device slots hold idle tasks (the executive alone).
    None,
    /// Serial ports, as `vehicle.toml` says.
    Serial(&'a VehicleConfig),
}

pub struct FlightPlan<'a> {
    pub log_dir: &'a Path,
    pub devices: Devices<'a>,
    pub options: RunOptions<'a>,
}

/// What happened to one log stream.
#[derive(Debug, Serialize)]
pub struct StreamReport {
    pub name: String,
    pub records_written: u64,
    pub records_dropped: u64,
    pub records_lost: u64,
    pub failed: bool,
}

/// One device at the end of the flight: its port and its decoder.
#[derive(Debug, Serialize)]
pub struct DeviceReport {
    pub name: &'static str,
    pub port: PathBuf,
    pub port_state: String,
    pub opens: u32,
    pub losses: u32,
    pub bytes_in: u64,
    pub bytes_out: u64,
    pub bytes_dropped: u64,
    pub frames: u32,
    pub bad_checksum: u32,
    pub framing_errors: u32,
    pub overflows: u32,
    pub bytes_discarded: u32,
    pub invalid_payload: u32,
    pub sequence_gaps: u32,
    pub stale_events: u32,
}

#[derive(Debug, Serialize)]
pub struct FlightReport {
    #[serde(flatten)]
    pub summary: SummaryReport,
    pub flight_dir: PathBuf,
    pub log_files: Vec<PathBuf>,
    pub log_streams: Vec<StreamReport>,
    pub devices: Vec<DeviceReport>,
}

/// The log streams of one flight, and their statuses for the report.
struct Streams {
    writer: LogWriter,
    statuses: Vec<(String, Arc<StreamStatus>)>,
}

impl Streams {
    fn open(&mut self, name: &str, ring_bytes: usize) -> LogStream {
        let stream = self.writer.stream(name, ring_bytes);
        self.statuses
            .push((name.to_string(), Arc::clone(&stream.status)));
        stream
    }
}

/// A running serial device: its port thread and what the report needs.
struct SerialDevice {
    name: &'static str,
    config: PortConfig,
    status: Arc<PortStatus>,
    join: std::thread::JoinHandle<()>,
}

/// Flies `table`: the watchdog in `health`, snapshots in `logging`, device tasks in `imu`,
/// `gps` and `servo` when the plan has devices, idle tasks elsewhere. Everything is logged
/// under `log_dir/<start time>/`.
pub fn fly<P: Platform>(
    platform: &P,
    table: &'static FrameTable,
    plan: FlightPlan<'_>,
) -> Result<FlightReport, String> {
    // Ports first: a typo in vehicle.toml is said before anything is created.
    let port_configs: Vec<(&'static str, PortConfig, u64)> = match &plan.devices {
        Devices::None => Vec::new(),
        Devices::Serial(vehicle) => vehicle
            .devices()
            .into_iter()
            .map(|(name, d)| {
                let config = PortConfig {
                    device: name.to_string(),
                    path: d.port.clone(),
                    baud: d.baud,
                };
                (name, config, u64::from(d.stale_ms) * MS)
            })
            .collect(),
    };
    for (_, config, _) in &port_configs {
        check_opens(config)?;
    }

    let started = SystemTime::now();
    let flight_dir = crate::flightdir::create(plan.log_dir, started).map_err(|e| {
        format!(
            "cannot create a flight directory in {}: {e}",
            plan.log_dir.display()
        )
    })?;
    let mut streams = Streams {
        writer: LogWriter::new(WriterConfig::new(flight_dir.clone())),
        statuses: Vec::new(),
    };
    let timing_stream = streams.open("executive", TIMING_RING_BYTES);
    let health_stream = streams.open("health", TASK_RING_BYTES);

    // Device I/O threads, each with its task's log stream.
    let io_stop = Arc::new(AtomicBool::new(false));
    let mut serial: Vec<SerialDevice> = Vec::new();
    let mut device_ports: Vec<(&'static str, DevicePort, LogStream, u64)> = Vec::new();
    for (name, config, stale_ns) in port_configs {
        let (handle, join) = spawn_port(config.clone(), Arc::clone(&io_stop))
            .map_err(|e| format!("cannot start the {name} port thread: {e}"))?;
        let log = streams.open(name, TASK_RING_BYTES);
        serial.push(SerialDevice {
            name,
            config,
            status: handle.status,
            join,
        });
        device_ports.push((name, DevicePort::new(handle.rx, handle.tx), log, stale_ns));
    }

    let writer = streams.writer.start().map_err(|e| {
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

    // The data path between tasks.
    let imu_samples: LatestSlot<ImuSample> = LatestSlot::new();
    let gps_fixes: LatestSlot<GpsFix> = LatestSlot::new();
    let servo_commands: LatestSlot<ComputerCommand> = LatestSlot::new();
    let pilot: LatestSlot<PilotInput> = LatestSlot::new();
    let watchdog_out = LatestSlot::new();

    let mut watchdog = HealthTask::new(&watchdog_out);
    let mut logging = LoggingTask::new(health_stream, HEALTH_SNAPSHOT_NS);
    let mut imu_task = None;
    let mut gps_task = None;
    let mut servo_task = None;
    for (name, port, log, stale_ns) in device_ports {
        match name {
            "imu" => imu_task = Some(ImuTask::new(port, log, stale_ns, &imu_samples)),
            "gps" => {
                let config = GpsConfig {
                    stale_timeout_ns: stale_ns,
                    ..GpsConfig::default()
                };
                gps_task = Some(GpsTask::new(port, log, config, &gps_fixes));
            }
            _ => {
                servo_task = Some(ServoTask::new(port, log, stale_ns, &servo_commands, &pilot));
            }
        }
    }

    let mut idle = idle_tasks(table.tasks.len());
    let mut real: Vec<(&'static str, &mut dyn Task)> =
        vec![("health", &mut watchdog), ("logging", &mut logging)];
    if let Some(t) = imu_task.as_mut() {
        real.push(("imu", t));
    }
    if let Some(t) = gps_task.as_mut() {
        real.push(("gps", t));
    }
    if let Some(t) = servo_task.as_mut() {
        real.push(("servo", t));
    }
    let mut tasks = assemble(table, &mut idle, real);
    let options = RunOptions {
        log_time_origin_ns: time_origin_ns,
        ..plan.options
    };
    let result = run_executive(platform, table, &mut tasks, options, |r| timing.record(r));
    drop(tasks);

    // Shut down in data order: device threads (their last output went out with the
    // tasks' shutdown), then the log.
    io_stop.store(true, Ordering::Relaxed);
    let mut devices = Vec::new();
    let stats = |name: &str| -> DecoderStats {
        match name {
            "imu" => imu_task.as_ref().map(|t| *t.stats()),
            "gps" => gps_task.as_ref().map(|t| *t.stats()),
            _ => servo_task.as_ref().map(|t| *t.stats()),
        }
        .unwrap_or_default()
    };
    for d in serial {
        let _ = d.join.join();
        devices.push(device_report(d.name, &d.config, &d.status, &stats(d.name)));
    }
    timing.finish();
    let log_files = writer.finish();
    let summary = result.map_err(|e: HostError| e.to_string())?;

    let mut report = SummaryReport::from(&summary);
    report.set_watchdog(watchdog.report());
    Ok(FlightReport {
        summary: report,
        flight_dir,
        log_files,
        log_streams: streams
            .statuses
            .iter()
            .map(|(name, status)| StreamReport {
                name: name.clone(),
                records_written: status.records_written.load(Ordering::Relaxed),
                records_dropped: status.records_dropped.load(Ordering::Relaxed),
                records_lost: status.records_lost.load(Ordering::Relaxed),
                failed: status.failed.load(Ordering::Relaxed),
            })
            .collect(),
        devices,
    })
}

fn device_report(
    name: &'static str,
    config: &PortConfig,
    port: &PortStatus,
    stats: &DecoderStats,
) -> DeviceReport {
    let state = match port.state() {
        PortState::Opening => "opening",
        PortState::Open => "open",
        PortState::Lost => "lost",
        PortState::Closed => "closed",
    };
    DeviceReport {
        name,
        port: config.path.clone(),
        port_state: state.into(),
        opens: port.opens.load(Ordering::Relaxed),
        losses: port.losses.load(Ordering::Relaxed),
        bytes_in: port.bytes_in.load(Ordering::Relaxed),
        bytes_out: port.bytes_out.load(Ordering::Relaxed),
        bytes_dropped: port.bytes_dropped.load(Ordering::Relaxed),
        frames: stats.frames,
        bad_checksum: stats.bad_checksum,
        framing_errors: stats.framing_errors,
        overflows: stats.overflows,
        bytes_discarded: stats.bytes_discarded,
        invalid_payload: stats.invalid_payload,
        sequence_gaps: stats.sequence_gaps,
        stale_events: stats.stale_events,
    }
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

/// The flight summary for people: the run, its devices, then where its files are.
pub fn render_flight(report: &FlightReport) -> String {
    let mut out = crate::summary::render_summary(&report.summary);
    for d in &report.devices {
        out += &format!(
            "device {:<5} {} ({}; opened {}x, lost {}x): {} B in, {} B out, {} B dropped; \
             {} frames, {} bad checksum, {} framing errors, {} overflows, {} went stale\n",
            d.name,
            d.port.display(),
            d.port_state,
            d.opens,
            d.losses,
            d.bytes_in,
            d.bytes_out,
            d.bytes_dropped,
            d.frames,
            d.bad_checksum,
            d.framing_errors,
            d.overflows,
            d.stale_events,
        );
    }
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

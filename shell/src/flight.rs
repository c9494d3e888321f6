//! One flight: a directory for its files, the log writer, the device I/O, the executive and
//! its tasks, and the report at the end. Slots whose task does not exist yet (estimator,
//! control, telemetry until their issues land) hold idle tasks.

use crate::executive_log::ExecutiveLog;
use crate::host::{EXIT_STOPPED_STUCK, HostError, RunOptions, STOP_CLOSE_WAIT, run_executive};
use crate::idle::idle_tasks;
use crate::logwriter::{LogStream, LogWriter, StreamMode, StreamStatus, WriterConfig};
use crate::platform::Platform;
use crate::serial::{DevicePort, PortConfig, PortState, PortStatus, check_opens, spawn_port};
use crate::simflight::{SimPlatform, device_rings};
use crate::summary::SummaryReport;
use crate::tasks::{FlyingTask, LinkParts, Needs, Shared, TaskEntry, TaskReports, Wiring};
use crate::vehicle::VehicleConfig;
use serde::Serialize;
use skyframe_core::comm::LogHealthCell;
use skyframe_core::control::mission::Mission;
use skyframe_core::control::mission_store::MissionStore;
use skyframe_core::control::mode::FlightMode;
use skyframe_core::devices::DecoderStats;
use skyframe_core::executive::Task;
use skyframe_core::link::ingress::IngressCounters;
use skyframe_core::link::messages::{Name, Value, ValueType};
use skyframe_core::link::params::{ParamTable, SetParamResult};
use skyframe_core::schedule::FrameTable;
use skyframe_core::tasks::control::define_params;
use skyframe_core::tasks::tap::Tap;
use skyframe_core::tasks::telemetry::TelemetryConfig;
use skyframe_sim::world::SimWorld;
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Ring of the executive's timing stream: ~100 B a frame, so several seconds of backlog.
const TIMING_RING_BYTES: usize = 256 * 1024;
/// Ring of each task's log stream: seconds of its heaviest output (IMU: ~5 kB/s).
const TASK_RING_BYTES: usize = 128 * 1024;
const MS: u64 = 1_000_000;

/// Where the flight's devices are.
pub enum Devices<'a> {
    /// None: device slots hold idle tasks (the executive alone).
    None,
    /// Serial ports, as `vehicle.toml` says.
    Serial(&'a VehicleConfig),
    /// The simulated airplane's devices, through in-process rings.
    Sim(Box<SimWorld>),
}

/// Staleness timeouts of the simulated devices: five periods of each.
const SIM_STALE_NS: [u64; 3] = [50 * MS, 500 * MS, 100 * MS];

pub struct FlightPlan<'a> {
    pub log_dir: &'a Path,
    pub log: LogSettings,
    pub devices: Devices<'a>,
    /// The telemetry link; `None` flies without one.
    pub link: Option<LinkPlan>,
    /// Waypoints for AUTO; without them AUTO holds altitude, heading and airspeed.
    pub mission: Option<Mission>,
    /// The tasks the schedule's names stand for ([`crate::tasks::REGISTRY`]).
    pub registry: &'a [TaskEntry],
    /// Parameters set before the first frame (`--param`, a scenario's `[parameters]`),
    /// through the same checks as the link's `set`.
    pub parameters: Vec<(String, f64)>,
    pub options: RunOptions<'a>,
    /// The MAVLink endpoint (`--mavlink`); it needs `link` (see [`LinkPlan::network`]).
    pub mavlink: Option<crate::mavlink::MavlinkPlan>,
}

/// How the flight talks to the ground.
#[derive(Clone, Debug)]
pub struct LinkPlan {
    /// The pre-shared key; `None`: a fresh one is written into the flight directory.
    pub key: Option<PathBuf>,
    pub commands: std::net::SocketAddr,
    /// `commands` is the default: when that port is taken (another vehicle on this machine),
    /// take any free one instead of failing.
    pub commands_is_default: bool,
    pub telemetry: Vec<std::net::SocketAddr>,
    pub vehicle_id: u16,
    pub sign_telemetry: bool,
    /// `false`: no skyframe link on the network (`--no-link` with `--mavlink`): no socket,
    /// no key file; the rings and the link thread carry MAVLink's traffic only.
    pub network: bool,
}

/// The link at the end of the flight.
#[derive(Debug, Serialize)]
pub struct LinkReport {
    pub key_file: PathBuf,
    pub commands_address: String,
    pub run_id: u32,
    pub datagrams_in: u64,
    pub datagrams_out: u64,
    pub send_errors: u64,
    pub commands_accepted: u32,
    pub commands_rejected: u32,
    pub telemetry_sent: u32,
}

/// How the flight's logs are written.
#[derive(Clone, Debug)]
pub struct LogSettings {
    /// Streams written as CSV text instead of binary.
    pub text_streams: Vec<String>,
    pub rotate_bytes: u64,
    pub flush_every: std::time::Duration,
    pub fsync_every: std::time::Duration,
    /// How to measure the log's free space (the platform's; `None`: not checked).
    pub free_space: Option<crate::platform::FreeSpaceProbe>,
    /// Refuse to fly when the free space is less than the flight is expected to log.
    pub require_space: bool,
}

impl LogSettings {
    pub fn from_config(log: &crate::vehicle::LogConfig, extra_text: &[String]) -> Self {
        let mut text_streams = log.text.clone();
        text_streams.extend(extra_text.iter().cloned());
        Self {
            text_streams,
            rotate_bytes: log.rotate_mb.saturating_mul(1024 * 1024),
            flush_every: std::time::Duration::from_millis(log.flush_ms),
            fsync_every: std::time::Duration::from_millis(log.fsync_ms),
            free_space: None,
            require_space: false,
        }
    }
}

/// What happened to one log stream.
#[derive(Debug, Serialize)]
pub struct StreamReport {
    pub name: String,
    pub records_written: u64,
    pub records_dropped: u64,
    pub records_lost: u64,
    pub failed: bool,
    /// Times a write failed (disk full) and the stream waited to write again.
    pub suspensions: u32,
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
    /// The decoder's counters, as fields of the device's own.
    #[serde(flatten)]
    pub decoder: DecoderStats,
}

#[derive(Debug, Serialize)]
pub struct FlightReport {
    #[serde(flatten)]
    pub summary: SummaryReport,
    /// Wall-clock time the flight took, and flight time per wall-clock time (virtual time
    /// runs faster than real time).
    pub wall_s: f64,
    pub speed_up: f64,
    pub flight_dir: PathBuf,
    pub log_files: Vec<PathBuf>,
    pub log_streams: Vec<StreamReport>,
    pub devices: Vec<DeviceReport>,
    pub link: Option<LinkReport>,
    /// The MAVLink endpoint's counters (`--mavlink`).
    pub mavlink: Option<crate::mavlink::ingress::CountersReport>,
}

/// The log streams of one flight, and their statuses for the report.
struct Streams {
    writer: LogWriter,
    text: Vec<String>,
    wait_when_full: bool,
    statuses: Vec<(String, Arc<StreamStatus>)>,
}

impl Streams {
    fn open(&mut self, name: &str, ring_bytes: usize) -> LogStream {
        let mode = if self.text.iter().any(|t| t == name) {
            StreamMode::Text
        } else {
            StreamMode::Binary
        };
        let mut stream = self.writer.stream_as(name, ring_bytes, mode);
        stream.set_wait_when_full(self.wait_when_full);
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

/// Flies `table`: the watchdog in `watchdog`, snapshots in `health`, device tasks in `imu`,
/// `gps` and `servo` when the plan has devices, idle tasks elsewhere. Everything is logged
/// under `log_dir/<start time>/`.
pub fn fly<P: Platform>(
    platform: &P,
    table: &'static FrameTable,
    plan: FlightPlan<'_>,
) -> Result<FlightReport, String> {
    // Ports first: a typo in vehicle.toml is said before anything is created.
    let port_configs: Vec<(&'static str, PortConfig, u64)> = match &plan.devices {
        Devices::None | Devices::Sim(_) => Vec::new(),
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
        check_opens(config, platform.serial_opener())?;
    }

    let started = SystemTime::now();
    let wall = std::time::Instant::now();
    let flight_dir = crate::flightdir::create(plan.log_dir, started).map_err(|e| {
        format!(
            "cannot create a flight directory in {}: {e}",
            plan.log_dir.display()
        )
    })?;
    check_log_space(&plan, &flight_dir)?;
    // The link: key, run id, socket thread.
    let io_stop = Arc::new(AtomicBool::new(false));
    let ingress = Arc::new(IngressCounters::new());
    let log_health = Arc::new(LogHealthCell::new());
    let mut link = None;
    let mavlink_key = plan.mavlink.as_ref().and_then(|m| m.key).map(|k| k.0);
    let (mut mavlink_hook, mut mavlink_ends) = match &plan.mavlink {
        Some(_) => {
            let (hook, ends) = crate::mavlink::hook_pair();
            (Some(hook), Some(ends))
        }
        None => (None, None),
    };
    let mut mavlink_join = None;
    let mut mavlink_counters = None;
    if let Some(plan_link) = &plan.link {
        let (key_file, key) = match &plan_link.key {
            Some(path) => (path.clone(), crate::link::load_key(path)?),
            None if !plan_link.network => (PathBuf::new(), crate::mavlink::memory_key()?),
            None => {
                let (path, key) = crate::link::write_new_key(&flight_dir)?;
                eprintln!(
                    "link key: {} (skyframe-ground finds it there)",
                    path.display()
                );
                (path, key)
            }
        };
        let run_id = crate::link::new_run_id()?;
        let screen = || crate::link::Screen {
            key: key.clone(),
            vehicle_id: plan_link.vehicle_id,
            ingress: Arc::clone(&ingress),
        };
        let spawned = crate::link::spawn_link_with(
            plan_link.network.then_some(plan_link.commands),
            plan_link.telemetry.clone(),
            screen(),
            Arc::clone(&io_stop),
            mavlink_hook.take(),
        );
        let spawned = match spawned {
            Err(e) if plan_link.commands_is_default => {
                let any = std::net::SocketAddr::new(plan_link.commands.ip(), 0);
                // The failed try took MAVLink's hook with it: a fresh pair.
                let hook = plan.mavlink.as_ref().map(|_| {
                    let (hook, ends) = crate::mavlink::hook_pair();
                    mavlink_ends = Some(ends);
                    hook
                });
                let spawned = crate::link::spawn_link_with(
                    Some(any),
                    plan_link.telemetry.clone(),
                    screen(),
                    Arc::clone(&io_stop),
                    hook,
                )?;
                log::warn!("{e}: listening for commands on a free port instead");
                spawned
            }
            other => other?,
        };
        link = Some((key_file, key, run_id, spawned, plan_link.clone()));
    }

    let mut streams = Streams {
        writer: LogWriter::new(WriterConfig {
            rotate_bytes: plan.log.rotate_bytes,
            flush_every: plan.log.flush_every,
            fsync_every: plan.log.fsync_every,
            free_space: plan.log.free_space,
            health: Some(Arc::clone(&log_health)),
            ..WriterConfig::new(flight_dir.clone())
        }),
        text: plan.log.text_streams.clone(),
        wait_when_full: platform.virtual_time(),
        statuses: Vec::new(),
    };
    let timing_stream = streams.open("executive", TIMING_RING_BYTES);

    // Device I/O: a port thread per serial device, or the simulated airplane's rings.
    let mut serial: Vec<SerialDevice> = Vec::new();
    let mut device_ports: Vec<(&'static str, DevicePort, u64)> = Vec::new();
    for (name, config, stale_ns) in port_configs {
        let (handle, join) = spawn_port(
            config.clone(),
            platform.serial_opener(),
            Arc::clone(&io_stop),
        )
        .map_err(|e| format!("cannot start the {name} port thread: {e}"))?;
        serial.push(SerialDevice {
            name,
            config,
            status: handle.status,
            join,
        });
        device_ports.push((name, DevicePort::new(handle.rx, handle.tx), stale_ns));
    }
    let mut sim = None;
    if let Devices::Sim(world) = plan.devices {
        let (ports, link) = device_rings();
        let [imu, gps, servo] = ports;
        for ((name, port), stale_ns) in [("imu", imu), ("gps", gps), ("servo", servo)]
            .into_iter()
            .zip(SIM_STALE_NS)
        {
            device_ports.push((name, port, stale_ns));
        }
        let truth = streams.open("truth", TASK_RING_BYTES);
        sim = Some((world, link, truth));
    }

    // Each slot of the table: its registry entry, and whether this flight has what it needs.
    let scheduled: Vec<&str> = table.tasks.iter().map(|t| t.name).collect();
    if let Some(mismatch) = crate::tasks::schedule_mismatch(&scheduled, plan.registry) {
        return Err(mismatch);
    }
    let has_sensors = !device_ports.is_empty();
    let mut slots: Vec<(&TaskEntry, Option<&'static str>)> = Vec::new();
    for slot in table.tasks {
        let Some(entry) = plan.registry.iter().find(|e| e.name == slot.name) else {
            return Err(format!("task `{}` has no registry entry", slot.name));
        };
        let missing = match entry.needs {
            Needs::Nothing => None,
            Needs::Device => (!device_ports.iter().any(|(name, ..)| *name == entry.name))
                .then_some("no such device on this flight"),
            Needs::Sensors => (!has_sensors).then_some("no devices to feed it"),
            Needs::Link => link.is_none().then_some("no link (--no-link)"),
        };
        if let Some(why) = missing {
            log::info!("task {} does not fly: {why}", entry.name);
        }
        slots.push((entry, missing));
    }
    let mut logs: Vec<Option<LogStream>> = slots
        .iter()
        .map(|(entry, missing)| {
            missing
                .is_none()
                .then(|| streams.open(entry.log, TASK_RING_BYTES))
        })
        .collect();

    // A stream named for text that this flight does not write is a typo, not a no-op.
    if let Some(unknown) = streams
        .text
        .iter()
        .find(|t| !streams.statuses.iter().any(|(name, _)| name == *t))
    {
        let written: Vec<&str> = streams.statuses.iter().map(|(n, _)| n.as_str()).collect();
        return Err(format!(
            "--text-log {unknown}: this flight writes no such stream ({})",
            written.join(", ")
        ));
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
    let mut timing = ExecutiveLog::start(timing_stream, table, time_origin_ns, 0)?;
    // The MAVLink endpoint, on the link's rings (docs/mavlink.md).
    if let (Some(mplan), Some(ends), Some((_, key, run_id, _, plan_link))) =
        (&plan.mavlink, mavlink_ends.take(), &link)
    {
        mavlink_counters = Some(Arc::clone(&ends.counters));
        mavlink_join = Some(crate::mavlink::bridge::spawn(
            crate::mavlink::bridge::BridgeSetup {
                plan: mplan.clone(),
                signing_key: mavlink_key,
                link_key: key.clone(),
                run_id: *run_id,
                vehicle_id: plan_link.vehicle_id,
                task_names: table.tasks.iter().map(|t| t.name.to_string()).collect(),
                mission: plan.mission.clone(),
                time_origin_ns,
                ends,
                io_stop: Arc::clone(&io_stop),
            },
        )?);
    }

    // The data path between tasks.
    let shared = Shared {
        mission: RefCell::new(MissionStore::new(plan.mission.as_ref())),
        ..Shared::default()
    };
    // A loaded mission is what the researcher wants flown when the pilot hands over; the
    // ground station can still request Stabilise or Manual at any time.
    if plan.mission.is_some() {
        shared.mode_request.publish(FlightMode::Auto);
    }
    if let Ok(mut params) = shared.params.try_borrow_mut() {
        define_params(&mut params, &shared.control)
            .map_err(|e| format!("control parameters: {e:?}"))?;
        set_parameters(&mut params, &plan.parameters)?;
    }
    let taps: Vec<Tap> = slots.iter().map(|_| Tap::new()).collect();
    let tap_refs: Vec<Option<&Tap>> = slots
        .iter()
        .zip(&taps)
        .map(|((_, missing), tap)| missing.is_none().then_some(tap))
        .collect();
    let duration_ns = plan
        .options
        .duration
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    let mut link_parts = None;
    let mut link_io = None;
    if let Some((key_file, key, run_id, (port, join, io), plan_link)) = link {
        let local = match io.local {
            Some(a) => a.to_string(),
            // --no-link with --mavlink: the link thread carries MAVLink's traffic only.
            None if !plan_link.network => "none (--no-link; MAVLink only)".to_string(),
            None => plan_link.commands.to_string(),
        };
        link_parts = Some(LinkParts {
            port,
            key,
            config: TelemetryConfig {
                vehicle_id: plan_link.vehicle_id,
                run_id,
                sign_telemetry: plan_link.sign_telemetry,
                duration_ns,
            },
            ingress: &ingress,
            log_health: &log_health,
        });
        link_io = Some((key_file, run_id, join, io, local));
    }

    // The tasks, each built by its registry entry.
    let mut flying: Vec<Option<FlyingTask<'_>>> = Vec::new();
    for (i, ((entry, missing), tap)) in slots.iter().zip(&taps).enumerate() {
        if missing.is_some() {
            flying.push(None);
            continue;
        }
        let device = (entry.needs == Needs::Device)
            .then(|| {
                let at = device_ports.iter().position(|(n, ..)| *n == entry.name)?;
                let (_, port, stale_ns) = device_ports.swap_remove(at);
                Some((port, stale_ns))
            })
            .flatten();
        let mut wiring = Wiring {
            shared: &shared,
            table,
            tap,
            taps: &tap_refs,
            log: logs.get_mut(i).and_then(Option::take),
            device,
            simulated: sim.is_some(),
            link: (entry.needs == Needs::Link)
                .then(|| link_parts.take())
                .flatten(),
            stop: plan.options.stop,
        };
        let task = (entry.build)(&mut wiring).map_err(|e| format!("task {}: {e}", entry.name))?;
        flying.push(Some(FlyingTask(task)));
    }
    let mut idle = idle_tasks(table.tasks.len());
    let mut tasks: Vec<&mut dyn Task> = flying
        .iter_mut()
        .zip(idle.iter_mut())
        .map(|(task, idle)| match task {
            Some(task) => task as &mut dyn Task,
            None => idle as &mut dyn Task,
        })
        .collect();
    // A stop that a stuck task keeps waiting: close the logs whole and end the process
    // around the task (the executive never cancels one), with an exit code that says so.
    let emergency = writer.emergency_close();
    let stuck_flight_dir = flight_dir.display().to_string();
    let on_stuck = move |waited: Duration| {
        let closed = emergency.close(STOP_CLOSE_WAIT);
        eprintln!(
            "skyframe: stopped abnormally: a task was still in its step {:.0} ms after the stop \
             request; logs in {stuck_flight_dir} {} (exit {EXIT_STOPPED_STUCK})",
            waited.as_secs_f64() * 1e3,
            if closed {
                "closed whole"
            } else {
                "NOT closed in time"
            },
        );
        std::process::exit(EXIT_STOPPED_STUCK);
    };
    let options = RunOptions {
        log_time_origin_ns: time_origin_ns,
        on_stuck_stop: Some(&on_stuck),
        ..plan.options
    };
    let result = match sim {
        Some((world, link, truth)) => {
            let sim_platform =
                SimPlatform::new(platform, *world, link, Some(truth), time_origin_ns);
            run_executive(&sim_platform, table, &mut tasks, options, &mut timing)
        }
        None => run_executive(platform, table, &mut tasks, options, &mut timing),
    };
    drop(tasks);

    // Shut down in data order: device threads (their last output went out with the
    // tasks' shutdown), then the log.
    io_stop.store(true, Ordering::Relaxed);
    let mut reports = TaskReports::default();
    for task in flying.iter().flatten() {
        task.0.report(&mut reports);
    }
    let stats = |name: &str| -> DecoderStats {
        reports
            .devices
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, s)| *s)
            .unwrap_or_default()
    };
    let mut devices = Vec::new();
    for d in serial {
        let _ = d.join.join();
        let port = (d.config.path.clone(), d.status);
        devices.push(device_report(d.name, Some(&port), &stats(d.name)));
    }
    if devices.is_empty() {
        for (name, _) in &reports.devices {
            devices.push(device_report(name, None, &stats(name)));
        }
    }
    if let Some(join) = mavlink_join {
        let _ = join.join();
    }
    let link = link_io.map(|(key_file, run_id, join, io, commands_address)| {
        let _ = join.join();
        let counters = reports.link.unwrap_or_default();
        LinkReport {
            key_file,
            commands_address,
            run_id,
            datagrams_in: io.datagrams_in.load(Ordering::Relaxed),
            datagrams_out: io.datagrams_out.load(Ordering::Relaxed),
            send_errors: io.send_errors.load(Ordering::Relaxed),
            commands_accepted: counters.accepted,
            commands_rejected: counters.rejected(),
            telemetry_sent: counters.telemetry_sent,
        }
    });
    timing.finish();
    let log_files = writer.finish();
    let summary = result.map_err(|e: HostError| e.to_string())?;

    let mut report = SummaryReport::from(&summary);
    if let Some(watchdog) = &reports.watchdog {
        report.set_watchdog(watchdog);
    }
    let wall_s = wall.elapsed().as_secs_f64();
    Ok(FlightReport {
        speed_up: report.elapsed_s / wall_s.max(1e-9),
        wall_s,
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
                suspensions: status.suspensions.load(Ordering::Relaxed),
            })
            .collect(),
        devices,
        link,
        mavlink: mavlink_counters.map(|c| c.snapshot()),
    })
}

/// What a flight logs per second, to check the free space at start against the programmed
/// duration: 45.3 kB/s measured on the shipped schedule in simulation (`skyframe sim --fast
/// --duration 100`: 4.53 MB, all streams, truth included), rounded up. CSV text streams are
/// larger; each one named adds as much again, a generous bound.
pub const LOG_BYTES_PER_S: f64 = 46_000.0;

/// Free space where the flight logs against what it is expected to log: a warning, or (with
/// `--require-log-space`) a refusal before anything flies. Skipped without a duration or a
/// way to measure.
fn check_log_space(plan: &FlightPlan<'_>, flight_dir: &Path) -> Result<(), String> {
    let (Some(probe), Some(duration)) = (plan.log.free_space, plan.options.duration) else {
        return Ok(());
    };
    let Ok(free) = probe(flight_dir) else {
        return Ok(());
    };
    let rate = LOG_BYTES_PER_S * (1.0 + plan.log.text_streams.len() as f64);
    let needed = rate * duration.as_secs_f64();
    if (free as f64) >= needed {
        return Ok(());
    }
    let message = format!(
        "{}: {} kB free, but a {:.0} s flight logs about {:.0} kB ({:.0} kB/s)",
        flight_dir.display(),
        free / 1024,
        duration.as_secs_f64(),
        needed / 1024.0,
        rate / 1024.0
    );
    if plan.log.require_space {
        // Nothing was written yet: leave no empty flight directory behind.
        let _ = std::fs::remove_dir(flight_dir);
        return Err(format!("refusing to fly (--require-log-space): {message}"));
    }
    log::warn!("{message}: logging will stop when the disk is full and resume when space returns");
    Ok(())
}

/// Sets each named parameter as the link's `set` would: a known name, a value of its type
/// in its range. `Err` is one line naming the parameter (the flight does not start).
pub fn set_parameters(table: &mut ParamTable, parameters: &[(String, f64)]) -> Result<(), String> {
    for (name, value) in parameters {
        let known = || {
            let names: Vec<&str> = table.iter().map(|p| p.name().as_str()).collect();
            format!(
                "parameter `{name}`: no such parameter ({})",
                names.join(", ")
            )
        };
        let (Some(param), Some(in_table)) = (Name::new(name), table.get(name)) else {
            return Err(known());
        };
        let typed = match in_table.value_type() {
            ValueType::F32 => Value::F32(*value as f32),
            ValueType::F64 => Value::F64(*value),
            ValueType::I32 if value.fract() == 0.0 => Value::I32(*value as i32),
            ValueType::U32 if value.fract() == 0.0 && *value >= 0.0 => Value::U32(*value as u32),
            ValueType::Bool if *value == 0.0 || *value == 1.0 => Value::Bool(*value == 1.0),
            other => {
                return Err(format!("parameter `{name}` = {value}: not a {other:?}"));
            }
        };
        let (min, max) = (in_table.min(), in_table.max());
        match table.set(&param, typed) {
            SetParamResult::Accepted { .. } => {}
            _ => {
                return Err(format!(
                    "parameter `{name}` = {value}: outside its range [{min:?}, {max:?}]"
                ));
            }
        }
    }
    Ok(())
}

/// `port` is the serial port's path and status; `None` for the simulator's in-process rings.
fn device_report(
    name: &'static str,
    port: Option<&(PathBuf, Arc<PortStatus>)>,
    stats: &DecoderStats,
) -> DeviceReport {
    let state = match port.map(|(_, s)| s.state()) {
        Some(PortState::Opening) => "opening",
        Some(PortState::Open) => "open",
        Some(PortState::Lost) => "lost",
        Some(PortState::Closed) => "closed",
        None => "simulated",
    };
    let counter = |f: fn(&PortStatus) -> u64| port.map_or(0, |(_, s)| f(s));
    DeviceReport {
        name,
        port: port.map_or_else(|| PathBuf::from("(simulator)"), |(p, _)| p.clone()),
        port_state: state.into(),
        opens: counter(|s| u64::from(s.opens.load(Ordering::Relaxed))) as u32,
        losses: counter(|s| u64::from(s.losses.load(Ordering::Relaxed))) as u32,
        bytes_in: counter(|s| s.bytes_in.load(Ordering::Relaxed)),
        bytes_out: counter(|s| s.bytes_out.load(Ordering::Relaxed)),
        bytes_dropped: counter(|s| s.bytes_dropped.load(Ordering::Relaxed)),
        decoder: *stats,
    }
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
            d.decoder.frames,
            d.decoder.bad_checksum,
            d.decoder.framing_errors,
            d.decoder.overflows,
            d.decoder.stale_events,
        );
    }
    if let Some(m) = &report.mavlink {
        out += &format!(
            "mavlink: {} datagrams in, {} accepted; refused: {} rate-limited, {} malformed, \
             {} unknown, {} unsigned, {} bad signature, {} replayed, {} for another system; \
             {} frames out ({} send errors)\n",
            m.datagrams_in,
            m.accepted,
            m.rate_limited,
            m.malformed,
            m.unknown,
            m.unsigned,
            m.bad_signature,
            m.replayed,
            m.other_target,
            m.frames_out,
            m.send_errors,
        );
    }
    out += &format!("flight directory: {}\n", report.flight_dir.display());
    for s in &report.log_streams {
        out += &format!(
            "log {}: {} records written, {} dropped (ring full), {} lost ({} write failures){}\n",
            s.name,
            s.records_written,
            s.records_dropped,
            s.records_lost,
            s.suspensions,
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

#[cfg(test)]
mod tests {
    use super::*;
    use skyframe_core::tasks::control::{ControlSettings, define_params};

    fn table() -> ParamTable {
        let mut table = ParamTable::new();
        define_params(&mut table, &ControlSettings::default()).expect("defines");
        table
    }

    #[test]
    fn parameters_are_set_through_the_tables_checks() {
        let mut t = table();
        set_parameters(&mut t, &[("control.roll_kp".into(), 0.8)]).expect("in range");
        assert_eq!(
            t.get("control.roll_kp").map(|p| p.value()),
            Some(Value::F32(0.8))
        );
        let e = set_parameters(&mut t, &[("control.roll_kp".into(), 99.0)]).expect_err("range");
        assert!(
            e.starts_with("parameter `control.roll_kp` = 99: outside its range"),
            "{e}"
        );
        // Refused: the value in force stays.
        assert_eq!(
            t.get("control.roll_kp").map(|p| p.value()),
            Some(Value::F32(0.8))
        );
        let e = set_parameters(&mut t, &[("control.nosuch".into(), 1.0)]).expect_err("unknown");
        assert!(
            e.starts_with("parameter `control.nosuch`: no such parameter (control.roll_kp, "),
            "{e}"
        );
    }
}

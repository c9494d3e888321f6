//! The task registry: every task a schedule can name, what it needs from the flight, and how
//! it is built. The real vehicle and the simulator fly the same table; only where the device
//! bytes come from differs (serial ports or the simulated airplane's rings).
//!
//! Adding a task (say a 50 ms barometer): write `core/src/tasks/baro.rs` (the task and its
//! `log_record!`s), add its line to `schedule.toml`, and add one [`TaskEntry`] here. A name in
//! the schedule with no entry, or an entry the schedule does not run, fails the build
//! (a `const` assertion below) and `skyframe check-schedule`; nothing runs as a
//! silent idle task.

use crate::logwriter::LogStream;
use crate::serial::DevicePort;
use skyframe_core::comm::{LatestSlot, LogHealthCell};
use skyframe_core::control::controls::ComputerCommand;
use skyframe_core::control::mission_store::MissionStore;
use skyframe_core::control::mode::FlightMode;
use skyframe_core::devices::DecoderStats;
use skyframe_core::devices::gps::{GpsConfig, GpsFix, SentenceKind};
use skyframe_core::devices::imu::ImuSample;
use skyframe_core::estimation::{Estimate, EstimatorConfig};
use skyframe_core::executive::{Task, TaskContext, TaskFault};
use skyframe_core::horizon::HorizonAttitude;
use skyframe_core::link::auth::LinkKey;
use skyframe_core::link::counters::LinkCounters;
use skyframe_core::link::ingress::IngressCounters;
use skyframe_core::link::params::ParamTable;
use skyframe_core::schedule::{FrameTable, SHIPPED};
use skyframe_core::tasks::control::{ControlSettings, ControlTask};
use skyframe_core::tasks::estimator::EstimatorTask;
use skyframe_core::tasks::gps::GpsTask;
use skyframe_core::tasks::health::HealthTask;
use skyframe_core::tasks::imu::ImuTask;
use skyframe_core::tasks::servo::{PilotInput, ServoTask};
use skyframe_core::tasks::tap::{Tap, TappedSink};
use skyframe_core::tasks::telemetry::{LinkShared, TelemetryConfig, TelemetryTask};
use skyframe_core::tasks::watchdog::{WatchdogReport, WatchdogTask};
use std::cell::{Cell, RefCell};
use std::sync::atomic::AtomicBool;

/// Health snapshots once a second.
const HEALTH_SNAPSHOT_NS: u64 = 1_000_000_000;

/// One task a schedule can name.
#[derive(Clone, Copy)]
pub struct TaskEntry {
    /// Its name in `schedule.toml`.
    pub name: &'static str,
    /// The log stream it writes (`<log>.bin`).
    pub log: &'static str,
    /// What the flight must have for the task to fly.
    pub needs: Needs,
    pub build: BuildFn,
}

/// Builds a task from the flight's wiring; `Err` is one line (the flight does not start).
pub type BuildFn = for<'w> fn(&mut Wiring<'w>) -> Result<Box<dyn FlightTask + 'w>, String>;

/// What a task needs from the flight. A flight without it does not fly the task, and says so
/// at the start (`skyframe sim --no-link`: no telemetry task).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Needs {
    Nothing,
    /// Its device's port (named as the task), from `vehicle.toml` or the simulator.
    Device,
    /// Devices to feed it (estimation and control fly whenever sensors do).
    Sensors,
    /// The telemetry link.
    Link,
}

/// The registry: one line a task.
pub const REGISTRY: &[TaskEntry] = &[
    TaskEntry {
        name: "imu",
        log: "imu",
        needs: Needs::Device,
        build: build_imu,
    },
    TaskEntry {
        name: "gps",
        log: "gps",
        needs: Needs::Device,
        build: build_gps,
    },
    TaskEntry {
        name: "servo",
        log: "servo",
        needs: Needs::Device,
        build: build_servo,
    },
    TaskEntry {
        name: "estimator",
        log: "estimator",
        needs: Needs::Sensors,
        build: build_estimator,
    },
    TaskEntry {
        name: "control",
        log: "control",
        needs: Needs::Sensors,
        build: build_control,
    },
    TaskEntry {
        name: "telemetry",
        log: "link",
        needs: Needs::Link,
        build: build_telemetry,
    },
    TaskEntry {
        name: "health",
        log: "health",
        needs: Needs::Nothing,
        build: build_health,
    },
    TaskEntry {
        name: "watchdog",
        log: "watchdog",
        needs: Needs::Nothing,
        build: build_watchdog,
    },
];

/// The names a registry holds, for `check-schedule` and error messages.
pub fn task_names(registry: &[TaskEntry]) -> Vec<&'static str> {
    registry.iter().map(|e| e.name).collect()
}

/// Whether every task of `table` has an entry and every entry is in `table`. `const`, so the
/// shipped schedule is checked when the shell builds.
pub const fn schedule_matches(table: &FrameTable, registry: &[TaskEntry]) -> bool {
    let mut i = 0;
    while i < table.tasks.len() {
        if !registry_has(registry, table.tasks[i].name) {
            return false;
        }
        i += 1;
    }
    let mut j = 0;
    while j < registry.len() {
        if !table_has(table, registry[j].name) {
            return false;
        }
        j += 1;
    }
    true
}

const fn registry_has(registry: &[TaskEntry], name: &str) -> bool {
    let mut j = 0;
    while j < registry.len() {
        if const_str_eq(registry[j].name, name) {
            return true;
        }
        j += 1;
    }
    false
}

const fn table_has(table: &FrameTable, name: &str) -> bool {
    let mut i = 0;
    while i < table.tasks.len() {
        if const_str_eq(table.tasks[i].name, name) {
            return true;
        }
        i += 1;
    }
    false
}

const fn const_str_eq(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut k = 0;
    while k < a.len() {
        if a[k] != b[k] {
            return false;
        }
        k += 1;
    }
    true
}

/// The build-time check: `schedule.toml` and the registry name the same tasks.
/// `skyframe check-schedule schedule.toml` says which name is missing where.
const _: () = assert!(
    schedule_matches(&SHIPPED, REGISTRY),
    "schedule.toml and the task registry (shell/src/tasks.rs) name different tasks: \
     run `skyframe check-schedule schedule.toml`"
);

/// The mismatch between a schedule and a registry, as one line; `None` when they agree.
pub fn schedule_mismatch(schedule: &[&str], registry: &[TaskEntry]) -> Option<String> {
    unknown_task(schedule, registry).or_else(|| unscheduled_task(schedule, registry))
}

/// A scheduled name with no registry entry: the schedule asks for a task skyframe lacks.
pub fn unknown_task(schedule: &[&str], registry: &[TaskEntry]) -> Option<String> {
    let names = task_names(registry);
    let unknown = schedule.iter().find(|n| !names.contains(n))?;
    Some(format!(
        "task `{unknown}` is in the schedule but skyframe has no such task (registered in \
         shell/src/tasks.rs: {})",
        names.join(", ")
    ))
}

/// A registered task the schedule does not run.
pub fn unscheduled_task(schedule: &[&str], registry: &[TaskEntry]) -> Option<String> {
    let unscheduled = registry.iter().find(|e| !schedule.contains(&e.name))?;
    Some(format!(
        "task `{}` is registered (shell/src/tasks.rs) but the schedule does not run it: add \
         it to the schedule, or remove its registry line",
        unscheduled.name
    ))
}

/// The data path between tasks: latest-value slots and the shared parameter table. Made by
/// the flight before any task, borrowed by every task it builds.
#[derive(Default)]
pub struct Shared {
    pub imu_samples: LatestSlot<ImuSample>,
    pub gps_fixes: LatestSlot<GpsFix>,
    pub servo_commands: LatestSlot<ComputerCommand>,
    pub pilot: LatestSlot<PilotInput>,
    pub estimate: LatestSlot<Estimate>,
    pub horizon: LatestSlot<HorizonAttitude>,
    pub watchdog: LatestSlot<WatchdogReport>,
    pub health_period_ms: Cell<u32>,
    /// The mode the ground asked for, and the mode control flies in.
    pub mode_request: LatestSlot<FlightMode>,
    pub active_mode: LatestSlot<FlightMode>,
    pub params: RefCell<ParamTable>,
    pub control: ControlSettings,
    /// The mission in force (`--mission` at start), and what the link uploads in flight.
    pub mission: RefCell<MissionStore>,
}

/// The link's parts for the telemetry task.
pub struct LinkParts<'w> {
    pub port: crate::link::RingDatagrams,
    pub key: LinkKey,
    pub config: TelemetryConfig,
    pub ingress: &'w IngressCounters,
    pub log_health: &'w LogHealthCell,
}

/// Everything a task's build may take: its log stream, its device, the shared data path.
pub struct Wiring<'w> {
    pub shared: &'w Shared,
    pub table: &'static FrameTable,
    /// This task's tap (what telemetry shows of its log), and every flying task's.
    pub tap: &'w Tap,
    pub taps: &'w [Option<&'w Tap>],
    pub log: Option<LogStream>,
    pub device: Option<(DevicePort, u64)>,
    /// The simulated GPS ends each epoch with POS: no epoch of delay.
    pub simulated: bool,
    pub link: Option<LinkParts<'w>>,
    pub stop: &'w AtomicBool,
}

impl<'w> Wiring<'w> {
    /// The task's log stream with its tap.
    pub fn tapped_log(&mut self) -> Result<TappedSink<'w, LogStream>, String> {
        let inner = self
            .log
            .take()
            .ok_or("the flight opened no log stream for this task")?;
        Ok(TappedSink {
            inner,
            tap: self.tap,
        })
    }

    /// The task's device port and its staleness timeout.
    pub fn device(&mut self) -> Result<(DevicePort, u64), String> {
        self.device
            .take()
            .ok_or_else(|| "the flight has no port for this task's device".to_string())
    }
}

/// What a task adds to the flight's report at the end.
#[derive(Default)]
pub struct TaskReports {
    pub devices: Vec<(&'static str, DecoderStats)>,
    pub watchdog: Option<WatchdogReport>,
    pub link: Option<LinkCounters>,
}

/// A task as a flight holds it: stepped by the executive, asked for its report at the end.
pub trait FlightTask: Task {
    fn report(&self, _reports: &mut TaskReports) {}
}

/// A built task in its executive slot: the executive steps a `dyn Task`, the flight asks the
/// same task for its report.
pub struct FlyingTask<'w>(pub Box<dyn FlightTask + 'w>);

impl Task for FlyingTask<'_> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        self.0.init(cx)
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        self.0.step(cx)
    }

    fn recover(&mut self, cx: &mut TaskContext<'_>) {
        self.0.recover(cx);
    }

    fn shutdown(&mut self, cx: &mut TaskContext<'_>) {
        self.0.shutdown(cx);
    }
}

type Log<'w> = TappedSink<'w, LogStream>;

impl FlightTask for ImuTask<'_, DevicePort, Log<'_>> {
    fn report(&self, reports: &mut TaskReports) {
        reports.devices.push(("imu", *self.stats()));
    }
}

impl FlightTask for GpsTask<'_, DevicePort, Log<'_>> {
    fn report(&self, reports: &mut TaskReports) {
        reports.devices.push(("gps", *self.stats()));
    }
}

impl FlightTask for ServoTask<'_, DevicePort, Log<'_>> {
    fn report(&self, reports: &mut TaskReports) {
        reports.devices.push(("servo", *self.stats()));
    }
}

impl FlightTask for WatchdogTask<'_, Log<'_>> {
    fn report(&self, reports: &mut TaskReports) {
        reports.watchdog = Some(*self.report());
    }
}

impl FlightTask for TelemetryTask<'_, crate::link::RingDatagrams, Log<'_>> {
    fn report(&self, reports: &mut TaskReports) {
        reports.link = Some(self.counters());
    }
}

impl FlightTask for EstimatorTask<'_, Log<'_>> {}
impl FlightTask for ControlTask<'_, Log<'_>> {}
impl FlightTask for HealthTask<Log<'_>> {}

fn build_imu<'w>(w: &mut Wiring<'w>) -> Result<Box<dyn FlightTask + 'w>, String> {
    let (port, stale_ns) = w.device()?;
    let log = w.tapped_log()?;
    Ok(Box::new(ImuTask::new(
        port,
        log,
        stale_ns,
        &w.shared.imu_samples,
    )))
}

fn build_gps<'w>(w: &mut Wiring<'w>) -> Result<Box<dyn FlightTask + 'w>, String> {
    let (port, stale_timeout_ns) = w.device()?;
    let config = GpsConfig {
        stale_timeout_ns,
        epoch_end: w.simulated.then_some(SentenceKind::AshtechPos),
    };
    let log = w.tapped_log()?;
    Ok(Box::new(GpsTask::new(
        port,
        log,
        config,
        &w.shared.gps_fixes,
    )))
}

fn build_servo<'w>(w: &mut Wiring<'w>) -> Result<Box<dyn FlightTask + 'w>, String> {
    let (port, stale_ns) = w.device()?;
    let log = w.tapped_log()?;
    let shared = w.shared;
    Ok(Box::new(ServoTask::new(
        port,
        log,
        stale_ns,
        &shared.servo_commands,
        &shared.pilot,
    )))
}

fn build_estimator<'w>(w: &mut Wiring<'w>) -> Result<Box<dyn FlightTask + 'w>, String> {
    let log = w.tapped_log()?;
    let shared = w.shared;
    Ok(Box::new(EstimatorTask::new(
        EstimatorConfig::default(),
        log,
        &shared.imu_samples,
        &shared.gps_fixes,
        Some(&shared.horizon),
        &shared.estimate,
    )))
}

fn build_control<'w>(w: &mut Wiring<'w>) -> Result<Box<dyn FlightTask + 'w>, String> {
    let log = w.tapped_log()?;
    let shared = w.shared;
    Ok(Box::new(
        ControlTask::new(
            shared.control,
            log,
            &shared.estimate,
            &shared.pilot,
            &shared.mode_request,
            None,
            &shared.params,
            &shared.servo_commands,
        )
        .flying_missions_from(&shared.mission)
        .publishing_mode(&shared.active_mode),
    ))
}

fn build_telemetry<'w>(w: &mut Wiring<'w>) -> Result<Box<dyn FlightTask + 'w>, String> {
    let log = w.tapped_log()?;
    let link = w.link.take().ok_or("the flight has no link")?;
    let shared = w.shared;
    Ok(Box::new(TelemetryTask::new(
        link.port,
        log,
        w.table,
        link.key,
        link.config,
        LinkShared {
            taps: w.taps,
            params: &shared.params,
            mode_request: &shared.mode_request,
            active_mode: &shared.active_mode,
            horizon: &shared.horizon,
            watchdog: &shared.watchdog,
            health_period_ms: &shared.health_period_ms,
            stop: w.stop,
            ingress: Some(link.ingress),
            log_health: Some(link.log_health),
            mission: Some(&shared.mission),
        },
    )))
}

fn build_health<'w>(w: &mut Wiring<'w>) -> Result<Box<dyn FlightTask + 'w>, String> {
    let log = w.tapped_log()?;
    Ok(Box::new(HealthTask::new(log, HEALTH_SNAPSHOT_NS)))
}

fn build_watchdog<'w>(w: &mut Wiring<'w>) -> Result<Box<dyn FlightTask + 'w>, String> {
    let log = w.tapped_log()?;
    let shared = w.shared;
    Ok(Box::new(
        WatchdogTask::new(&shared.watchdog)
            .logging_to(log)
            .with_period(&shared.health_period_ms),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_schedule_and_the_registry_name_the_same_tasks() {
        let shipped: Vec<&str> = SHIPPED.tasks.iter().map(|t| t.name).collect();
        assert_eq!(schedule_mismatch(&shipped, REGISTRY), None);
        assert!(schedule_matches(&SHIPPED, REGISTRY));
    }

    #[test]
    fn an_unwired_name_and_an_unscheduled_task_are_each_refused_by_name() {
        let mut names: Vec<&str> = SHIPPED.tasks.iter().map(|t| t.name).collect();
        names.push("baro");
        let e = schedule_mismatch(&names, REGISTRY).expect("refused");
        assert!(
            e.starts_with("task `baro` is in the schedule but skyframe has no such task"),
            "{e}"
        );
        names.retain(|n| *n != "baro" && *n != "gps");
        let e = schedule_mismatch(&names, REGISTRY).expect("refused");
        assert!(
            e.starts_with("task `gps` is registered (shell/src/tasks.rs) but the schedule"),
            "{e}"
        );
    }
}

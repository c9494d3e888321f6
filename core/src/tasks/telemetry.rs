//! The telemetry task: the vehicle's end of the link (`docs/link-protocol.md`).
//!
//! Each release it takes the commands the shell's socket thread received, lets the
//! [`CommandGate`] decide which are authentic, fresh and in range, acts on those (and
//! acknowledges), then sends what the [`TelemetrySchedule`] says is due: the executive's
//! status, one task's status in rotation, and each task's data at its own rate.
//!
//! Timing faults do not wait for the rotation: a task whose overrun or skip counts grew goes
//! out as a status (its counts by kind are the summary) at once, then at most once per
//! [`OVERRUN_REPORT_INTERVAL_NS`] while a burst lasts, so a burst of slips never floods the
//! link and the ground still sees it within a second.
//!
//! A task's data is its latest log record of each format: each task's log sink is wrapped
//! in a [`TappedSink`](super::tap::TappedSink), which passes every record on to the log and
//! keeps the latest data block (and the formats) for telemetry. So telemetry shows exactly
//! what is logged, with the same column names and time stamps, and no task has to know about
//! the link. Each task's column names are re-sent every
//! [`TASK_FORMAT_INTERVAL_MS`](crate::link::telemetry::TASK_FORMAT_INTERVAL_MS) with its
//! latest values, so a ground that joins late has them within that time.

use super::tap::Tap;
use super::task_log::TaskLog;
use crate::comm::{LatestSlot, LogHealthCell};
use crate::control::mission_store::MissionStore;
use crate::control::mode::FlightMode;
use crate::executive::{Task, TaskContext, TaskFault};
use crate::horizon::HorizonAttitude;
use crate::link::auth::{CommandGate, GateConfig, LinkKey};
use crate::link::counters::LinkCounters;
use crate::link::frame::{Envelope, MAX_DATAGRAM_LEN, encode_datagram};
use crate::link::ingress::IngressCounters;
use crate::link::messages::{
    AckResult, Command, CommandAck, ExecutiveStatus, Message, Name, TaskData, TaskFormat,
    TaskStatus, Telemetry, Value,
};
use crate::link::params::{ParamTable, SetParamResult};
use crate::link::telemetry::{Due, TelemetrySchedule, VehicleEnvelopes};
use crate::logfmt::RecordSink;
use crate::schedule::FrameTable;
use crate::schedule::analysis::MAX_TASKS;
use crate::tasks::watchdog::WatchdogReport;
use core::cell::{Cell, RefCell};
use core::sync::atomic::{AtomicBool, Ordering};

/// Where datagrams come from and go to: the shell's socket thread, through rings.
pub trait DatagramPort {
    /// The next received datagram into `buf`; its length, or `None` when none is waiting.
    fn receive(&mut self, buf: &mut [u8]) -> Option<usize>;
    /// Queues a datagram for every telemetry destination (and, with `reply`, for the sender
    /// of the last command received too). `false` when the queue is full.
    fn send(&mut self, datagram: &[u8], reply: bool) -> bool;
}

/// What the telemetry task shares with the rest of the vehicle.
pub struct LinkShared<'a> {
    /// One tap per task slot (`None`: the task logs nothing to show).
    pub taps: &'a [Option<&'a Tap>],
    pub params: &'a RefCell<ParamTable>,
    pub mode_request: &'a LatestSlot<FlightMode>,
    /// The mode the control task is flying in, as it last published it.
    pub active_mode: &'a LatestSlot<FlightMode>,
    pub horizon: &'a LatestSlot<HorizonAttitude>,
    pub watchdog: &'a LatestSlot<WatchdogReport>,
    pub health_period_ms: &'a Cell<u32>,
    /// Set by a `Stop` command: the shell ends the run cleanly between frames.
    pub stop: &'a AtomicBool,
    /// What the shell's socket thread dropped before queueing (`None` in tests without one).
    pub ingress: Option<&'a IngressCounters>,
    /// The flight log's free space and losses, as the shell's log writer measures them.
    pub log_health: Option<&'a LogHealthCell>,
    /// The mission slot the control task flies from (`None`: mission commands are refused).
    pub mission: Option<&'a RefCell<MissionStore>>,
}

pub struct TelemetryConfig {
    pub vehicle_id: u16,
    pub run_id: u32,
    /// Sign telemetry too (commands are always verified).
    pub sign_telemetry: bool,
    /// Programmed duration of the run, for the executive status (0: until stopped).
    pub duration_ns: u64,
}

const LINK_INDEX: u8 = 1;
const LINK_LOG_INTERVAL_NS: u64 = 1_000_000_000;

/// Datagrams handled per release at most: a flood cannot eat the frame.
const MAX_COMMANDS_PER_STEP: usize = 8;
const MAX_SENDS_PER_STEP: usize = 16;
/// The shortest time between two overrun-prompted statuses of one task.
pub const OVERRUN_REPORT_INTERVAL_NS: u64 = 1_000_000_000;

/// What the ground was last told of one task's timing faults.
#[derive(Clone, Copy, Default)]
struct OverrunReport {
    faults: u64,
    sent_ns: Option<u64>,
}

pub struct TelemetryTask<'a, P, S: RecordSink> {
    port: P,
    log: TaskLog<S>,
    /// The log is declared once, by the first init (a reset does not restart it).
    declared: bool,
    logged_ns: Option<u64>,
    table: &'static FrameTable,
    shared: LinkShared<'a>,
    key: LinkKey,
    config: TelemetryConfig,
    gate: CommandGate,
    schedule: Option<TelemetrySchedule>,
    envelopes: VehicleEnvelopes,
    mode: Option<FlightMode>,
    announced: bool,
    overrun_reports: [OverrunReport; MAX_TASKS],
    buf: [u8; MAX_DATAGRAM_LEN],
}

impl<'a, P: DatagramPort, S: RecordSink> TelemetryTask<'a, P, S> {
    /// `log` takes `link.bin` ([`LinkCounters`]).
    pub fn new(
        port: P,
        log: S,
        table: &'static FrameTable,
        key: LinkKey,
        config: TelemetryConfig,
        shared: LinkShared<'a>,
    ) -> Self {
        let gate = CommandGate::new(
            key.clone(),
            GateConfig {
                vehicle_id: config.vehicle_id,
                run_id: config.run_id,
                task_count: table.tasks.len(),
            },
        );
        Self {
            port,
            log: TaskLog::new(log),
            declared: false,
            logged_ns: None,
            table,
            shared,
            envelopes: VehicleEnvelopes::new(config.vehicle_id, config.run_id),
            key,
            config,
            gate,
            schedule: None,
            mode: None,
            announced: false,
            overrun_reports: [OverrunReport::default(); MAX_TASKS],
            buf: [0; MAX_DATAGRAM_LEN],
        }
    }

    /// Every datagram the vehicle received and what became of it: the gate's counters with
    /// the socket thread's drops added.
    pub fn counters(&self) -> LinkCounters {
        match self.shared.ingress {
            Some(ingress) => ingress.added_to(self.gate.counters()),
            None => *self.gate.counters(),
        }
    }

    fn send(&mut self, now_ns: u64, telemetry: Telemetry, reply: bool) {
        let envelope: Envelope = self.envelopes.next(now_ns);
        let key = self.config.sign_telemetry.then_some(&self.key);
        let sent = encode_datagram(
            &envelope,
            &Message::Telemetry(telemetry),
            key,
            &mut self.buf,
        )
        .ok()
        .is_some_and(|n| self.port.send(self.buf.get(..n).unwrap_or_default(), reply));
        let c = self.gate.counters_mut();
        if sent {
            c.telemetry_sent = c.telemetry_sent.saturating_add(1);
        } else {
            c.telemetry_send_failed = c.telemetry_send_failed.saturating_add(1);
        }
    }

    fn param_report(&self, index: usize) -> Option<crate::link::messages::ParamValue> {
        self.shared.params.try_borrow().ok()?.report(index)
    }

    fn act(
        &mut self,
        cx: &TaskContext<'_>,
        command: &Command,
        ack: impl Fn(AckResult, Option<Value>) -> CommandAck,
    ) {
        let now = cx.now_ns;
        let (result, in_force) = match *command {
            Command::SetTelemetryRate {
                task_index,
                interval_ms,
            } => {
                let ok = self
                    .schedule
                    .as_mut()
                    .is_some_and(|s| s.set_interval(usize::from(task_index), interval_ms, now));
                (
                    if ok {
                        AckResult::Accepted
                    } else {
                        AckResult::Refused
                    },
                    Some(Value::U32(interval_ms)),
                )
            }
            Command::SetHealthPeriod { period_ms } => {
                self.shared.health_period_ms.set(period_ms);
                (AckResult::Accepted, Some(Value::U32(period_ms)))
            }
            Command::SetParam { name, value } => {
                let outcome = self
                    .shared
                    .params
                    .try_borrow_mut()
                    .map(|mut p| p.set(&name, value))
                    .unwrap_or(SetParamResult::Unknown);
                match outcome {
                    SetParamResult::Accepted { in_force } => (AckResult::Accepted, Some(in_force)),
                    SetParamResult::OutOfRange { in_force } => {
                        (AckResult::OutOfRange, Some(in_force))
                    }
                    SetParamResult::WrongType { in_force } => {
                        (AckResult::WrongType, Some(in_force))
                    }
                    SetParamResult::Unknown => (AckResult::UnknownParam, None),
                }
            }
            Command::GetParam { name } => {
                let index = self
                    .shared
                    .params
                    .try_borrow()
                    .ok()
                    .and_then(|p| p.iter().position(|q| *q.name() == name));
                if let Some(report) = index.and_then(|i| self.param_report(i)) {
                    self.send(now, Telemetry::ParamValue(report), true);
                    (AckResult::Accepted, Some(report.value))
                } else {
                    (AckResult::UnknownParam, None)
                }
            }
            Command::ListParams => {
                let count = self.shared.params.try_borrow().map_or(0, |p| p.len());
                for i in 0..count {
                    if let Some(report) = self.param_report(i) {
                        self.send(now, Telemetry::ParamValue(report), true);
                    }
                }
                (AckResult::Accepted, None)
            }
            Command::RequestMode { mode } => {
                self.shared.mode_request.publish(mode);
                self.mode = Some(mode);
                (AckResult::Accepted, None)
            }
            Command::HorizonAttitude(attitude) => {
                self.shared.horizon.publish(attitude);
                (AckResult::Accepted, None)
            }
            Command::Stop => {
                self.shared.stop.store(true, Ordering::Relaxed);
                (AckResult::Accepted, None)
            }
            Command::MissionClear
            | Command::MissionItem { .. }
            | Command::MissionCommit { .. }
            | Command::MissionSetCurrent { .. } => (self.mission_command(command), None),
        };
        self.send(now, Telemetry::CommandAck(ack(result, in_force)), true);
    }

    /// Applies a mission command to the store: `Refused` when it is out of sequence,
    /// names no waypoint, or there is no store (or it is busy).
    fn mission_command(&self, command: &Command) -> AckResult {
        let Some(mut store) = self.shared.mission.and_then(|m| m.try_borrow_mut().ok()) else {
            return AckResult::Refused;
        };
        let done = match *command {
            Command::MissionClear => {
                store.clear();
                Ok(())
            }
            Command::MissionItem {
                index,
                count,
                waypoint,
            } => store.stage(usize::from(index), usize::from(count), waypoint),
            Command::MissionCommit {
                count,
                switch_radius_m,
                loiter_radius_m,
                loiter_clockwise,
            } => store.commit(
                usize::from(count),
                switch_radius_m,
                loiter_radius_m,
                loiter_clockwise,
            ),
            Command::MissionSetCurrent { index } => store.set_current(usize::from(index)),
            _ => return AckResult::Refused,
        };
        if done.is_ok() {
            AckResult::Accepted
        } else {
            AckResult::Refused
        }
    }

    fn receive_commands(&mut self, cx: &TaskContext<'_>) {
        let mut datagram = [0u8; MAX_DATAGRAM_LEN];
        for _ in 0..MAX_COMMANDS_PER_STEP {
            let Some(n) = self.port.receive(&mut datagram) else {
                break;
            };
            let bytes = datagram.get(..n).unwrap_or_default();
            let verdict = match self.shared.params.try_borrow() {
                Ok(params) => self.gate.accept(bytes, cx.now_ns, &params),
                Err(_) => continue,
            };
            match verdict {
                Ok(accepted) => {
                    let command = accepted.command;
                    self.act(cx, &command, |result, value| accepted.ack(result, value));
                }
                // Authentic but refused (out of range…): say why. Anything else: silence.
                Err(rejected) => {
                    if let Some(ack) = rejected.ack {
                        self.send(cx.now_ns, Telemetry::CommandAck(ack), true);
                    }
                }
            }
        }
    }

    fn task_status(&self, cx: &TaskContext<'_>, index: u8) -> Option<TaskStatus> {
        let i = usize::from(index);
        let health = cx.health.task(i)?;
        let slot = self.table.tasks.get(i)?;
        let mut status = TaskStatus::from_health(index, health, cx.health.alive(i));
        status.name = Name::new(slot.name).unwrap_or_default();
        status.watchdog_misses = self
            .shared
            .watchdog
            .peek()
            .and_then(|w| w.misses.get(i).copied())
            .unwrap_or(0);
        status.log_records_dropped = cx.health.log_dropped(i);
        status.telemetry_interval_ms = self
            .schedule
            .as_ref()
            .and_then(|s| s.interval_ms(i))
            .unwrap_or(0);
        status.budget_ns = slot.budget_ns;
        status.period_ns = slot.period_ns;
        Some(status)
    }

    /// A status for each task whose timing faults grew since the ground last heard, throttled
    /// per task.
    fn report_overruns(&mut self, cx: &TaskContext<'_>) {
        let now = cx.now_ns;
        for index in 0..self.table.tasks.len().min(MAX_TASKS) {
            let Some(health) = cx.health.task(index) else {
                break;
            };
            let faults = u64::from(health.overruns.budget)
                + u64::from(health.overruns.frame)
                + u64::from(health.overruns.missed)
                + u64::from(health.skipped);
            let Some(report) = self.overrun_reports.get(index).copied() else {
                break;
            };
            let quiet = report
                .sent_ns
                .is_none_or(|t| now.saturating_sub(t) >= OVERRUN_REPORT_INTERVAL_NS);
            if faults == report.faults || !quiet {
                continue;
            }
            if let Some(status) = self.task_status(cx, index as u8) {
                self.send(now, Telemetry::TaskStatus(status), false);
            }
            if let Some(r) = self.overrun_reports.get_mut(index) {
                *r = OverrunReport {
                    faults,
                    sent_ns: Some(now),
                };
            }
        }
    }

    fn log_counters(&mut self, cx: &TaskContext<'_>) {
        self.logged_ns = Some(cx.now_ns);
        let counters = self.counters();
        self.log.log(cx, LINK_INDEX, &counters);
    }

    fn tap(&self, task_index: u8) -> Option<&'a Tap> {
        self.shared
            .taps
            .get(usize::from(task_index))
            .copied()
            .flatten()
    }

    /// Every format's column names of one task, each followed by its latest values (fresh or
    /// not: a ground that joined late gets the whole picture, the gains logged once at start
    /// included).
    fn send_formats(&mut self, now: u64, task_index: u8) {
        let Some(tap) = self.tap(task_index) else {
            return;
        };
        for format_index in tap.format_indices() {
            if let Some(columns) = tap.columns(format_index).filter(|c| !c.is_empty()) {
                let format = TaskFormat {
                    task_index,
                    format_index,
                    columns,
                };
                self.send(now, Telemetry::TaskFormat(format), false);
            }
        }
        self.send_data(now, task_index, false);
    }

    /// The latest record of each of the task's formats (`only_fresh`: those logged since the
    /// last send).
    fn send_data(&mut self, now: u64, task_index: u8, only_fresh: bool) {
        let Some(tap) = self.tap(task_index) else {
            return;
        };
        for format_index in tap.format_indices() {
            if let Some(record) = tap.take_latest(format_index, only_fresh) {
                let data = TaskData {
                    task_index,
                    format_index: record.format_index,
                    time: record.time,
                    values: record.values,
                };
                self.send(now, Telemetry::TaskData(data), false);
            }
        }
    }

    /// The executive's status: the mode the control task flies in (not merely the last one
    /// requested), and the watchdog's check period in force (its own frame period while the
    /// ground has set none).
    fn executive_status(&self, cx: &TaskContext<'_>) -> ExecutiveStatus {
        let requested = self.shared.health_period_ms.get();
        let health_period_ms = if requested > 0 {
            requested
        } else {
            self.table
                .tasks
                .iter()
                .find(|t| t.name == "watchdog")
                .map_or(0, |t| {
                    u32::try_from(t.period_ns / 1_000_000).unwrap_or(u32::MAX)
                })
        };
        ExecutiveStatus {
            elapsed_ns: cx.now_ns,
            duration_ns: self.config.duration_ns,
            mode: self.shared.active_mode.peek().or(self.mode),
            task_count: self.table.tasks.len() as u8,
            health_period_ms,
            frames: cx.health.frames,
            link: self.counters(),
            log: self
                .shared
                .log_health
                .map(LogHealthCell::get)
                .unwrap_or_default(),
        }
    }

    fn send_due(&mut self, cx: &TaskContext<'_>) {
        let now = cx.now_ns;
        for _ in 0..MAX_SENDS_PER_STEP {
            let Some(due) = self.schedule.as_mut().and_then(|s| s.next_due(now)) else {
                break;
            };
            let message = match due {
                Due::ExecutiveStatus => Some(Telemetry::ExecutiveStatus(self.executive_status(cx))),
                Due::TaskStatus { task_index } => {
                    self.task_status(cx, task_index).map(Telemetry::TaskStatus)
                }
                Due::TaskFormat { task_index } => {
                    // The task's status (its name) leads its column names, so a ground that
                    // joins late can label what follows: both within one format interval.
                    if let Some(status) = self.task_status(cx, task_index) {
                        self.send(now, Telemetry::TaskStatus(status), false);
                    }
                    self.send_formats(now, task_index);
                    None
                }
                Due::TaskData { task_index } => {
                    self.send_data(now, task_index, true);
                    None
                }
            };
            if let Some(message) = message {
                self.send(now, message, false);
            }
        }
        // Parameters changed since the last release go out as values, once each.
        loop {
            let changed = self
                .shared
                .params
                .try_borrow_mut()
                .ok()
                .and_then(|mut p| p.take_changed());
            let Some(index) = changed else { break };
            if let Some(report) = self.param_report(index) {
                self.send(now, Telemetry::ParamValue(report), false);
            }
        }
    }
}

impl<P: DatagramPort, S: RecordSink> Task for TelemetryTask<'_, P, S> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        if !self.declared {
            self.log
                .declare::<LinkCounters>(cx, LINK_INDEX)
                .map_err(|_| TaskFault::new("link log format"))?;
            self.declared = true;
            self.log.begin(cx);
        }
        if self.schedule.is_none() {
            self.schedule = Some(TelemetrySchedule::new(self.table.tasks.len(), cx.now_ns));
        }
        Ok(())
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        if !self.announced {
            // Every task's status at once when the run starts: a ground station already
            // listening sees the whole vehicle within a second, not after a full rotation.
            self.announced = true;
            for index in 0..self.table.tasks.len() {
                if let Some(status) = self.task_status(cx, index as u8) {
                    self.send(cx.now_ns, Telemetry::TaskStatus(status), false);
                }
            }
        }
        self.receive_commands(cx);
        self.report_overruns(cx);
        self.send_due(cx);
        if self
            .logged_ns
            .is_none_or(|t| cx.now_ns.saturating_sub(t) >= LINK_LOG_INTERVAL_NS)
        {
            self.log_counters(cx);
        }
        Ok(())
    }

    fn shutdown(&mut self, cx: &mut TaskContext<'_>) {
        // Last word: the executive's final status, so the ground sees the run end.
        let status = self.executive_status(cx);
        self.send(cx.now_ns, Telemetry::ExecutiveStatus(status), false);
        self.log_counters(cx);
        self.log.end(cx);
    }
}

//! A stand-in vehicle on a real UDP socket, for the tests and the load bench: it sends
//! telemetry as the protocol's schedule (`TelemetrySchedule`) says, with the columns of
//! `docs/log-streams.md` and made-up values, and answers commands through the core's
//! `CommandGate` and `ParamTable` exactly as the vehicle must. One socket both sends
//! telemetry and receives commands, as the real vehicle's does.

use nalgebra::Vector3;
use skyframe_core::control::mode::FlightMode;
use skyframe_core::estimation::geo::{GeoPoint, LocalFrame};
use skyframe_core::link::auth::{CommandGate, GateConfig, LinkKey};
use skyframe_core::link::frame::{MAX_DATAGRAM_LEN, encode_datagram};
use skyframe_core::link::messages::{
    AckResult, Command, CommandAck, ExecutiveStatus, Message, Name, TaskData, TaskFormat,
    TaskStatus, Telemetry, Value,
};
use skyframe_core::link::params::ParamTable;
use skyframe_core::link::telemetry::{Due, TelemetrySchedule, VehicleEnvelopes};
use skyframe_core::logfmt::{LogRecord, Time};
use skyframe_core::tasks::{control, estimator, gps, imu, servo};
use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Task names in the frame-table order of the repository's `schedule.toml`, and each
/// task's formats (index, columns) as the vehicle's tasks declare them in the core; the last
/// three send no data here.
pub const TASKS: [(&str, &[(u8, &str)]); 8] = [
    ("imu", &[(imu::FAST_INDEX, imu::ImuFastLog::FORMAT.columns)]),
    (
        "estimator",
        &[(
            estimator::STATE_INDEX,
            estimator::EstimatorStateLog::FORMAT.columns,
        )],
    ),
    (
        "control",
        &[(control::CONTROL_INDEX, control::ControlLog::FORMAT.columns)],
    ),
    (
        "servo",
        &[
            (servo::PILOT_INDEX, servo::ServoPilotLog::FORMAT.columns),
            (servo::COMMAND_INDEX, servo::ServoCommandLog::FORMAT.columns),
        ],
    ),
    ("gps", &[(gps::FIX_INDEX, gps::GpsFixLog::FORMAT.columns)]),
    ("health", &[]),
    ("telemetry", &[]),
    ("watchdog", &[]),
];

#[derive(Clone, Debug)]
pub struct FakeVehicleConfig {
    pub vehicle_id: u16,
    pub run_id: u32,
    /// Commands are checked against this key; telemetry is signed with it if asked.
    pub key: LinkKey,
    pub sign_telemetry: bool,
    /// Where telemetry goes (the ground).
    pub telemetry_to: SocketAddr,
    /// Every task's data interval at start (the protocol's default is 1000).
    pub data_interval_ms: u32,
    /// The programmed duration reported in ExecutiveStatus (0: until stopped).
    pub duration: Duration,
}

/// What a fake vehicle did, when it ends.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FakeVehicleReport {
    pub sent: u64,
    pub send_failed: u64,
    pub commands_accepted: u64,
    pub commands_rejected: u64,
    pub stopped_by_command: bool,
}

pub struct FakeVehicle {
    socket: UdpSocket,
    config: FakeVehicleConfig,
    gate: CommandGate,
    params: ParamTable,
    schedule: TelemetrySchedule,
    envelopes: VehicleEnvelopes,
    start: Instant,
    mode: Option<FlightMode>,
    health_period_ms: u32,
    releases: u64,
    report: FakeVehicleReport,
    buffer: Vec<u8>,
}

fn task_count() -> u8 {
    TASKS.len() as u8
}

impl FakeVehicle {
    /// Binds `127.0.0.1:0` (any free port).
    pub fn bind(config: FakeVehicleConfig) -> io::Result<Self> {
        let socket = UdpSocket::bind(("127.0.0.1", 0))?;
        socket.set_read_timeout(Some(Duration::from_millis(2)))?;
        let gate = CommandGate::new(
            config.key.clone(),
            GateConfig {
                vehicle_id: config.vehicle_id,
                run_id: config.run_id,
                task_count: TASKS.len(),
            },
        );
        let mut schedule = TelemetrySchedule::new(TASKS.len(), 0);
        for task in 0..TASKS.len() {
            schedule.set_interval(task, config.data_interval_ms, 0);
        }
        Ok(Self {
            socket,
            gate,
            params: default_params(),
            schedule,
            envelopes: VehicleEnvelopes::new(config.vehicle_id, config.run_id),
            start: Instant::now(),
            mode: Some(FlightMode::Manual),
            health_period_ms: 1000,
            releases: 0,
            report: FakeVehicleReport::default(),
            buffer: vec![0; MAX_DATAGRAM_LEN + 1],
            config,
        })
    }

    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    pub fn params(&self) -> &ParamTable {
        &self.params
    }

    fn now_ns(&self) -> u64 {
        u64::try_from(self.start.elapsed().as_nanos()).unwrap_or(u64::MAX)
    }

    /// Sends what is due and handles the commands waiting (up to a short read timeout).
    /// `false` once a Stop has been accepted.
    pub fn step(&mut self) -> bool {
        let now_ns = self.now_ns();
        self.releases = now_ns / 10_000_000;
        while let Some(due) = self.schedule.next_due(now_ns) {
            self.send_due(due, now_ns);
        }
        while let Ok((len, from)) = self.socket.recv_from(&mut self.buffer) {
            let datagram = self.buffer.get(..len).unwrap_or(&[]).to_vec();
            self.handle_command(&datagram, from);
            if self.report.stopped_by_command {
                return false;
            }
        }
        true
    }

    /// Runs on a thread until stopped by command, by `stop`, or after `for_at_most`.
    pub fn spawn(
        mut self,
        stop: Arc<AtomicBool>,
        for_at_most: Duration,
    ) -> JoinHandle<FakeVehicleReport> {
        std::thread::spawn(move || {
            let end = Instant::now() + for_at_most;
            while !stop.load(Ordering::Relaxed) && Instant::now() < end && self.step() {}
            self.report.clone()
        })
    }

    fn send(&mut self, telemetry: Telemetry, now_ns: u64, to: SocketAddr) {
        let envelope = self.envelopes.next(now_ns);
        let key = self.config.sign_telemetry.then_some(&self.config.key);
        let mut out = [0u8; MAX_DATAGRAM_LEN];
        let sent = encode_datagram(&envelope, &Message::Telemetry(telemetry), key, &mut out)
            .ok()
            .and_then(|len| out.get(..len))
            .map(|bytes| self.socket.send_to(bytes, to).is_ok())
            .unwrap_or(false);
        let counters = self.gate.counters_mut();
        if sent {
            self.report.sent += 1;
            counters.telemetry_sent = counters.telemetry_sent.saturating_add(1);
        } else {
            self.report.send_failed += 1;
            counters.telemetry_send_failed = counters.telemetry_send_failed.saturating_add(1);
        }
    }

    fn send_due(&mut self, due: Due, now_ns: u64) {
        let to = self.config.telemetry_to;
        match due {
            Due::ExecutiveStatus => {
                let status = ExecutiveStatus {
                    elapsed_ns: now_ns,
                    duration_ns: u64::try_from(self.config.duration.as_nanos()).unwrap_or(0),
                    mode: self.mode,
                    task_count: task_count(),
                    health_period_ms: self.health_period_ms,
                    frames: skyframe_core::executive::FrameStats {
                        frames: now_ns / 10_000_000,
                        late: 2,
                        max_start_latency_ns: 85_000,
                        max_frame_work_ns: 2_400_000,
                        ..Default::default()
                    },
                    link: *self.gate.counters(),
                    log: skyframe_core::link::messages::LogHealth {
                        free_mib: 51_200,
                        ..Default::default()
                    },
                };
                self.send(Telemetry::ExecutiveStatus(status), now_ns, to);
            }
            Due::TaskStatus { task_index } => {
                let status = self.task_status(task_index);
                self.send(Telemetry::TaskStatus(status), now_ns, to);
            }
            Due::TaskFormat { task_index } => {
                // As the vehicle: the task's status (its name) leads its column names.
                let status = self.task_status(task_index);
                self.send(Telemetry::TaskStatus(status), now_ns, to);
                let formats = TASKS.get(usize::from(task_index)).map_or(&[][..], |t| t.1);
                for &(format_index, columns) in formats {
                    let Ok(columns) = heapless::Vec::from_slice(columns.as_bytes()) else {
                        continue;
                    };
                    let format = TaskFormat {
                        task_index,
                        format_index,
                        columns,
                    };
                    self.send(Telemetry::TaskFormat(format), now_ns, to);
                }
            }
            Due::TaskData { task_index } => {
                let formats = TASKS.get(usize::from(task_index)).map_or(&[][..], |t| t.1);
                for &(format_index, _) in formats {
                    let values = sample_values(task_index, format_index, now_ns);
                    let data = TaskData {
                        task_index,
                        format_index,
                        time: Time::from_ns(now_ns).unwrap_or_default(),
                        values,
                    };
                    self.send(Telemetry::TaskData(data), now_ns, to);
                }
            }
        }
    }

    fn task_status(&self, task_index: u8) -> TaskStatus {
        let interval_ms = self
            .schedule
            .interval_ms(usize::from(task_index))
            .unwrap_or(0);
        sample_task_status(task_index, interval_ms, self.releases)
    }

    fn handle_command(&mut self, datagram: &[u8], from: SocketAddr) {
        let now_ns = self.now_ns();
        let accepted = match self.gate.accept(datagram, now_ns, &self.params) {
            Ok(accepted) => accepted,
            Err(rejected) => {
                self.report.commands_rejected += 1;
                if let Some(ack) = rejected.ack {
                    self.send(Telemetry::CommandAck(ack), now_ns, from);
                }
                return;
            }
        };
        self.report.commands_accepted += 1;
        let ack = |result, value| accepted.ack(result, value);
        let answer: CommandAck = match accepted.command {
            Command::SetParam { name, value } => {
                let in_force = self.params.set(&name, value).in_force();
                ack(AckResult::Accepted, in_force)
            }
            Command::GetParam { name } => {
                if let Some(report) = self
                    .params
                    .index_of(&name)
                    .and_then(|i| self.params.report(i))
                {
                    self.send(Telemetry::ParamValue(report), now_ns, from);
                }
                let value = self.params.get(name.as_str()).map(|p| p.value());
                ack(AckResult::Accepted, value)
            }
            Command::ListParams => {
                for index in 0..self.params.len() {
                    if let Some(report) = self.params.report(index) {
                        self.send(Telemetry::ParamValue(report), now_ns, from);
                    }
                }
                ack(AckResult::Accepted, None)
            }
            Command::SetTelemetryRate {
                task_index,
                interval_ms,
            } => {
                self.schedule
                    .set_interval(usize::from(task_index), interval_ms, now_ns);
                ack(AckResult::Accepted, None)
            }
            Command::SetHealthPeriod { period_ms } => {
                self.health_period_ms = period_ms;
                ack(AckResult::Accepted, None)
            }
            Command::RequestMode { mode } => {
                // Like a vehicle whose GPS has no fix yet: auto is refused.
                if mode == FlightMode::Auto
                    && self
                        .params
                        .get("nav.auto_allowed")
                        .is_some_and(|p| p.value() == Value::Bool(false))
                {
                    ack(AckResult::Refused, None)
                } else {
                    self.mode = Some(mode);
                    ack(AckResult::Accepted, None)
                }
            }
            Command::HorizonAttitude(_) => ack(AckResult::Accepted, None),
            // No mission slot in the fake vehicle.
            Command::MissionClear
            | Command::MissionItem { .. }
            | Command::MissionCommit { .. }
            | Command::MissionSetCurrent { .. } => ack(AckResult::Refused, None),
            Command::Stop => {
                self.report.stopped_by_command = true;
                ack(AckResult::Accepted, None)
            }
        };
        self.send(Telemetry::CommandAck(answer), now_ns, from);
        while let Some(index) = self.params.take_changed() {
            if let Some(report) = self.params.report(index) {
                self.send(
                    Telemetry::ParamValue(report),
                    now_ns,
                    self.config.telemetry_to,
                );
            }
        }
    }
}

fn default_params() -> ParamTable {
    let mut table = ParamTable::new();
    let definitions = [
        (
            "control.roll_gain",
            Value::F32(1.0),
            Value::F32(0.0),
            Value::F32(5.0),
        ),
        (
            "control.pitch_gain",
            Value::F32(0.8),
            Value::F32(0.0),
            Value::F32(5.0),
        ),
        (
            "gps.min_satellites",
            Value::U32(6),
            Value::U32(4),
            Value::U32(12),
        ),
        (
            "servo.trim_us",
            Value::I32(0),
            Value::I32(-200),
            Value::I32(200),
        ),
        (
            "nav.auto_allowed",
            Value::Bool(true),
            Value::Bool(false),
            Value::Bool(true),
        ),
    ];
    for (name, value, min, max) in definitions {
        // The table is fixed above; a failure would only drop that parameter.
        let _ = table.define(name, value, min, max);
    }
    table
}

/// Made-up but plausible values for a task's format at `t_ns`, column by column: a gentle
/// circle at 12 m/s, banked 15°, over Zürich. A column not named here is 0.
pub fn sample_values(task_index: u8, format_index: u8, t_ns: u64) -> heapless::Vec<Value, 32> {
    let columns = TASKS
        .get(usize::from(task_index))
        .and_then(|(_, formats)| formats.iter().find(|(i, _)| *i == format_index))
        .map_or("", |(_, columns)| *columns);
    columns
        .split(',')
        .filter(|c| !c.is_empty())
        .map(|column| sample_value(column, t_ns))
        .take(32)
        .collect()
}

fn sample_value(column: &str, t_ns: u64) -> Value {
    let t = t_ns as f64 * 1e-9;
    let phase = t * 0.1;
    let (s, c) = phase.sin_cos();
    let radius_m = 120.0;
    let f = |x: f64| Value::F32(x as f32);
    match column {
        "counter" => Value::U32((t * 100.0) as u32 % 256),
        "p_rad_s" => f(0.01 * s),
        "q_rad_s" => f(0.02 * c),
        "r_rad_s" => f(0.1),
        "fx_m_s2" => f(0.3 * s),
        "fy_m_s2" => f(0.2),
        "fz_m_s2" => f(-9.80665),
        "valid" | "quality" | "healthy" | "ready" => Value::U32(1),
        "satellites" => Value::U32(9),
        "lat_deg" | "lon_deg" => {
            let home = GeoPoint {
                latitude_deg: 47.3977,
                longitude_deg: 8.5456,
                altitude_m: 0.0,
            };
            let on_circle = LocalFrame::new(home)
                .map(|frame| frame.to_geodetic(&Vector3::new(radius_m * s, radius_m * c, 0.0)))
                .unwrap_or(home);
            Value::F64(if column == "lat_deg" {
                on_circle.latitude_deg
            } else {
                on_circle.longitude_deg
            })
        }
        "alt_m" => f(488.0 + 2.0 * s),
        "vn_m_s" => f(12.0 * c),
        "ve_m_s" => f(-12.0 * s),
        "pdop" => f(1.8),
        "hdop" => f(0.9),
        "vdop" => f(1.5),
        "sd_n_m" => f(1.2),
        "sd_e_m" => f(1.1),
        "sd_d_m" => f(2.5),
        "utc_ms" => Value::U32((t * 1000.0) as u32),
        "roll_rad" => f(0.26 + 0.05 * (t * 0.5).sin()),
        "pitch_rad" => f(0.05 * (t * 0.3).cos()),
        "yaw_rad" | "course_rad" => f(phase % std::f64::consts::TAU),
        "pn_m" => f(radius_m * s),
        "pe_m" => f(radius_m * c),
        "pd_m" => f(-88.0 - 2.0 * s),
        "qw" => f(1.0),
        "mode" => Value::U32(1),
        "roll_c_rad" => f(0.26),
        "pitch_c_rad" => f(0.0),
        "alt_c_m" => f(490.0),
        "speed_m_s" | "speed_c_m_s" => f(12.0),
        "ch1_us" | "ch4_us" => Value::U32(1500),
        "ch2_us" => Value::U32(1450),
        "ch3_us" => Value::U32(1600),
        "ch5_us" | "ch6_us" | "ch7_us" | "ch8_us" => Value::U32(1000),
        "auto" => Value::U32(0),
        "aileron" => f(0.3 * s),
        "elevator" => f(-0.1),
        "throttle" => f(0.6),
        "batt_avionics_v" => f(11.8 - 0.001 * t),
        "batt_servo_v" => f(5.1),
        "aileron_cmd" => f(0.25 * s),
        "elevator_cmd" => f(-0.05),
        "throttle_cmd" => f(0.55),
        "rudder_cmd" => f(0.02),
        _ => f(0.0),
    }
}

/// A healthy task's status, with a few counters set so that a screen shows them: the
/// estimator has 3 budget overruns, gps dropped a log record, telemetry is out of frame.
pub fn sample_task_status(task_index: u8, telemetry_interval_ms: u32, releases: u64) -> TaskStatus {
    let name = TASKS
        .get(usize::from(task_index))
        .and_then(|t| Name::new(t.0))
        .unwrap_or_default();
    let budget_ns = 1_000_000 + u64::from(task_index) * 250_000;
    TaskStatus {
        task_index,
        name,
        initialised: true,
        running: true,
        in_frame: task_index != 6,
        alive: true,
        releases,
        overruns_budget: u32::from(task_index == 1) * 3,
        log_records_dropped: u32::from(task_index == 4),
        telemetry_interval_ms,
        exec_mean_ns: budget_ns / 4,
        exec_max_ns: budget_ns * 3 / 4,
        budget_ns,
        period_ns: if task_index == 4 {
            100_000_000
        } else {
            10_000_000
        },
        ..TaskStatus::default()
    }
}

//! The link's typed messages and their payload encodings (`docs/link-protocol.md` has the
//! byte tables).
//!
//! Two directions, two enums: [`Telemetry`] goes vehicle → ground, [`Command`] ground →
//! vehicle. The message type byte says which (`0x01..=0x7F` telemetry, `0x81..=0xFF`
//! commands), so a vehicle can refuse anything that is not a command before decoding it.

use super::counters::LinkCounters;
use super::wire::{Reader, WireError, Writer};
use crate::control::mission::{MAX_WAYPOINTS, Waypoint};
use crate::control::mission_store::{radii_in_range, waypoint_in_range};
use crate::control::mode::FlightMode;
use crate::executive::FrameStats;
use crate::horizon::HorizonAttitude;
use crate::logfmt::record::{TIME_LEN, Time};
use heapless::Vec;

/// Longest name of a parameter or a task on the wire.
pub const MAX_NAME_LEN: usize = 32;
/// Most values one [`TaskData`] message carries.
pub const MAX_TASK_VALUES: usize = 32;
/// Longest column list of a [`TaskFormat`] message.
pub const MAX_COLUMNS_LEN: usize = 255;

/// Message type bytes.
pub mod message_type {
    pub const TASK_DATA: u8 = 0x01;
    pub const TASK_FORMAT: u8 = 0x02;
    pub const TASK_STATUS: u8 = 0x03;
    pub const EXECUTIVE_STATUS: u8 = 0x04;
    pub const PARAM_VALUE: u8 = 0x05;
    pub const COMMAND_ACK: u8 = 0x06;

    pub const SET_TELEMETRY_RATE: u8 = 0x81;
    pub const SET_HEALTH_PERIOD: u8 = 0x82;
    pub const SET_PARAM: u8 = 0x83;
    pub const GET_PARAM: u8 = 0x84;
    pub const LIST_PARAMS: u8 = 0x85;
    pub const REQUEST_MODE: u8 = 0x86;
    pub const HORIZON_ATTITUDE: u8 = 0x87;
    pub const STOP: u8 = 0x88;
    pub const MISSION_CLEAR: u8 = 0x89;
    pub const MISSION_ITEM: u8 = 0x8A;
    pub const MISSION_COMMIT: u8 = 0x8B;
    pub const MISSION_SET_CURRENT: u8 = 0x8C;

    /// Commands have the top bit set; telemetry does not.
    pub const fn is_command(message_type: u8) -> bool {
        message_type & 0x80 != 0
    }
}

/// A name on the wire: 0 to [`MAX_NAME_LEN`] bytes of `A-Z a-z 0-9 _ . -`.
///
/// A small alphabet so that a name prints, sorts and compares the same everywhere (no case
/// folding, no Unicode normalisation, no whitespace to trim).
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Name {
    len: u8,
    /// Bytes past `len` are always zero, so the derived equality is equality of names.
    bytes: [u8; MAX_NAME_LEN],
}

impl Default for Name {
    fn default() -> Self {
        Self {
            len: 0,
            bytes: [0; MAX_NAME_LEN],
        }
    }
}

impl Name {
    /// `None` if the text is too long or has a character outside the alphabet.
    pub fn new(text: &str) -> Option<Self> {
        Self::from_bytes(text.as_bytes())
    }

    pub fn from_bytes(text: &[u8]) -> Option<Self> {
        if text.len() > MAX_NAME_LEN || !text.iter().copied().all(is_name_byte) {
            return None;
        }
        let mut name = Self::default();
        name.bytes.get_mut(..text.len())?.copy_from_slice(text);
        name.len = u8::try_from(text.len()).ok()?;
        Some(name)
    }

    pub fn as_bytes(&self) -> &[u8] {
        self.bytes.get(..usize::from(self.len)).unwrap_or(&[])
    }

    pub fn as_str(&self) -> &str {
        // Always ASCII by construction, so this never falls back.
        core::str::from_utf8(self.as_bytes()).unwrap_or("")
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    fn encode(&self, w: &mut Writer<'_>) -> Result<(), WireError> {
        w.u8(self.len)?;
        w.bytes(self.as_bytes())
    }

    fn decode(r: &mut Reader<'_>) -> Result<Self, WireError> {
        let len = r.u8()?;
        Self::from_bytes(r.bytes(usize::from(len))?).ok_or(WireError::Invalid)
    }
}

fn is_name_byte(b: u8) -> bool {
    b.is_ascii_alphanumeric() || matches!(b, b'_' | b'.' | b'-')
}

impl core::fmt::Debug for Name {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        core::fmt::Debug::fmt(self.as_str(), f)
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for Name {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "{=str}", self.as_str())
    }
}

/// The type of a [`Value`], with its tag byte on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum ValueType {
    Bool = 1,
    I32 = 2,
    U32 = 3,
    F32 = 4,
    F64 = 5,
}

/// A typed value: a parameter's, or one column of a task's data.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Value {
    Bool(bool),
    I32(i32),
    U32(u32),
    F32(f32),
    /// For what f32 cannot carry, e.g. latitude and longitude in degrees (f32 resolves
    /// about half a metre there).
    F64(f64),
}

impl Value {
    pub fn value_type(&self) -> ValueType {
        match self {
            Value::Bool(_) => ValueType::Bool,
            Value::I32(_) => ValueType::I32,
            Value::U32(_) => ValueType::U32,
            Value::F32(_) => ValueType::F32,
            Value::F64(_) => ValueType::F64,
        }
    }

    /// Whether `min <= self <= max`; `None` if the three are not of one type. NaN is never
    /// within a range.
    pub fn within(&self, min: &Value, max: &Value) -> Option<bool> {
        Some(match (self, min, max) {
            (Value::Bool(v), Value::Bool(lo), Value::Bool(hi)) => lo <= v && v <= hi,
            (Value::I32(v), Value::I32(lo), Value::I32(hi)) => lo <= v && v <= hi,
            (Value::U32(v), Value::U32(lo), Value::U32(hi)) => lo <= v && v <= hi,
            (Value::F32(v), Value::F32(lo), Value::F32(hi)) => lo <= v && v <= hi,
            (Value::F64(v), Value::F64(lo), Value::F64(hi)) => lo <= v && v <= hi,
            _ => return None,
        })
    }

    /// Same type and same bits (so a NaN equals itself and `0.0` differs from `-0.0`): the
    /// test for "did this parameter change".
    pub fn same_bits(&self, other: &Value) -> bool {
        match (self, other) {
            (Value::F32(a), Value::F32(b)) => a.to_bits() == b.to_bits(),
            (Value::F64(a), Value::F64(b)) => a.to_bits() == b.to_bits(),
            _ => self == other,
        }
    }

    fn encode(&self, w: &mut Writer<'_>) -> Result<(), WireError> {
        w.u8(self.value_type() as u8)?;
        match *self {
            Value::Bool(v) => w.bool(v),
            Value::I32(v) => w.i32(v),
            Value::U32(v) => w.u32(v),
            Value::F32(v) => w.f32(v),
            Value::F64(v) => w.f64(v),
        }
    }

    fn decode(r: &mut Reader<'_>) -> Result<Self, WireError> {
        let tag = r.u8()?;
        Self::decode_after_tag(tag, r)
    }

    fn decode_after_tag(tag: u8, r: &mut Reader<'_>) -> Result<Self, WireError> {
        match tag {
            1 => Ok(Value::Bool(r.bool()?)),
            2 => Ok(Value::I32(r.i32()?)),
            3 => Ok(Value::U32(r.u32()?)),
            4 => Ok(Value::F32(r.f32()?)),
            5 => Ok(Value::F64(r.f64()?)),
            _ => Err(WireError::Invalid),
        }
    }

    /// An optional value: tag 0 means none.
    fn encode_option(value: &Option<Value>, w: &mut Writer<'_>) -> Result<(), WireError> {
        match value {
            Some(v) => v.encode(w),
            None => w.u8(0),
        }
    }

    fn decode_option(r: &mut Reader<'_>) -> Result<Option<Self>, WireError> {
        match r.u8()? {
            0 => Ok(None),
            tag => Self::decode_after_tag(tag, r).map(Some),
        }
    }
}

/// One task's data, sent at the task's telemetry rate: the values of one of its formats,
/// in the format's column order (the column names come in [`TaskFormat`]).
///
/// One generic message rather than one message type per task, so a new task needs no new
/// message type, and the ground can show any task's data without knowing the task.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaskData {
    /// The task's index in the frame table.
    pub task_index: u8,
    /// Which of the task's formats (the log format index, where the task logs).
    pub format_index: u8,
    /// The TIME of the log record these values come from (`log-format.md`), so the ground
    /// can find the same record in the flight's log.
    pub time: Time,
    pub values: Vec<Value, MAX_TASK_VALUES>,
}

/// The column names of a task's format, sent before its first [`TaskData`] and on request.
#[derive(Clone, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaskFormat {
    pub task_index: u8,
    pub format_index: u8,
    /// Comma-separated column names with their units, as in the log's Format Comment
    /// (`p_rad_s,q_rad_s,r_rad_s`): printable ASCII.
    pub columns: Vec<u8, MAX_COLUMNS_LEN>,
}

/// One task's health, sent for one task per second in rotation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaskStatus {
    pub task_index: u8,
    pub name: Name,
    /// The seed's four lights.
    pub initialised: bool,
    pub running: bool,
    pub in_frame: bool,
    pub alive: bool,
    pub releases: u64,
    pub overruns_budget: u32,
    pub overruns_frame: u32,
    pub overruns_missed: u32,
    pub skipped: u32,
    pub resets: u32,
    pub faults: u32,
    pub init_failures: u32,
    /// Watchdog checks at which the task had been released but never completed a step.
    pub watchdog_misses: u32,
    /// Log records the task's log queue refused.
    pub log_records_dropped: u32,
    /// Interval of the task's [`TaskData`] (0: not sent).
    pub telemetry_interval_ms: u32,
    pub exec_mean_ns: u64,
    pub exec_max_ns: u64,
    pub budget_ns: u64,
    pub period_ns: u64,
}

impl TaskStatus {
    /// The fields the executive's health board knows; the caller adds the name, the
    /// schedule's budget and period, and the counters kept elsewhere (watchdog misses, log
    /// drops, telemetry interval).
    pub fn from_health(task_index: u8, health: &crate::executive::TaskHealth, alive: bool) -> Self {
        Self {
            task_index,
            initialised: health.initialised,
            running: health.running,
            in_frame: health.in_frame,
            alive,
            releases: health.releases,
            overruns_budget: health.overruns.budget,
            overruns_frame: health.overruns.frame,
            overruns_missed: health.overruns.missed,
            skipped: health.skipped,
            resets: health.resets,
            faults: health.faults,
            init_failures: health.init_failures,
            exec_mean_ns: health.exec.mean_ns(),
            exec_max_ns: health.exec.max_ns,
            ..Self::default()
        }
    }

    fn lights(&self) -> u8 {
        u8::from(self.initialised)
            | u8::from(self.running) << 1
            | u8::from(self.in_frame) << 2
            | u8::from(self.alive) << 3
    }
}

/// The executive's status, sent every 2 s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ExecutiveStatus {
    /// Time since the executive started.
    pub elapsed_ns: u64,
    /// Programmed duration of the run (0: until stopped).
    pub duration_ns: u64,
    pub mode: Option<FlightMode>,
    pub task_count: u8,
    /// Period of the watchdog's checks.
    pub health_period_ms: u32,
    pub frames: FrameStats,
    pub link: LinkCounters,
    /// The flight log's state: free space where it is written, records lost to failed writes.
    pub log: LogHealth,
}

/// How the flight's log is doing, as the shell's log writer last measured it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LogHealth {
    /// Free space on the log's file system, in MiB ([`LogHealth::UNKNOWN`] if not measured).
    pub free_mib: u32,
    /// Records that never reached the disk (failed writes: a full disk), all streams.
    pub records_lost: u32,
    /// Streams whose writes are failing right now (suspended, retrying).
    pub streams_suspended: u8,
}

impl LogHealth {
    pub const UNKNOWN: u32 = u32::MAX;
}

impl Default for LogHealth {
    fn default() -> Self {
        Self {
            free_mib: Self::UNKNOWN,
            records_lost: 0,
            streams_suspended: 0,
        }
    }
}

/// A parameter's value in force, with its range: sent for each parameter on
/// [`Command::ListParams`], for one on [`Command::GetParam`], and whenever one changes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParamValue {
    /// The parameter's index in the table, and the table's size, so the ground knows when
    /// it has the whole list.
    pub index: u16,
    pub count: u16,
    pub name: Name,
    pub value: Value,
    pub min: Value,
    pub max: Value,
}

/// What became of an authenticated command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum AckResult {
    Accepted = 0,
    /// A value outside its range: nothing changed.
    OutOfRange = 1,
    /// No parameter has that name.
    UnknownParam = 2,
    /// The parameter has another type: nothing changed.
    WrongType = 3,
    /// Well-formed and in range, but the vehicle will not do it now (e.g. a mode it cannot
    /// enter).
    Refused = 4,
}

impl AckResult {
    pub fn from_u8(value: u8) -> Option<Self> {
        match value {
            0 => Some(Self::Accepted),
            1 => Some(Self::OutOfRange),
            2 => Some(Self::UnknownParam),
            3 => Some(Self::WrongType),
            4 => Some(Self::Refused),
            _ => None,
        }
    }
}

/// The vehicle's answer to an authenticated command. Commands that fail authentication
/// (unsigned, badly signed, replayed, corrupt) get no answer: the vehicle does not tell a
/// stranger anything.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CommandAck {
    /// Sender id, sequence number and type of the command answered.
    pub command_sender_id: u8,
    pub command_sequence: u32,
    pub command_type: u8,
    pub result: AckResult,
    /// For parameter commands: the value in force after the command.
    pub value_in_force: Option<Value>,
}

/// Vehicle → ground.
// No heap in the core to box the big variants into: a message lives on the stack of the
// task that encodes or decodes it, and is gone when the datagram is.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Telemetry {
    TaskData(TaskData),
    TaskFormat(TaskFormat),
    TaskStatus(TaskStatus),
    ExecutiveStatus(ExecutiveStatus),
    ParamValue(ParamValue),
    CommandAck(CommandAck),
}

/// Ground → vehicle.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Send the task's [`TaskData`] every `interval_ms` (0: stop sending it).
    SetTelemetryRate {
        task_index: u8,
        interval_ms: u32,
    },
    /// Run the watchdog's check every `period_ms`.
    SetHealthPeriod {
        period_ms: u32,
    },
    SetParam {
        name: Name,
        value: Value,
    },
    GetParam {
        name: Name,
    },
    ListParams,
    RequestMode {
        mode: FlightMode,
    },
    HorizonAttitude(HorizonAttitude),
    /// End the run cleanly (tasks shut down, logs closed) before its programmed duration.
    Stop,
    /// No mission in force (AUTO holds altitude, heading and airspeed).
    MissionClear,
    /// Waypoint `index` of an upload of `count` (item 0 starts the upload; the rest follow
    /// in order). Staged: nothing is flown until [`Command::MissionCommit`].
    MissionItem {
        index: u8,
        count: u8,
        waypoint: Waypoint,
    },
    /// Puts the `count` staged waypoints in force, flown from the first.
    MissionCommit {
        count: u8,
        switch_radius_m: f32,
        loiter_radius_m: f32,
        loiter_clockwise: bool,
    },
    /// Flies the mission in force from waypoint `index`.
    MissionSetCurrent {
        index: u8,
    },
}

/// Limits of command arguments that do not depend on the parameter table.
pub mod limits {
    /// Fastest telemetry of one task: 20 Hz.
    pub const MIN_TELEMETRY_INTERVAL_MS: u32 = 50;
    /// Slowest telemetry of one task: once an hour.
    pub const MAX_TELEMETRY_INTERVAL_MS: u32 = 3_600_000;
    pub const MIN_HEALTH_PERIOD_MS: u32 = 100;
    pub const MAX_HEALTH_PERIOD_MS: u32 = 60_000;
}

/// Either direction.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Message {
    Telemetry(Telemetry),
    Command(Command),
}

impl From<Telemetry> for Message {
    fn from(t: Telemetry) -> Self {
        Message::Telemetry(t)
    }
}

impl From<Command> for Message {
    fn from(c: Command) -> Self {
        Message::Command(c)
    }
}

impl Message {
    pub fn message_type(&self) -> u8 {
        match self {
            Message::Telemetry(t) => t.message_type(),
            Message::Command(c) => c.message_type(),
        }
    }

    /// Writes the payload (not the header).
    pub fn encode_payload(&self, w: &mut Writer<'_>) -> Result<(), WireError> {
        match self {
            Message::Telemetry(t) => t.encode_payload(w),
            Message::Command(c) => c.encode_payload(w),
        }
    }

    /// Reads a whole payload of the given type; trailing bytes are an error.
    pub fn decode_payload(message_type: u8, payload: &[u8]) -> Result<Self, WireError> {
        if message_type::is_command(message_type) {
            Command::decode_payload(message_type, payload).map(Message::Command)
        } else {
            Telemetry::decode_payload(message_type, payload).map(Message::Telemetry)
        }
    }
}

impl Telemetry {
    pub fn message_type(&self) -> u8 {
        use crate::link::messages::message_type as t;
        match self {
            Telemetry::TaskData(_) => t::TASK_DATA,
            Telemetry::TaskFormat(_) => t::TASK_FORMAT,
            Telemetry::TaskStatus(_) => t::TASK_STATUS,
            Telemetry::ExecutiveStatus(_) => t::EXECUTIVE_STATUS,
            Telemetry::ParamValue(_) => t::PARAM_VALUE,
            Telemetry::CommandAck(_) => t::COMMAND_ACK,
        }
    }

    pub fn encode_payload(&self, w: &mut Writer<'_>) -> Result<(), WireError> {
        match self {
            Telemetry::TaskData(m) => {
                w.u8(m.task_index)?;
                w.u8(m.format_index)?;
                if !m.time.is_valid() {
                    return Err(WireError::Invalid);
                }
                w.bytes(&m.time.to_bytes())?;
                w.u8(u8::try_from(m.values.len()).map_err(|_| WireError::Invalid)?)?;
                m.values.iter().try_for_each(|v| v.encode(w))
            }
            Telemetry::TaskFormat(m) => {
                w.u8(m.task_index)?;
                w.u8(m.format_index)?;
                if !m.columns.iter().copied().all(is_column_byte) {
                    return Err(WireError::Invalid);
                }
                w.u8(u8::try_from(m.columns.len()).map_err(|_| WireError::Invalid)?)?;
                w.bytes(&m.columns)
            }
            Telemetry::TaskStatus(m) => {
                w.u8(m.task_index)?;
                w.u8(m.lights())?;
                m.name.encode(w)?;
                w.u64(m.releases)?;
                for count in [
                    m.overruns_budget,
                    m.overruns_frame,
                    m.overruns_missed,
                    m.skipped,
                    m.resets,
                    m.faults,
                    m.init_failures,
                    m.watchdog_misses,
                    m.log_records_dropped,
                    m.telemetry_interval_ms,
                ] {
                    w.u32(count)?;
                }
                for time in [m.exec_mean_ns, m.exec_max_ns, m.budget_ns, m.period_ns] {
                    w.u64(time)?;
                }
                Ok(())
            }
            Telemetry::ExecutiveStatus(m) => {
                w.u64(m.elapsed_ns)?;
                w.u64(m.duration_ns)?;
                // 0xFF: no mode yet (the controller has not started).
                w.u8(m.mode.map_or(0xFF, |mode| mode as u8))?;
                w.u8(m.task_count)?;
                w.u32(m.health_period_ms)?;
                let f = &m.frames;
                for count in [
                    f.frames,
                    f.missed,
                    f.late,
                    f.overrun,
                    f.max_start_latency_ns,
                    f.max_frame_work_ns,
                    f.timing_records_dropped,
                ] {
                    w.u64(count)?;
                }
                m.link.encode(w)?;
                w.u32(m.log.free_mib)?;
                w.u32(m.log.records_lost)?;
                w.u8(m.log.streams_suspended)
            }
            Telemetry::ParamValue(m) => {
                w.u16(m.index)?;
                w.u16(m.count)?;
                m.name.encode(w)?;
                m.value.encode(w)?;
                m.min.encode(w)?;
                m.max.encode(w)
            }
            Telemetry::CommandAck(m) => {
                w.u8(m.command_sender_id)?;
                w.u32(m.command_sequence)?;
                w.u8(m.command_type)?;
                w.u8(m.result as u8)?;
                Value::encode_option(&m.value_in_force, w)
            }
        }
    }

    pub fn decode_payload(message_type: u8, payload: &[u8]) -> Result<Self, WireError> {
        use crate::link::messages::message_type as t;
        let mut r = Reader::new(payload);
        let r = &mut r;
        let message = match message_type {
            t::TASK_DATA => {
                let task_index = r.u8()?;
                let format_index = r.u8()?;
                let time = Time::from_bytes(r.array::<TIME_LEN>()?);
                if !time.is_valid() {
                    return Err(WireError::Invalid);
                }
                let count = r.u8()?;
                let mut values = Vec::new();
                for _ in 0..count {
                    values
                        .push(Value::decode(r)?)
                        .map_err(|_| WireError::Invalid)?;
                }
                Telemetry::TaskData(TaskData {
                    task_index,
                    format_index,
                    time,
                    values,
                })
            }
            t::TASK_FORMAT => {
                let task_index = r.u8()?;
                let format_index = r.u8()?;
                let len = r.u8()?;
                let text = r.bytes(usize::from(len))?;
                if !text.iter().copied().all(is_column_byte) {
                    return Err(WireError::Invalid);
                }
                let columns = Vec::from_slice(text).map_err(|_| WireError::Invalid)?;
                Telemetry::TaskFormat(TaskFormat {
                    task_index,
                    format_index,
                    columns,
                })
            }
            t::TASK_STATUS => {
                let task_index = r.u8()?;
                let lights = r.u8()?;
                if lights & !0x0F != 0 {
                    return Err(WireError::Invalid);
                }
                Telemetry::TaskStatus(TaskStatus {
                    task_index,
                    initialised: lights & 1 != 0,
                    running: lights & 2 != 0,
                    in_frame: lights & 4 != 0,
                    alive: lights & 8 != 0,
                    name: Name::decode(r)?,
                    releases: r.u64()?,
                    overruns_budget: r.u32()?,
                    overruns_frame: r.u32()?,
                    overruns_missed: r.u32()?,
                    skipped: r.u32()?,
                    resets: r.u32()?,
                    faults: r.u32()?,
                    init_failures: r.u32()?,
                    watchdog_misses: r.u32()?,
                    log_records_dropped: r.u32()?,
                    telemetry_interval_ms: r.u32()?,
                    exec_mean_ns: r.u64()?,
                    exec_max_ns: r.u64()?,
                    budget_ns: r.u64()?,
                    period_ns: r.u64()?,
                })
            }
            t::EXECUTIVE_STATUS => Telemetry::ExecutiveStatus(ExecutiveStatus {
                elapsed_ns: r.u64()?,
                duration_ns: r.u64()?,
                mode: match r.u8()? {
                    0xFF => None,
                    mode => Some(FlightMode::from_u8(mode).ok_or(WireError::Invalid)?),
                },
                task_count: r.u8()?,
                health_period_ms: r.u32()?,
                frames: FrameStats {
                    frames: r.u64()?,
                    missed: r.u64()?,
                    late: r.u64()?,
                    overrun: r.u64()?,
                    max_start_latency_ns: r.u64()?,
                    max_frame_work_ns: r.u64()?,
                    timing_records_dropped: r.u64()?,
                },
                link: LinkCounters::decode(r)?,
                log: LogHealth {
                    free_mib: r.u32()?,
                    records_lost: r.u32()?,
                    streams_suspended: r.u8()?,
                },
            }),
            t::PARAM_VALUE => {
                let index = r.u16()?;
                let count = r.u16()?;
                let name = Name::decode(r)?;
                let value = Value::decode(r)?;
                let min = Value::decode(r)?;
                let max = Value::decode(r)?;
                if min.value_type() != value.value_type() || max.value_type() != value.value_type()
                {
                    return Err(WireError::Invalid);
                }
                Telemetry::ParamValue(ParamValue {
                    index,
                    count,
                    name,
                    value,
                    min,
                    max,
                })
            }
            t::COMMAND_ACK => Telemetry::CommandAck(CommandAck {
                command_sender_id: r.u8()?,
                command_sequence: r.u32()?,
                command_type: r.u8()?,
                result: AckResult::from_u8(r.u8()?).ok_or(WireError::Invalid)?,
                value_in_force: Value::decode_option(r)?,
            }),
            _ => return Err(WireError::Invalid),
        };
        r.finish()?;
        Ok(message)
    }
}

fn is_column_byte(b: u8) -> bool {
    (0x20..=0x7E).contains(&b)
}

impl Command {
    pub fn message_type(&self) -> u8 {
        use crate::link::messages::message_type as t;
        match self {
            Command::SetTelemetryRate { .. } => t::SET_TELEMETRY_RATE,
            Command::SetHealthPeriod { .. } => t::SET_HEALTH_PERIOD,
            Command::SetParam { .. } => t::SET_PARAM,
            Command::GetParam { .. } => t::GET_PARAM,
            Command::ListParams => t::LIST_PARAMS,
            Command::RequestMode { .. } => t::REQUEST_MODE,
            Command::HorizonAttitude(_) => t::HORIZON_ATTITUDE,
            Command::Stop => t::STOP,
            Command::MissionClear => t::MISSION_CLEAR,
            Command::MissionItem { .. } => t::MISSION_ITEM,
            Command::MissionCommit { .. } => t::MISSION_COMMIT,
            Command::MissionSetCurrent { .. } => t::MISSION_SET_CURRENT,
        }
    }

    pub fn encode_payload(&self, w: &mut Writer<'_>) -> Result<(), WireError> {
        match self {
            Command::SetTelemetryRate {
                task_index,
                interval_ms,
            } => {
                w.u8(*task_index)?;
                w.u32(*interval_ms)
            }
            Command::SetHealthPeriod { period_ms } => w.u32(*period_ms),
            Command::SetParam { name, value } => {
                name.encode(w)?;
                value.encode(w)
            }
            Command::GetParam { name } => name.encode(w),
            Command::ListParams | Command::Stop | Command::MissionClear => Ok(()),
            Command::MissionItem {
                index,
                count,
                waypoint,
            } => {
                w.u8(*index)?;
                w.u8(*count)?;
                w.f32(waypoint.north_m)?;
                w.f32(waypoint.east_m)?;
                w.f32(waypoint.altitude_m)?;
                w.f32(waypoint.airspeed_mps)
            }
            Command::MissionCommit {
                count,
                switch_radius_m,
                loiter_radius_m,
                loiter_clockwise,
            } => {
                w.u8(*count)?;
                w.f32(*switch_radius_m)?;
                w.f32(*loiter_radius_m)?;
                w.bool(*loiter_clockwise)
            }
            Command::MissionSetCurrent { index } => w.u8(*index),
            Command::RequestMode { mode } => w.u8(*mode as u8),
            Command::HorizonAttitude(h) => {
                w.f32(h.roll_rad)?;
                w.f32(h.pitch_rad)?;
                w.f32(h.confidence)?;
                w.u64(h.capture_t_ns)
            }
        }
    }

    pub fn decode_payload(message_type: u8, payload: &[u8]) -> Result<Self, WireError> {
        use crate::link::messages::message_type as t;
        let mut r = Reader::new(payload);
        let r = &mut r;
        let command = match message_type {
            t::SET_TELEMETRY_RATE => Command::SetTelemetryRate {
                task_index: r.u8()?,
                interval_ms: r.u32()?,
            },
            t::SET_HEALTH_PERIOD => Command::SetHealthPeriod {
                period_ms: r.u32()?,
            },
            t::SET_PARAM => Command::SetParam {
                name: Name::decode(r)?,
                value: Value::decode(r)?,
            },
            t::GET_PARAM => Command::GetParam {
                name: Name::decode(r)?,
            },
            t::LIST_PARAMS => Command::ListParams,
            t::REQUEST_MODE => Command::RequestMode {
                mode: FlightMode::from_u8(r.u8()?).ok_or(WireError::Invalid)?,
            },
            t::HORIZON_ATTITUDE => Command::HorizonAttitude(HorizonAttitude {
                roll_rad: r.f32()?,
                pitch_rad: r.f32()?,
                confidence: r.f32()?,
                capture_t_ns: r.u64()?,
            }),
            t::STOP => Command::Stop,
            t::MISSION_CLEAR => Command::MissionClear,
            t::MISSION_ITEM => Command::MissionItem {
                index: r.u8()?,
                count: r.u8()?,
                waypoint: Waypoint {
                    north_m: r.f32()?,
                    east_m: r.f32()?,
                    altitude_m: r.f32()?,
                    airspeed_mps: r.f32()?,
                },
            },
            t::MISSION_COMMIT => Command::MissionCommit {
                count: r.u8()?,
                switch_radius_m: r.f32()?,
                loiter_radius_m: r.f32()?,
                loiter_clockwise: r.bool()?,
            },
            t::MISSION_SET_CURRENT => Command::MissionSetCurrent { index: r.u8()? },
            _ => return Err(WireError::Invalid),
        };
        r.finish()?;
        Ok(command)
    }

    /// Range checks that need no parameter table: `false` means the command must be
    /// dropped as out of range. `task_count` is the number of tasks in the frame table.
    pub fn arguments_in_range(&self, task_count: usize) -> bool {
        use core::f32::consts::{FRAC_PI_2, PI};
        use limits::*;
        match *self {
            Command::SetTelemetryRate {
                task_index,
                interval_ms,
            } => {
                usize::from(task_index) < task_count
                    && (interval_ms == 0
                        || (MIN_TELEMETRY_INTERVAL_MS..=MAX_TELEMETRY_INTERVAL_MS)
                            .contains(&interval_ms))
            }
            Command::SetHealthPeriod { period_ms } => {
                (MIN_HEALTH_PERIOD_MS..=MAX_HEALTH_PERIOD_MS).contains(&period_ms)
            }
            // NaN fails every comparison, so it is out of range too.
            Command::HorizonAttitude(h) => {
                (-PI..=PI).contains(&h.roll_rad)
                    && (-FRAC_PI_2..=FRAC_PI_2).contains(&h.pitch_rad)
                    && (0.0..=1.0).contains(&h.confidence)
            }
            // A mission's items as the mission file loader checks them.
            Command::MissionItem {
                index,
                count,
                waypoint,
            } => {
                index < count && usize::from(count) <= MAX_WAYPOINTS && waypoint_in_range(&waypoint)
            }
            Command::MissionCommit {
                count,
                switch_radius_m,
                loiter_radius_m,
                ..
            } => {
                count > 0
                    && usize::from(count) <= MAX_WAYPOINTS
                    && radii_in_range(switch_radius_m, loiter_radius_m)
            }
            Command::MissionSetCurrent { index } => usize::from(index) < MAX_WAYPOINTS,
            // Parameter commands are checked against the table; the rest have no
            // arguments or only ones the decoder already restricts.
            Command::SetParam { .. }
            | Command::GetParam { .. }
            | Command::ListParams
            | Command::RequestMode { .. }
            | Command::Stop
            | Command::MissionClear => true,
        }
    }
}

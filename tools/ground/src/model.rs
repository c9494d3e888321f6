//! What the ground knows about the vehicles it hears, built only from decoded datagrams.
//! Pure logic: no sockets, no clock of its own (every update is given `now`), so tests can
//! script a message stream and look at the result.

use skyframe_core::link::frame::{FrameError, Header};
use skyframe_core::link::messages::{
    CommandAck, ExecutiveStatus, ParamValue, TaskData, TaskFormat, TaskStatus, Telemetry, Value,
};
use skyframe_core::logfmt::Time;
use std::collections::{BTreeMap, VecDeque};
use std::net::SocketAddr;
use std::time::{Duration, Instant};

/// Samples kept per column for charts: a minute at the link's fastest rate (20 Hz).
pub const HISTORY_LEN: usize = 1200;
/// The span the charts show: the last minute of the vehicle's clock.
pub const HISTORY_SPAN_S: f64 = 60.0;
/// Acknowledgements remembered per vehicle (the UI shows the last few).
pub const ACKS_KEPT: usize = 16;
/// Seconds of per-second arrival counts kept per vehicle (the link chart).
pub const ARRIVALS_KEPT_S: usize = 120;
/// A sequence number this far ahead of the last one is taken as a vehicle restart that kept
/// its run id (it must not, but a gap of 10⁶ datagrams is not "loss" worth reporting).
const IMPLAUSIBLE_GAP: u32 = 1_000_000;

/// A number a chart can plot.
pub fn value_as_f64(value: &Value) -> f64 {
    match *value {
        Value::Bool(b) => f64::from(u8::from(b)),
        Value::I32(v) => f64::from(v),
        Value::U32(v) => f64::from(v),
        Value::F32(v) => f64::from(v),
        Value::F64(v) => v,
    }
}

/// The unit a column's name ends in (`conventions.md`: units in the names), as a person
/// writes it; `None` for a count, a flag or a name without a unit.
pub fn column_unit(column: &str) -> Option<&'static str> {
    // Longest suffixes first: `_m_s2` before `_m_s` before `_s`.
    const UNITS: &[(&str, &str)] = &[
        ("_rad_s", "rad/s"),
        ("_m_s2", "m/s^2"),
        ("_m_s", "m/s"),
        ("_deg", "deg"),
        ("_rad", "rad"),
        ("_ns", "ns"),
        ("_us", "us"),
        ("_ms", "ms"),
        ("_pct", "%"),
        ("_ga", "Ga"),
        ("_m", "m"),
        ("_s", "s"),
        ("_v", "V"),
        ("_c", "degC"),
    ];
    UNITS
        .iter()
        .find(|(suffix, _)| column.ends_with(suffix))
        .map(|&(_, unit)| unit)
}

/// A log TIME in seconds.
pub fn time_s(time: Time) -> f64 {
    f64::from(time.sec) + f64::from(time.nsec) * 1e-9
}

/// One of a task's formats: column names (from TaskFormat), latest values, history.
#[derive(Clone, Debug, Default)]
pub struct FormatState {
    /// Empty until a TaskFormat arrives; data is kept meanwhile and shown as `c0, c1, …`.
    pub columns: Vec<String>,
    pub latest: Vec<Value>,
    /// The log TIME of the latest values (the record they come from).
    pub latest_time: Option<Time>,
    /// One ring per column, in column order, all of the same length.
    pub history: Vec<VecDeque<f64>>,
    /// The log TIME of each history entry, in seconds (the vehicle's clock), oldest first.
    pub history_times_s: VecDeque<f64>,
    pub records: u64,
}

impl FormatState {
    /// The column's name, or `c<index>` when the format has not been heard yet.
    pub fn column_name(&self, index: usize) -> String {
        self.columns
            .get(index)
            .cloned()
            .unwrap_or_else(|| format!("c{index}"))
    }

    /// Index of the column whose name is `name` or starts with `name_` (units may be left
    /// out, as on the log tool's command line).
    pub fn column_index(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|c| c == name).or_else(|| {
            let prefix = format!("{name}_");
            self.columns.iter().position(|c| c.starts_with(&prefix))
        })
    }

    pub fn latest_by_name(&self, name: &str) -> Option<f64> {
        self.column_index(name)
            .and_then(|i| self.latest.get(i))
            .map(value_as_f64)
    }

    pub fn history_by_name(&self, name: &str) -> Option<&VecDeque<f64>> {
        self.column_index(name).and_then(|i| self.history.get(i))
    }

    /// Seconds of the vehicle's clock of the latest values.
    pub fn latest_time_s(&self) -> Option<f64> {
        self.latest_time.map(time_s)
    }

    /// (seconds before the latest record, value) of one column, for a chart: newest at 0.
    pub fn recent(&self, column: usize, span_s: f64) -> Vec<(f64, f64)> {
        let (Some(ring), Some(&newest)) = (self.history.get(column), self.history_times_s.back())
        else {
            return Vec::new();
        };
        self.history_times_s
            .iter()
            .zip(ring)
            .map(|(&t, &v)| (t - newest, v))
            .filter(|&(age, _)| age >= -span_s)
            .collect()
    }

    fn record(&mut self, time: Time, values: &[Value], history_len: usize) {
        let t = time_s(time);
        let went_back = self.history_times_s.back().is_some_and(|&last| t < last);
        if self.history.len() != values.len() || went_back {
            // The format changed shape (a new build of the vehicle), or the clock went back
            // (a restart): old history no longer lines up with the columns or the time axis.
            self.history = vec![VecDeque::new(); values.len()];
            self.history_times_s.clear();
        }
        for (ring, value) in self.history.iter_mut().zip(values) {
            if ring.len() >= history_len {
                ring.pop_front();
            }
            ring.push_back(value_as_f64(value));
        }
        if self.history_times_s.len() >= history_len {
            self.history_times_s.pop_front();
        }
        self.history_times_s.push_back(t);
        self.latest = values.to_vec();
        self.latest_time = Some(time);
        self.records = self.records.saturating_add(1);
    }
}

/// One task of one vehicle.
#[derive(Clone, Debug, Default)]
pub struct TaskState {
    pub status: Option<TaskStatus>,
    /// By format index.
    pub formats: BTreeMap<u8, FormatState>,
}

impl TaskState {
    pub fn name(&self) -> Option<&str> {
        self.status.as_ref().map(|s| s.name.as_str())
    }
}

/// Link quality as the ground sees it, from the vehicle's sequence numbers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Datagrams decoded from this vehicle.
    pub received: u64,
    /// Sequence numbers skipped (never arrived, or not yet).
    pub missed: u64,
    /// Arrived with a sequence number at or below one already seen (reordered or duplicated).
    pub late: u64,
    /// From this vehicle's address, refused: CRC wrong.
    pub bad_crc: u64,
    /// From this vehicle's address, refused: signed with another key (or forged).
    pub bad_signature: u64,
    /// From this vehicle's address, refused: not a valid datagram.
    pub malformed: u64,
    /// Refused: unsigned, claiming to be a vehicle that has sent telemetry signed with our
    /// key (a forgery, or a downgrade).
    pub unsigned: u64,
}

impl LinkStats {
    /// Per cent of the vehicle's datagrams that did not arrive.
    pub fn loss_percent(&self) -> f64 {
        let expected = self.received.saturating_add(self.missed);
        if expected == 0 {
            0.0
        } else {
            100.0 * self.missed as f64 / expected as f64
        }
    }
}

/// Everything known about one vehicle.
#[derive(Clone, Debug)]
pub struct VehicleState {
    pub id: u16,
    /// Where its telemetry comes from: the vehicle receives commands on the same socket.
    pub address: SocketAddr,
    pub run_id: u32,
    pub last_seen: Instant,
    /// The vehicle's clock in its latest datagram.
    pub last_t_ns: u64,
    pub last_sequence: Option<u32>,
    /// Whether its latest telemetry was signed (and verified, when we have the key).
    pub signed: bool,
    /// It has sent telemetry that verified under our key: from then on its unsigned
    /// telemetry is refused, so nobody can impersonate it (and divert our commands to
    /// their address) by sending unsigned datagrams in its name.
    pub signed_verified: bool,
    pub link: LinkStats,
    /// By task index.
    pub tasks: BTreeMap<u8, TaskState>,
    pub executive: Option<ExecutiveStatus>,
    /// By parameter index.
    pub params: BTreeMap<u16, ParamValue>,
    /// Newest last.
    pub acks: VecDeque<CommandAck>,
    /// Datagrams per second: link quality over time.
    pub arrivals: ArrivalCounter,
}

impl VehicleState {
    fn new(id: u16, address: SocketAddr, run_id: u32, now: Instant) -> Self {
        Self {
            id,
            address,
            run_id,
            last_seen: now,
            last_t_ns: 0,
            last_sequence: None,
            signed: false,
            signed_verified: false,
            link: LinkStats::default(),
            tasks: BTreeMap::new(),
            executive: None,
            params: BTreeMap::new(),
            acks: VecDeque::new(),
            arrivals: ArrivalCounter::new(now),
        }
    }

    pub fn seen_ago(&self, now: Instant) -> Duration {
        now.saturating_duration_since(self.last_seen)
    }

    /// The task whose status names it `name`.
    pub fn task_by_name(&self, name: &str) -> Option<(u8, &TaskState)> {
        self.tasks
            .iter()
            .find(|(_, t)| t.name() == Some(name))
            .map(|(&i, t)| (i, t))
    }

    pub fn param_by_name(&self, name: &str) -> Option<&ParamValue> {
        self.params.values().find(|p| p.name.as_str() == name)
    }

    /// The acknowledgement of the command this ground sent as `sender_id` with `sequence`.
    pub fn ack_for(&self, sender_id: u8, sequence: u32) -> Option<&CommandAck> {
        self.acks
            .iter()
            .rev()
            .find(|a| a.command_sender_id == sender_id && a.command_sequence == sequence)
    }

    fn count_sequence(&mut self, sequence: u32) {
        match self.last_sequence {
            Some(last) if sequence > last => {
                let gap = sequence - last - 1;
                if gap < IMPLAUSIBLE_GAP {
                    self.link.missed = self.link.missed.saturating_add(u64::from(gap));
                    self.arrivals.missed(gap);
                }
                self.last_sequence = Some(sequence);
            }
            Some(_) => {
                self.link.late = self.link.late.saturating_add(1);
                // It was counted missed when the gap opened; it arrived after all.
                self.link.missed = self.link.missed.saturating_sub(1);
                self.arrivals.recovered();
            }
            None => self.last_sequence = Some(sequence),
        }
    }
}

/// One second of a vehicle's link: datagrams received, and sequence numbers skipped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkSecond {
    pub received: u32,
    pub missed: u32,
}

/// A vehicle's link per whole second since it was first heard: the chart, and the loss over
/// the last seconds (the run's total hides an outage that is happening now).
#[derive(Clone, Debug)]
pub struct ArrivalCounter {
    /// Closed seconds, oldest first, at most [`ARRIVALS_KEPT_S`].
    closed: VecDeque<LinkSecond>,
    first_seen: Instant,
    current_second: u64,
    current: LinkSecond,
}

impl ArrivalCounter {
    pub fn new(now: Instant) -> Self {
        Self {
            closed: VecDeque::new(),
            first_seen: now,
            current_second: 0,
            current: LinkSecond::default(),
        }
    }

    pub fn count(&mut self, now: Instant) {
        self.roll(now);
        self.current.received = self.current.received.saturating_add(1);
    }

    /// Sequence numbers found skipped by the datagram just counted.
    fn missed(&mut self, gap: u32) {
        self.current.missed = self.current.missed.saturating_add(gap);
    }

    /// A datagram counted missed arrived late after all (credited to this second).
    fn recovered(&mut self) {
        self.current.missed = self.current.missed.saturating_sub(1);
    }

    /// Datagrams received in each whole second up to `now`, oldest first, with the
    /// silence since the last datagram as zeros.
    pub fn per_second_until(&self, now: Instant) -> Vec<u32> {
        let mut rolled = self.clone();
        rolled.roll(now);
        rolled.closed.iter().map(|s| s.received).collect()
    }

    /// Loss over the last `seconds` whole seconds and the current one, from sequence gaps;
    /// `None` if nothing was received or missed then. A link gone silent shows no loss here
    /// until the next datagram reveals the gap: "last seen" says that.
    pub fn recent_loss_percent(&self, now: Instant, seconds: usize) -> Option<f64> {
        let mut rolled = self.clone();
        rolled.roll(now);
        let recent = rolled
            .closed
            .iter()
            .rev()
            .take(seconds)
            .chain(std::iter::once(&rolled.current));
        let (received, missed) = recent.fold((0u64, 0u64), |(r, m), s| {
            (r + u64::from(s.received), m + u64::from(s.missed))
        });
        let expected = received + missed;
        (expected > 0).then(|| 100.0 * missed as f64 / expected as f64)
    }

    /// Closes the seconds before `now`'s.
    fn roll(&mut self, now: Instant) {
        let second = now.saturating_duration_since(self.first_seen).as_secs();
        if second <= self.current_second {
            return;
        }
        let silent = (second - self.current_second - 1).min(ARRIVALS_KEPT_S as u64);
        let closed =
            std::iter::once(self.current).chain((0..silent).map(|_| LinkSecond::default()));
        for link_second in closed {
            if self.closed.len() >= ARRIVALS_KEPT_S {
                self.closed.pop_front();
            }
            self.closed.push_back(link_second);
        }
        self.current_second = second;
        self.current = LinkSecond::default();
    }
}

/// A datagram that could not be used, and who sent it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Refused {
    pub from: SocketAddr,
    pub error: FrameError,
}

/// All vehicles heard, by vehicle id.
#[derive(Clone, Debug)]
pub struct GroundModel {
    pub vehicles: BTreeMap<u16, VehicleState>,
    pub history_len: usize,
    /// Refused datagrams from addresses no vehicle has sent good telemetry from.
    pub unattributed: LinkStats,
    /// Commands (or anything else not telemetry) heard on the ground's port: another ground
    /// station sharing a broadcast address.
    pub ignored_commands: u64,
    /// The datagrams were decoded with our key (`Verify::IfSigned`): a signed one has
    /// verified. Without a key, a tag proves nothing and signing is not enforced.
    pub verifies_signatures: bool,
}

impl Default for GroundModel {
    fn default() -> Self {
        Self::new(HISTORY_LEN)
    }
}

impl GroundModel {
    pub fn new(history_len: usize) -> Self {
        Self {
            vehicles: BTreeMap::new(),
            history_len: history_len.max(1),
            unattributed: LinkStats::default(),
            ignored_commands: 0,
            verifies_signatures: false,
        }
    }

    /// Takes one decoded telemetry datagram. Returns the vehicle id it updated, or `None`
    /// if it was refused (unsigned, from a vehicle known to sign).
    pub fn apply(
        &mut self,
        header: &Header,
        telemetry: &Telemetry,
        from: SocketAddr,
        now: Instant,
    ) -> Option<u16> {
        let envelope = header.envelope;
        let id = envelope.vehicle_id;
        let history_len = self.history_len;
        if self.verifies_signatures && !header.signed {
            if let Some(vehicle) = self.vehicles.get_mut(&id).filter(|v| v.signed_verified) {
                vehicle.link.unsigned = vehicle.link.unsigned.saturating_add(1);
                return None;
            }
        }
        let vehicle = self
            .vehicles
            .entry(id)
            .or_insert_with(|| VehicleState::new(id, from, envelope.run_id, now));
        if vehicle.run_id != envelope.run_id {
            // A new run: its sequence numbers start over, and commands need the new run id.
            // Data, formats and parameters stay on screen until replaced.
            vehicle.run_id = envelope.run_id;
            vehicle.last_sequence = None;
            vehicle.link = LinkStats::default();
            vehicle.acks.clear();
        }
        vehicle.address = from;
        vehicle.last_seen = now;
        vehicle.last_t_ns = envelope.t_ns;
        vehicle.signed = header.signed;
        vehicle.signed_verified |= self.verifies_signatures && header.signed;
        vehicle.link.received = vehicle.link.received.saturating_add(1);
        vehicle.arrivals.count(now);
        vehicle.count_sequence(envelope.sequence);
        match telemetry {
            Telemetry::TaskData(data) => apply_task_data(vehicle, data, history_len),
            Telemetry::TaskFormat(format) => apply_task_format(vehicle, format),
            Telemetry::TaskStatus(status) => {
                vehicle.tasks.entry(status.task_index).or_default().status = Some(*status);
            }
            Telemetry::ExecutiveStatus(status) => vehicle.executive = Some(*status),
            Telemetry::ParamValue(param) => {
                // A table that shrank (new build) leaves no stale entries past its end.
                vehicle.params.retain(|&index, _| index < param.count);
                vehicle.params.insert(param.index, *param);
            }
            Telemetry::CommandAck(ack) => {
                if vehicle.acks.len() >= ACKS_KEPT {
                    vehicle.acks.pop_front();
                }
                vehicle.acks.push_back(*ack);
            }
        }
        Some(id)
    }

    /// Counts a datagram that failed to decode against the vehicle at its address, if any.
    pub fn refuse(&mut self, refused: Refused) {
        let stats = match self
            .vehicles
            .values_mut()
            .find(|v| v.address == refused.from)
        {
            Some(vehicle) => &mut vehicle.link,
            None => &mut self.unattributed,
        };
        let counter = match refused.error {
            FrameError::BadCrc => &mut stats.bad_crc,
            FrameError::BadSignature => &mut stats.bad_signature,
            FrameError::Unsigned => &mut stats.unsigned,
            FrameError::Malformed => &mut stats.malformed,
        };
        *counter = counter.saturating_add(1);
    }

    pub fn vehicle(&self, id: u16) -> Option<&VehicleState> {
        self.vehicles.get(&id)
    }

    pub fn vehicle_ids(&self) -> Vec<u16> {
        self.vehicles.keys().copied().collect()
    }
}

fn apply_task_data(vehicle: &mut VehicleState, data: &TaskData, history_len: usize) {
    let task = vehicle.tasks.entry(data.task_index).or_default();
    let format = task.formats.entry(data.format_index).or_default();
    format.record(data.time, &data.values, history_len);
}

fn apply_task_format(vehicle: &mut VehicleState, format: &TaskFormat) {
    let columns: Vec<String> = String::from_utf8_lossy(&format.columns)
        .split(',')
        .map(|c| c.trim().to_string())
        .filter(|c| !c.is_empty())
        .collect();
    let task = vehicle.tasks.entry(format.task_index).or_default();
    let state = task.formats.entry(format.format_index).or_default();
    if state.columns != columns {
        state.columns = columns;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skyframe_core::link::frame::Envelope;
    use skyframe_core::link::messages::{AckResult, Name, message_type};

    fn header(vehicle_id: u16, run_id: u32, sequence: u32, message_type: u8) -> Header {
        Header {
            envelope: Envelope {
                vehicle_id,
                sender_id: 0,
                run_id,
                sequence,
                t_ns: u64::from(sequence) * 1_000_000,
            },
            message_type,
            signed: false,
            payload_len: 0,
        }
    }

    fn addr(port: u16) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], port))
    }

    fn data(task_index: u8, values: &[f32]) -> Telemetry {
        data_at(task_index, 0, values)
    }

    fn data_at(task_index: u8, t_ms: u64, values: &[f32]) -> Telemetry {
        let mut v = heapless::Vec::new();
        for &x in values {
            v.push(Value::F32(x)).expect("fits");
        }
        Telemetry::TaskData(TaskData {
            task_index,
            format_index: 1,
            time: Time::from_ns(t_ms * 1_000_000).expect("in range"),
            values: v,
        })
    }

    fn format(task_index: u8, columns: &str) -> Telemetry {
        Telemetry::TaskFormat(TaskFormat {
            task_index,
            format_index: 1,
            columns: heapless::Vec::from_slice(columns.as_bytes()).expect("fits"),
        })
    }

    #[test]
    fn data_before_its_format_is_kept_and_named_once_the_format_arrives() {
        let mut model = GroundModel::new(4);
        let now = Instant::now();
        let h = header(7, 1, 1, message_type::TASK_DATA);
        model.apply(&h, &data(0, &[0.5, -1.0]), addr(9), now);
        let vehicle = model.vehicle(7).expect("vehicle");
        let f = &vehicle.tasks[&0].formats[&1];
        assert_eq!(f.column_name(1), "c1");
        model.apply(
            &header(7, 1, 2, 2),
            &format(0, "p_rad_s,q_rad_s"),
            addr(9),
            now,
        );
        let f = &model.vehicle(7).expect("vehicle").tasks[&0].formats[&1];
        assert_eq!(f.column_name(1), "q_rad_s");
        assert_eq!(f.latest_by_name("q"), Some(-1.0));
        assert_eq!(f.latest_by_name("q_rad_s"), Some(-1.0));
    }

    #[test]
    fn history_is_bounded_per_column() {
        let mut model = GroundModel::new(3);
        let now = Instant::now();
        for seq in 1..=5u32 {
            model.apply(
                &header(1, 1, seq, 1),
                &data(2, &[seq as f32, -(seq as f32)]),
                addr(9),
                now,
            );
        }
        let f = &model.vehicle(1).expect("vehicle").tasks[&2].formats[&1];
        assert_eq!(f.history[0], [3.0, 4.0, 5.0]);
        assert_eq!(f.history[1], [-3.0, -4.0, -5.0]);
        assert_eq!(f.records, 5);
    }

    #[test]
    fn charts_see_the_last_span_of_the_vehicles_clock_and_a_restart_starts_afresh() {
        let mut model = GroundModel::new(100);
        let now = Instant::now();
        // Every 10 s of vehicle time from 0 to 90 s.
        for (seq, t_s) in (0..10u64).map(|i| i * 10).enumerate() {
            let telemetry = data_at(2, t_s * 1000, &[t_s as f32]);
            model.apply(&header(1, 1, seq as u32 + 1, 1), &telemetry, addr(9), now);
        }
        let f = &model.vehicle(1).expect("vehicle").tasks[&2].formats[&1];
        assert_eq!(f.latest_time_s(), Some(90.0));
        let recent = f.recent(0, 60.0);
        assert_eq!(recent.first(), Some(&(-60.0, 30.0)), "{recent:?}");
        assert_eq!(recent.last(), Some(&(0.0, 90.0)), "{recent:?}");
        assert_eq!(recent.len(), 7);
        // The vehicle restarted its clock: the old minute is not drawn behind the new one.
        model.apply(&header(1, 1, 11, 1), &data_at(2, 500, &[1.0]), addr(9), now);
        let f = &model.vehicle(1).expect("vehicle").tasks[&2].formats[&1];
        assert_eq!(f.recent(0, 60.0), [(0.0, 1.0)]);
    }

    #[test]
    fn loss_comes_from_sequence_gaps_and_late_arrivals_are_forgiven() {
        let mut model = GroundModel::default();
        let now = Instant::now();
        for seq in [1, 2, 5, 6, 10] {
            model.apply(&header(3, 1, seq, 1), &data(0, &[1.0]), addr(9), now);
        }
        let link = model.vehicle(3).expect("vehicle").link;
        assert_eq!((link.received, link.missed), (5, 5));
        assert!((link.loss_percent() - 50.0).abs() < 1e-9);
        model.apply(&header(3, 1, 4, 1), &data(0, &[1.0]), addr(9), now);
        let link = model.vehicle(3).expect("vehicle").link;
        assert_eq!((link.received, link.missed, link.late), (6, 4, 1));
    }

    #[test]
    fn a_new_run_resets_sequence_tracking_and_the_run_id_commands_need() {
        let mut model = GroundModel::default();
        let now = Instant::now();
        model.apply(&header(3, 1, 500, 1), &data(0, &[1.0]), addr(9), now);
        model.apply(&header(3, 2, 1, 1), &data(0, &[1.0]), addr(10), now);
        let vehicle = model.vehicle(3).expect("vehicle");
        assert_eq!(vehicle.run_id, 2);
        assert_eq!(vehicle.address, addr(10));
        assert_eq!(vehicle.link.missed, 0);
        assert_eq!(vehicle.link.received, 1);
    }

    #[test]
    fn several_vehicles_are_kept_apart_and_last_seen_ages() {
        let mut model = GroundModel::default();
        let t0 = Instant::now();
        model.apply(&header(1, 1, 1, 1), &data(0, &[1.0]), addr(1), t0);
        let t1 = t0 + Duration::from_secs(3);
        model.apply(&header(2, 1, 1, 1), &data(0, &[2.0]), addr(2), t1);
        assert_eq!(model.vehicle_ids(), [1, 2]);
        let v1 = model.vehicle(1).expect("vehicle");
        assert_eq!(v1.seen_ago(t1), Duration::from_secs(3));
        assert_eq!(
            model.vehicle(2).expect("vehicle").seen_ago(t1),
            Duration::ZERO
        );
    }

    #[test]
    fn arrivals_are_counted_per_second_and_silence_shows_as_zeros() {
        let mut model = GroundModel::default();
        let t0 = Instant::now();
        let ms = |m: u64| t0 + Duration::from_millis(m);
        for (seq, at) in [(1, 0), (2, 300), (3, 900), (4, 1100), (5, 3500)] {
            model.apply(&header(1, 1, seq, 1), &data(0, &[1.0]), addr(1), ms(at));
        }
        let arrivals = &model.vehicle(1).expect("vehicle").arrivals;
        assert_eq!(arrivals.per_second_until(ms(3600)), [3, 1, 0]);
        assert_eq!(arrivals.per_second_until(ms(6000)), [3, 1, 0, 1, 0, 0]);
    }

    #[test]
    fn recent_loss_forgets_an_old_outage() {
        let mut model = GroundModel::default();
        let t0 = Instant::now();
        let ms = |m: u64| t0 + Duration::from_millis(m);
        // Second 0: sequences 1..=10 with 5 lost; then 20 s later, 10 in a row.
        for seq in [1, 3, 5, 7, 9, 10] {
            model.apply(&header(1, 1, seq, 1), &data(0, &[1.0]), addr(1), ms(100));
        }
        let vehicle = model.vehicle(1).expect("vehicle");
        let recent = vehicle.arrivals.recent_loss_percent(ms(500), 10);
        assert!(
            recent.is_some_and(|l| (l - 40.0).abs() < 1e-9),
            "{recent:?}"
        );
        for seq in 11..=20 {
            model.apply(&header(1, 1, seq, 1), &data(0, &[1.0]), addr(1), ms(20_000));
        }
        let vehicle = model.vehicle(1).expect("vehicle");
        assert_eq!(
            vehicle.arrivals.recent_loss_percent(ms(20_500), 10),
            Some(0.0)
        );
        assert!((vehicle.link.loss_percent() - 20.0).abs() < 1e-9);
    }

    #[test]
    fn once_a_vehicle_signs_with_our_key_its_unsigned_telemetry_is_refused() {
        let mut model = GroundModel {
            verifies_signatures: true,
            ..GroundModel::default()
        };
        let now = Instant::now();
        let unsigned = header(4, 1, 1, 1);
        assert_eq!(
            model.apply(&unsigned, &data(0, &[1.0]), addr(1), now),
            Some(4)
        );
        let signed = Header {
            signed: true,
            ..header(4, 1, 2, 1)
        };
        assert_eq!(
            model.apply(&signed, &data(0, &[2.0]), addr(1), now),
            Some(4)
        );
        // Someone else, unsigned, in vehicle 4's name from another address: refused, and
        // commands still go to the real vehicle.
        let forged = header(4, 1, 3, 1);
        assert_eq!(model.apply(&forged, &data(0, &[9.0]), addr(66), now), None);
        let vehicle = model.vehicle(4).expect("vehicle");
        assert_eq!(vehicle.address, addr(1));
        assert_eq!(vehicle.link.unsigned, 1);
        assert_eq!(vehicle.tasks[&0].formats[&1].latest, [Value::F32(2.0)]);
        // Without a key nothing is enforced (a tag we cannot check proves nothing).
        let mut keyless = GroundModel::default();
        keyless.apply(&signed, &data(0, &[2.0]), addr(1), now);
        assert_eq!(
            keyless.apply(&forged, &data(0, &[9.0]), addr(66), now),
            Some(4)
        );
    }

    #[test]
    fn status_params_acks_and_refusals_are_recorded() {
        let mut model = GroundModel::default();
        let now = Instant::now();
        let status = TaskStatus {
            task_index: 1,
            name: Name::new("gps").expect("name"),
            running: true,
            ..TaskStatus::default()
        };
        model.apply(
            &header(5, 1, 1, 3),
            &Telemetry::TaskStatus(status),
            addr(4),
            now,
        );
        let param = ParamValue {
            index: 0,
            count: 1,
            name: Name::new("control.roll_gain").expect("name"),
            value: Value::F32(1.0),
            min: Value::F32(0.0),
            max: Value::F32(5.0),
        };
        model.apply(
            &header(5, 1, 2, 5),
            &Telemetry::ParamValue(param),
            addr(4),
            now,
        );
        let ack = CommandAck {
            command_sender_id: 1,
            command_sequence: 77,
            command_type: message_type::STOP,
            result: AckResult::Accepted,
            value_in_force: None,
        };
        model.apply(
            &header(5, 1, 3, 6),
            &Telemetry::CommandAck(ack),
            addr(4),
            now,
        );
        model.refuse(Refused {
            from: addr(4),
            error: FrameError::BadCrc,
        });
        model.refuse(Refused {
            from: addr(99),
            error: FrameError::BadSignature,
        });
        let vehicle = model.vehicle(5).expect("vehicle");
        assert_eq!(vehicle.task_by_name("gps").map(|(i, _)| i), Some(1));
        assert_eq!(
            vehicle.param_by_name("control.roll_gain").map(|p| p.value),
            Some(Value::F32(1.0))
        );
        assert_eq!(
            vehicle.ack_for(1, 77).map(|a| a.result),
            Some(AckResult::Accepted)
        );
        assert!(vehicle.ack_for(1, 78).is_none());
        assert_eq!(vehicle.link.bad_crc, 1);
        assert_eq!(model.unattributed.bad_signature, 1);
    }
}

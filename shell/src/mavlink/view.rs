//! What the vehicle last said on its link, by task and column name: the MAVLink side's
//! only source of data. It reads the same telemetry datagrams the skyframe link sends (the
//! link thread hands each one over), so MAVLink shows the log's values at the log's TIME,
//! and no task knows MAVLink exists.

use skyframe_core::control::mode::FlightMode;
use skyframe_core::link::messages::{ExecutiveStatus, ParamValue, TaskStatus, Telemetry, Value};
use std::collections::HashMap;

/// One task's latest record of one format.
#[derive(Debug, Default, Clone)]
struct Record {
    values: Vec<f64>,
    /// Log TIME of the record, ns.
    time_ns: i128,
    /// Times this record was replaced (to see fresh data).
    updates: u64,
}

/// A telemetry message the MAVLink side cares about beyond the stored values.
pub enum Event {
    ParamValue(ParamValue),
    CommandAck(skyframe_core::link::messages::CommandAck),
    /// A task's counts of trouble grew: what, how many now.
    Warning(String),
}

#[derive(Debug, Default)]
pub struct VehicleView {
    /// Task names by frame-table index.
    task_names: Vec<String>,
    columns: HashMap<(u8, u8), Vec<String>>,
    records: HashMap<(u8, u8), Record>,
    statuses: HashMap<u8, TaskStatus>,
    pub executive: Option<ExecutiveStatus>,
    /// Log TIME of the executive's clock zero: `time_boot_ms` = record TIME − this.
    origin_ns: i128,
    latest_time_ns: i128,
    /// Last seen value of counters that warn when they grow, by (task, counter).
    counters: HashMap<(String, &'static str), f64>,
}

pub fn value_f64(v: &Value) -> f64 {
    match *v {
        Value::Bool(b) => f64::from(u8::from(b)),
        Value::I32(i) => f64::from(i),
        Value::U32(u) => f64::from(u),
        Value::F32(f) => f64::from(f),
        Value::F64(f) => f,
    }
}

/// Estimator health columns whose growth is an estimator reset, worth a STATUSTEXT.
const ESTIMATOR_RESETS: [&str; 3] = ["resets", "gps_resets", "align_restarts"];

impl VehicleView {
    pub fn new(task_names: Vec<String>, origin_ns: u64) -> Self {
        Self {
            task_names,
            origin_ns: i128::from(origin_ns),
            ..Self::default()
        }
    }

    fn task_index(&self, task: &str) -> Option<u8> {
        self.task_names
            .iter()
            .position(|n| n == task)
            .and_then(|i| u8::try_from(i).ok())
    }

    pub fn task_name(&self, index: u8) -> Option<&str> {
        self.task_names.get(usize::from(index)).map(String::as_str)
    }

    /// Takes one of the vehicle's telemetry messages; returns what needs an answer or a word.
    pub fn take(&mut self, t: Telemetry) -> Vec<Event> {
        let mut events = Vec::new();
        match t {
            Telemetry::TaskFormat(f) => {
                let text = String::from_utf8_lossy(&f.columns);
                let names = text.split(',').map(|c| c.trim().to_string()).collect();
                self.columns.insert((f.task_index, f.format_index), names);
            }
            Telemetry::TaskData(d) => {
                let time_ns = i128::from(d.time.sec) * 1_000_000_000 + i128::from(d.time.nsec);
                self.latest_time_ns = self.latest_time_ns.max(time_ns);
                let key = (d.task_index, d.format_index);
                let record = self.records.entry(key).or_default();
                record.values = d.values.iter().map(value_f64).collect();
                record.time_ns = time_ns;
                record.updates += 1;
                self.estimator_warnings(key, &mut events);
            }
            Telemetry::TaskStatus(s) => {
                let name = s.name.as_str().to_string();
                let counts = [
                    ("budget overruns", f64::from(s.overruns_budget)),
                    ("frame overruns", f64::from(s.overruns_frame)),
                    ("missed releases", f64::from(s.overruns_missed)),
                    ("skipped releases", f64::from(s.skipped)),
                    ("resets", f64::from(s.resets)),
                    ("faults", f64::from(s.faults)),
                    ("failed inits", f64::from(s.init_failures)),
                    ("watchdog misses", f64::from(s.watchdog_misses)),
                    ("log records dropped", f64::from(s.log_records_dropped)),
                ];
                for (what, now) in counts {
                    if let Some(text) = self.grew(&name, what, now) {
                        events.push(Event::Warning(text));
                    }
                }
                self.statuses.insert(s.task_index, s);
            }
            Telemetry::ExecutiveStatus(e) => {
                let lost = f64::from(e.log.records_lost);
                if let Some(text) = self.grew("log", "records lost (disk)", lost) {
                    events.push(Event::Warning(text));
                }
                let suspended = f64::from(e.log.streams_suspended);
                if let Some(text) = self.grew("log", "streams suspended", suspended) {
                    events.push(Event::Warning(text));
                }
                self.executive = Some(e);
            }
            Telemetry::ParamValue(p) => events.push(Event::ParamValue(p)),
            Telemetry::CommandAck(a) => events.push(Event::CommandAck(a)),
        }
        events
    }

    fn estimator_warnings(&mut self, key: (u8, u8), events: &mut Vec<Event>) {
        if self.task_name(key.0) != Some("estimator") {
            return;
        }
        for column in ESTIMATOR_RESETS {
            let Some(now) = self.get_at(key, column) else {
                continue;
            };
            if let Some(text) = self.grew("estimator", column, now) {
                events.push(Event::Warning(text));
            }
        }
    }

    /// A warning when `counter` of `task` grew since last seen (not at first sight: a count
    /// already there when MAVLink starts was reported by whoever watched then).
    fn grew(&mut self, task: &str, counter: &'static str, now: f64) -> Option<String> {
        let before = self.counters.insert((task.to_string(), counter), now)?;
        (now > before).then(|| format!("{task}: {counter} {now:.0} (+{:.0})", now - before))
    }

    fn get_at(&self, key: (u8, u8), column: &str) -> Option<f64> {
        let i = self.columns.get(&key)?.iter().position(|c| c == column)?;
        self.records.get(&key)?.values.get(i).copied()
    }

    /// The latest value of `column` in any of `task`'s formats.
    pub fn get(&self, task: &str, column: &str) -> Option<f64> {
        let index = self.task_index(task)?;
        self.columns
            .iter()
            .filter(|((t, _), _)| *t == index)
            .find_map(|(key, _)| self.get_at(*key, column))
    }

    /// How many records of `task` arrived (any format): to tell fresh data from none.
    pub fn updates(&self, task: &str) -> u64 {
        let Some(index) = self.task_index(task) else {
            return 0;
        };
        self.records
            .iter()
            .filter(|((t, _), _)| *t == index)
            .map(|(_, r)| r.updates)
            .sum()
    }

    pub fn status(&self, task: &str) -> Option<&TaskStatus> {
        self.statuses.get(&self.task_index(task)?)
    }

    fn boot_ms(&self, time_ns: i128) -> u32 {
        u32::try_from((time_ns - self.origin_ns).max(0) / 1_000_000).unwrap_or(u32::MAX)
    }

    /// Milliseconds of the executive's clock at the newest record seen (MAVLink's
    /// `time_boot_ms`: the log's TIME less its origin, so a message finds its log record).
    pub fn time_boot_ms(&self) -> u32 {
        self.boot_ms(self.latest_time_ns)
    }

    /// [`Self::time_boot_ms`] of the record `column` of `task` comes from: the time of the
    /// values a message takes from it.
    pub fn boot_ms_of(&self, task: &str, column: &str) -> Option<u32> {
        let index = self.task_index(task)?;
        let key = self
            .columns
            .iter()
            .find(|((t, _), names)| *t == index && names.iter().any(|c| c == column))
            .map(|(key, _)| *key)?;
        self.records.get(&key).map(|r| self.boot_ms(r.time_ns))
    }

    /// The flight mode: the control task's, else the executive's report.
    pub fn mode(&self) -> Option<FlightMode> {
        self.get("control", "mode")
            .and_then(|m| u8::try_from(m as i64).ok())
            .and_then(FlightMode::from_u8)
            .or_else(|| self.executive.and_then(|e| e.mode))
    }

    pub fn task_index_of(&self, task: &str) -> Option<u8> {
        self.task_index(task)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skyframe_core::link::messages::{Name, TaskData, TaskFormat};
    use skyframe_core::logfmt::Time;

    fn view() -> VehicleView {
        VehicleView::new(vec!["imu".into(), "estimator".into()], 1_000_000_000)
    }

    #[test]
    fn values_are_found_by_task_and_column_once_the_format_is_known() {
        let mut v = view();
        let data = TaskData {
            task_index: 1,
            format_index: 1,
            time: Time { sec: 10, nsec: 5 },
            values: heapless::Vec::from_slice(&[Value::F32(0.5), Value::F32(-0.25)]).expect("fits"),
        };
        v.take(Telemetry::TaskData(data.clone()));
        assert_eq!(v.get("estimator", "roll_rad"), None, "no column names yet");
        v.take(Telemetry::TaskFormat(TaskFormat {
            task_index: 1,
            format_index: 1,
            columns: heapless::Vec::from_slice(b"roll_rad,pitch_rad").expect("fits"),
        }));
        assert_eq!(v.get("estimator", "pitch_rad"), Some(-0.25));
        assert_eq!(v.get("imu", "pitch_rad"), None);
        let later = TaskData {
            time: Time {
                sec: 12,
                nsec: 500_000_005,
            },
            ..data
        };
        v.take(Telemetry::TaskData(later));
        // TIME 12.500000005 s, origin 1 s.
        assert_eq!(v.time_boot_ms(), 11_500);
        assert_eq!(v.boot_ms_of("estimator", "roll_rad"), Some(11_500));
        assert_eq!(v.boot_ms_of("estimator", "yaw_rad"), None);
        assert_eq!(v.updates("estimator"), 2);
    }

    #[test]
    fn growing_trouble_counts_become_warnings_and_first_sight_does_not() {
        let mut v = view();
        let status = |overruns| TaskStatus {
            task_index: 0,
            name: Name::new("imu").expect("name"),
            overruns_frame: overruns,
            ..TaskStatus::default()
        };
        assert!(v.take(Telemetry::TaskStatus(status(3))).is_empty());
        assert!(v.take(Telemetry::TaskStatus(status(3))).is_empty());
        let events = v.take(Telemetry::TaskStatus(status(5)));
        let texts: Vec<String> = events
            .into_iter()
            .filter_map(|e| match e {
                Event::Warning(t) => Some(t),
                _ => None,
            })
            .collect();
        assert_eq!(texts, vec!["imu: frame overruns 5 (+2)".to_string()]);
    }
}

//! The telemetry tap: a task's log sink that also keeps, for the link, the latest record of
//! each of the task's formats.
//!
//! Telemetry shows exactly what is logged: a [`TaskData`](crate::link::messages::TaskData)
//! carries the typed values of the record the log took, with the log's TIME, and the column
//! names are the record's declaration ([`log_record!`](crate::log_record)), the same text the
//! log's Format Comment holds. The task's log hands both on as it logs
//! ([`RecordSink::declared`], [`RecordSink::logged`]): nothing re-parses the bytes, so the
//! link and the log cannot disagree, and no task has to know about the link.

use crate::link::messages::{MAX_COLUMNS_LEN, MAX_TASK_VALUES, Value};
use crate::logfmt::RecordSink;
use crate::logfmt::record::Time;
use crate::logfmt::{LogFormat, MAX_RECORD_FIELDS, printf};
use core::cell::RefCell;

/// Formats a tap follows per task (the IMU logs three: fast, slow, device status).
pub const TAP_FORMATS: usize = 4;

/// One format of a task, as declared in its log, with its latest values.
#[derive(Clone, Debug)]
struct TappedFormat {
    index: u8,
    columns: &'static str,
    latest: Option<(Time, heapless::Vec<printf::Value, MAX_RECORD_FIELDS>)>,
    /// Data blocks seen, and the count when the telemetry task last took one.
    records: u32,
    records_sent: u32,
}

/// A format's latest record as link values.
#[derive(Clone, Debug, PartialEq)]
pub struct TappedRecord {
    pub format_index: u8,
    pub time: Time,
    pub values: heapless::Vec<Value, MAX_TASK_VALUES>,
}

/// The latest data of one task, as it went to its log.
#[derive(Default)]
pub struct Tap {
    formats: RefCell<heapless::Vec<TappedFormat, TAP_FORMATS>>,
}

impl Tap {
    pub const fn new() -> Self {
        Self {
            formats: RefCell::new(heapless::Vec::new()),
        }
    }

    /// A format declared at `index`. A redefinition starts over: the old data belong to the
    /// old format.
    pub fn declare(&self, index: u8, format: &LogFormat) {
        let Ok(mut formats) = self.formats.try_borrow_mut() else {
            return;
        };
        let fresh = TappedFormat {
            index,
            columns: format.columns,
            latest: None,
            records: 0,
            records_sent: 0,
        };
        match formats.iter_mut().find(|f| f.index == index) {
            Some(f) => *f = fresh,
            // More formats than a tap follows: the extra ones are logged, not sent.
            None => {
                let _ = formats.push(fresh);
            }
        }
    }

    /// The values of a record the log took.
    pub fn take_values(&self, index: u8, time: Time, values: &[printf::Value]) {
        let Ok(mut formats) = self.formats.try_borrow_mut() else {
            return;
        };
        let Some(f) = formats.iter_mut().find(|f| f.index == index) else {
            return;
        };
        let mut kept = heapless::Vec::new();
        if kept.extend_from_slice(values).is_ok() {
            f.latest = Some((time, kept));
            f.records = f.records.wrapping_add(1);
        }
    }

    /// The format indices this tap follows, in declaration order.
    pub fn format_indices(&self) -> heapless::Vec<u8, TAP_FORMATS> {
        self.formats
            .try_borrow()
            .map(|f| f.iter().map(|f| f.index).collect())
            .unwrap_or_default()
    }

    /// The column names of the format at `format_index`, as in its Format Comment.
    pub fn columns(&self, format_index: u8) -> Option<heapless::Vec<u8, MAX_COLUMNS_LEN>> {
        let formats = self.formats.try_borrow().ok()?;
        let f = formats.iter().find(|f| f.index == format_index)?;
        let text = f.columns.as_bytes();
        heapless::Vec::from_slice(text.get(..MAX_COLUMNS_LEN).unwrap_or(text)).ok()
    }

    /// The latest record of the format at `format_index` as link values; with `only_fresh`,
    /// only if it arrived since the last call that took it. Marks it taken.
    pub fn take_latest(&self, format_index: u8, only_fresh: bool) -> Option<TappedRecord> {
        let mut formats = self.formats.try_borrow_mut().ok()?;
        let f = formats.iter_mut().find(|f| f.index == format_index)?;
        if only_fresh && f.records == f.records_sent {
            return None;
        }
        let (time, values) = f.latest.as_ref()?;
        let values = values
            .iter()
            .map(|&v| link_value(v))
            .take(MAX_TASK_VALUES)
            .collect();
        let time = *time;
        f.records_sent = f.records;
        Some(TappedRecord {
            format_index,
            time,
            values,
        })
    }
}

/// A log value as a link value: exact for every field type but 64-bit integers, which
/// travel as f64 (exact below 2^53).
fn link_value(value: printf::Value) -> Value {
    match value {
        printf::Value::I8(v) => Value::I32(i32::from(v)),
        printf::Value::U8(v) => Value::U32(u32::from(v)),
        printf::Value::I16(v) => Value::I32(i32::from(v)),
        printf::Value::U16(v) => Value::U32(u32::from(v)),
        printf::Value::I32(v) => Value::I32(v),
        printf::Value::U32(v) => Value::U32(v),
        printf::Value::I64(v) => Value::F64(v as f64),
        printf::Value::U64(v) => Value::F64(v as f64),
        printf::Value::F32(v) => Value::F32(v),
        printf::Value::F64(v) => Value::F64(v),
    }
}

/// A task's log sink that also keeps the task's latest data for telemetry.
pub struct TappedSink<'a, S> {
    pub inner: S,
    pub tap: &'a Tap,
}

impl<S: RecordSink> RecordSink for TappedSink<'_, S> {
    fn push_record(&mut self, record: &[u8]) -> bool {
        self.inner.push_record(record)
    }

    fn declared(&mut self, index: u8, format: &LogFormat) {
        self.inner.declared(index, format);
        self.tap.declare(index, format);
    }

    /// Called only for what the log took: a record a full ring dropped is in neither, so the
    /// ground never shows a value the log does not have.
    fn logged(&mut self, index: u8, time: Time, values: &[printf::Value]) {
        self.inner.logged(index, time, values);
        self.tap.take_values(index, time, values);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::executive::{HealthBoard, TaskContext};
    use crate::logfmt::LogRecord;
    use crate::tasks::task_log::TaskLog;

    crate::log_record! {
        struct Sample {
            counter: u8 = "%hhu",
            p_rad_s: f32 = "%.4f",
            lat_deg: f64 = "%.8lf",
            t_c: i16 = "%hd",
        }
    }

    crate::log_record! {
        struct Other {
            frames: u32 = "%u",
        }
    }

    /// A log ring that takes records until it is "full".
    struct Ring {
        room: usize,
    }

    impl RecordSink for Ring {
        fn push_record(&mut self, _record: &[u8]) -> bool {
            let taken = self.room > 0;
            self.room = self.room.saturating_sub(1);
            taken
        }
    }

    fn at<R>(health: &HealthBoard, now_ns: u64, f: impl FnOnce(&TaskContext<'_>) -> R) -> R {
        let cx = TaskContext {
            now_ns,
            frame: 0,
            task: 0,
            health,
            log_time_origin_ns: 0,
        };
        f(&cx)
    }

    fn sample(counter: u8) -> Sample {
        Sample {
            counter,
            p_rad_s: -0.125,
            lat_deg: 47.397_742_1,
            t_c: -12,
        }
    }

    #[test]
    fn a_record_the_log_dropped_is_not_shown_on_the_link_either() {
        let tap = Tap::new();
        let health = HealthBoard::new(1);
        let mut log = TaskLog::new(TappedSink {
            inner: Ring { room: 2 },
            tap: &tap,
        });
        at(&health, 0, |cx| log.declare::<Sample>(cx, 1)).expect("declares");
        at(&health, 1_000, |cx| log.log(cx, 1, &sample(1)));
        // The second record finds the ring full: the latest on the link is the first.
        at(&health, 2_000, |cx| log.log(cx, 1, &sample(2)));
        let latest = tap.take_latest(1, false).expect("one was logged");
        assert_eq!(latest.values[0], Value::U32(1));
        assert_eq!(
            latest.time,
            Time {
                sec: 0,
                nsec: 1_000
            }
        );
    }

    #[test]
    fn the_declaration_gives_the_columns_and_the_record_its_typed_values() {
        let tap = Tap::new();
        let health = HealthBoard::new(1);
        let mut log = TaskLog::new(TappedSink {
            inner: Ring { room: 10 },
            tap: &tap,
        });
        at(&health, 0, |cx| log.declare::<Sample>(cx, 1)).expect("declares");
        assert_eq!(
            tap.columns(1).as_deref(),
            Some(&b"counter,p_rad_s,lat_deg,t_c"[..])
        );
        at(&health, 12_340_000_000, |cx| log.log(cx, 1, &sample(7)));
        let latest = tap.take_latest(1, true).expect("fresh");
        assert_eq!(
            latest.time,
            Time {
                sec: 12,
                nsec: 340_000_000
            }
        );
        assert_eq!(
            latest.values.as_slice(),
            [
                Value::U32(7),
                Value::F32(-0.125),
                Value::F64(47.397_742_1),
                Value::I32(-12)
            ]
        );
    }

    #[test]
    fn each_format_keeps_its_own_latest_record_and_freshness() {
        let tap = Tap::new();
        let health = HealthBoard::new(1);
        let mut log = TaskLog::new(TappedSink {
            inner: Ring { room: 10 },
            tap: &tap,
        });
        at(&health, 0, |cx| {
            log.declare::<Sample>(cx, 1)?;
            log.declare::<Other>(cx, 2)
        })
        .expect("declares");
        assert_eq!(tap.format_indices().as_slice(), [1, 2]);
        at(&health, 1, |cx| log.log(cx, 1, &sample(1)));
        at(&health, 2, |cx| log.log(cx, 2, &Other { frames: 99 }));
        at(&health, 3, |cx| log.log(cx, 1, &sample(2)));
        assert_eq!(
            tap.take_latest(2, true).expect("fresh").values[0],
            Value::U32(99)
        );
        assert_eq!(
            tap.take_latest(1, true).expect("fresh").values[0],
            Value::U32(2)
        );
        // Taken: not fresh again until the next record, but still there for a late joiner.
        assert!(tap.take_latest(1, true).is_none());
        assert_eq!(
            tap.take_latest(1, false).expect("kept").values[0],
            Value::U32(2)
        );
    }

    #[test]
    fn a_redefinition_forgets_the_old_data_and_undeclared_formats_are_ignored() {
        let tap = Tap::new();
        tap.declare(1, &Sample::FORMAT);
        tap.take_values(1, Time::default(), &[printf::Value::U8(1)]);
        assert!(tap.take_latest(1, false).is_some());
        tap.declare(1, &Sample::FORMAT);
        assert!(tap.take_latest(1, false).is_none());
        tap.take_values(9, Time::default(), &[printf::Value::U8(1)]);
        assert!(tap.take_latest(9, false).is_none());
    }
}

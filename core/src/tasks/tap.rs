//! The telemetry tap: a task's log sink that also keeps, for the link, the latest record of
//! each of the task's formats.
//!
//! Telemetry shows exactly what is logged: the values a [`TaskData`](crate::link::messages::TaskData)
//! carries are decoded from the very bytes that went to the log, with the log's TIME, and the
//! column names are the log's Format Comment. So the link and the log cannot disagree, and no
//! task has to know about the link.
//!
//! A task may hand its sink several records in one slice (a format's declaration is its
//! Definition followed by its Comment), so the tap walks every record of the slice by its
//! header length. Formats are parsed once, when declared, not on every send.

use crate::comm::RecordSink;
use crate::link::messages::{MAX_COLUMNS_LEN, MAX_TASK_VALUES, Value};
use crate::logfmt::format::{Format, trim_nuls};
use crate::logfmt::printf;
use crate::logfmt::record::{TIME_LEN, Time, kind};
use core::cell::RefCell;

/// Longest data block a tap keeps (the widest shipped format is ~100 bytes).
pub const TAP_DATA: usize = 192;
/// Formats a tap follows per task (the IMU logs three: fast, slow, device status).
pub const TAP_FORMATS: usize = 4;

/// One format of a task, as declared in its log, with its latest data block.
#[derive(Clone, Debug)]
struct TappedFormat {
    index: u8,
    format: Format,
    columns: heapless::Vec<u8, MAX_COLUMNS_LEN>,
    latest: Option<(Time, heapless::Vec<u8, TAP_DATA>)>,
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

    /// Takes note of every record in `records` (one or several whole records).
    pub fn take_records(&self, mut records: &[u8]) {
        let Ok(mut formats) = self.formats.try_borrow_mut() else {
            return;
        };
        while let [record_kind, index, l0, l1, rest @ ..] = records {
            let len = usize::from(u16::from_le_bytes([*l0, *l1]));
            let timed = matches!(
                *record_kind,
                kind::DATA_BLOCK | kind::BYTE_ARRAY | kind::BEGIN_DATA | kind::END_DATA
            );
            let body_len = if timed { TIME_LEN + len } else { len };
            let Some(body) = rest.get(..body_len) else {
                return;
            };
            take_record(&mut formats, *record_kind, *index, body);
            records = rest.get(body_len..).unwrap_or_default();
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
        Some(f.columns.clone())
    }

    /// The latest record of the format at `format_index` as link values; with `only_fresh`,
    /// only if it arrived since the last call that took it. Marks it taken.
    pub fn take_latest(&self, format_index: u8, only_fresh: bool) -> Option<TappedRecord> {
        let mut formats = self.formats.try_borrow_mut().ok()?;
        let f = formats.iter_mut().find(|f| f.index == format_index)?;
        if only_fresh && f.records == f.records_sent {
            return None;
        }
        let (time, data) = f.latest.as_ref()?;
        let values = decode_values(&f.format, data)?;
        let time = *time;
        f.records_sent = f.records;
        Some(TappedRecord {
            format_index,
            time,
            values,
        })
    }
}

fn take_record(
    formats: &mut heapless::Vec<TappedFormat, TAP_FORMATS>,
    record_kind: u8,
    index: u8,
    body: &[u8],
) {
    let slot = formats.iter().position(|f| f.index == index);
    match record_kind {
        kind::FORMAT_DEFINITION => {
            // A redefinition starts over: the old columns and data belong to the old format.
            let fresh = TappedFormat {
                index,
                format: Format::parse_bytes(body).unwrap_or(Format::EMPTY),
                columns: heapless::Vec::new(),
                latest: None,
                records: 0,
                records_sent: 0,
            };
            match slot.and_then(|at| formats.get_mut(at)) {
                Some(f) => *f = fresh,
                None => {
                    // More formats than a tap follows: the extra ones are logged, not sent.
                    let _ = formats.push(fresh);
                }
            }
        }
        kind::FORMAT_COMMENT => {
            if let Some(f) = slot.and_then(|at| formats.get_mut(at)) {
                let text = trim_nuls(body);
                f.columns.clear();
                let _ = f
                    .columns
                    .extend_from_slice(text.get(..MAX_COLUMNS_LEN).unwrap_or(text));
            }
        }
        kind::DATA_BLOCK => {
            let Some(f) = slot.and_then(|at| formats.get_mut(at)) else {
                return;
            };
            let (Some(time), Some(data)) = (body.get(..TIME_LEN), body.get(TIME_LEN..)) else {
                return;
            };
            let mut time_bytes = [0u8; TIME_LEN];
            time_bytes.copy_from_slice(time);
            let mut kept = heapless::Vec::new();
            if kept.extend_from_slice(data).is_ok() {
                f.latest = Some((Time::from_bytes(time_bytes), kept));
                f.records = f.records.wrapping_add(1);
            }
        }
        _ => {}
    }
}

/// A data block's fields as link values: exact for every field type but 64-bit integers,
/// which travel as f64 (exact below 2^53).
fn decode_values(format: &Format, data: &[u8]) -> Option<heapless::Vec<Value, MAX_TASK_VALUES>> {
    if data.len() != format.data_len() || format.fields().is_empty() {
        return None;
    }
    let mut values = heapless::Vec::new();
    let mut at = 0usize;
    for field in format.fields() {
        let size = field.ty.size();
        let bytes = data.get(at..at.checked_add(size)?)?;
        at += size;
        let value = match printf::Value::decode(field.ty, bytes)? {
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
        };
        // A format wider than a message carries: the first columns go, the rest are logged.
        if values.push(value).is_err() {
            break;
        }
    }
    Some(values)
}

/// A task's log sink that also keeps the task's latest data for telemetry.
pub struct TappedSink<'a, S> {
    pub inner: S,
    pub tap: &'a Tap,
}

impl<S: RecordSink> RecordSink for TappedSink<'_, S> {
    /// The tap sees only what the log took: a record a full ring dropped is in neither, so
    /// the ground never shows a value the log does not have.
    fn push_record(&mut self, record: &[u8]) -> bool {
        let logged = self.inner.push_record(record);
        if logged {
            self.tap.take_records(record);
        }
        logged
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::logfmt::record::{DataBlockWriter, LogFormat, encode_begin_data};

    const FORMAT: LogFormat = LogFormat::new("%hhu,%.4f,%.8lf,%hd", "counter,p_rad_s,lat_deg,t_c");
    const OTHER: LogFormat = LogFormat::new("%u", "frames");

    fn declare(tap: &Tap, index: u8, format: &LogFormat) {
        let mut buf = [0u8; 256];
        let len = format.encode_declaration(&mut buf, index).expect("encodes");
        // Definition and Comment arrive in one slice, as a task's log hands them on.
        tap.take_records(&buf[..len]);
    }

    fn data(
        tap: &Tap,
        index: u8,
        t_ns: u64,
        fill: impl for<'b, 'f> FnOnce(DataBlockWriter<'b, 'f>) -> DataBlockWriter<'b, 'f>,
    ) {
        let format = if index == 1 { FORMAT } else { OTHER }
            .parse()
            .expect("parses");
        let mut buf = [0u8; 256];
        let len = fill(DataBlockWriter::new(&mut buf, index, t_ns, &format))
            .finish()
            .expect("encodes");
        tap.take_records(&buf[..len]);
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

    #[test]
    fn a_record_the_log_dropped_is_not_shown_on_the_link_either() {
        let tap = Tap::new();
        declare(&tap, 1, &FORMAT);
        let format = FORMAT.parse().expect("parses");
        let mut sink = TappedSink {
            inner: Ring { room: 1 },
            tap: &tap,
        };
        for (t_ns, counter) in [(1_000, 1u8), (2_000, 2)] {
            let mut buf = [0u8; 256];
            let len = DataBlockWriter::new(&mut buf, 1, t_ns, &format)
                .u8(counter)
                .f32(0.0)
                .f64(0.0)
                .i16(0)
                .finish()
                .expect("encodes");
            sink.push_record(&buf[..len]);
        }
        // The second record found the ring full: the latest on the link is the first.
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
    fn a_declaration_in_one_slice_gives_both_the_format_and_its_columns() {
        let tap = Tap::new();
        declare(&tap, 1, &FORMAT);
        assert_eq!(
            tap.columns(1).as_deref(),
            Some(&b"counter,p_rad_s,lat_deg,t_c"[..])
        );
        data(&tap, 1, 12_340_000_000, |w| {
            w.u8(7).f32(-0.125).f64(47.397_742_1).i16(-12)
        });
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
        declare(&tap, 1, &FORMAT);
        declare(&tap, 2, &OTHER);
        assert_eq!(tap.format_indices().as_slice(), [1, 2]);
        let mut buf = [0u8; 16];
        let len = encode_begin_data(&mut buf, 0).expect("encodes");
        tap.take_records(&buf[..len]);
        data(&tap, 1, 1, |w| w.u8(1).f32(0.0).f64(0.0).i16(0));
        data(&tap, 2, 2, |w| w.u32(99));
        data(&tap, 1, 3, |w| w.u8(2).f32(0.0).f64(0.0).i16(0));
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
    fn a_redefinition_forgets_the_old_data_and_damage_is_ignored() {
        let tap = Tap::new();
        declare(&tap, 1, &FORMAT);
        data(&tap, 1, 1, |w| w.u8(1).f32(0.0).f64(0.0).i16(0));
        declare(&tap, 1, &FORMAT);
        assert!(tap.take_latest(1, false).is_none());
        // A header whose length runs past the slice, an unknown kind, random bytes: no panic,
        // nothing taken.
        tap.take_records(&[kind::DATA_BLOCK, 1, 0xFF, 0xFF, 1, 2, 3]);
        tap.take_records(&[0x42, 1, 0, 0]);
        tap.take_records(&[1, 2, 3]);
        assert!(tap.take_latest(1, false).is_none());
        // A data block of the wrong length for its format is not decoded.
        tap.take_records(&[kind::DATA_BLOCK, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 5]);
        assert!(tap.take_latest(1, false).is_none());
    }
}

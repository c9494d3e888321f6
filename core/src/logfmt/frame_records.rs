//! The executive's per-frame timing records ([`FrameRecord`]) as a log format, for the
//! frame-overrun report tool.
//!
//! The layout is fixed except for its tail: twelve frame columns, then one `exec_ns_<task>`
//! column per task of the frame table, in table order:
//!
//! ```text
//! %llu,%llu,%u,%u,%u,%u,%u,%u,%u,%u,%u,%hhu,%u,%u,...
//! frame,release_ns,start_latency_ns,work_ns,overhead_ns,missed_before,ran_mask,
//!   over_budget_mask,over_frame_mask,skipped_mask,reset_mask,flags,exec_ns_imu,...
//! ```
//!
//! A reader finds the task names in the comment (every column after `flags`, without its
//! `exec_ns_` prefix), so a log stays readable after the schedule changes. The task masks
//! print in decimal so Matlab reads them as numbers; bit `i` is task `i` of the table.

use core::fmt::Write;

use heapless::String;

use super::format::{FieldType, Format};
use super::record::{DataBlockWriter, EncodeError};
use crate::executive::FrameRecord;
use crate::schedule::TaskSlot;
use crate::schedule::analysis::MAX_TASKS;

/// The format string of the columns before the per-task times.
pub const FRAME_FIXED_FORMAT: &str = "%llu,%llu,%u,%u,%u,%u,%u,%u,%u,%u,%u,%hhu";
/// Their names.
pub const FRAME_FIXED_COLUMNS: &str = "frame,release_ns,start_latency_ns,work_ns,overhead_ns,\
missed_before,ran_mask,over_budget_mask,over_frame_mask,skipped_mask,reset_mask,flags";
/// How many columns come before the per-task times.
pub const FRAME_FIXED_FIELDS: usize = 12;
/// The prefix of each per-task time column.
pub const EXEC_COLUMN_PREFIX: &str = "exec_ns_";

/// Longest task name a frame log column can carry.
pub const MAX_TASK_NAME: usize = 32;
const FORMAT_CAPACITY: usize = FRAME_FIXED_FORMAT.len() + 3 * MAX_TASKS;
const COLUMNS_CAPACITY: usize =
    FRAME_FIXED_COLUMNS.len() + (1 + EXEC_COLUMN_PREFIX.len() + MAX_TASK_NAME) * MAX_TASKS;

/// The frame log format of one frame table: format string, column names, parsed fields.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrameRecordFormat {
    format_text: String<FORMAT_CAPACITY>,
    columns: String<COLUMNS_CAPACITY>,
    format: Format,
    task_count: usize,
}

impl FrameRecordFormat {
    /// Builds the format for the tasks of a frame table. Task names become column names, so
    /// they must be short identifiers (`[A-Za-z0-9_]`, at most [`MAX_TASK_NAME`] bytes).
    pub fn new(tasks: &[TaskSlot]) -> Result<Self, EncodeError> {
        if tasks.len() > MAX_TASKS {
            return Err(EncodeError::TooLong);
        }
        let mut format_text = String::new();
        let mut columns = String::new();
        let overflow = |_| EncodeError::TooLong;
        format_text
            .write_str(FRAME_FIXED_FORMAT)
            .map_err(overflow)?;
        columns.write_str(FRAME_FIXED_COLUMNS).map_err(overflow)?;
        for task in tasks {
            let name_ok = !task.name.is_empty()
                && task.name.len() <= MAX_TASK_NAME
                && task
                    .name
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b == b'_');
            if !name_ok {
                return Err(EncodeError::InvalidColumnName);
            }
            format_text.write_str(",%u").map_err(overflow)?;
            write!(columns, ",{EXEC_COLUMN_PREFIX}{}", task.name).map_err(overflow)?;
        }
        let format = Format::parse(&format_text).map_err(EncodeError::InvalidFormat)?;
        Ok(Self {
            format_text,
            columns,
            format,
            task_count: tasks.len(),
        })
    }

    /// The printf format string (for the Format Definition).
    pub fn format_text(&self) -> &str {
        &self.format_text
    }

    /// The column names (for the Format Comment).
    pub fn columns(&self) -> &str {
        &self.columns
    }

    pub fn format(&self) -> &Format {
        &self.format
    }

    pub fn task_count(&self) -> usize {
        self.task_count
    }

    /// Encodes the Format Definition and Comment at `index`; returns the bytes written.
    pub fn encode_declaration(&self, buf: &mut [u8], index: u8) -> Result<usize, EncodeError> {
        let definition = super::record::encode_format_definition(buf, index, self.format_text())?;
        let rest = buf.get_mut(definition..).unwrap_or(&mut []);
        let comment = super::record::encode_format_comment(rest, index, self.columns())?;
        Ok(definition + comment)
    }
}

/// Encodes one frame's timing record as a Data Block of `log`'s format at `index`.
pub fn encode_frame_record(
    buf: &mut [u8],
    index: u8,
    t_ns: u64,
    log: &FrameRecordFormat,
    record: &FrameRecord,
) -> Result<usize, EncodeError> {
    let mut writer = DataBlockWriter::new(buf, index, t_ns, log.format())
        .u64(record.frame)
        .u64(record.release_ns)
        .u32(record.start_latency_ns)
        .u32(record.work_ns)
        .u32(record.overhead_ns)
        .u32(record.missed_before)
        .u32(record.ran)
        .u32(record.over_budget)
        .u32(record.over_frame)
        .u32(record.skipped)
        .u32(record.reset)
        .u8(record.flags);
    for &exec_ns in record.exec_ns.iter().take(log.task_count()) {
        writer = writer.u32(exec_ns);
    }
    writer.finish()
}

/// The task names of a frame log, from its Format Comment; `None` when the columns are not a
/// frame log's (the fixed columns first, then only `exec_ns_<task>` columns).
pub fn frame_record_task_names(columns: &str) -> Option<impl Iterator<Item = &str>> {
    let rest = columns.strip_prefix(FRAME_FIXED_COLUMNS)?;
    if !(rest.is_empty() || rest.starts_with(',')) {
        return None;
    }
    let names = rest.split(',').skip(1);
    if names.clone().any(|c| !c.starts_with(EXEC_COLUMN_PREFIX)) {
        return None;
    }
    Some(names.filter_map(|c| c.strip_prefix(EXEC_COLUMN_PREFIX)))
}

/// Decodes a Data Block of a frame log back into a [`FrameRecord`] (for the frame-overrun
/// report tool); `None` when the format is not a frame log's or `data` does not fit it.
/// Tasks past [`MAX_TASKS`] cannot be in a frame log.
pub fn decode_frame_record(format: &Format, data: &[u8]) -> Option<FrameRecord> {
    const FIXED: [FieldType; FRAME_FIXED_FIELDS] = [
        FieldType::U64,
        FieldType::U64,
        FieldType::U32,
        FieldType::U32,
        FieldType::U32,
        FieldType::U32,
        FieldType::U32,
        FieldType::U32,
        FieldType::U32,
        FieldType::U32,
        FieldType::U32,
        FieldType::U8,
    ];
    let fields = format.fields();
    let (fixed, exec) = fields.split_at_checked(FRAME_FIXED_FIELDS)?;
    let layout_ok = fixed.iter().map(|f| f.ty).eq(FIXED)
        && exec.len() <= MAX_TASKS
        && exec.iter().all(|f| f.ty == FieldType::U32)
        && data.len() == format.data_len();
    if !layout_ok {
        return None;
    }
    let mut cursor = Cursor { data, offset: 0 };
    let mut record = FrameRecord::empty();
    record.frame = cursor.u64()?;
    record.release_ns = cursor.u64()?;
    record.start_latency_ns = cursor.u32()?;
    record.work_ns = cursor.u32()?;
    record.overhead_ns = cursor.u32()?;
    record.missed_before = cursor.u32()?;
    record.ran = cursor.u32()?;
    record.over_budget = cursor.u32()?;
    record.over_frame = cursor.u32()?;
    record.skipped = cursor.u32()?;
    record.reset = cursor.u32()?;
    record.flags = cursor.u8()?;
    for exec_ns in record.exec_ns.iter_mut().take(exec.len()) {
        *exec_ns = cursor.u32()?;
    }
    Some(record)
}

/// Reads little-endian fields in order.
struct Cursor<'a> {
    data: &'a [u8],
    offset: usize,
}

impl Cursor<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let bytes = self.data.get(self.offset..)?.first_chunk::<N>()?;
        self.offset += N;
        Some(*bytes)
    }

    fn u64(&mut self) -> Option<u64> {
        self.take().map(u64::from_le_bytes)
    }

    fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }

    fn u8(&mut self) -> Option<u8> {
        self.take().map(u8::from_le_bytes)
    }
}

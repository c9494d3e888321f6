//! The binary flight log (`shared/specs/log-format.md`): formats, records, reading, printing.
//!
//! - [`format`]: printf format strings parsed into the fields of a data block;
//! - [`record`]: encoding records into a caller's fixed buffer ([`LogFormat`],
//!   [`DataBlockWriter`]);
//! - [`reader`]: a streaming, resynchronising reader that survives any bytes;
//! - [`printf`]: a data block's text exactly as C's `printf` prints it;
//! - [`csv`]: the lines of a text log / CSV conversion (`% format`, `% time,`, data lines);
//! - [`frame_log`]: the executive's per-frame timing records as a log format.
//!
//! Nothing here allocates, panics or blocks; the reader and renderer are meant for hosts
//! (`skyframe-log`), the encoders for tasks.

pub mod csv;
pub mod declare;
pub mod format;
pub mod frame_records;
pub mod printf;
pub mod reader;
pub mod record;
pub mod sink;

pub use csv::{
    write_byte_array_line, write_columns_line, write_data_line, write_format_line, write_header,
    write_values_line,
};
pub use declare::{LogField, LogRecord, MAX_RECORD_FIELDS, encode_record, record_values};
pub use format::{Conversion, Field, FieldType, Flags, Format, FormatError, MAX_FIELDS};
pub use frame_records::{
    FrameRecordFormat, decode_frame_record, encode_frame_record, frame_record_task_names,
};
pub use printf::{
    ByteWrite, RenderError, Value, render_byte_array, render_byte_array_bytes, render_data_block,
    render_data_block_bytes, render_field, render_field_bytes,
};
pub use reader::{Event, LogReader, Problem, ProblemKind, Record, read_slice};
pub use record::{
    DataBlockWriter, EncodeError, LogFormat, MAX_RECORD_LEN, Time, encode_begin_data,
    encode_byte_array, encode_data_block, encode_end_data, encode_format_comment,
    encode_format_definition,
};
pub use sink::{NoLog, RecordSink};

#[cfg(test)]
mod tests;

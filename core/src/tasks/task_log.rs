//! A task's log: declares its formats once, stamps records with the log clock, and counts
//! every record its ring could not take in the task's health (nothing is dropped silently).

use crate::comm::RecordSink;
use crate::executive::TaskContext;
use crate::logfmt::format::Format;
use crate::logfmt::record::{
    DataBlockWriter, EncodeError, LogFormat, encode_begin_data, encode_end_data,
};

/// Room for one record: the largest format declaration or data block a task writes.
pub const TASK_LOG_BUFFER: usize = 768;

pub struct TaskLog<S: RecordSink> {
    sink: S,
    buf: [u8; TASK_LOG_BUFFER],
}

impl<S: RecordSink> TaskLog<S> {
    pub fn new(sink: S) -> Self {
        Self {
            sink,
            buf: [0; TASK_LOG_BUFFER],
        }
    }

    fn push(&mut self, cx: &TaskContext<'_>, len: usize) {
        let record = self.buf.get(..len).unwrap_or_default();
        if !self.sink.push_record(record) {
            cx.health.note_log_drop(cx.task);
        }
    }

    /// Writes a format's definition and column names at `index`; returns it parsed for
    /// [`record`](Self::record).
    pub fn declare(
        &mut self,
        cx: &TaskContext<'_>,
        index: u8,
        format: &LogFormat,
    ) -> Result<Format, EncodeError> {
        let parsed = format.parse()?;
        let len = format.encode_declaration(&mut self.buf, index)?;
        self.push(cx, len);
        Ok(parsed)
    }

    /// Begin Data: the task starts logging.
    pub fn begin(&mut self, cx: &TaskContext<'_>) {
        if let Ok(len) = encode_begin_data(&mut self.buf, cx.log_time_ns()) {
            self.push(cx, len);
        }
    }

    /// End Data: the task stops logging.
    pub fn end(&mut self, cx: &TaskContext<'_>) {
        if let Ok(len) = encode_end_data(&mut self.buf, cx.log_time_ns()) {
            self.push(cx, len);
        }
    }

    /// One data block of `format` at `index`, its fields filled in by `fill` in format
    /// order. A record that does not encode (a field missing or of the wrong type: a bug the
    /// task's tests catch) is counted as dropped.
    pub fn record(
        &mut self,
        cx: &TaskContext<'_>,
        index: u8,
        format: &Format,
        fill: impl for<'b, 'f> FnOnce(DataBlockWriter<'b, 'f>) -> DataBlockWriter<'b, 'f>,
    ) {
        let t = cx.log_time_ns();
        match fill(DataBlockWriter::new(&mut self.buf, index, t, format)).finish() {
            Ok(len) => self.push(cx, len),
            Err(_) => cx.health.note_log_drop(cx.task),
        }
    }
}

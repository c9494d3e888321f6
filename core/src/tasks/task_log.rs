//! A task's log: declares its records once, stamps them with the log clock, and counts every
//! record its ring could not take in the task's health (nothing is dropped silently).

use crate::executive::TaskContext;
use crate::logfmt::RecordSink;
use crate::logfmt::record::{EncodeError, Time, encode_begin_data, encode_end_data};
use crate::logfmt::{LogRecord, encode_record, record_values};

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

    fn push(&mut self, cx: &TaskContext<'_>, len: usize) -> bool {
        let record = self.buf.get(..len).unwrap_or_default();
        let taken = self.sink.push_record(record);
        if !taken {
            cx.health.note_log_drop(cx.task);
        }
        taken
    }

    /// Writes record `R`'s Format Definition and column names at `index`, after checking
    /// the declaration (an unsound one is a bug its task's test catches: `Err`).
    pub fn declare<R: LogRecord + Default>(
        &mut self,
        cx: &TaskContext<'_>,
        index: u8,
    ) -> Result<(), EncodeError> {
        R::check()?;
        let len = R::FORMAT.encode_declaration(&mut self.buf, index)?;
        if self.push(cx, len) {
            self.sink.declared(index, &R::FORMAT);
        }
        Ok(())
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

    /// One Data Block of the record declared at `index`. A record that does not encode (a
    /// time past 2038) is counted as dropped.
    pub fn log<R: LogRecord>(&mut self, cx: &TaskContext<'_>, index: u8, record: &R) {
        let t = cx.log_time_ns();
        match encode_record(&mut self.buf, index, t, record) {
            Ok(len) => {
                if self.push(cx, len) {
                    let time = Time::from_ns(t).unwrap_or_default();
                    self.sink.logged(index, time, &record_values(record));
                }
            }
            Err(_) => cx.health.note_log_drop(cx.task),
        }
    }
}

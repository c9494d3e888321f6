//! Where a task's encoded records go, and what else may watch them go.

use super::printf::Value;
use super::record::{LogFormat, Time};

/// Where a task's encoded log records go: a ring the shell's log writer drains. Takes a
/// whole record or nothing, and never waits.
pub trait RecordSink {
    fn push_record(&mut self, record: &[u8]) -> bool;

    /// A declared record's format, after its declaration went into the log: for a sink that
    /// also shows the task's data elsewhere (the telemetry tap).
    fn declared(&mut self, _index: u8, _format: &LogFormat) {}

    /// The typed values of the Data Block the log has just taken, as the task declared them:
    /// what the telemetry tap keeps, so nothing re-parses the bytes.
    fn logged(&mut self, _index: u8, _time: Time, _values: &[Value]) {}
}

/// The sink of a task built without a log (unit tests, tools): takes every record, keeps none.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoLog;

impl RecordSink for NoLog {
    fn push_record(&mut self, _record: &[u8]) -> bool {
        true
    }
}

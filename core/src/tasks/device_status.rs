//! Once a second, each device task logs its decoder's counters and whether the device is
//! stale, so a flight's log shows when a device started garbling or went quiet — not just
//! the totals at the end.

use super::task_log::TaskLog;
use crate::devices::{Decoder, DecoderStats};
use crate::executive::{TaskContext, TaskFault};
use crate::logfmt::RecordSink;
use crate::logfmt::record::EncodeError;

crate::log_record! {
    /// A device's decoder counters, once a second.
    pub struct DeviceStatusRecord {
        frames: u32 = "%u",
        bad_checksum: u32 = "%u",
        framing_errors: u32 = "%u",
        overflows: u32 = "%u",
        bytes_discarded: u32 = "%u",
        invalid_payload: u32 = "%u",
        ignored: u32 = "%u",
        sequence_gaps: u32 = "%u",
        stale_events: u32 = "%u",
        stale: bool = "%hhu",
    }
}

const INTERVAL_NS: u64 = 1_000_000_000;

/// The degraded reason a device task sets in its health while its device is stale.
pub const DEVICE_STALE: &str = "device stale";

/// The status record of one device task.
pub struct DeviceStatusLog {
    index: u8,
    next_ns: u64,
}

impl DeviceStatusLog {
    pub const fn new(index: u8) -> Self {
        Self { index, next_ns: 0 }
    }

    /// Opens a logging section (the task's init): the task's own records
    /// (`declare_records`), the status record, then Begin Data. A record that cannot be
    /// declared fails the init with `log_format_fault`.
    pub fn open<S: RecordSink>(
        &mut self,
        log: &mut TaskLog<S>,
        cx: &TaskContext<'_>,
        log_format_fault: &'static str,
        declare_records: impl FnOnce(&mut TaskLog<S>) -> Result<(), EncodeError>,
    ) -> Result<(), TaskFault> {
        declare_records(log)
            .and_then(|()| log.declare::<DeviceStatusRecord>(cx, self.index))
            .map_err(|_| TaskFault::new(log_format_fault))?;
        self.next_ns = cx.now_ns;
        log.begin(cx);
        Ok(())
    }

    /// The end of every step: the task is degraded while its device is stale, and the
    /// counters go into the log once a second. The step fails with `port_fault` when draining
    /// its port failed (`drained`), after the counters are in.
    pub fn after_step<S: RecordSink, D: Decoder, T, E>(
        &mut self,
        log: &mut TaskLog<S>,
        cx: &TaskContext<'_>,
        decoder: &D,
        drained: Result<T, E>,
        port_fault: &'static str,
    ) -> Result<(), TaskFault> {
        let stale = decoder.is_stale(cx.now_ns);
        cx.health
            .set_degraded(cx.task, stale.then_some(DEVICE_STALE));
        self.maybe_log(log, cx, decoder.stats(), stale, false);
        drained.map(|_| ()).map_err(|_| TaskFault::new(port_fault))
    }

    /// Closes a logging section (recover, shutdown): the counters as they stand, then End
    /// Data. The decoder keeps its counters; `init` opens the next section.
    pub fn close<S: RecordSink, D: Decoder>(
        &mut self,
        log: &mut TaskLog<S>,
        cx: &TaskContext<'_>,
        decoder: &D,
    ) {
        let stale = decoder.is_stale(cx.now_ns);
        self.maybe_log(log, cx, decoder.stats(), stale, true);
        log.end(cx);
    }

    /// Logs the counters when a second has passed since the last record (or `force`).
    fn maybe_log<S: RecordSink>(
        &mut self,
        log: &mut TaskLog<S>,
        cx: &TaskContext<'_>,
        stats: &DecoderStats,
        stale: bool,
        force: bool,
    ) {
        if !force && cx.now_ns < self.next_ns {
            return;
        }
        self.next_ns = self
            .next_ns
            .saturating_add(INTERVAL_NS)
            .max(cx.now_ns.saturating_add(1));
        let record = DeviceStatusRecord {
            frames: stats.frames,
            bad_checksum: stats.bad_checksum,
            framing_errors: stats.framing_errors,
            overflows: stats.overflows,
            bytes_discarded: stats.bytes_discarded,
            invalid_payload: stats.invalid_payload,
            ignored: stats.ignored,
            sequence_gaps: stats.sequence_gaps,
            stale_events: stats.stale_events,
            stale,
        };
        log.log(cx, self.index, &record);
    }
}

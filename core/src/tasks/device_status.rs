//! Once a second, each device task logs its decoder's counters and whether the device is
//! stale, so a flight's log shows when a device started garbling or went quiet — not just
//! the totals at the end.

use super::task_log::TaskLog;
use crate::comm::RecordSink;
use crate::devices::{Decoder, DecoderStats};
use crate::executive::TaskContext;
use crate::logfmt::format::Format;
use crate::logfmt::record::{EncodeError, LogFormat};

pub const DEVICE_STATUS_LOG: LogFormat = LogFormat::new(
    "%u,%u,%u,%u,%u,%u,%u,%u,%u,%hhu",
    "frames,bad_checksum,framing_errors,overflows,bytes_discarded,invalid_payload,ignored,\
     sequence_gaps,stale_events,stale",
);

const INTERVAL_NS: u64 = 1_000_000_000;

/// The degraded reason a device task sets in its health while its device is stale.
pub const DEVICE_STALE: &str = "device stale";

/// The status record of one device task.
pub struct DeviceStatusLog {
    index: u8,
    format: Format,
    next_ns: u64,
}

impl DeviceStatusLog {
    pub const fn new(index: u8) -> Self {
        Self {
            index,
            format: Format::EMPTY,
            next_ns: 0,
        }
    }

    pub fn declare<S: RecordSink>(
        &mut self,
        log: &mut TaskLog<S>,
        cx: &TaskContext<'_>,
    ) -> Result<(), EncodeError> {
        self.format = log.declare(cx, self.index, &DEVICE_STATUS_LOG)?;
        self.next_ns = cx.now_ns;
        Ok(())
    }

    /// The end of every step: the task is degraded while its device is stale, and the
    /// counters go into the log once a second.
    pub fn after_step<S: RecordSink, D: Decoder>(
        &mut self,
        log: &mut TaskLog<S>,
        cx: &TaskContext<'_>,
        decoder: &D,
    ) {
        let stale = decoder.is_stale(cx.now_ns);
        cx.health
            .set_degraded(cx.task, stale.then_some(DEVICE_STALE));
        self.maybe_log(log, cx, decoder.stats(), stale, false);
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
        log.record(cx, self.index, &self.format, |w| {
            w.u32(stats.frames)
                .u32(stats.bad_checksum)
                .u32(stats.framing_errors)
                .u32(stats.overflows)
                .u32(stats.bytes_discarded)
                .u32(stats.invalid_payload)
                .u32(stats.ignored)
                .u32(stats.sequence_gaps)
                .u32(stats.stale_events)
                .u8(u8::from(stale))
        });
    }
}

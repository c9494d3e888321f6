//! The executive's log, `executive.bin`: one [`FrameRecord`] a minor frame (the frame's
//! timing) in their own format, and the start-up timer check; read back by `skyframe-log`
//! and the frame-overrun report tool. One name for each: the record is a frame record, the
//! stream the executive log.

use crate::host::{TimerCheck, TimingSink};
use crate::logwriter::LogStream;
use skyframe_core::executive::FrameRecord;
use skyframe_core::logfmt::frame_records::{FrameRecordFormat, encode_frame_record};
use skyframe_core::logfmt::record::{MAX_RECORD_LEN, encode_begin_data, encode_end_data};
use skyframe_core::logfmt::{LogRecord, encode_record};
use skyframe_core::schedule::FrameTable;

/// Format index of the timing records in the executive's log file.
pub const TIMING_FORMAT_INDEX: u8 = 1;

/// Format index of the start-up timer check (one record, before the first frame's).
pub const TIMER_CHECK_FORMAT_INDEX: u8 = 2;

skyframe_core::log_record! {
    /// The start-up timer check: how late `samples` wake-ups of period `period_us` were,
    /// against the frame margin; `over_margin` 1 when the worst ate the whole margin.
    pub struct TimerCheckLog {
        period_us: u32 = "%u",
        samples: u32 = "%u",
        wakeup_latency_mean_us: f32 = "%.1f",
        wakeup_latency_p50_us: f32 = "%.1f",
        wakeup_latency_p99_us: f32 = "%.1f",
        wakeup_latency_p999_us: f32 = "%.1f",
        wakeup_latency_max_us: f32 = "%.1f",
        margin_us: f32 = "%.1f",
        over_margin: bool = "%hhu",
    }
}

pub struct ExecutiveLog {
    stream: LogStream,
    format: FrameRecordFormat,
    /// Log TIME = this + the executive's clock: wall clock on a vehicle, 0 in virtual time.
    time_origin_ns: u64,
    buf: Vec<u8>,
    last_t_ns: u64,
}

impl ExecutiveLog {
    /// Declares the format and begins the data.
    pub fn start(
        stream: LogStream,
        table: &FrameTable,
        time_origin_ns: u64,
        t_ns: u64,
    ) -> Result<Self, String> {
        let format =
            FrameRecordFormat::new(table.tasks).map_err(|e| format!("timing log format: {e:?}"))?;
        let mut log = Self {
            stream,
            format,
            time_origin_ns,
            buf: vec![0; MAX_RECORD_LEN],
            last_t_ns: t_ns,
        };
        let n = log
            .format
            .encode_declaration(&mut log.buf, TIMING_FORMAT_INDEX)
            .map_err(|e| format!("timing log declaration: {e:?}"))?;
        log.push(n);
        let n =
            encode_begin_data(&mut log.buf, time_origin_ns + t_ns).map_err(|e| format!("{e:?}"))?;
        log.push(n);
        Ok(log)
    }

    fn push(&mut self, n: usize) {
        if let Some(record) = self.buf.get(..n) {
            self.stream.push_record(record);
        }
    }

    /// Logs one frame; a record that does not fit the ring is counted by the stream.
    pub fn record(&mut self, r: &FrameRecord) {
        let t = r.release_ns + u64::from(r.start_latency_ns) + u64::from(r.work_ns);
        self.last_t_ns = t;
        if let Ok(n) = encode_frame_record(
            &mut self.buf,
            TIMING_FORMAT_INDEX,
            self.time_origin_ns + t,
            &self.format,
            r,
        ) {
            self.push(n);
        }
    }

    /// Logs the start-up timer check, stamped with the time the first frame is due.
    pub fn timer_check(&mut self, check: &TimerCheck) {
        let Ok(n) =
            TimerCheckLog::FORMAT.encode_declaration(&mut self.buf, TIMER_CHECK_FORMAT_INDEX)
        else {
            return;
        };
        self.push(n);
        let latency = &check.wakeup_latency_us;
        let record = TimerCheckLog {
            period_us: u32::try_from(check.period_us).unwrap_or(u32::MAX),
            samples: u32::try_from(latency.count).unwrap_or(u32::MAX),
            wakeup_latency_mean_us: latency.mean as f32,
            wakeup_latency_p50_us: latency.p50 as f32,
            wakeup_latency_p99_us: latency.p99 as f32,
            wakeup_latency_p999_us: latency.p999 as f32,
            wakeup_latency_max_us: latency.max as f32,
            margin_us: check.margin_us as f32,
            over_margin: check.over_margin,
        };
        let t_ns = self.time_origin_ns + self.last_t_ns;
        if let Ok(n) = encode_record(&mut self.buf, TIMER_CHECK_FORMAT_INDEX, t_ns, &record) {
            self.push(n);
        }
    }

    /// Ends the data (End Data at the last frame's time).
    pub fn finish(mut self) {
        if let Ok(n) = encode_end_data(&mut self.buf, self.time_origin_ns + self.last_t_ns) {
            self.push(n);
        }
    }
}

impl TimingSink for &mut ExecutiveLog {
    fn frame(&mut self, record: &FrameRecord) {
        self.record(record);
    }

    fn timer_check(&mut self, check: &TimerCheck) {
        ExecutiveLog::timer_check(self, check);
    }
}

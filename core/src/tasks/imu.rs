//! The IMU task: drains the IMU's bytes, publishes each sample for the estimator, logs fast
//! frames and slow records (`docs/log-streams.md`, `imu.bin`).

use super::device_status::DeviceStatusLog;
use super::task_log::TaskLog;
use crate::comm::{LatestSlot, RecordSink};
use crate::devices::imu::{ImuDecoder, ImuFrame, ImuSample};
use crate::devices::port::drain;
use crate::devices::{Decoder, DecoderStats};
use crate::executive::{Task, TaskContext, TaskFault};
use crate::logfmt::format::Format;
use crate::logfmt::record::LogFormat;
use embedded_io::{Read, ReadReady};

pub const IMU_FAST_LOG: LogFormat = LogFormat::new(
    "%hhu,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%hhu",
    "counter,p_rad_s,q_rad_s,r_rad_s,fx_m_s2,fy_m_s2,fz_m_s2,status",
);
pub const IMU_SLOW_LOG: LogFormat = LogFormat::new(
    "%hu,%.2f,%.3f,%hu,%.5f,%.5f,%.5f,%.4f,%.4f,%.4f,%hu",
    "record_counter,temperature_c,supply_v,serial_number,mean_p_rad_s,mean_q_rad_s,\
     mean_r_rad_s,mean_fx_m_s2,mean_fy_m_s2,mean_fz_m_s2,built_in_test",
);
pub const FAST_INDEX: u8 = 1;
pub const SLOW_INDEX: u8 = 2;
pub const STATUS_INDEX: u8 = 3;

/// Bytes taken from the port per step: 24 frames' worth, so a babbling line cannot eat the
/// frame (the rest waits in the ring for the next step).
pub const MAX_BYTES_PER_STEP: usize = 512;

pub struct ImuTask<'a, P, S: RecordSink> {
    port: P,
    decoder: ImuDecoder,
    log: TaskLog<S>,
    fast: Format,
    slow: Format,
    status: DeviceStatusLog,
    samples: &'a LatestSlot<ImuSample>,
}

impl<'a, P: Read + ReadReady, S: RecordSink> ImuTask<'a, P, S> {
    pub fn new(port: P, log: S, stale_timeout_ns: u64, samples: &'a LatestSlot<ImuSample>) -> Self {
        Self {
            port,
            decoder: ImuDecoder::new(stale_timeout_ns),
            log: TaskLog::new(log),
            fast: Format::EMPTY,
            slow: Format::EMPTY,
            status: DeviceStatusLog::new(STATUS_INDEX),
            samples,
        }
    }

    pub fn stats(&self) -> &DecoderStats {
        self.decoder.stats()
    }

    pub fn is_stale(&self, now_ns: u64) -> bool {
        self.decoder.is_stale(now_ns)
    }
}

impl<P: Read + ReadReady, S: RecordSink> Task for ImuTask<'_, P, S> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let bad = |_| TaskFault::new("imu log format");
        self.fast = self
            .log
            .declare(cx, FAST_INDEX, &IMU_FAST_LOG)
            .map_err(bad)?;
        self.slow = self
            .log
            .declare(cx, SLOW_INDEX, &IMU_SLOW_LOG)
            .map_err(bad)?;
        self.status.declare(&mut self.log, cx).map_err(bad)?;
        self.log.begin(cx);
        Ok(())
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let cx = &*cx;
        let Self {
            port,
            decoder,
            log,
            fast,
            slow,
            samples,
            ..
        } = self;
        let drained = drain(
            port,
            decoder,
            cx.now_ns,
            MAX_BYTES_PER_STEP,
            &mut |frame| match frame {
                ImuFrame::Sample(sample) => {
                    samples.publish(sample);
                    let m = sample.measurement;
                    log.record(cx, FAST_INDEX, fast, |w| {
                        w.u8(sample.counter)
                            .f32(m.rate_radps[0])
                            .f32(m.rate_radps[1])
                            .f32(m.rate_radps[2])
                            .f32(m.specific_force_mps2[0])
                            .f32(m.specific_force_mps2[1])
                            .f32(m.specific_force_mps2[2])
                            .u8(m.status.0)
                    });
                }
                ImuFrame::Slow(frame) => {
                    let r = frame.record;
                    log.record(cx, SLOW_INDEX, slow, |w| {
                        w.u16(r.record_counter)
                            .f32(r.temperature_c)
                            .f32(r.supply_v)
                            .u16(r.serial_number)
                            .f32(r.mean_rate_radps[0])
                            .f32(r.mean_rate_radps[1])
                            .f32(r.mean_rate_radps[2])
                            .f32(r.mean_specific_force_mps2[0])
                            .f32(r.mean_specific_force_mps2[1])
                            .f32(r.mean_specific_force_mps2[2])
                            .u16(r.built_in_test)
                    });
                }
            },
        );
        self.status.after_step(&mut self.log, cx, &self.decoder);
        drained
            .map(|_| ())
            .map_err(|_| TaskFault::new("imu port error"))
    }

    /// The decoder resynchronises by itself and its counters must survive a reset, so
    /// recovering only closes this logging section; `init` opens the next.
    fn recover(&mut self, cx: &mut TaskContext<'_>) {
        self.status.close(&mut self.log, cx, &self.decoder);
    }

    fn shutdown(&mut self, cx: &mut TaskContext<'_>) {
        self.status.close(&mut self.log, cx, &self.decoder);
    }
}

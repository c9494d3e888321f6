//! The IMU task: drains the IMU's bytes, publishes each sample for the estimator, logs fast
//! frames and slow records (`docs/log-streams.md`, `imu.bin`).

use super::device_status::DeviceStatusLog;
use super::task_log::TaskLog;
use crate::comm::LatestSlot;
use crate::devices::imu::{ImuDecoder, ImuFrame, ImuSample};
use crate::devices::port::drain;
use crate::devices::{Decoder, DecoderStats};
use crate::executive::{Task, TaskContext, TaskFault};
use crate::logfmt::RecordSink;
use embedded_io::{Read, ReadReady};

crate::log_record! {
    /// Each 100 Hz frame (format 1).
    pub struct ImuFastLog {
        counter: u8 = "%hhu",
        p_rad_s: f32 = "%.4f",
        q_rad_s: f32 = "%.4f",
        r_rad_s: f32 = "%.4f",
        fx_m_s2: f32 = "%.4f",
        fy_m_s2: f32 = "%.4f",
        fz_m_s2: f32 = "%.4f",
        status: u8 = "%hhu",
    }
}
crate::log_record! {
    /// Each slow record (format 2).
    pub struct ImuSlowLog {
        record_counter: u16 = "%hu",
        temperature_c: f32 = "%.2f",
        supply_v: f32 = "%.3f",
        serial_number: u16 = "%hu",
        mean_p_rad_s: f32 = "%.5f",
        mean_q_rad_s: f32 = "%.5f",
        mean_r_rad_s: f32 = "%.5f",
        mean_fx_m_s2: f32 = "%.4f",
        mean_fy_m_s2: f32 = "%.4f",
        mean_fz_m_s2: f32 = "%.4f",
        built_in_test: u16 = "%hu",
    }
}
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
    status: DeviceStatusLog,
    samples: &'a LatestSlot<ImuSample>,
}

impl<'a, P: Read + ReadReady, S: RecordSink> ImuTask<'a, P, S> {
    pub fn new(port: P, log: S, stale_timeout_ns: u64, samples: &'a LatestSlot<ImuSample>) -> Self {
        Self {
            port,
            decoder: ImuDecoder::new(stale_timeout_ns),
            log: TaskLog::new(log),
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
        self.status
            .open(&mut self.log, cx, "imu log format", |log| {
                log.declare::<ImuFastLog>(cx, FAST_INDEX)?;
                log.declare::<ImuSlowLog>(cx, SLOW_INDEX)
            })
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let cx = &*cx;
        let Self {
            port,
            decoder,
            log,
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
                    let [p_rad_s, q_rad_s, r_rad_s] = m.rate_radps;
                    let [fx_m_s2, fy_m_s2, fz_m_s2] = m.specific_force_mps2;
                    let record = ImuFastLog {
                        counter: sample.counter,
                        p_rad_s,
                        q_rad_s,
                        r_rad_s,
                        fx_m_s2,
                        fy_m_s2,
                        fz_m_s2,
                        status: m.status.0,
                    };
                    log.log(cx, FAST_INDEX, &record);
                }
                ImuFrame::Slow(frame) => {
                    let r = frame.record;
                    let [mean_p_rad_s, mean_q_rad_s, mean_r_rad_s] = r.mean_rate_radps;
                    let [mean_fx_m_s2, mean_fy_m_s2, mean_fz_m_s2] = r.mean_specific_force_mps2;
                    let record = ImuSlowLog {
                        record_counter: r.record_counter,
                        temperature_c: r.temperature_c,
                        supply_v: r.supply_v,
                        serial_number: r.serial_number,
                        mean_p_rad_s,
                        mean_q_rad_s,
                        mean_r_rad_s,
                        mean_fx_m_s2,
                        mean_fy_m_s2,
                        mean_fz_m_s2,
                        built_in_test: r.built_in_test,
                    };
                    log.log(cx, SLOW_INDEX, &record);
                }
            },
        );
        self.status
            .after_step(&mut self.log, cx, &self.decoder, drained, "imu port error")
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

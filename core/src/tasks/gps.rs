//! The GPS task: drains the receiver's sentences, publishes each epoch's fix for the
//! estimator, logs it (`docs/log-streams.md`, `gps.bin`). A value the receiver did not give
//! is logged as NaN (or the integer field's "unknown" value) so columns never shift.

use super::device_status::DeviceStatusLog;
use super::task_log::TaskLog;
use crate::comm::LatestSlot;
use crate::devices::DecoderStats;
use crate::devices::gps::{GpsConfig, GpsFix, NmeaDecoder};
use crate::devices::port::drain;
use crate::executive::{Task, TaskContext, TaskFault};
use crate::logfmt::RecordSink;
use embedded_io::{Read, ReadReady};

crate::log_record! {
    /// Each fix the receiver completes (format 1); unknown values are NaN or the all-ones
    /// integer.
    pub struct GpsFixLog {
        valid: bool = "%hhu",
        quality: u8 = "%hhu",
        satellites: u8 = "%hhu",
        lat_deg: f64 = "%.8lf",
        lon_deg: f64 = "%.8lf",
        alt_m: f64 = "%.3lf",
        vn_m_s: f32 = "%.3f",
        ve_m_s: f32 = "%.3f",
        vd_m_s: f32 = "%.3f",
        pdop: f32 = "%.2f",
        hdop: f32 = "%.2f",
        vdop: f32 = "%.2f",
        sd_n_m: f32 = "%.3f",
        sd_e_m: f32 = "%.3f",
        sd_d_m: f32 = "%.3f",
        utc_ms: u32 = "%u",
    }
}
pub const FIX_INDEX: u8 = 1;
pub const STATUS_INDEX: u8 = 2;

/// "Not reported" for the small integer columns.
pub const UNKNOWN_U8: u8 = u8::MAX;
pub const UNKNOWN_U32: u32 = u32::MAX;

/// A 10 Hz receiver sends ~450 bytes per epoch; a 100 ms step may see two epochs at once.
pub const MAX_BYTES_PER_STEP: usize = 2048;

pub struct GpsTask<'a, P, S: RecordSink> {
    port: P,
    decoder: NmeaDecoder,
    log: TaskLog<S>,
    status: DeviceStatusLog,
    fixes: &'a LatestSlot<GpsFix>,
}

impl<'a, P: Read + ReadReady, S: RecordSink> GpsTask<'a, P, S> {
    pub fn new(port: P, log: S, config: GpsConfig, fixes: &'a LatestSlot<GpsFix>) -> Self {
        Self {
            port,
            decoder: NmeaDecoder::new(config),
            log: TaskLog::new(log),
            status: DeviceStatusLog::new(STATUS_INDEX),
            fixes,
        }
    }

    pub fn stats(&self) -> &DecoderStats {
        self.decoder.stats()
    }
}

fn or_nan32(v: Option<f32>) -> f32 {
    v.unwrap_or(f32::NAN)
}

fn or_nan64(v: Option<f64>) -> f64 {
    v.unwrap_or(f64::NAN)
}

impl<P: Read + ReadReady, S: RecordSink> Task for GpsTask<'_, P, S> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        self.status
            .open(&mut self.log, cx, "gps log format", |log| {
                log.declare::<GpsFixLog>(cx, FIX_INDEX)
            })
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let cx = &*cx;
        let Self {
            port,
            decoder,
            log,
            fixes,
            ..
        } = self;
        let drained = drain(
            port,
            decoder,
            cx.now_ns,
            MAX_BYTES_PER_STEP,
            &mut |fix: GpsFix| {
                fixes.publish(fix);
                let [vn, ve, vd] = fix.velocity_ned_mps;
                let [sd_n, sd_e, sd_d] = fix.position_sd_m;
                let record = GpsFixLog {
                    valid: fix.valid,
                    quality: fix.quality.map_or(UNKNOWN_U8, |q| q.gga_code()),
                    satellites: fix.satellites.unwrap_or(UNKNOWN_U8),
                    lat_deg: or_nan64(fix.latitude_deg),
                    lon_deg: or_nan64(fix.longitude_deg),
                    alt_m: or_nan64(fix.altitude_msl_m),
                    vn_m_s: or_nan32(vn),
                    ve_m_s: or_nan32(ve),
                    vd_m_s: or_nan32(vd),
                    pdop: or_nan32(fix.pdop),
                    hdop: or_nan32(fix.hdop),
                    vdop: or_nan32(fix.vdop),
                    sd_n_m: or_nan32(sd_n),
                    sd_e_m: or_nan32(sd_e),
                    sd_d_m: or_nan32(sd_d),
                    utc_ms: fix.utc_time_ms.unwrap_or(UNKNOWN_U32),
                };
                log.log(cx, FIX_INDEX, &record);
            },
        );
        self.status
            .after_step(&mut self.log, cx, &self.decoder, drained, "gps port error")
    }

    fn recover(&mut self, cx: &mut TaskContext<'_>) {
        self.status.close(&mut self.log, cx, &self.decoder);
    }

    fn shutdown(&mut self, cx: &mut TaskContext<'_>) {
        self.recover(cx);
    }
}

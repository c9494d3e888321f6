//! `skyframe bench parsers`: decoder throughput on synthetic but protocol-exact streams, and
//! for GGA/RMC the `nmea` crate's on the same bytes in the same run.
//!
//! The streams are made with the devices' own encoders (`docs/protocols.md`), a few percent
//! garbage mixed into each so resynchronisation is part of what is measured. Throughput is
//! the best of several passes (the least disturbed by the rest of the machine).

use serde::Serialize;
use skyframe_core::devices::Decoder;
use skyframe_core::devices::gps::{
    GpsConfig, GpsFix, NmeaDecoder, SentenceKind, Talker, encode_sentence,
};
use skyframe_core::devices::imu::{
    IMU_FRAME_LEN, ImuDecoder, ImuMeasurement, ImuStatus, SlowSlot, encode_imu_frame,
};
use skyframe_core::devices::servo::{
    BoardStatus, PILOT_FRAME_LEN, PilotReport, ServoDecoder, encode_pilot_frame,
};
use std::time::Instant;

const PASSES: usize = 5;

#[derive(Debug, Serialize)]
pub struct DecoderFigures {
    pub bytes: usize,
    pub frames: u64,
    pub mb_per_s: f64,
}

#[derive(Debug, Serialize)]
pub struct NmeaComparison {
    pub bytes: usize,
    pub sentences: u64,
    pub ours_mb_per_s: f64,
    pub nmea_crate_mb_per_s: f64,
    /// Ours / nmea crate: above 1 means ours is faster.
    pub ratio: f64,
}

#[derive(Debug, Serialize)]
pub struct ParserBench {
    pub imu: DecoderFigures,
    pub servo: DecoderFigures,
    /// GGA, RMC, VTG, GSA, GST and $PASHR,POS.
    pub gps_all_sentences: DecoderFigures,
    /// GGA and RMC only: what the `nmea` crate parses too.
    pub gga_rmc: NmeaComparison,
}

/// Best throughput of `PASSES` runs of `decode` over `bytes`; `decode` returns frames found.
fn best(bytes: &[u8], mut decode: impl FnMut(&[u8]) -> u64) -> DecoderFigures {
    let mut best_s = f64::INFINITY;
    let mut frames = 0;
    for _ in 0..PASSES {
        let start = Instant::now();
        frames = std::hint::black_box(decode(std::hint::black_box(bytes)));
        best_s = best_s.min(start.elapsed().as_secs_f64());
    }
    DecoderFigures {
        bytes: bytes.len(),
        frames,
        mb_per_s: bytes.len() as f64 / 1e6 / best_s.max(1e-9),
    }
}

/// Feeds `bytes` in 64-byte chunks, as `port::drain` does.
fn decode_all<D: Decoder>(mut decoder: D, bytes: &[u8]) -> u64 {
    let mut frames = 0u64;
    for chunk in bytes.chunks(64) {
        decoder.push(chunk, 0, &mut |_| frames += 1);
    }
    frames
}

fn imu_stream(frames: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(frames * (IMU_FRAME_LEN + 2));
    for n in 0..frames {
        let m = ImuMeasurement {
            rate_radps: [0.01 * (n % 100) as f32, -0.2, 0.05],
            specific_force_mps2: [0.3, -0.1, -9.80665],
            status: ImuStatus(0),
        };
        let mut frame = [0u8; IMU_FRAME_LEN];
        encode_imu_frame(
            n as u8,
            &m,
            SlowSlot {
                index: (n % 100) as u8,
                byte: n as u8,
            },
            &mut frame,
        );
        out.extend_from_slice(&frame);
        if n % 50 == 49 {
            out.extend_from_slice(&[0xA5, 0x00]);
        }
    }
    out
}

fn servo_stream(frames: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(frames * (PILOT_FRAME_LEN + 2));
    for n in 0..frames {
        let report = PilotReport {
            pilot_us: [
                1500 + (n % 400) as u16,
                1500,
                1100,
                1500,
                1500,
                1500,
                1500,
                1500,
            ],
            switch_us: 1000,
            logic_battery_v: 12.0,
            servo_battery_v: 5.0,
            status: BoardStatus(0),
        };
        let mut frame = [0u8; PILOT_FRAME_LEN];
        encode_pilot_frame(n as u8, &report, &mut frame);
        out.extend_from_slice(&frame);
        if n % 50 == 49 {
            out.extend_from_slice(&[0xA5, 0x00]);
        }
    }
    out
}

fn gps_stream(epochs: usize, kinds: &[SentenceKind]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut buf = [0u8; 160];
    for n in 0..epochs {
        let fix = GpsFix {
            utc_time_ms: Some(((n * 100) % 86_400_000) as u32),
            valid: true,
            satellites: Some(9),
            latitude_deg: Some(42.36 + n as f64 * 1e-6),
            longitude_deg: Some(-71.09),
            altitude_msl_m: Some(120.5),
            altitude_ellipsoid_m: Some(92.0),
            geoid_separation_m: Some(-28.5),
            ground_speed_mps: Some(25.0),
            course_rad: Some(1.2),
            velocity_ned_mps: [Some(9.0), Some(23.3), Some(-0.4)],
            pdop: Some(1.8),
            hdop: Some(0.9),
            vdop: Some(1.5),
            position_sd_m: [Some(1.2), Some(1.1), Some(2.5)],
            ..GpsFix::default()
        };
        for &kind in kinds {
            if let Some(len) = encode_sentence(kind, Talker::Gp, &fix, &mut buf) {
                out.extend_from_slice(buf.get(..len).unwrap_or_default());
            }
        }
        if n % 50 == 49 {
            out.extend_from_slice(b"$GP\x01\r\n");
        }
    }
    out
}

/// Runs the bench on streams of about `megabytes` each (5 gives steady figures).
pub fn run(megabytes: f64) -> ParserBench {
    let scale = (megabytes.max(0.01) / 5.0).min(100.0);
    let count = |n: f64| ((n * scale) as usize).max(200);
    let imu = imu_stream(count(240_000.0));
    let servo = servo_stream(count(170_000.0));
    let gps_all = gps_stream(count(14_000.0), &SentenceKind::ALL);
    let gga_rmc = gps_stream(count(34_000.0), &[SentenceKind::Gga, SentenceKind::Rmc]);

    let imu_figures = best(&imu, |b| decode_all(ImuDecoder::new(u64::MAX), b));
    let servo_figures = best(&servo, |b| decode_all(ServoDecoder::new(u64::MAX), b));
    let gps_figures = best(&gps_all, |b| {
        decode_all(NmeaDecoder::new(GpsConfig::default()), b)
    });
    let ours = best(&gga_rmc, |b| {
        decode_all(NmeaDecoder::new(GpsConfig::default()), b)
    });
    // The crate takes one sentence at a time: splitting the lines is part of its work, as
    // assembling them is part of ours.
    let theirs = best(&gga_rmc, |b| {
        let text = std::str::from_utf8(b).unwrap_or_default();
        text.lines()
            .filter(|line| nmea::parse_str(line).is_ok())
            .count() as u64
    });
    ParserBench {
        imu: imu_figures,
        servo: servo_figures,
        gps_all_sentences: gps_figures,
        gga_rmc: NmeaComparison {
            bytes: gga_rmc.len(),
            sentences: theirs.frames,
            ours_mb_per_s: ours.mb_per_s,
            nmea_crate_mb_per_s: theirs.mb_per_s,
            ratio: ours.mb_per_s / theirs.mb_per_s.max(1e-9),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_decode_to_what_was_encoded() {
        // 500 fast frames and the 5 slow records they carry.
        assert_eq!(decode_all(ImuDecoder::new(u64::MAX), &imu_stream(500)), 505);
        assert_eq!(
            decode_all(ServoDecoder::new(u64::MAX), &servo_stream(500)),
            500
        );
        // Epochs end when the next one starts: the last stays open.
        let gga_rmc = gps_stream(100, &[SentenceKind::Gga, SentenceKind::Rmc]);
        assert_eq!(
            decode_all(NmeaDecoder::new(GpsConfig::default()), &gga_rmc),
            99
        );
        let text = std::str::from_utf8(&gga_rmc).expect("ascii");
        let parsed = text.lines().filter(|l| nmea::parse_str(l).is_ok()).count();
        assert_eq!(parsed, 200, "the crate reads every GGA and RMC we wrote");
    }
}

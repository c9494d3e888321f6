use super::*;
use crate::devices::framing::{SYNC, crc16};
use crate::devices::test_support::{decode_chunked, decode_whole};
use proptest::prelude::*;
use std::vec::Vec;

const G: f32 = 9.80665;

fn at_rest() -> ImuMeasurement {
    ImuMeasurement {
        rate_radps: [0.01, -0.02, 0.5],
        specific_force_mps2: [0.0, 0.0, -G],
        status: ImuStatus::default(),
    }
}

fn frame(counter: u8, measurement: &ImuMeasurement, slot: SlowSlot) -> [u8; IMU_FRAME_LEN] {
    let mut out = [0u8; IMU_FRAME_LEN];
    assert_eq!(
        encode_imu_frame(counter, measurement, slot, &mut out),
        IMU_FRAME_LEN
    );
    out
}

fn samples(frames: &[ImuFrame]) -> Vec<ImuSample> {
    frames
        .iter()
        .filter_map(|frame| match frame {
            ImuFrame::Sample(sample) => Some(*sample),
            ImuFrame::Slow(_) => None,
        })
        .collect()
}

fn slow_records(frames: &[ImuFrame]) -> Vec<ImuSlowRecord> {
    frames
        .iter()
        .filter_map(|frame| match frame {
            ImuFrame::Slow(slow) => Some(slow.record),
            ImuFrame::Sample(_) => None,
        })
        .collect()
}

fn stream(frames: usize) -> Vec<u8> {
    let mut encoder = ImuStreamEncoder::new();
    encoder.set_slow_record(&example_record());
    let mut bytes = Vec::new();
    for _ in 0..frames {
        let mut out = [0u8; IMU_FRAME_LEN];
        let len = encoder.encode(&at_rest(), &mut out);
        bytes.extend_from_slice(&out[..len]);
    }
    bytes
}

fn example_record() -> ImuSlowRecord {
    ImuSlowRecord {
        record_counter: 7,
        temperature_c: 31.25,
        supply_v: 5.012,
        serial_number: 4242,
        mean_rate_radps: [1.5e-5, -2.25e-4, 0.001],
        mean_specific_force_mps2: [0.01234, -0.00567, -G],
        built_in_test: 0,
    }
}

#[test]
fn crc_is_ccitt_false() {
    assert_eq!(crc16(b"123456789"), 0x29B1);
}

/// The worked example in docs/protocols.md, "IMU fast frame".
#[test]
fn documented_example_frame() {
    let measurement = ImuMeasurement {
        rate_radps: [0.1, -0.2, 0.05],
        specific_force_mps2: [0.0, 0.0, -G],
        status: ImuStatus::default(),
    };
    let bytes = frame(
        0x2A,
        &measurement,
        SlowSlot {
            index: 3,
            byte: 0x7F,
        },
    );
    let expected: [u8; IMU_FRAME_LEN] = [
        0xA5, 0x49, 0x0F, 0x2A, // sync, type 'I', length 15, counter 42
        0x64, 0x00, 0x38, 0xFF, 0x32, 0x00, // p = 100, q = -200, r = 50 (× 1e-3 rad/s)
        0x00, 0x00, 0x00, 0x00, 0x57, 0xF8, // fx = 0, fy = 0, fz = -1961 (× 5e-3 m/s²)
        0x00, 0x03, 0x7F, // status, slot index 3, slot byte 0x7F
        0xF9, 0x03, // CRC-16/CCITT-FALSE 0x03F9, little-endian
    ];
    assert_eq!(bytes, expected, "{bytes:02X?}");
}

#[test]
fn level_at_rest_round_trips_within_half_a_step() {
    let mut decoder = ImuDecoder::default();
    let bytes = frame(5, &at_rest(), SlowSlot::default());
    let frames = decode_whole(&mut decoder, &bytes, 1_000);
    let [ImuFrame::Sample(sample)] = frames.as_slice() else {
        panic!("one sample expected, got {frames:?}");
    };
    assert_eq!(sample.counter, 5);
    assert_eq!(sample.received_ns, 1_000);
    for (decoded, sent) in sample
        .measurement
        .rate_radps
        .iter()
        .zip(at_rest().rate_radps)
    {
        assert!((decoded - sent).abs() <= RATE_LSB_RADPS / 2.0);
    }
    let force = sample.measurement.specific_force_mps2;
    assert_eq!(force[0], 0.0);
    assert_eq!(force[1], 0.0);
    assert!((force[2] + G).abs() <= SPECIFIC_FORCE_LSB_MPS2 / 2.0);
    assert_eq!(decoder.stats().frames, 1);
    assert_eq!(decoder.stats().problems(), 0);
}

#[test]
fn out_of_range_values_saturate_instead_of_wrapping() {
    let wild = ImuMeasurement {
        rate_radps: [1e9, -1e9, f32::NAN],
        specific_force_mps2: [500.0, -500.0, 0.0],
        status: ImuStatus(ImuStatus::GYRO_SATURATED | ImuStatus::ACCEL_SATURATED),
    };
    let frames = decode_whole(
        &mut ImuDecoder::default(),
        &frame(0, &wild, SlowSlot::default()),
        0,
    );
    let sample = samples(&frames)[0];
    assert_eq!(
        sample.measurement.rate_radps,
        [32767.0 * RATE_LSB_RADPS, -32768.0 * RATE_LSB_RADPS, 0.0]
    );
    assert!(sample.measurement.specific_force_mps2[0] > 163.0);
    assert!(sample.measurement.status.gyro_saturated());
    assert!(sample.measurement.status.accel_saturated());
    assert!(!sample.measurement.status.built_in_test_failed());
}

#[test]
fn bad_checksum_is_counted_and_the_next_frame_still_decodes() {
    let mut corrupted = frame(1, &at_rest(), SlowSlot::default());
    corrupted[6] ^= 0x01;
    let mut bytes = corrupted.to_vec();
    bytes.extend_from_slice(&frame(2, &at_rest(), SlowSlot::default()));
    let mut decoder = ImuDecoder::default();
    let frames = decode_whole(&mut decoder, &bytes, 0);
    assert_eq!(samples(&frames).len(), 1);
    assert_eq!(samples(&frames)[0].counter, 2);
    assert_eq!(decoder.stats().bad_checksum, 1);
    assert_eq!(decoder.stats().bytes_discarded, IMU_FRAME_LEN as u32);
}

#[test]
fn resynchronises_after_garbage_containing_sync_bytes() {
    let mut bytes = std::vec![0x00, SYNC, 0x13, SYNC, SYNC, IMU_FRAME_TYPE, 0x99, 0xFF];
    let garbage_len = bytes.len();
    bytes.extend_from_slice(&frame(9, &at_rest(), SlowSlot::default()));
    let mut decoder = ImuDecoder::default();
    let frames = decode_whole(&mut decoder, &bytes, 0);
    assert_eq!(samples(&frames).len(), 1);
    let stats = decoder.stats();
    assert_eq!(stats.frames, 1);
    assert_eq!(stats.bytes_discarded, garbage_len as u32);
    // `A5 13` and `A5 A5` are impossible headers; `A5 49 99` claims a 153-byte payload.
    assert_eq!(stats.framing_errors, 2);
    assert_eq!(stats.overflows, 1);
}

#[test]
fn a_frame_hidden_inside_a_truncated_one_is_found() {
    // A frame cut short by a lost byte run, then a complete frame: the complete one starts
    // inside what the decoder first took for the truncated frame's payload.
    let truncated = &frame(1, &at_rest(), SlowSlot::default())[..10];
    let mut bytes = truncated.to_vec();
    bytes.extend_from_slice(&frame(2, &at_rest(), SlowSlot::default()));
    let mut decoder = ImuDecoder::default();
    let frames = decode_whole(&mut decoder, &bytes, 0);
    assert_eq!(samples(&frames).len(), 1);
    assert_eq!(samples(&frames)[0].counter, 2);
    assert_eq!(decoder.stats().bad_checksum, 1);
    assert_eq!(decoder.stats().bytes_discarded, 10);
}

#[test]
fn length_byte_beyond_the_buffer_counts_as_overflow() {
    let mut bytes = std::vec![SYNC, IMU_FRAME_TYPE, 0xFF];
    bytes.extend_from_slice(&frame(0, &at_rest(), SlowSlot::default()));
    let mut decoder = ImuDecoder::default();
    let frames = decode_whole(&mut decoder, &bytes, 0);
    assert_eq!(samples(&frames).len(), 1);
    assert_eq!(decoder.stats().overflows, 1);
    assert_eq!(decoder.stats().bytes_discarded, 3);
}

#[test]
fn counter_jumps_count_as_sequence_gaps() {
    let mut bytes = Vec::new();
    for counter in [254u8, 255, 0, 3, 4] {
        bytes.extend_from_slice(&frame(counter, &at_rest(), SlowSlot::default()));
    }
    let mut decoder = ImuDecoder::default();
    decode_whole(&mut decoder, &bytes, 0);
    assert_eq!(decoder.stats().frames, 5);
    assert_eq!(
        decoder.stats().sequence_gaps,
        1,
        "wrap 255 → 0 is not a gap"
    );
}

#[test]
fn slow_record_is_rebuilt_from_100_frames() {
    let bytes = stream(2 * SLOW_RECORD_LEN);
    let mut decoder = ImuDecoder::default();
    let frames = decode_whole(&mut decoder, &bytes, 0);
    assert_eq!(samples(&frames).len(), 200);
    let records = slow_records(&frames);
    assert_eq!(records.len(), 2);
    let sent = example_record();
    for record in records {
        assert_eq!(record.record_counter, sent.record_counter);
        assert_eq!(record.serial_number, sent.serial_number);
        assert!((record.temperature_c - sent.temperature_c).abs() < 0.006);
        assert!((record.supply_v - sent.supply_v).abs() < 0.0006);
        for (got, want) in record.mean_rate_radps.iter().zip(sent.mean_rate_radps) {
            assert!((got - want).abs() <= 6e-7, "{got} vs {want}");
        }
        for (got, want) in record
            .mean_specific_force_mps2
            .iter()
            .zip(sent.mean_specific_force_mps2)
        {
            assert!((got - want).abs() <= 6e-6, "{got} vs {want}");
        }
    }
    // The record follows the sample that completed it.
    assert!(matches!(frames[100], ImuFrame::Slow(_)));
    assert_eq!(decoder.slow_records_dropped(), 0);
}

#[test]
fn slow_record_round_trips_through_bytes() {
    let record = example_record();
    let bytes = record.to_bytes();
    assert_eq!(&bytes[..2], &7u16.to_le_bytes());
    assert_eq!(&bytes[2..4], &3125i16.to_le_bytes());
    assert!(bytes[34..].iter().all(|&b| b == 0), "reserved tail is zero");
    assert_eq!(ImuSlowRecord::from_bytes(&bytes).to_bytes(), bytes);
}

#[test]
fn a_lost_frame_costs_its_slow_record_only() {
    let bytes = stream(3 * SLOW_RECORD_LEN);
    // Drop frame 50 (in the first record).
    let mut damaged = bytes[..50 * IMU_FRAME_LEN].to_vec();
    damaged.extend_from_slice(&bytes[51 * IMU_FRAME_LEN..]);
    let mut decoder = ImuDecoder::default();
    let frames = decode_whole(&mut decoder, &damaged, 0);
    assert_eq!(samples(&frames).len(), 299);
    assert_eq!(slow_records(&frames).len(), 2);
    assert_eq!(decoder.slow_records_dropped(), 1);
    assert_eq!(decoder.stats().sequence_gaps, 1);
}

#[test]
fn a_slot_index_past_the_record_is_invalid_but_the_sample_is_kept() {
    let bytes = frame(
        0,
        &at_rest(),
        SlowSlot {
            index: 100,
            byte: 0,
        },
    );
    let mut decoder = ImuDecoder::default();
    let frames = decode_whole(&mut decoder, &bytes, 0);
    assert_eq!(samples(&frames).len(), 1);
    assert_eq!(decoder.stats().invalid_payload, 1);
    assert_eq!(decoder.stats().frames, 0);
}

#[test]
fn goes_stale_without_valid_frames_and_counts_it_once() {
    let mut decoder = ImuDecoder::new(50_000_000);
    assert!(Decoder::is_stale(&decoder, 0), "never heard from");
    decode_whole(
        &mut decoder,
        &frame(0, &at_rest(), SlowSlot::default()),
        1_000_000,
    );
    assert!(!Decoder::is_stale(&decoder, 51_000_000));
    // Garbage keeps arriving, but garbage is not a sign of life.
    decode_whole(&mut decoder, &[0u8; 40], 52_000_000);
    assert!(Decoder::is_stale(&decoder, 52_000_000));
    assert_eq!(decoder.stats().stale_events, 1);
    decode_whole(&mut decoder, &[], 90_000_000);
    assert_eq!(decoder.stats().stale_events, 1);
    decode_whole(
        &mut decoder,
        &frame(1, &at_rest(), SlowSlot::default()),
        95_000_000,
    );
    assert!(!Decoder::is_stale(&decoder, 95_000_000));
    assert_eq!(decoder.staleness().last_valid_ns(), Some(95_000_000));
}

/// A stream of good frames, corrupted frames and garbage, for the chunking property.
fn messy_stream() -> impl Strategy<Value = Vec<u8>> {
    let piece = prop_oneof![
        (any::<u8>(), any::<[i16; 6]>(), 0u8..110, any::<u8>()).prop_map(
            |(counter, raw, index, byte)| {
                let measurement = ImuMeasurement {
                    rate_radps: [raw[0], raw[1], raw[2]].map(|r| f32::from(r) * RATE_LSB_RADPS),
                    specific_force_mps2: [raw[3], raw[4], raw[5]]
                        .map(|r| f32::from(r) * SPECIFIC_FORCE_LSB_MPS2),
                    status: ImuStatus(0),
                };
                frame(counter, &measurement, SlowSlot { index, byte }).to_vec()
            }
        ),
        (any::<u8>(), 0usize..IMU_FRAME_LEN, any::<u8>()).prop_map(|(counter, at, flip)| {
            let mut bytes = frame(counter, &at_rest(), SlowSlot::default()).to_vec();
            bytes[at] ^= flip;
            bytes
        }),
        proptest::collection::vec(any::<u8>(), 0..30),
        Just(std::vec![SYNC, IMU_FRAME_TYPE]),
    ];
    proptest::collection::vec(piece, 0..40).prop_map(|pieces| pieces.concat())
}

proptest! {
    #[test]
    fn chunking_does_not_change_the_output(
        bytes in messy_stream(),
        chunks in proptest::collection::vec(0usize..50, 1..20),
    ) {
        let mut whole = ImuDecoder::default();
        let expected = decode_whole(&mut whole, &bytes, 7);
        let mut chunked = ImuDecoder::default();
        let got = decode_chunked(&mut chunked, &bytes, &chunks, 7);
        prop_assert_eq!(got, expected);
        prop_assert_eq!(chunked.stats(), whole.stats());
        prop_assert_eq!(chunked.slow_records_dropped(), whole.slow_records_dropped());
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_every_byte_is_accounted_for(
        bytes in proptest::collection::vec(any::<u8>(), 0..2000),
        chunks in proptest::collection::vec(0usize..64, 1..10),
    ) {
        let mut decoder = ImuDecoder::default();
        let frames = decode_chunked(&mut decoder, &bytes, &chunks, 0);
        let stats = decoder.stats();
        let accepted = u64::from(stats.frames) + u64::from(stats.invalid_payload);
        prop_assert_eq!(samples(&frames).len() as u64, accepted);
        // Every byte is either part of a frame, discarded, or still buffered (< one frame).
        let used = accepted * IMU_FRAME_LEN as u64 + u64::from(stats.bytes_discarded);
        prop_assert!(used <= bytes.len() as u64);
        prop_assert!(bytes.len() as u64 - used < IMU_FRAME_LEN as u64);
    }
}

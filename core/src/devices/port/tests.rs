use super::*;
use crate::devices::imu::{IMU_FRAME_LEN, ImuDecoder, ImuFrame, ImuMeasurement, ImuStreamEncoder};
use crate::devices::servo::{ServoCommandDecoder, ServoCommandFrame};
use crate::devices::test_support::{MockError, MockPort, decode_whole};
use std::vec::Vec;

fn imu_bytes(frames: usize) -> Vec<u8> {
    let mut encoder = ImuStreamEncoder::new();
    let mut bytes = Vec::new();
    for _ in 0..frames {
        let mut out = [0u8; IMU_FRAME_LEN];
        let len = encoder.encode(&ImuMeasurement::default(), &mut out);
        bytes.extend_from_slice(&out[..len]);
    }
    bytes
}

#[test]
fn drain_reads_only_what_is_there_and_never_blocks() {
    let mut port = MockPort {
        received: imu_bytes(3).into(),
        read_limit: 16,
        ..MockPort::default()
    };
    let mut decoder = ImuDecoder::default();
    let mut frames = Vec::new();
    // MockPort panics if `read` is called with nothing received.
    let read = drain(&mut port, &mut decoder, 10, usize::MAX, &mut |frame| {
        frames.push(frame)
    })
    .expect("no port error");
    assert_eq!(read, 3 * IMU_FRAME_LEN);
    assert_eq!(frames.len(), 3);
    assert!(frames.iter().all(|f| matches!(f, ImuFrame::Sample(_))));
    // Nothing left: a second drain returns at once.
    let read = drain(&mut port, &mut decoder, 20, usize::MAX, &mut |_| {}).expect("ok");
    assert_eq!(read, 0);
}

#[test]
fn drain_stops_at_its_byte_budget_and_resumes_next_call() {
    let bytes = imu_bytes(4);
    let mut port = MockPort {
        received: bytes.clone().into(),
        ..MockPort::default()
    };
    let mut decoder = ImuDecoder::default();
    let mut frames = Vec::new();
    let budget = IMU_FRAME_LEN + 5;
    let read = drain(&mut port, &mut decoder, 0, budget, &mut |f| frames.push(f)).expect("ok");
    assert_eq!(read, budget);
    assert_eq!(frames.len(), 1);
    while !port.received.is_empty() {
        drain(&mut port, &mut decoder, 0, budget, &mut |f| frames.push(f)).expect("ok");
    }
    // Same frames as decoding the stream in one go.
    assert_eq!(frames, decode_whole(&mut ImuDecoder::default(), &bytes, 0));
}

#[test]
fn drain_evaluates_staleness_when_nothing_arrives() {
    let mut port = MockPort {
        received: imu_bytes(1).into(),
        ..MockPort::default()
    };
    let mut decoder = ImuDecoder::new(1_000);
    drain(&mut port, &mut decoder, 0, usize::MAX, &mut |_| {}).expect("ok");
    drain(&mut port, &mut decoder, 5_000, usize::MAX, &mut |_| {}).expect("ok");
    assert_eq!(decoder.stats().stale_events, 1);
    assert_eq!(port.reads, 1);
}

#[test]
fn drain_reports_port_errors_after_decoding_what_it_read() {
    let mut port = MockPort {
        received: imu_bytes(1).into(),
        read_limit: IMU_FRAME_LEN,
        ..MockPort::default()
    };
    let mut decoder = ImuDecoder::default();
    let mut frames = Vec::new();
    drain(&mut port, &mut decoder, 0, IMU_FRAME_LEN, &mut |f| {
        frames.push(f)
    })
    .expect("ok");
    port.fail_next_read = true;
    let result = drain(&mut port, &mut decoder, 0, usize::MAX, &mut |f| {
        frames.push(f)
    });
    assert_eq!(result, Err(MockError));
    assert_eq!(frames.len(), 1);
}

fn sent_commands(port: &MockPort) -> Vec<ServoCommandFrame> {
    decode_whole(&mut ServoCommandDecoder::default(), &port.transmitted, 0)
}

fn command(pulse_us: u16) -> ServoCommand {
    ServoCommand {
        channels_us: [pulse_us; 8],
        autopilot_ready: true,
    }
}

#[test]
fn writer_sends_a_frame_across_partial_writes() {
    let mut writer = CommandWriter::new();
    let mut port = MockPort::default();
    assert!(writer.submit_servo_command(&command(1600)));
    // Transmitter full: nothing is written, nothing blocks.
    writer.poll(&mut port).expect("ok");
    assert!(port.transmitted.is_empty());
    for _ in 0..COMMAND_FRAME_LEN {
        port.write_room = 7;
        writer.poll(&mut port).expect("ok");
    }
    let sent = sent_commands(&port);
    assert_eq!(sent.len(), 1);
    assert_eq!(sent[0].command, command(1600));
    assert_eq!(writer.stats().frames_sent, 1);
    assert!(writer.is_idle());
}

#[test]
fn a_newer_command_replaces_one_not_yet_started_but_never_cuts_one_in_half() {
    let mut writer = CommandWriter::new();
    let mut port = MockPort::default();
    writer.submit_servo_command(&command(1100));
    writer.submit_servo_command(&command(1200));
    assert_eq!(writer.stats().frames_superseded, 1);
    port.write_room = 5;
    writer.poll(&mut port).expect("ok");
    // 1200 is half out; 1300 waits, then 1400 replaces it.
    writer.submit_servo_command(&command(1300));
    writer.submit_servo_command(&command(1400));
    assert_eq!(writer.stats().frames_superseded, 2);
    port.write_room = 1000;
    writer.poll(&mut port).expect("ok");
    let sent: Vec<_> = sent_commands(&port)
        .iter()
        .map(|frame| frame.command.channels_us[0])
        .collect();
    assert_eq!(sent, [1200, 1400]);
    assert_eq!(writer.stats().frames_sent, 2);
}

#[test]
fn writer_refuses_frames_longer_than_a_frame() {
    let mut writer = CommandWriter::new();
    assert!(!writer.submit(&[0u8; MAX_FRAME_LEN + 1]));
    assert_eq!(writer.stats().frames_rejected, 1);
    assert!(writer.is_idle());
}

#[test]
fn a_byte_at_a_time_uart_gives_the_same_gps_fixes() {
    use crate::devices::gps::{
        GpsConfig, GpsFix, NmeaDecoder, SentenceKind, Talker, encode_sentence,
    };
    let fix = GpsFix {
        utc_time_ms: Some(1_000),
        valid: true,
        latitude_deg: Some(47.3),
        longitude_deg: Some(8.5),
        ..GpsFix::default()
    };
    let mut bytes = Vec::new();
    for kind in [SentenceKind::Gga, SentenceKind::Rmc] {
        let mut out = [0u8; 140];
        let len = encode_sentence(kind, Talker::Gp, &fix, &mut out).expect("fits");
        bytes.extend_from_slice(&out[..len]);
    }
    let config = GpsConfig {
        epoch_end: Some(SentenceKind::Rmc),
        ..GpsConfig::default()
    };
    let mut port = MockPort {
        received: bytes.clone().into(),
        read_limit: 1,
        ..MockPort::default()
    };
    let mut decoder = NmeaDecoder::new(config);
    let mut fixes = Vec::new();
    // A task's frame budget of 16 bytes per call, as on a slow microcontroller.
    while !port.received.is_empty() {
        drain(&mut port, &mut decoder, 0, 16, &mut |f| fixes.push(f)).expect("ok");
    }
    assert_eq!(port.reads, bytes.len());
    assert_eq!(
        fixes,
        decode_whole(&mut NmeaDecoder::new(config), &bytes, 0)
    );
    assert_eq!(fixes.len(), 1);
    assert!(fixes[0].valid);
}

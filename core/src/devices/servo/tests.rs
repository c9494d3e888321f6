use super::*;
use crate::devices::framing::SYNC;
use crate::devices::test_support::{decode_chunked, decode_whole};
use proptest::prelude::*;
use std::vec::Vec;

fn report() -> PilotReport {
    PilotReport {
        pilot_us: [1500, 1000, 2000, 1234, 1500, 1500, 1100, 1900],
        switch_us: 1000,
        logic_battery_v: 12.345,
        servo_battery_v: 6.02,
        status: BoardStatus::default(),
    }
}

fn pilot_frame(counter: u8, report: &PilotReport) -> [u8; PILOT_FRAME_LEN] {
    let mut out = [0u8; PILOT_FRAME_LEN];
    assert_eq!(
        encode_pilot_frame(counter, report, &mut out),
        PILOT_FRAME_LEN
    );
    out
}

fn command_frame(counter: u8, command: &ServoCommand) -> [u8; COMMAND_FRAME_LEN] {
    let mut out = [0u8; COMMAND_FRAME_LEN];
    assert_eq!(
        encode_servo_command(counter, command, &mut out),
        COMMAND_FRAME_LEN
    );
    out
}

/// The worked example in docs/protocols.md, "Servo board → computer".
#[test]
fn documented_pilot_frame() {
    let bytes = pilot_frame(0x10, &report());
    let expected: [u8; PILOT_FRAME_LEN] = [
        0xA5, 0x53, 0x17, 0x10, // sync, type 'S', length 23, counter 16
        0xDC, 0x05, 0xE8, 0x03, 0xD0, 0x07, 0xD2, 0x04, // ch1–4: 1500, 1000, 2000, 1234 µs
        0xDC, 0x05, 0xDC, 0x05, 0x4C, 0x04, 0x6C, 0x07, // ch5–8: 1500, 1500, 1100, 1900 µs
        0xE8, 0x03, // switch 1000 µs (manual)
        0x39, 0x30, 0x84, 0x17, // logic 12345 mV, servo 6020 mV
        0x00, // status
        0xED, 0xC9, // CRC-16/CCITT-FALSE 0xC9ED, little-endian
    ];
    assert_eq!(bytes, expected, "{bytes:02X?}");
}

/// The worked example in docs/protocols.md, "Computer → servo board".
#[test]
fn documented_command_frame() {
    let command = ServoCommand::from_channels(
        [
            ChannelCommand::Surface(0.0),
            ChannelCommand::Surface(0.5),
            ChannelCommand::Throttle(0.75),
            ChannelCommand::Surface(-1.0),
            ChannelCommand::Surface(0.0),
            ChannelCommand::Surface(0.0),
            ChannelCommand::Surface(0.0),
            ChannelCommand::Surface(0.0),
        ],
        true,
    );
    let bytes = command_frame(0x05, &command);
    let expected: [u8; COMMAND_FRAME_LEN] = [
        0xA5, 0x43, 0x11, 0x05, // sync, type 'C', length 17, counter 5
        0xDC, 0x05, 0xD6, 0x06, 0xD6, 0x06, 0xE8, 0x03, // 1500, 1750, 1750, 1000 µs
        0xDC, 0x05, 0xDC, 0x05, 0xDC, 0x05, 0xDC, 0x05, // 1500 µs × 4
        0x01, // flags: autopilot ready
        0x16, 0xCC, // CRC-16/CCITT-FALSE 0xCC16, little-endian
    ];
    assert_eq!(bytes, expected, "{bytes:02X?}");
}

#[test]
fn pilot_frame_round_trips() {
    let mut decoder = ServoDecoder::default();
    let frames = decode_whole(&mut decoder, &pilot_frame(3, &report()), 42);
    let [frame] = frames.as_slice() else {
        panic!("one frame expected, got {frames:?}");
    };
    assert_eq!(frame.counter, 3);
    assert_eq!(frame.received_ns, 42);
    assert_eq!(frame.report.pilot_us, report().pilot_us);
    assert_eq!(frame.report.requested_mode(), ControlMode::Manual);
    assert!((frame.report.logic_battery_v - 12.345).abs() < 1e-4);
    assert!((frame.report.servo_battery_v - 6.02).abs() < 1e-4);
    assert_eq!(decoder.stats().frames, 1);
}

#[test]
fn switch_above_threshold_requests_auto() {
    let auto = PilotReport {
        switch_us: 1900,
        status: BoardStatus(BoardStatus::COMPUTER_IN_CONTROL),
        ..report()
    };
    let frames = decode_whole(&mut ServoDecoder::default(), &pilot_frame(0, &auto), 0);
    assert_eq!(frames[0].report.requested_mode(), ControlMode::Auto);
    assert!(frames[0].report.status.computer_in_control());
    assert!(!frames[0].report.status.command_timeout());
}

#[test]
fn implausible_pulses_are_invalid_unless_the_receiver_is_in_failsafe() {
    let broken = PilotReport {
        pilot_us: [0; PILOT_CHANNELS],
        ..report()
    };
    let mut decoder = ServoDecoder::default();
    assert!(decode_whole(&mut decoder, &pilot_frame(0, &broken), 0).is_empty());
    assert_eq!(decoder.stats().invalid_payload, 1);
    assert!(
        decoder.is_stale_for_test(0),
        "an invalid frame is not a sign of life"
    );

    let failsafe = PilotReport {
        status: BoardStatus(BoardStatus::RECEIVER_FAILSAFE),
        ..broken
    };
    let frames = decode_whole(&mut decoder, &pilot_frame(1, &failsafe), 0);
    assert!(frames[0].report.status.receiver_failsafe());
}

#[test]
fn command_frame_round_trips_through_the_boards_decoder() {
    let command = ServoCommand {
        channels_us: [1000, 1100, 1200, 1300, 1700, 1800, 1900, 2000],
        autopilot_ready: true,
    };
    let mut decoder = ServoCommandDecoder::default();
    let frames = decode_whole(&mut decoder, &command_frame(9, &command), 5);
    assert_eq!(
        frames,
        [ServoCommandFrame {
            counter: 9,
            received_ns: 5,
            command
        }]
    );
    // A board frame on the command line is a framing error, not a command.
    let mut decoder = ServoCommandDecoder::default();
    assert!(decode_whole(&mut decoder, &pilot_frame(0, &report()), 0).is_empty());
    assert_eq!(decoder.stats().framing_errors, 1);
}

#[test]
fn unknown_command_flags_are_invalid() {
    let mut bytes = command_frame(0, &ServoCommand::default());
    // Re-encode by hand with a reserved flag bit set.
    let mut payload = [0u8; COMMAND_PAYLOAD_LEN];
    payload.copy_from_slice(&bytes[4..4 + COMMAND_PAYLOAD_LEN]);
    payload[..2].copy_from_slice(&1500u16.to_le_bytes());
    payload[COMMAND_PAYLOAD_LEN - 1] = 0x80;
    framing::encode_frame(COMMAND_FRAME_TYPE, 0, &payload, &mut bytes).expect("fits");
    let mut decoder = ServoCommandDecoder::default();
    assert!(decode_whole(&mut decoder, &bytes, 0).is_empty());
    assert_eq!(decoder.stats().invalid_payload, 1);
}

#[test]
fn normalised_commands_map_to_pulses_and_back() {
    assert_eq!(surface_to_pulse_us(0.0), 1500);
    assert_eq!(surface_to_pulse_us(1.0), 2000);
    assert_eq!(surface_to_pulse_us(-1.0), 1000);
    assert_eq!(surface_to_pulse_us(7.0), 2000, "clamped");
    assert_eq!(surface_to_pulse_us(f32::NAN), 1500, "NaN is neutral");
    assert_eq!(throttle_to_pulse_us(0.0), 1000);
    assert_eq!(throttle_to_pulse_us(1.0), 2000);
    assert_eq!(throttle_to_pulse_us(-0.5), 1000, "clamped");
    assert_eq!(throttle_to_pulse_us(f32::NAN), 1000, "NaN is idle");
    assert_eq!(pulse_us_to_surface(1750), 0.5);
    assert_eq!(pulse_us_to_surface(900), -1.0);
    assert_eq!(pulse_us_to_throttle(1250), 0.25);
    assert_eq!(pulse_us_to_throttle(2500), 1.0);
}

#[test]
fn stale_board_is_detected() {
    let mut decoder = ServoDecoder::new(100);
    decode_whole(&mut decoder, &pilot_frame(0, &report()), 1_000);
    decode_whole(&mut decoder, &[], 1_100);
    assert_eq!(decoder.stats().stale_events, 0);
    decode_whole(&mut decoder, &[], 1_101);
    assert_eq!(decoder.stats().stale_events, 1);
    assert!(decoder.staleness().is_stale(1_101));
}

impl<C: PayloadCodec> BinaryDecoder<C> {
    fn is_stale_for_test(&self, now_ns: u64) -> bool {
        Decoder::is_stale(self, now_ns)
    }
}

fn messy_stream() -> impl Strategy<Value = Vec<u8>> {
    let piece = prop_oneof![
        (
            any::<u8>(),
            proptest::array::uniform8(400u16..2600),
            any::<u8>()
        )
            .prop_map(|(counter, pilot_us, status)| {
                let report = PilotReport {
                    pilot_us,
                    status: BoardStatus(status),
                    ..report()
                };
                pilot_frame(counter, &report).to_vec()
            }),
        (any::<u8>(), 0usize..PILOT_FRAME_LEN, any::<u8>()).prop_map(|(counter, at, flip)| {
            let mut bytes = pilot_frame(counter, &report()).to_vec();
            bytes[at] ^= flip;
            bytes
        }),
        proptest::collection::vec(any::<u8>(), 0..40),
        Just(std::vec![SYNC, PILOT_FRAME_TYPE, PILOT_PAYLOAD_LEN as u8]),
    ];
    proptest::collection::vec(piece, 0..40).prop_map(|pieces| pieces.concat())
}

proptest! {
    #[test]
    fn chunking_does_not_change_the_output(
        bytes in messy_stream(),
        chunks in proptest::collection::vec(0usize..60, 1..20),
    ) {
        let mut whole = ServoDecoder::default();
        let expected = decode_whole(&mut whole, &bytes, 3);
        let mut chunked = ServoDecoder::default();
        let got = decode_chunked(&mut chunked, &bytes, &chunks, 3);
        prop_assert_eq!(got, expected);
        prop_assert_eq!(chunked.stats(), whole.stats());
    }

    #[test]
    fn arbitrary_bytes_never_panic(
        bytes in proptest::collection::vec(any::<u8>(), 0..2000),
        chunks in proptest::collection::vec(0usize..64, 1..10),
    ) {
        let mut board_side = ServoCommandDecoder::default();
        let commands = decode_chunked(&mut board_side, &bytes, &chunks, 0);
        prop_assert_eq!(commands.len() as u64, u64::from(board_side.stats().frames));
        let mut computer_side = ServoDecoder::default();
        let frames = decode_chunked(&mut computer_side, &bytes, &chunks, 0);
        prop_assert_eq!(frames.len() as u64, u64::from(computer_side.stats().frames));
    }

    #[test]
    fn normalised_surface_commands_survive_the_wire_within_one_microsecond(
        command in -1.0f32..=1.0,
    ) {
        let back = pulse_us_to_surface(surface_to_pulse_us(command));
        prop_assert!((back - command).abs() <= 1.0 / f32::from(PULSE_HALF_RANGE_US));
    }
}

//! Protocol-level tests: the worked examples of `docs/link-protocol.md`, round trips of
//! every message, one rejection test per reason, replay windows, and arbitrary input.

extern crate std;

use super::auth::{GuardError, MAX_SENDERS, ReplayError, ReplayGuard};
use super::frame::{CRC_LEN, HEADER_LEN, TAG_LEN, crc32};
use super::messages::*;
use super::*;
use crate::control::mission::Waypoint;
use crate::control::mode::FlightMode;
use crate::executive::FrameStats;
use crate::horizon::HorizonAttitude;
use crate::logfmt::Time;
use proptest::prelude::*;
use std::vec::Vec as StdVec;
// `prop_oneof!` of more than ten strategies builds a `vec!`.
use std::vec;

const VEHICLE: u16 = 7;
const GROUND: u8 = 1;
const TASKS: usize = 8;
const RUN: u32 = 0x1234_5678;

fn hex(text: &str) -> StdVec<u8> {
    let text: StdVec<u8> = text.bytes().filter(u8::is_ascii_hexdigit).collect();
    text.chunks(2)
        .map(|pair| u8::from_str_radix(std::str::from_utf8(pair).expect("ascii"), 16).expect("hex"))
        .collect()
}

/// The key of the worked examples: bytes 0x00, 0x01, … 0x1f.
fn example_key() -> LinkKey {
    LinkKey::from_hex("000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f")
        .expect("64 hex digits")
}

fn name(text: &str) -> Name {
    Name::new(text).expect("valid name")
}

fn encode(envelope: &Envelope, message: &Message, key: Option<&LinkKey>) -> StdVec<u8> {
    let mut buffer = [0u8; MAX_DATAGRAM_LEN];
    let len = encode_datagram(envelope, message, key, &mut buffer).expect("encodes");
    buffer[..len].to_vec()
}

/// A datagram with any header fields and payload bytes, CRC'd and (with a key) signed, for
/// datagrams `encode_datagram` refuses to make.
fn raw_datagram(
    message_type: u8,
    header_flags: u8,
    envelope: &Envelope,
    payload: &[u8],
    key: Option<&LinkKey>,
) -> StdVec<u8> {
    let mut d = StdVec::new();
    d.extend_from_slice(b"SKYF");
    d.push(1);
    d.push(header_flags);
    d.push(message_type);
    d.push(envelope.sender_id);
    d.extend_from_slice(&envelope.vehicle_id.to_le_bytes());
    d.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    d.extend_from_slice(&envelope.run_id.to_le_bytes());
    d.extend_from_slice(&envelope.sequence.to_le_bytes());
    d.extend_from_slice(&envelope.t_ns.to_le_bytes());
    d.extend_from_slice(payload);
    if let Some(key) = key {
        d.extend_from_slice(&auth::sign(key, &d).expect("signs"));
    }
    let crc = crc32(&d);
    d.extend_from_slice(&crc.to_le_bytes());
    d
}

fn with_crc_fixed(mut d: StdVec<u8>) -> StdVec<u8> {
    let n = d.len() - CRC_LEN;
    let crc = crc32(&d[..n]);
    d[n..].copy_from_slice(&crc.to_le_bytes());
    d
}

// ---------------------------------------------------------------------------------------
// Worked examples (docs/link-protocol.md, "Worked examples"): checked byte for byte.

const EXAMPLE_TASK_DATA: &str = "
    534b5946 01 00 01 00 0700 1a00 78563412 01000000 00ca9a3b00000000
    00 01 00000000 009d693a 03 04 0000803e 04 0000c0bf 02 fdffffff
    d697205e";

const EXAMPLE_SET_PARAM: &str = "
    534b5946 01 01 83 01 0700 0f00 78563412 2a000000 00f2052a01000000
    09 726f6c6c5f6761696e 04 0000c03f
    014819f17a0b9446e9c89481dd57d804897b4e7090f57be7e618e38283779906
    abed5c8c";

const EXAMPLE_ACK: &str = "
    534b5946 01 00 06 00 0700 0c00 78563412 02000000 80889e2a01000000
    01 2a000000 83 00 04 0000c03f
    54a7dfb4";

fn example_task_data() -> (Envelope, Message) {
    (
        Envelope {
            vehicle_id: VEHICLE,
            sender_id: 0,
            run_id: RUN,
            sequence: 1,
            t_ns: 1_000_000_000,
        },
        Message::Telemetry(Telemetry::TaskData(TaskData {
            task_index: 0,
            format_index: 1,
            time: Time {
                sec: 0,
                nsec: 980_000_000,
            },
            values: heapless::Vec::from_slice(&[
                Value::F32(0.25),
                Value::F32(-1.5),
                Value::I32(-3),
            ])
            .expect("fits"),
        })),
    )
}

fn example_set_param() -> (Envelope, Message) {
    (
        Envelope {
            vehicle_id: VEHICLE,
            sender_id: GROUND,
            run_id: RUN,
            sequence: 42,
            t_ns: 5_000_000_000,
        },
        Message::Command(Command::SetParam {
            name: name("roll_gain"),
            value: Value::F32(1.5),
        }),
    )
}

fn example_ack() -> (Envelope, Message) {
    (
        Envelope {
            vehicle_id: VEHICLE,
            sender_id: 0,
            run_id: RUN,
            sequence: 2,
            t_ns: 5_010_000_000,
        },
        Message::Telemetry(Telemetry::CommandAck(CommandAck {
            command_sender_id: GROUND,
            command_sequence: 42,
            command_type: message_type::SET_PARAM,
            result: AckResult::Accepted,
            value_in_force: Some(Value::F32(1.5)),
        })),
    )
}

#[test]
fn crc32_is_the_ethernet_crc() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(crc32(b""), 0);
}

#[test]
fn worked_examples_encode_byte_for_byte() {
    let key = example_key();
    let (e, m) = example_task_data();
    assert_eq!(encode(&e, &m, None), hex(EXAMPLE_TASK_DATA));
    let (e, m) = example_set_param();
    assert_eq!(encode(&e, &m, Some(&key)), hex(EXAMPLE_SET_PARAM));
    let (e, m) = example_ack();
    assert_eq!(encode(&e, &m, None), hex(EXAMPLE_ACK));
}

#[test]
fn worked_examples_decode() {
    let key = example_key();
    for (bytes, (envelope, message), signed) in [
        (EXAMPLE_TASK_DATA, example_task_data(), false),
        (EXAMPLE_SET_PARAM, example_set_param(), true),
        (EXAMPLE_ACK, example_ack(), false),
    ] {
        let (header, decoded) =
            decode_datagram(&hex(bytes), Verify::IfSigned(&key)).expect("decodes");
        assert_eq!(header.envelope, envelope);
        assert_eq!(header.signed, signed);
        assert_eq!(decoded, message);
    }
    // The vehicle's gate accepts the example command.
    let params = test_params();
    let mut gate = gate();
    let accepted = gate
        .accept(&hex(EXAMPLE_SET_PARAM), 0, &params)
        .expect("accepted");
    assert_eq!((accepted.sender_id, accepted.sequence), (GROUND, 42));
}

#[test]
fn key_from_hex_takes_exactly_64_digits() {
    assert_eq!(
        LinkKey::from_hex(&"AB".repeat(32)),
        Some(LinkKey::new([0xAB; 32]))
    );
    assert_eq!(LinkKey::from_hex(&"ab".repeat(31)), None);
    assert_eq!(LinkKey::from_hex(&"ab".repeat(33)), None);
    assert_eq!(LinkKey::from_hex(&"g0".repeat(32)), None);
    assert_eq!(std::format!("{:?}", example_key()), "LinkKey(..)");
}

// ---------------------------------------------------------------------------------------
// Round trips of every message, signed and unsigned.

fn any_name() -> impl Strategy<Value = Name> {
    "[A-Za-z0-9_.-]{0,32}".prop_map(|s| name(&s))
}

/// Floats by bit pattern, so NaNs, infinities and -0.0 are covered too.
fn any_value() -> impl Strategy<Value = Value> {
    prop_oneof![
        any::<bool>().prop_map(Value::Bool),
        any::<i32>().prop_map(Value::I32),
        any::<u32>().prop_map(Value::U32),
        any::<u32>().prop_map(|b| Value::F32(f32::from_bits(b))),
        any::<u64>().prop_map(|b| Value::F64(f64::from_bits(b))),
    ]
}

fn same_type_values() -> impl Strategy<Value = (Value, Value, Value)> {
    (any_value(), any::<[u32; 2]>(), any::<[u64; 2]>()).prop_map(|(v, b32, b64)| match v {
        Value::Bool(_) => (
            v,
            Value::Bool(b32[0] & 1 == 1),
            Value::Bool(b32[1] & 1 == 1),
        ),
        Value::I32(_) => (v, Value::I32(b32[0] as i32), Value::I32(b32[1] as i32)),
        Value::U32(_) => (v, Value::U32(b32[0]), Value::U32(b32[1])),
        Value::F32(_) => (
            v,
            Value::F32(f32::from_bits(b32[0])),
            Value::F32(f32::from_bits(b32[1])),
        ),
        Value::F64(_) => (
            v,
            Value::F64(f64::from_bits(b64[0])),
            Value::F64(f64::from_bits(b64[1])),
        ),
    })
}

fn any_mode() -> impl Strategy<Value = FlightMode> {
    prop_oneof![
        Just(FlightMode::Manual),
        Just(FlightMode::Stabilise),
        Just(FlightMode::Auto)
    ]
}

fn any_ack_result() -> impl Strategy<Value = AckResult> {
    (0u8..5).prop_map(|r| AckResult::from_u8(r).expect("0..5 are results"))
}

fn any_task_status() -> impl Strategy<Value = TaskStatus> {
    (
        any::<u8>(),
        any_name(),
        any::<[bool; 4]>(),
        any::<u64>(),
        any::<[u32; 10]>(),
        any::<[u64; 4]>(),
    )
        .prop_map(|(task_index, name, lights, releases, c, t)| TaskStatus {
            task_index,
            name,
            initialised: lights[0],
            running: lights[1],
            in_frame: lights[2],
            alive: lights[3],
            releases,
            overruns_budget: c[0],
            overruns_frame: c[1],
            overruns_missed: c[2],
            skipped: c[3],
            resets: c[4],
            faults: c[5],
            init_failures: c[6],
            watchdog_misses: c[7],
            log_records_dropped: c[8],
            telemetry_interval_ms: c[9],
            exec_mean_ns: t[0],
            exec_max_ns: t[1],
            budget_ns: t[2],
            period_ns: t[3],
        })
}

fn any_executive_status() -> impl Strategy<Value = ExecutiveStatus> {
    (
        any::<[u64; 2]>(),
        proptest::option::of(any_mode()),
        any::<u8>(),
        any::<u32>(),
        any::<[u64; 7]>(),
        any::<[u32; 16]>(),
        any::<(u32, u32, u8)>(),
    )
        .prop_map(
            |(times, mode, task_count, health_period_ms, f, l, log)| ExecutiveStatus {
                elapsed_ns: times[0],
                duration_ns: times[1],
                mode,
                task_count,
                health_period_ms,
                frames: FrameStats {
                    frames: f[0],
                    missed: f[1],
                    late: f[2],
                    overrun: f[3],
                    max_start_latency_ns: f[4],
                    max_frame_work_ns: f[5],
                    timing_records_dropped: f[6],
                },
                link: LinkCounters {
                    received: l[0],
                    accepted: l[1],
                    bad_crc: l[2],
                    malformed: l[3],
                    wrong_vehicle: l[4],
                    unsigned: l[5],
                    bad_signature: l[6],
                    wrong_run: l[7],
                    replayed: l[8],
                    too_many_senders: l[9],
                    out_of_range: l[10],
                    unknown_param: l[11],
                    wrong_type: l[12],
                    telemetry_sent: l[13],
                    telemetry_send_failed: l[14],
                    rate_limited: l[15],
                },
                log: LogHealth {
                    free_mib: log.0,
                    records_lost: log.1,
                    streams_suspended: log.2,
                },
            },
        )
}

fn any_telemetry() -> impl Strategy<Value = Telemetry> {
    prop_oneof![
        (
            any::<u8>(),
            any::<u8>(),
            any::<i32>(),
            0..1_000_000_000u32,
            proptest::collection::vec(any_value(), 0..=MAX_TASK_VALUES)
        )
            .prop_map(|(task_index, format_index, sec, nsec, values)| {
                Telemetry::TaskData(TaskData {
                    task_index,
                    format_index,
                    time: Time { sec, nsec },
                    values: heapless::Vec::from_slice(&values).expect("fits"),
                })
            }),
        (any::<u8>(), any::<u8>(), "[ -~]{0,255}").prop_map(
            |(task_index, format_index, columns)| {
                Telemetry::TaskFormat(TaskFormat {
                    task_index,
                    format_index,
                    columns: heapless::Vec::from_slice(columns.as_bytes()).expect("fits"),
                })
            }
        ),
        any_task_status().prop_map(Telemetry::TaskStatus),
        any_executive_status().prop_map(Telemetry::ExecutiveStatus),
        (any::<u16>(), any::<u16>(), any_name(), same_type_values()).prop_map(
            |(index, count, name, (value, min, max))| {
                Telemetry::ParamValue(ParamValue {
                    index,
                    count,
                    name,
                    value,
                    min,
                    max,
                })
            }
        ),
        (
            any::<u8>(),
            any::<u32>(),
            any::<u8>(),
            any_ack_result(),
            proptest::option::of(any_value())
        )
            .prop_map(|(sender, sequence, command_type, result, value)| {
                Telemetry::CommandAck(CommandAck {
                    command_sender_id: sender,
                    command_sequence: sequence,
                    command_type,
                    result,
                    value_in_force: value,
                })
            }),
    ]
}

fn any_command() -> impl Strategy<Value = Command> {
    prop_oneof![
        (any::<u8>(), any::<u32>()).prop_map(|(task_index, interval_ms)| {
            Command::SetTelemetryRate {
                task_index,
                interval_ms,
            }
        }),
        any::<u32>().prop_map(|period_ms| Command::SetHealthPeriod { period_ms }),
        (any_name(), any_value()).prop_map(|(name, value)| Command::SetParam { name, value }),
        any_name().prop_map(|name| Command::GetParam { name }),
        Just(Command::ListParams),
        any_mode().prop_map(|mode| Command::RequestMode { mode }),
        (any::<[u32; 3]>(), any::<u64>()).prop_map(|(f, capture_t_ns)| {
            Command::HorizonAttitude(HorizonAttitude {
                roll_rad: f32::from_bits(f[0]),
                pitch_rad: f32::from_bits(f[1]),
                confidence: f32::from_bits(f[2]),
                capture_t_ns,
            })
        }),
        Just(Command::Stop),
        Just(Command::MissionClear),
        (any::<u8>(), any::<u8>(), any::<[u32; 4]>()).prop_map(|(index, count, f)| {
            Command::MissionItem {
                index,
                count,
                waypoint: Waypoint {
                    north_m: f32::from_bits(f[0]),
                    east_m: f32::from_bits(f[1]),
                    altitude_m: f32::from_bits(f[2]),
                    airspeed_mps: f32::from_bits(f[3]),
                },
            }
        }),
        (any::<u8>(), any::<[u32; 2]>(), any::<bool>()).prop_map(|(count, f, loiter_clockwise)| {
            Command::MissionCommit {
                count,
                switch_radius_m: f32::from_bits(f[0]),
                loiter_radius_m: f32::from_bits(f[1]),
                loiter_clockwise,
            }
        }),
        any::<u8>().prop_map(|index| Command::MissionSetCurrent { index }),
    ]
}

/// A waypoint the mission file loader would take.
fn flyable(north_m: f32, east_m: f32) -> Waypoint {
    Waypoint {
        north_m,
        east_m,
        altitude_m: 120.0,
        airspeed_mps: 23.0,
    }
}

fn any_message() -> impl Strategy<Value = Message> {
    prop_oneof![
        any_telemetry().prop_map(Message::Telemetry),
        any_command().prop_map(Message::Command),
    ]
}

fn any_envelope() -> impl Strategy<Value = Envelope> {
    (any::<u16>(), any::<u8>(), any::<[u32; 2]>(), any::<u64>()).prop_map(
        |(vehicle_id, sender_id, [run_id, sequence], t_ns)| Envelope {
            vehicle_id,
            sender_id,
            run_id,
            sequence,
            t_ns,
        },
    )
}

/// Equality that treats floats by bits: NaN == NaN (same payload), 0.0 != -0.0.
fn same(a: &Message, b: &Message) -> bool {
    std::format!("{a:?}") == std::format!("{b:?}")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn every_message_round_trips(envelope in any_envelope(), message in any_message(), signed: bool) {
        let key = example_key();
        let key = signed.then_some(&key);
        let bytes = encode(&envelope, &message, key);
        prop_assert!(bytes.len() <= MAX_DATAGRAM_LEN);
        let verify = key.map_or(Verify::No, Verify::Required);
        let (header, decoded) = decode_datagram(&bytes, verify).expect("decodes");
        prop_assert_eq!(header.envelope, envelope);
        prop_assert_eq!(header.signed, signed);
        prop_assert_eq!(header.message_type, message.message_type());
        prop_assert!(same(&decoded, &message), "{:?} != {:?}", decoded, message);
        // Same bytes again: one encoding per message.
        prop_assert_eq!(encode(&envelope, &decoded, key), bytes);
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_are_never_accepted(
        bytes in proptest::collection::vec(any::<u8>(), 0..1600),
    ) {
        let key = example_key();
        let _ = decode_datagram(&bytes, Verify::No);
        let _ = decode_datagram(&bytes, Verify::IfSigned(&key));
        let mut gate = gate();
        prop_assert!(gate.accept(&bytes, 0, &test_params()).is_err());
        prop_assert_eq!(gate.counters().received, 1);
        prop_assert_eq!(gate.counters().rejected(), 1);
    }

    /// Arbitrary bytes behind a valid header, CRC and signature: the payload decoder is the
    /// only thing between them and the vehicle.
    #[test]
    fn arbitrary_signed_payloads_never_panic(
        message_type: u8,
        payload in proptest::collection::vec(any::<u8>(), 0..64),
    ) {
        let key = example_key();
        let e = ground_envelope(1, 0);
        let d = raw_datagram(message_type, 1, &e, &payload, Some(&key));
        let _ = decode_datagram(&d, Verify::Required(&key));
        let mut gate = gate();
        let result = gate.accept(&d, 0, &test_params());
        let c = gate.counters();
        prop_assert_eq!(c.received, c.accepted + c.rejected());
        if let Ok(accepted) = result {
            // Whatever got through re-encodes to the same payload.
            let again = encode(&e, &Message::Command(accepted.command), Some(&key));
            prop_assert_eq!(again, d);
        }
    }

    /// Any single corrupted byte of a signed command is caught (by the CRC, usually).
    #[test]
    fn corrupted_commands_are_never_accepted(
        command in any_command(),
        position: proptest::sample::Index,
        flip in 1u8..=255,
    ) {
        let key = example_key();
        let e = ground_envelope(5, 0);
        let mut d = encode(&e, &Message::Command(command), Some(&key));
        let i = position.index(d.len());
        d[i] ^= flip;
        let mut gate = gate();
        prop_assert!(gate.accept(&d, 0, &test_params()).is_err());
        // And with the CRC recomputed (over a change outside the CRC), the tag catches it.
        if i < d.len() - CRC_LEN {
            let d = with_crc_fixed(d);
            let result = gate.accept(&d, 0, &test_params());
            prop_assert!(result.is_err(), "{:?}", result);
        }
    }

    /// The window against a plain model: a sequence number is accepted iff it was never
    /// accepted and is less than 64 behind the newest accepted.
    #[test]
    fn replay_window_matches_a_model(
        steps in proptest::collection::vec((any::<bool>(), 0u32..200, any::<u32>()), 1..300),
    ) {
        let mut window = ReplayWindow::new();
        let mut accepted = std::collections::BTreeSet::new();
        for (near, small, big) in steps {
            // Mostly numbers near the newest, sometimes anywhere.
            let sequence = if near {
                window.newest().unwrap_or(0).saturating_add(small).saturating_sub(100)
            } else {
                big
            };
            let newest = accepted.iter().next_back().copied();
            let fresh = !accepted.contains(&sequence)
                && newest.is_none_or(|n: u32| sequence > n || n - sequence < 64);
            prop_assert_eq!(window.check(sequence).is_ok(), fresh);
            prop_assert_eq!(window.accept(sequence).is_ok(), fresh);
            if fresh {
                accepted.insert(sequence);
            }
            prop_assert_eq!(window.newest(), accepted.iter().next_back().copied());
        }
    }
}

#[test]
fn the_largest_messages_fit_one_datagram() {
    let big_data = Message::Telemetry(Telemetry::TaskData(TaskData {
        task_index: 0,
        format_index: 0,
        time: Time::default(),
        values: heapless::Vec::from_slice(&[Value::F64(0.0); MAX_TASK_VALUES]).expect("fits"),
    }));
    let big_format = Message::Telemetry(Telemetry::TaskFormat(TaskFormat {
        task_index: 0,
        format_index: 0,
        columns: heapless::Vec::from_slice(&[b'x'; MAX_COLUMNS_LEN]).expect("fits"),
    }));
    let key = example_key();
    for m in [big_data, big_format] {
        let d = encode(&Envelope::default(), &m, Some(&key));
        assert!(d.len() <= MAX_DATAGRAM_LEN, "{}", d.len());
    }
    // And a buffer that is too small is an error, not a panic.
    let mut small = [0u8; 30];
    assert_eq!(
        encode_datagram(
            &Envelope::default(),
            &example_task_data().1,
            None,
            &mut small
        ),
        Err(frame::EncodeError::TooLong)
    );
}

// ---------------------------------------------------------------------------------------
// The command gate: acceptance, and one test per rejection reason with the counters.

fn test_params() -> ParamTable {
    let mut params = ParamTable::new();
    params
        .define(
            "roll_gain",
            Value::F32(0.5),
            Value::F32(0.0),
            Value::F32(2.0),
        )
        .expect("define");
    params
        .define(
            "log_imu",
            Value::Bool(true),
            Value::Bool(false),
            Value::Bool(true),
        )
        .expect("define");
    params
}

fn gate() -> CommandGate {
    CommandGate::new(
        example_key(),
        GateConfig {
            vehicle_id: VEHICLE,
            run_id: RUN,
            task_count: TASKS,
        },
    )
}

/// The ground station's envelope for this vehicle and run.
fn ground_envelope(sequence: u32, t_ns: u64) -> Envelope {
    Envelope {
        vehicle_id: VEHICLE,
        sender_id: GROUND,
        run_id: RUN,
        sequence,
        t_ns,
    }
}

fn command(sequence: u32, command: Command) -> StdVec<u8> {
    command_from(GROUND, sequence, command)
}

fn command_from(sender_id: u8, sequence: u32, command: Command) -> StdVec<u8> {
    let e = Envelope {
        sender_id,
        ..ground_envelope(sequence, 1_000)
    };
    encode(&e, &Message::Command(command), Some(&example_key()))
}

/// Runs the datagrams through a fresh gate and returns the last outcome and the counters.
fn run(datagrams: &[StdVec<u8>]) -> (Result<AcceptedCommand, Rejected>, LinkCounters) {
    let mut gate = gate();
    let params = test_params();
    let mut last = Err(Rejected {
        reason: RejectReason::Malformed,
        ack: None,
    });
    for (i, d) in datagrams.iter().enumerate() {
        last = gate.accept(d, i as u64, &params);
    }
    let c = *gate.counters();
    assert_eq!(c.received, datagrams.len() as u32);
    assert_eq!(c.received, c.accepted + c.rejected(), "{c:?}");
    (last, c)
}

/// Counters after `accepted` good commands and one rejected with `reason`.
fn expect_counters(reason: RejectReason, accepted: u32) -> LinkCounters {
    let mut c = LinkCounters {
        received: accepted + 1,
        accepted,
        ..LinkCounters::default()
    };
    let counter = match reason {
        RejectReason::BadCrc => &mut c.bad_crc,
        RejectReason::Malformed => &mut c.malformed,
        RejectReason::WrongVehicle => &mut c.wrong_vehicle,
        RejectReason::Unsigned => &mut c.unsigned,
        RejectReason::BadSignature => &mut c.bad_signature,
        RejectReason::WrongRun => &mut c.wrong_run,
        RejectReason::Replayed => &mut c.replayed,
        RejectReason::TooManySenders => &mut c.too_many_senders,
        RejectReason::OutOfRange => &mut c.out_of_range,
        RejectReason::UnknownParam => &mut c.unknown_param,
        RejectReason::WrongType => &mut c.wrong_type,
    };
    *counter = 1;
    c
}

#[track_caller]
fn assert_rejected(datagrams: &[StdVec<u8>], reason: RejectReason) -> Option<CommandAck> {
    let (last, counters) = run(datagrams);
    let rejected = last.expect_err("must be rejected");
    assert_eq!(rejected.reason, reason);
    assert_eq!(
        counters,
        expect_counters(reason, datagrams.len() as u32 - 1)
    );
    rejected.ack
}

fn telemetry_rate(task_index: u8, interval_ms: u32) -> Command {
    Command::SetTelemetryRate {
        task_index,
        interval_ms,
    }
}

#[test]
fn every_command_in_range_is_accepted() {
    let commands = [
        telemetry_rate(7, 50),
        telemetry_rate(0, 0),
        Command::SetHealthPeriod { period_ms: 100 },
        Command::SetHealthPeriod { period_ms: 60_000 },
        Command::SetParam {
            name: name("roll_gain"),
            value: Value::F32(2.0),
        },
        Command::GetParam {
            name: name("log_imu"),
        },
        Command::ListParams,
        Command::RequestMode {
            mode: FlightMode::Auto,
        },
        Command::HorizonAttitude(HorizonAttitude {
            roll_rad: -core::f32::consts::PI,
            pitch_rad: core::f32::consts::FRAC_PI_2,
            confidence: 1.0,
            capture_t_ns: 123,
        }),
        Command::Stop,
        Command::MissionClear,
        Command::MissionItem {
            index: 31,
            count: 32,
            waypoint: Waypoint {
                altitude_m: 1000.0,
                airspeed_mps: 32.0,
                ..flyable(-600.0, 500.0)
            },
        },
        Command::MissionItem {
            index: 0,
            count: 1,
            waypoint: Waypoint {
                altitude_m: 20.0,
                airspeed_mps: 17.0,
                ..flyable(0.0, 0.0)
            },
        },
        Command::MissionCommit {
            count: 32,
            switch_radius_m: 30.0,
            loiter_radius_m: 110.0,
            loiter_clockwise: false,
        },
        Command::MissionSetCurrent { index: 31 },
    ];
    let mut gate = gate();
    let params = test_params();
    for (i, c) in commands.iter().enumerate() {
        let accepted = gate
            .accept(&command(i as u32 + 1, *c), 10 + i as u64, &params)
            .expect("accepted");
        assert_eq!(accepted.command, *c);
        assert_eq!(accepted.sent_t_ns, 1_000);
        let ack = accepted.ack(AckResult::Accepted, None);
        assert_eq!(
            (ack.command_sequence, ack.command_type),
            (i as u32 + 1, c.message_type())
        );
    }
    let n = commands.len() as u32;
    assert_eq!(
        *gate.counters(),
        LinkCounters {
            received: n,
            accepted: n,
            ..LinkCounters::default()
        }
    );
    assert_eq!(gate.last_accepted_ns(), Some(10 + u64::from(n) - 1));
}

#[test]
fn rejects_bad_crc() {
    let mut d = command(1, Command::Stop);
    d[HEADER_LEN - 1] ^= 0x01;
    assert_rejected(&[d], RejectReason::BadCrc);
    let mut d = command(1, Command::Stop);
    let last = d.len() - 1;
    d[last] ^= 0x80;
    assert_rejected(&[d], RejectReason::BadCrc);
    // A damaged tag is caught by the CRC too, not reported as a forgery.
    let mut d = command(1, Command::Stop);
    d[HEADER_LEN] ^= 0x01;
    assert_rejected(&[d], RejectReason::BadCrc);
}

#[test]
fn rejects_malformed_datagrams() {
    let key = example_key();
    let e = ground_envelope(1, 0);
    let stop = message_type::STOP;
    let cases: [StdVec<u8>; 10] = [
        // Empty, and shorter than a header and a CRC.
        StdVec::new(),
        command(1, Command::Stop)[..HEADER_LEN + CRC_LEN - 1].to_vec(),
        // Longer than a datagram may be.
        with_crc_fixed([command(1, Command::Stop), std::vec![0; 1500]].concat()),
        // Wrong magic, wrong version, a reserved flag.
        with_crc_fixed({
            let mut d = command(1, Command::Stop);
            d[0] = b'X';
            d
        }),
        with_crc_fixed({
            let mut d = command(1, Command::Stop);
            d[4] = 2;
            d
        }),
        raw_datagram(stop, 0x03, &e, &[], Some(&key)),
        // Payload length that disagrees with the datagram's.
        raw_datagram(stop, 0x01, &e, &[0], Some(&key))
            .into_iter()
            .enumerate()
            .map(|(i, b)| if i == 10 { 0 } else { b })
            .collect::<StdVec<u8>>(),
        // Telemetry sent to the vehicle.
        raw_datagram(message_type::TASK_DATA, 0x01, &e, &[0, 0, 0], Some(&key)),
        // Authentic, but the payload does not decode: a mode that does not exist, and a
        // trailing byte.
        raw_datagram(message_type::REQUEST_MODE, 0x01, &e, &[3], Some(&key)),
        raw_datagram(stop, 0x01, &e, &[0], Some(&key)),
    ];
    for (i, d) in cases.into_iter().enumerate() {
        let d = if i == 6 { with_crc_fixed(d) } else { d };
        assert_rejected(&[d], RejectReason::Malformed);
    }
}

#[test]
fn rejects_another_vehicles_commands() {
    let e = Envelope {
        vehicle_id: VEHICLE + 1,
        ..ground_envelope(1, 0)
    };
    let d = encode(&e, &Message::Command(Command::Stop), Some(&example_key()));
    assert_rejected(&[d], RejectReason::WrongVehicle);
}

#[test]
fn rejects_unsigned_commands() {
    let e = ground_envelope(1, 0);
    let d = encode(&e, &Message::Command(Command::Stop), None);
    assert_rejected(&[d], RejectReason::Unsigned);
}

#[test]
fn rejects_commands_signed_with_another_key() {
    let e = ground_envelope(1, 0);
    let other = LinkKey::new([0x55; 32]);
    let d = encode(&e, &Message::Command(Command::Stop), Some(&other));
    assert_rejected(&[d], RejectReason::BadSignature);
    // A correct tag on a changed header (sequence number 1 → 2, CRC recomputed).
    let mut d = command(1, Command::Stop);
    d[16] = 2;
    assert_rejected(&[with_crc_fixed(d)], RejectReason::BadSignature);
    // A forgery claiming sequence 9 spends nothing: the real 9 is still accepted.
    let (last, counters) = run(&[
        with_crc_fixed({
            let mut d = command(9, Command::Stop);
            d[HEADER_LEN + 3] ^= 1;
            d
        }),
        command(9, Command::Stop),
    ]);
    assert!(last.is_ok());
    assert_eq!((counters.bad_signature, counters.accepted), (1, 1));
}

#[test]
fn rejects_commands_from_another_run() {
    // Authentic, fresh sequence number, but recorded in the vehicle's previous run.
    let e = Envelope {
        run_id: RUN - 1,
        ..ground_envelope(1, 0)
    };
    let d = encode(&e, &Message::Command(Command::Stop), Some(&example_key()));
    assert_rejected(&[d], RejectReason::WrongRun);
    // It spends nothing: this run's sequence 1 is still accepted afterwards.
    let stale = encode(&e, &Message::Command(Command::Stop), Some(&example_key()));
    let (last, counters) = run(&[stale, command(1, Command::Stop)]);
    assert!(last.is_ok());
    assert_eq!((counters.wrong_run, counters.accepted), (1, 1));
}

#[test]
fn rejects_replays() {
    // The same datagram twice.
    let d = command(10, Command::Stop);
    assert_rejected(&[d.clone(), d], RejectReason::Replayed);
    // An older one after the window has moved 64 on.
    assert_rejected(
        &[command(74, Command::Stop), command(10, Command::Stop)],
        RejectReason::Replayed,
    );
    // A replayed malformed datagram counts as a replay: its number was spent.
    let e = ground_envelope(3, 0);
    let bad = raw_datagram(message_type::STOP, 1, &e, &[0], Some(&example_key()));
    let (last, counters) = run(&[bad.clone(), bad]);
    assert_eq!(last.map_err(|r| r.reason), Err(RejectReason::Replayed));
    assert_eq!((counters.malformed, counters.replayed), (1, 1));
    // Each sender has its own window: the same number from another sender is fine.
    let (last, _) = run(&[
        command(10, Command::Stop),
        command_from(2, 10, Command::Stop),
    ]);
    assert!(last.is_ok());
}

#[test]
fn rejects_a_new_sender_when_every_window_is_taken() {
    let mut datagrams: StdVec<StdVec<u8>> = (0..MAX_SENDERS as u8)
        .map(|sender| command_from(sender + 1, 1, Command::Stop))
        .collect();
    datagrams.push(command_from(200, 1, Command::Stop));
    assert_rejected(&datagrams, RejectReason::TooManySenders);
    // Known senders carry on.
    datagrams.push(command_from(1, 2, Command::Stop));
    let (last, _) = run(&datagrams);
    assert!(last.is_ok());
}

#[test]
fn rejects_out_of_range_arguments_with_an_ack() {
    use core::f32::consts::{FRAC_PI_2, PI};
    let horizon = |roll_rad: f32, pitch_rad: f32, confidence: f32| {
        Command::HorizonAttitude(HorizonAttitude {
            roll_rad,
            pitch_rad,
            confidence,
            capture_t_ns: 0,
        })
    };
    let cases = [
        telemetry_rate(TASKS as u8, 1000),
        telemetry_rate(0, 49),
        telemetry_rate(0, 3_600_001),
        Command::SetHealthPeriod { period_ms: 99 },
        Command::SetHealthPeriod { period_ms: 60_001 },
        horizon(PI * 1.01, 0.0, 0.5),
        horizon(0.0, -FRAC_PI_2 * 1.01, 0.5),
        horizon(0.0, 0.0, 1.01),
        horizon(f32::NAN, 0.0, 0.5),
        horizon(0.0, f32::INFINITY, 0.5),
        horizon(0.0, 0.0, f32::NAN),
        // Missions: as the mission file loader refuses them.
        Command::MissionItem {
            index: 1,
            count: 1,
            waypoint: flyable(0.0, 0.0),
        },
        Command::MissionItem {
            index: 0,
            count: 33,
            waypoint: flyable(0.0, 0.0),
        },
        Command::MissionItem {
            index: 0,
            count: 1,
            waypoint: flyable(f32::NAN, 0.0),
        },
        Command::MissionItem {
            index: 0,
            count: 1,
            waypoint: flyable(0.0, f32::INFINITY),
        },
        Command::MissionItem {
            index: 0,
            count: 1,
            waypoint: Waypoint {
                altitude_m: 19.0,
                ..flyable(0.0, 0.0)
            },
        },
        Command::MissionItem {
            index: 0,
            count: 1,
            waypoint: Waypoint {
                airspeed_mps: 40.0,
                ..flyable(0.0, 0.0)
            },
        },
        Command::MissionCommit {
            count: 0,
            switch_radius_m: 30.0,
            loiter_radius_m: 150.0,
            loiter_clockwise: true,
        },
        Command::MissionCommit {
            count: 33,
            switch_radius_m: 30.0,
            loiter_radius_m: 150.0,
            loiter_clockwise: true,
        },
        Command::MissionCommit {
            count: 2,
            switch_radius_m: 30.0,
            loiter_radius_m: 100.0,
            loiter_clockwise: true,
        },
        Command::MissionCommit {
            count: 2,
            switch_radius_m: f32::NAN,
            loiter_radius_m: 150.0,
            loiter_clockwise: true,
        },
        Command::MissionSetCurrent { index: 32 },
    ];
    for c in cases {
        let ack = assert_rejected(&[command(1, c)], RejectReason::OutOfRange).expect("acked");
        assert_eq!(ack.result, AckResult::OutOfRange);
        assert_eq!((ack.command_sender_id, ack.command_sequence), (GROUND, 1));
        assert_eq!(ack.command_type, c.message_type());
    }
    // A parameter out of its range: acknowledged with the value in force.
    let ack = assert_rejected(
        &[command(
            1,
            Command::SetParam {
                name: name("roll_gain"),
                value: Value::F32(2.5),
            },
        )],
        RejectReason::OutOfRange,
    )
    .expect("acked");
    assert_eq!(ack.result, AckResult::OutOfRange);
    assert_eq!(ack.value_in_force, Some(Value::F32(0.5)));
}

#[test]
fn rejects_unknown_parameters_with_an_ack() {
    for c in [
        Command::SetParam {
            name: name("yaw_gain"),
            value: Value::F32(1.0),
        },
        Command::GetParam {
            name: name("yaw_gain"),
        },
    ] {
        let ack = assert_rejected(&[command(1, c)], RejectReason::UnknownParam).expect("acked");
        assert_eq!(
            (ack.result, ack.value_in_force),
            (AckResult::UnknownParam, None)
        );
    }
}

#[test]
fn rejects_parameters_of_the_wrong_type_with_an_ack() {
    let c = Command::SetParam {
        name: name("log_imu"),
        value: Value::U32(1),
    };
    let ack = assert_rejected(&[command(1, c)], RejectReason::WrongType).expect("acked");
    assert_eq!(
        (ack.result, ack.value_in_force),
        (AckResult::WrongType, Some(Value::Bool(true)))
    );
}

#[test]
fn unauthenticated_rejections_get_no_ack() {
    let e = ground_envelope(1, 0);
    let unsigned = encode(&e, &Message::Command(Command::Stop), None);
    assert_eq!(assert_rejected(&[unsigned], RejectReason::Unsigned), None);
    let d = command(1, Command::Stop);
    assert_eq!(
        assert_rejected(&[d.clone(), d], RejectReason::Replayed),
        None
    );
}

// ---------------------------------------------------------------------------------------
// Replay window edge cases.

#[test]
fn replay_window_edges() {
    let mut w = ReplayWindow::new();
    // The first number is taken whatever it is.
    assert_eq!(w.accept(100), Ok(()));
    assert_eq!(w.accept(100), Err(ReplayError::Duplicate));
    // 63 behind is inside the window, 64 behind is not.
    assert_eq!(w.check(37), Ok(()));
    assert_eq!(w.check(36), Err(ReplayError::TooOld));
    assert_eq!(w.accept(37), Ok(()));
    assert_eq!(w.accept(37), Err(ReplayError::Duplicate));
    // Late but inside the window, once.
    assert_eq!(w.accept(99), Ok(()));
    assert_eq!(w.accept(99), Err(ReplayError::Duplicate));
    // Slide by one: 37 is now 64 behind.
    assert_eq!(w.accept(101), Ok(()));
    assert_eq!(w.check(37), Err(ReplayError::TooOld));
    assert_eq!(w.check(99), Err(ReplayError::Duplicate));
    assert_eq!(w.check(98), Ok(()));
    // Slide by 63: 101 sits at the window's far end, still remembered.
    assert_eq!(w.accept(164), Ok(()));
    assert_eq!(w.check(101), Err(ReplayError::Duplicate));
    assert_eq!(w.check(100), Err(ReplayError::TooOld));
    // Far ahead: everything before the new window is too old, the window is empty.
    assert_eq!(w.accept(1_000_000), Ok(()));
    assert_eq!(w.newest(), Some(1_000_000));
    assert_eq!(w.check(164), Err(ReplayError::TooOld));
    assert_eq!(w.check(999_937), Ok(()));
    assert_eq!(w.check(999_936), Err(ReplayError::TooOld));
    // Slide by exactly 64: the old newest falls out.
    assert_eq!(w.accept(1_000_064), Ok(()));
    assert_eq!(w.check(1_000_000), Err(ReplayError::TooOld));
    // At the top of the number space nothing newer exists: the sender must re-key.
    assert_eq!(w.accept(u32::MAX), Ok(()));
    assert_eq!(w.accept(u32::MAX), Err(ReplayError::Duplicate));
    // Near zero, "behind" must not underflow.
    let mut w = ReplayWindow::new();
    assert_eq!(w.accept(0), Ok(()));
    assert_eq!(w.accept(0), Err(ReplayError::Duplicate));
    assert_eq!(w.accept(1), Ok(()));
}

#[test]
fn replay_guard_keeps_one_window_per_sender() {
    let mut guard = ReplayGuard::new();
    assert_eq!(guard.accept(1, 5), Ok(()));
    assert_eq!(guard.accept(2, 5), Ok(()));
    assert_eq!(
        guard.accept(1, 5),
        Err(GuardError::Replay(ReplayError::Duplicate))
    );
    assert_eq!(guard.window(2).and_then(ReplayWindow::newest), Some(5));
    assert_eq!(guard.window(3), None);
}

// ---------------------------------------------------------------------------------------
// Decoding for the ground side.

#[test]
fn decode_checks_tags_as_asked() {
    let key = example_key();
    let other = LinkKey::new([9; 32]);
    let (e, m) = example_task_data();
    let unsigned = encode(&e, &m, None);
    let signed = encode(&e, &m, Some(&key));
    assert_eq!(signed.len(), unsigned.len() + TAG_LEN);
    assert!(decode_datagram(&unsigned, Verify::IfSigned(&key)).is_ok());
    assert_eq!(
        decode_datagram(&unsigned, Verify::Required(&key)).map(|_| ()),
        Err(FrameError::Unsigned)
    );
    assert_eq!(
        decode_datagram(&signed, Verify::IfSigned(&other)).map(|_| ()),
        Err(FrameError::BadSignature)
    );
    // Without a key a ground station can still show signed telemetry.
    assert!(decode_datagram(&signed, Verify::No).is_ok());
}

#[test]
fn task_status_takes_the_health_boards_fields() {
    let mut health = crate::executive::TaskHealth {
        initialised: true,
        running: true,
        releases: 10,
        resets: 2,
        ..Default::default()
    };
    health.overruns.frame = 3;
    health.exec.record(100, 1000);
    health.exec.record(300, 1000);
    let s = TaskStatus::from_health(4, &health, true);
    assert_eq!(
        (s.task_index, s.initialised, s.running, s.in_frame, s.alive),
        (4, true, true, false, true)
    );
    assert_eq!((s.releases, s.resets, s.overruns_frame), (10, 2, 3));
    assert_eq!((s.exec_mean_ns, s.exec_max_ns), (200, 300));
}

#[test]
fn payload_sizes_match_the_spec_table() {
    fn payload_len(message: Message) -> usize {
        encode(&Envelope::default(), &message, None).len() - HEADER_LEN - CRC_LEN
    }
    let long_name = name(&"n".repeat(MAX_NAME_LEN));
    let t = |m| payload_len(Message::Telemetry(m));
    let c = |m| payload_len(Message::Command(m));
    assert_eq!(
        t(Telemetry::ExecutiveStatus(ExecutiveStatus::default())),
        151
    );
    assert_eq!(
        t(Telemetry::TaskStatus(TaskStatus {
            name: long_name,
            ..TaskStatus::default()
        })),
        115
    );
    assert_eq!(
        t(Telemetry::ParamValue(ParamValue {
            index: 0,
            count: 1,
            name: long_name,
            value: Value::F64(0.0),
            min: Value::F64(0.0),
            max: Value::F64(0.0),
        })),
        64
    );
    assert_eq!(
        c(Command::SetParam {
            name: long_name,
            value: Value::F64(0.0)
        }),
        42
    );
    assert_eq!(c(Command::GetParam { name: long_name }), 33);
    assert_eq!(
        c(Command::SetTelemetryRate {
            task_index: 0,
            interval_ms: 0
        }),
        5
    );
    assert_eq!(c(Command::SetHealthPeriod { period_ms: 0 }), 4);
    assert_eq!(
        c(Command::RequestMode {
            mode: FlightMode::Manual
        }),
        1
    );
    assert_eq!(
        c(Command::HorizonAttitude(HorizonAttitude {
            roll_rad: 0.0,
            pitch_rad: 0.0,
            confidence: 0.0,
            capture_t_ns: 0
        })),
        20
    );
    assert_eq!(c(Command::ListParams) + c(Command::Stop), 0);
    assert_eq!(frame::MAX_PAYLOAD_LEN, 1408);
}

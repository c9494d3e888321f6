//! Everything that parses bytes from the radio, fed arbitrary bytes: it must never panic,
//! and whatever decodes must re-encode to the very same bytes (one encoding per message,
//! so a signature over the bytes is a signature over the meaning).
#![no_main]

use libfuzzer_sys::fuzz_target;
use skyframe_core::link::frame::{Verify, decode_datagram, encode_datagram};
use skyframe_core::link::messages::Message;
use skyframe_core::link::wire::Writer;
use skyframe_core::link::auth::screen_command;
use skyframe_core::link::ingress::IngressCounters;
use skyframe_core::link::{CommandGate, GateConfig, LinkCounters, LinkKey, ParamTable, Value};

/// The key of the worked examples in docs/link-protocol.md (bytes 0x00..=0x1f), so the
/// signed example in the seed corpus authenticates.
const KEY: [u8; 32] = {
    let mut key = [0u8; 32];
    let mut i = 0;
    while i < 32 {
        key[i] = i as u8;
        i += 1;
    }
    key
};

fuzz_target!(|data: &[u8]| {
    let key = LinkKey::new(KEY);

    // 1. Whole datagrams, as the ground and the vehicle see them.
    for verify in [Verify::No, Verify::IfSigned(&key)] {
        if let Ok((header, message)) = decode_datagram(data, verify) {
            let mut out = [0u8; 1472];
            let signing = if header.signed { Some(&key) } else { None };
            let len = encode_datagram(&header.envelope, &message, signing, &mut out)
                .expect("a decoded message encodes");
            if matches!(verify, Verify::IfSigned(_)) || !header.signed {
                assert_eq!(&out[..len], data, "decoded datagram re-encodes differently");
            }
        }
    }
    let mut params = ParamTable::new();
    let _ = params.define("gain", Value::F32(1.0), Value::F32(0.0), Value::F32(2.0));
    let mut gate = CommandGate::new(
        key.clone(),
        GateConfig {
            vehicle_id: 7,
            run_id: 0x1234_5678,
            task_count: 8,
        },
    );
    // The socket thread's screen (what it drops before queueing) and the gate agree: a
    // datagram the screen refuses, the gate refuses for the same reason.
    let screened = screen_command(data, &key, 7).map(|_| ());
    let gated = gate.accept(data, 0, &params);
    if let Err(reason) = screened {
        assert_eq!(gated.map(|_| ()).map_err(|r| r.reason), Err(reason));
        let ingress = IngressCounters::new();
        ingress.screened_out(reason);
        let all = ingress.added_to(&LinkCounters::default());
        assert_eq!((all.received, all.rejected()), (1, 1));
    }
    let c = gate.counters();
    assert_eq!(c.received, c.accepted + c.rejected());

    // 2. Payloads alone (most random datagrams die at the CRC): first byte is the type.
    if let Some((&message_type, payload)) = data.split_first() {
        if let Ok(message) = Message::decode_payload(message_type, payload) {
            let mut out = [0u8; 2048];
            let mut w = Writer::new(&mut out);
            message.encode_payload(&mut w).expect("a decoded payload encodes");
            assert_eq!(message.message_type(), message_type);
            assert_eq!(w.written(), payload, "decoded payload re-encodes differently");
        }
    }
});

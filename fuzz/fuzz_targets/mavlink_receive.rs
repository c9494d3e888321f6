//! The MAVLink endpoint's receive path (`shell/src/mavlink/ingress.rs`) fed arbitrary
//! datagrams: the `mavlink` crate's framing and parsing, the signature and replay check
//! (with and without a key), the target check, then what the endpoint does with what passes
//! (parameter ids and values, mission items translated to skyframe waypoints). It must never
//! panic, and every datagram must be counted: accepted or refused for a reason.
#![no_main]

use libfuzzer_sys::fuzz_target;
use skyframe_core::estimation::geo::{GeoPoint, LocalFrame};
use skyframe_core::link::messages::ValueType;
use skyframe_shell::mavlink::ingress::{Counters, Verifier, screen};
use skyframe_shell::mavlink::mav::MavMessage;
use skyframe_shell::mavlink::mission::mission_from_items;
use skyframe_shell::mavlink::params::{decode_value, id_from_bytes};

fuzz_target!(|data: &[u8]| {
    let home = LocalFrame::new(GeoPoint {
        latitude_deg: 47.397742,
        longitude_deg: 8.545594,
        altitude_m: 488.0,
    });
    for key in [None, Some([0x31u8; 32])] {
        let mut verifier = Verifier::new(key);
        let counters = Counters::default();
        let mut out = Vec::new();
        // Twice: the second pass meets the replay windows the first one filled.
        for _ in 0..2 {
            screen(data, 1, &mut verifier, &counters, 1 << 40, &mut out);
        }
        let c = counters.snapshot();
        // A datagram with no frame is counted malformed; each frame is counted once.
        assert!(c.accepted as usize == out.len());
        let mut items = Vec::new();
        for accepted in out {
            match accepted.message {
                MavMessage::PARAM_SET(s) => {
                    let _ = id_from_bytes(&s.param_id[..]);
                    for t in [
                        ValueType::Bool,
                        ValueType::I32,
                        ValueType::U32,
                        ValueType::F32,
                    ] {
                        let _ = decode_value(s.param_value, t);
                    }
                }
                MavMessage::PARAM_REQUEST_READ(r) => {
                    let _ = id_from_bytes(&r.param_id[..]);
                }
                MavMessage::MISSION_ITEM_INT(i) => items.push(i),
                _ => {}
            }
        }
        if let Some(home) = &home {
            let _ = mission_from_items(&items, home, 25.0);
        }
    }
});

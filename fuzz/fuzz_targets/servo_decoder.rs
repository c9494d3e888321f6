#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use skyframe_core::devices::servo::{
    COMMAND_FRAME_TYPE, COMMAND_PAYLOAD_LEN, PILOT_FRAME_TYPE, PILOT_PAYLOAD_LEN,
    ServoCommandDecoder, ServoDecoder,
};

// Both directions: the flight side's decoder and the simulator's.
fuzz_target!(|data: &[u8]| {
    let Some((&seed, rest)) = data.split_first() else {
        return;
    };
    if seed & 0x80 == 0 {
        common::whole_and_chunked(ServoDecoder::default, seed, rest);
        common::whole_and_chunked(ServoCommandDecoder::default, seed, rest);
    } else {
        let pilot = common::scripted_stream(rest, PILOT_FRAME_TYPE, PILOT_PAYLOAD_LEN, None);
        common::whole_and_chunked(ServoDecoder::default, seed, &pilot);
        let commands = common::scripted_stream(rest, COMMAND_FRAME_TYPE, COMMAND_PAYLOAD_LEN, None);
        common::whole_and_chunked(ServoCommandDecoder::default, seed, &commands);
    }
});

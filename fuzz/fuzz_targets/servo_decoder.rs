#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use skyframe_core::devices::servo::{ServoCommandDecoder, ServoDecoder};

// Both directions: the flight side's decoder and the simulator's.
fuzz_target!(|data: &[u8]| {
    common::whole_and_chunked(ServoDecoder::default, data);
    common::whole_and_chunked(ServoCommandDecoder::default, data);
});

#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use skyframe_core::devices::imu::ImuDecoder;

fuzz_target!(|data: &[u8]| {
    common::whole_and_chunked(ImuDecoder::default, data);
});

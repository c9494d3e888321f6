#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use skyframe_core::devices::imu::{IMU_FRAME_TYPE, IMU_PAYLOAD_LEN, ImuDecoder};

/// Payload offset of the slow record slot index.
const SLOT_INDEX_OFFSET: usize = 13;

fuzz_target!(|data: &[u8]| {
    let Some((&seed, rest)) = data.split_first() else {
        return;
    };
    if seed & 0x80 == 0 {
        common::whole_and_chunked(ImuDecoder::default, seed, rest);
    } else {
        let stream = common::scripted_stream(
            rest,
            IMU_FRAME_TYPE,
            IMU_PAYLOAD_LEN,
            Some(SLOT_INDEX_OFFSET),
        );
        common::whole_and_chunked(ImuDecoder::default, seed, &stream);
    }
});

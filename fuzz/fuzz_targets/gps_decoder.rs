#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use skyframe_core::devices::gps::{GpsConfig, NmeaDecoder, SentenceKind};

fuzz_target!(|data: &[u8]| {
    let fixes = common::whole_and_chunked(NmeaDecoder::default, data);
    for fix in &fixes {
        assert!(fix.velocity_ned_mps.iter().flatten().all(|v| v.is_finite()));
    }
    // The early-emit path too.
    let mut decoder = NmeaDecoder::new(GpsConfig {
        epoch_end: Some(SentenceKind::Rmc),
        ..GpsConfig::default()
    });
    decoder.push(data, 0, |_| {});
    decoder.flush(|_| {});
});

#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use skyframe_core::devices::gps::{GpsConfig, NmeaDecoder, SentenceKind};

fuzz_target!(|data: &[u8]| {
    let Some((&seed, stream)) = data.split_first() else {
        return;
    };
    let fixes = common::whole_and_chunked(NmeaDecoder::default, seed, stream);
    for fix in &fixes {
        assert!(fix.velocity_ned_mps.iter().flatten().all(|v| v.is_finite()));
    }
    // The early-emit path too.
    let mut decoder = NmeaDecoder::new(GpsConfig {
        epoch_end: Some(SentenceKind::Rmc),
        ..GpsConfig::default()
    });
    decoder.push(stream, 0, |_| {});
    decoder.flush(|_| {});
});

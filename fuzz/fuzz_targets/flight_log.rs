//! Any bytes through `skyframe replay`'s flight-log readers (PX4 ULog through the
//! `px4-ulog` crate, ArduPilot DataFlash through ours): an error or a log, never a panic or
//! a hang; an error is one line naming the byte offset. A log that reads and spans at most
//! a few seconds is replayed as well, so whatever values the readers let through go
//! through the frame table, the estimator and the agreement too.
//!
//! The first byte picks the reader; its magic is put in front of the rest when missing, so
//! the fuzzer spends its time past the header.

#![no_main]

use libfuzzer_sys::fuzz_target;
use skyframe_shell::replay::{RunOptions, StartMode, dataflash, replay, ulog};

const ULOG_HEADER: [u8; 16] = *b"ULog\x01\x12\x35\x01\0\0\0\0\0\0\0\0";
const DATAFLASH_HEAD: [u8; 2] = [0xA3, 0x95];

fuzz_target!(|input: &[u8]| {
    let Some((&selector, rest)) = input.split_first() else {
        return;
    };
    let result = if selector & 1 == 0 {
        let bytes = if rest.starts_with(&ULOG_HEADER[..7]) {
            rest.to_vec()
        } else {
            [&ULOG_HEADER[..], rest].concat()
        };
        ulog::read("fuzz", &bytes)
    } else {
        let bytes = if rest.starts_with(&DATAFLASH_HEAD) {
            rest.to_vec()
        } else {
            [&DATAFLASH_HEAD[..], rest].concat()
        };
        dataflash::read("fuzz", &bytes)
    };
    match result {
        Err(message) => {
            assert!(!message.contains('\n'), "an error is one line: {message}");
            assert!(message.starts_with("fuzz: byte "), "names the offset: {message}");
        }
        Ok(log) => {
            let span = match (log.imu.first(), log.imu.last()) {
                (Some(a), Some(b)) => b.t_us.saturating_sub(a.t_us),
                _ => u64::MAX,
            };
            if span <= 3_000_000 && selector & 2 == 0 {
                let options = RunOptions {
                    start: if selector & 4 == 0 {
                        StartMode::Auto
                    } else {
                        StartMode::Onboard
                    },
                    gps_latency_ms: None,
                    gps_velocity_sd_m_s: None,
                };
                let _ = replay("fuzz", &log, options);
            }
        }
    }
});

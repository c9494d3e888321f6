//! Power-cut and kill -9 durability of the log writer: a child logs at full rate and is
//! killed with SIGKILL at random moments; every record it reported as fsynced must be in the
//! file, in order, and everything in the file must be whole records but for a torn tail.

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use skyframe_tests::{binary, scratch};
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Whole records at the start of the file (the format definition, then `(sequence,
/// !sequence)` data records), and the length of the torn rest.
fn read_back(bytes: &[u8]) -> (u64, usize) {
    // The format definition first: 0xFD, 1, len, "%u,%u".
    let mut at = 4 + usize::from(u16::from_le_bytes([bytes[2], bytes[3]]));
    let mut expected: u32 = 0;
    while bytes.len() - at >= 20 {
        let r = &bytes[at..at + 20];
        assert_eq!(
            (r[0], r[1], r[2], r[3]),
            (0xDB, 1, 8, 0),
            "whole records only, at {at}"
        );
        let seq = u32::from_le_bytes(r[12..16].try_into().expect("4"));
        let inv = u32::from_le_bytes(r[16..20].try_into().expect("4"));
        assert_eq!(
            (seq, inv),
            (expected, !expected),
            "records in order, intact, at {at}"
        );
        expected += 1;
        at += 20;
    }
    (1 + u64::from(expected), bytes.len() - at)
}

#[test]
fn records_fsynced_before_sigkill_are_always_there() {
    let stress = binary("skyframe-tests", "log-stress");
    // A fixed sequence of "random" kill moments (20-400 ms): reproducible, spread out.
    let mut state: u64 = 0x2545_F491_4F6C_DD1D;
    let mut rounds_with_synced_records = 0;
    for round in 0..8 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let kill_after = Duration::from_millis(20 + state % 380);
        let dir = scratch(&format!("durability-{round}"));
        let mut child = Command::new(&stress)
            .arg(&dir)
            .stdout(Stdio::piped())
            .spawn()
            .expect("spawns");
        let mut lines = BufReader::new(child.stdout.take().expect("stdout")).lines();
        let start = Instant::now();
        let mut synced = 0u64;
        while start.elapsed() < kill_after {
            match lines.next() {
                Some(Ok(line)) => {
                    if let Some(n) = line.strip_prefix("synced ").and_then(|n| n.parse().ok()) {
                        synced = n;
                    }
                }
                _ => break,
            }
        }
        kill(Pid::from_raw(child.id() as i32), Signal::SIGKILL).expect("kill");
        let _ = child.wait();
        let bytes = std::fs::read(dir.join("stress.bin")).expect("the log exists");
        let (records, torn) = read_back(&bytes);
        assert!(
            records >= synced,
            "round {round}: {records} records < {synced} reported synced"
        );
        assert!(
            torn < 20,
            "round {round}: only a partial last record may be torn"
        );
        if synced > 0 {
            rounds_with_synced_records += 1;
        }
    }
    // The guarantee is only tested when the child had fsynced something before the kill.
    assert!(
        rounds_with_synced_records >= 6,
        "only {rounds_with_synced_records} of 8 rounds saw an fsync"
    );
}

//! Test logs built by hand, byte by byte, from `log-format.md` (not by the core's encoder),
//! and the binary under test.

use std::process::{Command, Output};

/// `skyframe-log ARGS`, run to its end.
pub fn skyframe_log(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_skyframe-log"))
        .args(args)
        .output()
        .expect("the binary runs")
}

pub fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// A log with the spec's example (format 1) and a byte array format (2) written with both
/// type bytes, 0xBA and 0xDA. Offsets: BD 0, FD 12, FC 31, DB 54, FD 84, FC 95, BA 103,
/// DA 118, ED 131; 143 bytes.
#[rustfmt::skip]
pub const WHOLE: &[u8] = &[
    // Begin Data at 1.000000000
    0xBD, 0, 0, 0,  1, 0, 0, 0,  0, 0, 0, 0,
    // Format Definition 1, 15 bytes
    0xFD, 1, 15, 0,
    b'%', b'u', b',', b'%', b'h', b'd', b',', b'%', b'.', b'3', b'f', b',', b'%', b'l', b'f',
    // Format Comment 1, 19 bytes
    0xFC, 1, 19, 0,
    b'c', b'o', b'u', b'n', b't', b',', b'd', b'e', b'l', b't', b'a', b',',
    b'x', b'_', b'm', b',', b'y', b'_', b'm',
    // Data Block 1, 18 bytes, at 1.500000000: 7u32, -2i16, 1.5f32, 0.25f64
    0xDB, 1, 18, 0,  1, 0, 0, 0,  0x00, 0x65, 0xCD, 0x1D,
    7, 0, 0, 0,  0xFE, 0xFF,  0x00, 0x00, 0xC0, 0x3F,  0, 0, 0, 0, 0, 0, 0xD0, 0x3F,
    // Format Definition 2, "%02hhx" with a trailing NUL (ignored)
    0xFD, 2, 7, 0,  b'%', b'0', b'2', b'h', b'h', b'x', 0,
    // Format Comment 2, "byte"
    0xFC, 2, 4, 0,  b'b', b'y', b't', b'e',
    // Byte Array 2 (0xBA), 3 bytes, at 2.000000005
    0xBA, 2, 3, 0,  2, 0, 0, 0,  5, 0, 0, 0,  0x0A, 0xFF, 0x00,
    // Byte Array 2 (0xDA, the thesis's name), 1 byte, at 2.000000006
    0xDA, 2, 1, 0,  2, 0, 0, 0,  6, 0, 0, 0,  0x7F,
    // End Data at 3.000000000
    0xED, 0, 0, 0,  3, 0, 0, 0,  0, 0, 0, 0,
];

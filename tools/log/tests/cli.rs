//! Runs the real `skyframe-log` binary on files built by hand, byte by byte, from the spec
//! (not by the core's encoder), and checks its output byte for byte.

use std::path::Path;

#[allow(dead_code)] // shared with ulog.rs and plot.rs: each test crate uses part of it
mod common;

use common::{WHOLE, skyframe_log, stderr};

const CSV_1: &str = "% format 1: %u,%hd,%.3f,%lf\n\
                     % time,count,delta,x_m,y_m\n\
                     1.500000000,7,-2,1.500,0.250000\n";
const CSV_2: &str = "% format 2: %02hhx\n\
                     % time,byte\n\
                     2.000000005,0a,ff,00\n\
                     2.000000006,7f\n";

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn whole_file_converts_exactly() {
    assert_eq!(WHOLE.len(), 143);
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("flight.bin");
    std::fs::write(&log, WHOLE).expect("write");
    let out = dir.path().join("csv");
    let output = skyframe_log(&[
        "to-csv",
        log.to_str().expect("utf-8"),
        "--out-dir",
        out.to_str().expect("utf-8"),
    ]);
    assert_eq!(output.status.code(), Some(0), "stderr: {}", stderr(&output));
    assert_eq!(stderr(&output), "");
    assert_eq!(read(&out.join("flight.1.csv")), CSV_1);
    assert_eq!(read(&out.join("flight.2.csv")), CSV_2);
    let mut names: Vec<_> = std::fs::read_dir(&out)
        .expect("list")
        .map(|e| e.expect("entry").file_name())
        .collect();
    names.sort();
    assert_eq!(names, ["flight.1.csv", "flight.2.csv"]);
}

#[test]
fn directories_convert_beside_the_inputs() {
    let dir = tempfile::tempdir().expect("temp dir");
    std::fs::write(dir.path().join("a.bin"), WHOLE).expect("write");
    std::fs::write(dir.path().join("b.log"), WHOLE).expect("write");
    // A flight directory's other files are not logs.
    std::fs::write(dir.path().join("link.key"), "00".repeat(32)).expect("write");
    std::fs::write(dir.path().join("vehicle.toml"), "[devices]\n").expect("write");
    let output = skyframe_log(&["to-csv", dir.path().to_str().expect("utf-8")]);
    assert_eq!(output.status.code(), Some(0), "stderr: {}", stderr(&output));
    for stem in ["a", "b"] {
        assert_eq!(read(&dir.path().join(format!("{stem}.1.csv"))), CSV_1);
        assert_eq!(read(&dir.path().join(format!("{stem}.2.csv"))), CSV_2);
    }
    // Converting again skips the CSVs it wrote and gives the same files.
    let output = skyframe_log(&["to-csv", dir.path().to_str().expect("utf-8")]);
    assert_eq!(output.status.code(), Some(0), "stderr: {}", stderr(&output));
    assert_eq!(read(&dir.path().join("a.1.csv")), CSV_1);
}

/// A log file `name` holding `bytes`, in a directory of its own.
fn log_in_dir(name: &str, bytes: &[u8]) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join(name);
    std::fs::write(&log, bytes).expect("write");
    (dir, log)
}

/// `to-csv` of a damaged log: exit 3, and what it said on stderr.
fn to_csv_damaged(log: &std::path::Path) -> String {
    let output = skyframe_log(&["to-csv", log.to_str().expect("utf-8")]);
    assert_eq!(output.status.code(), Some(3));
    stderr(&output)
}

/// `to-csv` of a whole log: exit 0.
fn to_csv_whole(log: &std::path::Path) {
    let output = skyframe_log(&["to-csv", log.to_str().expect("utf-8")]);
    assert_eq!(output.status.code(), Some(0), "stderr: {}", stderr(&output));
}

/// The example log with power lost in the middle of its first byte array (offset 103, 15
/// bytes long).
fn cut_log() -> (tempfile::TempDir, std::path::PathBuf) {
    log_in_dir("cut.bin", &WHOLE[..110])
}

#[test]
fn truncated_tail_keeps_what_came_before_and_exits_3() {
    let (dir, log) = cut_log();
    let path = log.display();
    assert_eq!(
        to_csv_damaged(&log),
        format!(
            "{path}: offset 103: truncated record: type 0xBA needs 15 bytes but the file ends \
             after 7; \
             skipped to offset 110\n\
             {path}: offset 110: no final End Data: the file was not closed cleanly\n"
        )
    );
    assert_eq!(read(&dir.path().join("cut.1.csv")), CSV_1);
    assert!(!dir.path().join("cut.2.csv").exists());
}

#[test]
fn garbage_and_bad_records_are_reported_with_offsets() {
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("bad.bin");
    let mut bytes = WHOLE[..54].to_vec();
    bytes.extend_from_slice(&[0x13, 0x37, 0x00, 0xDB, 0x01]); // garbage at 54..59
    bytes.extend_from_slice(&WHOLE[54..84]); // the data block, now at 59
    // A data block of format 1 with 2 bytes (its format needs 18), at 89.
    bytes.extend_from_slice(&[0xDB, 1, 2, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0xAA, 0xBB]);
    // Data of format 9, never defined, at 103.
    bytes.extend_from_slice(&[0xDB, 9, 1, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0xCC]);
    bytes.extend_from_slice(&WHOLE[131..]); // End Data at 116
    std::fs::write(&log, &bytes).expect("write");
    let path = log.display();
    assert_eq!(
        to_csv_damaged(&log),
        format!(
            "{path}: offset 54: unknown record type 0x13; skipped to offset 59\n\
             {path}: offset 89: data block of format 1 has 2 bytes, its format needs 18; \
             skipped to offset 103\n\
             {path}: offset 103: data of format 9 before its format definition; record skipped\n"
        )
    );
    assert_eq!(read(&dir.path().join("bad.1.csv")), CSV_1);
}

#[test]
fn percent_c_writes_raw_bytes_like_c() {
    #[rustfmt::skip]
    let bytes: &[u8] = &[
        0xFD, 4, 2, 0,  b'%', b'c',
        0xBA, 4, 3, 0,  0, 0, 0, 0,  0, 0, 0, 0,  b'A', 0xE9, b',',
        0xED, 0, 0, 0,  0, 0, 0, 0,  0, 0, 0, 0,
    ];
    let (dir, log) = log_in_dir("chars.bin", bytes);
    to_csv_whole(&log);
    let csv = std::fs::read(dir.path().join("chars.4.csv")).expect("read");
    assert_eq!(csv, b"% format 4: %c\n0.000000000,A,\xE9,,\n");
}

#[test]
fn info_summarises_a_file() {
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("flight.bin");
    std::fs::write(&log, WHOLE).expect("write");
    let output = skyframe_log(&["info", log.to_str().expect("utf-8")]);
    assert_eq!(output.status.code(), Some(0), "stderr: {}", stderr(&output));
    let expected = format!(
        "{} (143 bytes)
  formats:
    1 (offset 12): %u,%hd,%.3f,%lf
      columns: count,delta,x_m,y_m
    2 (offset 84): %02hhx
      columns: byte
  records per format:
    1: data blocks 1
    2: data blocks 0, byte arrays 2
  time span: 1.000000000 to 3.000000000 (2.000000000 s)
  largest time step: 0.999999994 s, to the record at offset 131
  gaps: none
  Begin/End pairs:
    begin 1.000000000 (offset 0) to end 3.000000000 (offset 131): 2.000000000 s
  closed cleanly: yes
  damage: none
",
        log.display()
    );
    assert_eq!(String::from_utf8_lossy(&output.stdout), expected);
    // The two byte arrays of format 2 are 1 ns apart.
    let output = skyframe_log(&[
        "info",
        "--gap-s",
        "0.0000000005",
        log.to_str().expect("utf-8"),
    ]);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("  gaps: 1\n    format 2: 0.000000001 s between offsets 103 and 118\n"),
        "{stdout}"
    );
}

#[test]
fn info_reports_damage_and_exits_3() {
    let (_dir, log) = cut_log();
    let output = skyframe_log(&["info", log.to_str().expect("utf-8")]);
    assert_eq!(output.status.code(), Some(3));
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("  closed cleanly: no (no final End Data)\n"),
        "{stdout}"
    );
    assert!(
        stdout.contains("  damage: problems 1, bytes skipped 7\n    offset 103..110: truncated record: type 0xBA needs 15 bytes"),
        "{stdout}"
    );
    assert_eq!(stderr(&output).lines().count(), 2);
}

#[test]
fn usage_and_io_errors_exit_2() {
    assert_eq!(skyframe_log(&[]).status.code(), Some(2));
    assert_eq!(skyframe_log(&["to-csv"]).status.code(), Some(2));
    let output = skyframe_log(&["info", "/nonexistent/flight.bin"]);
    assert_eq!(output.status.code(), Some(2));
    assert_eq!(stderr(&output).lines().count(), 1, "{}", stderr(&output));
    let help = skyframe_log(&["--help"]);
    assert_eq!(help.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&help.stdout).contains("to-csv"));
}

#[test]
fn random_bytes_never_panic() {
    let dir = tempfile::tempdir().expect("temp dir");
    // A deterministic pseudo-random file, with pieces of real records mixed in.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut bytes = Vec::new();
    for i in 0..20_000 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        bytes.push((state >> 24) as u8);
        if i % 997 == 0 {
            bytes.extend_from_slice(&WHOLE[(i % 130)..]);
        }
    }
    let log = dir.path().join("noise.bin");
    std::fs::write(&log, &bytes).expect("write");
    for command in ["info", "to-csv"] {
        let output = skyframe_log(&[command, log.to_str().expect("utf-8")]);
        assert_eq!(
            output.status.code(),
            Some(3),
            "{command}: {}",
            stderr(&output)
        );
    }
}

#[test]
fn redefinitions_print_new_header_lines_only_when_the_format_changes() {
    #[rustfmt::skip]
    let bytes: &[u8] = &[
        0xFD, 1, 2, 0,  b'%', b'd',
        0xFC, 1, 1, 0,  b'a',
        0xDB, 1, 4, 0,  1, 0, 0, 0,  0, 0, 0, 0,  1, 0, 0, 0,
        // The same definition again (a task restarting): no new header.
        0xFD, 1, 2, 0,  b'%', b'd',
        0xDB, 1, 4, 0,  2, 0, 0, 0,  0, 0, 0, 0,  2, 0, 0, 0,
        // A new layout for index 1, without a comment of its own: the old one stays.
        0xFD, 1, 4, 0,  b'%', b'h', b'h', b'x',
        0xDB, 1, 1, 0,  3, 0, 0, 0,  0, 0, 0, 0,  0xAB,
        0xED, 0, 0, 0,  4, 0, 0, 0,  0, 0, 0, 0,
    ];
    let (dir, log) = log_in_dir("redef.bin", bytes);
    to_csv_whole(&log);
    assert_eq!(
        read(&dir.path().join("redef.1.csv")),
        "% format 1: %d\n% time,a\n1.000000000,1\n2.000000000,2\n\
         % format 1: %hhx\n% time,a\n3.000000000,ab\n"
    );
}

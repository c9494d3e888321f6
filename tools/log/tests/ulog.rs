//! `to-ulog` checked with pyulog, PX4's own reader. Skipped (with a message saying so) only
//! when pyulog is not installed: `pip install pyulog`.

#[allow(dead_code)] // shared with cli.rs and plot.rs: each test crate uses part of it
mod common;

use std::process::Command;

use common::{WHOLE, skyframe_log, stderr};

const DUMP: &str = r#"
import sys
from pyulog import ULog
log = ULog(sys.argv[1])
print(log.msg_info_dict.get("sys_name"))
for d in sorted(log.data_list, key=lambda d: d.name):
    names = [f.field_name for f in d.field_data]
    print(d.name, ",".join(names))
    for i in range(len(d.data["timestamp"])):
        print(",".join(repr(d.data[k][i].item()) for k in names))
"#;

fn pyulog_available() -> bool {
    Command::new("python3")
        .args(["-c", "import pyulog"])
        .output()
        .is_ok_and(|o| o.status.success())
}

#[test]
fn ulog_reads_back_with_pyulog() {
    if !pyulog_available() {
        // CI installs pyulog (.ci/run): there a missing pyulog is a failure, not a skip.
        assert!(
            std::env::var_os("CI").is_none(),
            "pyulog is required in CI (pip install pyulog)"
        );
        eprintln!(
            "SKIPPED ulog_reads_back_with_pyulog: pyulog is not installed (pip install pyulog)"
        );
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("flight.bin");
    let mut bytes = WHOLE[..131].to_vec();
    // A redefinition of format 1 with a column named `timestamp`, then its data at 2.25 s.
    let text = b"%lld;%hhu";
    bytes.extend_from_slice(&[0xFD, 1, text.len() as u8, 0]);
    bytes.extend_from_slice(text);
    let comment = b"timestamp,mode id";
    bytes.extend_from_slice(&[0xFC, 1, comment.len() as u8, 0]);
    bytes.extend_from_slice(comment);
    bytes.extend_from_slice(&[0xDB, 1, 9, 0, 2, 0, 0, 0, 0x80, 0xB2, 0xE6, 0x0E]);
    bytes.extend_from_slice(&(-5i64).to_le_bytes());
    bytes.push(200);
    bytes.extend_from_slice(&WHOLE[131..]);
    std::fs::write(&log, &bytes).expect("write");
    let ulg = dir.path().join("flight.ulg");
    let output = skyframe_log(&[
        "to-ulog",
        log.to_str().expect("utf-8"),
        "-o",
        ulg.to_str().expect("utf-8"),
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(
        stderr(&output),
        format!(
            "skyframe-log: note: {}: 2 byte arrays not converted (ULog has no variable-length \
             messages)\n",
            log.display()
        )
    );
    let dump = Command::new("python3")
        .args(["-c", DUMP, ulg.to_str().expect("utf-8")])
        .output()
        .expect("python runs");
    assert!(
        dump.status.success(),
        "{}",
        String::from_utf8_lossy(&dump.stderr)
    );
    assert_eq!(
        String::from_utf8_lossy(&dump.stdout),
        "skyframe\n\
         skyframe_flight timestamp,count,delta,x_m,y_m\n\
         500000,7,-2,1.5,0.25\n\
         skyframe_flight_1 timestamp,timestamp_log,mode_id\n\
         1250000,-5,200\n"
    );
}

//! `bench --json` on a short synthetic flight: the record counts follow the streams' rates,
//! binary sizes are the format's header + fields, text sizes are the CSV's, and pyulog's
//! ulog2csv is timed on the ULog export when it is installed.

use std::process::Command;

#[test]
fn bench_json_reports_sizes_rates_and_timings() {
    let dir = tempfile::tempdir().expect("temp dir");
    let keep = dir.path().join("flight");
    let output = Command::new(env!("CARGO_BIN_EXE_skyframe-log"))
        .args(["bench", "--json", "--minutes", "0.1", "--runs", "1"])
        .arg("--keep-flight")
        .arg(&keep)
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "stderr: {err}");
    let r: serde_json::Value = serde_json::from_slice(&output.stdout).expect("json");

    // 6 s of flight at the streams' rates.
    let formats = r["formats"].as_array().expect("formats");
    let find = |stream: &str, index: u64| {
        formats
            .iter()
            .find(|f| f["stream"] == stream && f["index"] == index)
            .unwrap_or_else(|| panic!("{stream}.{index} missing"))
    };
    for (stream, index, records, data_len) in [
        ("executive", 1, 600, 16 + 4 * 9 + 1 + 4 * 5),
        ("imu", 1, 600, 1 + 6 * 4 + 1),
        ("imu", 2, 6, 2 + 4 + 4 + 2 + 6 * 4 + 2),
        ("gps", 1, 60, 3 + 3 * 8 + 9 * 4 + 4),
        ("servo", 1, 300, 1 + 8 * 2 + 1 + 6 * 4),
        ("servo", 2, 300, 1 + 4 * 4),
        ("health", 1, 30, 5 + 8 + 6 * 4 + 2 * 4 + 4),
    ] {
        let f = find(stream, index);
        assert_eq!(f["records"], records, "{stream}.{index}");
        assert_eq!(
            f["binary_bytes_per_record"].as_f64(),
            Some(f64::from(12 + data_len)),
            "{stream}.{index}"
        );
        let text = f["text_bytes_per_record"].as_f64().expect("text");
        let saving = f["saving_percent"].as_f64().expect("saving");
        assert!(
            (saving - 100.0 * (1.0 - f64::from(12 + data_len) / text)).abs() < 1e-9,
            "{stream}.{index}"
        );
    }
    // The text size is the CSV's: every data line of imu.1 as to-csv wrote it.
    let records: u64 = formats
        .iter()
        .map(|f| f["records"].as_u64().expect("n"))
        .sum();
    assert_eq!(r["records"], records);
    let imu_bin = std::fs::metadata(keep.join("imu.bin")).expect("kept").len();
    assert!(imu_bin > 600 * 38);
    let to_csv = &r["to_csv"];
    assert!(to_csv["best_s"].as_f64().expect("best") > 0.0);
    assert!(to_csv["mb_per_s"].as_f64().expect("MB/s") > 0.0);
    let binary: u64 = ["executive", "imu", "gps", "servo", "health"]
        .iter()
        .map(|s| {
            std::fs::metadata(keep.join(format!("{s}.bin")))
                .expect("kept")
                .len()
        })
        .sum();
    assert_eq!(r["binary_bytes"], binary);
    assert_eq!(to_csv["input_bytes"], binary);

    let pyulog = Command::new("python3")
        .args(["-c", "import pyulog"])
        .output()
        .is_ok_and(|o| o.status.success());
    if pyulog {
        assert!(r["ulog2csv"]["timing"]["best_s"].as_f64().expect("timed") > 0.0);
        assert!(r["ulog2csv_over_to_csv_time"].as_f64().expect("ratio") > 0.0);
        // One ULog per flight, as `to-ulog FLIGHT_DIR` writes it.
        assert_eq!(r["ulog2csv"]["files"], 1);
        assert!(
            r["ulog2csv"]["in_process_best_s"]
                .as_f64()
                .expect("in process")
                > 0.0
        );
        assert!(
            r["pyulog_in_process_over_to_csv_time"]
                .as_f64()
                .expect("ratio")
                > 0.0
        );
    } else {
        assert!(std::env::var_os("CI").is_none(), "CI installs pyulog");
        assert!(r["ulog2csv_unavailable"].is_string());
    }
}

//! A real simulated flight through `skyframe-log to-ulog`, read back with PX4's own reader
//! (pyulog): the contract between what the vehicle logs and what the field's tools see. The
//! converter's own tests (tools/log/tests) check the mapping on synthetic logs; this one
//! checks it on the formats the tasks actually write, so a change to a task's record that
//! the converter does not follow fails here.

use skyframe_tests::{binary, csv_column, run_ok, scratch, skyframe, to_csv};
use std::process::Command;

#[test]
fn a_simulated_flight_reads_back_in_pyulog_with_px4_topics_equal_to_the_log() {
    let dir = scratch("ulog-flight");
    let out = run_ok(
        skyframe()
            .args(["sim", "--fast", "--duration", "30", "--no-link", "--json"])
            .arg("--log-dir")
            .arg(&dir),
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("report");
    let flight = std::path::PathBuf::from(report["flight_dir"].as_str().expect("dir"));
    let ulog = dir.join("flight.ulg");
    run_ok(
        Command::new(binary("skyframe-log", "skyframe-log"))
            .arg("to-ulog")
            .arg(&flight)
            .arg("-o")
            .arg(&ulog),
    );
    let csv = to_csv(&[&flight], &dir.join("csv"));

    // pyulog prints the columns we compare, one value per line, topic by topic.
    let script = r#"
import sys
from pyulog import ULog
u = ULog(sys.argv[1])
def col(topic, field):
    d = u.get_dataset(topic).data[field]
    print(topic + "." + field, ",".join(repr(float(v)) for v in d))
col("sensor_combined", "gyro_rad[0]")
col("sensor_combined", "accelerometer_m_s2[2]")
col("vehicle_attitude", "q[0]")
col("vehicle_attitude", "q[3]")
print("params", len(u.initial_parameters))
"#;
    let py = Command::new("python3")
        .arg("-c")
        .arg(script)
        .arg(&ulog)
        .output()
        .expect("python3 runs");
    assert!(
        py.status.success(),
        "pyulog: {}",
        String::from_utf8_lossy(&py.stderr)
    );
    let text = String::from_utf8_lossy(&py.stdout);
    let series = |key: &str| -> Vec<f64> {
        text.lines()
            .find_map(|l| l.strip_prefix(&format!("{key} ")))
            .unwrap_or_else(|| panic!("{key}: {text}"))
            .split(',')
            .map(|v| v.parse().expect("number"))
            .collect()
    };
    // The CSV prints %.4f (IMU) and %.6f (quaternion): equal within that rounding.
    for (key, csv_file, column, tolerance) in [
        (
            "sensor_combined.gyro_rad[0]",
            "imu.1.csv",
            "p_rad_s",
            5.1e-5,
        ),
        (
            "sensor_combined.accelerometer_m_s2[2]",
            "imu.1.csv",
            "fz_m_s2",
            5.1e-5,
        ),
        ("vehicle_attitude.q[0]", "estimator.1.csv", "qw", 5.1e-7),
        ("vehicle_attitude.q[3]", "estimator.1.csv", "qz", 5.1e-7),
    ] {
        let from_ulog = series(key);
        let from_log = csv_column(&csv.join(csv_file), column);
        assert_eq!(from_ulog.len(), from_log.len(), "{key}: record counts");
        assert!(from_log.len() > 1000, "{key}: {} records", from_log.len());
        let worst = from_ulog
            .iter()
            .zip(&from_log)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst <= tolerance, "{key} differs from {column} by {worst}");
    }
    // The 23 control gains in force at start are the ULog's parameters.
    assert!(text.contains("params 23"), "{text}");
}

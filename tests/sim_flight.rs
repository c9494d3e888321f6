//! `skyframe sim`: the whole on-board system flying the simulated airplane, its devices
//! speaking the hardware protocols through the same decoders.

use serde_json::Value;
use skyframe_tests::{binary, scratch, skyframe};
use std::path::{Path, PathBuf};
use std::process::Command;

fn sim_fast(dir: &Path, seconds: &str, seed: &str) -> Value {
    let out = skyframe()
        .args([
            "sim",
            "--fast",
            "--json",
            "--duration",
            seconds,
            "--seed",
            seed,
            "--log-dir",
        ])
        .arg(dir)
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON report")
}

/// Every log file of a flight, by file name, with its bytes.
fn logs(report: &Value) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = report["log_files"]
        .as_array()
        .expect("log files")
        .iter()
        .filter_map(Value::as_str)
        .map(|f| {
            let path = PathBuf::from(f);
            let name = path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            (name, std::fs::read(&path).expect("log readable"))
        })
        .collect();
    files.sort();
    files
}

#[test]
fn a_fast_run_is_byte_identical_for_the_same_seed() {
    let a = sim_fast(&scratch("sim-det-a"), "60", "7");
    let b = sim_fast(&scratch("sim-det-b"), "60", "7");
    let c = sim_fast(&scratch("sim-det-c"), "60", "8");
    let (la, lb, lc) = (logs(&a), logs(&b), logs(&c));
    let names: Vec<&str> = la.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "executive.bin",
            "gps.bin",
            "health.bin",
            "imu.bin",
            "servo.bin",
            "truth.bin"
        ]
    );
    for ((name, x), (_, y)) in la.iter().zip(&lb) {
        assert!(x.len() > 1000, "{name} has a minute of data");
        assert!(x == y, "{name} differs between two runs with seed 7");
    }
    let imu = |l: &[(String, Vec<u8>)]| {
        l.iter()
            .find(|(n, _)| n == "imu.bin")
            .map(|(_, b)| b.clone())
    };
    assert_ne!(imu(&la), imu(&lc), "another seed flies another flight");
    assert!(
        a["speed_up"].as_f64().unwrap_or(0.0) > 5.0,
        "virtual time is faster than real time: {}",
        a["speed_up"]
    );
}

#[test]
fn the_simulated_devices_decode_cleanly_and_the_airplane_flies() {
    let dir = scratch("sim-devices");
    let report = sim_fast(&dir, "30", "1");
    for device in report["devices"].as_array().expect("devices") {
        let errors = [
            "bad_checksum",
            "framing_errors",
            "overflows",
            "invalid_payload",
            "sequence_gaps",
            "stale_events",
        ]
        .iter()
        .map(|k| device[k].as_u64().unwrap_or(0))
        .sum::<u64>();
        assert_eq!(errors, 0, "a clean simulated line: {device}");
    }
    let frames = |name: &str| {
        report["devices"]
            .as_array()
            .and_then(|d| d.iter().find(|d| d["name"] == name))
            .map_or(0, |d| d["frames"].as_u64().unwrap_or(0))
    };
    assert!(
        (2995..=3001).contains(&frames("imu")),
        "100 Hz for 30 s: {}",
        frames("imu")
    );
    assert!(
        (1495..=1501).contains(&frames("servo")),
        "50 Hz for 30 s: {}",
        frames("servo")
    );
    // The seed's receiver: 140 ms mean period, six sentences an epoch.
    let epochs = frames("gps") as f64 / 6.0;
    assert!(
        (190.0..240.0).contains(&epochs),
        "{epochs} GPS epochs in 30 s"
    );

    // Truth: still flying near 100 m after 30 s of light turbulence with the pilot holding trim.
    let flight = PathBuf::from(report["flight_dir"].as_str().expect("dir"));
    let out = dir.join("csv");
    let run = Command::new(binary("skyframe-log", "skyframe-log"))
        .arg("to-csv")
        .arg(&flight)
        .arg("--out-dir")
        .arg(&out)
        .output()
        .expect("converter");
    assert!(
        run.status.success(),
        "every log whole: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let truth = std::fs::read_to_string(out.join("truth.1.csv")).expect("truth");
    let last: Vec<f64> = truth
        .lines()
        .last()
        .expect("rows")
        .split(',')
        .map(|v| v.parse().unwrap_or(f64::NAN))
        .collect();
    let (north, down, airspeed) = (last[1], last[3], last[13]);
    assert!(north > 500.0, "flew north: {north}");
    assert!((-140.0..-60.0).contains(&down), "altitude {}", -down);
    assert!((18.0..32.0).contains(&airspeed), "airspeed {airspeed}");
    // The GPS log: mostly valid fixes (the receiver model loses one now and then, as the
    // seed's did in Fig. 6-1), invalid ones with empty (NaN) positions.
    let gps = std::fs::read_to_string(out.join("gps.1.csv")).expect("gps");
    let rows: Vec<Vec<&str>> = gps
        .lines()
        .filter(|l| !l.starts_with('%'))
        .map(|l| l.split(',').collect())
        .collect();
    let valid = rows.iter().filter(|r| r[1] == "1").count();
    assert!(
        valid * 10 >= rows.len() * 9,
        "{valid} valid of {}",
        rows.len()
    );
    assert!(
        rows.iter().filter(|r| r[1] == "0").all(|r| r[4] == "nan"),
        "no position without a fix"
    );
}

#[test]
fn a_real_time_sim_flies_on_the_clock() {
    let dir = scratch("sim-realtime");
    let out = skyframe()
        .args([
            "sim",
            "--json",
            "--duration",
            "2",
            "--priority",
            "0",
            "--no-mlockall",
            "--log-dir",
        ])
        .arg(&dir)
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let speed_up = report["speed_up"].as_f64().unwrap_or(0.0);
    assert!((0.5..1.2).contains(&speed_up), "real time: {speed_up}");
    assert_eq!(
        report["frames"].as_u64().unwrap_or(0) + report["frames_missed"].as_u64().unwrap_or(0),
        200
    );
}

//! The real ground station against the real vehicle on 127.0.0.1: `skyframe-ground monitor`
//! sees every task's status within 3 s, `send rate` changes a telemetry rate, a stop with the
//! wrong key does nothing, the right key ends the run cleanly with the logs closed, and
//! `get` prints the values the vehicle logged.

use serde_json::Value;
use skyframe_logtable::load_stream;
use skyframe_tests::{binary, finish_ok, on_the_clock, scratch, spawn_piped, to_csv};
use std::net::UdpSocket;
use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Command, Output, Stdio};

fn ground(args: &[&str], listen: &str, key: &Path, state: &Path) -> Output {
    Command::new(binary("skyframe-ground", "skyframe-ground"))
        .args(args)
        .args(["--listen", listen, "--key"])
        .arg(key)
        .arg("--state-dir")
        .arg(state)
        .output()
        .expect("skyframe-ground runs")
}

/// JSON objects of `monitor --json`.
fn messages(out: &Output) -> Vec<Value> {
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

fn key_file(path: &Path, byte: u8) {
    std::fs::write(path, format!("{}\n", format!("{byte:02x}").repeat(32))).expect("key");
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600)).expect("chmod");
}

#[test]
fn ground_and_vehicle_find_each_other_and_the_key_decides_who_stops_the_run() {
    let dir = scratch("ground-vehicle");
    let (key, wrong, state) = (
        dir.join("link.key"),
        dir.join("wrong.key"),
        dir.join("state"),
    );
    key_file(&key, 0x21);
    key_file(&wrong, 0x22);
    // A free port for the ground to listen on.
    let listen = {
        let probe = UdpSocket::bind("127.0.0.1:0").expect("probe");
        probe.local_addr().expect("addr").to_string()
    };

    // The vehicle's command first: finding its binary may build it, which must not eat into
    // the monitor's 3 s.
    let mut vehicle = on_the_clock("sim", "60");
    vehicle
        .args(["--commands", "127.0.0.1:0", "--telemetry", &listen, "--key"])
        .arg(&key)
        .arg("--log-dir")
        .arg(dir.join("flights"));
    let monitor = Command::new(binary("skyframe-ground", "skyframe-ground"))
        .args(["monitor", "--json", "--seconds", "3", "--listen", &listen])
        .stdout(Stdio::piped())
        .spawn()
        .expect("monitor");
    let vehicle = spawn_piped(vehicle);
    let seen = messages(&monitor.wait_with_output().expect("monitor ends"));
    let statuses: std::collections::BTreeSet<String> = seen
        .iter()
        .filter(|m| m.to_string().contains("TaskStatus") || m["type"] == "task_status")
        .filter_map(|m| {
            let s = m.to_string();
            s.split("\"task_index\":")
                .nth(1)
                .and_then(|r| r.split([',', '}']).next())
                .map(str::to_string)
        })
        .collect();
    assert_eq!(
        statuses.len(),
        8,
        "every task's status within 3 s: {statuses:?} of {} messages",
        seen.len()
    );

    // Telemetry rate of task 0 (imu) to 10 Hz: acknowledged, and the data comes 10 times a second.
    let out = ground(&["send", "rate", "0", "10"], &listen, &key, &state);
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let out = ground(
        &["monitor", "--json", "--seconds", "2"],
        &listen,
        &key,
        &state,
    );
    let imu_data = messages(&out)
        .iter()
        .filter(|m| {
            let s = m.to_string();
            (s.contains("TaskData") || m["type"] == "task_data") && s.contains("\"task_index\":0")
        })
        .count();
    assert!(imu_data >= 15, "imu data at 10 Hz: {imu_data} in 2 s");

    // `get` prints the latest values by name; they are checked against the log below.
    let out = ground(
        &[
            "get",
            "--json",
            "estimator.roll_rad",
            "imu.fz",
            "gps.lat_deg",
            "servo.batt_avionics_v",
        ],
        &listen,
        &key,
        &state,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got: Value = serde_json::from_slice(&out.stdout).expect("get --json");

    // The wrong key: refused by the vehicle, the ground gives up (exit 1), the run goes on.
    let out = ground(&["send", "stop", "--timeout", "2"], &listen, &wrong, &state);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The right key stops it.
    let out = ground(&["send", "stop"], &listen, &key, &state);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let run = finish_ok(vehicle);
    let report: Value = serde_json::from_slice(&run.stdout).expect("report");
    assert_eq!(report["stop_reason"], "requested");
    assert!(
        report["link"]["commands_rejected"].as_u64().unwrap_or(0) >= 1,
        "{}",
        report["link"]
    );
    let flight = Path::new(report["flight_dir"].as_str().expect("dir"));
    to_csv(&[flight.to_str().expect("utf-8")], &dir.join("csv"));

    // Each value `get` printed is the logged value of that column at the record's TIME.
    for (name, stream) in [
        ("estimator.roll_rad", "estimator"),
        ("imu.fz_m_s2", "imu"),
        ("gps.lat_deg", "gps"),
        ("servo.batt_avionics_v", "servo"),
    ] {
        let entry = &got[name];
        let value = entry["value"]
            .as_f64()
            .unwrap_or_else(|| panic!("{name}: {got}"));
        // `log_time` is the CSV's exact `sec.nsec` (a wall-clock `time` in f64 seconds is
        // only good to a few hundred ns).
        let (sec, nsec) = entry["log_time"]
            .as_str()
            .and_then(|t| t.split_once('.'))
            .unwrap_or_else(|| panic!("{name}: {got}"));
        let time_ns =
            sec.parse::<i64>().expect("sec") * 1_000_000_000 + nsec.parse::<i64>().expect("nsec");
        let column = name.split_once('.').expect("TASK.COLUMN").1;
        let path = flight.join(format!("{stream}.bin"));
        let logged = load_stream(&path, |p| panic!("{}: {p:?}", path.display())).expect("log");
        let found = logged.tables.values().any(|table| {
            let Some(c) = table.columns.iter().position(|n| n == column) else {
                return false;
            };
            table
                .times_ns
                .iter()
                .zip(&table.values[c])
                .any(|(&t, &v)| t == time_ns && v == value)
        });
        assert!(
            found,
            "{name} = {value} at {time_ns} ns is not in {}",
            path.display()
        );
    }
}

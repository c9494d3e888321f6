//! The scriptable subcommands, run as the real binary against a fake vehicle on loopback
//! sockets: the vehicle's side is the core's CommandGate and ParamTable.

mod support;

use support::{Ground, KEY_HEX, RunningVehicle, path_str, stderr, stdout};

#[test]
fn monitor_json_prints_one_object_per_message_with_named_columns() {
    let ground = Ground::new();
    let (output, report) =
        ground.run_with_vehicle(&["monitor", "--json", "--seconds", "1.8"], 7, 200);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let objects: Vec<serde_json::Value> = stdout(&output)
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object per line"))
        .collect();
    assert!(objects.len() >= 20, "only {} messages", objects.len());
    assert!(report.sent >= objects.len() as u64);
    assert!(objects.iter().all(|o| o["vehicle"] == 7));
    let imu = objects
        .iter()
        .find(|o| o["type"] == "task_data" && o["task_index"] == 0)
        .expect("imu data");
    assert_eq!(imu["format_index"], 1);
    assert_eq!(imu["task"], "imu");
    // The TaskFormat came first, so the values are keyed by their column names, with units.
    assert_eq!(imu["columns_known"], true, "{imu}");
    assert_eq!(imu["values"].as_object().map(|v| v.len()), Some(8), "{imu}");
    assert!(imu["values"]["fz_m_s2"].as_f64().is_some(), "{imu}");
    assert_eq!(imu["units"]["fz_m_s2"], "m/s^2", "{imu}");
    assert_eq!(imu["units"]["p_rad_s"], "rad/s", "{imu}");
    assert!(imu["units"].get("counter").is_none(), "{imu}");
    assert!(
        imu["time"].as_f64().is_some() && imu["seq"].as_u64().is_some(),
        "{imu}"
    );
    for kind in ["task_format", "task_status", "executive_status"] {
        assert!(objects.iter().any(|o| o["type"] == kind), "no {kind}");
    }
}

#[test]
fn monitor_text_is_one_line_per_message() {
    let ground = Ground::new();
    let (output, _) = ground.run_with_vehicle(&["monitor", "--seconds", "1.3"], 3, 200);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let text = stdout(&output);
    assert!(
        text.lines()
            .any(|l| l.starts_with("vehicle 3 ") && l.contains("task_data imu#1 counter=")),
        "{text}"
    );
}

#[test]
fn set_changes_a_parameter_and_prints_the_value_in_force() {
    let ground = Ground::new();
    let key = ground.write_key("link.key", KEY_HEX, 0o600);
    let vehicle = RunningVehicle::start(7, ground.listen, 1000);
    let key = path_str(&key);
    let output = ground.run(&["set", "control.roll_gain", "2.5", "--key", key]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(stdout(&output), "control.roll_gain = 2.5 (accepted)\n");
    let listed = ground.run(&["params", "--key", key, "--vehicle", "7"]);
    assert_eq!(listed.status.code(), Some(0), "{}", stderr(&listed));
    let table = stdout(&listed);
    let row = table
        .lines()
        .find(|l| l.starts_with("control.roll_gain"))
        .unwrap_or_else(|| panic!("{table}"));
    let fields: Vec<&str> = row.split_whitespace().collect();
    assert_eq!(fields, ["control.roll_gain", "f32", "2.5", "0", "5"]);
    assert!(table.contains("nav.auto_allowed"), "{table}");
    // Out of range: the vehicle says so, keeps the value, and the tool exits 1.
    let refused = ground.run(&["set", "control.roll_gain", "9", "--key", key]);
    assert_eq!(refused.status.code(), Some(1));
    assert_eq!(stdout(&refused), "control.roll_gain = 2.5 (out of range)\n");
    // A value that is not of the parameter's type is a usage error, sent nowhere.
    let typo = ground.run(&["set", "gps.min_satellites", "-1", "--key", key]);
    assert_eq!(typo.status.code(), Some(2), "{}", stderr(&typo));
    let report = vehicle.finish();
    assert!(report.commands_accepted >= 4, "{report:?}");
}

#[test]
fn sequence_numbers_carry_on_across_ground_restarts() {
    let ground = Ground::new();
    let key = ground.write_key("link.key", KEY_HEX, 0o600);
    let vehicle = RunningVehicle::start(2, ground.listen, 1000);
    let key = path_str(&key);
    // By name (learnt from the task's status: up to 8 s for the 8 tasks in rotation), then
    // by index. A restarted ground starting again at sequence 1 would be refused as a replay.
    for (task, hz) in [("gps", "5"), ("4", "2")] {
        let output = ground.run(&["send", "rate", task, hz, "--key", key, "--timeout", "10"]);
        assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
        assert!(
            stdout(&output).ends_with(": accepted\n"),
            "{}",
            stdout(&output)
        );
    }
    let mode = ground.run(&["send", "mode", "auto", "--key", key]);
    assert_eq!(mode.status.code(), Some(0), "{}", stderr(&mode));
    assert_eq!(stdout(&mode), "vehicle 2: mode auto: accepted\n");
    let period = ground.run(&["send", "health-period", "500", "--key", key]);
    assert_eq!(period.status.code(), Some(0), "{}", stderr(&period));
    assert_eq!(
        stdout(&period),
        "vehicle 2: health period 500 ms: accepted\n"
    );
    let report = vehicle.finish();
    assert_eq!(report.commands_rejected, 0, "{report:?}");
    let state = std::fs::read_dir(ground.state_dir())
        .expect("state dir")
        .filter_map(Result::ok)
        .map(|e| std::fs::read_to_string(e.path()).expect("read"))
        .collect::<Vec<_>>();
    assert_eq!(state, ["4\n"]);
}

#[test]
fn stop_with_the_right_key_ends_the_run() {
    let ground = Ground::new();
    let key = ground.write_key("link.key", KEY_HEX, 0o600);
    let vehicle = RunningVehicle::start(9, ground.listen, 1000);
    let output = ground.run(&["send", "stop", "--key", path_str(&key)]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(stdout(&output), "vehicle 9: stop: accepted\n");
    assert!(vehicle.finish().stopped_by_command);
}

#[test]
fn a_wrong_keys_stop_is_dropped_by_the_gate_and_times_out() {
    let ground = Ground::new();
    let wrong = ground.write_key("wrong.key", &"ab".repeat(32), 0o600);
    let vehicle = RunningVehicle::start(9, ground.listen, 1000);
    let output = ground.run(&["send", "stop", "--key", path_str(&wrong), "--timeout", "4"]);
    let report = vehicle.finish();
    assert_eq!(output.status.code(), Some(1), "{}", stderr(&output));
    assert!(
        stderr(&output).contains("no acknowledgement"),
        "{}",
        stderr(&output)
    );
    assert_eq!(stderr(&output).lines().count(), 1);
    assert!(!report.stopped_by_command);
    assert!(
        report.commands_rejected >= 2,
        "resent, and each refused: {report:?}"
    );
    assert_eq!(report.commands_accepted, 0);
}

#[test]
fn a_group_readable_key_file_is_refused_with_one_line() {
    let ground = Ground::new();
    let key = ground.write_key("link.key", KEY_HEX, 0o640);
    let output = ground.run(&["send", "stop", "--key", path_str(&key)]);
    assert_eq!(output.status.code(), Some(2));
    let message = stderr(&output);
    assert_eq!(message.lines().count(), 1, "{message}");
    assert!(message.contains("readable by group or others"), "{message}");
}

#[test]
fn commands_without_a_key_are_refused_but_monitoring_works() {
    let ground = Ground::new();
    let output = ground.run(&["send", "stop"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(
        stderr(&output).contains("no link key"),
        "{}",
        stderr(&output)
    );
}

#[test]
fn the_newest_flight_key_is_found_without_key_option() {
    let ground = Ground::new();
    let flight = ground.dir.path().join("flights/2026-11-22T08-00-00Z");
    std::fs::create_dir_all(&flight).expect("mkdir");
    let key = flight.join("link.key");
    std::fs::write(&key, KEY_HEX).expect("write");
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).expect("chmod");
    let vehicle = RunningVehicle::start(4, ground.listen, 1000);
    let output = ground.run(&["send", "mode", "stabilise"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(vehicle.finish().commands_accepted, 1);
}

#[test]
fn several_vehicles_need_vehicle_and_with_it_only_that_one_is_commanded() {
    let ground = Ground::new();
    let key = ground.write_key("link.key", KEY_HEX, 0o600);
    let key = path_str(&key);
    let first = RunningVehicle::start(1, ground.listen, 1000);
    let second = RunningVehicle::start(2, ground.listen, 1000);
    let ambiguous = ground.run(&["send", "stop", "--key", key]);
    assert_eq!(ambiguous.status.code(), Some(2));
    assert!(stderr(&ambiguous).contains("several vehicles heard (1, 2)"));
    let output = ground.run(&["send", "stop", "--key", key, "--vehicle", "2"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert!(second.finish().stopped_by_command);
    assert!(!first.finish().stopped_by_command);
}

#[test]
fn no_vehicle_heard_times_out_with_exit_1() {
    let ground = Ground::new();
    let key = ground.write_key("link.key", KEY_HEX, 0o600);
    let output = ground.run(&["params", "--key", path_str(&key), "--timeout", "0.5"]);
    assert_eq!(output.status.code(), Some(1));
    assert!(stderr(&output).contains("no vehicle heard"));
}

#[test]
fn bench_prints_throughput_loss_and_cpu_as_json() {
    let ground = Ground::new();
    let output = ground.run(&["bench", "--vehicles", "3", "--seconds", "1.5", "--json"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let result: serde_json::Value = serde_json::from_str(stdout(&output).trim()).expect("JSON");
    assert_eq!(result["vehicles_seen"], 3);
    // 3 vehicles × ~122 datagrams/s (see bench.rs): well over 200/s even on a busy machine.
    let rate = result["messages_per_s"].as_f64().expect("rate");
    assert!(rate > 200.0, "{result}");
    let handled = result["handled"].as_u64().expect("handled");
    let sent = result["sent"].as_u64().expect("sent");
    assert!(handled <= sent && handled * 100 >= sent * 95, "{result}");
    for field in ["loss_percent", "receive_cpu_percent", "process_cpu_percent"] {
        assert!(result[field].as_f64().is_some(), "{field} in {result}");
    }
}

#[test]
fn a_mode_the_vehicle_refuses_exits_1_with_the_reason() {
    let ground = Ground::new();
    let key = ground.write_key("link.key", KEY_HEX, 0o600);
    let key = path_str(&key);
    let vehicle = RunningVehicle::start(5, ground.listen, 1000);
    // The fake vehicle refuses auto while nav.auto_allowed is false (a bool parameter).
    let set = ground.run(&["set", "nav.auto_allowed", "false", "--key", key]);
    assert_eq!(set.status.code(), Some(0), "{}", stderr(&set));
    assert_eq!(stdout(&set), "nav.auto_allowed = false (accepted)\n");
    let mode = ground.run(&["send", "mode", "auto", "--key", key]);
    assert_eq!(mode.status.code(), Some(1), "{}", stdout(&mode));
    assert_eq!(stderr(&mode), "skyframe-ground: vehicle answered refused\n");
    let unknown = ground.run(&["set", "control.no_such_gain", "1", "--key", key]);
    assert_eq!(unknown.status.code(), Some(1));
    assert!(
        stderr(&unknown).contains("unknown parameter"),
        "{}",
        stderr(&unknown)
    );
    vehicle.finish();
}

#[test]
fn a_port_already_in_use_is_one_line_and_exit_2() {
    let ground = Ground::new();
    let _taken = std::net::UdpSocket::bind(ground.listen).expect("bind");
    let output = ground.run(&["monitor", "--seconds", "0.1"]);
    assert_eq!(output.status.code(), Some(2));
    let message = stderr(&output);
    assert_eq!(message.lines().count(), 1, "{message}");
    assert!(message.contains("cannot listen on"), "{message}");
}

#[test]
fn signed_telemetry_verifies_with_the_key_and_is_refused_with_another() {
    let ground = Ground::new();
    let right = ground.write_key("right.key", KEY_HEX, 0o600);
    let wrong = ground.write_key("wrong.key", &"cd".repeat(32), 0o600);
    let vehicle = RunningVehicle::start_signed(6, ground.listen, 200);
    let lines = |key: &std::path::Path| -> Vec<serde_json::Value> {
        let output = ground.run(&[
            "monitor",
            "--json",
            "--seconds",
            "1",
            "--key",
            path_str(key),
        ]);
        assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
        stdout(&output)
            .lines()
            .map(|l| serde_json::from_str(l).expect("JSON"))
            .collect()
    };
    let good = lines(&right);
    assert!(!good.is_empty());
    assert!(
        good.iter()
            .all(|o| o["signed"] == true && o["vehicle"] == 6),
        "{good:?}"
    );
    let bad = lines(&wrong);
    assert!(!bad.is_empty());
    assert!(
        bad.iter()
            .all(|o| o["type"] == "refused" && o["error"] == "bad_signature"),
        "{bad:?}"
    );
    // And a command still works with the right key while the telemetry is signed.
    let stop = ground.run(&["send", "stop", "--key", path_str(&right)]);
    assert_eq!(stop.status.code(), Some(0), "{}", stderr(&stop));
    assert!(vehicle.finish().stopped_by_command);
}

#[test]
fn get_prints_the_latest_logged_value_of_a_column() {
    let ground = Ground::new();
    let (output, _) = ground.run_with_vehicle(&["get", "imu.fz_m_s2"], 4, 100);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    // The fake vehicle's IMU reports -9.80665 m/s² as an f32: printed as the link carries it.
    assert_eq!(stdout(&output).trim(), (-9.80665f32).to_string());
}

#[test]
fn get_json_names_each_value_with_its_unit_and_log_time() {
    let ground = Ground::new();
    // Units may be left out of the name, as on the log tool's command line.
    let (output, _) = ground.run_with_vehicle(&["get", "--json", "gps.lat", "imu.p"], 4, 100);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let object: serde_json::Value = serde_json::from_str(stdout(&output).trim()).expect("JSON");
    let lat = &object["gps.lat_deg"];
    assert_eq!(lat["unit"], "deg", "{object}");
    let value = lat["value"].as_f64().expect("a number");
    // The fake vehicle circles 120 m around 47.3977° N.
    assert!((value - 47.3977).abs() < 0.0011, "{value}");
    assert!(lat["time"].as_f64().is_some(), "{object}");
    assert!(
        lat["log_time"].as_str().is_some_and(|t| t.contains('.')),
        "{object}"
    );
    assert_eq!(object["imu.p_rad_s"]["unit"], "rad/s", "{object}");
}

#[test]
fn get_waits_for_a_threshold_and_says_when_it_is_not_crossed() {
    let ground = Ground::new();
    // The fake vehicle's GPS altitude is 488 ± 2 m.
    let (output, _) = ground.run_with_vehicle(&["get", "gps.alt_m", "--above", "480"], 4, 100);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let alt: f64 = stdout(&output).trim().parse().expect("a number");
    assert!(alt > 480.0, "{alt}");

    let (output, _) = ground.run_with_vehicle(
        &["get", "gps.alt_m", "--above", "1000", "--timeout", "2"],
        4,
        100,
    );
    assert_eq!(output.status.code(), Some(1), "{}", stderr(&output));
    let message = stderr(&output);
    assert!(
        message.contains("gps.alt_m") && message.contains("not above 1000"),
        "{message}"
    );
    assert_eq!(message.trim().lines().count(), 1, "{message}");
}

#[test]
fn get_refuses_a_column_the_task_does_not_log_and_a_malformed_name() {
    let ground = Ground::new();
    let (output, _) = ground.run_with_vehicle(&["get", "imu.altitude"], 4, 100);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    let message = stderr(&output);
    assert!(
        message.contains("task imu logs no column \"altitude\"") && message.contains("fz_m_s2"),
        "{message}"
    );
    let output = ground.run(&["get", "altitude"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(
        stderr(&output).contains("not TASK.COLUMN"),
        "{}",
        stderr(&output)
    );
}

//! `to-ulog FLIGHT_DIR` and `to-parquet`, read back by PX4's pyulog and by pyarrow, compared
//! value by value with `to-csv` of the same flight (an independent path: printf text from
//! the binary logs, not the converters' code).
//!
//! Skipped (with a message) only when pyulog/pyarrow are missing outside CI; CI installs
//! them (.ci/run), so there a missing module is a failure.

#[allow(dead_code)] // shared with plot.rs: each test crate uses part of it
mod flight;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value as Json;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_skyframe-log"))
}

fn python_has(module: &str, test: &str) -> bool {
    let ok = Command::new("python3")
        .args(["-c", &format!("import {module}")])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var_os("CI").is_none(),
            "{module} is required in CI (pip install {module})"
        );
        eprintln!("SKIPPED {test}: {module} is not installed (pip install {module})");
    }
    ok
}

fn run(command: &mut Command) -> Output {
    command.output().expect("runs")
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// One CSV file of `to-csv`: times (ns), columns, rows, and how far a value may be from the
/// binary's (half a unit of the printed precision; 0 for integers).
struct Csv {
    times_ns: Vec<i64>,
    columns: Vec<String>,
    rows: Vec<Vec<f64>>,
    tolerance: Vec<f64>,
}

impl Csv {
    fn read(path: &Path) -> Csv {
        let text = std::fs::read_to_string(path).expect("csv");
        let mut csv = Csv {
            times_ns: Vec::new(),
            columns: Vec::new(),
            rows: Vec::new(),
            tolerance: Vec::new(),
        };
        for line in text.lines() {
            if let Some(format) = line.strip_prefix("% format ") {
                let format = format.split_once(": ").expect("format line").1;
                csv.tolerance = format
                    .split(',')
                    .map(|spec| match spec.split_once('.') {
                        Some((_, p)) => {
                            let digits: String =
                                p.chars().take_while(char::is_ascii_digit).collect();
                            let p: i32 = digits.parse().expect("precision");
                            // Half a printed unit, plus the f32 rounding of the binary value.
                            0.5 * 10f64.powi(-p) * 1.000_001 + 1e-12
                        }
                        None => 0.0,
                    })
                    .collect();
            } else if let Some(columns) = line.strip_prefix("% time,") {
                csv.columns = columns.split(',').map(String::from).collect();
            } else if !line.starts_with('%') {
                let mut parts = line.split(',');
                let time = parts.next().expect("time");
                let (sec, nsec) = time.split_once('.').expect("sec.nsec");
                let t = sec.parse::<i64>().expect("sec") * 1_000_000_000
                    + nsec.parse::<i64>().expect("nsec");
                csv.times_ns.push(t);
                csv.rows.push(
                    parts
                        .map(|v| {
                            if v.contains("nan") {
                                f64::NAN
                            } else {
                                v.parse().expect("number")
                            }
                        })
                        .collect(),
                );
            }
        }
        csv
    }

    fn column(&self, name: &str) -> Vec<f64> {
        let c = self
            .columns
            .iter()
            .position(|n| n == name)
            .unwrap_or_else(|| panic!("no column {name}"));
        self.rows.iter().map(|r| r[c]).collect()
    }

    fn tolerance_of(&self, name: &str) -> f64 {
        let c = self.columns.iter().position(|n| n == name).expect("column");
        self.tolerance[c]
    }
}

/// What pyulog reads from a ULog, as JSON.
const PYULOG_DUMP: &str = r#"
import sys, json, math
from pyulog import ULog
u = ULog(sys.argv[1])
def clean(x):
    x = x.item() if hasattr(x, "item") else x
    return None if isinstance(x, float) and math.isnan(x) else x
out = {
    "info": {k: clean(v) if not isinstance(v, (bytes, list)) else str(v) for k, v in u.msg_info_dict.items()},
    "params": u.initial_parameters,
    "changed": [[t, k, v] for t, k, v in u.changed_parameters],
    "messages": [[m.timestamp, m.log_level_str(), m.message] for m in u.logged_messages],
    "dropouts": [[d.timestamp, d.duration] for d in u.dropouts],
    "topics": [{"name": d.name, "multi_id": d.multi_id,
                "types": {f.field_name: f.type_str for f in d.field_data},
                "data": {k: [clean(x) for x in v] for k, v in d.data.items()}}
               for d in u.data_list],
}
print(json.dumps(out))
"#;

struct Ulog(Json);

impl Ulog {
    fn read(path: &Path) -> Ulog {
        let dump = run(Command::new("python3").args(["-c", PYULOG_DUMP]).arg(path));
        assert!(dump.status.success(), "pyulog: {}", stderr(&dump));
        Ulog(serde_json::from_slice(&dump.stdout).expect("json"))
    }

    fn topic(&self, name: &str, multi_id: u64) -> &Json {
        self.0["topics"]
            .as_array()
            .expect("topics")
            .iter()
            .find(|t| t["name"] == name && t["multi_id"] == multi_id)
            .unwrap_or_else(|| panic!("no topic {name} (multi_id {multi_id})"))
    }

    fn names(&self) -> Vec<String> {
        self.0["topics"]
            .as_array()
            .expect("topics")
            .iter()
            .map(|t| t["name"].as_str().expect("name").to_string())
            .collect()
    }

    fn series(&self, topic: &str, multi_id: u64, field: &str) -> Vec<f64> {
        self.topic(topic, multi_id)["data"][field]
            .as_array()
            .unwrap_or_else(|| panic!("no field {topic}.{field}"))
            .iter()
            .map(|v| v.as_f64().unwrap_or(f64::NAN))
            .collect()
    }

    fn origin_ns(&self) -> i64 {
        self.0["info"]["skyframe_time_origin_ns"]
            .as_i64()
            .expect("origin")
    }
}

/// Asserts two series are equal within `tolerance` (NaN equals NaN).
fn assert_close(what: &str, ours: &[f64], expected: &[f64], tolerance: f64) {
    assert_eq!(ours.len(), expected.len(), "{what}: row count");
    for (i, (a, b)) in ours.iter().zip(expected).enumerate() {
        let same = (a.is_nan() && b.is_nan()) || (a - b).abs() <= tolerance;
        assert!(same, "{what}[{i}]: {a} vs {b} (tolerance {tolerance})");
    }
}

/// A flight directory with every stream the converter maps, converted by `to-ulog` (with a
/// vehicle id and version) and by `to-csv`.
struct Converted {
    _dir: tempfile::TempDir,
    flight: PathBuf,
    csv: PathBuf,
    ulog: Ulog,
}

fn csv_of(c: &Converted, name: &str) -> Csv {
    Csv::read(&c.csv.join(format!("{name}.csv")))
}

fn convert_full_flight() -> Converted {
    let dir = tempfile::tempdir().expect("temp dir");
    let flight = dir.path().join("2026-11-25T10-00-00Z");
    std::fs::create_dir(&flight).expect("flight dir");
    flight::write_full_flight(&flight);
    let out =
        run(bin()
            .arg("to-ulog")
            .arg(&flight)
            .args(["--vehicle-id", "7", "--ver-sw", "0a84882"]));
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert_eq!(stderr(&out), "");
    let csv = dir.path().join("csv");
    let out = run(bin().arg("to-csv").arg(&flight).arg("--out-dir").arg(&csv));
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let ulog = Ulog::read(&flight.join("flight.ulg"));
    Converted {
        _dir: dir,
        flight,
        csv,
        ulog,
    }
}

#[test]
fn a_flight_is_one_ulog_whose_skyframe_topics_equal_the_csv() {
    if !python_has(
        "pyulog",
        "a_flight_is_one_ulog_whose_skyframe_topics_equal_the_csv",
    ) {
        return;
    }
    let c = convert_full_flight();
    // One file for the whole flight.
    let ulogs: Vec<_> = std::fs::read_dir(&c.flight)
        .expect("list")
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "ulg"))
        .collect();
    assert_eq!(ulogs.len(), 1);
    let names = c.ulog.names();
    assert!(
        names.iter().all(|n| !n.starts_with("log_")),
        "unnamed topics: {names:?}"
    );

    let info = &c.ulog.0["info"];
    assert_eq!(info["sys_name"], "skyframe");
    assert_eq!(info["ver_sw"], "0a84882");
    assert_eq!(info["sys_uuid"], "7");
    assert_eq!(info["time_ref_utc"], 0);
    assert_eq!(info["skyframe_flight"], "2026-11-25T10-00-00Z");
    let origin = c.ulog.origin_ns();
    assert_eq!(origin, flight::START_NS as i64);

    // Every CSV the flight converts to has its topic, named here independently of the
    // converter's table, with the CSV's columns, times and values.
    let expected = [
        ("executive.1", "skyframe_executive"),
        ("imu.1", "skyframe_imu"),
        ("imu.2", "skyframe_imu_slow"),
        ("gps.1", "skyframe_gps"),
        ("servo.1", "skyframe_servo_board"),
        ("servo.2", "skyframe_servo_command"),
        ("estimator.1", "skyframe_estimator"),
        ("control.1", "skyframe_control"),
        ("control.2", "skyframe_control_gains"),
    ];
    let mut csvs: Vec<String> = std::fs::read_dir(&c.csv)
        .expect("csv dir")
        .flatten()
        .map(|e| {
            e.file_name()
                .to_string_lossy()
                .trim_end_matches(".csv")
                .to_string()
        })
        .collect();
    csvs.sort();
    let mut listed: Vec<String> = expected.iter().map(|e| e.0.to_string()).collect();
    listed.sort();
    assert_eq!(csvs, listed, "every format of the flight is checked");
    for (csv_name, topic) in expected {
        let csv = csv_of(&c, csv_name);
        let times: Vec<f64> = csv
            .times_ns
            .iter()
            .map(|t| ((t - origin) / 1000) as f64)
            .collect();
        assert_close(
            &format!("{topic}.timestamp"),
            &c.ulog.series(topic, 0, "timestamp"),
            &times,
            0.0,
        );
        for column in &csv.columns {
            assert_close(
                &format!("{topic}.{column}"),
                &c.ulog.series(topic, 0, column),
                &csv.column(column),
                csv.tolerance_of(column),
            );
        }
    }
}

#[test]
fn px4_topics_carry_the_flights_values_in_px4_units() {
    if !python_has("pyulog", "px4_topics_carry_the_flights_values_in_px4_units") {
        return;
    }
    let c = convert_full_flight();
    let u = &c.ulog;
    let imu = csv_of(&c, "imu.1");
    let gps = csv_of(&c, "gps.1");
    let board = csv_of(&c, "servo.1");
    let command = csv_of(&c, "servo.2");
    let estimator = csv_of(&c, "estimator.1");
    let control = csv_of(&c, "control.1");
    let origin = u.origin_ns();
    let us = |csv: &Csv| -> Vec<f64> {
        csv.times_ns
            .iter()
            .map(|t| ((t - origin) / 1000) as f64)
            .collect()
    };
    let same = |topic: &str, multi: u64, field: &str, csv: &Csv, column: &str| {
        assert_close(
            &format!("{topic}.{field}"),
            &u.series(topic, multi, field),
            &csv.column(column),
            csv.tolerance_of(column),
        );
    };

    // sensor_combined: rates and specific force, body FRD, as logged.
    assert_close(
        "sensor_combined.timestamp",
        &u.series("sensor_combined", 0, "timestamp"),
        &us(&imu),
        0.0,
    );
    for (i, column) in ["p_rad_s", "q_rad_s", "r_rad_s"].iter().enumerate() {
        same(
            "sensor_combined",
            0,
            &format!("gyro_rad[{i}]"),
            &imu,
            column,
        );
    }
    for (i, column) in ["fx_m_s2", "fy_m_s2", "fz_m_s2"].iter().enumerate() {
        same(
            "sensor_combined",
            0,
            &format!("accelerometer_m_s2[{i}]"),
            &imu,
            column,
        );
    }

    // vehicle_gps_position: 1e-7 degrees and millimetres (integers), fix type.
    let gps_t = us(&gps);
    assert_close(
        "vehicle_gps_position.timestamp",
        &u.series("vehicle_gps_position", 0, "timestamp"),
        &gps_t,
        0.0,
    );
    let valid = gps.column("valid");
    for (field, column, scale) in [
        ("lat", "lat_deg", 1e7),
        ("lon", "lon_deg", 1e7),
        ("alt", "alt_m", 1e3),
    ] {
        let ours = u.series("vehicle_gps_position", 0, field);
        let csv = gps.column(column);
        for (i, (&a, &b)) in ours.iter().zip(&csv).enumerate() {
            if valid[i] == 1.0 {
                // The CSV's rounding, scaled, plus the integer's own rounding.
                let tolerance = gps.tolerance_of(column) * scale + 0.5;
                assert!(
                    (a - b * scale).abs() <= tolerance,
                    "{field}[{i}]: {a} vs {}",
                    b * scale
                );
            }
        }
    }
    let fix = u.series("vehicle_gps_position", 0, "fix_type");
    for (i, &v) in valid.iter().enumerate() {
        assert_eq!(fix[i] >= 3.0, v == 1.0, "fix_type[{i}]");
    }
    same("vehicle_gps_position", 0, "vel_n_m_s", &gps, "vn_m_s");
    same("vehicle_gps_position", 0, "vel_e_m_s", &gps, "ve_m_s");
    same("vehicle_gps_position", 0, "vel_d_m_s", &gps, "vd_m_s");
    same("vehicle_gps_position", 0, "hdop", &gps, "hdop");
    same("vehicle_gps_position", 0, "epv", &gps, "sd_d_m");
    let sats = u.series("vehicle_gps_position", 0, "satellites_used");
    assert_close("satellites_used", &sats, &gps.column("satellites"), 0.0);

    // vehicle_attitude: the estimator's quaternion (Hamilton, w first, FRD → NED).
    for (i, column) in ["qw", "qx", "qy", "qz"].iter().enumerate() {
        same(
            "vehicle_attitude",
            0,
            &format!("q[{i}]"),
            &estimator,
            column,
        );
    }
    // vehicle_local_position: NED from home, home = the first valid fix.
    same("vehicle_local_position", 0, "x", &estimator, "pn_m");
    same("vehicle_local_position", 0, "y", &estimator, "pe_m");
    same("vehicle_local_position", 0, "z", &estimator, "pd_m");
    same("vehicle_local_position", 0, "vx", &estimator, "vn_m_s");
    same(
        "vehicle_local_position",
        0,
        "heading",
        &estimator,
        "yaw_rad",
    );
    let first_fix = valid.iter().position(|&v| v == 1.0).expect("a fix");
    let (lat0, lon0, alt0) = (
        gps.column("lat_deg")[first_fix],
        gps.column("lon_deg")[first_fix],
        gps.column("alt_m")[first_fix],
    );
    let ref_lat = u.series("vehicle_local_position", 0, "ref_lat");
    assert!((ref_lat[0] - lat0).abs() < 1e-8, "{} vs {lat0}", ref_lat[0]);
    let ref_lon = u.series("vehicle_local_position", 0, "ref_lon");
    assert!((ref_lon[0] - lon0).abs() < 1e-8);
    // vehicle_global_position: the local position placed at home. A metre north is about
    // 1/111 km of latitude at 45°; altitude is home's less down.
    let lat = u.series("vehicle_global_position", 0, "lat");
    let alt = u.series("vehicle_global_position", 0, "alt");
    let north = estimator.column("pn_m");
    let down = estimator.column("pd_m");
    for i in (0..lat.len()).step_by(97) {
        let metres = (lat[i] - lat0).to_radians() * 6_367_400.0;
        assert!(
            (metres - north[i]).abs() <= 0.002 * north[i].abs() + 0.01,
            "lat[{i}]: {metres} m vs {}",
            north[i]
        );
        assert!((alt[i] - (alt0 - down[i])).abs() < 0.01, "alt[{i}]");
    }

    // actuator_outputs: the computer's normalised commands; input_rc: the pilot's µs.
    for (i, column) in ["aileron_cmd", "elevator_cmd", "throttle_cmd", "rudder_cmd"]
        .iter()
        .enumerate()
    {
        same(
            "actuator_outputs",
            0,
            &format!("output[{i}]"),
            &command,
            column,
        );
    }
    for i in 0..8 {
        same(
            "input_rc",
            0,
            &format!("values[{i}]"),
            &board,
            &format!("ch{}_us", i + 1),
        );
    }
    // battery_status: instance 0 avionics, 1 servo.
    same("battery_status", 0, "voltage_v", &board, "batt_avionics_v");
    same("battery_status", 1, "voltage_v", &board, "batt_servo_v");

    // vehicle_status: manual (0), then auto (3: AUTO_MISSION), then stabilise (15), with
    // the change times of control.1's mode.
    let nav = u.series("vehicle_status", 0, "nav_state");
    let nav_t = u.series("vehicle_status", 0, "timestamp");
    let mut changes = Vec::new();
    for (i, &state) in nav.iter().enumerate() {
        if i == 0 || nav[i - 1] != state {
            changes.push((nav_t[i], state));
        }
    }
    assert_eq!(
        changes,
        [(0.0, 0.0), (5_000_000.0, 3.0), (15_000_000.0, 15.0)]
    );

    // The autopilot's setpoints, only where its loops ran.
    let roll_c = control.column("roll_c_rad");
    let ran: Vec<usize> = (0..roll_c.len())
        .filter(|&i| roll_c[i].is_finite())
        .collect();
    let roll_sp = u.series("vehicle_attitude_setpoint", 0, "roll_body");
    assert_close(
        "vehicle_attitude_setpoint.roll_body",
        &roll_sp,
        &ran.iter().map(|&i| roll_c[i]).collect::<Vec<_>>(),
        control.tolerance_of("roll_c_rad"),
    );
    let alt_c = control.column("alt_c_m");
    let alt_sp = u.series("tecs_status", 0, "altitude_sp");
    assert_close(
        "tecs_status.altitude_sp (AMSL)",
        &alt_sp,
        &ran.iter().map(|&i| alt0 + alt_c[i]).collect::<Vec<_>>(),
        0.01,
    );
}

#[test]
fn parameters_and_events_are_in_the_ulog() {
    if !python_has("pyulog", "parameters_and_events_are_in_the_ulog") {
        return;
    }
    let c = convert_full_flight();
    let gains = csv_of(&c, "control.2");
    let params = c.ulog.0["params"].as_object().expect("params");
    assert_eq!(params.len(), gains.columns.len());
    for (column, value) in gains.columns.iter().zip(&gains.rows[0]) {
        let ours = params[&format!("control.{column}")]
            .as_f64()
            .expect("float");
        assert!(
            (ours - value).abs() <= gains.tolerance_of(column),
            "control.{column}"
        );
    }
    // The change at 10 s, and only it.
    let changed = c.ulog.0["changed"].as_array().expect("changed");
    assert_eq!(changed.len(), 1, "{changed:?}");
    assert_eq!(changed[0][0], 10_000_000);
    assert_eq!(changed[0][1], "control.roll_kp");
    assert_eq!(changed[0][2], 1.5);
    let messages: Vec<(u64, String, String)> = c.ulog.0["messages"]
        .as_array()
        .expect("messages")
        .iter()
        .map(|m| {
            (
                m[0].as_u64().expect("t"),
                m[1].as_str().expect("level").to_string(),
                m[2].as_str().expect("text").to_string(),
            )
        })
        .collect();
    let has = |t: u64, level: &str, start: &str| {
        messages
            .iter()
            .any(|m| m.0 == t && m.1 == level && m.2.starts_with(start))
    };
    assert!(has(0, "INFO", "mode MANUAL"), "{messages:?}");
    assert!(has(5_000_000, "INFO", "mode AUTO"), "{messages:?}");
    assert!(has(15_000_000, "INFO", "mode STABILISE"), "{messages:?}");
    assert!(
        has(
            10_000_000,
            "INFO",
            "parameter control.roll_kp changed: 1.2 -> 1.5"
        ),
        "{messages:?}"
    );
}

#[test]
fn damage_becomes_warnings_and_a_dropout() {
    if !python_has("pyulog", "damage_becomes_warnings_and_a_dropout") {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let flight_dir = dir.path().join("flight");
    std::fs::create_dir(&flight_dir).expect("dir");
    flight::write_flight(&flight_dir);
    // 40 bytes of garbage before the imu record at 5.00 s: 500 fast records (12 + 26 bytes)
    // and 5 slow ones (12 + 38) after the first data block.
    let imu = flight_dir.join("imu.bin");
    let mut bytes = std::fs::read(&imu).expect("imu");
    let first_data = bytes.iter().position(|&b| b == 0xDB).expect("data");
    let at = first_data + 500 * 38 + (500 / 100) * 50;
    assert_eq!(bytes[at], 0xDB, "a record starts at {at}");
    bytes.splice(at..at, [0x7Bu8; 40]);
    std::fs::write(&imu, &bytes).expect("write");
    let out = run(bin().arg("to-ulog").arg(&flight_dir));
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(
        err.contains(&format!("{}: offset {at}: ", imu.display())),
        "{err}"
    );
    let u = Ulog::read(&flight_dir.join("flight.ulg"));
    let warnings: Vec<&Json> = u.0["messages"]
        .as_array()
        .expect("messages")
        .iter()
        .filter(|m| {
            m[1] == "WARNING"
                && m[2]
                    .as_str()
                    .is_some_and(|t| t.contains(&format!("offset {at}")))
        })
        .collect();
    assert_eq!(warnings.len(), 1, "{:?}", u.0["messages"]);
    // Between the last record before the damage (4.99 s) and the next (5.00 s).
    assert_eq!(u.0["dropouts"], serde_json::json!([[4_990_000, 10]]));
}

/// PX4's message definitions (v1.14 `msg/*.msg`, sensor_gps as v1.14 declares it) for every
/// field the converter may write, copied from the .msg files — kept apart from the
/// converter's table so that one cannot silently follow the other.
const PX4_MSG: &[(&str, &str)] = &[
    (
        "sensor_combined",
        "uint64 timestamp; float32[3] gyro_rad; uint32 gyro_integral_dt; \
         int32 accelerometer_timestamp_relative; float32[3] accelerometer_m_s2; \
         uint32 accelerometer_integral_dt; uint8 accelerometer_clipping; uint8 gyro_clipping",
    ),
    (
        "vehicle_gps_position",
        "uint64 timestamp; uint32 device_id; int32 lat; int32 lon; int32 alt; \
         int32 alt_ellipsoid; float32 s_variance_m_s; float32 c_variance_rad; uint8 fix_type; \
         float32 eph; float32 epv; float32 hdop; float32 vdop; int32 noise_per_ms; \
         float32 vel_m_s; float32 vel_n_m_s; float32 vel_e_m_s; float32 vel_d_m_s; \
         float32 cog_rad; bool vel_ned_valid; int32 timestamp_time_relative; \
         uint64 time_utc_usec; uint8 satellites_used; float32 heading",
    ),
    (
        "vehicle_attitude",
        "uint64 timestamp; uint64 timestamp_sample; float32[4] q; float32[4] delta_q_reset; \
         uint8 quat_reset_counter",
    ),
    (
        "vehicle_attitude_groundtruth",
        "uint64 timestamp; float32[4] q",
    ),
    (
        "vehicle_local_position",
        "uint64 timestamp; bool xy_valid; bool z_valid; bool v_xy_valid; bool v_z_valid; \
         float32 x; float32 y; float32 z; float32 vx; float32 vy; float32 vz; float32 ax; \
         float32 ay; float32 az; float32 heading; bool xy_global; bool z_global; \
         uint64 ref_timestamp; float64 ref_lat; float64 ref_lon; float32 ref_alt; \
         float32 eph; float32 epv; float32 evh; float32 evv",
    ),
    (
        "vehicle_local_position_groundtruth",
        "uint64 timestamp; float32 x; float32 y; float32 z; float32 vx; float32 vy; \
         float32 vz; float32 heading",
    ),
    (
        "vehicle_global_position",
        "uint64 timestamp; float64 lat; float64 lon; float32 alt; float32 alt_ellipsoid; \
         float32 eph; float32 epv",
    ),
    (
        "actuator_outputs",
        "uint64 timestamp; uint32 noutputs; float32[16] output",
    ),
    (
        "input_rc",
        "uint64 timestamp; uint64 timestamp_last_signal; uint8 channel_count; int32 rssi; \
         bool rc_failsafe; bool rc_lost; uint16[18] values",
    ),
    (
        "battery_status",
        "uint64 timestamp; bool connected; float32 voltage_v; float32 current_a; \
         float32 discharged_mah; float32 remaining; uint8 cell_count; uint8 id",
    ),
    (
        "vehicle_status",
        "uint64 timestamp; uint8 nav_state; uint8 arming_state",
    ),
    (
        "vehicle_attitude_setpoint",
        "uint64 timestamp; float32 roll_body; float32 pitch_body; float32 yaw_body; \
         float32[4] q_d; float32[3] thrust_body",
    ),
    (
        "tecs_status",
        "uint64 timestamp; float32 altitude_sp; float32 altitude_sp_filtered; \
         float32 true_airspeed_sp; float32 true_airspeed_filtered",
    ),
];

/// The fields pyulog reports for a .msg declaration: arrays flattened, ULog type names.
fn msg_fields(declaration: &str) -> BTreeMap<String, String> {
    let mut fields = BTreeMap::new();
    for field in declaration.split(';').map(str::trim) {
        let (ty, name) = field.split_once(' ').expect("type name");
        let (ty, len) = match ty.split_once('[') {
            Some((t, n)) => (t, n.trim_end_matches(']').parse::<usize>().expect("len")),
            None => (ty, 0),
        };
        let ulog = match ty {
            "float32" => "float".to_string(),
            "float64" => "double".to_string(),
            "bool" => "bool".to_string(),
            other => format!("{other}_t"),
        };
        if len == 0 {
            fields.insert(name.to_string(), ulog);
        } else {
            for i in 0..len {
                fields.insert(format!("{name}[{i}]"), ulog.clone());
            }
        }
    }
    fields
}

#[test]
fn px4_named_topics_have_px4_field_names_and_types() {
    if !python_has("pyulog", "px4_named_topics_have_px4_field_names_and_types") {
        return;
    }
    let c = convert_full_flight();
    let topics = c.ulog.0["topics"].as_array().expect("topics");
    // The topics the issue asks for are there.
    for wanted in [
        "sensor_combined",
        "vehicle_gps_position",
        "vehicle_attitude",
        "vehicle_local_position",
        "vehicle_global_position",
        "actuator_outputs",
        "input_rc",
        "battery_status",
        "vehicle_status",
        "vehicle_attitude_setpoint",
        "tecs_status",
    ] {
        assert!(
            topics.iter().any(|t| t["name"] == wanted),
            "{wanted} missing"
        );
    }
    for topic in topics {
        let name = topic["name"].as_str().expect("name");
        if name.starts_with("skyframe_") {
            continue;
        }
        let declared = PX4_MSG
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, d)| msg_fields(d))
            .unwrap_or_else(|| panic!("{name}: not a skyframe_ topic and not in PX4_MSG"));
        for (field, ty) in topic["types"].as_object().expect("types") {
            // pyulog reports each array element with the element's type.
            assert_eq!(
                declared.get(field).map(String::as_str),
                Some(ty.as_str().expect("type")),
                "{name}.{field}: not PX4's name or type"
            );
        }
    }
    // The fields the issue names.
    let types = |t: &str| c.ulog.topic(t, 0)["types"].clone();
    for (topic, fields) in [
        (
            "sensor_combined",
            &["gyro_rad[2]", "accelerometer_m_s2[2]"][..],
        ),
        (
            "vehicle_gps_position",
            &[
                "lat",
                "lon",
                "alt",
                "fix_type",
                "eph",
                "epv",
                "vel_n_m_s",
                "satellites_used",
            ],
        ),
        ("vehicle_attitude", &["q[0]", "q[3]"]),
        ("vehicle_status", &["nav_state"]),
    ] {
        for field in fields {
            assert!(types(topic).get(field).is_some(), "{topic}.{field} missing");
        }
    }
}

#[test]
fn parquet_of_two_flights_reads_back_with_pyarrow() {
    if !python_has("pyarrow", "parquet_of_two_flights_reads_back_with_pyarrow") {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let a = dir.path().join("2026-11-25T10-00-00Z");
    let b = dir.path().join("2026-11-25T11-00-00Z");
    for f in [&a, &b] {
        std::fs::create_dir(f).expect("dir");
        flight::write_full_flight(f);
    }
    let out_dir = dir.path().join("parquet");
    let out = run(bin()
        .arg("to-parquet")
        .arg(&a)
        .arg(&b)
        .arg("--out-dir")
        .arg(&out_dir)
        .args(["--vehicle-id", "7"]));
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let csv_dir = dir.path().join("csv");
    let out = run(bin().arg("to-csv").arg(&a).arg("--out-dir").arg(&csv_dir));
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));

    const READ: &str = r#"
import sys, json, math
import pyarrow.parquet as pq
f = pq.ParquetFile(sys.argv[1])
t = f.read()
clean = lambda x: None if isinstance(x, float) and math.isnan(x) else x
print(json.dumps({
    "row_groups": f.metadata.num_row_groups,
    "types": {field.name: str(field.type) for field in t.schema},
    "columns": {name: [clean(x) for x in t.column(name).to_pylist()] for name in t.column_names},
}))
"#;
    for (name, types) in [
        (
            "imu.1",
            &[
                ("counter", "uint8"),
                ("p_rad_s", "float"),
                ("status", "uint8"),
            ][..],
        ),
        (
            "gps.1",
            &[
                ("lat_deg", "double"),
                ("utc_ms", "uint32"),
                ("valid", "uint8"),
            ],
        ),
        ("executive.1", &[("frame", "uint64"), ("flags", "uint8")]),
        ("control.2", &[("roll_kp", "float")]),
    ] {
        let read = run(Command::new("python3")
            .args(["-c", READ])
            .arg(out_dir.join(format!("{name}.parquet"))));
        assert!(read.status.success(), "{name}: {}", stderr(&read));
        let p: Json = serde_json::from_slice(&read.stdout).expect("json");
        assert_eq!(p["row_groups"], 2, "{name}: one row group per flight");
        assert_eq!(p["types"]["flight_id"], "string");
        assert_eq!(p["types"]["time_ns"], "int64");
        for (column, ty) in types {
            assert_eq!(p["types"][column], *ty, "{name}.{column}");
        }
        let csv = Csv::read(&csv_dir.join(format!("{name}.csv")));
        let n = csv.times_ns.len();
        let column = |c: &str| -> Vec<Json> { p["columns"][c].as_array().expect("column").clone() };
        let flights = column("flight_id");
        assert_eq!(flights.len(), 2 * n, "{name}: both flights' rows");
        assert!(flights[..n].iter().all(|f| f == "2026-11-25T10-00-00Z"));
        assert!(flights[n..].iter().all(|f| f == "2026-11-25T11-00-00Z"));
        assert!(column("vehicle_id").iter().all(|v| v == "7"));
        let times: Vec<i64> = column("time_ns")
            .iter()
            .map(|t| t.as_i64().expect("t"))
            .collect();
        assert_eq!(&times[..n], &csv.times_ns[..], "{name}.time_ns");
        for c in &csv.columns {
            let ours: Vec<f64> = column(c)[..n]
                .iter()
                .map(|v| v.as_f64().unwrap_or(f64::NAN))
                .collect();
            assert_close(
                &format!("{name}.{c}"),
                &ours,
                &csv.column(c),
                csv.tolerance_of(c),
            );
        }
    }
}

#[test]
fn converters_given_nothing_say_so_in_one_line_and_fail() {
    let dir = tempfile::tempdir().expect("temp dir");
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).expect("dir");
    let missing = dir.path().join("missing");
    let garbage = dir.path().join("garbage.bin");
    std::fs::write(&garbage, [0x55u8; 300]).expect("write");
    let out_dir = dir.path().join("out");
    let cases: Vec<(Vec<&std::ffi::OsStr>, String)> = vec![
        (
            vec!["to-ulog".as_ref(), empty.as_os_str()],
            format!(
                "skyframe-log: {}: no stream files (*.bin, or text logs",
                empty.display()
            ),
        ),
        (
            vec!["to-ulog".as_ref(), missing.as_os_str()],
            format!(
                "skyframe-log: {}: no such file or directory",
                missing.display()
            ),
        ),
        (
            vec!["to-ulog".as_ref(), garbage.as_os_str()],
            format!(
                "skyframe-log: {}: no data records to convert",
                garbage.display()
            ),
        ),
        (
            vec![
                "to-parquet".as_ref(),
                empty.as_os_str(),
                "--out-dir".as_ref(),
                out_dir.as_os_str(),
            ],
            format!(
                "skyframe-log: {}: no stream files (*.bin, or text logs",
                empty.display()
            ),
        ),
        (
            vec![
                "to-parquet".as_ref(),
                garbage.as_os_str(),
                "--out-dir".as_ref(),
                out_dir.as_os_str(),
            ],
            "skyframe-log: no data records to convert in ".to_string(),
        ),
    ];
    for (args, start) in cases {
        let out = run(bin().args(&args));
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        let err = stderr(&out);
        let last = err.lines().last().unwrap_or_default();
        assert!(last.starts_with(&start), "{args:?}: {err}");
        // Damage lines (the garbage file's) come first; the verdict is one line.
        assert!(
            err.lines()
                .filter(|l| l.starts_with("skyframe-log: "))
                .count()
                == 1,
            "{err}"
        );
    }
    // An output that cannot be written is named.
    let flight_dir = dir.path().join("flight");
    std::fs::create_dir(&flight_dir).expect("dir");
    flight::write_imu(&flight_dir);
    let bad = dir.path().join("no/such/dir/flight.ulg");
    let out = run(bin().arg("to-ulog").arg(&flight_dir).arg("-o").arg(&bad));
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).starts_with(&format!("skyframe-log: {}: ", bad.display())),
        "{}",
        stderr(&out)
    );
}

#[test]
fn no_input_makes_the_converters_panic() {
    // Random bytes, a real stream cut at every 7th length, text logs that do not fit their
    // formats: never a panic (exit 101), always a verdict (0, 2 or 3).
    let dir = tempfile::tempdir().expect("temp dir");
    let flight_dir = dir.path().join("flight");
    std::fs::create_dir(&flight_dir).expect("dir");
    flight::write_servo(&flight_dir);
    let servo = std::fs::read(flight_dir.join("servo.bin")).expect("servo");
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut inputs: Vec<Vec<u8>> = (0..20)
        .map(|n| {
            (0..n * 37)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state >> 24) as u8
                })
                .collect()
        })
        .collect();
    inputs.extend(
        (1..servo.len().min(700))
            .step_by(7)
            .map(|n| servo[..n].to_vec()),
    );
    // Text logs (`--text-log` streams) with lines that do not fit their format.
    let text_logs: Vec<&[u8]> = vec![
        b"% format 1: %hhu,%.4f\n1.000000000,7,0.5\n99999999999.0,1,1\n-5.5,1,1\n1.2000000000,1,1\n",
        b"% format 1: %hhu,%.4f\n1.0,300,nan\n1.0,-1,-nan\n1.0,1\n1.0,1,2,3\n1.0\n,\n\n",
        b"% format 1: %d%d\n1.0,12\n% format 1: %s\n1.0,x\n% format 1: 100%% %x|%c\n1.0,100% ff|\xff\n",
        b"% format 1: %lld,%llu,%hd\n1.0,-9223372036854775809,18446744073709551616,70000\n",
        b"% format 1\n1.0,1\n% time,a,b,c\n% format 2: %f\n1.0,1e400\n",
    ];
    let cases = inputs.len();
    for (i, bytes) in inputs
        .iter()
        .map(Vec::as_slice)
        .chain(text_logs)
        .enumerate()
    {
        let case = dir.path().join(format!("case{i}"));
        std::fs::create_dir(&case).expect("dir");
        let name = if i < cases {
            "servo.bin"
        } else {
            "servo.1.csv"
        };
        std::fs::write(case.join(name), bytes).expect("write");
        for args in [
            vec!["to-ulog".to_string(), case.display().to_string()],
            vec![
                "to-parquet".to_string(),
                case.display().to_string(),
                "--out-dir".to_string(),
                case.join("pq").display().to_string(),
            ],
        ] {
            let out = run(bin().args(&args));
            let code = out.status.code();
            assert!(
                matches!(code, Some(0 | 2 | 3)),
                "{args:?}: {code:?} {}",
                stderr(&out)
            );
            assert!(
                !stderr(&out).contains("panicked"),
                "{args:?}: {}",
                stderr(&out)
            );
        }
    }
}

#[test]
fn text_log_streams_convert_like_their_binary_logs() {
    if !python_has("pyulog", "text_log_streams_convert_like_their_binary_logs") {
        return;
    }
    let c = convert_full_flight();
    // The same flight with imu and gps flown as text logs (`--text-log`): a text log is
    // exactly what to-csv writes for the binary (log-format.md).
    let text_flight = c._dir.path().join("text-flight");
    std::fs::create_dir(&text_flight).expect("dir");
    for entry in std::fs::read_dir(&c.flight).expect("list").flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.ends_with(".bin") && name != "imu.bin" && name != "gps.bin" {
            std::fs::copy(entry.path(), text_flight.join(&name)).expect("copy");
        }
    }
    for name in ["imu.1.csv", "imu.2.csv", "gps.1.csv"] {
        std::fs::copy(c.csv.join(name), text_flight.join(name)).expect("copy");
    }
    // A line that does not parse is reported with its line number and skipped.
    let imu_text = text_flight.join("imu.1.csv");
    let mut text = std::fs::read_to_string(&imu_text).expect("read");
    let lines = text.lines().count();
    text.push_str("1700000020.000000000,x,0.1,0.1,0.1,0.0,0.0,-9.8,0\n");
    std::fs::write(&imu_text, text).expect("write");
    let out = run(bin().arg("to-ulog").arg(&text_flight));
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert_eq!(
        stderr(&out),
        format!(
            "{}: line {}: field 1 \"x\" is not a u8; line skipped\n",
            imu_text.display(),
            lines + 1
        )
    );
    let t = Ulog::read(&text_flight.join("flight.ulg"));
    assert_eq!(t.origin_ns(), c.ulog.origin_ns());
    for (topic, csv_name) in [
        ("skyframe_imu", "imu.1"),
        ("skyframe_imu_slow", "imu.2"),
        ("skyframe_gps", "gps.1"),
    ] {
        let csv = csv_of(&c, csv_name);
        let fields = ["timestamp".to_string()]
            .into_iter()
            .chain(csv.columns.clone());
        for field in fields {
            let tolerance = if field == "timestamp" {
                0.0
            } else {
                csv.tolerance_of(&field)
            };
            assert_close(
                &format!("text {topic}.{field}"),
                &t.series(topic, 0, &field),
                &c.ulog.series(topic, 0, &field),
                tolerance,
            );
        }
    }
    let imu = csv_of(&c, "imu.1");
    assert_close(
        "text sensor_combined.gyro_rad[0]",
        &t.series("sensor_combined", 0, "gyro_rad[0]"),
        &c.ulog.series("sensor_combined", 0, "gyro_rad[0]"),
        imu.tolerance_of("p_rad_s"),
    );
    assert_close(
        "text vehicle_gps_position.lat",
        &t.series("vehicle_gps_position", 0, "lat"),
        &c.ulog.series("vehicle_gps_position", 0, "lat"),
        1.0,
    );
}

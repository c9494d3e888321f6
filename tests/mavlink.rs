//! MAVLink 2 acceptance (issue 16): the real `skyframe sim` binary on 127.0.0.1 with
//! pymavlink — MAVLink's reference implementation — as the ground station
//! (`tests/mavlink/ground.py`, which only reports what it saw). What it saw is compared with
//! sources that do not go through the MAVLink code: the simulator's home (truth log), the
//! flight's own logs read back with `skyframe-log to-csv`, the shipped parameter table and
//! the mission file.
//!
//! Plus issue 21's MAVLink share: a shutdown request ends a run with a stuck task within
//! 1 s, and a flood of wrong-key frames does not keep the key holder's sets out.

use skyframe_core::link::params::ParamTable;
use skyframe_core::tasks::control::{ControlSettings, define_params};
use skyframe_shell::mavlink::params::mavlink_id;
use skyframe_tests::{
    csv_column, csv_columns, csv_rows, scratch, shipped, skyframe, spawn_piped, to_csv, workspace,
};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::time::{Duration, Instant};

/// The flood test runs alone: its 150 000 frames/s share two cores with nothing else of this
/// file, so what it measures is the endpoint, not the machine's other load.
static FLOOD_ALONE: std::sync::RwLock<()> = std::sync::RwLock::new(());

fn free_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

/// `ground.py PORT PHASE [ARG]`, its JSON.
fn ground(port: u16, phase: &str, arg: Option<&str>) -> serde_json::Value {
    let script = workspace().join("tests/mavlink/ground.py");
    let mut cmd = Command::new("python3");
    cmd.arg(&script).arg(port.to_string()).arg(phase);
    if let Some(a) = arg {
        cmd.arg(a);
    }
    let out = cmd.output().expect("python3 runs");
    assert!(
        out.status.success(),
        "ground.py {phase}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let value: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "ground.py {phase} printed no JSON ({e}): {}",
            String::from_utf8_lossy(&out.stdout)
        )
    });
    assert_eq!(value["contact"], true, "no heartbeat from the vehicle");
    value
}

/// A scenario that stays parked on the runway with the brakes on.
const PARKED: &str = r#"
seed = 11
duration_s = 120
[initial]
kind = "runway"
heading_deg = 0
[wind]
speed_mps = 0
from_deg = 0
turbulence = "none"
[gps]
preset = "nominal"
[runway]
touchdown_north_m = 100
touchdown_east_m = 0
heading_deg = 0
[[timeline]]
t_s = 0
switch = "manual"
[[timeline]]
t_s = 0
pilot = "sticks"
aileron = 0
elevator = 0
rudder = 0
throttle = 0
brake = 1
duration_s = 120
"#;

fn start_sim(dir: &Path, args: &[&str]) -> Child {
    spawn_piped(
        skyframe()
            .arg("sim")
            .args(args)
            .arg("--log-dir")
            .arg(dir)
            .arg("--json"),
    )
}

/// What a test of one vehicle starts from: the lock that keeps it apart from the flood test
/// (hold it to the test's end), a scratch directory and a free port for the ground station.
fn setup(test: &str) -> (std::sync::RwLockReadGuard<'static, ()>, PathBuf, u16) {
    let others = FLOOD_ALONE
        .read()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    (others, scratch(test), free_port())
}

/// [`PARKED`] written into `dir`; its path.
fn parked_in(dir: &Path) -> String {
    let scenario = dir.join("parked.toml");
    std::fs::write(&scenario, PARKED).expect("scenario");
    scenario.to_str().expect("utf-8 path").to_string()
}

/// `sim --speedup SPEEDUP --no-link --mavlink udpin:127.0.0.1:PORT ARGS…`: MAVLink alone, the
/// vehicle listening on `port`.
fn sim_on_mavlink(dir: &Path, port: u16, speedup: &str, args: &[&str]) -> Child {
    let endpoint = format!("udpin:127.0.0.1:{port}");
    let mavlink = ["--speedup", speedup, "--no-link", "--mavlink", &endpoint];
    start_sim(dir, &[&mavlink[..], args].concat())
}

/// The AUTO circuit (`scenarios/auto-circuit.toml` with its mission), whole (235 s), at 8×
/// real time, on MAVLink alone.
fn auto_circuit_on_mavlink(dir: &Path, port: u16) -> Child {
    let (scenario, mission) = (shipped("auto-circuit"), shipped("circuit-mission"));
    let circuit = [
        "--duration",
        "235",
        "--scenario",
        &scenario,
        "--mission",
        &mission,
    ];
    sim_on_mavlink(dir, port, "8", &circuit)
}

/// The sequence numbers of a mission's waypoints (MAV_CMD_NAV_WAYPOINT items).
fn waypoint_seqs(items: &[serde_json::Value]) -> Vec<u64> {
    items
        .iter()
        .filter(|i| i["command"] == 16)
        .map(|i| i["seq"].as_u64().expect("seq"))
        .collect()
}

/// The MISSION_ITEM_REACHED sequence numbers the ground saw, in order.
fn reached(seen: &serde_json::Value) -> Vec<u64> {
    seen["reached"]
        .as_array()
        .expect("reached")
        .iter()
        .map(|s| s.as_u64().expect("seq"))
        .collect()
}

/// A MAVLink 2 signing key file (mode 0600) holding `bytes`; its path.
fn key_file(dir: &Path, bytes: &[u8]) -> String {
    use std::os::unix::fs::PermissionsExt;
    let key = dir.join("mavlink.key");
    std::fs::write(&key, bytes).expect("key");
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).expect("chmod");
    key.to_str().expect("utf-8 path").to_string()
}

/// Ends a run with SIGINT (a clean stop) and returns its JSON report.
fn stop_sim(child: Child) -> serde_json::Value {
    let pid = nix::unistd::Pid::from_raw(i32::try_from(child.id()).expect("pid"));
    let _ = nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT);
    finish_sim(child)
}

fn finish_sim(child: Child) -> serde_json::Value {
    let out = child.wait_with_output().expect("sim ends");
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "no report ({e}); exit {:?}: {}",
            out.status.code(),
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

/// The row of a `skyframe-log to-csv` file at log TIME `t_s` (to the millisecond), by
/// column name.
fn row_at(csv: &Path, t_s: f64) -> std::collections::HashMap<String, f64> {
    let names = csv_columns(csv);
    let row = csv_rows(csv)
        .into_iter()
        .find(|r| (r[0] - t_s).abs() < 0.0005)
        .unwrap_or_else(|| panic!("no record at {t_s} s in {}", csv.display()));
    names.iter().zip(row).map(|(n, v)| (n.clone(), v)).collect()
}

/// Metres between two latitude/longitude points (equirectangular: fine over metres).
fn metres(lat1: f64, lon1: f64, lat2: f64, lon2: f64) -> f64 {
    let r = 6_371_000.0;
    let dn = (lat2 - lat1).to_radians() * r;
    let de = (lon2 - lon1).to_radians() * r * lat1.to_radians().cos();
    dn.hypot(de)
}

fn f(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn flight_csv(report: &serde_json::Value, dir: &Path) -> PathBuf {
    let flight = PathBuf::from(report["flight_dir"].as_str().expect("flight_dir"));
    to_csv(&[&flight], &dir.join("csv"))
}

#[test]
fn a_parked_vehicle_speaks_mavlink_to_pymavlink() {
    let (_others, dir, port) = setup("mavlink-parked");
    let dir = dir.as_path();
    let mission = shipped("circuit-mission");
    let sim = sim_on_mavlink(
        dir,
        port,
        "1",
        &[
            "--scenario",
            &parked_in(dir),
            "--mission",
            &mission,
            // A warning the vehicle reports: imu over its budget in frames 500..505 (5 s).
            "--inject-overrun",
            "imu:1000@500..505",
        ],
    );
    let seen = ground(port, "parked", None);
    let report = stop_sim(sim);
    let csv = flight_csv(&report, dir);

    // The scenario's home: the simulator's GPS origin, as its truth log records it.
    let home_lat = csv_column(&csv.join("truth.2.csv"), "origin_lat_deg")[0];
    let home_lon = csv_column(&csv.join("truth.2.csv"), "origin_lon_deg")[0];
    let home_alt = csv_column(&csv.join("truth.2.csv"), "origin_alt_m")[0];

    // HEARTBEAT: 1 Hz, a fixed wing, generic autopilot, custom mode = the logged mode.
    let beats = seen["heartbeats"].as_array().expect("heartbeats");
    assert!(beats.len() >= 10, "{} heartbeats in 12 s", beats.len());
    let span = f(&beats[beats.len() - 1]["t"]) - f(&beats[0]["t"]);
    let rate = (beats.len() - 1) as f64 / span;
    assert!((0.85..=1.15).contains(&rate), "heartbeat at {rate:.2} Hz");
    let beat = &beats[beats.len() - 1];
    assert_eq!(beat["type"], 1, "MAV_TYPE_FIXED_WING");
    assert_eq!(beat["autopilot"], 0, "MAV_AUTOPILOT_GENERIC");
    assert_eq!(f(&beat["base_mode"]) as u32 & 1, 1, "CUSTOM_MODE_ENABLED");
    let logged_mode = csv_column(&csv.join("control.1.csv"), "mode");
    assert!(logged_mode.iter().all(|m| *m == 0.0), "parked in manual");
    assert_eq!(f(&beat["custom_mode"]), 0.0);

    let last = |t: &str| &seen["streams"][t]["last"];
    for t in [
        "SYS_STATUS",
        "EXTENDED_SYS_STATE",
        "ATTITUDE",
        "GLOBAL_POSITION_INT",
        "GPS_RAW_INT",
        "VFR_HUD",
        "BATTERY_STATUS",
        "SERVO_OUTPUT_RAW",
        "RC_CHANNELS",
        "SCALED_IMU",
        "MISSION_CURRENT",
        "HOME_POSITION",
    ] {
        assert!(!last(t).is_null(), "no {t}");
    }
    // ATTITUDE and GLOBAL_POSITION_INT are the estimator's log record at their time_boot_ms
    // (virtual time: log TIME = time since start), value for value (the log's text keeps
    // 5 decimals of radians, 3 of metres).
    let att = last("ATTITUDE");
    let rec = row_at(
        &csv.join("estimator.1.csv"),
        f(&att["time_boot_ms"]) / 1000.0,
    );
    assert!(
        (f(&att["roll"]) - rec["roll_rad"]).abs() <= 6e-6,
        "{att} vs {rec:?}"
    );
    assert!(
        (f(&att["pitch"]) - rec["pitch_rad"]).abs() <= 6e-6,
        "{att} vs {rec:?}"
    );
    let yaw = (rec["yaw_rad"] + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
        - std::f64::consts::PI;
    assert!((f(&att["yaw"]) - yaw).abs() <= 6e-6, "{att} vs {rec:?}");
    let gpi = last("GLOBAL_POSITION_INT");
    let rec = row_at(
        &csv.join("estimator.1.csv"),
        f(&gpi["time_boot_ms"]) / 1000.0,
    );
    assert!(
        (f(&gpi["relative_alt"]) * 1e-3 + rec["pd_m"]).abs() <= 0.0011,
        "{gpi} vs {rec:?}"
    );
    assert!(
        (f(&gpi["vx"]) * 1e-2 - rec["vn_m_s"]).abs() <= 0.0051,
        "{gpi} vs {rec:?}"
    );
    assert!(
        (f(&gpi["vy"]) * 1e-2 - rec["ve_m_s"]).abs() <= 0.0051,
        "{gpi} vs {rec:?}"
    );
    assert!(
        (f(&gpi["vz"]) * 1e-2 - rec["vd_m_s"]).abs() <= 0.0051,
        "{gpi} vs {rec:?}"
    );

    // Parked: level within 3°, on the ground, where the scenario put it.
    assert!(f(&last("ATTITUDE")["roll"]).abs() < 3f64.to_radians());
    assert!(f(&last("ATTITUDE")["pitch"]).abs() < 3f64.to_radians());
    assert_eq!(last("EXTENDED_SYS_STATE")["landed_state"], 1, "ON_GROUND");
    let pos = last("GLOBAL_POSITION_INT");
    let (lat, lon) = (f(&pos["lat"]) * 1e-7, f(&pos["lon"]) * 1e-7);
    let off = metres(home_lat, home_lon, lat, lon);
    assert!(off < 10.0, "GLOBAL_POSITION_INT {off:.1} m from home");
    assert!((f(&pos["alt"]) * 1e-3 - home_alt).abs() < 8.0, "{pos}");
    let gps = last("GPS_RAW_INT");
    assert_eq!(gps["fix_type"], 3);
    let off = metres(
        home_lat,
        home_lon,
        f(&gps["lat"]) * 1e-7,
        f(&gps["lon"]) * 1e-7,
    );
    assert!(off < 10.0, "GPS_RAW_INT {off:.1} m from home");
    let home = &seen["home"];
    assert_eq!(seen["home_ack"], 0);
    let off = metres(
        home_lat,
        home_lon,
        f(&home["latitude"]) * 1e-7,
        f(&home["longitude"]) * 1e-7,
    );
    assert!(
        off < 10.0,
        "HOME_POSITION {off:.1} m from the scenario's home"
    );
    // Specific force of a parked airplane: −1 g on body z (down).
    let imu = last("SCALED_IMU");
    assert!((f(&imu["zacc"]) + 1000.0).abs() < 50.0, "{imu}");
    // Battery and sticks equal to what the servo board logged.
    let volts = csv_column(&csv.join("servo.1.csv"), "batt_avionics_v");
    let mv = f(&last("BATTERY_STATUS")["voltages"][0]);
    let (lo, hi) = volts
        .iter()
        .fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
    assert!(
        mv >= lo * 1e3 - 1.0 && mv <= hi * 1e3 + 1.0,
        "{mv} mV not in the log's {lo}..{hi} V"
    );
    let mv = f(&last("SYS_STATUS")["voltage_battery"]);
    assert!(
        mv >= lo * 1e3 - 1.0 && mv <= hi * 1e3 + 1.0,
        "SYS_STATUS {mv} mV not in the log's {lo}..{hi} V"
    );
    for ch in 1..=8 {
        let logged = csv_column(&csv.join("servo.1.csv"), &format!("ch{ch}_us"));
        let sent = f(&last("RC_CHANNELS")[format!("chan{ch}_raw").as_str()]);
        assert!(logged.contains(&sent), "chan{ch}_raw {sent} never logged");
    }
    // GPS, IMU, servo and estimator present in SYS_STATUS.
    let present = f(&last("SYS_STATUS")["onboard_control_sensors_present"]) as u32;
    for bit in [1u32, 2, 32, 0x8000, 0x20_0000] {
        assert_eq!(present & bit, bit, "sensor bit {bit:#x} not present");
    }

    // The injected overruns, as the health log counted them, reach the ground as text.
    let health = csv.join("health.1.csv");
    let imu_task = 0.0; // the frame table's first task
    let overruns = csv_column(&health, "task")
        .iter()
        .zip(csv_column(&health, "overruns_budget"))
        .filter(|(t, _)| **t == imu_task)
        .map(|(_, n)| n)
        .fold(0.0, f64::max);
    assert!(overruns >= 1.0, "the log counted the overruns");
    let texts: Vec<&str> = seen["statustexts"]
        .as_array()
        .expect("texts")
        .iter()
        .filter_map(|t| t.as_str())
        .collect();
    assert!(
        texts.iter().any(|t| t.starts_with("imu: budget overruns")),
        "{texts:?}"
    );

    // AUTOPILOT_VERSION on MAV_CMD_REQUEST_MESSAGE.
    assert_eq!(seen["autopilot_version_ack"], 0);
    let version = &seen["autopilot_version"];
    let caps = f(&version["capabilities"]) as u64;
    for bit in [8192u64, 4, 131_072] {
        assert_eq!(caps & bit, bit, "capability {bit} missing");
    }
    let git = Command::new("git")
        .args(["rev-parse", "HEAD"])
        .current_dir(workspace())
        .output()
        .expect("git");
    let hash = String::from_utf8_lossy(&git.stdout);
    let custom: Vec<u8> = version["flight_custom_version"]
        .as_array()
        .expect("bytes")
        .iter()
        .map(|b| f(b) as u8)
        .collect();
    assert_eq!(&custom[..], &hash.as_bytes()[..8], "git hash");

    // Parameters: every shipped one, by its documented id, with the shipped default.
    let mut table = ParamTable::new();
    define_params(&mut table, &ControlSettings::default()).expect("params");
    let params = seen["params"].as_array().expect("params");
    assert_eq!(params.len(), table.len());
    for (i, p) in params.iter().enumerate() {
        let shipped = table.by_index(i).expect("param");
        assert_eq!(p["id"], mavlink_id(shipped.name().as_str()).as_str());
        assert_eq!(f(&p["count"]) as usize, table.len());
        let skyframe_core::link::messages::Value::F32(v) = shipped.value() else {
            panic!("control params are f32");
        };
        assert_eq!(f(&p["value"]) as f32, v, "{}", p["id"]);
    }
    assert_eq!(seen["param_read_by_index"]["param_index"], 3);
    assert_eq!(
        seen["param_read_by_index"]["param_id"],
        mavlink_id(table.by_index(3).expect("p").name().as_str()).as_str()
    );
    // A set in range is applied (the control task logs the new gain), a set out of range
    // answers the value in force.
    assert_eq!(f(&seen["set_accepted"]) as f32, 0.75);
    assert_eq!(f(&seen["set_rejected"]) as f32, 0.75);
    assert_eq!(f(&seen["read_back"]) as f32, 0.75);
    let gains = csv_column(&csv.join("control.2.csv"), "roll_kp");
    assert_eq!(gains.first(), Some(&1.2));
    assert_eq!(gains.last(), Some(&0.75), "the log's roll gain");

    // The mission: the mission file's waypoints, positions from home, altitudes above it.
    let file = skyframe_shell::mission::load(&workspace().join("scenarios/circuit-mission.toml"))
        .expect("mission");
    let items = seen["mission"].as_array().expect("mission");
    let waypoints: Vec<&serde_json::Value> = items.iter().filter(|i| i["command"] == 16).collect();
    assert_eq!(waypoints.len(), file.waypoints.len());
    for (item, w) in waypoints.iter().zip(&file.waypoints) {
        let lat = home_lat + (f64::from(w.north_m) / 6_371_000.0).to_degrees();
        let lon = home_lon
            + (f64::from(w.east_m) / (6_371_000.0 * home_lat.to_radians().cos())).to_degrees();
        let off = metres(lat, lon, f(&item["x"]) * 1e-7, f(&item["y"]) * 1e-7);
        assert!(off < 12.0, "waypoint {off:.1} m from the mission file's");
        assert_eq!(f(&item["z"]) as f32, w.altitude_m);
    }
    let speed = items.iter().find(|i| i["command"] == 178).expect("speed");
    assert_eq!(f(&speed["param2"]) as f32, file.waypoints[0].airspeed_mps);
    let loiter = items.last().expect("loiter");
    assert_eq!(loiter["command"], 17);
    assert_eq!(f(&loiter["param3"]) as f32, file.loiter_radius_m);
    assert_eq!(seen["upload_same"], 0, "MAV_MISSION_ACCEPTED");
    assert_eq!(seen["upload_takeoff"], 3, "MAV_MISSION_UNSUPPORTED");
    assert_eq!(
        seen["upload_local_frame"], 2,
        "MAV_MISSION_UNSUPPORTED_FRAME"
    );

    // Commands: every one answered.
    assert_eq!(seen["unsupported_command"], 3, "MAV_RESULT_UNSUPPORTED");
    assert_eq!(seen["set_mode_stabilise"], 0, "ACCEPTED");
    assert_eq!(seen["set_mode_nonsense"], 2, "DENIED");
    assert!(!seen["arm"].is_null(), "arming answered");
    // SET_MESSAGE_INTERVAL: ATTITUDE at 2 Hz over 4 s.
    assert_eq!(seen["interval_ack"], 0);
    let attitude = &seen["attitude_after_interval"];
    let hz = (f(&attitude["count"]) - 1.0) / (f(&attitude["last_t"]) - f(&attitude["first_t"]));
    assert!((1.5..=2.6).contains(&hz), "ATTITUDE at {hz:.2} Hz");

    let counters = &report["mavlink"];
    assert_eq!(counters["malformed"], 0);
    assert!(f(&counters["accepted"]) > 20.0);
}

#[test]
fn with_speedup_the_auto_mission_reports_every_waypoint_reached() {
    let (_others, dir, port) = setup("mavlink-auto");
    let started = Instant::now();
    let sim = auto_circuit_on_mavlink(&dir, port);
    let seen = ground(port, "auto", Some("60"));
    let report = finish_sim(sim);
    let wall = started.elapsed().as_secs_f64();
    assert_eq!(seen["upload_same"], 0, "the uploaded mission is accepted");
    let items = seen["mission"].as_array().expect("mission");
    let (reached, waypoint_seqs) = (reached(&seen), waypoint_seqs(items));
    assert_eq!(
        reached, waypoint_seqs,
        "MISSION_ITEM_REACHED for each waypoint, in order"
    );
    let modes = seen["modes"].as_array().expect("modes");
    assert!(
        modes.contains(&serde_json::json!(10)),
        "AUTO (10) seen: {modes:?}"
    );
    // The log agrees: the control task's active waypoint went through all of them in AUTO.
    let csv = flight_csv(&report, &dir);
    let mode = csv_column(&csv.join("control.1.csv"), "mode");
    let waypoint = csv_column(&csv.join("control.1.csv"), "waypoint");
    let highest = mode
        .iter()
        .zip(&waypoint)
        .filter(|(m, _)| **m == 2.0)
        .map(|(_, w)| *w)
        .fold(0.0, f64::max);
    assert_eq!(highest as usize, waypoint_seqs.len() - 1);
    // In the air (the parked test sees ON_GROUND), and as high as the estimator logged
    // (GLOBAL_POSITION_INT samples it at 5 Hz of wall time: 1.6 s of flight at 8×).
    let landed = seen["landed_states"].as_array().expect("landed");
    assert!(landed.contains(&serde_json::json!(2)), "IN_AIR: {landed:?}");
    let pd = csv_column(&csv.join("estimator.1.csv"), "pd_m");
    let logged_top = pd.iter().fold(f64::MIN, |a, d| a.max(-d));
    let seen_top = f(&seen["highest_relative_alt_mm"]) * 1e-3;
    assert!(
        (seen_top - logged_top).abs() < 5.0,
        "highest {seen_top:.1} m on MAVLink, {logged_top:.1} m in the log"
    );
    // Paced: 235 s of flight at 8× is ~29 s of wall time (slower if the machine is).
    let speed_up = f(&report["speed_up"]);
    eprintln!(
        "mavlink auto: reached {reached:?}, modes {modes:?}, flight/wall {speed_up:.2}x, test wall {wall:.1} s"
    );
    assert!(speed_up <= 8.4, "speed-up {speed_up:.1} above the pace");
    assert!(wall > 235.0 / 8.4, "{wall:.1} s of wall time");
}

#[test]
fn in_flight_a_new_mission_is_flown_then_set_current_and_clear_all_take_effect() {
    let (_others, dir, port) = setup("mavlink-inflight");
    let sim = auto_circuit_on_mavlink(&dir, port);
    let seen = ground(port, "inflight", None);
    let report = finish_sim(sim);
    assert!(
        !seen["first_reached"].is_null(),
        "in flight on the first mission: {seen}"
    );
    assert_eq!(seen["upload_new"], 0, "MAV_MISSION_ACCEPTED: {seen}");
    // Downloaded back: the mission uploaded (positions within 2e-7°, ~2 cm).
    let up = seen["uploaded"].as_array().expect("uploaded");
    let down = seen["downloaded"].as_array().expect("downloaded");
    assert_eq!(down.len(), up.len(), "{down:?}");
    for (u, d) in up.iter().zip(down) {
        assert_eq!((&u["seq"], &u["command"]), (&d["seq"], &d["command"]));
        for k in ["x", "y"] {
            assert!((f(&u[k]) - f(&d[k])).abs() <= 2.0, "{k}: {u} vs {d}");
        }
        for k in ["z", "param1", "param2", "param3"] {
            assert_eq!(f(&u[k]) as f32, f(&d[k]) as f32, "{k}: {u} vs {d}");
        }
    }
    // Flown: MISSION_ITEM_REACHED for each of its waypoints, in order.
    let want = waypoint_seqs(up);
    assert_eq!(
        reached(&seen),
        want,
        "the new mission's waypoints reached: {seen}"
    );
    // Set current: MISSION_CURRENT shows it.
    assert_eq!(seen["set_current"]["seq"].as_u64(), Some(want[0]), "{seen}");
    // Clear all: accepted, and a download has nothing.
    assert_eq!(seen["clear_all"], 0, "{seen}");
    assert_eq!(seen["after_clear"], serde_json::json!([]));
    assert_eq!(seen["set_current_without_mission"]["total"], 0);
    // The log: the control task flew the new mission's altitudes (the first mission's + 10 m,
    // which it never asked for), then no waypoint once cleared.
    let csv = flight_csv(&report, &dir);
    let alt_c = csv_column(&csv.join("control.1.csv"), "alt_c_m");
    let waypoint = csv_column(&csv.join("control.1.csv"), "waypoint");
    for u in up.iter().filter(|i| i["command"] == 16) {
        let z = f(&u["z"]) as f32;
        assert!(
            alt_c.iter().any(|a| *a as f32 == z),
            "altitude {z} m commanded in the log"
        );
    }
    assert_eq!(waypoint.last(), Some(&255.0), "no mission at the end");
}

#[test]
fn with_a_key_only_signed_sets_change_anything() {
    let (_others, dir, port) = setup("mavlink-signed");
    let dir = dir.as_path();
    let key_hex = "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef";
    let key = key_file(dir, format!("{key_hex}\n").as_bytes());
    let sim = sim_on_mavlink(
        dir,
        port,
        "1",
        &["--scenario", &parked_in(dir), "--mavlink-key", &key],
    );
    let seen = ground(port, "signed", Some(key_hex));
    let report = stop_sim(sim);
    assert_eq!(f(&seen["before"]) as f32, 1.2);
    assert_eq!(
        f(&seen["after_unsigned"]) as f32,
        1.2,
        "unsigned set ignored"
    );
    assert_eq!(f(&seen["signed_set"]) as f32, 0.65);
    assert_eq!(f(&seen["after_signed"]) as f32, 0.65, "signed set applied");
    assert_eq!(seen["heartbeat_signed"], true, "telemetry is signed");
    assert_eq!(report["mavlink"]["unsigned"], 1, "{}", report["mavlink"]);
    let csv = flight_csv(&report, dir);
    let gains = csv_column(&csv.join("control.2.csv"), "roll_kp");
    assert_eq!(gains.last(), Some(&0.65));
    assert!(
        !gains.contains(&0.6),
        "the unsigned value never reached the vehicle"
    );
}

#[test]
fn a_mavlink_shutdown_ends_a_run_with_a_stuck_task_within_a_second() {
    let (_others, dir, port) = setup("mavlink-stop");
    let endpoint = format!("udpin:127.0.0.1:{port}");
    // Real time (the stuck task must really hold the executive): imu stuck for 10 s from
    // frame 300 (3 s).
    let sim = spawn_piped(
        skyframe()
            .args([
                "sim",
                "--no-link",
                "--priority",
                "0",
                "--duration",
                "30",
                "--inject-overrun",
                "imu:10000000@300..301",
                "--mavlink",
                &endpoint,
                "--log-dir",
            ])
            .arg(&dir),
    );
    let seen = ground(port, "stop", Some("5"));
    let sent = Instant::now();
    assert_eq!(seen["stop_ack"], 0, "shutdown accepted");
    let out = sim.wait_with_output().expect("ends");
    let took = sent.elapsed();
    eprintln!(
        "mavlink stop: exit {:?} {:.0} ms after the shutdown's COMMAND_ACK",
        out.status.code(),
        took.as_secs_f64() * 1e3
    );
    assert!(took < Duration::from_secs(1), "took {took:?}");
    assert_eq!(
        out.status.code(),
        Some(4),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("closed whole"));
}

/// Forged frames a second in the flood test.
const FLOOD_PER_S: f64 = 150_000.0;

/// Issue 21's flood, on the MAVLink endpoint: 8 sources send wrong-key signed PARAM_SETs at
/// 150 000 frames/s while the key holder sets a parameter 30 times; every genuine set
/// is answered with its value, and the report's counters account for the flood.
#[test]
fn a_flood_of_forged_frames_does_not_lock_out_the_key_holder() {
    let _alone = FLOOD_ALONE
        .write()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    use mavlink::dialects::common::{MavMessage, MavParamType, PARAM_SET_DATA};
    use mavlink::{MavHeader, MavlinkReader, SigningConfig, SigningData};
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};

    let dir = scratch("mavlink-flood");
    let port = free_port();
    let key = key_file(&dir, &[0x31u8; 32]);
    let sim = sim_on_mavlink(
        &dir,
        port,
        "1",
        &["--scenario", &parked_in(&dir), "--mavlink-key", &key],
    );
    let vehicle: std::net::SocketAddr = ([127, 0, 0, 1], port).into();
    let set = |value: f32| {
        MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: value,
            target_system: 1,
            target_component: 1,
            param_id: "CTL_ROLL_KP".into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        })
    };
    let frame = |msg: &MavMessage, signing: &SigningData| {
        let mut out = Vec::new();
        let header = MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: 0,
        };
        mavlink::write_v2_msg_signed(&mut out, header, msg, Some(signing)).expect("frame");
        out
    };

    let done = Arc::new(AtomicBool::new(false));
    let flood = {
        let done = Arc::clone(&done);
        let forged = frame(
            &set(0.9),
            &SigningData::from_config(SigningConfig::new([0x32; 32], 0, true, false)),
        );
        std::thread::spawn(move || {
            let sockets: Vec<UdpSocket> = (0..8)
                .map(|_| UdpSocket::bind("127.0.0.1:0").expect("flood socket"))
                .collect();
            let started = Instant::now();
            let mut sent = 0u64;
            // 150 000 frames/s (issue 21 asks for 100 000), paced in 1 ms bursts.
            while !done.load(Ordering::Relaxed) && started.elapsed() < Duration::from_secs(20) {
                let due = started.elapsed().as_secs_f64() * FLOOD_PER_S;
                while (sent as f64) < due {
                    let socket = &sockets[sent as usize % sockets.len()];
                    if socket.send_to(&forged, vehicle).is_ok() {
                        sent += 1;
                    }
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            (sent, started.elapsed())
        })
    };

    let ground = UdpSocket::bind("127.0.0.1:0").expect("ground");
    ground
        .set_read_timeout(Some(Duration::from_millis(100)))
        .expect("timeout");
    let signing = SigningData::from_config(SigningConfig::new([0x31; 32], 0, true, false));
    // The vehicle must be up first (its socket is bound once the flight starts).
    std::thread::sleep(Duration::from_secs(2));
    let mut answered = 0;
    let mut buf = [0u8; 2048];
    for i in 0..30 {
        let value = 0.5 + 0.01 * i as f32;
        let mut got = false;
        // A ground station resends a set that gets no answer (the flood fills the socket's
        // buffer, and the kernel drops what does not fit, genuine or not). On two cores the
        // flood's sender and the endpoint share the machine and the endpoint reads about a
        // third of the flood: with 5 tries one set in 30 went unanswered once in four runs;
        // 10 tries, 1 s apart, is still a ground station's patience.
        for _attempt in 0..10 {
            let _ = ground.send_to(&frame(&set(value), &signing), vehicle);
            let deadline = Instant::now() + Duration::from_secs(1);
            while !got && Instant::now() < deadline {
                let Ok(n) = ground.recv(&mut buf) else {
                    continue;
                };
                let mut reader = MavlinkReader::new(&buf[..n]);
                while let Ok((_, msg)) = reader.read_any_message::<MavMessage>() {
                    if let MavMessage::PARAM_VALUE(p) = msg
                        && p.param_id.to_str().ok() == Some("CTL_ROLL_KP")
                        && p.param_value == value
                    {
                        got = true;
                    }
                }
            }
            if got {
                break;
            }
        }
        answered += usize::from(got);
    }
    done.store(true, Ordering::Relaxed);
    let (sent, took) = flood.join().expect("flood");
    let report = stop_sim(sim);
    let m = &report["mavlink"];
    let rate = sent as f64 / took.as_secs_f64();
    eprintln!(
        "mavlink flood: {sent} forged frames at {rate:.0}/s; genuine answered {answered}/30; {m}"
    );
    assert_eq!(answered, 30, "{m}");
    assert!(rate > 100_000.0, "only {rate:.0} frames/s");
    // Every datagram that reached the endpoint (the kernel drops the rest when the socket's
    // buffer is full) is accounted for, one frame each: refused for a reason, or accepted.
    let refused = f(&m["bad_signature"]) + f(&m["rate_limited"]);
    let reasons = [
        "rate_limited",
        "malformed",
        "unknown",
        "unsigned",
        "bad_signature",
        "replayed",
        "other_target",
        "accepted",
    ];
    let accounted: f64 = reasons.iter().map(|r| f(&m[*r])).sum();
    assert_eq!(accounted, f(&m["datagrams_in"]), "{m}");
    assert!(refused >= 10_000.0, "the flood reached the endpoint: {m}");
    assert!(refused <= sent as f64, "{refused} of {sent}");
    // The genuine sets (and any resends) are all that was accepted.
    assert!((30.0..=90.0).contains(&f(&m["accepted"])), "{m}");
}

#[test]
fn two_simulators_appear_as_two_vehicles_in_one_ground_station() {
    let (_others, dir, port) = setup("mavlink-two");
    let dir = dir.as_path();
    let scenario = parked_in(dir);
    let endpoint = format!("udpout:127.0.0.1:{port}");
    let sims: Vec<Child> = ["1", "2"]
        .iter()
        .map(|sysid| {
            // With the skyframe link on as well (the second takes a free command port):
            // MAVLink works beside it.
            start_sim(
                &dir.join(sysid),
                &[
                    "--speedup",
                    "1",
                    "--telemetry",
                    "127.0.0.1:9",
                    "--scenario",
                    &scenario,
                    "--mavlink",
                    &endpoint,
                    "--mavlink-sysid",
                    sysid,
                ],
            )
        })
        .collect();
    let seen = ground(port, "listen", None);
    for sim in sims {
        stop_sim(sim);
    }
    let by_system = &seen["heartbeats_by_system"];
    for sysid in ["1", "2"] {
        let n = f(&by_system[sysid]);
        assert!(
            (8.0..=12.0).contains(&n),
            "system {sysid}: {n} heartbeats in 10 s"
        );
    }
    assert_eq!(seen["components"], serde_json::json!([1]), "the autopilot");
}

#[test]
fn bad_mavlink_options_are_refused_in_one_line_before_the_run() {
    let (_others, dir, _) = setup("mavlink-options");
    let missing = dir.join("no-such.key");
    let readable = dir.join("readable.key");
    std::fs::write(&readable, [7u8; 32]).expect("key");
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&readable, std::fs::Permissions::from_mode(0o644)).expect("chmod");
    let log_dir = dir.join("flights");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--mavlink", "tcp:127.0.0.1:5760"], "unknown kind"),
        (vec!["--mavlink", "udpout:127.0.0.1:0"], "port other than 0"),
        (vec!["--mavlink", "udpin:nowhere"], "nowhere"),
        (
            vec!["--mavlink", "udpin:127.0.0.1:0", "--mavlink-sysid", "0"],
            "mavlink-sysid",
        ),
        (
            vec!["--mavlink", "udpin:127.0.0.1:0", "--mavlink-sysid", "256"],
            "mavlink-sysid",
        ),
        (vec!["--mavlink-sysid", "3"], "need --mavlink"),
        (
            vec!["--mavlink", "udpin:127.0.0.1:0", "--vehicle-id", "300"],
            "--mavlink-sysid N is needed",
        ),
        (
            vec![
                "--mavlink",
                "udpin:127.0.0.1:0",
                "--mavlink-key",
                missing.to_str().expect("p"),
            ],
            "no-such.key",
        ),
        (
            vec![
                "--mavlink",
                "udpin:127.0.0.1:0",
                "--mavlink-key",
                readable.to_str().expect("p"),
            ],
            "readable by group or others",
        ),
        (vec!["--speedup", "0.5"], "speedup"),
        (vec!["--speedup", "5000"], "speedup"),
        (vec!["--speedup", "lots"], "speedup"),
        (vec!["--speedup", "2", "--fast"], "cannot be used with"),
    ];
    for (args, says) in cases {
        let out = skyframe()
            .arg("sim")
            .args(&args)
            .arg("--log-dir")
            .arg(&log_dir)
            .output()
            .expect("runs");
        let text = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {text}");
        let first = text.lines().next().unwrap_or_default();
        assert!(
            first.contains(says),
            "{args:?}: the first line says why: {text}"
        );
        assert!(
            !log_dir.exists(),
            "{args:?}: refused before any flight directory"
        );
    }
}

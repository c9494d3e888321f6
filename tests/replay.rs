//! `skyframe replay` on real flight logs, as a user runs it: the binary, `--json`, exit codes.
//!
//! The figures are compared with the onboard estimate of the same log (agreement) and, for
//! yaw, with the wind triangle of the log's airspeed and GPS (which neither estimator uses).
//! Thresholds are the measured values (docs/replay.md) with a margin for platform-dependent
//! floating point, so a change to the estimator that makes real flights worse fails here.
//!
//! The Zurich flight is `shared/data/real-flights/` beside the clone (as CI has it); the
//! other logs are shipped in `tests/data/` (README there: sources and licences).

use std::path::{Path, PathBuf};
use std::process::Output;

use serde_json::Value;
use skyframe_tests::{scratch, skyframe, workspace};

fn zurich() -> PathBuf {
    let path = workspace().join("../shared/data/real-flights/px4-fixedwing-zurich-100s.ulg");
    assert!(
        path.is_file(),
        "{} is missing: the tests expect shared/ beside the clone",
        path.display()
    );
    path
}

fn shipped(name: &str) -> PathBuf {
    workspace().join("tests/data").join(name)
}

fn replay(log: &Path, extra: &[&str]) -> Output {
    skyframe()
        .arg("replay")
        .arg(log)
        .args(extra)
        .output()
        .expect("skyframe runs")
}

fn replay_json(log: &Path, extra: &[&str]) -> Value {
    let out = replay(log, &[&["--json"], extra].concat());
    assert!(
        out.status.success(),
        "replay of {} failed: {}",
        log.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

fn num(v: &Value, pointer: &str) -> f64 {
    v.pointer(pointer)
        .and_then(Value::as_f64)
        .unwrap_or_else(|| panic!("{pointer} is not a number in {v:#}"))
}

/// The estimator's own health on a real log: finite, no whole-filter reset, no GPS reset.
fn assert_healthy(v: &Value) {
    assert_eq!(
        v.pointer("/estimator/stayed_finite_without_reset"),
        Some(&Value::Bool(true))
    );
    assert_eq!(num(v, "/estimator/counts/non_finite_estimates"), 0.0);
    assert_eq!(num(v, "/estimator/counts/resets"), 0.0);
    assert_eq!(num(v, "/estimator/counts/gps_resets"), 0.0);
    assert_eq!(num(v, "/estimator/counts/imu_rejected"), 0.0);
}

#[test]
fn zurich_fixed_wing_stays_healthy_and_agrees_as_measured() {
    let v = replay_json(&zurich(), &[]);
    assert_healthy(&v);
    // The flight is launched by hand: never 10 s at rest, so the warm start at launch.
    assert_eq!(
        v.pointer("/estimator/start/how").and_then(Value::as_str),
        Some("onboard-attitude")
    );
    assert!((num(&v, "/estimator/start/at_s") - 16.0).abs() < 1.5);
    assert!(num(&v, "/estimator/running_s") > 80.0);
    // The log's GPS velocity contradicts its positions (docs/replay.md): replaced.
    assert_eq!(
        v.pointer("/log/gps_velocity_check/replaced"),
        Some(&Value::Bool(true))
    );
    assert!(num(&v, "/log/gps_velocity_check/rms_difference_m_s") > 15.0);
    // The filter takes almost every fix (measured: 414/0 position, 408/6 velocity).
    assert!(num(&v, "/estimator/counts/gps_position_accepted") >= 400.0);
    assert!(num(&v, "/estimator/counts/gps_position_rejected") <= 3.0);
    assert!(num(&v, "/estimator/counts/gps_velocity_rejected") <= 15.0);
    // Agreement with the 2013 onboard estimator (measured 5.16 / 7.82 / 25.2 deg RMS) and
    // our position against the fixes (1.62 m RMS).
    assert!(num(&v, "/agreement/all/roll_deg/rms") < 6.0);
    assert!(num(&v, "/agreement/all/pitch_deg/rms") < 9.0);
    assert!(num(&v, "/agreement/all/yaw_deg/rms") < 29.0);
    assert!(num(&v, "/agreement/all/gps_horizontal_m/rms") < 2.0);
    assert!(num(&v, "/agreement/all/roll_deg/samples") > 3500.0);
    // Yaw against the wind triangle, the arbiter: ours is the consistent heading (measured
    // residual 2.46 m/s and 13.1 deg against 4.69 m/s and 29.8 deg for the onboard one).
    let ours = num(&v, "/heading_check/ours/residual_rms_m_s");
    let onboard = num(&v, "/heading_check/onboard/residual_rms_m_s");
    assert!(
        ours < 3.0 && ours < onboard,
        "ours {ours}, onboard {onboard}"
    );
    assert!(num(&v, "/heading_check/ours/heading_vs_air_track_rms_deg") < 15.0);
    assert!((num(&v, "/heading_check/ours/airspeed_scale") - 1.0).abs() < 0.1);
    // Every phase the flight has is reported.
    for phase in ["climb", "cruise", "turn", "descent"] {
        assert!(
            v.pointer(&format!("/agreement/phases/{phase}/seconds"))
                .is_some(),
            "no {phase} phase"
        );
    }
}

#[test]
fn cubeorange_on_the_ground_agrees_in_roll_and_pitch() {
    let log = shipped("px4-cubeorange-vtol-ground-6s.ulg");
    // 6.5 s at rest: too short for the 10 s alignment, so by default the estimator never
    // starts, and says so.
    let v = replay_json(&log, &[]);
    assert_eq!(v.pointer("/estimator/start"), Some(&Value::Null));
    assert_eq!(num(&v, "/estimator/running_s"), 0.0);
    // Warm-started at the first fix, it holds the onboard roll and pitch (measured 0.24 and
    // 0.14 deg RMS) and takes every fix.
    let v = replay_json(&log, &["--start", "onboard"]);
    assert_healthy(&v);
    assert!(num(&v, "/estimator/running_s") > 5.5);
    assert!(num(&v, "/agreement/all/roll_deg/rms") < 0.5);
    assert!(num(&v, "/agreement/all/pitch_deg/rms") < 0.5);
    assert_eq!(num(&v, "/estimator/counts/gps_position_rejected"), 0.0);
    assert!(num(&v, "/agreement/all/gps_horizontal_m/rms") < 1.5);
    // A 161 ms logging dropout in the IMU: frames without IMU data, counted.
    assert!(num(&v, "/estimator/imu_frames_empty") >= 10.0);
}

/// The same hand launch with nothing borrowed from the onboard estimator (`--start align`):
/// it never rests 10 s, so the estimator starts itself in motion at the first GPS course at
/// 5 m/s (17.0 s), levelling on the specific force less the GPS acceleration. Measured:
/// 5.33 / 8.58 / 29.7 deg RMS from the onboard estimate, 1.65 m from the fixes, and a
/// heading 7.8 deg RMS from the air track (the onboard one 29.8 deg): the most consistent
/// heading of the three starts.
#[test]
fn zurich_hand_launch_starts_in_motion_without_the_onboard_attitude() {
    let v = replay_json(&zurich(), &["--start", "align"]);
    assert_healthy(&v);
    assert_eq!(
        v.pointer("/estimator/start/how").and_then(Value::as_str),
        Some("in-motion")
    );
    assert!((num(&v, "/estimator/start/at_s") - 17.0).abs() < 1.0);
    assert!(num(&v, "/estimator/running_s") > 80.0);
    assert!(num(&v, "/estimator/counts/gps_position_rejected") <= 3.0);
    assert!(num(&v, "/agreement/all/roll_deg/rms") < 6.5);
    assert!(num(&v, "/agreement/all/pitch_deg/rms") < 10.0);
    assert!(num(&v, "/agreement/all/yaw_deg/rms") < 34.0);
    assert!(num(&v, "/agreement/all/gps_horizontal_m/rms") < 2.0);
    let ours = num(&v, "/heading_check/ours/heading_vs_air_track_rms_deg");
    let onboard = num(&v, "/heading_check/onboard/heading_vs_air_track_rms_deg");
    assert!(
        ours < 10.0 && ours < onboard,
        "ours {ours}, onboard {onboard}"
    );
}

/// A real ArduPilot DataFlash log (ArduCopter 3.3 on a Pixhawk, 2015; tests/data/README.md):
/// the only real log here on which the airplane's own 10 s alignment completes. A
/// multirotor is outside the estimator's design (its heading comes from the GPS course,
/// and a copter does not fly along its nose), so these thresholds only pin down what it
/// does today (measured: roll 2.30, pitch 0.98 deg RMS, velocity 1.31 m/s RMS against the
/// onboard EKF1, 2.7 m from the fixes, no fix rejected; with the gyro noise of 5e-4 rad/√s
/// it was 6.05 / 2.81 deg, 6.2 m/s and one reset to the GPS after 50 rejected fixes,
/// docs/replay.md).
#[test]
fn ardupilot_copter_dataflash_stays_finite_and_aligns_by_itself() {
    let v = replay_json(&shipped("ardupilot-copter-2015-cut.bin"), &[]);
    assert_eq!(
        v.pointer("/log/format").and_then(Value::as_str),
        Some("ArduPilot DataFlash")
    );
    assert_eq!(
        v.pointer("/estimator/stayed_finite_without_reset"),
        Some(&Value::Bool(true))
    );
    assert_eq!(
        v.pointer("/estimator/start/how").and_then(Value::as_str),
        Some("alignment")
    );
    assert!((num(&v, "/estimator/start/at_s") - 26.7).abs() < 1.0);
    // What the reader found, against a separate DataFlash parser's count of the file (a
    // Python script): 11166 IMU records less the first (no interval yet) and one after a
    // logging dropout over 100 ms (never bridged), 1123 GPS, 2233 ATT.
    assert_eq!(num(&v, "/log/imu_records"), 11164.0);
    assert_eq!(num(&v, "/log/gps_fixes"), 1123.0);
    assert_eq!(num(&v, "/log/onboard_attitude_records"), 2233.0);
    assert_eq!(num(&v, "/estimator/counts/gps_resets"), 0.0);
    assert!(num(&v, "/estimator/counts/gps_position_rejected") <= 3.0);
    assert!(num(&v, "/agreement/all/roll_deg/rms") < 2.8);
    assert!(num(&v, "/agreement/all/pitch_deg/rms") < 1.2);
    assert!(num(&v, "/agreement/all/velocity_m_s/rms") < 1.6);
    assert!(num(&v, "/agreement/all/gps_horizontal_m/rms") < 3.3);
    assert!(num(&v, "/agreement/all/velocity_m_s/samples") > 1000.0);
}

/// The same flight written as an ArduPilot DataFlash log (IMT delta angles, GPS, ATT, ARSP)
/// replays to the same agreement as the ULog: the DataFlash reader against the ULog one.
#[test]
fn dataflash_of_the_same_flight_replays_alike() {
    let dir = scratch("replay-dataflash");
    let ulog_path = zurich();
    let bytes = std::fs::read(&ulog_path).expect("zurich");
    let log = skyframe_shell::replay::ulog::read("zurich", &bytes).expect("reads");
    let bin = dir.join("zurich.bin");
    std::fs::write(&bin, dataflash::write(&log)).expect("write");
    let a = replay_json(&ulog_path, &[]);
    let b = replay_json(&bin, &[]);
    assert_eq!(
        b.pointer("/log/format").and_then(Value::as_str),
        Some("ArduPilot DataFlash")
    );
    assert_healthy(&b);
    for p in [
        "/agreement/all/roll_deg/rms",
        "/agreement/all/pitch_deg/rms",
        "/agreement/all/yaw_deg/rms",
    ] {
        let (x, y) = (num(&a, p), num(&b, p));
        // Integer microseconds and centidegrees in the DataFlash copy.
        assert!((x - y).abs() < 0.2, "{p}: ulog {x}, dataflash {y}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn damaged_logs_are_one_line_naming_the_byte_never_a_panic() {
    let dir = scratch("replay-damaged");
    let zurich = std::fs::read(zurich()).expect("zurich");
    let cases: [(&str, Vec<u8>, &str); 3] = [
        (
            "noise.ulg",
            (0..5000u32).map(|i| (i * 7919 % 251) as u8).collect(),
            "byte 0:",
        ),
        ("empty.bin", Vec::new(), "byte 0:"),
        // A definition with a broken format string, 200 bytes in.
        (
            "broken.ulg",
            {
                let mut b = zurich.get(..4000).unwrap_or_default().to_vec();
                for x in b.iter_mut().skip(200).take(60) {
                    *x = 0xff;
                }
                b
            },
            "byte ",
        ),
    ];
    for (name, bytes, expect) in cases {
        let path = dir.join(name);
        std::fs::write(&path, bytes).expect("write");
        let out = replay(&path, &["--json"]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{name} replayed");
        assert_eq!(stderr.lines().count(), 1, "{name}: {stderr}");
        assert!(
            stderr.contains(&path.display().to_string()),
            "{name}: {stderr}"
        );
        assert!(stderr.contains(expect), "{name}: {stderr}");
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
    }
    // Cut mid-message: what was read is replayed, the cut is a warning with its offset.
    let path = dir.join("cut.ulg");
    std::fs::write(
        &path,
        zurich.get(..zurich.len() / 2 + 7).unwrap_or_default(),
    )
    .expect("write");
    let v = replay_json(&path, &[]);
    let warning = v
        .pointer("/log/warnings/0")
        .and_then(Value::as_str)
        .unwrap_or_default();
    assert!(
        warning.contains("byte ") && warning.contains("truncated"),
        "{warning}"
    );
    assert!(num(&v, "/log/duration_s") > 45.0);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn plot_writes_the_figures_and_their_numbers() {
    let dir = scratch("replay-plot");
    let out = replay(
        &shipped("px4-cubeorange-vtol-ground-6s.ulg"),
        &["--start", "onboard", "--plot", &dir.display().to_string()],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in ["attitude.png", "attitude_difference.png"] {
        let bytes = std::fs::read(dir.join(f)).expect("figure");
        assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000, "{f}");
    }
    let csv = std::fs::read_to_string(dir.join("attitude.csv")).expect("csv");
    assert!(csv.lines().count() > 1000);
    let estimates = std::fs::read_to_string(dir.join("estimates.csv")).expect("csv");
    assert!(estimates.lines().count() > 600);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A minimal DataFlash writer for the test: FMT, then IMT, GPS, ATT and ARSP records with
/// the columns ArduPilot logs them with.
mod dataflash {
    use skyframe_shell::replay::FlightLog;

    fn fmt(out: &mut Vec<u8>, ty: u8, name: &str, format: &str, columns: &str, len: u8) {
        out.extend_from_slice(&[0xA3, 0x95, 0x80, ty, len]);
        let mut pad = |s: &str, n: usize| {
            let mut b = s.as_bytes().to_vec();
            b.resize(n, 0);
            out.extend_from_slice(&b);
        };
        pad(name, 4);
        pad(format, 16);
        pad(columns, 64);
    }

    fn head(out: &mut Vec<u8>, ty: u8, t_us: u64) {
        out.extend_from_slice(&[0xA3, 0x95, ty]);
        out.extend_from_slice(&t_us.to_le_bytes());
    }

    pub fn write(log: &FlightLog) -> Vec<u8> {
        let mut out = Vec::new();
        fmt(
            &mut out,
            0x80,
            "FMT",
            "BBnNZ",
            "Type,Length,Name,Format,Columns",
            89,
        );
        fmt(
            &mut out,
            1,
            "IMT",
            "QBffffffff",
            "TimeUS,I,DelaT,DelvT,DelAX,DelAY,DelAZ,DelVX,DelVY,DelVZ",
            3 + 8 + 1 + 32,
        );
        fmt(
            &mut out,
            2,
            "GPS",
            "QBBLLffff",
            "TimeUS,I,Status,Lat,Lng,Alt,Spd,GCrs,VZ",
            3 + 8 + 2 + 8 + 16,
        );
        fmt(
            &mut out,
            3,
            "ATT",
            "Qcccccc",
            "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw",
            3 + 8 + 12,
        );
        fmt(
            &mut out,
            4,
            "ARSP",
            "QBf",
            "TimeUS,I,Airspeed",
            3 + 8 + 1 + 4,
        );
        let mut records: Vec<(u64, Vec<u8>)> = Vec::new();
        for r in &log.imu {
            let mut m = Vec::new();
            head(&mut m, 1, r.t_us);
            m.push(0);
            for v in [r.dt_s, r.dt_s]
                .iter()
                .chain(&r.delta_angle_rad)
                .chain(&r.delta_velocity_m_s)
            {
                m.extend_from_slice(&(*v as f32).to_le_bytes());
            }
            records.push((r.t_us, m));
        }
        for g in &log.gps {
            let mut m = Vec::new();
            head(&mut m, 2, g.t_us);
            m.extend_from_slice(&[0, if g.fix_3d { 3 } else { 1 }]);
            m.extend_from_slice(&((g.latitude_deg * 1e7).round() as i32).to_le_bytes());
            m.extend_from_slice(&((g.longitude_deg * 1e7).round() as i32).to_le_bytes());
            let [vn, ve, vd] = g.velocity_ned_m_s.map(|v| v.unwrap_or(0.0));
            let course = ve.atan2(vn).to_degrees().rem_euclid(360.0);
            for v in [g.altitude_m, vn.hypot(ve), course, vd] {
                m.extend_from_slice(&(v as f32).to_le_bytes());
            }
            records.push((g.t_us, m));
        }
        for a in &log.onboard_attitude {
            let [w, x, y, z] = a.quaternion;
            let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
            let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
            let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
            let mut m = Vec::new();
            head(&mut m, 3, a.t_us);
            for v in [0.0, roll, 0.0, pitch, 0.0, yaw] {
                let c = (v.to_degrees() * 100.0).round() as i16;
                m.extend_from_slice(&c.to_le_bytes());
            }
            records.push((a.t_us, m));
        }
        for &(t_us, v) in &log.airspeed {
            let mut m = Vec::new();
            head(&mut m, 4, t_us);
            m.push(0);
            m.extend_from_slice(&(v as f32).to_le_bytes());
            records.push((t_us, m));
        }
        records.sort_by_key(|r| r.0);
        for (_, m) in records {
            out.extend_from_slice(&m);
        }
        out
    }
}

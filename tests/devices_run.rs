//! `skyframe run` against three pseudo-terminal devices fed by this test at their real
//! rates: the IMU (with garbage between frames, unplugged and plugged back through a
//! re-pointed symlink), the GPS (NMEA with garbage, then silent), the servo board (pilot
//! frames in, computer commands out). Asserts the decoded values, counters and states in the
//! run's report and logs.

use serde_json::Value;
use serialport::TTYPort;
use skyframe_core::devices::gps::{GpsFix, SentenceKind, Talker, encode_sentence};
use skyframe_core::devices::imu::{
    IMU_FRAME_LEN, ImuMeasurement, ImuStatus, SlowSlot, encode_imu_frame,
};
use skyframe_core::devices::servo::{
    BoardStatus, PILOT_FRAME_LEN, PilotReport, ServoCommandDecoder, encode_pilot_frame,
};
use skyframe_tests::pty::{self, point};
use skyframe_tests::{on_the_clock, scratch, skyframe, to_csv};
use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// A pty whose slave `skyframe` opens by path; the test holds the master (the device).
fn device() -> (TTYPort, PathBuf) {
    pty::device(Duration::from_millis(5))
}

fn imu_frame(counter: u8) -> [u8; IMU_FRAME_LEN] {
    let m = ImuMeasurement {
        rate_radps: [0.25, -0.125, 0.064],
        specific_force_mps2: [0.5, 0.0, -9.80665],
        status: ImuStatus(0),
    };
    let mut out = [0u8; IMU_FRAME_LEN];
    encode_imu_frame(
        counter,
        &m,
        SlowSlot {
            index: counter % 100,
            byte: 0,
        },
        &mut out,
    );
    out
}

fn gps_epoch(n: u32) -> Vec<u8> {
    let fix = GpsFix {
        utc_time_ms: Some(43_200_000 + 100 * n),
        valid: true,
        satellites: Some(8),
        latitude_deg: Some(48.1173),
        longitude_deg: Some(11.5167),
        altitude_msl_m: Some(545.4),
        hdop: Some(0.9),
        ground_speed_mps: Some(12.0),
        course_rad: Some(0.5),
        ..GpsFix::default()
    };
    let mut out = Vec::new();
    let mut buf = [0u8; 128];
    for kind in [SentenceKind::Gga, SentenceKind::Rmc] {
        let len = encode_sentence(kind, Talker::Gp, &fix, &mut buf).expect("fits");
        out.extend_from_slice(&buf[..len]);
    }
    out
}

fn pilot_frame(counter: u8) -> [u8; PILOT_FRAME_LEN] {
    let report = PilotReport {
        pilot_us: [1600, 1450, 1300, 1500, 1500, 1500, 1500, 1500],
        switch_us: 1000,
        logic_battery_v: 12.1,
        servo_battery_v: 5.2,
        status: BoardStatus(0),
    };
    let mut out = [0u8; PILOT_FRAME_LEN];
    encode_pilot_frame(counter, &report, &mut out);
    out
}

/// Writes `frame(n)` every `period` until `until` is set; returns how many it wrote.
fn feed(
    mut port: TTYPort,
    period: Duration,
    stop_after: Duration,
    until: &AtomicBool,
    mut frame: impl FnMut(u32) -> Vec<u8>,
) -> (TTYPort, u32) {
    let start = Instant::now();
    let mut n = 0;
    while !until.load(Ordering::Relaxed) && start.elapsed() < stop_after {
        let _ = port.write_all(&frame(n));
        n += 1;
        std::thread::sleep(period);
    }
    (port, n)
}

#[test]
fn run_flies_three_pty_devices_through_unplug_and_silence() {
    let dir = scratch("devices-run");
    let imu_link = dir.join("ttyUSB-imu");
    let (imu1, imu1_path) = device();
    point(&imu_link, &imu1_path);
    let (gps, gps_path) = device();
    let (mut servo, servo_path) = device();
    let vehicle = dir.join("vehicle.toml");
    std::fs::write(
        &vehicle,
        format!(
            "[devices.imu]\nport = \"{}\"\nbaud = 115200\nstale_ms = 50\n\
             [devices.gps]\nport = \"{}\"\nbaud = 115200\nstale_ms = 400\n\
             [devices.servo]\nport = \"{}\"\nbaud = 115200\nstale_ms = 100\n\
             [log]\ndir = \"{}\"\n",
            imu_link.display(),
            gps_path.display(),
            servo_path.display(),
            dir.join("flights").display()
        ),
    )
    .expect("vehicle file");

    let child = on_the_clock("run", "3.5")
        .arg("--vehicle")
        .arg(&vehicle)
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("skyframe runs");

    let done = Arc::new(AtomicBool::new(false));
    let garbage = b"\x00\xff\xa5\x49garbage";
    // IMU: 1.0 s, unplugged 0.4 s, then 1.5 s from a new pty behind the same link.
    let imu_thread = {
        let done = Arc::clone(&done);
        let link = imu_link.clone();
        std::thread::spawn(move || {
            let mut counter = 0u8;
            let mut frame = |n: u32| {
                counter = counter.wrapping_add(1);
                let mut f = imu_frame(counter).to_vec();
                if n % 10 == 9 {
                    f.extend_from_slice(garbage);
                }
                f
            };
            let (first, a) = feed(
                imu1,
                Duration::from_millis(10),
                Duration::from_millis(1000),
                &done,
                &mut frame,
            );
            drop(first);
            std::thread::sleep(Duration::from_millis(400));
            let (imu2, imu2_path) = device();
            point(&link, &imu2_path);
            let (second, b) = feed(
                imu2,
                Duration::from_millis(10),
                Duration::from_millis(1500),
                &done,
                &mut frame,
            );
            // Stays plugged in (silent) until the run is over.
            while !done.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(10));
            }
            drop(second);
            (a, b)
        })
    };
    // GPS: 10 Hz for 1.5 s, garbage lines between epochs, then silent.
    let gps_thread = {
        let done = Arc::clone(&done);
        std::thread::spawn(move || {
            let (port, n) = feed(
                gps,
                Duration::from_millis(100),
                Duration::from_millis(1500),
                &done,
                |n| {
                    let mut bytes = gps_epoch(n);
                    bytes.extend_from_slice(b"$GPXXX,noise*ZZ\r\n\x01\x02");
                    bytes
                },
            );
            (port, n)
        })
    };
    // Servo board: 50 Hz pilot frames; collect the computer's command frames.
    let servo_thread = {
        let done = Arc::clone(&done);
        std::thread::spawn(move || {
            let mut received = Vec::new();
            let mut counter = 0u8;
            let start = Instant::now();
            while !done.load(Ordering::Relaxed) && start.elapsed() < Duration::from_secs(6) {
                counter = counter.wrapping_add(1);
                let _ = servo.write_all(&pilot_frame(counter));
                let mut buf = [0u8; 256];
                if let Ok(n) = servo.read(&mut buf) {
                    received.extend_from_slice(&buf[..n]);
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            received
        })
    };

    let out = child.wait_with_output().expect("exits");
    done.store(true, Ordering::Relaxed);
    let (imu_before, imu_after) = imu_thread.join().expect("imu feeder");
    let (_gps, gps_epochs) = gps_thread.join().expect("gps feeder");
    let commands = servo_thread.join().expect("servo feeder");
    assert!(out.status.success(), "skyframe run failed");
    let report: Value = serde_json::from_slice(&out.stdout).expect("JSON report");
    let device = |name: &str| -> &Value {
        report["devices"]
            .as_array()
            .and_then(|d| d.iter().find(|d| d["name"] == name))
            .expect("device in report")
    };

    let imu = device("imu");
    assert_eq!(imu["opens"], 2, "reopened after the unplug: {imu}");
    assert_eq!(imu["losses"], 1, "{imu}");
    let imu_frames = imu["frames"].as_u64().unwrap_or(0);
    let fed = u64::from(imu_before + imu_after);
    // Frames written while the port was being reopened are lost with the old pty.
    assert!(
        imu_frames + 40 >= fed && imu_frames <= fed,
        "{imu_frames} decoded of {fed} fed"
    );
    assert!(
        imu["bytes_discarded"].as_u64().unwrap_or(0) >= 10 * 5,
        "garbage counted: {imu}"
    );
    // Stale while unplugged, and again after the feed stopped with the port still open.
    assert_eq!(imu["stale_events"], 2, "{imu}");

    let gps = device("gps");
    // `frames` counts sentences: GGA and RMC per epoch. Bytes written before `skyframe`
    // first opened the port may be flushed with the pty's queue: allow the first epochs.
    let sentences = gps["frames"].as_u64().unwrap_or(0);
    let sent = 2 * u64::from(gps_epochs);
    assert!(
        sentences + 6 >= sent && sentences <= sent,
        "{sentences} of {sent}: {gps}"
    );
    assert!(
        gps["framing_errors"].as_u64().unwrap_or(0) + gps["bad_checksum"].as_u64().unwrap_or(0) > 0,
        "the noise lines are counted: {gps}"
    );
    assert_eq!(gps["stale_events"], 1, "silent after 1.5 s: {gps}");

    let task = |name: &str| -> &Value {
        report["tasks"]
            .as_array()
            .and_then(|t| t.iter().find(|t| t["name"] == name))
            .expect("task in report")
    };
    assert_eq!(
        task("gps")["degraded"],
        "device stale",
        "the silent GPS shows in health"
    );
    assert!(
        task("servo")["degraded"].is_null(),
        "the servo board kept talking"
    );

    let servo_report = device("servo");
    assert!(
        servo_report["frames"].as_u64().unwrap_or(0) >= 100,
        "{servo_report}"
    );
    let mut decoder = ServoCommandDecoder::new(1_000_000_000);
    let mut sent = Vec::new();
    decoder.push(&commands, 0, |f| sent.push(f.command));
    assert!(
        sent.len() >= 100,
        "a command frame every 20 ms: {}",
        sent.len()
    );
    assert!(
        sent.iter().all(|c| !c.autopilot_ready),
        "no controller yet: the pilot keeps control"
    );

    // The logs: the IMU's fast frames and the servo's pilot report, as a researcher reads them.
    let flight = PathBuf::from(report["flight_dir"].as_str().expect("flight dir"));
    let csv = to_csv(
        &[
            flight.join("imu.bin"),
            flight.join("servo.bin"),
            flight.join("gps.bin"),
        ],
        &dir.join("csv"),
    );
    let imu_csv = std::fs::read_to_string(csv.join("imu.1.csv")).expect("imu csv");
    let rows: Vec<&str> = imu_csv.lines().filter(|l| !l.starts_with('%')).collect();
    assert_eq!(rows.len() as u64, imu_frames);
    assert!(
        rows[5].ends_with(",0.2500,-0.1250,0.0640,0.5000,0.0000,-9.8050,0"),
        "{}",
        rows[5]
    );
    let servo_csv = std::fs::read_to_string(csv.join("servo.1.csv")).expect("servo csv");
    let pilot_row = servo_csv
        .lines()
        .find(|l| !l.starts_with('%'))
        .expect("pilot row");
    assert!(
        pilot_row.contains(
            ",1600,1450,1300,1500,1500,1500,1500,1500,0,0.200,-0.100,0.300,0.000,12.100,5.200"
        ),
        "{pilot_row}"
    );
    let gps_csv = std::fs::read_to_string(csv.join("gps.1.csv")).expect("gps csv");
    assert!(
        gps_csv
            .lines()
            .any(|l| l.contains(",1,1,8,48.11730000,11.51670000,545.400,")),
        "{gps_csv}"
    );
    let status_csv = std::fs::read_to_string(csv.join("gps.2.csv")).expect("gps status csv");
    assert!(
        status_csv.lines().last().is_some_and(|l| l.ends_with(",1")),
        "gps stale at the end: {status_csv}"
    );
}

#[test]
fn run_refuses_a_port_that_cannot_be_opened_in_one_line() {
    let dir = scratch("devices-bad-port");
    let vehicle = dir.join("vehicle.toml");
    std::fs::write(
        &vehicle,
        "[devices.imu]\nport = \"/dev/ttyNOPE0\"\nbaud = 115200\nstale_ms = 50\n\
         [devices.gps]\nport = \"/dev/ttyNOPE1\"\nbaud = 115200\nstale_ms = 400\n\
         [devices.servo]\nport = \"/dev/ttyNOPE2\"\nbaud = 115200\nstale_ms = 100\n",
    )
    .expect("vehicle file");
    let out = skyframe()
        .args(["run", "--vehicle"])
        .arg(&vehicle)
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("devices.imu.port = /dev/ttyNOPE0: cannot open"),
        "{err}"
    );
    let out = skyframe()
        .args(["run", "--vehicle", "/nonexistent/vehicle.toml"])
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    std::fs::write(&vehicle, "[devices.imu]\nport = 3\n").expect("write");
    let out = skyframe()
        .args(["run", "--vehicle"])
        .arg(&vehicle)
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2));
    assert!(err.contains("vehicle.toml: line 2"), "{err}");
}

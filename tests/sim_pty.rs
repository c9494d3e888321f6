//! The simulated airplane on pseudo-terminals: `skyframe-sim --pty` serves the devices and
//! writes a vehicle file; an unmodified `skyframe run` flies it for 10 s as if it were
//! hardware.

use serde_json::Value;
use skyframe_tests::{binary, finish_ok, on_the_clock, run_ok, scratch, spawn_piped};
use std::process::Command;
use std::time::{Duration, Instant};

#[test]
fn skyframe_run_flies_the_simulator_over_ptys_for_ten_seconds() {
    let dir = scratch("sim-pty");
    let vehicle = dir.join("vehicle.toml");
    // `skyframe run`'s command first: finding its binary may build it, which must not eat
    // into the simulator's 14 s.
    let mut run = on_the_clock("run", "10");
    run.arg("--vehicle")
        .arg(&vehicle)
        .arg("--log-dir")
        .arg(dir.join("flights"));
    let sim = spawn_piped(
        Command::new(binary("skyframe-sim", "skyframe-sim"))
            .args(["--pty", "--duration", "14", "--write-vehicle"])
            .arg(&vehicle),
    );
    let start = Instant::now();
    while !vehicle.exists() {
        assert!(start.elapsed() < Duration::from_secs(10), "no vehicle file");
        std::thread::sleep(Duration::from_millis(20));
    }
    let run = run_ok(run);
    let sim = finish_ok(sim);
    let sim_says = String::from_utf8_lossy(&sim.stdout);

    let report: Value = serde_json::from_slice(&run.stdout).expect("JSON report");
    let device = |name: &str| -> &Value {
        report["devices"]
            .as_array()
            .and_then(|d| d.iter().find(|d| d["name"] == name))
            .expect("device")
    };
    for name in ["imu", "gps", "servo"] {
        let d = device(name);
        let errors: u64 = [
            "bad_checksum",
            "framing_errors",
            "overflows",
            "invalid_payload",
        ]
        .iter()
        .map(|k| d[k].as_u64().unwrap_or(0))
        .sum();
        assert_eq!(errors, 0, "{d}");
        assert_eq!(d["losses"], 0, "{d}");
    }
    let frames = |name: &str| device(name)["frames"].as_u64().unwrap_or(0);
    assert!(
        (950..=1100).contains(&frames("imu")),
        "100 Hz for 10 s: {}",
        frames("imu")
    );
    assert!(
        (480..=560).contains(&frames("servo")),
        "50 Hz for 10 s: {}",
        frames("servo")
    );
    assert!(
        frames("gps") >= 6 * 60,
        "GPS epochs at ~140 ms: {} sentences",
        frames("gps")
    );
    // The computer's commands reached the simulated board.
    let received: u64 = sim_says
        .split("board reports sent; ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(received >= 450, "command frames at the board: {sim_says}");
}

#[test]
fn skyframe_sim_says_why_it_will_not_start() {
    let out = Command::new(binary("skyframe-sim", "skyframe-sim"))
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("pass --pty"));
    let dir = scratch("sim-bad-scenario");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "duration_s = \"long\"\n").expect("write");
    let out = Command::new(binary("skyframe-sim", "skyframe-sim"))
        .arg("--pty")
        .arg("--scenario")
        .arg(&bad)
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("bad.toml"), "{err}");
}

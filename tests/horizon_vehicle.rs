//! Horizon attitude from the ground to the vehicle's estimator: `skyframe-horizon detect
//! --send` sends each frame's roll and pitch as a signed command; the flying vehicle accepts
//! them and its estimator takes them up (fused, or gated when they disagree with the inertial
//! solution — these frames are synthetic and not of this flight).

use serde_json::Value;
use skyframe_tests::{binary, finish_ok, on_the_clock, run_ok, scratch, spawn_piped, to_csv};
use std::net::UdpSocket;
use std::os::unix::fs::PermissionsExt;
use std::process::Command;

fn free_port() -> String {
    let probe = UdpSocket::bind("127.0.0.1:0").expect("probe");
    probe.local_addr().expect("addr").to_string()
}

#[test]
fn horizon_results_reach_the_estimator_with_their_capture_time() {
    let dir = scratch("horizon-vehicle");
    let frames = dir.join("frames");
    run_ok(
        Command::new(binary("skyframe-horizon", "skyframe-horizon"))
            .args([
                "synth", "--frames", "20", "--width", "320", "--height", "240", "--seed", "3",
                "--out",
            ])
            .arg(&frames),
    );
    let key = dir.join("link.key");
    std::fs::write(&key, format!("{}\n", "3c".repeat(32))).expect("key");
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).expect("chmod");
    let (commands, telemetry) = (free_port(), free_port());

    // Parked: the filter aligns in 10 s at rest, then takes horizon updates.
    let scenario = skyframe_tests::workspace().join("tests/scenarios/parked.toml");
    let vehicle = spawn_piped(
        on_the_clock("sim", "16")
            .arg("--scenario")
            .arg(&scenario)
            .args(["--commands", &commands, "--telemetry", &telemetry, "--key"])
            .arg(&key)
            .arg("--log-dir")
            .arg(dir.join("flights")),
    );
    std::thread::sleep(std::time::Duration::from_secs(12));
    let detect = run_ok(
        Command::new(binary("skyframe-horizon", "skyframe-horizon"))
            .arg("detect")
            .arg(&frames)
            .arg("--camera")
            .arg(frames.join("camera.toml"))
            .args(["--send", &commands, "--listen", &telemetry, "--key"])
            .arg(&key),
    );
    let detected = String::from_utf8_lossy(&detect.stdout)
        .lines()
        .filter(|l| !l.starts_with("frame") && l.split(',').nth(1).is_some_and(|r| !r.is_empty()))
        .count();
    assert!(detected >= 15, "{detected} horizons found");

    let out = finish_ok(vehicle);
    let report: Value = serde_json::from_slice(&out.stdout).expect("report");
    let accepted = report["link"]["commands_accepted"].as_u64().unwrap_or(0);
    assert!(
        accepted as usize >= detected,
        "{accepted} commands accepted for {detected} horizons"
    );

    // The estimator's health records count each horizon it took up.
    let flight = report["flight_dir"].as_str().expect("dir");
    let csv = to_csv(&[flight], &dir.join("csv"));
    let health = std::fs::read_to_string(csv.join("estimator.2.csv")).expect("estimator health");
    let columns: Vec<&str> = health
        .lines()
        .find_map(|l| l.strip_prefix("% time,"))
        .expect("columns")
        .split(',')
        .collect();
    let last: Vec<&str> = health
        .lines()
        .last()
        .expect("rows")
        .split(',')
        .skip(1)
        .collect();
    let count = |name: &str| -> u64 {
        columns
            .iter()
            .position(|c| *c == name)
            .and_then(|i| last.get(i))
            .and_then(|v| v.parse().ok())
            .unwrap_or(0)
    };
    // The horizon input is a latest-value slot (the seed's "always the newest"): this test
    // sends its frames in a burst, faster than the estimator's 10 ms step, so several collapse
    // into the newest; at a camera's frame rate (30 ms and more apart) each one is taken.
    let taken = count("horizon_ok") + count("horizon_rejected") + count("horizon_unusable");
    assert!(
        (5..=detected as u64).contains(&taken),
        "estimator took up {taken} of {detected} horizons"
    );
}

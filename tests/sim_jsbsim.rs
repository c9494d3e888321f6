//! `skyframe sim` on JSBSim (issue 20): the autopilot's AUTO circuit on JSBSim's Cessna 172
//! scored against JSBSim's truth, the command line's choice of plant, and the ways the JSBSim
//! child can fail. Needs python3 with the jsbsim package (`.ci/run` installs it).

use serde_json::Value;
use skyframe_tests::{scratch, shipped, skyframe};
use std::path::Path;

fn sim(dir: &Path, extra: &[&str]) -> std::process::Output {
    skyframe()
        .args(["sim", "--fast", "--json", "--no-link", "--log-dir"])
        .arg(dir)
        .args(extra)
        .output()
        .expect("runs")
}

#[test]
fn the_autopilot_flies_the_auto_circuit_on_jsbsims_c172x() {
    let dir = scratch("jsbsim-c172x-circuit");
    let (scenario, mission) = (
        shipped("c172x-auto-circuit"),
        shipped("c172x-circuit-mission"),
    );
    let out = sim(
        &dir,
        &[
            "--scenario",
            &scenario,
            "--mission",
            &mission,
            "--score",
            "--no-reference-filters",
            // Not the scenario's seed 5, on which the 172's roll gain was chosen.
            "--seed",
            "8",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).expect("JSON report");
    let score = &report["score"];
    let figure = |group: &str, name: &str| skyframe_tests::score_figure(score, group, name);
    // Issue 20's targets, against JSBSim's truth (truth.bin is written from the same Truth
    // whichever plant flies).
    assert!(figure("attitude", "roll_rms_deg") <= 0.5, "{score}");
    assert!(figure("attitude", "pitch_rms_deg") <= 0.5, "{score}");
    assert!(figure("control", "auto_s") > 200.0, "{score}");
    assert!(figure("control", "altitude_hold_rms_m") <= 5.0, "{score}");
    assert!(figure("control", "altitude_hold_s") > 120.0, "{score}");
    assert!(figure("control", "heading_hold_rms_deg") <= 5.0, "{score}");
    assert!(figure("control", "heading_hold_s") > 60.0, "{score}");
}

#[test]
fn the_plant_is_chosen_on_the_command_line_with_one_line_errors() {
    let dir = scratch("jsbsim-cli");
    for (args, expected) in [
        (
            &["--plant", "jsbsim", "--aircraft", "no-such-plane"][..],
            "no aircraft \"no-such-plane\"",
        ),
        (&["--plant", "xplane"][..], "unknown plant \"xplane\""),
        (
            &["--plant", "builtin", "--aircraft", "c172x"][..],
            "flies only \"aerosonde\"",
        ),
    ] {
        let out = sim(&dir, &[&["--duration", "1"], args].concat());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

#[test]
fn a_jsbsim_flight_is_deterministic_and_on_the_truth_log() {
    let run = |name: &str| {
        let dir = scratch(name);
        let out = sim(
            &dir,
            &[
                "--plant",
                "jsbsim",
                "--aircraft",
                "c172x",
                "--duration",
                "20",
                "--seed",
                "3",
            ],
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let report: Value = serde_json::from_slice(&out.stdout).expect("JSON");
        let flight = std::path::PathBuf::from(report["flight_dir"].as_str().expect("dir"));
        (
            std::fs::read(flight.join("truth.bin")).expect("truth"),
            std::fs::read(flight.join("imu.bin")).expect("imu"),
        )
    };
    let a = run("jsbsim-det-a");
    let b = run("jsbsim-det-b");
    assert!(a.0.len() > 1000 && a.1.len() > 1000);
    assert!(a == b, "same seed, same bytes on JSBSim too");
}

#[test]
fn jsbsim_dying_mid_flight_stops_the_flight_with_its_logs_closed() {
    let dir = scratch("jsbsim-dies");
    // A python3 that runs the real driver and kills it two seconds in.
    let python = dir.join("python-dies");
    std::fs::write(
        &python,
        "#!/bin/sh\nexec 3<&0\npython3 \"$@\" <&3 &\npid=$!\nsleep 2\nkill -9 $pid\nwait $pid\n",
    )
    .expect("write");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&python, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    }
    let started = std::time::Instant::now();
    let out = skyframe()
        .env("SKYFRAME_PYTHON", &python)
        // The killed driver cannot remove its working directory: keep it in the scratch dir.
        .env("TMPDIR", &dir)
        .args([
            "sim",
            "--fast",
            "--no-link",
            "--plant",
            "jsbsim",
            "--log-dir",
        ])
        .arg(&dir)
        .output()
        .expect("runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("the simulated airplane stopped: jsbsim:"),
        "{stderr}"
    );
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(started.elapsed().as_secs() < 60, "no hang");
    // Stopped as a signal would stop it: every log closed with its final End Data.
    let flight = std::fs::read_dir(&dir)
        .expect("scratch dir")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.join("truth.bin").is_file())
        .expect("a flight directory");
    let logs: Vec<_> = std::fs::read_dir(&flight)
        .expect("flight dir")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "bin"))
        .collect();
    assert!(logs.len() >= 8, "{logs:?}");
    let text = skyframe_tests::log_info(&logs);
    assert_eq!(
        text.matches("closed cleanly: yes").count(),
        logs.len(),
        "{text}"
    );
}

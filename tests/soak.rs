//! `skyframe soak` on a quarter hour of virtual flight (CI's share of the 10 h soak, which
//! is run by hand: README): the faults scenario loops 5 times, the process's memory and open
//! files stay flat, and the flight's counters agree with each other and with the faults flown.

use skyframe_tests::{scratch, skyframe};

#[test]
fn a_quarter_hour_of_looped_faults_leaks_nothing_and_every_counter_agrees() {
    let dir = scratch("soak");
    let out = skyframe()
        .args(["soak", "--hours", "0.25", "--json", "--no-link"])
        .arg("--log-dir")
        .arg(&dir)
        .output()
        .expect("skyframe soak");
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert!((report["virtual_hours"].as_f64().expect("hours") - 0.25).abs() < 1e-3);
    assert_eq!(report["fault_loops"], 5, "{report}");
    let checks = report["checks"].as_array().expect("checks");
    let named = |name: &str| {
        checks
            .iter()
            .find(|c| c["name"] == name)
            .unwrap_or_else(|| panic!("no check {name}: {report}"))
    };
    for name in [
        "resident memory flat",
        "open files flat",
        "every minor frame ran",
        "imu went stale once per silence",
        "gps went stale once per silence",
    ] {
        assert_eq!(named(name)["ok"], true, "{}", named(name));
    }
    // 5 loops of one IMU silence and one GPS silence each.
    assert!(
        named("imu went stale once per silence")["detail"]
            .as_str()
            .is_some_and(|d| d.starts_with("5 stale events")),
        "{report}"
    );
    assert!(checks.iter().all(|c| c["ok"] == true), "{report}");
    assert!(checks.len() >= 20, "{report}");
    // The logs were removed once checked.
    assert_eq!(report["logs_kept"], false);
    assert!(std::fs::read_dir(&dir).expect("dir").next().is_none());
}

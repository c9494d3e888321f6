//! The frame table is built at compile time: an infeasible `schedule.toml` must fail
//! `cargo build` with a message naming the frame and its tasks.

use skyframe_tests::{cargo_command, workspace};
use std::process::Output;

/// Builds the core against `schedule` in a target dir of its own (the outer build's lock
/// stays untouched; later runs reuse the compiled dependencies).
fn build_core_with(schedule: &str) -> Output {
    let root = workspace();
    cargo_command()
        .args(["build", "--offline", "-p", "skyframe-core", "--target-dir"])
        .arg(root.join("target/schedule-check"))
        .env(
            "SKYFRAME_SCHEDULE",
            root.join("tests/schedules").join(schedule),
        )
        .current_dir(&root)
        .output()
        .expect("cargo runs")
}

#[test]
fn over_full_frame_fails_the_build_naming_the_frame_and_tasks() {
    let out = build_core_with("overfull.toml");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "an infeasible schedule built:\n{stderr}"
    );
    assert!(
        stderr.contains(
            "infeasible schedule: minor frame 3 is over-full: budgets 9500 us > frame less \
             margin 9 ms (tasks: imu, estimator, gps)"
        ),
        "{stderr}"
    );
    assert!(
        stderr.contains("overfull.toml"),
        "the message names the file: {stderr}"
    );
}

#[test]
fn dependency_cycle_fails_the_build() {
    let out = build_core_with("cycle.toml");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("dependency cycle among tasks: estimator, control"),
        "{stderr}"
    );
}

#[test]
fn a_feasible_alternative_schedule_builds() {
    let out = build_core_with("imu-5ms.toml");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("3 tasks, minor frame 5000 us, 20 minor frames"),
        "{stderr}"
    );
}

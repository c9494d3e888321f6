//! What a careless user types never takes skyframe down (issue 21): every file it reads is
//! bounded, every number is range-checked before the run, unknown names are errors, and a
//! stop request ends a run within a second even while a task is stuck in its step. Each
//! test runs the real binary and checks the exit code and the one line it says.

use skyframe_tests::{scratch, skyframe, spawn_piped};
use std::process::{Output, Stdio};
use std::time::{Duration, Instant};

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Exit 2 and exactly one line on stderr that contains `says`.
fn refused_in_one_line(args: &[&str], says: &str) {
    let started = Instant::now();
    let out = skyframe().args(args).output().expect("runs");
    let text = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {text}");
    assert!(text.contains(says), "{args:?}: {text}");
    // clap's own errors add a "For more information" hint after a blank line; ours are one.
    let first = text.lines().next().unwrap_or_default();
    assert!(
        first.contains(says),
        "{args:?}: the first line says why: {text}"
    );
    // Refused before the run: no file read to its end, no timer measured.
    assert!(started.elapsed() < Duration::from_secs(5), "{args:?}");
}

#[test]
fn endless_files_are_refused_at_their_size_limit() {
    refused_in_one_line(
        &["check-schedule", "/dev/zero"],
        "schedule /dev/zero: larger than 1 MiB",
    );
    refused_in_one_line(
        &["sim", "--fast", "--scenario", "/dev/zero"],
        "scenario /dev/zero: larger than 1 MiB",
    );
    refused_in_one_line(
        &["sim", "--fast", "--mission", "/dev/zero"],
        "mission /dev/zero: larger than 1 MiB",
    );
    refused_in_one_line(
        &["run", "--vehicle", "/dev/zero"],
        "vehicle /dev/zero: larger than 1 MiB",
    );
    refused_in_one_line(&["sim", "--fast", "--key", "/dev/zero"], "key /dev/zero");
}

#[test]
fn numbers_out_of_their_documented_range_are_refused_before_the_run() {
    refused_in_one_line(
        &["sim", "--timer-check-ms", "99999999999"],
        "99999999999 is not in 0..=10000",
    );
    refused_in_one_line(
        &[
            "sim",
            "--duration",
            "1",
            "--inject-overrun",
            "imu:99999999999@0..10",
        ],
        "EXTRA_US 99999999999 is out of range 1..=10000000",
    );
    refused_in_one_line(
        &["sim", "--inject-overrun", "imu:1000@0..99999999999"],
        "is past the last one",
    );
    refused_in_one_line(&["sim", "--duration", "1e12"], "out of range");
    refused_in_one_line(&["sim", "--duration", "nan"], "out of range");
    refused_in_one_line(&["bench", "--seconds", "1e9"], "out of range");
    refused_in_one_line(&["bench", "parsers", "--megabytes", "1e9"], "out of range");
    refused_in_one_line(
        &["sim", "--clock-period-us", "99999999999"],
        "not in 0..=1000000",
    );
    refused_in_one_line(&["sim", "--cpu", "70000"], "not in 0..=1023");
}

#[test]
fn an_overflowing_schedule_number_is_named_not_wrapped() {
    let dir = scratch("hostile-schedule");
    let path = dir.join("schedule.toml");
    std::fs::write(
        &path,
        "[executive]\nmargin_us = 2000\nlate_start_us = 1000\n\n[[tasks]]\nname = \"imu\"\n\
         period_ms = 18446744073709551615\nbudget_us = 300\non_overrun = \"log\"\n",
    )
    .expect("write");
    refused_in_one_line(
        &["check-schedule", path.to_str().expect("utf-8")],
        "task `imu`: period_ms = 18446744073709551615 is out of range (1..=3600000)",
    );
}

#[test]
fn an_unknown_text_log_stream_is_an_error() {
    let dir = scratch("hostile-text-log");
    let fly_with_text_log = |stream: &str| {
        skyframe()
            .args([
                "sim",
                "--fast",
                "--duration",
                "1",
                "--no-link",
                "--text-log",
                stream,
            ])
            .arg("--log-dir")
            .arg(&dir)
            .output()
            .expect("runs")
    };
    let out = fly_with_text_log("nosuch");
    let text = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{text}");
    assert!(
        text.contains("--text-log nosuch: this flight writes no such stream (")
            && text.contains("imu"),
        "{text}"
    );
    // A known one is still taken.
    let out = fly_with_text_log("gps");
    assert!(out.status.success(), "{}", stderr(&out));
}

/// SIGTERM while the IMU task is stuck for 5 s in one step: the process ends within 1 s with
/// exit 4, says so in one line, and leaves every log file whole and closed (a final End Data,
/// no damage: the converter reads every file without a problem).
#[test]
fn a_stop_while_a_task_is_stuck_ends_the_run_within_a_second_with_the_logs_whole() {
    let dir = scratch("hostile-stuck");
    // Frame 150 (1.5 s into the flight, after the 200 ms timer check) holds the IMU 5 s.
    let mut child = skyframe()
        .args([
            "sim",
            "--duration",
            "30",
            "--priority",
            "0",
            "--no-mlockall",
            "--no-link",
            "--inject-overrun",
            "imu:5000000@150..151",
        ])
        .arg("--log-dir")
        .arg(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("skyframe sim");
    std::thread::sleep(Duration::from_millis(2800));
    let pid = nix::unistd::Pid::from_raw(child.id() as i32);
    let asked = Instant::now();
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).expect("signal");
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        assert!(asked.elapsed() < Duration::from_secs(3), "still running");
        std::thread::sleep(Duration::from_millis(10));
    };
    let took = asked.elapsed();
    let mut text = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().expect("stderr"), &mut text)
        .expect("read");
    assert_eq!(status.code(), Some(4), "{text}");
    assert!(took < Duration::from_secs(1), "took {took:?}");
    let line = text
        .lines()
        .find(|l| l.contains("stopped abnormally"))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(
        line.contains("closed whole") && line.contains("exit 4"),
        "{line}"
    );

    let flight = std::fs::read_dir(&dir)
        .expect("dir")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .find(|p| p.is_dir())
        .expect("flight directory");
    let mut logs = 0;
    for entry in std::fs::read_dir(&flight).expect("flight") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "bin") {
            logs += 1;
            let info = skyframe_tests::binary("skyframe-log", "skyframe-log");
            let out = std::process::Command::new(info)
                .arg("info")
                .arg(&path)
                .output()
                .expect("skyframe-log info");
            let report = String::from_utf8_lossy(&out.stdout);
            assert!(out.status.success(), "{}: {}", path.display(), stderr(&out));
            assert!(
                report.contains("closed cleanly: yes"),
                "{}: {report}",
                path.display()
            );
            assert!(
                report.contains("damage: none"),
                "{}: {report}",
                path.display()
            );
        }
    }
    assert!(logs >= 8, "{logs} log files in {}", flight.display());
}

/// A flight on a 400 kB tmpfs that a 300 kB ballast file has nearly filled: logging is
/// suspended when the disk fills, the flight goes on, and when the ballast is deleted
/// logging resumes. Every file is whole (no half-written record, each closed with End
/// Data), the IMU log has records from after the space came back, and the run says how much
/// was lost (exit 3). Needs root for the mount (CI and the dev machines run as root).
#[test]
fn a_full_disk_suspends_logging_which_resumes_when_space_returns() {
    let dir = scratch("hostile-disk");
    let mount = dir.join("small");
    std::fs::create_dir_all(&mount).expect("dir");
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=400k", "tmpfs"])
        .arg(&mount)
        .status()
        .expect("mount runs");
    assert!(mounted.success(), "mounting a tmpfs needs root");
    struct Unmount(std::path::PathBuf);
    impl Drop for Unmount {
        fn drop(&mut self) {
            let _ = std::process::Command::new("umount").arg(&self.0).status();
        }
    }
    let _unmount = Unmount(mount.clone());
    let ballast = mount.join("ballast");
    std::fs::write(&ballast, vec![0u8; 300 * 1024]).expect("ballast");

    // Asked to, it refuses to fly a flight the disk cannot hold (9 s × ~46 kB/s > 100 kB).
    let refused = skyframe()
        .args([
            "sim",
            "--fast",
            "--duration",
            "9",
            "--no-link",
            "--require-log-space",
        ])
        .arg("--log-dir")
        .arg(mount.join("flights"))
        .output()
        .expect("runs");
    let text = stderr(&refused);
    assert_eq!(refused.status.code(), Some(2), "{text}");
    assert!(
        text.contains("refusing to fly (--require-log-space)") && text.contains("kB free"),
        "{text}"
    );

    let child = spawn_piped(
        skyframe()
            .args([
                "sim",
                "--duration",
                "9",
                "--priority",
                "0",
                "--no-mlockall",
                "--no-link",
                "--json",
            ])
            .arg("--log-dir")
            .arg(mount.join("flights")),
    );
    // About 44 kB/s: the last 100 kB are gone in 2-3 s.
    std::thread::sleep(Duration::from_secs(4));
    std::fs::remove_file(&ballast).expect("delete the ballast");
    let freed_wall = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .expect("clock")
        .as_secs_f64();
    let out = child.wait_with_output().expect("exits");
    let text = stderr(&out);
    assert_eq!(out.status.code(), Some(3), "{text}");
    assert!(
        text.contains("write failed") && text.contains("suspended"),
        "{text}"
    );
    // Warned at start, without --require-log-space.
    assert!(
        text.contains("kB free, but a 9 s flight logs about"),
        "{text}"
    );
    assert!(text.contains("writing again"), "{text}");
    let line = text
        .lines()
        .find(|l| l.contains("logging was lost"))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(line.contains("records"), "{line}");

    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("report");
    let lost: u64 = report["log_streams"]
        .as_array()
        .expect("streams")
        .iter()
        .map(|s| s["records_lost"].as_u64().unwrap_or(0))
        .sum();
    assert!(lost > 0, "{}", report["log_streams"]);
    eprintln!("disk full: {line}");
    let flight = std::path::PathBuf::from(report["flight_dir"].as_str().expect("dir"));
    let log_tool = skyframe_tests::binary("skyframe-log", "skyframe-log");
    for entry in std::fs::read_dir(&flight).expect("flight") {
        let path = entry.expect("entry").path();
        if path.extension().is_none_or(|e| e != "bin") {
            continue;
        }
        let out = std::process::Command::new(&log_tool)
            .arg("info")
            .arg(&path)
            .output()
            .expect("skyframe-log info");
        let info = String::from_utf8_lossy(&out.stdout);
        assert!(info.contains("damage: none"), "{}: {info}", path.display());
        assert!(
            info.contains("closed cleanly: yes"),
            "{}: {info}",
            path.display()
        );
    }
    // The IMU logged again after the space came back (log TIME is wall-clock in real time).
    let imu = skyframe_logtable::load_stream(&flight.join("imu.bin"), |p| panic!("{p:?}"))
        .expect("imu log");
    let last_s = imu
        .tables
        .values()
        .flat_map(|t| t.times_ns.iter())
        .max()
        .map(|&t| t as f64 * 1e-9)
        .expect("records");
    assert!(
        last_s > freed_wall + 1.0,
        "last IMU record {last_s}, space back at {freed_wall}"
    );
}

#[test]
fn a_converter_given_nothing_to_convert_says_so_and_fails() {
    let dir = scratch("hostile-empty");
    let out = std::process::Command::new(skyframe_tests::binary("skyframe-log", "skyframe-log"))
        .arg("to-csv")
        .arg(&dir)
        .output()
        .expect("skyframe-log");
    let text = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{text}");
    assert!(text.contains("no log files in this directory"), "{text}");
    assert_eq!(text.lines().count(), 1, "{text}");
}

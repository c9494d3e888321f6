//! The real `skyframe` binary: schedule check, timing detection on the real clock, clean stop
//! on signals and on the programmed duration.

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use serde_json::Value;
use skyframe_tests::{on_the_clock, run_ok, scratch, skyframe, spawn_piped, workspace};
use std::process::Command;
use std::time::{Duration, Instant};

/// `skyframe idle` (the executive alone) logging into a fresh scratch directory (never the caller's `flights/`).
fn sim(test: &str) -> Command {
    let mut cmd = skyframe();
    cmd.arg("idle").arg("--log-dir").arg(scratch(test));
    cmd
}

/// `skyframe idle --json` for `seconds` on the clock into a scratch directory, plus `extra`
/// arguments; the run must succeed.
fn sim_json(test: &str, seconds: &str, extra: &[&str]) -> Value {
    let out = run_ok(
        on_the_clock("idle", seconds)
            .arg("--log-dir")
            .arg(scratch(test))
            .args(extra),
    );
    json(&out.stdout)
}

use skyframe_tests::json_of as json;

fn task<'a>(summary: &'a Value, name: &str) -> &'a Value {
    summary["tasks"]
        .as_array()
        .and_then(|tasks| tasks.iter().find(|t| t["name"] == name))
        .unwrap_or_else(|| panic!("no task {name} in {summary}"))
}

#[test]
fn check_schedule_prints_the_shipped_frame_table() {
    let out = skyframe()
        .args(["check-schedule", "schedule.toml"])
        .current_dir(workspace())
        .output()
        .expect("runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("minor frame 10 ms, major frame 100 ms (10 minor frames)"),
        "{text}"
    );
    assert!(text.contains("utilisation 29.8 %"), "{text}");
    let header = text
        .lines()
        .find(|l| l.trim_start().starts_with("frame"))
        .expect("frame header");
    for name in [
        "imu",
        "estimator",
        "control",
        "servo",
        "gps",
        "telemetry",
        "health",
        "watchdog",
    ] {
        assert!(header.contains(name), "{header}");
    }
}

#[test]
fn check_schedule_exits_1_on_infeasible_and_2_on_unreadable_files() {
    let overfull = workspace().join("tests/schedules/overfull.toml");
    let out = skyframe()
        .arg("check-schedule")
        .arg(&overfull)
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("minor frame 3 is over-full"), "{err}");

    let dir = scratch("check-bad");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "tasks = [ { name = \"imu\" ").expect("write");
    let out = skyframe()
        .arg("check-schedule")
        .arg(&bad)
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    assert!(err.contains("bad.toml") && err.contains("line 1"), "{err}");

    let out = skyframe()
        .args(["check-schedule", "/nonexistent.toml"])
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
}

/// The run's timing log (`executive.bin`) through `skyframe-log to-csv`: one row per frame,
/// by frame number, as the named columns.
fn timing_rows(
    summary: &Value,
) -> std::collections::BTreeMap<u64, std::collections::HashMap<String, u64>> {
    let log = summary["log_files"]
        .as_array()
        .and_then(|f| {
            f.iter()
                .filter_map(Value::as_str)
                .find(|f| f.ends_with("/executive.bin"))
        })
        .expect("executive log")
        .to_string();
    let out_dir =
        skyframe_tests::to_csv(&[&log], &std::path::Path::new(&log).with_file_name("csv"));
    let csv = std::fs::read_to_string(out_dir.join("executive.1.csv")).expect("csv");
    let columns: Vec<String> = csv
        .lines()
        .find_map(|l| l.strip_prefix("% time,"))
        .expect("column comment")
        .split(',')
        .map(str::to_string)
        .collect();
    csv.lines()
        .filter(|l| !l.starts_with('%'))
        .map(|line| {
            let row: std::collections::HashMap<String, u64> = columns
                .iter()
                .zip(line.split(',').skip(1))
                .map(|(c, v)| (c.clone(), v.parse().unwrap_or(u64::MAX)))
                .collect();
            (row["frame"], row)
        })
        .collect()
}

#[test]
fn injected_overruns_are_detected_on_the_real_clock_and_policies_apply() {
    // imu (budget 300 us, policy reset) gets 3 ms extra in frames 10..20; estimator (log)
    // 12 ms extra in frames 50..52, which runs frames 50 and 51 into the next frame. The
    // timing log says exactly what happened in those frames; elsewhere a loaded test machine
    // may add overruns of its own, so totals are only bounded below.
    let s = sim_json(
        "injected_overruns_are_detected_on_the_real_clock_and_policies_apply",
        "1",
        &[
            "--inject-overrun",
            "imu:3000@10..20",
            "--inject-overrun",
            "estimator:12000@50..52",
        ],
    );
    const IMU: u64 = 1 << 0;
    const ESTIMATOR: u64 = 1 << 1;
    let rows = timing_rows(&s);
    // A machine loaded enough to miss whole frames leaves gaps in the frame numbers: the
    // injection follows frame numbers, so check the injected frames that ran.
    let ran = |range: std::ops::Range<u64>| -> Vec<u64> {
        range.filter(|f| rows.contains_key(f)).collect()
    };
    let imu_frames = ran(10..20);
    assert!(imu_frames.len() >= 8, "{imu_frames:?}");
    for frame in imu_frames {
        let r = &rows[&frame];
        assert_ne!(
            r["over_budget_mask"] & IMU,
            0,
            "frame {frame}: imu over budget"
        );
        assert!(r["exec_ns_imu"] >= 3_000_000, "frame {frame}");
        // Reset policy: recover + init at the imu's next release (every frame).
        if let Some((next, r)) = rows.range(frame + 1..).next() {
            assert_ne!(
                r["reset_mask"] & IMU,
                0,
                "frame {next}: reset after frame {frame}"
            );
        }
    }
    let estimator_frames = ran(50..52);
    assert!(!estimator_frames.is_empty());
    for &frame in &estimator_frames {
        let r = &rows[&frame];
        assert_ne!(r["over_budget_mask"] & ESTIMATOR, 0, "frame {frame}");
        assert_ne!(
            r["over_frame_mask"] & ESTIMATOR,
            0,
            "frame {frame}: ran into the next frame"
        );
        let (next, after) = rows.range(frame + 1..).next().expect("a frame after");
        assert!(
            after["start_latency_ns"] >= 2_000_000 || after["missed_before"] > 0,
            "frame {next} starts late (or after missed frames) behind frame {frame}"
        );
    }
    assert!(
        rows.values().all(|r| r["reset_mask"] & ESTIMATOR == 0),
        "log policy never resets"
    );

    let imu = task(&s, "imu");
    assert!(imu["overruns_budget"].as_u64().unwrap_or(0) >= 10, "{s}");
    assert!(imu["resets"].as_u64().unwrap_or(0) >= 10, "{s}");
    // Each injected frame that ran overran; a loaded machine may miss frame 51 whole behind
    // frame 50's overrun, and then only frame 50's counts.
    let injected = estimator_frames.len() as u64;
    let estimator = task(&s, "estimator");
    assert!(
        estimator["overruns_frame"].as_u64().unwrap_or(0) >= injected,
        "{s}"
    );
    assert_eq!(estimator["resets"], 0, "log policy only counts");
    assert!(s["frames_overrun"].as_u64().unwrap_or(0) >= injected, "{s}");
    assert!(
        s["max_start_latency_us"].as_f64().unwrap_or(0.0) >= 2000.0,
        "{s}"
    );
}

#[test]
fn a_long_stall_misses_whole_frames_and_counts_their_releases() {
    // 35 ms in imu's step of frame 30 (due at 300 ms): it ends near 335 ms, so frames 31
    // (310-320 ms) and 32 (320-330 ms) pass whole and frame 33 starts about 5 ms late. The
    // injection covers frames 30..33 because a loaded machine may itself miss frame 30 (it
    // did in CI: no stall, 3 frames missed by load): then the first of 31 and 32 to run
    // stalls instead, and the frames it covers are missed, so only one stall happens.
    let s = sim_json(
        "a_long_stall_misses_whole_frames_and_counts_their_releases",
        "1",
        &["--inject-overrun", "imu:35000@30..33"],
    );
    assert!(s["frames_missed"].as_u64().unwrap_or(0) >= 2, "{s}");
    assert!(
        task(&s, "imu")["overruns_missed"].as_u64().unwrap_or(0) >= 2,
        "{s}"
    );
    assert!(
        task(&s, "imu")["overruns_frame"].as_u64().unwrap_or(0) >= 1,
        "{s}"
    );
    let frames = s["frames"].as_u64().unwrap_or(0) + s["frames_missed"].as_u64().unwrap_or(0);
    assert!(
        (100..=101).contains(&frames),
        "1 s of 10 ms frames, run or missed: {s}"
    );
}

fn stops_cleanly_on(signal: Signal) {
    let child = spawn_piped(
        on_the_clock("idle", "60")
            .arg("--log-dir")
            // One directory per signal: the two tests run at once, and scratch() empties it.
            .arg(scratch(&format!("stops_cleanly_on_{signal}"))),
    );
    std::thread::sleep(Duration::from_millis(700));
    let sent = Instant::now();
    kill(Pid::from_raw(child.id() as i32), signal).expect("signal");
    let out = child.wait_with_output().expect("exits");
    assert!(
        sent.elapsed() < Duration::from_secs(2),
        "stopped within a frame or two"
    );
    assert!(
        out.status.success(),
        "{:?}: {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let s = json(&out.stdout);
    assert_eq!(s["stop_reason"], "requested");
    for t in s["tasks"].as_array().expect("tasks") {
        assert_eq!(t["running"], false, "shutdown reached {}", t["name"]);
        assert!(t["steps"].as_u64().unwrap_or(0) > 0);
    }
}

#[test]
fn sigint_ends_the_run_cleanly() {
    stops_cleanly_on(Signal::SIGINT);
}

#[test]
fn sigterm_ends_the_run_cleanly() {
    stops_cleanly_on(Signal::SIGTERM);
}

#[test]
fn watchdog_counts_a_task_whose_releases_are_all_skipped() {
    // health (policy skip, every 10 ms) overruns on every release in frames 20..60: every
    // other release is skipped, so it still completes steps and stays alive. The watchdog
    // runs every 100 ms and sees all tasks alive. Given by its old name, `logging`, which
    // is read with a warning until the release after next.
    let s = sim_json(
        "watchdog_counts_a_task_whose_releases_are_all_skipped",
        "1",
        &["--inject-overrun", "logging:1000@20..60"],
    );
    assert_eq!(s["watchdog_checks"], 10, "{s}");
    let health = task(&s, "health");
    // 40 releases in frames 20..60, each over budget when it runs, each skipping the next:
    // 20 run and 20 are skipped (a loaded machine may add overruns elsewhere).
    assert!(health["skipped"].as_u64().unwrap_or(0) >= 20, "{s}");
    assert!(health["overruns_budget"].as_u64().unwrap_or(0) >= 20, "{s}");
    assert!(
        s["tasks"]
            .as_array()
            .expect("tasks")
            .iter()
            .all(|t| t["watchdog_misses"] == 0),
        "{s}"
    );
}

#[test]
fn real_time_refusals_are_reported_once_and_the_run_goes_on() {
    // Without CAP_SYS_NICE and CAP_IPC_LOCK even root is refused SCHED_FIFO.
    let out = std::process::Command::new("setpriv")
        .args([
            "--bounding-set=-sys_nice,-ipc_lock",
            "--inh-caps=-sys_nice,-ipc_lock",
        ])
        .arg(skyframe_tests::binary("skyframe-linux", "skyframe"))
        .args([
            "idle",
            "--duration",
            "0.3",
            "--json",
            "--cpu",
            // The highest CPU the option takes: no machine this runs on has it.
            "1023",
            "--log-dir",
        ])
        .arg(scratch("refusals"))
        .output();
    let Ok(out) = out else {
        panic!("setpriv (util-linux) is needed for this test");
    };
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(err.matches("SCHED_FIFO refused").count(), 1, "{err}");
    assert_eq!(err.matches("CPU pinning refused").count(), 1, "{err}");
    let s = json(&out.stdout);
    assert_eq!(s["realtime"]["sched_fifo_priority"]["status"], "refused");
    assert_eq!(s["realtime"]["cpu"]["status"], "refused");
    assert_eq!(task(&s, "imu")["releases"], 30);
}

#[test]
fn pinning_to_an_existing_cpu_is_granted() {
    let out = sim("pinning_to_an_existing_cpu_is_granted")
        .args([
            "--duration",
            "0.2",
            "--json",
            "--cpu",
            "0",
            "--priority",
            "0",
        ])
        .output()
        .expect("runs");
    assert!(out.status.success());
    let s = json(&out.stdout);
    assert_eq!(s["realtime"]["cpu"]["status"], "granted");
    assert_eq!(s["realtime"]["cpu"]["value"], 0);
    assert_eq!(s["realtime"]["sched_fifo_priority"]["status"], "not_asked");
}

/// The QNX binary flies on Linux too (its timer and settings are POSIX but for the QNX-only
/// calls), and says that the clock period, a QNX call, is refused here rather than faking it.
#[test]
fn the_qnx_platform_flies_on_linux_and_refuses_only_the_clock_period() {
    let out = Command::new(skyframe_tests::binary("skyframe-qnx", "skyframe-qnx"))
        .arg("idle")
        .arg("--log-dir")
        .arg(scratch("qnx_platform_on_linux"))
        .args([
            "--duration",
            "0.3",
            "--json",
            "--priority",
            "0",
            "--no-mlockall",
        ])
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(err.matches("clock period refused").count(), 1, "{err}");
    let s = json(&out.stdout);
    assert_eq!(s["stop_reason"], "duration");
    // 0.3 s of 10 ms frames, run or missed (a loaded machine misses some whole).
    let frames = s["frames"].as_u64().unwrap_or(0) + s["frames_missed"].as_u64().unwrap_or(0);
    assert!((30..=31).contains(&frames), "{s}");
    assert_eq!(s["realtime"]["clock_period_ns"]["status"], "refused");
    assert_eq!(s["realtime"]["timer_slack_ns"]["status"], "not_asked");
    assert_eq!(s["realtime"]["cpu_dma_latency_us"]["status"], "not_asked");
}

#[test]
fn programmed_duration_ends_the_run() {
    let s = sim_json("programmed_duration_ends_the_run", "0.5", &[]);
    assert_eq!(s["stop_reason"], "duration");
    assert_eq!(task(&s, "imu")["releases"], 50);
    assert_eq!(task(&s, "gps")["releases"], 5);
}

#[test]
fn bench_prints_both_latency_distributions_overhead_and_ratios() {
    let out = run_ok(skyframe().args(["bench", "--seconds", "0.5", "--json"]));
    let b = json(&out.stdout);
    for key in ["p50", "p99", "p999", "max"] {
        assert!(b["executive"]["wakeup_latency_us"][key].is_number(), "{b}");
        assert!(
            b["bare_clock_nanosleep"]["wakeup_latency_us"][key].is_number(),
            "{b}"
        );
    }
    // 0.5 s of 10 ms frames: each of the 50 slots run or counted missed. A frame due in the
    // last slot that starts after a stall runs in the slot it starts in, past the run's end,
    // and the slots it skipped are counted: frames + missed is then over 50 (51 seen once).
    let frames = b["executive"]["frames"].as_u64().unwrap_or(0);
    let missed = b["executive"]["overruns"]["missed_frames"]
        .as_u64()
        .unwrap_or(0);
    assert!(frames <= 50 && frames + missed >= 50, "{b}");
    assert!(frames >= 25, "{b}");
    assert!(b["bare_clock_nanosleep"]["wakeups"].as_u64().unwrap_or(0) == 50);
    assert!(
        b["executive"]["overhead_ns_per_frame"]["mean"]
            .as_f64()
            .unwrap_or(0.0)
            > 0.0
    );
    assert!(
        b["latency_ratio_executive_to_bare"]["p50"].is_number()
            || b["bare_clock_nanosleep"]["wakeup_latency_us"]["p50"] == 0.0
    );
    // Asked for SCHED_FIFO by default: granted or refused, never silently skipped.
    assert_ne!(b["realtime"]["sched_fifo_priority"]["status"], "not_asked");
}

#[test]
fn bad_arguments_exit_2_with_one_line() {
    let out = sim("bench_prints_both_latency_distributions_overhead_and_ratios")
        .args(["--inject-overrun", "camera:1@1..2"])
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no task `camera`"), "{err}");
    let out = skyframe()
        .args(["bench", "--seconds", "soon"])
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn bench_compares_against_cyclictest_in_the_same_run() {
    // .ci/run installs rt-tests; on a machine without it the bench says so in one line.
    let out = skyframe()
        .args([
            "bench",
            "--seconds",
            "0.3",
            "--json",
            "--compare-cyclictest",
        ])
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let b = json(&out.stdout);
    let c = &b["cyclictest"];
    assert_eq!(c["wakeup_latency_us"]["count"], 30, "{b}");
    assert!(
        c["command"].as_str().unwrap_or("").contains("-i10000 -l30"),
        "{b}"
    );
    for key in ["p50", "p99", "max"] {
        assert!(
            b["latency_ratio_executive_to_cyclictest"][key].is_number()
                || c["wakeup_latency_us"][key] == 0.0,
            "{b}"
        );
    }
}

#[test]
fn a_run_logs_its_timing_records_readably_for_skyframe_log() {
    let dir = scratch("timing-log");
    let out = on_the_clock("idle", "0.5")
        .args(["--log-dir"])
        .arg(&dir)
        .output()
        .expect("runs");
    assert!(out.status.success());
    let s = json(&out.stdout);
    let files: Vec<&str> = s["log_files"]
        .as_array()
        .expect("log files")
        .iter()
        .filter_map(Value::as_str)
        .collect();
    // The frame records, the health snapshots and the watchdog's checks.
    assert_eq!(files.len(), 3, "{s}");
    let file = files
        .iter()
        .find(|f| f.ends_with("/executive.bin"))
        .expect("executive log");
    assert!(file.starts_with(dir.to_str().expect("utf-8")), "{file}");
    // Definition, comment, begin, the timer check (its definition, comment and record), one
    // record per frame run (a loaded machine may miss whole frames, which leave no record), end.
    let frames_run = s["frames"].as_u64().unwrap_or(0);
    // A stall of the machine (seen once: 7 frames missed in 0.5 s) costs frames, not records;
    // a frame started late past the run's end counts the slots it skipped (see the bench test).
    assert!(frames_run >= 25, "{s}");
    let missed = s["frames_missed"].as_u64().unwrap_or(0);
    assert!(
        frames_run <= 50 && frames_run + missed >= 50,
        "0.5 s of 10 ms frames, each slot run or counted missed: {s}"
    );
    assert_eq!(s["log_streams"][0]["records_written"], 7 + frames_run);
    // health.bin: a snapshot of the 8 tasks at 0 s and at shutdown, between its begin/end.
    assert_eq!(s["log_streams"][1]["name"], "health");
    assert_eq!(s["log_streams"][1]["records_written"], 2 + 1 + 16 + 1);
    assert!(
        s["tasks"]
            .as_array()
            .expect("tasks")
            .iter()
            .all(|t| t["log_dropped"] == 0)
    );
    let text = skyframe_tests::log_info(&[*file]);
    assert!(
        text.contains(&format!("1: data blocks {frames_run}\n")),
        "{frames_run} frames run: {text}"
    );
    assert!(text.contains("2: data blocks 1"), "{text}");
    assert!(text.contains("closed cleanly: yes"), "{text}");
    assert!(text.contains("exec_ns_imu"), "{text}");

    // The start-up timer check is in the log with the figures the summary gives.
    let csv = skyframe_tests::to_csv(&[*file], &dir.join("csv")).join("executive.2.csv");
    let text = std::fs::read_to_string(&csv).expect("timer check CSV");
    assert!(text.contains("% time,period_us,samples,"), "{text}");
    let row: Vec<f64> = skyframe_tests::csv_rows(&csv).concat();
    let check = &s["timer_check"];
    let latency = &check["wakeup_latency_us"];
    let close = |logged: f64, reported: &Value| {
        (logged - reported.as_f64().unwrap_or(f64::NAN)).abs() <= 0.051
    };
    assert_eq!(row.len(), 10, "one record: {text}");
    assert_eq!(Some(row[1] as u64), check["period_us"].as_u64());
    assert_eq!(Some(row[2] as u64), latency["count"].as_u64());
    assert!(close(row[5], &latency["p99"]), "{text} vs {check}");
    assert!(close(row[7], &latency["max"]), "{text} vs {check}");
    assert!(close(row[8], &check["margin_us"]), "{text} vs {check}");
    assert_eq!(row[9] == 1.0, check["over_margin"] == true);
}

#[test]
fn bench_parsers_measures_each_decoder_and_the_nmea_crate_on_the_same_bytes() {
    let out = run_ok(skyframe().args(["bench", "parsers", "--json", "--megabytes", "0.05"]));
    let b = json(&out.stdout);
    for decoder in ["imu", "servo", "gps_all_sentences"] {
        assert!(b[decoder]["mb_per_s"].as_f64().unwrap_or(0.0) > 0.0, "{b}");
        assert!(b[decoder]["frames"].as_u64().unwrap_or(0) > 0, "{b}");
    }
    let g = &b["gga_rmc"];
    assert!(
        g["ours_mb_per_s"].as_f64().unwrap_or(0.0) > 0.0
            && g["nmea_crate_mb_per_s"].as_f64().unwrap_or(0.0) > 0.0,
        "{b}"
    );
    assert_eq!(
        g["sentences"].as_u64().unwrap_or(0) % 2,
        0,
        "GGA and RMC in pairs: {b}"
    );
}

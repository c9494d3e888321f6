//! skyframe-overrun end to end: a synthetic timing log with known overruns gives the known
//! figures; damaged and unusable input; figures; `run --` on real flights.

use std::path::PathBuf;
use std::process::{Command, Output};

use serde_json::Value;
use skyframe_core::executive::FrameRecord;
use skyframe_core::executive::timing::flags;
use skyframe_core::logfmt::{
    DataBlockWriter, Format, FrameRecordFormat, MAX_RECORD_LEN, encode_begin_data, encode_end_data,
    encode_format_definition, encode_frame_record,
};
use skyframe_core::schedule::SHIPPED;

fn overrun() -> Command {
    Command::new(env!("CARGO_BIN_EXE_skyframe-overrun"))
}

fn task(name: &str) -> usize {
    SHIPPED.task_index(name).expect("shipped task")
}

fn append(out: &mut Vec<u8>, encode: impl FnOnce(&mut [u8]) -> usize) {
    let mut buf = [0u8; MAX_RECORD_LEN];
    let n = encode(&mut buf);
    out.extend_from_slice(&buf[..n]);
}

/// The synthetic flight: frames 0..1000 of the shipped table less 498 and 499 (missed:
/// frame 500 says so), every task at a fixed execution time except
/// - imu 3000 us (over its 300 us budget, reset) in frames 100..=104;
/// - estimator 12000 us (over budget, into the next frame) in frame 700, so frame 701 starts
///   2500 us late;
/// - health skipped in frames 300..=309;
/// - start latency 20 us, 50 us in frames 0..=9, 5000 us in frame 500 (after the missed
///   ones), 2500 us in frame 701; overhead 1 us per frame.
fn synthetic_frames() -> Vec<FrameRecord> {
    let (imu, estimator, health) = (task("imu"), task("estimator"), task("health"));
    let mut frames = Vec::new();
    for k in 0..1000u64 {
        if k == 498 || k == 499 {
            continue;
        }
        let mut f = FrameRecord::empty();
        f.frame = k;
        f.release_ns = (k + 1) * 10_000_000;
        let released = SHIPPED.released(k);
        f.ran = released;
        for i in 0..SHIPPED.tasks.len() {
            if released & (1 << i) != 0 {
                f.exec_ns[i] = 10_000;
            }
        }
        f.exec_ns[imu] = 100_000;
        f.exec_ns[estimator] = 200_000;
        if (100..=104).contains(&k) {
            f.exec_ns[imu] = 3_000_000;
            f.over_budget |= 1 << imu;
            f.reset |= 1 << imu;
        }
        if k == 700 {
            f.exec_ns[estimator] = 12_000_000;
            f.over_budget |= 1 << estimator;
            f.over_frame |= 1 << estimator;
            f.flags |= flags::OVERRUN;
        }
        if (300..=309).contains(&k) {
            f.ran &= !(1 << health);
            f.skipped |= 1 << health;
            f.exec_ns[health] = 0;
        }
        f.start_latency_ns = match k {
            0..=9 => 50_000,
            500 => 5_000_000,
            701 => 2_500_000,
            _ => 20_000,
        };
        if k == 500 {
            f.missed_before = 2;
            f.flags |= flags::AFTER_MISSED;
        }
        if f.start_latency_ns >= 1_000_000 {
            f.flags |= flags::LATE;
        }
        f.overhead_ns = 1_000;
        f.work_ns = f.exec_ns.iter().sum::<u32>() + f.overhead_ns;
        frames.push(f);
    }
    frames
}

fn executive_log(frames: &[FrameRecord]) -> Vec<u8> {
    let log = FrameRecordFormat::new(SHIPPED.tasks).expect("frame log format");
    let mut out = Vec::new();
    append(&mut out, |b| encode_begin_data(b, 0).expect("begin"));
    append(&mut out, |b| {
        log.encode_declaration(b, 1).expect("declaration")
    });
    for f in frames {
        append(&mut out, |b| {
            encode_frame_record(b, 1, f.release_ns, &log, f).expect("record")
        });
    }
    append(&mut out, |b| {
        encode_end_data(b, 11_000_000_000).expect("end")
    });
    out
}

/// A gps.bin with 11 epochs 140 ms apart.
fn gps_log() -> Vec<u8> {
    let format = Format::parse("%u").expect("format");
    let mut out = Vec::new();
    append(&mut out, |b| encode_begin_data(b, 0).expect("begin"));
    append(&mut out, |b| {
        encode_format_definition(b, 1, "%u").expect("def")
    });
    for i in 0..11u32 {
        append(&mut out, |b| {
            DataBlockWriter::new(b, 1, 1_000_000_000 + u64::from(i) * 140_000_000, &format)
                .u32(i)
                .finish()
                .expect("gps record")
        });
    }
    append(&mut out, |b| {
        encode_end_data(b, 3_000_000_000).expect("end")
    });
    out
}

fn synthetic_flight() -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(
        dir.path().join("executive.bin"),
        executive_log(&synthetic_frames()),
    )
    .expect("write");
    std::fs::write(dir.path().join("gps.bin"), gps_log()).expect("write");
    dir
}

fn json_of(output: &Output) -> Value {
    serde_json::from_slice(&output.stdout).unwrap_or_else(|e| {
        panic!(
            "not JSON ({e}): {}\n{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        )
    })
}

fn task_json<'a>(report: &'a Value, name: &str) -> &'a Value {
    report["tasks"]
        .as_array()
        .expect("tasks")
        .iter()
        .find(|t| t["name"] == name)
        .unwrap_or_else(|| panic!("no task {name}"))
}

#[test]
fn synthetic_log_gives_the_known_figures() {
    let dir = synthetic_flight();
    let output = overrun()
        .args(["report", "--json"])
        .arg(dir.path())
        .output()
        .expect("runs");
    assert_eq!(
        output.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let r = json_of(&output);
    assert_eq!(r["damaged"], false);

    let imu = task_json(&r, "imu");
    assert_eq!(imu["ran"], 998);
    assert_eq!(imu["missed"], 2);
    assert_eq!(imu["releases"], 1000);
    assert_eq!(imu["budget_ns"], 300_000);
    assert_eq!(imu["exec_ns"]["min"], 100_000);
    // 993 × 100 us, 5 × 3000 us: p99 is rank 989, p99.9 rank 998 (nearest rank).
    assert_eq!(imu["exec_ns"]["p99"], 100_000);
    assert_eq!(imu["exec_ns"]["p999"], 3_000_000);
    assert_eq!(imu["exec_ns"]["max"], 3_000_000);
    let mean = imu["exec_ns"]["mean"].as_f64().expect("mean");
    assert!((mean - 114_300_000.0 / 998.0).abs() < 1e-6, "{mean}");
    assert_eq!(imu["over_budget"], 5);
    assert_eq!(imu["over_frame"], 0);
    assert_eq!(imu["resets"], 5);
    assert_eq!(imu["slack_ns"], 300_000 - 3_000_000);

    let estimator = task_json(&r, "estimator");
    assert_eq!(estimator["over_budget"], 1);
    assert_eq!(estimator["over_frame"], 1);
    assert_eq!(estimator["exec_ns"]["max"], 12_000_000);
    assert_eq!(estimator["slack_ns"], 1_500_000 - 12_000_000);

    let health = task_json(&r, "health");
    assert_eq!(health["skipped"], 10);
    assert_eq!(health["ran"], 988);
    assert_eq!(health["releases"], 1000);

    // control and servo: every 20 ms; 498 (missed) is one of theirs.
    let servo = task_json(&r, "servo");
    assert_eq!(servo["ran"], 499);
    assert_eq!(servo["missed"], 1);
    assert_eq!(servo["slack_ns"], 300_000 - 10_000);

    let frames = &r["frames"];
    assert_eq!(frames["count"], 998);
    assert_eq!(frames["late"], 2);
    assert_eq!(frames["missed"], 2);
    assert_eq!(frames["overrun"], 1);
    assert_eq!(frames["after_missed"], 1);
    // 986 × 20 us, 10 × 50 us, 2500 us, 5000 us.
    assert_eq!(frames["start_latency_ns"]["p50"], 20_000);
    assert_eq!(frames["start_latency_ns"]["p99"], 50_000);
    assert_eq!(frames["start_latency_ns"]["p999"], 5_000_000);
    assert_eq!(frames["start_latency_ns"]["max"], 5_000_000);

    let worst: Vec<u64> = r["worst_frames"]
        .as_array()
        .expect("worst")
        .iter()
        .map(|w| w["frame"].as_u64().expect("frame"))
        .collect();
    // 700: 12.3 ms of work; 500: 5 ms late; 100, 102, 104: 3 ms of imu (ties by frame number)
    // beat 701's 2.5 ms latency.
    assert_eq!(worst, [700, 500, 100, 102, 104]);
    let w = &r["worst_frames"][0];
    assert_eq!(
        w["end_ns"],
        20_000 + 12_000_000 + 100_000 + 3 * 10_000 + 1_000
    );
    assert_eq!(w["flags"], serde_json::json!(["OVERRUN"]));
    let est = w["tasks"]
        .as_array()
        .expect("tasks")
        .iter()
        .find(|t| t["name"] == "estimator")
        .expect("estimator ran");
    assert_eq!(est["exec_ns"], 12_000_000);
    assert_eq!(est["over_frame"], true);

    // IMU → servo: the 499 frames where both ran; worst is frame 700: 20 us + imu 100 +
    // estimator 12000 + health, control, servo 10 each + all of the 1 us overhead.
    let e2e = &r["end_to_end"]["latency_ns"];
    assert_eq!(e2e["count"], 499);
    assert_eq!(e2e["max"], 12_151_000);
    assert_eq!(e2e["p50"], 351_000);

    let gps = &r["device_periods"][0];
    assert_eq!(gps["device"], "gps");
    assert_eq!(gps["samples"], 11);
    assert!((gps["mean_ms"].as_f64().expect("mean") - 140.0).abs() < 1e-9);
    assert!((gps["max_ms"].as_f64().expect("max") - 140.0).abs() < 1e-9);
}

#[test]
fn text_report_names_the_figures() {
    let dir = synthetic_flight();
    let output = overrun()
        .arg("report")
        .arg(dir.path().join("executive.bin"))
        .output()
        .expect("runs");
    assert_eq!(output.status.code(), Some(0));
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(
        text.contains("frames: 2 late, 2 missed, 1 overrun"),
        "{text}"
    );
    assert!(text.contains("frame     700"), "{text}");
    assert!(
        text.contains("end-to-end IMU -> servo latency over 499 frames"),
        "{text}"
    );
    assert!(text.contains("gps"), "{text}");
}

#[test]
fn damaged_log_reports_what_is_readable_and_exits_3() {
    let dir = synthetic_flight();
    let path = dir.path().join("executive.bin");
    let mut bytes = std::fs::read(&path).expect("read");
    let middle = bytes.len() / 2;
    bytes[middle..middle + 40].fill(0xEE);
    bytes.truncate(bytes.len() - 30);
    std::fs::write(&path, &bytes).expect("write");
    let output = overrun()
        .args(["report", "--json"])
        .arg(&path)
        .output()
        .expect("runs");
    assert_eq!(output.status.code(), Some(3));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("offset"), "{stderr}");
    let r = json_of(&output);
    assert_eq!(r["damaged"], true);
    let count = r["frames"]["count"].as_u64().expect("count");
    assert!(count > 900 && count < 998, "{count}");
}

#[test]
fn unusable_input_is_one_line_and_exit_2() {
    let dir = tempfile::tempdir().expect("tempdir");
    let missing = overrun()
        .arg("report")
        .arg(dir.path().join("nothing"))
        .output()
        .expect("runs");
    assert_eq!(missing.status.code(), Some(2));
    assert_eq!(String::from_utf8_lossy(&missing.stderr).lines().count(), 1);

    let empty_dir = overrun()
        .arg("report")
        .arg(dir.path())
        .output()
        .expect("runs");
    assert_eq!(empty_dir.status.code(), Some(2));

    let text = dir.path().join("notes.txt");
    std::fs::write(&text, "not a log at all\n").expect("write");
    let not_a_log = overrun().arg("report").arg(&text).output().expect("runs");
    assert_eq!(not_a_log.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&not_a_log.stderr).contains("no executive timing records"));
}

#[test]
fn plot_writes_png_and_svg() {
    let dir = synthetic_flight();
    let plots = dir.path().join("plots");
    let output = overrun()
        .arg("report")
        .arg(dir.path())
        .arg("--plot")
        .arg(&plots)
        .output()
        .expect("runs");
    assert_eq!(
        output.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    for name in ["latency_histogram", "exec_vs_budget", "worst_frames"] {
        let png = std::fs::read(plots.join(format!("{name}.png"))).expect("png");
        assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "{name}.png");
        let svg = std::fs::read_to_string(plots.join(format!("{name}.svg"))).expect("svg");
        assert!(svg.contains("<svg") && svg.contains("</svg>"), "{name}.svg");
    }
}

/// The `skyframe` flight binary, built if needed.
fn skyframe() -> PathBuf {
    skyframe_tests::binary("skyframe-linux", "skyframe")
}

#[test]
fn run_follows_an_idle_flight_with_injected_overruns() {
    let logs = tempfile::tempdir().expect("tempdir");
    let output = overrun()
        .args(["run", "--json", "--"])
        .arg(skyframe())
        .args(["idle", "--duration", "2", "--priority", "0", "--log-dir"])
        .arg(logs.path())
        .args([
            "--inject-overrun",
            "imu:3000@50..55",
            "--inject-overrun",
            "estimator:12000@100..101",
        ])
        .output()
        .expect("runs");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains("flight directory: "), "{stderr}");
    let r = json_of(&output);
    assert!(r["frames"]["count"].as_u64().expect("count") >= 150);
    // At least the injected ones (a loaded test machine may add its own).
    let imu = task_json(&r, "imu");
    assert!(imu["over_budget"].as_u64().expect("count") >= 5, "{imu}");
    assert!(imu["resets"].as_u64().expect("count") >= 5, "{imu}");
    assert!(
        imu["exec_ns"]["max"].as_u64().expect("max") >= 3_000_000,
        "{imu}"
    );
    let estimator = task_json(&r, "estimator");
    assert!(estimator["over_budget"].as_u64().expect("count") >= 1);
    assert!(estimator["over_frame"].as_u64().expect("count") >= 1);
    assert!(estimator["exec_ns"]["max"].as_u64().expect("max") >= 12_000_000);
    assert!(r["frames"]["overrun"].as_u64().expect("overrun") >= 1);
}

#[test]
fn run_reports_a_fast_sim_flight_with_device_periods() {
    let logs = tempfile::tempdir().expect("tempdir");
    let output = overrun()
        .args(["run", "--"])
        .arg(skyframe())
        .args([
            "sim",
            "--fast",
            "--duration",
            "5",
            "--commands",
            "127.0.0.1:0",
        ])
        .arg("--log-dir")
        .arg(logs.path())
        .output()
        .expect("runs");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "{stderr}");
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(text.contains("500 frame records"), "{text}");
    assert!(text.contains("device sample periods"), "{text}");
    for device in ["imu", "gps", "servo"] {
        assert!(
            text.lines()
                .any(|l| l.trim_start().starts_with(device) && l.contains("samples")),
            "{device}: {text}"
        );
    }
}

#[test]
fn an_interrupted_run_still_reports_what_was_flown() {
    let logs = tempfile::tempdir().expect("tempdir");
    let tool = overrun()
        .args(["run", "--json", "--"])
        .arg(skyframe())
        .args(["idle", "--duration", "60", "--priority", "0", "--log-dir"])
        .arg(logs.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("starts");
    // Let frames be logged, then Ctrl-C the tool alone (not its process group): it must
    // pass the interrupt on and report.
    std::thread::sleep(std::time::Duration::from_millis(2500));
    let pid = nix::unistd::Pid::from_raw(i32::try_from(tool.id()).expect("pid"));
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).expect("signal");
    let started = std::time::Instant::now();
    let output = tool.wait_with_output().expect("ends");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        started.elapsed() < std::time::Duration::from_secs(20),
        "ended {:?} after the interrupt",
        started.elapsed()
    );
    assert_eq!(output.status.code(), Some(0), "{stderr}");
    let r = json_of(&output);
    let frames = r["frames"]["count"].as_u64().expect("count");
    // 60 s were asked for; about 2.5 s (less the timer check) were flown.
    assert!((50..1000).contains(&frames), "{frames} frames: {stderr}");
}

#[test]
fn run_exits_with_a_failing_childs_code() {
    let logs = tempfile::tempdir().expect("tempdir");
    let output = overrun()
        .args(["run", "--", "sh", "-c", "exit 7", "--log-dir"])
        .arg(logs.path())
        .output()
        .expect("runs");
    assert_eq!(output.status.code(), Some(7));
}

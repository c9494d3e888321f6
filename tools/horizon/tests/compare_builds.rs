//! `tools/horizon/compare_builds.py`: two builds on the same sets, answers compared frame by
//! frame against the builds' own `detect` output, times gathered per frame size.
//!
//! The interpreter is `python3`, or `SKYFRAME_HORIZON_PYTHON` (the standard library is all
//! the script needs).

mod common;

use common::{binary, detect_set, python, succeeded};
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("compare_builds.py")
}

fn compare(baseline: &Path, candidate: &Path, extra: &[&str], sets: &[&Path]) -> Output {
    Command::new(python())
        .arg(script())
        .arg("--baseline")
        .arg(baseline)
        .arg("--candidate")
        .arg(candidate)
        .args(extra)
        .args(sets)
        .output()
        .expect("runs python")
}

/// A "build": the shell script `body`, where `REAL` stands for the real build (to change its
/// output, or to fail in its place).
fn wrapped_build(dir: &Path, name: &str, body: &str) -> PathBuf {
    let path = dir.join(name);
    let real = env!("CARGO_BIN_EXE_skyframe-horizon");
    std::fs::write(
        &path,
        format!("#!/bin/sh\n{}\n", body.replace("REAL", real)),
    )
    .expect("writes the wrapper");
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    path
}

#[test]
fn a_changed_answer_is_found_where_it_is_and_the_same_build_agrees_with_itself() {
    let dir = std::env::temp_dir().join(format!("skyframe-compare-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    let set = dir.join("clean");
    succeeded(
        binary()
            .args(["synth", "--degradation", "clean", "--frames", "4"])
            .args(["--width", "320", "--height", "240", "--out"])
            .arg(&set)
            .output()
            .expect("renders"),
    );
    let real = PathBuf::from(env!("CARGO_BIN_EXE_skyframe-horizon"));

    // The same build on both sides: every frame alike, and one size timed over two runs.
    let out = compare(&real, &real, &["--runs", "2", "--require-same"], &[&set]);
    let report: serde_json::Value = serde_json::from_str(&succeeded(out)).expect("JSON");
    assert_eq!(report["frames"], 4, "{report}");
    assert_eq!(report["answers_differ"], 0, "{report}");
    let speed = &report["speed"][0];
    assert_eq!(speed["size"], "320x240", "{report}");
    // The paired ratio is the median of the runs' own ratios (of two runs: their mean).
    let runs = |build: &str| -> Vec<f64> {
        speed[build]["ms_median_of_each_run"]
            .as_array()
            .map(|v| v.iter().filter_map(serde_json::Value::as_f64).collect())
            .unwrap_or_default()
    };
    let (base, cand) = (runs("baseline"), runs("candidate"));
    assert_eq!((base.len(), cand.len()), (2, 2), "{report}");
    let expected = (base[0] / cand[0] + base[1] / cand[1]) / 2.0;
    let paired = speed["speedup_median_paired"].as_f64().unwrap_or(f64::NAN);
    assert!(
        (paired - expected).abs() < 1e-9,
        "{paired} vs {expected}: {report}"
    );
    assert_eq!(speed["frames_per_run"], 4, "{report}");

    // A build whose second frame's roll is a degree off: that frame, and only it, differs,
    // with the real build's answer (as `detect` prints it) on the baseline's side.
    let shifted = wrapped_build(
        &dir,
        "shifted",
        r#"REAL "$@" | awk -F, -v OFS=, 'NR == 3 { $2 = $2 + 1 } { print }'"#,
    );
    let detected = detect_set(&set);
    let frame_1: Vec<&str> = detected
        .lines()
        .nth(2)
        .expect("frame 1")
        .split(',')
        .collect();
    let out = compare(&real, &shifted, &[], &[&set]);
    let report: serde_json::Value = serde_json::from_str(&succeeded(out)).expect("JSON");
    assert_eq!(report["answers_differ"], 1, "{report}");
    let differing = &report["differing"][0];
    assert_eq!(differing["frame"], 1, "{report}");
    assert_eq!(differing["baseline"], frame_1[1..4].join(","), "{report}");
    assert_ne!(differing["candidate"], differing["baseline"], "{report}");
    // Under --require-same the difference is the exit code.
    let out = compare(&real, &shifted, &["--require-same"], &[&set]);
    assert_eq!(out.status.code(), Some(1));

    // Bad input: one line naming what is wrong, exit 2.
    let failing = wrapped_build(&dir, "failing", "echo 'no such frame' >&2; exit 3");
    let missing = dir.join("no-such-set");
    for (out, names) in [
        (compare(&real, &failing, &[], &[&set]), "failing"),
        (compare(&real, &real, &[], &[&missing]), "no-such-set"),
        (compare(&real, &missing, &[], &[&set]), "no-such-set"),
    ] {
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(
            stderr.starts_with("compare_builds: ") && stderr.contains(names),
            "{stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Whatever a build prints and whatever a set's camera file holds, the comparison either
/// reports or refuses in one line (exit 2): never a traceback.
#[test]
fn any_output_and_any_camera_file_are_reported_or_refused_in_one_line() {
    let dir = std::env::temp_dir().join(format!("skyframe-compare-fuzz-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let set = dir.join("set");
    std::fs::create_dir_all(&set).expect("scratch dir");
    let output = dir.join("output");
    let printing = wrapped_build(&dir, "printing", &format!("cat '{}'", output.display()));
    let real_output = "frame,roll_deg,pitch_deg,confidence,ms\n0,1.250,-2.500,0.800,0.612\n\
                       1,,,0.000,0.400\n";
    let camera = "width = 320\nheight = 240\nfx = 277.1\nfy = 277.1\ncx = 159.5\ncy = 119.5\n";
    // A small generator of its own (xorshift): the same cases every run.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let (mut reported, mut refused) = (0, 0);
    for case in 0..120 {
        // Half the cases keep the build's output whole: a mangled line is refused (the
        // times could not be read), so those would seldom reach the report.
        let out_bytes = if case % 2 == 0 {
            mangle(real_output, &mut next)
        } else {
            real_output.as_bytes().to_vec()
        };
        std::fs::write(&output, &out_bytes).expect("writes the output");
        let camera_bytes = if case % 3 == 0 {
            mangle(camera, &mut next)
        } else {
            camera.as_bytes().to_vec()
        };
        std::fs::write(set.join("camera.toml"), &camera_bytes).expect("writes the camera");
        let out = compare(&printing, &printing, &[], &[&set]);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        match out.status.code() {
            Some(0) => {
                serde_json::from_slice::<serde_json::Value>(&out.stdout).expect("JSON");
                reported += 1;
            }
            Some(2) => {
                assert!(
                    stderr.lines().count() == 1 && stderr.starts_with("compare_builds: "),
                    "case {case}: {stderr}"
                );
                refused += 1;
            }
            code => panic!("case {case}: exit {code:?}: {stderr}"),
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        reported > 10 && refused > 10,
        "reported {reported}, refused {refused}"
    );
}

/// `text` with one to six bytes changed, cut off, or a comma or a line break put in.
fn mangle(text: &str, next: &mut dyn FnMut() -> u64) -> Vec<u8> {
    let mut bytes = text.as_bytes().to_vec();
    for _ in 0..1 + next() % 6 {
        if bytes.is_empty() {
            break;
        }
        let at = (next() % bytes.len() as u64) as usize;
        match next() % 4 {
            0 => bytes[at] = next() as u8,
            1 => bytes.truncate(at),
            2 => bytes.insert(at, b','),
            _ => bytes.insert(at, b'\n'),
        }
    }
    bytes
}

//! The binary as a user meets it: formats in, CSV out, one-line errors with exit code 2.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn binary() -> Command {
    Command::new(env!("CARGO_BIN_EXE_skyframe-horizon"))
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "skyframe-horizon-cli-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

fn run(args: &[&str]) -> Output {
    binary().args(args).output().expect("runs")
}

fn synth(dir: &Path, format: &str, frames: usize) {
    let out = run(&[
        "synth",
        "--out",
        dir.to_str().expect("utf-8"),
        "--frames",
        &frames.to_string(),
        "--format",
        format,
        "--seed",
        "3",
    ]);
    assert!(
        out.status.success(),
        "synth: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Checks the CSV: header, one line a frame numbered from 0, attitude near the truth.
fn check_csv(csv: &str, truth_path: &Path, frames: usize) {
    let truth = std::fs::read_to_string(truth_path).expect("truth");
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("frame,roll_deg,pitch_deg,confidence,ms"));
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), frames);
    for (i, (row, t)) in rows.iter().zip(truth.lines().skip(1)).enumerate() {
        let f: Vec<&str> = row.split(',').collect();
        let t: Vec<f32> = t.split(',').map(|v| v.parse().expect("number")).collect();
        assert_eq!(f[0], i.to_string());
        let roll: f32 = f[1].parse().expect("a roll");
        let pitch: f32 = f[2].parse().expect("a pitch");
        assert!(
            (roll - t[1]).abs() < 1.0 && (pitch - t[2]).abs() < 1.0,
            "frame {i}: {row} vs {t:?}"
        );
    }
}

fn assert_input_error(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "one line: {stderr}");
    assert!(stderr.contains(needle), "{needle:?} not in {stderr}");
}

#[test]
fn png_directory_with_camera_and_annotations() {
    let dir = scratch("png");
    synth(&dir, "png", 3);
    let annotated = dir.join("annotated");
    let csv_path = dir.join("out.csv");
    let out = run(&[
        "detect",
        dir.to_str().expect("utf-8"),
        "--camera",
        dir.join("camera.toml").to_str().expect("utf-8"),
        "-o",
        csv_path.to_str().expect("utf-8"),
        "--annotate",
        annotated.to_str().expect("utf-8"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    check_csv(
        &std::fs::read_to_string(&csv_path).expect("csv"),
        &dir.join("truth.csv"),
        3,
    );
    assert!(annotated.join("frame_000002.png").exists());
}

#[test]
fn y4m_from_a_file_and_from_stdin() {
    let dir = scratch("y4m");
    synth(&dir, "y4m", 3);
    let stream = dir.join("frames.y4m");
    let out = run(&["detect", stream.to_str().expect("utf-8")]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    check_csv(
        &String::from_utf8_lossy(&out.stdout),
        &dir.join("truth.csv"),
        3,
    );

    let mut child = binary()
        .args(["detect", "-"])
        .stdin(Stdio::from(std::fs::File::open(&stream).expect("stream")))
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawns");
    let stdout = child.stdout.take().expect("stdout");
    let csv = std::io::read_to_string(stdout).expect("csv");
    assert!(child.wait().expect("exits").success());
    check_csv(&csv, &dir.join("truth.csv"), 3);
}

#[test]
fn single_pgm_image() {
    let dir = scratch("pgm");
    synth(&dir, "pgm", 1);
    let out = run(&[
        "detect",
        dir.join("frame_000000.pgm").to_str().expect("utf-8"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    check_csv(
        &String::from_utf8_lossy(&out.stdout),
        &dir.join("truth.csv"),
        1,
    );
}

#[test]
fn synth_is_deterministic_for_a_seed() {
    let (a, b) = (scratch("det-a"), scratch("det-b"));
    synth(&a, "pgm", 2);
    synth(&b, "pgm", 2);
    for name in ["frame_000001.pgm", "truth.csv", "camera.toml"] {
        assert_eq!(
            std::fs::read(a.join(name)).expect("a"),
            std::fs::read(b.join(name)).expect("b"),
            "{name}"
        );
    }
}

#[test]
fn missing_input_is_one_line_exit_2() {
    assert_input_error(
        &run(&["detect", "/no/such/flight.y4m"]),
        "/no/such/flight.y4m",
    );
}

#[test]
fn not_a_y4m_stream() {
    let dir = scratch("garbage");
    let path = dir.join("flight.y4m");
    std::fs::write(&path, b"this is not video\n").expect("write");
    assert_input_error(&run(&["detect", path.to_str().expect("utf-8")]), "byte 0");
}

#[test]
fn truncated_y4m_names_the_offset() {
    let dir = scratch("truncated");
    synth(&dir, "y4m", 2);
    let bytes = std::fs::read(dir.join("frames.y4m")).expect("stream");
    let cut = dir.join("cut.y4m");
    std::fs::write(&cut, &bytes[..bytes.len() - 1000]).expect("write");
    let out = run(&["detect", cut.to_str().expect("utf-8")]);
    assert_input_error(&out, "frame 1 truncated");
    // The first frame's result was written before the error.
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 2);
}

#[test]
fn truncated_pgm_and_bad_png() {
    let dir = scratch("badimg");
    std::fs::write(dir.join("a.pgm"), b"P5\n320 240\n255\n\x00\x01").expect("write");
    assert_input_error(
        &run(&["detect", dir.join("a.pgm").to_str().expect("utf-8")]),
        "truncated",
    );
    std::fs::write(dir.join("b.png"), b"\x89PNG\r\n\x1a\nnope").expect("write");
    assert_input_error(
        &run(&["detect", dir.join("b.png").to_str().expect("utf-8")]),
        "b.png",
    );
}

#[test]
fn bad_camera_file_names_the_file() {
    let dir = scratch("camera");
    synth(&dir, "pgm", 1);
    let camera = dir.join("bad.toml");
    std::fs::write(&camera, "width = 320\nheight = 240\nfx = \"wide\"\n").expect("write");
    let out = run(&[
        "detect",
        dir.join("frame_000000.pgm").to_str().expect("utf-8"),
        "--camera",
        camera.to_str().expect("utf-8"),
    ]);
    assert_input_error(&out, "bad.toml");
}

#[test]
fn help_explains_the_commands() {
    let out = run(&["--help"]);
    let text = String::from_utf8_lossy(&out.stdout);
    for word in ["detect", "synth", "bench"] {
        assert!(text.contains(word), "{word} missing from --help");
    }
    let out = run(&["detect", "--help"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("yuv4mpegpipe") && text.contains("--annotate") && text.contains("--camera")
    );
}

#[test]
fn bench_scores_a_real_set_directory_and_refuses_a_bad_one() {
    // A "real" set made of synthetic frames, so that its truth is known: the bench must read
    // it back and score it as the truth says.
    let dir = scratch("real-set");
    synth(&dir, "png", 6);
    let out = run(&[
        "bench",
        "--json",
        "--no-opencv",
        "--real",
        dir.to_str().expect("utf-8"),
        "--only",
        dir.file_name().and_then(|n| n.to_str()).expect("name"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let set = &report["accuracy"][0];
    assert_eq!(set["generator"], "real");
    assert_eq!(set["ours"]["accuracy"]["frames"], 6);
    assert_eq!(set["ours"]["accuracy"]["within_2deg"], 1.0, "{set}");
    // Its frames are files: ours was timed on each right after decoding it, as OpenCV is.
    assert_eq!(
        report["speed"][0]["ours_timed_after_decoding"], true,
        "{report}"
    );
    // A truth file that does not match the frames: one line, exit 2.
    std::fs::write(
        dir.join("truth.csv"),
        "frame,roll_deg,pitch_deg,visible\n0,1,2,1\n",
    )
    .expect("write");
    let out = run(&[
        "bench",
        "--no-opencv",
        "--real",
        dir.to_str().expect("utf-8"),
    ]);
    assert_input_error(&out, "6 frames but 1 truth lines");
}

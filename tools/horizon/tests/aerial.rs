//! The third generator, `aerial` (tools/horizon/aerial_set.py, held out from all tuning):
//! its geometry is the conventions' line, and `bench --real` scores what it writes.
//!
//! The interpreter is `python3`, or `SKYFRAME_HORIZON_PYTHON` (numpy and OpenCV, as for the
//! baseline: see tests/opencv.rs).

mod common;

use common::{binary, python, score_real, succeeded};
use std::path::PathBuf;
use std::process::Command;

fn script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("aerial_set.py")
}

#[test]
fn aerial_rays_fall_on_the_ground_side_of_the_conventions_line() {
    let out = Command::new(python())
        .arg(script())
        .arg("--check")
        .output()
        .expect("runs python");
    let stdout = succeeded(out);
    assert!(
        stdout.contains("0 of 200 rays on the wrong side"),
        "{stdout}"
    );
}

#[test]
fn bench_scores_an_aerial_set_against_its_truth() {
    let dir = std::env::temp_dir().join(format!("skyframe-aerial-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(python())
        .arg(script())
        .args(["--out", dir.to_str().expect("utf-8 path")])
        .args([
            "--seed", "7", "--frames", "3", "--sizes", "320x240", "--only", "clean",
        ])
        .output()
        .expect("runs python");
    succeeded(out);
    let set = dir.join("clean_320");
    let truth = std::fs::read_to_string(set.join("truth.csv")).expect("truth.csv");
    assert_eq!(truth.lines().count(), 4, "{truth}");

    let accuracy = score_real(&set, "clean_320");
    let pooled = pool_twice(&dir, &set);
    let _ = std::fs::remove_dir_all(&dir);
    // A clear horizon on every frame of this seed: the detector, which never saw this
    // generator, finds each within 5°. A truth written on the wrong side, with the wrong sign
    // or in the wrong pixel frame would put them tens of degrees off.
    assert_eq!(accuracy["within_5deg"], 1.0, "{accuracy}");

    // The same report pooled as two seeds: twice the frames, the bench's own shares (the
    // pooled counts are the shares times the frames, divided back), two seeds scored.
    let set = &pooled["sets"][0];
    assert_eq!(set["set"], "clean_320", "{pooled}");
    assert_eq!(set["frames"], 6, "{pooled}");
    assert_eq!(
        set["visible"],
        2 * accuracy["visible"].as_u64().expect("visible")
    );
    for key in [
        "within_1deg",
        "within_2deg",
        "within_5deg",
        "false_confident_rate",
    ] {
        let (got, bench) = (set[key].as_f64(), accuracy[key].as_f64());
        assert!(
            matches!((got, bench), (Some(g), Some(b)) if (g - b).abs() < 1e-9),
            "{key}: pooled {got:?}, bench {bench:?}"
        );
    }
    assert_eq!(set["seeds_with_visible_horizon"], 2, "{pooled}");
    assert!(
        set["opencv_within_2deg"].is_null(),
        "no OpenCV run: {pooled}"
    );
}

/// `tools/horizon/pool_bench.py --json` over the bench report of `set` given twice; also
/// checks that a file that is not a report is refused with exit code 2, naming the file.
fn pool_twice(dir: &std::path::Path, set: &std::path::Path) -> serde_json::Value {
    let out = binary()
        .args(["bench", "--json", "--no-opencv", "--generator", "synth"])
        .args(["--only", "clean_320", "--frames", "1", "--sizes", "320x240"])
        .arg("--real")
        .arg(set)
        .output()
        .expect("runs bench");
    let report = dir.join("report.json");
    std::fs::write(&report, succeeded(out)).expect("writes the report");
    let pool = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("pool_bench.py");
    let out = Command::new(python())
        .arg(&pool)
        .args([&report, &report])
        .arg("--json")
        .output()
        .expect("runs python");
    let pooled = serde_json::from_str(&succeeded(out)).expect("JSON");

    let not_a_report = dir.join("truth-not-report.json");
    std::fs::write(&not_a_report, "{\"accuracy\": 3}").expect("writes");
    let out = Command::new(python())
        .arg(&pool)
        .arg(&not_a_report)
        .output()
        .expect("runs python");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.lines().count() == 1 && stderr.contains("truth-not-report.json"),
        "{stderr}"
    );
    pooled
}

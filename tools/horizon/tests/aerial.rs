//! The third generator, `aerial` (tools/horizon/aerial_set.py, held out from all tuning):
//! its geometry is the conventions' line, and `bench --real` scores what it writes.
//!
//! The interpreter is `python3`, or `SKYFRAME_HORIZON_PYTHON` (numpy and OpenCV, as for the
//! baseline: see tests/opencv.rs).

mod common;

use common::{python, score_real, succeeded};
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
    let _ = std::fs::remove_dir_all(&dir);
    // A clear horizon on every frame of this seed: the detector, which never saw this
    // generator, finds each within 5°. A truth written on the wrong side, with the wrong sign
    // or in the wrong pixel frame would put them tens of degrees off.
    assert_eq!(accuracy["within_5deg"], 1.0, "{accuracy}");
}

//! What the integration tests that run the bench and the Python tools share. Each test file
//! uses part of it.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// The bench binary.
pub fn binary() -> Command {
    Command::new(env!("CARGO_BIN_EXE_skyframe-horizon"))
}

/// The interpreter: `python3`, or `SKYFRAME_HORIZON_PYTHON` (numpy and the pinned OpenCV; a
/// virtual environment where the system's has another OpenCV).
pub fn python() -> String {
    std::env::var("SKYFRAME_HORIZON_PYTHON").unwrap_or_else(|_| "python3".into())
}

/// The standard output of a run that must have succeeded (else its output and errors).
pub fn succeeded(out: Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// `detect`'s CSV for the set `dir`, read with its own camera file.
pub fn detect_set(dir: &Path) -> String {
    succeeded(
        binary()
            .arg("detect")
            .arg(dir)
            .arg("--camera")
            .arg(dir.join("camera.toml"))
            .output()
            .expect("runs detect"),
    )
}

/// `bench --real`'s accuracy of our detector on the set `dir`, whose name is `name`.
pub fn score_real(dir: &Path, name: &str) -> serde_json::Value {
    let out = binary()
        .args(["bench", "--json", "--no-opencv", "--generator", "synth"])
        .args(["--only", name, "--frames", "1", "--sizes", "320x240"])
        .arg("--real")
        .arg(dir)
        .output()
        .expect("runs bench");
    let report: serde_json::Value = serde_json::from_str(&succeeded(out)).expect("JSON");
    let sets = report["accuracy"].as_array().expect("accuracy");
    sets.iter()
        .find(|s| s["generator"] == "real" && s["set"] == name)
        .unwrap_or_else(|| panic!("no set {name} in {report}"))["ours"]["accuracy"]
        .clone()
}

//! The OpenCV comparison of `skyframe-horizon bench` runs (CI installs the pinned
//! opencv-python-headless, `.ci/run`): both detectors' angles against the truth on one set.
//!
//! The interpreter is `python3`, or `SKYFRAME_HORIZON_PYTHON` where the system one has another
//! OpenCV (e.g. a virtual environment with the pin).

mod common;

use common::{binary, python};

fn f64_at(v: &serde_json::Value, path: &[&str]) -> f64 {
    path.iter()
        .fold(v, |v, k| &v[*k])
        .as_f64()
        .unwrap_or_else(|| panic!("{path:?} is not a number in {v}"))
}

#[test]
fn bench_compares_with_the_pinned_opencv_on_the_same_frames() {
    let out = binary()
        .args([
            "bench",
            "--json",
            "--frames",
            "8",
            "--seed",
            "4",
            "--generator",
            "synth",
            "--only",
            "clean",
            "--sizes",
            "320x240",
            "--python",
            &python(),
        ])
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "bench: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(report["opencv_version"], "4.10.0", "{report}");
    let set = &report["accuracy"][0];
    assert_eq!(set["set"], "clean");
    // Both answered the clean frames with the truth's angles: ours within 2° on every frame,
    // OpenCV's Canny + Hough (1° bins) on most, and neither with a pitch bias over 0.5°.
    assert_eq!(
        f64_at(set, &["ours", "accuracy", "within_2deg"]),
        1.0,
        "{set}"
    );
    assert!(
        f64_at(set, &["opencv", "accuracy", "within_2deg"]) >= 0.75,
        "{set}"
    );
    for who in ["ours", "opencv"] {
        let bias = f64_at(set, &[who, "accuracy", "pitch_median_signed_deg"]);
        assert!(bias.abs() < 0.5, "{who}: pitch bias {bias}°");
        assert!(f64_at(set, &[who, "ms_median"]) > 0.0);
    }
    let speed = &report["speed"][0];
    assert!(f64_at(speed, &["speedup_median"]) > 0.0, "{speed}");
    // Both timed each frame right after decoding its file.
    assert_eq!(speed["ours_timed_after_decoding"], true, "{speed}");
}

#[test]
fn another_opencv_major_version_is_refused_in_one_line() {
    // A stand-in interpreter that reports OpenCV 5 to the bench's probe.
    let dir = std::env::temp_dir().join(format!("skyframe-horizon-opencv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch dir");
    let fake = dir.join("python");
    std::fs::write(&fake, "#!/bin/sh\nprintf 5.0.0\n").expect("write");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    }
    // Another test's child, forked while the script was open for writing, can hold it open
    // until that child execs: running the script then fails with ETXTBSY ("Text file busy")
    // for a moment, and the bench says the interpreter cannot be run. Tried again; a probe
    // that never runs still fails below.
    let run = || {
        binary()
            .args(["bench", "--frames", "1", "--python"])
            .arg(&fake)
            .output()
            .expect("runs")
    };
    let mut out = run();
    for _ in 0..20 {
        if !String::from_utf8_lossy(&out.stderr).contains("the OpenCV baseline needs") {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
        out = run();
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("OpenCV 5.0.0") && stderr.contains("4.10.0.84"),
        "{stderr}"
    );
    assert!(out.stdout.is_empty());
}

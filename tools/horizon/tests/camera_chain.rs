//! A tuning set passed through a real camera-and-link chain (tools/horizon/camera_chain.py:
//! a Bayer sensor demosaicked by OpenCV, an analogue link, libjpeg at half resolution), and
//! the bench's score of what comes out.
//!
//! The interpreter is `python3`, or `SKYFRAME_HORIZON_PYTHON` (numpy and OpenCV, as for the
//! baseline: see tests/opencv.rs).

mod common;

use common::{binary, detect_set, python, score_real, succeeded};
use std::path::{Path, PathBuf};
use std::process::Command;

fn script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("camera_chain.py")
}

fn h264_script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("h264_link.py")
}

/// `frames` frames of `terrain` `clean` of `seed` at `size` (`WIDTHxHEIGHT`), kept by the bench
/// under `dir`: the set's directory.
fn rendered_clean(dir: &Path, seed: u32, size: &str, frames: u32) -> PathBuf {
    rendered(dir, ("terrain", "clean"), seed, size, frames)
}

/// `frames` frames of a tuning generator's class (`(generator, class)`) of `seed` at `size`,
/// kept by the bench under `dir`: the set's directory.
fn rendered(
    dir: &Path,
    (generator, class): (&str, &str),
    seed: u32,
    size: &str,
    frames: u32,
) -> PathBuf {
    let _ = std::fs::remove_dir_all(dir);
    let out = binary()
        .args(["bench", "--json", "--generator", generator, "--seed"])
        .arg(seed.to_string())
        .args(["--only", class, "--sizes", size, "--frames"])
        .arg(frames.to_string())
        .args(["--python", &python(), "--keep"])
        .arg(dir)
        .output()
        .expect("runs bench");
    succeeded(out);
    dir.join(format!("{generator}-{class}-{size}"))
}

/// `terrain` `clean` of `seed` at `size` (`WIDTHxHEIGHT`), 40 frames, passed through the chain's
/// `stages` with `chain_seed`: `bench --real`'s accuracy of what comes out.
fn chained(seed: u32, size: &str, stages: &str, chain_seed: u32) -> serde_json::Value {
    let dir = std::env::temp_dir().join(format!(
        "skyframe-chain-test-{}-{seed}-{chain_seed}",
        std::process::id()
    ));
    let rendered = rendered_clean(&dir, seed, size, 40);
    let chained = dir.join("chain_clean");
    pass_through_chain(&rendered, &chained, stages, chain_seed);
    let accuracy = score_real(&chained, "chain_clean");
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!("{accuracy}");
    accuracy
}

/// Passes the set `input` through the chain's `stages` with `chain_seed` into `output`.
fn pass_through_chain(input: &Path, output: &Path, stages: &str, chain_seed: u32) {
    succeeded(
        Command::new(python())
            .arg(script())
            .arg(input)
            .arg(output)
            .args(["--stages", stages, "--seed", &chain_seed.to_string()])
            .output()
            .expect("runs python"),
    );
}

/// At least `min_within` of the frames within 2°, and false confidence at most 0.05.
fn assert_read_or_not_trusted(accuracy: &serde_json::Value, min_within: f64) {
    let within = accuracy["within_2deg"].as_f64().expect("within_2deg");
    let false_confident = accuracy["false_confident_rate"]
        .as_f64()
        .expect("false_confident_rate");
    assert!(within >= min_within, "{within} within 2°");
    assert!(
        false_confident <= 0.05,
        "{false_confident} false confidence"
    );
}

/// `terrain` `clean` seed 16 at 320×240 through the whole chain (chain seed 34): the Bayer
/// noise and the link's jitter scatter the binned image's edge points across the hazy
/// horizon, and its line was 2–8° off in roll on a quarter of the frames, trusted on six.
/// The halves of the full-resolution profile find the edge on either side of such a line:
/// it is turned to them (`profile::place`), or trusted less when no clearer line runs
/// through them. Within 2° 0.53 → 0.65, false confidence 0.15 → 0.00 (the turn alone: 0.65,
/// 0.075). Later changes left it at 0.60; a seam a link spliced no longer chosen (see `seam`)
/// read frame 30 and lost 34 and 38 here, 0.575, while it won 106 frames of the 20238 seen
/// ones. The bar stays above the 0.53 without the turn.
#[test]
fn a_hazy_horizon_through_a_sensor_and_two_links_is_read_or_not_trusted() {
    assert_read_or_not_trusted(
        &chained(16, "320x240", "bayer,analogue,jpeg-half", 34),
        0.55,
    );
}

/// `terrain` `clean` seed 18 at 640×480 through libjpeg (chain seed 123): slices of 16 rows
/// lost and concealed with the previous frame's splice the frame along block rows, and the
/// splice was taken for a level horizon, trusted on four frames (`seam`). False confidence
/// 0.125 → 0.025 (0.10 with the turn and the contradicted-roll term only).
#[test]
fn a_slice_concealed_from_the_previous_frame_is_not_trusted_as_a_level_horizon() {
    assert_read_or_not_trusted(&chained(18, "640x480", "jpeg", 123), 0.6);
}

/// `terrain` `clean` seed 18 at 320×240 through the analogue link at the `interference`
/// class's full amplitude (chain seed 605: 10 levels, 34 px, crests bent by the chirp and
/// shaken by the line timebase): its crests are no family of straight lines, the hazy
/// horizon's edge points scatter, and the line chosen was a compromise 9–25° off on half
/// the frames (21 of 40 within 2°, none trusted). The pattern is a spike in the working
/// image's spectrum, notched out before the edges are found (`interference`): 34 of 40,
/// 27 trusted (9 before).
#[test]
fn a_bent_shaken_interference_pattern_is_notched_out_of_a_hazy_horizon() {
    assert_read_or_not_trusted(&chained(18, "320x240", "interference", 605), 0.8);
}

/// `synth` `calm-sea` seed 1 at 320×240 through the whole chain (chain seeds 1 and 2). Its
/// frames 24–31 look steeply down at the shore, the horizon out of view: a sea seen from
/// above is darker than its fields, so it is not trusted as a sky unless its brightest part
/// glows as a sky does (`sky_outshines_ground`). The chain's speckle lifted the sea's
/// brightest tenth to the fields' median, and two of those frames were trusted on each
/// chain seed; the sea stays far under the fields' own brightest part.
#[test]
fn a_sea_seen_from_above_through_the_chain_is_not_trusted_as_a_sky() {
    let dir = std::env::temp_dir().join(format!("skyframe-chain-test-{}-sea", std::process::id()));
    let set = rendered(&dir, ("synth", "calm-sea"), 1, "320x240", 40);
    for chain_seed in [1, 2] {
        let chained = dir.join(format!("chain_{chain_seed}"));
        pass_through_chain(&set, &chained, "bayer,analogue,jpeg-half", chain_seed);
        let csv = detect_set(&chained);
        let truth = std::fs::read_to_string(chained.join("truth.csv")).expect("truth.csv");
        let out_of_view: Vec<&str> = truth
            .lines()
            .skip(1)
            .filter(|l| l.ends_with(",0"))
            .filter_map(|l| l.split(',').next())
            .collect();
        assert_eq!(out_of_view.len(), 8, "frames with the horizon out of view");
        let trusted: Vec<&str> = csv
            .lines()
            .skip(1)
            .filter(|l| {
                let f: Vec<&str> = l.split(',').collect();
                matches!((f.first(), f.get(3)), (Some(frame), Some(confidence))
                    if out_of_view.contains(frame)
                        && confidence
                            .parse::<f32>()
                            .is_ok_and(|c| c >= skyframe_horizon::accuracy::gate()))
            })
            .collect();
        assert!(
            trusted.is_empty(),
            "chain seed {chain_seed}: trusted {trusted:?}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs the chain on `input` with `stages`; its exit code and standard error.
fn chain(input: &Path, stages: &str) -> (Option<i32>, String) {
    chain_with(input, &["--stages", stages])
}

/// Runs the chain on `input` with `args`; its exit code and standard error.
fn chain_with(input: &Path, args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(python())
        .arg(script())
        .arg(input)
        .arg(input.join("out"))
        .args(args)
        .output()
        .expect("runs python");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn the_chain_says_in_one_line_why_it_refuses() {
    let dir = std::env::temp_dir().join(format!("skyframe-chain-bad-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    let not_a_set = chain(&dir, "bayer");
    std::fs::write(dir.join("camera.toml"), "width = 320\n").expect("write");
    std::fs::write(dir.join("truth.csv"), "frame,roll_deg,pitch_deg\n").expect("write");
    let no_frames = chain(&dir, "bayer");
    let unknown_stage = chain(&dir, "bayer,fog");
    let two_analogue_links = chain(&dir, "analogue,interference");
    let backwards_quality = chain_with(&dir, &["--stages", "jpeg", "--jpeg-quality", "30,4"]);
    let _ = std::fs::remove_dir_all(&dir);
    for ((code, stderr), says) in [
        (not_a_set, "camera.toml: missing"),
        (no_frames, "no frame_NNNNNN.png frames"),
        (unknown_stage, "unknown stage 'fog'"),
        (two_analogue_links, "analogue and interference are one link"),
        (
            backwards_quality,
            "--jpeg-quality '30,4': want LOWEST,HIGHEST",
        ),
    ] {
        assert_eq!(code, Some(1), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(says), "{stderr}");
    }
}

/// The held-out H.264 link (tools/horizon/h264_link.py, only scored): a clear link (no slice
/// lost) passes every frame, at its size, and the bench reads them back against the truth.
#[test]
fn an_h264_link_passes_a_set_the_bench_scores() {
    let dir = std::env::temp_dir().join(format!("skyframe-h264-test-{}", std::process::id()));
    let rendered = rendered_clean(&dir, 16, "320x240", 6);
    let linked = dir.join("h264_clean");
    let out = Command::new(python())
        .arg(h264_script())
        .arg(rendered)
        .arg(&linked)
        .args(["--crf", "30", "--loss", "0", "--seed", "1"])
        .output()
        .expect("runs python");
    succeeded(out);
    let frames = std::fs::read_dir(&linked)
        .expect("output")
        .filter(|e| {
            e.as_ref()
                .is_ok_and(|e| e.file_name().to_string_lossy().starts_with("frame_"))
        })
        .count();
    let accuracy = score_real(&linked, "h264_clean");
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(frames, 6);
    assert_eq!(accuracy["frames"], 6, "{accuracy}");
    assert_eq!(accuracy["within_5deg"], 1.0, "{accuracy}");
}

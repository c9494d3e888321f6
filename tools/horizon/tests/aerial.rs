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
        "usable",
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

    // Speed is pooled by the target's measure, each seed's ratio of median frame times, with
    // the ratio of means beside it: two seeds, one under 2× by medians and over it by means.
    let mut timed: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("reads")).expect("JSON");
    let seeds = [(1.5, 2.5), (2.2, 2.1)].map(|(median, mean)| {
        timed["speed"] = serde_json::json!([{"size": "320x240", "frames": 40,
            "ours_ms_mean": 1.0, "ours_ms_median": 1.0, "opencv_ms_mean": mean,
            "opencv_ms_median": median, "speedup_mean": mean, "speedup_median": median}]);
        let path = dir.join(format!("timed-{median}.json"));
        std::fs::write(&path, timed.to_string()).expect("writes");
        path
    });
    let out = Command::new(python())
        .arg(&pool)
        .args(&seeds)
        .arg("--json")
        .output()
        .expect("runs python");
    let speed: serde_json::Value = serde_json::from_str(&succeeded(out)).expect("JSON");
    let speed = &speed["speed"][0];
    assert_eq!(speed["speedup_lowest"], 1.5, "{speed}");
    assert_eq!(speed["seeds_under_2x"], 1, "{speed}");
    assert_eq!(speed["speedup_of_means_lowest"], 2.1, "{speed}");
    assert_eq!(speed["seeds_under_2x_by_means"], 0, "{speed}");

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

    let fuzzed = dir.join("fuzzed.json");
    // Fuzzed: the real report with values replaced, keys dropped, bytes cut or flipped. Each
    // is pooled in one Python process; each must be pooled or refused (exit 2), never raise.
    let out = Command::new(python())
        .arg("-c")
        .arg(FUZZ_POOL)
        .arg(&pool)
        .arg(&report)
        .arg(&fuzzed)
        .output()
        .expect("runs python");
    // Each refusal is one short line of its own: the file, and why in a few words.
    let refusals = String::from_utf8_lossy(&out.stderr).into_owned();
    let stdout = succeeded(out);
    assert!(stdout.contains("400 fuzzed reports, 0 raised"), "{stdout}");
    assert!(
        refusals
            .lines()
            .all(|l| l.starts_with("pool_bench: ") && l.len() <= 220 + fuzzed.as_os_str().len()),
        "{refusals}"
    );
    pooled
}

/// The fuzzing of `pool_bench.py` (arguments: the script, a real report, a scratch file).
const FUZZ_POOL: &str = r#"
import importlib.util, json, random, sys
spec = importlib.util.spec_from_file_location("pool_bench", sys.argv[1])
pb = importlib.util.module_from_spec(spec); spec.loader.exec_module(pb)
text = open(sys.argv[2], "rb").read(); scratch = sys.argv[3]; rng = random.Random(7)
odd = [None, True, -1, 1e309, "x", [], {}, [1, 2], {"a": 1}, 3.5, "", 0]
def nodes(v, out):
    if isinstance(v, dict):
        for k in list(v): out.append((v, k)); nodes(v[k], out)
    elif isinstance(v, list):
        for i in range(len(v)): out.append((v, i)); nodes(v[i], out)
    return out
raised = 0
for n in range(400):
    if n % 4 == 3:
        b = bytearray(text)
        for _ in range(rng.randint(1, 8)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        data = bytes(b[: rng.randrange(len(b) + 1)]) if n % 8 == 7 else bytes(b)
    else:
        doc = json.loads(text)
        for _ in range(rng.randint(1, 4)):
            parent, key = rng.choice(nodes(doc, []))
            if rng.random() < 0.3 and isinstance(parent, dict):
                del parent[key]
            else:
                parent[key] = rng.choice(odd)
        data = json.dumps(doc).encode()
    open(scratch, "wb").write(data)
    try:
        rows, speed = pb.pool([scratch])
        pb.as_markdown(pb.as_json(rows, speed, 1))
    except SystemExit as e:
        if e.code != 2:
            raised += 1; print("exit", e.code, file=sys.stderr)
    except Exception as e:
        raised += 1; print(repr(e), file=sys.stderr)
print(f"400 fuzzed reports, {raised} raised")
"#;

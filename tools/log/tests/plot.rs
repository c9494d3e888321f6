//! `plot` on flights encoded with the core's encoders (docs/log-streams.md): the report's
//! files, their image sizes and contents, its interval statistics, and `--series` errors.

#[allow(dead_code)] // shared with cli.rs and ulog.rs: each test crate uses part of it
mod common;
#[allow(dead_code)] // shared with flight_ulog.rs: each test crate uses part of it
mod flight;

use std::path::Path;

use common::{skyframe_log, stderr};
use flight::{SECONDS, StreamFile, gps_times_ns, write_flight, write_gps};
use skyframe_core::logfmt::{LogFormat, Value};

const FIGURES: [&str; 6] = [
    "gps_validity",
    "gps_track",
    "gps_accuracy",
    "intervals",
    "imu_rates_vs_aileron",
    "battery",
];

fn s(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

/// Width and height from a PNG's signature and IHDR chunk.
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(
        &bytes[..8],
        b"\x89PNG\r\n\x1a\n",
        "{}: not a PNG",
        path.display()
    );
    assert_eq!(&bytes[12..16], b"IHDR", "{}: no IHDR first", path.display());
    let w = u32::from_be_bytes(bytes[16..20].try_into().expect("4 bytes"));
    let h = u32::from_be_bytes(bytes[20..24].try_into().expect("4 bytes"));
    (w, h)
}

/// Decodes a PNG and counts the pixels of exactly `rgb`.
fn count_pixels(path: &Path, rgb: [u8; 3]) -> usize {
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(path).expect("open"),
    ));
    let mut reader = decoder.read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("png data");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf[..info.buffer_size()]
        .chunks_exact(3)
        .filter(|p| *p == rgb)
        .count()
}

/// The first series colour of the figures.
const FIRST_COLOUR: [u8; 3] = [31, 119, 180];

#[test]
fn report_writes_every_figure_with_right_sizes_and_series() {
    let dir = tempfile::tempdir().expect("temp dir");
    let flight = dir.path().join("flight");
    std::fs::create_dir(&flight).expect("mkdir");
    write_flight(&flight);
    let out = dir.path().join("report");
    let output = skyframe_log(&[
        "plot",
        s(&flight),
        "--report",
        s(&out),
        "--json",
        "--size",
        "800x600",
    ]);
    assert_eq!(output.status.code(), Some(0), "stderr: {}", stderr(&output));
    assert_eq!(stderr(&output), "");
    for name in FIGURES {
        let png = out.join(format!("{name}.png"));
        assert_eq!(png_size(&png), (800, 600), "{name}");
        assert!(
            count_pixels(&png, FIRST_COLOUR) > 50,
            "{name}: no series drawn"
        );
        let svg = std::fs::read_to_string(out.join(format!("{name}.svg"))).expect("svg");
        assert!(svg.starts_with("<svg"), "{name}");
        assert!(svg.contains(r#"width="800""#) && svg.contains(r#"height="600""#));
    }
    let svg = |name: &str| std::fs::read_to_string(out.join(format!("{name}.svg"))).expect("svg");
    for (figure, names) in [
        ("gps_validity", &["valid", "quality", "satellites"][..]),
        ("gps_track", &["east (m)", "north (m)"][..]),
        (
            "gps_accuracy",
            &["pdop", "hdop", "vdop", "sd_n_m", "sd_e_m", "sd_d_m"][..],
        ),
        (
            "imu_rates_vs_aileron",
            &["p_rad_s", "q_rad_s", "r_rad_s", "aileron"][..],
        ),
        ("battery", &["batt_avionics_v", "batt_servo_v"][..]),
        (
            "intervals",
            &[
                "executive.1: mean 10.0 ms",
                "imu.1: mean 10.0 ms",
                "imu.2: mean 1000.0 ms",
                "gps.1: mean",
                "servo.1: mean 20.0 ms",
                "servo.2: mean 20.0 ms",
            ][..],
        ),
    ] {
        let text = svg(figure);
        for name in names {
            assert!(text.contains(name), "{figure}.svg lacks {name}");
        }
    }

    // The interval statistics, against the times the GPS records were written at.
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).expect("json");
    let times = gps_times_ns();
    let diffs: Vec<f64> = times
        .windows(2)
        .map(|w| (w[1] - w[0]) as f64 / 1e6)
        .collect();
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    let max = diffs.iter().copied().fold(0.0, f64::max);
    assert!((mean - 140.0).abs() < 2.0, "the test flight's GPS: {mean}");
    assert_eq!(max, 300.0);
    let intervals = summary["intervals"].as_array().expect("intervals");
    let gps = intervals
        .iter()
        .find(|i| i["stream"] == "gps" && i["index"] == 1)
        .expect("gps.1 statistics");
    assert_eq!(gps["records"], times.len());
    assert_eq!(gps["intervals"], diffs.len());
    assert!((gps["mean_ms"].as_f64().expect("mean") - mean).abs() < 1e-6);
    assert!((gps["max_ms"].as_f64().expect("max") - max).abs() < 1e-6);
    assert!((gps["min_ms"].as_f64().expect("min") - 30.0).abs() < 1e-6);
    let imu = intervals
        .iter()
        .find(|i| i["stream"] == "imu" && i["index"] == 1)
        .expect("imu.1 statistics");
    assert_eq!(imu["records"], SECONDS * 100);
    assert!((imu["mean_ms"].as_f64().expect("mean") - 10.0).abs() < 1e-6);
    assert!((imu["max_ms"].as_f64().expect("max") - 10.0).abs() < 1e-6);
    let streams: Vec<String> = intervals
        .iter()
        .map(|i| format!("{}.{}", i["stream"].as_str().expect("name"), i["index"]))
        .collect();
    assert_eq!(
        streams,
        [
            "executive.1",
            "gps.1",
            "imu.1",
            "imu.2",
            "servo.1",
            "servo.2"
        ]
    );
    assert_eq!(summary["skipped"], serde_json::json!({}));
    assert_eq!(summary["figures"].as_object().expect("figures").len(), 6);
}

#[test]
fn report_skips_figures_whose_streams_are_missing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let flight = dir.path().join("flight");
    std::fs::create_dir(&flight).expect("mkdir");
    write_gps(&flight);
    let out = dir.path().join("report");
    let output = skyframe_log(&["plot", s(&flight), "--report", s(&out)]);
    assert_eq!(output.status.code(), Some(0), "stderr: {}", stderr(&output));
    let err = stderr(&output);
    let notes: Vec<&str> = err.lines().collect();
    assert_eq!(notes.len(), 2, "{err}");
    assert!(notes[0].starts_with("skyframe-log: note: imu_rates_vs_aileron skipped: no imu.bin"));
    assert!(notes[1].starts_with("skyframe-log: note: battery skipped: no servo.bin"));
    for name in ["gps_validity", "gps_track", "gps_accuracy", "intervals"] {
        assert_eq!(png_size(&out.join(format!("{name}.png"))), (1280, 960));
        assert!(out.join(format!("{name}.svg")).is_file());
    }
    for name in ["imu_rates_vs_aileron", "battery"] {
        assert!(!out.join(format!("{name}.png")).exists());
    }
}

#[test]
fn a_damaged_stream_still_plots_and_exits_3() {
    let dir = tempfile::tempdir().expect("temp dir");
    let flight = dir.path().join("flight");
    std::fs::create_dir(&flight).expect("mkdir");
    write_flight(&flight);
    // Power lost mid-write: the IMU log ends in half a record.
    let imu = flight.join("imu.bin");
    let bytes = std::fs::read(&imu).expect("read");
    std::fs::write(&imu, &bytes[..bytes.len() - 12 - 20]).expect("write");
    let out = dir.path().join("report");
    let output = skyframe_log(&["plot", s(&flight), "--report", s(&out)]);
    assert_eq!(output.status.code(), Some(3), "stderr: {}", stderr(&output));
    assert!(
        stderr(&output).contains("imu.bin: offset"),
        "{}",
        stderr(&output)
    );
    assert!(out.join("imu_rates_vs_aileron.png").is_file());
}

#[test]
fn series_plot_to_png_and_svg() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_flight(dir.path());
    let svg = dir.path().join("rates.svg");
    let output = skyframe_log(&[
        "plot",
        s(dir.path()),
        "--series",
        "imu.p,servo.aileron",
        "--series",
        "imu.2.supply_v",
        "-o",
        s(&svg),
    ]);
    assert_eq!(output.status.code(), Some(0), "stderr: {}", stderr(&output));
    let text = std::fs::read_to_string(&svg).expect("svg");
    for name in ["imu.p_rad_s", "servo.aileron", "imu.supply_v", "time (s)"] {
        assert!(text.contains(name), "svg lacks {name}");
    }
    // One file: its stream is the file stem.
    let png = dir.path().join("q.png");
    let output = skyframe_log(&[
        "plot",
        s(&dir.path().join("imu.bin")),
        "--series",
        "imu.q",
        "-o",
        s(&png),
        "--size",
        "640x480",
    ]);
    assert_eq!(output.status.code(), Some(0), "stderr: {}", stderr(&output));
    assert_eq!(png_size(&png), (640, 480));
    assert!(count_pixels(&png, FIRST_COLOUR) > 50);
}

#[test]
fn series_errors_name_the_series_and_exit_2() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_flight(dir.path());
    let out = dir.path().join("out.png");
    let run = |file: &Path, series: &str, out: &Path| {
        let output = skyframe_log(&["plot", s(file), "--series", series, "-o", s(out)]);
        let err = stderr(&output);
        assert_eq!(output.status.code(), Some(2), "{series}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists(), "{series}: an image was written");
        err
    };
    let err = run(dir.path(), "imu.p,imu.pitch", &out);
    assert!(err.contains("unknown column 'pitch'"), "{err}");
    assert!(err.contains("imu.bin"), "{err}");
    assert!(err.contains("p_rad_s (format 1)"), "{err}");
    assert!(err.contains("mean_fz_m_s2 (format 2)"), "{err}");

    // Only a unit may be left out: `sd` is no column of gps.bin.
    let err = run(dir.path(), "gps.sd", &out);
    assert!(err.contains("unknown column 'sd'"), "{err}");
    assert!(err.contains("sd_n_m (format 1)"), "{err}");

    // The same column in two formats needs the index.
    const A: LogFormat = LogFormat::new("%.3f,%u", "x_m,n");
    const B: LogFormat = LogFormat::new("%.1f", "x_m");
    let mut twin = StreamFile::new(&[(1, A), (2, B)]);
    twin.record(1, &A, 0, &[Value::F32(1.0), Value::U32(1)]);
    twin.record(2, &B, 5, &[Value::F32(2.0)]);
    twin.finish(&dir.path().join("twin.bin"));
    let err = run(dir.path(), "twin.x", &out);
    assert!(
        err.contains("column 'x' is ambiguous: x_m (format 1), x_m (format 2)"),
        "{err}"
    );
    assert!(err.contains("<stream>.<index>.<column>"), "{err}");
    let output = skyframe_log(&["plot", s(dir.path()), "--series", "twin.2.x", "-o", s(&out)]);
    assert_eq!(output.status.code(), Some(0), "stderr: {}", stderr(&output));
    std::fs::remove_file(&out).expect("written");

    let err = run(dir.path(), "camera.roll_deg", &out);
    assert!(err.contains("unknown stream 'camera'"), "{err}");
    assert!(err.contains("executive, gps, imu, servo, twin"), "{err}");

    let err = run(&dir.path().join("imu.bin"), "gps.valid", &out);
    assert!(err.contains("unknown stream 'gps'"), "{err}");

    let err = run(dir.path(), "imu", &out);
    assert!(err.contains("series 'imu'"), "{err}");

    let err = run(dir.path(), "imu.p", &dir.path().join("out.jpg"));
    assert!(
        err.contains("out.jpg") && err.contains(".png or .svg"),
        "{err}"
    );

    let err = run(&dir.path().join("nothing"), "imu.p", &out);
    assert!(err.contains("nothing: no such file or directory"), "{err}");
}

#[test]
fn a_text_log_written_with_the_core_equals_the_conversion() {
    use skyframe_core::logfmt::{ByteWrite, Time, write_data_line, write_header};

    struct Text(Vec<u8>);
    impl std::fmt::Write for Text {
        fn write_str(&mut self, s: &str) -> std::fmt::Result {
            self.0.extend_from_slice(s.as_bytes());
            Ok(())
        }
    }
    impl ByteWrite for Text {
        fn write_byte(&mut self, byte: u8) -> std::fmt::Result {
            self.0.push(byte);
            Ok(())
        }
    }

    let dir = tempfile::tempdir().expect("temp dir");
    write_gps(dir.path());
    let out = dir.path().join("csv");
    let output = skyframe_log(&[
        "to-csv",
        s(&dir.path().join("gps.bin")),
        "--out-dir",
        s(&out),
    ]);
    assert_eq!(output.status.code(), Some(0), "stderr: {}", stderr(&output));
    let converted = std::fs::read(out.join("gps.1.csv")).expect("csv");

    // What the GPS task would write as a text log, directly.
    let format = flight::GPS.parse().expect("format");
    let mut text = Text(Vec::new());
    write_header(&mut text, 1, flight::GPS.format, Some(flight::GPS.columns)).expect("header");
    let bytes = std::fs::read(dir.path().join("gps.bin")).expect("bin");
    let mut reader = Box::new(skyframe_core::logfmt::LogReader::new());
    let mut lines = 0;
    skyframe_core::logfmt::read_slice(&mut reader, &bytes, |event| {
        if let skyframe_core::logfmt::Event::Record {
            record: skyframe_core::logfmt::Record::DataBlock { time, data, .. },
            ..
        } = event
        {
            let time: Time = time;
            write_data_line(&mut text, time, flight::GPS.format, &format, data).expect("line");
            lines += 1;
        }
    });
    assert_eq!(lines, gps_times_ns().len());
    assert_eq!(
        String::from_utf8_lossy(&text.0),
        String::from_utf8_lossy(&converted)
    );
    assert!(
        String::from_utf8_lossy(&converted).contains("\n1700000003.360000000,1,1,9,"),
        "a data line as log-format.md spells it"
    );
}

#[test]
fn extreme_values_and_many_formats_plot_without_panicking() {
    let dir = tempfile::tempdir().expect("temp dir");
    const WILD: LogFormat = LogFormat::new("%lf,%f,%llu", "x_m,y_m,n");
    let mut wild = StreamFile::new(&[(1, WILD)]);
    let values = [
        (f64::MAX, f32::MAX, u64::MAX),
        (-f64::MAX, f32::MIN, 0),
        (f64::INFINITY, f32::NEG_INFINITY, 1),
        (f64::NAN, f32::NAN, 2),
        (1e-300, 1e-30, 3),
    ];
    // Times that go backwards, too.
    for (i, (x, y, n)) in values.into_iter().enumerate() {
        let t_ns = [5, 1, 3, 3, 0][i] * 1_000_000;
        wild.record(
            1,
            &WILD,
            t_ns,
            &[Value::F64(x), Value::F32(y), Value::U64(n)],
        );
    }
    wild.finish(&dir.path().join("wild.bin"));
    // One stream of 40 formats, one record each: more interval panels than fit.
    let formats: Vec<(u8, LogFormat)> = (1..=40u8)
        .map(|i| (i, LogFormat::new("%hhu", "v")))
        .collect();
    let mut many = StreamFile::new(&formats);
    for (i, format) in &formats {
        many.record(*i, format, u64::from(*i) * 1_000, &[Value::U8(*i)]);
        many.record(*i, format, u64::from(*i) * 2_000, &[Value::U8(*i)]);
    }
    many.finish(&dir.path().join("many.bin"));

    let out = dir.path().join("report");
    let output = skyframe_log(&["plot", s(dir.path()), "--report", s(&out), "--json"]);
    let err = stderr(&output);
    assert_eq!(output.status.code(), Some(0), "stderr: {err}");
    assert!(err.contains("intervals: 11 of 41 formats drawn"), "{err}");
    assert_eq!(png_size(&out.join("intervals.png")), (1280, 960));
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).expect("json");
    assert_eq!(summary["intervals"].as_array().expect("list").len(), 41);
    for series in ["wild.x", "wild.y", "wild.n"] {
        let svg = dir.path().join("wild.svg");
        let output = skyframe_log(&["plot", s(dir.path()), "--series", series, "-o", s(&svg)]);
        assert_eq!(
            output.status.code(),
            Some(0),
            "{series}: {}",
            stderr(&output)
        );
        let png = dir.path().join("wild.png");
        let output = skyframe_log(&["plot", s(dir.path()), "--series", series, "-o", s(&png)]);
        assert_eq!(
            output.status.code(),
            Some(0),
            "{series}: {}",
            stderr(&output)
        );
    }
}

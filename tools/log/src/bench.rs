//! `bench`: how fast `to-csv` converts, and how much smaller the binary log is than its text,
//! on a synthetic flight of the shipped streams (`docs/log-streams.md`) at their real rates;
//! in the same run, PX4's `ulog2csv` (pyulog) on the ULog export of the same flight (one
//! ULog for the flight, as `to-ulog FLIGHT_DIR` writes it, with the skyframe topics only: the
//! same records to-csv converts, none of the derived PX4 topics).
//!
//! Throughput is MB (10⁶ bytes) of binary log in per second of wall time, the fastest of
//! `--runs` conversions of the whole flight directory, in this process (no progress bar).
//! The ratio is `ulog2csv` seconds over `to-csv` seconds for the same flight: how many times
//! longer pyulog takes (its Python start-up included, once, as a user meets it).
//! A second ratio leaves the start-up out: pyulog's `convert_ulog2csv` timed inside one warm
//! Python process.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use serde::Serialize;
use skyframe_core::logfmt::frame_records::FRAME_FIXED_FORMAT;
use skyframe_core::logfmt::{
    Format, Value, encode_begin_data, encode_data_block, encode_end_data, encode_format_comment,
    encode_format_definition,
};

use crate::Outcome;

const FRAME_TASKS: [&str; 5] = ["imu", "gps", "servo", "health", "logger"];

/// One shipped format, as docs/log-streams.md lists it, and how often it is logged.
struct Shipped {
    stream: &'static str,
    index: u8,
    format: String,
    columns: String,
    /// Records per second.
    rate_hz: u32,
}

fn shipped() -> Vec<Shipped> {
    let s = |stream, index, format: &str, columns: &str, rate_hz| Shipped {
        stream,
        index,
        format: format.to_string(),
        columns: columns.to_string(),
        rate_hz,
    };
    let frame_format = format!("{FRAME_FIXED_FORMAT}{}", ",%u".repeat(FRAME_TASKS.len()));
    let frame_columns = format!(
        "frame,release_ns,start_latency_ns,work_ns,overhead_ns,missed_before,ran_mask,\
         over_budget_mask,over_frame_mask,skipped_mask,reset_mask,flags{}",
        FRAME_TASKS
            .iter()
            .map(|t| format!(",exec_ns_{t}"))
            .collect::<String>()
    );
    vec![
        s("executive", 1, &frame_format, &frame_columns, 100),
        s(
            "imu",
            1,
            "%hhu,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%hhu",
            "counter,p_rad_s,q_rad_s,r_rad_s,fx_m_s2,fy_m_s2,fz_m_s2,status",
            100,
        ),
        s(
            "imu",
            2,
            "%hu,%.2f,%.3f,%hu,%.5f,%.5f,%.5f,%.4f,%.4f,%.4f,%hu",
            "record_counter,temperature_c,supply_v,serial_number,mean_p_rad_s,mean_q_rad_s,\
             mean_r_rad_s,mean_fx_m_s2,mean_fy_m_s2,mean_fz_m_s2,built_in_test",
            1,
        ),
        s(
            "gps",
            1,
            "%hhu,%hhu,%hhu,%.8lf,%.8lf,%.3lf,%.3f,%.3f,%.3f,%.2f,%.2f,%.2f,%.3f,%.3f,%.3f,%u",
            "valid,quality,satellites,lat_deg,lon_deg,alt_m,vn_m_s,ve_m_s,vd_m_s,pdop,hdop,\
             vdop,sd_n_m,sd_e_m,sd_d_m,utc_ms",
            10,
        ),
        s(
            "servo",
            1,
            "%hhu,%hu,%hu,%hu,%hu,%hu,%hu,%hu,%hu,%hhu,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f",
            "counter,ch1_us,ch2_us,ch3_us,ch4_us,ch5_us,ch6_us,ch7_us,ch8_us,auto,aileron,\
             elevator,throttle,rudder,batt_avionics_v,batt_servo_v",
            50,
        ),
        s(
            "servo",
            2,
            "%hhu,%.3f,%.3f,%.3f,%.3f",
            "ready,aileron_cmd,elevator_cmd,throttle_cmd,rudder_cmd",
            50,
        ),
        s(
            "health",
            1,
            "%hhu,%hhu,%hhu,%hhu,%hhu,%llu,%u,%u,%u,%u,%u,%u,%.1f,%.1f,%u",
            "task,initialised,running,in_frame,alive,releases,overruns_budget,overruns_frame,\
             overruns_missed,skipped,resets,faults,exec_mean_us,exec_max_us,log_dropped",
            // One record per task per second.
            FRAME_TASKS.len() as u32,
        ),
    ]
}

/// A small deterministic noise source.
struct Noise(u64);

impl Noise {
    /// Uniform in [-1, 1).
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// Plausible values of record `n` (at `t` s) of a shipped format.
fn values(spec: &Shipped, n: u64, t: f64, noise: &mut Noise) -> Vec<Value> {
    let f = |x: f64| Value::F32(x as f32);
    let wave = |period: f64, amp: f64| amp * (std::f64::consts::TAU * t / period).sin();
    match (spec.stream, spec.index) {
        ("executive", _) => {
            let mut v = vec![
                Value::U64(n),
                Value::U64(n * 10_000_000),
                Value::U32(20_000 + (noise.next().abs() * 30_000.0) as u32),
                Value::U32(2_500_000 + (noise.next().abs() * 900_000.0) as u32),
                Value::U32(40_000 + (noise.next().abs() * 9_000.0) as u32),
                Value::U32(0),
                Value::U32(if n % 10 == 0 { 0b11111 } else { 0b00101 }),
                Value::U32(0),
                Value::U32(0),
                Value::U32(0),
                Value::U32(0),
                Value::U8(0),
            ];
            for _ in FRAME_TASKS {
                v.push(Value::U32(
                    150_000 + (noise.next().abs() * 600_000.0) as u32,
                ));
            }
            v
        }
        ("imu", 1) => vec![
            Value::U8((n % 256) as u8),
            f(wave(4.0, 0.6) + 0.02 * noise.next()),
            f(wave(7.0, 0.2) + 0.02 * noise.next()),
            f(wave(11.0, 0.1) + 0.02 * noise.next()),
            f(0.3 * noise.next()),
            f(0.3 * noise.next()),
            f(-9.80665 + 0.5 * noise.next()),
            Value::U8(0),
        ],
        ("imu", _) => vec![
            Value::U16((n % 65_536) as u16),
            f(31.5 + noise.next()),
            f(5.01 + 0.01 * noise.next()),
            Value::U16(4242),
            f(0.001 * noise.next()),
            f(0.001 * noise.next()),
            f(0.001 * noise.next()),
            f(0.01 * noise.next()),
            f(0.01 * noise.next()),
            f(-9.80665 + 0.01 * noise.next()),
            Value::U16(0),
        ],
        // The first second without a fix, as a receiver starts.
        ("gps", _) if n < 10 => vec![
            Value::U8(0),
            Value::U8(0),
            Value::U8(2),
            Value::F64(f64::NAN),
            Value::F64(f64::NAN),
            Value::F64(f64::NAN),
            f(f64::NAN),
            f(f64::NAN),
            f(f64::NAN),
            f(99.99),
            f(99.99),
            f(99.99),
            f(f64::NAN),
            f(f64::NAN),
            f(f64::NAN),
            Value::U32(((43_200.0 + t) * 1000.0) as u32),
        ],
        ("gps", _) => vec![
            Value::U8(1),
            Value::U8(1),
            Value::U8(9),
            Value::F64(45.0623 + wave(300.0, 0.004)),
            Value::F64(7.6624 + wave(280.0, 0.005)),
            Value::F64(260.0 + wave(120.0, 40.0)),
            f(wave(300.0, 20.0)),
            f(wave(280.0, 20.0)),
            f(0.5 * noise.next()),
            f(1.8 + 0.1 * noise.next()),
            f(0.9 + 0.1 * noise.next()),
            f(1.5 + 0.1 * noise.next()),
            f(1.2 + 0.2 * noise.next()),
            f(1.1 + 0.2 * noise.next()),
            f(2.5 + 0.3 * noise.next()),
            Value::U32(((43_200.0 + t) * 1000.0) as u32),
        ],
        ("servo", 1) => {
            let mut v = vec![Value::U8((n % 256) as u8)];
            for ch in 0..8u32 {
                let us = 1500.0 + wave(3.0 + f64::from(ch), 400.0);
                v.push(Value::U16(us as u16));
            }
            v.extend([
                Value::U8(u8::from(t > 60.0)),
                f(wave(4.0, 0.8)),
                f(wave(7.0, 0.5)),
                f(0.6 + wave(30.0, 0.3)),
                f(wave(11.0, 0.3)),
                f(12.3 - t * 1e-4 + 0.02 * noise.next()),
                f(7.9 - t * 3e-4 + 0.1 * noise.next()),
            ]);
            v
        }
        ("servo", _) => vec![
            Value::U8(1),
            f(wave(4.0, 0.7)),
            f(wave(7.0, 0.4)),
            f(0.6 + wave(30.0, 0.3)),
            f(wave(11.0, 0.2)),
        ],
        _ => {
            let task = n % FRAME_TASKS.len() as u64;
            let second = n / FRAME_TASKS.len() as u64;
            vec![
                Value::U8(task as u8),
                Value::U8(1),
                Value::U8(1),
                Value::U8(0),
                Value::U8(1),
                Value::U64(second * 100),
                Value::U32(0),
                Value::U32(0),
                Value::U32(0),
                Value::U32(0),
                Value::U32(0),
                Value::U32(0),
                f(420.0 + 50.0 * noise.next()),
                f(900.0 + 100.0 * noise.next()),
                Value::U32(0),
            ]
        }
    }
}

/// Writes the synthetic flight's streams into `dir`; returns (stream, bytes) per file.
fn synthesise(dir: &Path, seconds: f64) -> Result<Vec<(String, u64)>, String> {
    let specs = shipped();
    let mut streams: Vec<&str> = specs.iter().map(|s| s.stream).collect();
    streams.dedup();
    let mut noise = Noise(0x5eed);
    let start_ns: u64 = 1_700_000_000 * 1_000_000_000;
    let duration_ns = (seconds * 1e9) as u64;
    let mut files = Vec::new();
    let mut buf = vec![0u8; 4096];
    for stream in streams {
        let mut bytes = Vec::new();
        let mine: Vec<&Shipped> = specs.iter().filter(|s| s.stream == stream).collect();
        let mut formats = Vec::new();
        let n = encode_begin_data(&mut buf, start_ns).map_err(|e| format!("{e:?}"))?;
        bytes.extend_from_slice(buf.get(..n).unwrap_or(&[]));
        for spec in &mine {
            let parsed = Format::parse(&spec.format)
                .map_err(|e| format!("{}.{}: {e}", spec.stream, spec.index))?;
            let n = encode_format_definition(&mut buf, spec.index, &spec.format)
                .map_err(|e| format!("{e:?}"))?;
            bytes.extend_from_slice(buf.get(..n).unwrap_or(&[]));
            let n = encode_format_comment(&mut buf, spec.index, &spec.columns)
                .map_err(|e| format!("{e:?}"))?;
            bytes.extend_from_slice(buf.get(..n).unwrap_or(&[]));
            formats.push((spec, parsed));
        }
        // 1 ms ticks; each format at its rate, with up to 0.5 ms of jitter.
        let mut counts = vec![0u64; formats.len()];
        let ticks = duration_ns / 1_000_000;
        for tick in 0..ticks {
            for ((spec, parsed), count) in formats.iter().zip(counts.iter_mut()) {
                let period_ticks = u64::from(1000 / spec.rate_hz.max(1));
                if tick % period_ticks != 0 {
                    continue;
                }
                let jitter = (noise.next().abs() * 500_000.0) as u64;
                let t_ns = start_ns + tick * 1_000_000 + jitter;
                let t = (tick as f64) * 1e-3;
                let vals = values(spec, *count, t, &mut noise);
                let n = encode_data_block(&mut buf, spec.index, t_ns, parsed, &vals)
                    .map_err(|e| format!("{}.{}: {e:?}", spec.stream, spec.index))?;
                bytes.extend_from_slice(buf.get(..n).unwrap_or(&[]));
                *count += 1;
            }
        }
        let n = encode_end_data(&mut buf, start_ns + duration_ns).map_err(|e| format!("{e:?}"))?;
        bytes.extend_from_slice(buf.get(..n).unwrap_or(&[]));
        let path = dir.join(format!("{stream}.bin"));
        std::fs::write(&path, &bytes).map_err(|e| format!("{}: {e}", path.display()))?;
        files.push((stream.to_string(), bytes.len() as u64));
    }
    Ok(files)
}

#[derive(Serialize)]
struct FormatSize {
    stream: String,
    index: u8,
    format: String,
    records: u64,
    binary_bytes_per_record: f64,
    text_bytes_per_record: f64,
    /// 100 · (1 − binary / text).
    saving_percent: f64,
}

#[derive(Serialize)]
struct Timing {
    runs_s: Vec<f64>,
    best_s: f64,
    input_bytes: u64,
    /// MB (10⁶ bytes) of input per second, at the best run.
    mb_per_s: f64,
}

impl Timing {
    fn new(runs_s: Vec<f64>, input_bytes: u64) -> Timing {
        let best_s = runs_s.iter().copied().fold(f64::INFINITY, f64::min);
        Timing {
            mb_per_s: input_bytes as f64 / 1e6 / best_s,
            runs_s,
            best_s,
            input_bytes,
        }
    }
}

#[derive(Serialize)]
struct Ulog2Csv {
    command: String,
    files: usize,
    /// Seconds for all ULog files of the flight (one invocation per file), per run.
    timing: Timing,
    /// One `python3 -c 'import pyulog.ulog2csv'`: the start-up each invocation pays.
    python_import_s: Option<f64>,
    /// pyulog's `convert_ulog2csv` on the same files inside one warm Python process (start-up
    /// excluded): the conversion work alone, best of the runs.
    in_process_best_s: Option<f64>,
}

#[derive(Serialize)]
struct BenchReport {
    profile: &'static str,
    flight_minutes: f64,
    records: u64,
    binary_bytes: u64,
    csv_bytes: u64,
    to_csv: Timing,
    formats: Vec<FormatSize>,
    /// Over all data records: 100 · (1 − binary bytes / text bytes), headers excluded.
    total_saving_percent: f64,
    ulog_bytes: u64,
    ulog2csv: Option<Ulog2Csv>,
    /// Why ulog2csv was not timed, when it was not.
    ulog2csv_unavailable: Option<String>,
    /// ulog2csv best seconds / to-csv best seconds for the same flight (the CLI as a user
    /// runs it, once per ULog file).
    ulog2csv_over_to_csv_time: Option<f64>,
    /// The same without Python's start-up: pyulog's conversion alone / to-csv.
    pyulog_in_process_over_to_csv_time: Option<f64>,
}

/// Data lines and their bytes (newline included) of a CSV file.
fn text_lines(path: &Path) -> Result<(u64, u64), String> {
    let text = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut lines = 0;
    let mut bytes = 0;
    for line in text.split_inclusive(|&b| b == b'\n') {
        if line.first() != Some(&b'%') {
            lines += 1;
            bytes += line.len() as u64;
        }
    }
    Ok((lines, bytes))
}

fn ulog2csv_command() -> Option<Vec<String>> {
    let works = |program: &str, args: &[&str]| {
        Command::new(program)
            .args(args)
            .output()
            .is_ok_and(|o| o.status.success())
    };
    if works("ulog2csv", &["-h"]) {
        Some(vec!["ulog2csv".into()])
    } else if works("python3", &["-m", "pyulog.ulog2csv", "-h"]) {
        Some(vec![
            "python3".into(),
            "-m".into(),
            "pyulog.ulog2csv".into(),
        ])
    } else {
        None
    }
}

/// Times pyulog's converter inside one Python process: the best of `runs` conversions of
/// all `ulogs`, in seconds.
const IN_PROCESS: &str = r#"
import sys, time
from pyulog.ulog2csv import convert_ulog2csv
runs, out, files = int(sys.argv[1]), sys.argv[2], sys.argv[3:]
best = float("inf")
for _ in range(runs):
    start = time.perf_counter()
    for f in files:
        convert_ulog2csv(f, None, out, ",", None, None)
    best = min(best, time.perf_counter() - start)
print(best)
"#;

fn time_pyulog_in_process(ulogs: &[PathBuf], out: &Path, runs: u32) -> Option<f64> {
    let output = Command::new("python3")
        .args(["-c", IN_PROCESS, &runs.to_string()])
        .arg(out)
        .args(ulogs)
        .output()
        .ok()?;
    if !output.status.success() {
        return None;
    }
    // pyulog prints a line per CSV it writes; the time is the last line.
    String::from_utf8_lossy(&output.stdout)
        .lines()
        .last()?
        .trim()
        .parse()
        .ok()
}

fn time_ulog2csv(command: &[String], ulogs: &[PathBuf], out: &Path) -> Result<f64, String> {
    let (program, args) = command
        .split_first()
        .ok_or_else(|| "empty ulog2csv command".to_string())?;
    let start = Instant::now();
    for ulog in ulogs {
        let output = Command::new(program)
            .args(args)
            .arg("-o")
            .arg(out)
            .arg(ulog)
            .output()
            .map_err(|e| format!("{program}: {e}"))?;
        if !output.status.success() {
            return Err(format!(
                "{program} {}: {}",
                ulog.display(),
                String::from_utf8_lossy(&output.stderr).trim()
            ));
        }
    }
    Ok(start.elapsed().as_secs_f64())
}

pub fn run(json: bool, minutes: f64, runs: u32, keep_flight: Option<&Path>) -> Outcome {
    match bench(minutes, runs.max(1), keep_flight) {
        Ok(report) => {
            if json {
                if let Err(e) = crate::print_json(&report) {
                    eprintln!("skyframe-log: {e}");
                    return Outcome::Failed;
                }
            } else if let Err(e) = crate::print_text(&table(&report)) {
                eprintln!("skyframe-log: {e}");
                return Outcome::Failed;
            }
            Outcome::Whole
        }
        Err(message) => {
            eprintln!("skyframe-log: bench: {message}");
            Outcome::Failed
        }
    }
}

fn table(r: &BenchReport) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "synthetic flight: {} min, {} records, {} bytes binary ({} build)",
        r.flight_minutes, r.records, r.binary_bytes, r.profile
    );
    let _ = writeln!(
        out,
        "to-csv: best {:.3} s of {} runs, {:.1} MB/s of binary in, {} bytes of CSV",
        r.to_csv.best_s,
        r.to_csv.runs_s.len(),
        r.to_csv.mb_per_s,
        r.csv_bytes
    );
    let _ = writeln!(
        out,
        "format       records  binary B/rec  text B/rec  saving"
    );
    for f in &r.formats {
        let _ = writeln!(
            out,
            "{:<10} {:>9}  {:>12.1}  {:>10.1}  {:>5.1} %",
            format!("{}.{}", f.stream, f.index),
            f.records,
            f.binary_bytes_per_record,
            f.text_bytes_per_record,
            f.saving_percent
        );
    }
    let _ = writeln!(out, "all records: {:.1} % saving", r.total_saving_percent);
    let _ = match (&r.ulog2csv, r.ulog2csv_over_to_csv_time) {
        (Some(u), Some(ratio)) => writeln!(
            out,
            "ulog2csv ({}): best {:.3} s for {} ULog file(s) ({} bytes, {:.1} MB/s); \
             ulog2csv time / to-csv time = {ratio:.1}{}",
            u.command,
            u.timing.best_s,
            u.files,
            r.ulog_bytes,
            u.timing.mb_per_s,
            match (u.in_process_best_s, r.pyulog_in_process_over_to_csv_time) {
                (Some(s), Some(x)) => format!(
                    "\npyulog's converter in one warm Python process (no start-up): best \
                     {s:.3} s; its time / to-csv time = {x:.1}"
                ),
                _ => String::new(),
            }
        ),
        _ => writeln!(
            out,
            "ulog2csv not timed: {}",
            r.ulog2csv_unavailable.as_deref().unwrap_or("unknown")
        ),
    };
    out
}

fn bench(minutes: f64, runs: u32, keep_flight: Option<&Path>) -> Result<BenchReport, String> {
    if !(minutes > 0.0 && minutes <= 600.0) {
        return Err(format!("--minutes {minutes}: must be in (0, 600]"));
    }
    let temp = tempfile::tempdir().map_err(|e| format!("temporary directory: {e}"))?;
    let flight = temp.path().join("flight");
    let csv = temp.path().join("csv");
    let ulog_dir = temp.path().join("ulog");
    let ulog_csv = temp.path().join("ulog-csv");
    for dir in [&flight, &csv, &ulog_dir, &ulog_csv] {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let files = synthesise(&flight, minutes * 60.0)?;
    let binary_bytes: u64 = files.iter().map(|f| f.1).sum();
    if let Some(keep) = keep_flight {
        std::fs::create_dir_all(keep).map_err(|e| format!("{}: {e}", keep.display()))?;
        for (stream, _) in &files {
            let name = format!("{stream}.bin");
            std::fs::copy(flight.join(&name), keep.join(&name))
                .map_err(|e| format!("{}: {e}", keep.join(&name).display()))?;
        }
    }

    let mut runs_s = Vec::new();
    for _ in 0..runs {
        let start = Instant::now();
        let outcome = crate::to_csv::run_quiet(std::slice::from_ref(&flight), Some(&csv));
        runs_s.push(start.elapsed().as_secs_f64());
        if outcome != Outcome::Whole {
            return Err("to-csv reported problems on the synthetic flight".into());
        }
    }
    let to_csv = Timing::new(runs_s, binary_bytes);

    let mut formats = Vec::new();
    let (mut all_bin, mut all_text, mut records, mut csv_bytes) = (0u64, 0u64, 0u64, 0u64);
    for spec in shipped() {
        let path = csv.join(format!("{}.{}.csv", spec.stream, spec.index));
        let (lines, text) = text_lines(&path)?;
        csv_bytes += std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
        let parsed = Format::parse(&spec.format).map_err(|e| format!("{}: {e}", spec.format))?;
        let bin_per = (12 + parsed.data_len()) as f64;
        let text_per = text as f64 / lines.max(1) as f64;
        all_bin += lines * (12 + parsed.data_len() as u64);
        all_text += text;
        records += lines;
        formats.push(FormatSize {
            stream: spec.stream.into(),
            index: spec.index,
            format: spec.format.clone(),
            records: lines,
            binary_bytes_per_record: bin_per,
            text_bytes_per_record: text_per,
            saving_percent: 100.0 * (1.0 - bin_per / text_per),
        });
    }

    // One ULog for the flight, as `to-ulog FLIGHT_DIR` writes it, but with the skyframe
    // topics only: exactly the records to-csv converts, so both sides convert the same data
    // (the PX4 topics would give pyulog more to do).
    let ulog = ulog_dir.join("flight.ulg");
    let options = crate::to_ulog::UlogOptions {
        px4_topics: false,
        ..Default::default()
    };
    let reported = crate::to_ulog::convert(&flight, &ulog, &options)?;
    if !reported.is_empty() {
        return Err(format!("to-ulog reported: {}", reported.join("; ")));
    }
    let ulog_bytes = std::fs::metadata(&ulog).map(|m| m.len()).unwrap_or(0);
    let ulogs = vec![ulog];
    let (ulog2csv, unavailable) = match ulog2csv_command() {
        None => (
            None,
            Some(
                "neither ulog2csv nor python3 -m pyulog.ulog2csv runs (pip install pyulog)".into(),
            ),
        ),
        Some(command) => {
            let mut runs_s = Vec::new();
            let mut failed = None;
            for _ in 0..runs {
                match time_ulog2csv(&command, &ulogs, &ulog_csv) {
                    Ok(s) => runs_s.push(s),
                    Err(e) => {
                        failed = Some(e);
                        break;
                    }
                }
            }
            match failed {
                Some(e) => (None, Some(e)),
                None => {
                    let start = Instant::now();
                    let import = Command::new("python3")
                        .args(["-c", "import pyulog.ulog2csv"])
                        .status()
                        .ok()
                        .filter(|s| s.success())
                        .map(|_| start.elapsed().as_secs_f64());
                    let in_process = time_pyulog_in_process(&ulogs, &ulog_csv, runs);
                    (
                        Some(Ulog2Csv {
                            command: command.join(" "),
                            files: ulogs.len(),
                            timing: Timing::new(runs_s, ulog_bytes),
                            python_import_s: import,
                            in_process_best_s: in_process,
                        }),
                        None,
                    )
                }
            }
        }
    };
    let ratio = ulog2csv.as_ref().map(|u| u.timing.best_s / to_csv.best_s);
    let in_process_ratio = ulog2csv
        .as_ref()
        .and_then(|u| u.in_process_best_s)
        .map(|s| s / to_csv.best_s);
    Ok(BenchReport {
        profile: if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        },
        flight_minutes: minutes,
        records,
        binary_bytes,
        csv_bytes,
        to_csv,
        formats,
        total_saving_percent: 100.0 * (1.0 - all_bin as f64 / all_text.max(1) as f64),
        ulog_bytes,
        ulog2csv,
        ulog2csv_unavailable: unavailable,
        ulog2csv_over_to_csv_time: ratio,
        pyulog_in_process_over_to_csv_time: in_process_ratio,
    })
}

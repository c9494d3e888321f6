//! `skyframe-log`: reads skyframe's binary flight logs (`shared/specs/log-format.md`), the
//! successor of the thesis's ReadUavLogs.
//!
//! - `info`, `to-csv`, `to-ulog` (one ULog per flight), `to-parquet` (many flights):
//!   summaries and conversions;
//! - `plot FILE --series imu.p,servo.aileron -o out.png|svg`: series against log time;
//! - `plot DIR --report OUT [--json]`: the thesis's standard figures (chapter 6.1.3) of a
//!   flight directory, PNG and SVG, with the interval statistics per stream and format;
//! - `bench [--json]`: `to-csv` throughput and binary-vs-text sizes on a synthetic flight,
//!   against pyulog's `ulog2csv` on its ULog export.
//!
//! Exit status: 0 when every file was whole, 3 when anything was reported (damage, a file not
//! closed cleanly; each report on stderr with the file name and offset), 2 for usage and I/O
//! errors.

mod bench;
mod figure;
mod flight;
mod flightlog;
mod info;
mod input;
mod plot;
mod to_csv;
mod to_parquet;
mod to_ulog;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "skyframe-log",
    version,
    about = "Read skyframe binary flight logs: summarise, convert (CSV, ULog), plot, benchmark",
    long_about = "Read skyframe binary flight logs (shared/specs/log-format.md).\n\n\
        Damaged files (truncated tail, garbage, malformed records) are read as far as \
        possible; every problem is reported on stderr as `FILE: offset N: ...`.\n\n\
        Exit status: 0 every file whole, 3 something was reported, 2 usage or I/O error."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Summarise log files: formats, counts, time span, sessions, damage
    ///
    /// For each file: its formats (index, format string, columns), record counts per format,
    /// time span and largest time step, gaps, Begin/End pairs, whether it was closed cleanly
    /// (a final End Data), and damage with offsets (also on stderr).
    Info {
        /// Binary log files.
        #[arg(required = true, value_name = "FILE")]
        files: Vec<PathBuf>,
        /// List as a gap every pause longer than this between two records of the same format.
        #[arg(long, value_name = "SECONDS", default_value_t = 1.0)]
        gap_s: f64,
    },
    /// Convert log files to CSV, one file per format (Matlab-friendly)
    ///
    /// Writes `<file stem>.<index>.csv` for each format index with data: first the comment
    /// lines `% format <index>: <format string>` and `% time,<columns>`, then one line
    /// `<tv_sec>.<tv_nsec, 9 digits>,<record text>` per record, the text exactly as C's printf
    /// prints it. Files stream through in constant memory.
    ToCsv {
        /// Binary log files, or directories whose files (not `*.csv`, not hidden, not in
        /// subdirectories) are all converted.
        #[arg(required = true, value_name = "FILE|DIR")]
        inputs: Vec<PathBuf>,
        /// Where to write the CSV files (created if missing). Default: beside each input.
        #[arg(long, value_name = "DIR")]
        out_dir: Option<PathBuf>,
    },
    /// Convert a flight (a directory of streams, or one .bin) to one PX4 ULog file
    ///
    /// Every stream of FLIGHT_DIR goes into one ULog on one clock (µs from the flight's
    /// first record). Where a format means what a PX4 topic means, the topic is written with
    /// PX4's name, fields, types and units (sensor_combined, vehicle_gps_position,
    /// vehicle_attitude, vehicle_local_position, vehicle_global_position, actuator_outputs,
    /// input_rc, battery_status, vehicle_status, vehicle_attitude_setpoint, tecs_status, …);
    /// every format is also written as it was logged, as `skyframe_<what>` (skyframe_imu,
    /// skyframe_executive, skyframe_task_timing, skyframe_device_status, …) with its columns
    /// as fields. The control.* parameters (control.bin format 2) are ULog parameters, their
    /// changes parameter messages; mode, estimator and device changes and every damage
    /// report are logged messages; lost records are dropouts. docs/ulog.md has the mapping.
    /// Byte arrays are not converted.
    ToUlog {
        /// A flight directory (its *.bin streams, and text logs <stream>.<index>.csv of
        /// streams flown with --text-log), or one binary log or text log file.
        #[arg(value_name = "FLIGHT_DIR|FILE")]
        input: PathBuf,
        /// The ULog file to write. Default: FLIGHT_DIR/flight.ulg, or FILE with `.ulg`.
        #[arg(short, long, value_name = "OUT.ulg")]
        output: Option<PathBuf>,
        /// The vehicle's id (info `sys_uuid`); the logs do not record it. Default: unknown.
        #[arg(long, value_name = "ID")]
        vehicle_id: Option<String>,
        /// The software version flown, e.g. its git hash (info `ver_sw`); the logs do not
        /// record it. Default: unknown.
        #[arg(long, value_name = "VERSION")]
        ver_sw: Option<String>,
    },
    /// Convert many flights to Parquet: one file per stream and format, a row group per flight
    ///
    /// Writes DIR/<stream>.<index>.parquet with the columns flight_id (the flight
    /// directory's name), vehicle_id, time_ns (log TIME, ns) and the format's columns, typed
    /// as logged (uint8, int16, float32, float64, …). One row group per flight, so a reader
    /// can skip flights. A flight whose format has another layout than the file's goes to
    /// <stream>.<index>-<n>.parquet (noted on stderr). Byte arrays are not converted.
    ToParquet {
        /// Flight directories (their *.bin streams) or binary log files.
        #[arg(required = true, value_name = "FLIGHT_DIR")]
        inputs: Vec<PathBuf>,
        /// Where to write the Parquet files (created if missing).
        #[arg(long, value_name = "DIR")]
        out_dir: PathBuf,
        /// The vehicle id to write in every row (the logs do not record it). Default: unknown.
        #[arg(long, value_name = "ID")]
        vehicle_id: Option<String>,
    },
    /// Plot series against time, or draw a flight's standard figures (`--report`)
    ///
    /// FILE is a flight directory (streams are `<dir>/<stream>.bin`) or one `.bin` file (its
    /// stream is the file stem). A series is `<stream>.<column>` (docs/log-streams.md), the
    /// unit suffix optional when unambiguous (`imu.p` is `imu.p_rad_s`), or
    /// `<stream>.<index>.<column>`. The x axis is the log TIME in seconds from the first
    /// record. Series of one unit share a panel.
    ///
    /// `--report DIR` writes, as PNG and SVG: gps_validity, gps_track (north/east metres
    /// from the first valid fix), gps_accuracy (DOPs, standard deviations), intervals
    /// (between consecutive entries of every stream and format, mean/max in the legend),
    /// imu_rates_vs_aileron, battery. A figure whose streams are missing is skipped with a
    /// note on stderr.
    #[command(group(clap::ArgGroup::new("what").required(true).args(["series", "report"])))]
    Plot {
        /// Flight directory or binary log file.
        #[arg(value_name = "FILE|DIR")]
        file: PathBuf,
        /// Series to plot, comma-separated or repeated: `imu.p,servo.aileron`.
        #[arg(long, value_name = "STREAM.COLUMN", requires = "output")]
        series: Vec<String>,
        /// The image to write; its extension (.png or .svg) chooses the format.
        #[arg(short, long, value_name = "OUT.png|OUT.svg", conflicts_with = "report")]
        output: Option<PathBuf>,
        /// Write the standard figures into this directory (created if missing).
        #[arg(long, value_name = "DIR")]
        report: Option<PathBuf>,
        /// With --report: print a JSON summary (files, skipped figures, interval
        /// statistics per stream and format) on stdout.
        #[arg(long, requires = "report")]
        json: bool,
        /// Image size in pixels.
        #[arg(long, value_name = "WxH", default_value = "1280x960", value_parser = plot::parse_size)]
        size: (u32, u32),
    },
    /// Benchmark: to-csv throughput and binary vs text size on a synthetic flight, against
    /// pyulog's ulog2csv on the ULog export of the same flight
    Bench {
        /// Print the results as JSON (otherwise a table).
        #[arg(long)]
        json: bool,
        /// Minutes of flight to synthesise.
        #[arg(long, value_name = "MINUTES", default_value_t = 10.0)]
        minutes: f64,
        /// Timed runs of each converter; the fastest counts.
        #[arg(long, value_name = "N", default_value_t = 3)]
        runs: u32,
        /// Also keep the synthetic flight's streams in this directory (created if missing),
        /// e.g. to try `plot --report` on them.
        #[arg(long, value_name = "DIR")]
        keep_flight: Option<PathBuf>,
    },
}

/// How a run went, worst first when combined.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Outcome {
    Whole,
    Reported,
    Failed,
}

impl Outcome {
    /// A conversion's outcome: its report lines on stderr, then `Reported` if any is a
    /// problem (anything but a `skyframe-log: note:`), `Whole` if none, `Failed` (with the
    /// error's line) if it did not convert.
    pub fn of_conversion(result: Result<Vec<String>, String>) -> Self {
        match result {
            Ok(lines) => {
                for line in &lines {
                    eprintln!("{line}");
                }
                if lines.iter().any(|l| !l.starts_with("skyframe-log: note:")) {
                    Outcome::Reported
                } else {
                    Outcome::Whole
                }
            }
            Err(e) => {
                eprintln!("skyframe-log: {e}");
                Outcome::Failed
            }
        }
    }

    fn exit_code(self) -> ExitCode {
        match self {
            Outcome::Whole => ExitCode::SUCCESS,
            Outcome::Reported => ExitCode::from(3),
            Outcome::Failed => ExitCode::from(2),
        }
    }
}

/// Prints `value` as pretty JSON on stdout; a closed pipe is an error, not a panic.
pub fn print_json(value: &impl serde::Serialize) -> Result<(), String> {
    use std::io::Write;
    let text = serde_json::to_string_pretty(value).map_err(|e| format!("JSON: {e}"))?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{text}")
        .and_then(|()| out.flush())
        .map_err(|e| format!("stdout: {e}"))
}

/// Prints `text` on stdout; a closed pipe is an error, not a panic.
pub fn print_text(text: &str) -> Result<(), String> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| format!("stdout: {e}"))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = match cli.command {
        Command::Info { files, gap_s } => info::run(&files, gap_s),
        Command::ToCsv { inputs, out_dir } => to_csv::run(&inputs, out_dir.as_deref()),
        Command::ToUlog {
            input,
            output,
            vehicle_id,
            ver_sw,
        } => to_ulog::run(
            &input,
            output.as_deref(),
            &to_ulog::UlogOptions {
                px4_topics: true,
                vehicle_id,
                ver_sw,
            },
        ),
        Command::ToParquet {
            inputs,
            out_dir,
            vehicle_id,
        } => to_parquet::run(&inputs, &out_dir, vehicle_id.as_deref()),
        Command::Plot {
            file,
            series,
            output,
            report,
            json,
            size,
        } => {
            let options = plot::PlotOptions { size };
            match (report, output) {
                (Some(dir), _) => plot::run_report(&file, &dir, json, &options),
                (None, Some(output)) => plot::run_series(&file, &series, &output, &options),
                (None, None) => {
                    eprintln!("skyframe-log: plot: give --series with -o, or --report DIR");
                    Outcome::Failed
                }
            }
        }
        Command::Bench {
            json,
            minutes,
            runs,
            keep_flight,
        } => bench::run(json, minutes, runs, keep_flight.as_deref()),
    };
    outcome.exit_code()
}

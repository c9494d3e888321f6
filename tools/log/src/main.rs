//! `skyframe-log`: reads skyframe's binary flight logs (`shared/specs/log-format.md`), the
//! successor of the thesis's ReadUavLogs.
//!
//! Exit status: 0 when every file was whole, 3 when anything was reported (damage, a file not
//! closed cleanly; each report on stderr with the file name and offset), 2 for usage and I/O
//! errors.

mod info;
mod input;
mod to_csv;
mod to_ulog;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "skyframe-log",
    version,
    about = "Read skyframe binary flight logs: summarise them or convert them to CSV",
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
    /// Convert a log file to a PX4 ULog file
    ///
    /// One ULog message `log_<index>` per format (`log_<index>_<n>` after a redefinition),
    /// with a `timestamp` (µs) and the format's columns as fields. Byte arrays are not
    /// converted.
    ToUlog {
        /// Binary log file.
        #[arg(value_name = "FILE")]
        file: PathBuf,
        /// The ULog file to write.
        #[arg(short, long, value_name = "OUT.ulg")]
        output: PathBuf,
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
    fn exit_code(self) -> ExitCode {
        match self {
            Outcome::Whole => ExitCode::SUCCESS,
            Outcome::Reported => ExitCode::from(3),
            Outcome::Failed => ExitCode::from(2),
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = match cli.command {
        Command::Info { files, gap_s } => info::run(&files, gap_s),
        Command::ToCsv { inputs, out_dir } => to_csv::run(&inputs, out_dir.as_deref()),
        Command::ToUlog { file, output } => to_ulog::run(&file, &output),
    };
    outcome.exit_code()
}

//! skyframe-overrun: the frame-overrun report of a flight, from the executive's per-frame
//! timing records (`executive.bin`), after the flight (`report`) or while it flies (`run`).
//!
//! Exit codes: 0 a whole report; 2 bad usage or unusable input (one line on stderr); 3 the
//! logs are damaged: the report covers what is readable and stderr lists the problems (as
//! skyframe-log does). `run` exits with the child's code when the child failed.

mod plot;
mod read;
mod report;
mod run;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use skyframe_core::logfmt::LogReader;

use read::{Damage, FrameCollector};

#[derive(Parser, Debug)]
#[command(
    name = "skyframe-overrun",
    version,
    about = "Frame-overrun report: task execution times against budgets, frame start latency, IMU-to-servo latency, device sample periods"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Args, Debug, Clone)]
struct Output {
    /// Print the report as JSON instead of a text table.
    #[arg(long)]
    json: bool,
    /// Also draw the figures (PNG and SVG) into DIR: latency_histogram, exec_vs_budget,
    /// worst_frames.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// How many worst frames to list.
    #[arg(long, default_value_t = 5)]
    worst: usize,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Report on a flight: its directory, or an executive.bin.
    Report {
        /// A flight directory (flights/<UTC>/) or an executive.bin.
        input: PathBuf,
        #[command(flatten)]
        output: Output,
    },
    /// Run a flight command, follow its timing records live, report when it ends.
    ///
    /// The flight directory is the new subdirectory of the command's --log-dir (default
    /// `flights`) that appears after the start, or the one the command prints as
    /// "flight directory: ...". The child's output goes to stderr; the report to stdout.
    /// Ctrl-C stops the flight cleanly (the interrupt is passed on) and still reports.
    Run {
        #[command(flatten)]
        output: Output,
        /// The command, after `--`: e.g. `-- skyframe sim --duration 10`.
        #[arg(last = true, required = true)]
        command: Vec<String>,
    },
}

/// How a report ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    Whole,
    Damaged,
    Failed,
}

impl Outcome {
    fn code(self) -> ExitCode {
        match self {
            Outcome::Whole => ExitCode::SUCCESS,
            Outcome::Failed => ExitCode::from(2),
            Outcome::Damaged => ExitCode::from(3),
        }
    }
}

/// The executive log and flight directory of a `report` input.
fn locate(input: &Path) -> Result<(PathBuf, Option<PathBuf>), String> {
    if input.is_dir() {
        let exec = input.join("executive.bin");
        if !exec.is_file() {
            return Err(format!(
                "{}: not a flight directory: no executive.bin",
                input.display()
            ));
        }
        Ok((exec, Some(input.to_path_buf())))
    } else if input.is_file() {
        Ok((input.to_path_buf(), input.parent().map(Path::to_path_buf)))
    } else {
        Err(format!("{}: no such file or directory", input.display()))
    }
}

/// Finishes a report from collected frames: device logs, figures, output. Damage goes to
/// stderr.
pub fn finish(
    exec_path: &Path,
    dir: Option<&Path>,
    collector: FrameCollector,
    output: &OutputOptions,
) -> Outcome {
    if !collector.found_format() {
        eprintln!(
            "{}: no executive timing records (no frame log format in the file)",
            exec_path.display()
        );
        return Outcome::Failed;
    }
    let mut damage: Vec<Damage> = collector.damage;
    let mut devices = Vec::new();
    if let Some(dir) = dir {
        let mut reader = LogReader::new();
        let (found, mut more, unreadable) = read::read_devices(dir, &mut reader);
        devices = found;
        damage.append(&mut more);
        for line in unreadable {
            damage.push(Damage {
                path: dir.to_path_buf(),
                line,
            });
        }
    }
    for d in &damage {
        eprintln!("{}", d.line);
    }
    let report = report::build(&report::Input {
        source: exec_path.display().to_string(),
        tasks: &collector.tasks,
        frames: &collector.frames,
        devices: &devices,
        worst: output.worst,
        damaged: !damage.is_empty(),
    });
    if output.json {
        match serde_json::to_string_pretty(&report) {
            Ok(json) => println!("{json}"),
            Err(e) => {
                eprintln!("cannot write the JSON report: {e}");
                return Outcome::Failed;
            }
        }
    } else {
        print!("{}", report::text(&report));
    }
    if let Some(plot_dir) = &output.plot
        && let Err(e) = plot::draw_all(plot_dir, &report, &collector.frames, &collector.tasks)
    {
        eprintln!("{e}");
        return Outcome::Failed;
    }
    if damage.is_empty() {
        Outcome::Whole
    } else {
        eprintln!(
            "{}: damaged logs: the report covers the readable records",
            exec_path.display()
        );
        Outcome::Damaged
    }
}

/// What the report prints and draws.
#[derive(Clone, Debug)]
pub struct OutputOptions {
    pub json: bool,
    pub plot: Option<PathBuf>,
    pub worst: usize,
}

impl From<Output> for OutputOptions {
    fn from(o: Output) -> Self {
        Self {
            json: o.json,
            plot: o.plot,
            worst: o.worst,
        }
    }
}

fn report_command(input: &Path, output: &OutputOptions) -> Outcome {
    let (exec, dir) = match locate(input) {
        Ok(found) => found,
        Err(e) => {
            eprintln!("{e}");
            return Outcome::Failed;
        }
    };
    let mut collector = FrameCollector::new(&exec);
    let mut reader = LogReader::new();
    if let Err(e) = read::read_file(&exec, &mut reader, |event| collector.event(event)) {
        eprintln!("{}: cannot read: {e}", exec.display());
        return Outcome::Failed;
    }
    finish(&exec, dir.as_deref(), collector, output)
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    match cli.command {
        Command::Report { input, output } => report_command(&input, &output.into()).code(),
        Command::Run { output, command } => run::run(&command, &output.into()),
    }
}

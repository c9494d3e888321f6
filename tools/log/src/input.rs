//! Feeding files through the core's streaming reader, with a progress bar on a terminal.

use std::io::{self, IsTerminal};
use std::path::{Path, PathBuf};

use indicatif::{ProgressBar, ProgressStyle};
use skyframe_core::logfmt::{Event, LogReader};

/// The files named on the command line, directories expanded to their files (sorted, not
/// hidden, not recursive) — the seed's "convert every log here" batch script — less what a
/// flight directory holds that is not a binary log: CSV (text logs, conversions), ULog and
/// Parquet (conversions), JSON (the
/// simulator's `score.json`), the link key, TOML (vehicle and scenario files). Such a file is still read when named itself.
pub fn expand(inputs: &[PathBuf]) -> Result<Vec<PathBuf>, String> {
    let mut files = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let entries = std::fs::read_dir(input)
                .map_err(|e| format!("{}: cannot list directory: {e}", input.display()))?;
            let mut found = Vec::new();
            for entry in entries {
                let path = entry
                    .map_err(|e| format!("{}: cannot list directory: {e}", input.display()))?
                    .path();
                let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
                let hidden = name.as_deref().is_none_or(|n| n.starts_with('.'));
                let not_a_log = path.extension().is_some_and(|e| {
                    ["csv", "json", "key", "toml", "ulg", "parquet"]
                        .iter()
                        .any(|skip| e.eq_ignore_ascii_case(skip))
                });
                if path.is_file() && !hidden && !not_a_log {
                    found.push(path);
                }
            }
            if found.is_empty() {
                // Nothing to convert is a mistake (a wrong directory), not a success.
                return Err(format!(
                    "{}: no log files in this directory (binary logs; CSV, ULog, Parquet, JSON, \
                     keys and TOML are skipped)",
                    input.display()
                ));
            }
            found.sort();
            files.extend(found);
        } else {
            files.push(input.clone());
        }
    }
    Ok(files)
}

/// A progress bar over the bytes of all files, drawn only when stderr is a terminal.
pub fn progress_bar(files: &[PathBuf]) -> ProgressBar {
    if !io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let total = files
        .iter()
        .filter_map(|f| std::fs::metadata(f).ok())
        .map(|m| m.len())
        .sum();
    let bar = ProgressBar::new(total);
    if let Ok(style) = ProgressStyle::with_template(
        "{spinner} [{elapsed_precise}] {wide_bar} {bytes}/{total_bytes} ({bytes_per_sec}, {eta}) {msg}",
    ) {
        bar.set_style(style);
    }
    bar
}

/// Prints a line on stderr without tearing the progress bar.
pub fn report_line(bar: &ProgressBar, line: &str) {
    bar.suspend(|| eprintln!("{line}"));
}

pub use skyframe_logtable::problem_line;

/// Streams `path` through a fresh reader, calling `on_event` for every event in file order.
/// Memory stays constant: the reader's window is the only buffer.
pub fn read_file(
    path: &Path,
    reader: &mut LogReader,
    bar: &ProgressBar,
    on_event: impl FnMut(Event<'_>),
) -> io::Result<()> {
    skyframe_logtable::read_file(path, reader, |n| bar.inc(n as u64), on_event)
}

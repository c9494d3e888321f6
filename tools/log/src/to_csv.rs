//! `to-csv`: one CSV per format index, exactly as `log-format.md` ("Text logs and CSV
//! conversion") says.

use std::collections::HashMap;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use indicatif::ProgressBar;
use skyframe_core::logfmt::{
    Event, Format, LogReader, Record, RenderError, write_byte_array_line, write_data_line,
    write_header,
};
use skyframe_logtable::CsvLine;

use crate::Outcome;
use crate::input::{expand, problem_line, progress_bar, read_file, report_line};

const INDEXES: usize = 256;

pub fn run(inputs: &[PathBuf], out_dir: Option<&Path>) -> Outcome {
    convert(inputs, out_dir, true)
}

/// [`run`] without a progress bar, for timing it (`bench`).
pub fn run_quiet(inputs: &[PathBuf], out_dir: Option<&Path>) -> Outcome {
    convert(inputs, out_dir, false)
}

fn convert(inputs: &[PathBuf], out_dir: Option<&Path>, progress: bool) -> Outcome {
    let files = match expand(inputs) {
        Ok(files) => files,
        Err(message) => {
            eprintln!("skyframe-log: {message}");
            return Outcome::Failed;
        }
    };
    if let Some(dir) = out_dir {
        if let Err(e) = std::fs::create_dir_all(dir) {
            eprintln!(
                "skyframe-log: {}: cannot create directory: {e}",
                dir.display()
            );
            return Outcome::Failed;
        }
    }
    let bar = if progress {
        progress_bar(&files)
    } else {
        ProgressBar::hidden()
    };
    let mut reader = Box::new(LogReader::new());
    let mut outcome = Outcome::Whole;
    // Output name prefix → the input that writes it: two inputs of the same stem would
    // overwrite each other's CSVs.
    let mut prefixes: HashMap<PathBuf, PathBuf> = HashMap::new();
    for file in &files {
        let dir = match out_dir {
            Some(dir) => dir.to_path_buf(),
            None => match file.parent() {
                Some(parent) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
                _ => PathBuf::from("."),
            },
        };
        let stem = file
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let prefix = dir.join(&stem);
        if let Some(other) = prefixes.get(&prefix) {
            report_line(
                &bar,
                &format!(
                    "skyframe-log: {}: skipped: its CSVs would overwrite those of {} ({}.*.csv)",
                    file.display(),
                    other.display(),
                    prefix.display()
                ),
            );
            outcome = outcome.max(Outcome::Failed);
            continue;
        }
        prefixes.insert(prefix, file.clone());
        bar.set_message(file.display().to_string());
        let mut converter = Converter::new(file, dir, stem, &bar);
        let read = read_file(file, &mut reader, &bar, |event| converter.on_event(event));
        let result = read.and_then(|()| converter.flush());
        match result {
            Ok(()) if converter.reported => outcome = outcome.max(Outcome::Reported),
            Ok(()) => {}
            Err(e) => {
                report_line(&bar, &format!("skyframe-log: {}: {e}", file.display()));
                outcome = outcome.max(Outcome::Failed);
            }
        }
    }
    bar.finish_and_clear();
    outcome
}

/// One open CSV and the header it last printed.
struct CsvOut {
    writer: BufWriter<File>,
    /// The format version its header lines describe.
    version: u64,
    header: Option<(String, Option<String>)>,
}

/// The conversion of one file.
struct Converter<'a> {
    path: &'a Path,
    dir: PathBuf,
    stem: String,
    bar: &'a ProgressBar,
    formats: Vec<Option<String>>,
    comments: Vec<Option<String>>,
    /// Bumped at every Format Definition or Comment of the index.
    versions: Vec<u64>,
    outputs: Vec<Option<CsvOut>>,
    line: CsvLine,
    reported: bool,
    /// The first write error; writing stops there.
    error: Option<io::Error>,
}

impl<'a> Converter<'a> {
    fn new(path: &'a Path, dir: PathBuf, stem: String, bar: &'a ProgressBar) -> Self {
        Self {
            path,
            dir,
            stem,
            bar,
            formats: vec![None; INDEXES],
            comments: vec![None; INDEXES],
            versions: vec![0; INDEXES],
            outputs: (0..INDEXES).map(|_| None).collect(),
            line: CsvLine::default(),
            reported: false,
            error: None,
        }
    }

    fn on_event(&mut self, event: Event<'_>) {
        match event {
            Event::Problem(problem) => {
                self.reported = true;
                report_line(self.bar, &problem_line(self.path, &problem));
            }
            Event::Record { offset, record } => match record {
                Record::FormatDefinition { index, text, .. } => {
                    self.set(index, |c| &mut c.formats, text);
                }
                Record::FormatComment { index, text } => {
                    self.set(index, |c| &mut c.comments, text);
                }
                Record::DataBlock {
                    index,
                    time,
                    data,
                    format,
                } => self.write_record(offset, index, format, |out, text, format| {
                    write_data_line(out, time, text, format, data)
                }),
                Record::ByteArray {
                    index,
                    time,
                    bytes,
                    format,
                    ..
                } => self.write_record(offset, index, format, |out, text, format| {
                    write_byte_array_line(out, time, text, format, bytes)
                }),
                Record::BeginData { .. } | Record::EndData { .. } => {}
            },
        }
    }

    fn set(&mut self, index: u8, field: fn(&mut Self) -> &mut Vec<Option<String>>, text: &[u8]) {
        let slot = usize::from(index);
        if let Some(value) = field(self).get_mut(slot) {
            *value = Some(String::from_utf8_lossy(text).into_owned());
        }
        if let Some(version) = self.versions.get_mut(slot) {
            *version += 1;
        }
    }

    fn write_record(
        &mut self,
        offset: u64,
        index: u8,
        format: &Format,
        render: impl FnOnce(&mut CsvLine, &str, &Format) -> Result<(), RenderError>,
    ) {
        if self.error.is_some() {
            return;
        }
        let slot = usize::from(index);
        // Borrowed, not cloned: this runs once per record (two allocations per record were
        // a measurable share of to-csv's time).
        let text = self
            .formats
            .get(slot)
            .and_then(|t| t.as_deref())
            .unwrap_or_default();
        self.line.0.clear();
        if render(&mut self.line, text, format).is_err() {
            // The reader only yields records that match their format; this is a defect.
            self.reported = true;
            report_line(
                self.bar,
                &format!(
                    "{}: offset {offset}: record of format {index} could not be rendered",
                    self.path.display()
                ),
            );
            return;
        }
        if let Err(e) = self.write_line(slot, index) {
            self.error = Some(e);
        }
    }

    fn write_line(&mut self, slot: usize, index: u8) -> io::Result<()> {
        let version = self.versions.get(slot).copied().unwrap_or(0);
        let output = self
            .outputs
            .get_mut(slot)
            .ok_or_else(|| io::Error::other("format index out of range"))?;
        if output.is_none() {
            let path = self.dir.join(format!("{}.{index}.csv", self.stem));
            let file = File::create(&path)
                .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
            *output = Some(CsvOut {
                writer: BufWriter::with_capacity(64 * 1024, file),
                version: u64::MAX,
                header: None,
            });
        }
        let Some(out) = output.as_mut() else {
            return Err(io::Error::other("output not open"));
        };
        if out.version != version {
            out.version = version;
            // A redefinition that changes nothing (a task re-declaring its formats when it
            // restarts) prints no new header.
            let text = self
                .formats
                .get(slot)
                .cloned()
                .flatten()
                .unwrap_or_default();
            let comment = self.comments.get(slot).cloned().flatten();
            let header = (text, comment);
            if out.header.as_ref() != Some(&header) {
                let mut lines = String::new();
                write_header(&mut lines, index, &header.0, header.1.as_deref())
                    .map_err(|_| io::Error::other("header could not be formatted"))?;
                out.writer.write_all(lines.as_bytes())?;
                out.header = Some(header);
            }
        }
        out.writer.write_all(&self.line.0)
    }

    fn flush(&mut self) -> io::Result<()> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        for out in self.outputs.iter_mut().flatten() {
            out.writer.flush()?;
        }
        Ok(())
    }
}

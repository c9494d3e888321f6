//! A flight's streams loaded into columns, for `plot`: every data block's fields as `f64`,
//! every record's time, per stream and format index (`docs/log-streams.md`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use indicatif::ProgressBar;
use skyframe_core::logfmt::{Event, LogReader, Record, Time, Value};

use crate::input::{problem_line, read_file, report_line};

/// A record's time in ns (`tv_sec · 10⁹ + tv_nsec`).
pub fn time_ns(time: Time) -> i64 {
    i64::from(time.sec) * 1_000_000_000 + i64::from(time.nsec)
}

/// The records of one format index of a stream.
#[derive(Debug, Default)]
pub struct Table {
    pub index: u8,
    /// The format string last in force.
    pub format_text: String,
    /// Column names (from the Format Comment; `field<n>` where it has none). A redefinition
    /// that adds columns appends them; rows without a column hold NaN there.
    pub columns: Vec<String>,
    /// One entry per data block or byte array, in file order.
    pub times_ns: Vec<i64>,
    /// Which Begin Data session each entry belongs to (0 before the first Begin Data).
    pub sessions: Vec<u32>,
    /// `values[c][row]`; byte arrays add a row of NaN.
    pub values: Vec<Vec<f64>>,
}

impl Table {
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        let c = self.columns.iter().position(|n| n == name)?;
        self.values.get(c).map(Vec::as_slice)
    }

    fn push_row(&mut self, time: Time, session: u32, layout: &[String], row: &[f64]) {
        let mut filled = vec![false; self.columns.len()];
        let rows = self.times_ns.len();
        for (name, &value) in layout.iter().zip(row) {
            let c = match self.columns.iter().position(|n| n == name) {
                Some(c) => c,
                None => {
                    self.columns.push(name.clone());
                    self.values.push(vec![f64::NAN; rows]);
                    filled.push(false);
                    self.columns.len() - 1
                }
            };
            if let (Some(column), Some(done)) = (self.values.get_mut(c), filled.get_mut(c)) {
                if !*done {
                    column.push(value);
                    *done = true;
                }
            }
        }
        for (column, done) in self.values.iter_mut().zip(&filled) {
            if !done {
                column.push(f64::NAN);
            }
        }
        self.times_ns.push(time_ns(time));
        self.sessions.push(session);
    }
}

/// One stream: a binary log file and its tables by format index.
#[derive(Debug)]
pub struct Stream {
    pub name: String,
    pub path: PathBuf,
    pub tables: BTreeMap<u8, Table>,
    /// Problems the reader reported (each already printed on stderr).
    pub problems: usize,
}

impl Stream {
    /// The time of the first record with a time, in ns.
    pub fn first_time_ns(&self) -> Option<i64> {
        self.tables
            .values()
            .filter_map(|t| t.times_ns.first().copied())
            .min()
    }
}

/// The stream name of a file: its stem (`imu.bin` → `imu`).
pub fn stream_name(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

fn value_f64(value: Value) -> f64 {
    match value {
        Value::I8(v) => f64::from(v),
        Value::U8(v) => f64::from(v),
        Value::I16(v) => f64::from(v),
        Value::U16(v) => f64::from(v),
        Value::I32(v) => f64::from(v),
        Value::U32(v) => f64::from(v),
        // Counters and nanosecond sums: exact below 2⁵³, which is all a plot needs.
        Value::I64(v) => v as f64,
        Value::U64(v) => v as f64,
        Value::F32(v) => f64::from(v),
        Value::F64(v) => v,
    }
}

/// Reads a stream file into its tables. Reader problems are printed on stderr (as `info`
/// does) and counted; only I/O errors fail.
pub fn load_stream(path: &Path) -> Result<Stream, String> {
    let mut reader = Box::new(LogReader::new());
    let bar = ProgressBar::hidden();
    let mut stream = Stream {
        name: stream_name(path),
        path: path.to_path_buf(),
        tables: BTreeMap::new(),
        problems: 0,
    };
    let mut layouts: BTreeMap<u8, Vec<String>> = BTreeMap::new();
    let mut session = 0u32;
    let mut row = Vec::new();
    read_file(path, &mut reader, &bar, |event| match event {
        Event::Problem(problem) => {
            stream.problems += 1;
            report_line(&bar, &problem_line(path, &problem));
        }
        Event::Record { record, .. } => match record {
            Record::BeginData { .. } => session += 1,
            Record::EndData { .. } => {}
            Record::FormatDefinition {
                index,
                text,
                format,
            } => {
                let table = stream.tables.entry(index).or_insert_with(|| Table {
                    index,
                    ..Table::default()
                });
                table.format_text = String::from_utf8_lossy(text).into_owned();
                // Until a comment says otherwise, columns are named by position.
                let fields = format.map_or(0, |f| f.fields().len());
                layouts.insert(index, (1..=fields).map(|i| format!("field{i}")).collect());
            }
            Record::FormatComment { index, text } => {
                let names = String::from_utf8_lossy(text);
                layouts.insert(
                    index,
                    names.split(',').map(|n| n.trim().to_string()).collect(),
                );
            }
            Record::DataBlock {
                index,
                time,
                data,
                format,
            } => {
                row.clear();
                let mut offset = 0;
                for field in format.fields() {
                    let value = data
                        .get(offset..)
                        .and_then(|bytes| Value::decode(field.ty, bytes))
                        .map_or(f64::NAN, value_f64);
                    row.push(value);
                    offset += field.ty.size();
                }
                let layout = layouts.get(&index).cloned().unwrap_or_default();
                let table = stream.tables.entry(index).or_insert_with(|| Table {
                    index,
                    ..Table::default()
                });
                table.push_row(time, session, &layout, &row);
            }
            Record::ByteArray { index, time, .. } => {
                let table = stream.tables.entry(index).or_insert_with(|| Table {
                    index,
                    ..Table::default()
                });
                table.push_row(time, session, &[], &[]);
            }
        },
    })
    .map_err(|e| format!("{}: {e}", path.display()))?;
    // A format defined but never used has no rows: keep it only if it has data.
    stream.tables.retain(|_, t| !t.times_ns.is_empty());
    Ok(stream)
}

/// Where a flight's streams are: a directory of `<stream>.bin`, or one `.bin` file.
pub enum Source {
    Dir(PathBuf),
    File(PathBuf),
}

impl Source {
    pub fn new(path: &Path) -> Result<Source, String> {
        if path.is_dir() {
            Ok(Source::Dir(path.to_path_buf()))
        } else if path.is_file() {
            Ok(Source::File(path.to_path_buf()))
        } else {
            Err(format!("{}: no such file or directory", path.display()))
        }
    }

    /// The names of the streams there, sorted.
    pub fn stream_names(&self) -> Vec<String> {
        match self {
            Source::File(path) => vec![stream_name(path)],
            Source::Dir(dir) => {
                let mut names: Vec<String> = std::fs::read_dir(dir)
                    .into_iter()
                    .flatten()
                    .flatten()
                    .map(|e| e.path())
                    .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "bin"))
                    .map(|p| stream_name(&p))
                    .filter(|n| !n.starts_with('.'))
                    .collect();
                names.sort();
                names
            }
        }
    }

    /// The file of stream `name`, if the source has it.
    pub fn stream_path(&self, name: &str) -> Option<PathBuf> {
        match self {
            Source::File(path) => (stream_name(path) == name).then(|| path.clone()),
            Source::Dir(dir) => {
                let path = dir.join(format!("{name}.bin"));
                path.is_file().then_some(path)
            }
        }
    }

    /// Why stream `name` is not there, for a note.
    pub fn missing(&self, name: &str) -> String {
        match self {
            Source::Dir(dir) => format!("no {name}.bin in {}", dir.display()),
            Source::File(path) => format!(
                "no {name} stream: {} is the {} stream (give the flight directory)",
                path.display(),
                stream_name(path)
            ),
        }
    }

    pub fn display(&self) -> String {
        match self {
            Source::Dir(p) | Source::File(p) => p.display().to_string(),
        }
    }
}

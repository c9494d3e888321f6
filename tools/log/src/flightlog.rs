//! A whole flight held in memory as its records, for the converters that merge streams
//! (`to-ulog`, `to-parquet`): every stream's data blocks with their raw bytes (copied as they
//! are, so nothing is lost or rounded), the layouts (format + columns) they were written
//! with, Begin/End Data, and the reader's problems with where in time they happened.
//!
//! A flight directory is a few MB per minute of flight, so holding it is cheaper and simpler
//! than the two-pass streaming `to-csv` needs for arbitrarily long files.

use std::path::{Path, PathBuf};

use skyframe_core::logfmt::{Event, FieldType, Format, LogReader, ProblemKind, Record, Value};
use skyframe_logtable::{problem_line, read_file, stream_name, time_ns};

/// One distinct layout of a format index in one stream: the format string and column names
/// in force when its data blocks were written. A redefinition with a different text or
/// comment makes a new layout (`version` 1, 2, …).
#[derive(Clone, Debug)]
pub struct Layout {
    pub stream: String,
    pub index: u8,
    /// 0 for the first layout of this index in the stream, then 1, 2, … after redefinitions.
    pub version: usize,
    pub format: Format,
    pub format_text: String,
    /// One per field: the Format Comment's names, or `field<n>` where it has none (or the
    /// wrong count).
    pub columns: Vec<String>,
}

impl Layout {
    pub fn column(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|c| c == name)
    }

    pub fn types(&self) -> impl Iterator<Item = FieldType> + '_ {
        self.format.fields().iter().map(|f| f.ty)
    }
}

/// One data block.
#[derive(Clone, Copy, Debug)]
pub struct Rec {
    pub t_ns: i64,
    /// Index into [`Flight::layouts`].
    pub layout: usize,
    /// Its bytes are `Flight::data[start..start + len]`.
    pub start: usize,
    pub len: usize,
}

/// Something the reader reported, placed in time: after the record at `after_ns` (None:
/// before any record of the stream) and before the one at `before_ns`.
#[derive(Clone, Debug)]
pub struct Damage {
    pub line: String,
    pub after_ns: Option<i64>,
    pub before_ns: Option<i64>,
    /// Records were lost or damaged here (not merely a file left unclosed).
    pub lost_data: bool,
}

/// A stream's logging sessions: Begin Data and End Data times.
#[derive(Clone, Debug, Default)]
pub struct StreamInfo {
    pub name: String,
    pub path: PathBuf,
    pub begins_ns: Vec<i64>,
    pub ends_ns: Vec<i64>,
    pub byte_arrays: u64,
}

#[derive(Debug, Default)]
pub struct Flight {
    pub streams: Vec<StreamInfo>,
    pub layouts: Vec<Layout>,
    /// Every data block of every stream, streams in name order, each stream in file order.
    pub records: Vec<Rec>,
    pub data: Vec<u8>,
    pub damage: Vec<Damage>,
}

/// The binary logs a converter reads: every `*.bin` of a flight directory (sorted), or the
/// one file given. Errors name the path.
pub fn stream_files(input: &Path) -> Result<Vec<PathBuf>, String> {
    if input.is_dir() {
        let entries = std::fs::read_dir(input)
            .map_err(|e| format!("{}: cannot list directory: {e}", input.display()))?;
        let mut files: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                p.is_file()
                    && p.extension().is_some_and(|e| e == "bin")
                    && !stream_name(p).starts_with('.')
            })
            .collect();
        files.sort();
        if files.is_empty() {
            return Err(format!(
                "{}: no stream files (*.bin) to convert in this directory",
                input.display()
            ));
        }
        Ok(files)
    } else if input.is_file() {
        Ok(vec![input.to_path_buf()])
    } else {
        Err(format!("{}: no such file or directory", input.display()))
    }
}

impl Flight {
    /// Reads every stream file. Reader problems are collected (and returned as lines by
    /// [`Flight::problem_lines`]); only I/O errors fail.
    pub fn load(files: &[PathBuf]) -> Result<Flight, String> {
        let mut flight = Flight::default();
        let mut reader = Box::new(LogReader::new());
        for path in files {
            flight.load_stream(path, &mut reader)?;
        }
        Ok(flight)
    }

    fn load_stream(&mut self, path: &Path, reader: &mut LogReader) -> Result<(), String> {
        let name = stream_name(path);
        let mut info = StreamInfo {
            name: name.clone(),
            path: path.to_path_buf(),
            ..StreamInfo::default()
        };
        // Per index: the text and comment in force, and the layout they make.
        let mut texts: Vec<Option<String>> = vec![None; 256];
        let mut comments: Vec<Option<String>> = vec![None; 256];
        let mut current: Vec<Option<usize>> = vec![None; 256];
        let mut versions = [0usize; 256];
        let mut last_ns: Option<i64> = None;
        let mut pending: Vec<usize> = Vec::new();
        read_file(
            path,
            reader,
            |_| {},
            |event| match event {
                Event::Problem(problem) => {
                    pending.push(self.damage.len());
                    self.damage.push(Damage {
                        line: problem_line(path, &problem),
                        after_ns: last_ns,
                        before_ns: None,
                        lost_data: problem.kind != ProblemKind::NotClosedCleanly,
                    });
                }
                Event::Record { record, .. } => {
                    let t = match record {
                        Record::BeginData { time } => {
                            info.begins_ns.push(time_ns(time));
                            Some(time_ns(time))
                        }
                        Record::EndData { time } => {
                            info.ends_ns.push(time_ns(time));
                            Some(time_ns(time))
                        }
                        Record::FormatDefinition { index, text, .. } => {
                            let i = usize::from(index);
                            texts[i] = Some(String::from_utf8_lossy(text).into_owned());
                            current[i] = None;
                            None
                        }
                        Record::FormatComment { index, text } => {
                            let i = usize::from(index);
                            comments[i] = Some(String::from_utf8_lossy(text).into_owned());
                            current[i] = None;
                            None
                        }
                        Record::ByteArray { time, .. } => {
                            // ULog and Parquet columns have fixed types; byte arrays are
                            // counted and left to `to-csv`.
                            info.byte_arrays += 1;
                            Some(time_ns(time))
                        }
                        Record::DataBlock {
                            index,
                            time,
                            data,
                            format,
                        } => {
                            let i = usize::from(index);
                            let layout = match current[i] {
                                Some(layout) => layout,
                                None => {
                                    let text = texts[i].clone().unwrap_or_default();
                                    let columns = column_names(format, comments[i].as_deref());
                                    let existing = self.layouts.iter().position(|l| {
                                        l.stream == name
                                            && l.index == index
                                            && l.format_text == text
                                            && l.columns == columns
                                    });
                                    let layout = existing.unwrap_or_else(|| {
                                        self.layouts.push(Layout {
                                            stream: name.clone(),
                                            index,
                                            version: versions[i],
                                            format: *format,
                                            format_text: text,
                                            columns,
                                        });
                                        versions[i] += 1;
                                        self.layouts.len() - 1
                                    });
                                    current[i] = Some(layout);
                                    layout
                                }
                            };
                            let start = self.data.len();
                            self.data.extend_from_slice(data);
                            self.records.push(Rec {
                                t_ns: time_ns(time),
                                layout,
                                start,
                                len: data.len(),
                            });
                            Some(time_ns(time))
                        }
                    };
                    if let Some(t) = t {
                        last_ns = Some(t);
                        for d in pending.drain(..) {
                            if let Some(damage) = self.damage.get_mut(d) {
                                damage.before_ns = Some(t);
                            }
                        }
                    }
                }
            },
        )
        .map_err(|e| format!("{}: {e}", path.display()))?;
        self.streams.push(info);
        Ok(())
    }

    /// The flight's first time (any record with a TIME), in ns.
    pub fn start_ns(&self) -> Option<i64> {
        let records = self.records.iter().map(|r| r.t_ns);
        let sessions = self
            .streams
            .iter()
            .flat_map(|s| s.begins_ns.iter().copied());
        records.chain(sessions).min()
    }

    pub fn bytes(&self, rec: &Rec) -> &[u8] {
        self.data.get(rec.start..rec.start + rec.len).unwrap_or(&[])
    }

    /// The fields of a record as `f64` (exact for every f32 and every integer below 2⁵³).
    pub fn values(&self, rec: &Rec, out: &mut Vec<f64>) {
        out.clear();
        let Some(layout) = self.layouts.get(rec.layout) else {
            return;
        };
        let bytes = self.bytes(rec);
        let mut offset = 0;
        for field in layout.format.fields() {
            let value = bytes
                .get(offset..)
                .and_then(|b| Value::decode(field.ty, b))
                .map_or(f64::NAN, skyframe_logtable::value_f64);
            out.push(value);
            offset += field.ty.size();
        }
    }

    /// The records of one layout, in file order.
    pub fn records_of(&self, layout: usize) -> impl Iterator<Item = &Rec> {
        self.records.iter().filter(move |r| r.layout == layout)
    }

    /// The first layout of `stream`'s format `index`.
    pub fn layout_of(&self, stream: &str, index: u8) -> Option<usize> {
        self.layouts
            .iter()
            .position(|l| l.stream == stream && l.index == index)
    }
}

/// The column names of a format: its comment's, when it names every field; otherwise
/// `field<n>`, as `skyframe-logtable` names them.
fn column_names(format: &Format, comment: Option<&str>) -> Vec<String> {
    let count = format.fields().len();
    let names: Vec<String> = comment
        .map(|c| c.split(',').map(|n| n.trim().to_string()).collect())
        .unwrap_or_default();
    if names.len() == count {
        names
    } else {
        (1..=count).map(|i| format!("field{i}")).collect()
    }
}

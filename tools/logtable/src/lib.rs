//! Reading flight logs on a host, for the tools and the simulator's score.
//!
//! ```text
//! file ──feed──▶ core LogReader (constant memory) ──events──▶ caller
//!                                                 └─▶ load_stream: columns per format index
//! ```
//!
//! The reader is the flight core's own (`skyframe_core::logfmt`), so a damaged file yields
//! what is readable plus its problems, each with the file offset.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, Read};
use std::path::{Path, PathBuf};

use skyframe_core::logfmt::{Event, LogReader, Problem, ProblemKind, Record, Time, Value};

/// The stderr line of a reader problem: the file, the offset, what is wrong and where
/// reading went on.
pub fn problem_line(path: &Path, problem: &Problem) -> String {
    let file = path.display();
    match problem.kind {
        ProblemKind::NotClosedCleanly => {
            format!("{file}: offset {}: {}", problem.offset, problem.kind)
        }
        kind if kind.resynchronises() => format!(
            "{file}: offset {}: {kind}; skipped to offset {}",
            problem.offset, problem.resume_offset
        ),
        kind => format!("{file}: offset {}: {kind}; record skipped", problem.offset),
    }
}

/// Reads what `file` has now into the reader's space; returns how many bytes (0 at its end
/// for now: a growing file may have more later).
pub fn feed(file: &mut File, reader: &mut LogReader) -> io::Result<usize> {
    let space = reader.space();
    if space.is_empty() {
        // The window holds the longest record, so a drained reader always has room.
        return Err(io::Error::other("log reader stalled with a full window"));
    }
    let count = loop {
        match file.read(space) {
            Ok(n) => break n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        }
    };
    reader.commit(count);
    Ok(count)
}

/// Streams `path` through `reader` (reset first), calling `on_bytes` with each chunk's size
/// (for a progress bar) and `on_event` for every event in file order. Memory stays constant:
/// the reader's window is the only buffer.
pub fn read_file(
    path: &Path,
    reader: &mut LogReader,
    mut on_bytes: impl FnMut(usize),
    mut on_event: impl FnMut(Event<'_>),
) -> io::Result<()> {
    let mut file = File::open(path)?;
    reader.reset();
    loop {
        let count = feed(&mut file, reader)?;
        on_bytes(count);
        if count == 0 {
            reader.finish();
        }
        while let Some(event) = reader.next_event() {
            on_event(event);
        }
        if count == 0 {
            return Ok(());
        }
    }
}

/// A record's time in ns (`tv_sec · 10⁹ + tv_nsec`).
pub fn time_ns(time: Time) -> i64 {
    i64::from(time.sec) * 1_000_000_000 + i64::from(time.nsec)
}

/// A field as `f64`: exact for every integer below 2⁵³ (counters, nanosecond sums).
pub fn value_f64(value: Value) -> f64 {
    match value {
        Value::I8(v) => f64::from(v),
        Value::U8(v) => f64::from(v),
        Value::I16(v) => f64::from(v),
        Value::U16(v) => f64::from(v),
        Value::I32(v) => f64::from(v),
        Value::U32(v) => f64::from(v),
        Value::I64(v) => v as f64,
        Value::U64(v) => v as f64,
        Value::F32(v) => f64::from(v),
        Value::F64(v) => v,
    }
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
    /// Problems the reader reported (each also passed to the caller's `on_problem`).
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

    /// The table of format `index`, if it has rows.
    pub fn table(&self, index: u8) -> Option<&Table> {
        self.tables.get(&index)
    }
}

/// The stream name of a file: its stem (`imu.bin` → `imu`).
pub fn stream_name(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Reads a stream file into its tables. Each reader problem is counted and handed to
/// `on_problem`; only I/O errors fail.
pub fn load_stream(path: &Path, mut on_problem: impl FnMut(&Problem)) -> Result<Stream, String> {
    let mut reader = Box::new(LogReader::new());
    let mut stream = Stream {
        name: stream_name(path),
        path: path.to_path_buf(),
        tables: BTreeMap::new(),
        problems: 0,
    };
    let mut layouts: BTreeMap<u8, Vec<String>> = BTreeMap::new();
    let mut session = 0u32;
    let mut row = Vec::new();
    read_file(
        path,
        &mut reader,
        |_| {},
        |event| match event {
            Event::Problem(problem) => {
                stream.problems += 1;
                on_problem(&problem);
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
        },
    )
    .map_err(|e| format!("{}: {e}", path.display()))?;
    // A format defined but never used has no rows: keep it only if it has data.
    stream.tables.retain(|_, t| !t.times_ns.is_empty());
    Ok(stream)
}

/// A CSV line being rendered, as bytes: `%c` prints raw bytes, exactly as C does, even when
/// they are not UTF-8. `to-csv` and the shell's text logs render into it with
/// `skyframe_core::logfmt::csv`, so their lines are the same bytes.
#[derive(Default)]
pub struct CsvLine(pub Vec<u8>);

impl std::fmt::Write for CsvLine {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.0.extend_from_slice(s.as_bytes());
        Ok(())
    }
}

impl skyframe_core::logfmt::printf::ByteWrite for CsvLine {
    fn write_byte(&mut self, byte: u8) -> std::fmt::Result {
        self.0.push(byte);
        Ok(())
    }

    fn write_ascii(&mut self, ascii: &[u8]) -> std::fmt::Result {
        // Bytes in, bytes out: the renderer's digits need no check that they are text.
        self.0.extend_from_slice(ascii);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skyframe_core::logfmt::record::{
        DataBlockWriter, LogFormat, encode_begin_data, encode_end_data,
    };

    const FORMAT: LogFormat = LogFormat::new("%hhu,%.3f,%.6lf", "counter,x_m,t_s");

    /// A log with one session of `rows` records, then `tail` appended raw.
    fn write_log(path: &Path, rows: u8, tail: &[u8]) {
        let format = FORMAT.parse().expect("format");
        let mut bytes = Vec::new();
        let mut buf = [0u8; 512];
        let mut push = |n: usize, buf: &[u8]| bytes.extend_from_slice(buf.get(..n).expect("n"));
        let n = FORMAT.encode_declaration(&mut buf, 1).expect("declaration");
        push(n, &buf);
        let n = encode_begin_data(&mut buf, 0).expect("begin");
        push(n, &buf);
        for i in 0..rows {
            let t_ns = u64::from(i) * 10_000_000;
            let n = DataBlockWriter::new(&mut buf, 1, t_ns, &format)
                .u8(i)
                .f32(f32::from(i) * 0.5)
                .f64(t_ns as f64 * 1e-9)
                .finish()
                .expect("record");
            push(n, &buf);
        }
        let n = encode_end_data(&mut buf, 0).expect("end");
        push(n, &buf);
        bytes.extend_from_slice(tail);
        std::fs::write(path, bytes).expect("write");
    }

    #[test]
    fn a_stream_loads_as_named_columns_with_times_and_sessions() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("probe.bin");
        write_log(&path, 50, &[]);
        let stream = load_stream(&path, |p| panic!("no problem expected: {p:?}")).expect("load");
        assert_eq!(stream.name, "probe");
        assert_eq!(stream.problems, 0);
        let table = stream.table(1).expect("format 1");
        assert_eq!(table.columns, ["counter", "x_m", "t_s"]);
        assert_eq!(table.times_ns.len(), 50);
        assert_eq!(table.times_ns.get(7), Some(&70_000_000));
        assert_eq!(table.column("x_m").and_then(|c| c.get(7)), Some(&3.5));
        assert_eq!(table.column("counter").and_then(|c| c.get(49)), Some(&49.0));
        assert!(table.sessions.iter().all(|&s| s == 1));
        assert_eq!(stream.first_time_ns(), Some(0));
    }

    #[test]
    fn damage_is_reported_with_its_offset_and_the_rest_still_loads() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("damaged.bin");
        write_log(&path, 10, &[0x7B, 0x22, 0x00, 0x01]);
        let mut lines = Vec::new();
        let stream = load_stream(&path, |p| lines.push(problem_line(&path, p))).expect("load");
        assert_eq!(stream.table(1).map(|t| t.times_ns.len()), Some(10));
        assert!(stream.problems > 0);
        assert_eq!(lines.len(), stream.problems);
        assert!(
            lines.iter().any(|l| l.contains("damaged.bin: offset ")),
            "{lines:?}"
        );
    }

    #[test]
    fn a_missing_file_is_an_error_naming_it() {
        let e = load_stream(Path::new("/nonexistent/imu.bin"), |_| {}).expect_err("missing");
        assert!(e.starts_with("/nonexistent/imu.bin: "), "{e}");
    }
}

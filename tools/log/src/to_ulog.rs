//! `to-ulog`: a log as a PX4 ULog file, for PX4's tools (FlightPlot, PlotJuggler, pyulog).
//!
//! Each distinct layout of a format index (format string + columns) becomes one ULog message
//! `log_<index>` (`log_<index>_<n>` for later redefinitions) with a `uint64_t timestamp` (µs,
//! from the record's TIME) followed by the data block's fields, named after the columns. A
//! data block is already packed little-endian without padding, as ULog wants, so its bytes
//! are copied as they are. ULog formats must all come before the data, so the file is read
//! twice: once for the layouts, once for the data. Byte arrays have no fixed size and are not
//! converted (a note says how many).

use std::collections::HashMap;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use indicatif::ProgressBar;
use skyframe_core::logfmt::{Event, FieldType, Format, LogReader, Record, Time};

use crate::Outcome;
use crate::input::{problem_line, progress_bar, read_file, report_line};

const ULOG_MAGIC: [u8; 7] = [b'U', b'L', b'o', b'g', 0x01, 0x12, 0x35];
const ULOG_VERSION: u8 = 1;

/// One ULog message layout.
struct Layout {
    name: String,
    /// `type name` per field, timestamp first.
    fields: Vec<String>,
}

/// The format text and comment currently in force for each index.
struct Current {
    texts: Vec<Option<String>>,
    comments: Vec<Option<String>>,
}

impl Current {
    fn new() -> Self {
        Self {
            texts: vec![None; 256],
            comments: vec![None; 256],
        }
    }

    /// Follows definitions and comments; returns the layout key of a data block.
    fn key(&mut self, record: &Record<'_>) -> Option<(u8, String, Option<String>)> {
        match *record {
            Record::FormatDefinition { index, text, .. } => {
                self.texts[usize::from(index)] = Some(String::from_utf8_lossy(text).into_owned());
                None
            }
            Record::FormatComment { index, text } => {
                self.comments[usize::from(index)] =
                    Some(String::from_utf8_lossy(text).into_owned());
                None
            }
            Record::DataBlock { index, .. } => Some((
                index,
                self.texts[usize::from(index)].clone().unwrap_or_default(),
                self.comments[usize::from(index)].clone(),
            )),
            _ => None,
        }
    }
}

fn ulog_type(ty: FieldType) -> &'static str {
    match ty {
        FieldType::I8 => "int8_t",
        FieldType::U8 => "uint8_t",
        FieldType::I16 => "int16_t",
        FieldType::U16 => "uint16_t",
        FieldType::I32 => "int32_t",
        FieldType::U32 => "uint32_t",
        FieldType::I64 => "int64_t",
        FieldType::U64 => "uint64_t",
        FieldType::F32 => "float",
        FieldType::F64 => "double",
    }
}

/// ULog field names: the columns made identifiers, unique, never `timestamp` (ours).
fn field_names(format: &Format, comment: Option<&str>) -> Vec<String> {
    let columns: Vec<&str> = comment.map(|c| c.split(',').collect()).unwrap_or_default();
    let count = format.fields().len();
    let mut names: Vec<String> = Vec::with_capacity(count);
    for i in 0..count {
        let column = if columns.len() == count {
            columns[i].trim()
        } else {
            ""
        };
        let mut name: String = column
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        if name.is_empty() || name.starts_with(|c: char| c.is_ascii_digit()) {
            name = format!("f{i}_{name}").trim_end_matches('_').to_string();
        }
        if name == "timestamp" || name.starts_with("_padding") {
            name = format!("{name}_log");
        }
        if names.contains(&name) {
            name = format!("{name}_{i}");
        }
        names.push(name);
    }
    names
}

fn timestamp_us(time: Time) -> u64 {
    let us = i64::from(time.sec) * 1_000_000 + i64::from(time.nsec / 1000);
    u64::try_from(us).unwrap_or(0)
}

fn message(out: &mut impl Write, kind: u8, body: &[u8]) -> io::Result<()> {
    let size = u16::try_from(body.len()).map_err(|_| io::Error::other("ULog message too long"))?;
    out.write_all(&size.to_le_bytes())?;
    out.write_all(&[kind])?;
    out.write_all(body)
}

pub fn run(input: &Path, output: &Path) -> Outcome {
    let files = [input.to_path_buf()];
    let bar = progress_bar(&files);
    bar.set_length(bar.length().unwrap_or(0) * 2);
    let result = convert(input, output, &bar);
    bar.finish_and_clear();
    match result {
        Ok(reported) if reported => Outcome::Reported,
        Ok(_) => Outcome::Whole,
        Err(e) => {
            eprintln!("skyframe-log: {e}");
            Outcome::Failed
        }
    }
}

/// Converts; returns whether anything was reported.
fn convert(input: &Path, output: &Path, bar: &ProgressBar) -> io::Result<bool> {
    let mut reader = Box::new(LogReader::new());
    let in_err = |e: io::Error| io::Error::new(e.kind(), format!("{}: {e}", input.display()));
    let out_err = |e: io::Error| io::Error::new(e.kind(), format!("{}: {e}", output.display()));

    // Pass 1: the layouts, in order of first data.
    let mut layouts: Vec<Layout> = Vec::new();
    let mut ids: HashMap<(u8, String, Option<String>), u16> = HashMap::new();
    let mut per_index = [0usize; 256];
    let mut first_time: Option<Time> = None;
    let mut current = Current::new();
    let mut too_many = false;
    read_file(input, &mut reader, bar, |event| {
        let Event::Record { record, .. } = event else {
            return;
        };
        if let Record::DataBlock { time, .. } | Record::ByteArray { time, .. } = record {
            first_time.get_or_insert(time);
        }
        let (Some(key), Record::DataBlock { index, format, .. }) = (current.key(&record), record)
        else {
            return;
        };
        if ids.contains_key(&key) {
            return;
        }
        let Ok(id) = u16::try_from(layouts.len()) else {
            too_many = true;
            return;
        };
        let seen = &mut per_index[usize::from(index)];
        let name = match *seen {
            0 => format!("log_{index}"),
            n => format!("log_{index}_{n}"),
        };
        *seen += 1;
        let mut fields = vec![String::from("uint64_t timestamp")];
        for (field, name) in format
            .fields()
            .iter()
            .zip(field_names(format, key.2.as_deref()))
        {
            fields.push(format!("{} {name}", ulog_type(field.ty)));
        }
        layouts.push(Layout { name, fields });
        ids.insert(key, id);
    })
    .map_err(in_err)?;
    if too_many {
        return Err(io::Error::other(format!(
            "{}: more than 65536 layouts",
            input.display()
        )));
    }

    // Header and definitions.
    let file = File::create(output).map_err(out_err)?;
    let mut out = BufWriter::with_capacity(256 * 1024, file);
    let mut header = Vec::with_capacity(16);
    header.extend_from_slice(&ULOG_MAGIC);
    header.push(ULOG_VERSION);
    header.extend_from_slice(&first_time.map_or(0, timestamp_us).to_le_bytes());
    out.write_all(&header).map_err(out_err)?;
    // Flag bits: no compatible or incompatible flags, no appended data.
    message(&mut out, b'B', &[0u8; 40]).map_err(out_err)?;
    let key = b"char[8] sys_name";
    let mut info = vec![u8::try_from(key.len()).unwrap_or(0)];
    info.extend_from_slice(key);
    info.extend_from_slice(b"skyframe");
    message(&mut out, b'I', &info).map_err(out_err)?;
    for layout in &layouts {
        let text = format!("{}:{};", layout.name, layout.fields.join(";"));
        message(&mut out, b'F', text.as_bytes()).map_err(out_err)?;
    }
    for (id, layout) in layouts.iter().enumerate() {
        let mut body = vec![0u8]; // multi_id
        body.extend_from_slice(&u16::try_from(id).unwrap_or(u16::MAX).to_le_bytes());
        body.extend_from_slice(layout.name.as_bytes());
        message(&mut out, b'A', &body).map_err(out_err)?;
    }

    // Pass 2: the data.
    let mut current = Current::new();
    let mut reported = false;
    let mut byte_arrays = 0u64;
    let mut write_error: Option<io::Error> = None;
    let mut body = Vec::new();
    read_file(input, &mut reader, bar, |event| {
        let record = match event {
            Event::Problem(problem) => {
                reported = true;
                report_line(bar, &problem_line(input, &problem));
                return;
            }
            Event::Record { record, .. } => record,
        };
        if let Record::ByteArray { .. } = record {
            byte_arrays += 1;
        }
        let (Some(key), Record::DataBlock { time, data, .. }) = (current.key(&record), record)
        else {
            return;
        };
        let Some(&id) = ids.get(&key) else {
            return;
        };
        if write_error.is_some() {
            return;
        }
        body.clear();
        body.extend_from_slice(&id.to_le_bytes());
        body.extend_from_slice(&timestamp_us(time).to_le_bytes());
        body.extend_from_slice(data);
        if let Err(e) = message(&mut out, b'D', &body) {
            write_error = Some(e);
        }
    })
    .map_err(in_err)?;
    if let Some(e) = write_error {
        return Err(out_err(e));
    }
    out.flush().map_err(out_err)?;
    if byte_arrays > 0 {
        report_line(
            bar,
            &format!(
                "skyframe-log: note: {}: {byte_arrays} byte arrays not converted (ULog has no \
                 variable-length messages)",
                input.display()
            ),
        );
    }
    Ok(reported)
}

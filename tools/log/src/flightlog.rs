//! A whole flight held in memory as its records, for the converters that merge streams
//! (`to-ulog`, `to-parquet`): every stream's data blocks with their raw bytes (copied as they
//! are, so nothing is lost or rounded), the layouts (format + columns) they were written
//! with, Begin/End Data, and the reader's problems with where in time they happened.
//!
//! A flight directory is a few MB per minute of flight, so holding it is cheaper and simpler
//! than the two-pass streaming `to-csv` needs for arbitrarily long files.

use std::path::{Path, PathBuf};

use skyframe_core::logfmt::{
    Conversion, Event, FieldType, Format, LogReader, ProblemKind, Record, Value,
};
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
        let paths: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
        let binary = |p: &PathBuf| {
            p.is_file()
                && p.extension().is_some_and(|e| e == "bin")
                && !stream_name(p).starts_with('.')
        };
        let mut files: Vec<PathBuf> = paths.iter().filter(|p| binary(p)).cloned().collect();
        // A stream flown with `--text-log` is `<stream>.<index>.csv` instead of a .bin; a CSV
        // beside its stream's .bin is a conversion and is left alone.
        files.extend(
            paths
                .iter()
                .filter(|p| {
                    p.is_file()
                        && text_log_name(p).is_some_and(|(stream, _)| {
                            !stream.starts_with('.')
                                && !input.join(format!("{stream}.bin")).is_file()
                        })
                        && is_text_log(p)
                })
                .cloned(),
        );
        files.sort();
        if files.is_empty() {
            return Err(format!(
                "{}: no stream files (*.bin, or text logs <stream>.<index>.csv) to convert in \
                 this directory",
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
            match text_log_name(path) {
                Some((stream, index)) if path.extension().is_some_and(|e| e == "csv") => {
                    flight.load_text_log(path, &stream, index)?;
                }
                _ => flight.load_stream(path, &mut reader)?,
            }
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

    /// Reads a text log (`log-format.md`: the lines `to-csv` writes): each data line's text
    /// is parsed back into the fields of the format in force, so it converts like the binary
    /// record it stands for (to the printed precision). A line that does not parse is
    /// reported (file and line) and skipped.
    fn load_text_log(&mut self, path: &Path, stream: &str, index: u8) -> Result<(), String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let text = String::from_utf8_lossy(&bytes);
        self.streams.push(StreamInfo {
            name: stream.to_string(),
            path: path.to_path_buf(),
            ..StreamInfo::default()
        });
        let mut format: Option<(String, Format)> = None;
        let mut columns: Option<Vec<String>> = None;
        let mut layout: Option<usize> = None;
        let mut last_ns: Option<i64> = None;
        let mut pending: Vec<usize> = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let report = |why: String| Damage {
                line: format!("{}: line {}: {why}; line skipped", path.display(), n + 1),
                after_ns: last_ns,
                before_ns: None,
                lost_data: true,
            };
            if let Some(rest) = line.strip_prefix("% format ") {
                layout = None;
                columns = None;
                format = None;
                let Some((_, spec)) = rest.split_once(": ") else {
                    pending.push(self.damage.len());
                    self.damage
                        .push(report("a format line without `: `".into()));
                    continue;
                };
                match Format::parse(spec) {
                    Ok(parsed) => format = Some((spec.to_string(), parsed)),
                    Err(e) => {
                        pending.push(self.damage.len());
                        self.damage
                            .push(report(format!("invalid format {spec:?}: {e:?}")));
                    }
                }
                continue;
            }
            if let Some(names) = line.strip_prefix("% time,") {
                columns = Some(names.split(',').map(|c| c.trim().to_string()).collect());
                layout = None;
                continue;
            }
            if line.starts_with('%') || line.trim().is_empty() {
                continue;
            }
            let Some((spec, parsed)) = format.as_ref() else {
                pending.push(self.damage.len());
                self.damage
                    .push(report("a data line before any format line".into()));
                continue;
            };
            let start = self.data.len();
            let t_ns = match parse_text_record(line, spec, parsed, &mut self.data) {
                Ok(t_ns) => t_ns,
                Err(why) => {
                    self.data.truncate(start);
                    pending.push(self.damage.len());
                    self.damage.push(report(why));
                    continue;
                }
            };
            let l = match layout {
                Some(l) => l,
                None => {
                    let names = match &columns {
                        Some(c) if c.len() == parsed.fields().len() => c.clone(),
                        _ => column_names(parsed, None),
                    };
                    let l = self.layout_for(stream, index, spec, parsed, names);
                    layout = Some(l);
                    l
                }
            };
            self.records.push(Rec {
                t_ns,
                layout: l,
                start,
                len: self.data.len() - start,
            });
            last_ns = Some(t_ns);
            for d in pending.drain(..) {
                if let Some(damage) = self.damage.get_mut(d) {
                    damage.before_ns = Some(t_ns);
                }
            }
        }
        Ok(())
    }

    /// The layout of `stream`'s format `index` with this text and these columns, added if new.
    fn layout_for(
        &mut self,
        stream: &str,
        index: u8,
        text: &str,
        format: &Format,
        columns: Vec<String>,
    ) -> usize {
        let same = |l: &Layout| l.stream == stream && l.index == index;
        if let Some(l) = self
            .layouts
            .iter()
            .position(|l| same(l) && l.format_text == text && l.columns == columns)
        {
            return l;
        }
        let version = self.layouts.iter().filter(|l| same(l)).count();
        self.layouts.push(Layout {
            stream: stream.to_string(),
            index,
            version,
            format: *format,
            format_text: text.to_string(),
            columns,
        });
        self.layouts.len() - 1
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
/// An identifier for the converters' outputs (ULog fields and topics, Parquet columns) from
/// any text: ASCII alphanumerics and `_`, with `lead` put first when it would be empty or start
/// with a digit.
pub fn identifier(text: &str, lead: &str) -> String {
    let name: String = text
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
        format!("{lead}{name}")
    } else {
        name
    }
}

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

/// `<stream>.<index>.csv` → (stream, index), for index 1..=255.
fn text_log_name(path: &Path) -> Option<(String, u8)> {
    let name = path.file_name()?.to_str()?;
    let stem = name.strip_suffix(".csv")?;
    let (stream, index) = stem.rsplit_once('.')?;
    let index: u8 = index.parse().ok()?;
    (index > 0 && !stream.is_empty()).then(|| (stream.to_string(), index))
}

/// Whether a file starts like a text log (its first line a `% format` line).
fn is_text_log(path: &Path) -> bool {
    use std::io::Read;
    let mut start = [0u8; 9];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut start))
        .is_ok_and(|()| &start == b"% format ")
}

/// Parses a text log's data line `<sec>.<nsec>,<record text>` against its format, appending
/// the fields' little-endian bytes to `data`; returns the time in ns. The record text is
/// split at the format's literal text between conversions (`,` in every shipped format).
fn parse_text_record(
    line: &str,
    spec: &str,
    format: &Format,
    data: &mut Vec<u8>,
) -> Result<i64, String> {
    let (time, mut rest) = line.split_once(',').ok_or("no time field")?;
    let (sec, nsec) = time
        .split_once('.')
        .ok_or_else(|| format!("time {time:?} is not <sec>.<nsec>"))?;
    // TIME's own ranges (log-format.md): i32 seconds, nanoseconds below 10⁹.
    let sec: i32 = sec.parse().map_err(|_| format!("time {time:?}"))?;
    let nsec: u32 = nsec
        .parse()
        .ok()
        .filter(|&n| n < 1_000_000_000)
        .ok_or_else(|| format!("time {time:?}"))?;
    let fields = format.fields();
    let literal = |from: usize, to: usize| spec.get(from..to).map(|l| l.replace("%%", "%"));
    let mut previous_end = 0usize;
    for (i, field) in fields.iter().enumerate() {
        let before = literal(previous_end, usize::from(field.span_start)).ok_or("format text")?;
        rest = rest
            .strip_prefix(before.as_str())
            .ok_or_else(|| format!("expected {before:?} before field {}", i + 1))?;
        previous_end = usize::from(field.span_end);
        let next_start = fields
            .get(i + 1)
            .map_or(spec.len(), |f| usize::from(f.span_start));
        let after = literal(previous_end, next_start).ok_or("format text")?;
        let token = if i + 1 == fields.len() && after.is_empty() {
            std::mem::take(&mut rest)
        } else if after.is_empty() {
            return Err("two conversions without text between them cannot be split".into());
        } else {
            let at = rest
                .find(after.as_str())
                .ok_or_else(|| format!("expected {after:?} after field {}", i + 1))?;
            let (token, tail) = rest.split_at(at);
            rest = tail;
            token
        };
        let value = parse_field(token, field.ty, field.conversion)
            .ok_or_else(|| format!("field {} {token:?} is not a {}", i + 1, field.ty.name()))?;
        let mut bytes = [0u8; 8];
        let n = value.encode(&mut bytes).ok_or("field size")?;
        data.extend_from_slice(bytes.get(..n).unwrap_or(&[]));
    }
    let tail = literal(previous_end, spec.len()).ok_or("format text")?;
    if rest != tail {
        return Err(format!("unexpected text {rest:?} at the end"));
    }
    Ok(i64::from(sec) * 1_000_000_000 + i64::from(nsec))
}

/// A printed field back to its value (padding spaces allowed).
fn parse_field(token: &str, ty: FieldType, conversion: Conversion) -> Option<Value> {
    let t = token.trim();
    if conversion == Conversion::Char {
        return Some(Value::U8(*token.as_bytes().first()?));
    }
    if matches!(ty, FieldType::F32 | FieldType::F64) {
        // C prints NaN as `nan`/`-nan`, infinities as `inf`/`-inf` (any case with %F etc.).
        let lower = t.to_ascii_lowercase();
        let x = match lower.trim_start_matches(['-', '+']) {
            "nan" => f64::NAN,
            _ => lower.parse::<f64>().ok()?,
        };
        return Some(match ty {
            FieldType::F32 => Value::F32(x as f32),
            _ => Value::F64(x),
        });
    }
    let (digits, radix) = match conversion {
        Conversion::HexLower | Conversion::HexUpper => {
            (t.trim_start_matches("0x").trim_start_matches("0X"), 16)
        }
        Conversion::Octal => (t, 8),
        _ => (t.trim_start_matches('+'), 10),
    };
    let wide = i128::from_str_radix(digits, radix).ok()?;
    // %u/%x/%o of a signed field (or %d of an unsigned one) prints the other reading of the
    // same bits, so either reading is accepted (and cast back, as C reinterprets it); a
    // number neither reading of the field's width can print is not this field's.
    let bits = 8 * ty.size() as u32;
    if wide < -(1i128 << (bits - 1)) || wide > (1i128 << bits) - 1 {
        return None;
    }
    Some(match ty {
        FieldType::I8 => Value::I8(wide as i8),
        FieldType::U8 => Value::U8(wide as u8),
        FieldType::I16 => Value::I16(wide as i16),
        FieldType::U16 => Value::U16(wide as u16),
        FieldType::I32 => Value::I32(wide as i32),
        FieldType::U32 => Value::U32(wide as u32),
        FieldType::I64 => Value::I64(wide as i64),
        FieldType::U64 => Value::U64(wide as u64),
        FieldType::F32 | FieldType::F64 => return None,
    })
}

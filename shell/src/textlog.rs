//! Text logs: a stream written as CSV instead of binary, in exactly the lines
//! `skyframe-log to-csv` prints for the equivalent binary log (`log-format.md`): one file per
//! format index, `<name>.<index>.csv`, rendered by the same `core::logfmt::csv` functions.

use skyframe_core::logfmt::csv::{write_byte_array_line, write_data_line, write_header};
use skyframe_core::logfmt::format::{Format, trim_nuls};
use skyframe_core::logfmt::record::Time;
use skyframe_logtable::CsvLine;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use skyframe_core::logfmt::record::kind::{
    BYTE_ARRAY, BYTE_ARRAY_LEGACY, DATA_BLOCK, FORMAT_COMMENT, FORMAT_DEFINITION,
};

/// One format index of a text stream and its CSV file.
struct IndexFile {
    index: u8,
    text: String,
    format: Option<Format>,
    columns: Option<String>,
    /// The header the open file last printed: a redefinition prints a new one.
    printed: Option<(String, Option<String>)>,
    file: Option<BufWriter<File>>,
    bytes: u64,
    sequence: u32,
}

/// The CSV files of one text stream.
pub struct TextStream {
    name: String,
    indices: Vec<IndexFile>,
    line: CsvLine,
}

/// What became of a record.
pub enum Written {
    /// Written (or a declaration taken in).
    Yes,
    /// A data record of an index with no valid format: nothing to render it with.
    Unrenderable,
}

impl TextStream {
    pub fn new(name: &str) -> Self {
        Self {
            name: name.to_string(),
            indices: Vec::new(),
            line: CsvLine::default(),
        }
    }

    fn entry(&mut self, index: u8) -> &mut IndexFile {
        let at = match self.indices.iter().position(|f| f.index == index) {
            Some(at) => at,
            None => {
                self.indices.push(IndexFile {
                    index,
                    text: String::new(),
                    format: None,
                    columns: None,
                    printed: None,
                    file: None,
                    bytes: 0,
                    sequence: 0,
                });
                self.indices.len() - 1
            }
        };
        &mut self.indices[at]
    }

    /// Takes one whole binary record.
    pub fn write(
        &mut self,
        record: &[u8],
        dir: &Path,
        rotate_bytes: u64,
        files: &mut Vec<PathBuf>,
    ) -> std::io::Result<Written> {
        let (Some(&kind), Some(&index)) = (record.first(), record.get(1)) else {
            return Ok(Written::Yes);
        };
        match kind {
            FORMAT_DEFINITION => {
                let text = String::from_utf8_lossy(trim_nuls(record.get(4..).unwrap_or_default()));
                let entry = self.entry(index);
                entry.format = Format::parse(&text).ok();
                entry.text = text.into_owned();
                Ok(Written::Yes)
            }
            FORMAT_COMMENT => {
                let text = String::from_utf8_lossy(trim_nuls(record.get(4..).unwrap_or_default()));
                self.entry(index).columns = Some(text.into_owned());
                Ok(Written::Yes)
            }
            DATA_BLOCK | BYTE_ARRAY | BYTE_ARRAY_LEGACY => {
                let Some(time) = record.get(4..12).and_then(|t| <[u8; 8]>::try_from(t).ok()) else {
                    return Ok(Written::Unrenderable);
                };
                let time = Time::from_bytes(time);
                let body = record.get(12..).unwrap_or_default();
                let mut line = std::mem::take(&mut self.line);
                line.0.clear();
                let name = self.name.clone();
                let entry = self.entry(index);
                let Some(format) = entry.format.as_ref() else {
                    self.line = line;
                    return Ok(Written::Unrenderable);
                };
                let rendered = if kind == DATA_BLOCK {
                    write_data_line(&mut line, time, &entry.text, format, body).is_ok()
                } else {
                    write_byte_array_line(&mut line, time, &entry.text, format, body).is_ok()
                };
                let result = if rendered {
                    entry
                        .write_line(&line.0, &name, dir, rotate_bytes, files)
                        .map(|()| Written::Yes)
                } else {
                    Ok(Written::Unrenderable)
                };
                self.line = line;
                result
            }
            // Begin and End Data have no line in the CSV (the converter prints none).
            _ => Ok(Written::Yes),
        }
    }

    pub fn flush(&mut self, sync: bool) -> std::io::Result<()> {
        for f in &mut self.indices {
            if let Some(w) = f.file.as_mut() {
                w.flush()?;
                if sync {
                    w.get_ref().sync_data()?;
                }
            }
        }
        Ok(())
    }

    pub fn close(&mut self) -> std::io::Result<()> {
        for f in &mut self.indices {
            if let Some(mut w) = f.file.take() {
                w.flush()?;
                w.get_ref().sync_all()?;
            }
        }
        Ok(())
    }
}

impl IndexFile {
    fn path(&self, name: &str, dir: &Path) -> PathBuf {
        if self.sequence == 0 {
            dir.join(format!("{name}.{}.csv", self.index))
        } else {
            dir.join(format!("{name}.{}.{}.csv", self.index, self.sequence))
        }
    }

    fn write_line(
        &mut self,
        line: &[u8],
        name: &str,
        dir: &Path,
        rotate_bytes: u64,
        files: &mut Vec<PathBuf>,
    ) -> std::io::Result<()> {
        if self.file.is_none() {
            let path = self.path(name, dir);
            let file = File::create(&path)?;
            File::open(dir).and_then(|d| d.sync_all())?;
            files.push(path);
            self.file = Some(BufWriter::with_capacity(64 * 1024, file));
            self.printed = None;
            self.bytes = 0;
        }
        let header = (self.text.clone(), self.columns.clone());
        if self.printed.as_ref() != Some(&header) {
            let mut text = String::new();
            let _ = write_header(&mut text, self.index, &header.0, header.1.as_deref());
            if let Some(w) = self.file.as_mut() {
                w.write_all(text.as_bytes())?;
            }
            self.bytes += text.len() as u64;
            self.printed = Some(header);
        }
        if let Some(w) = self.file.as_mut() {
            w.write_all(line)?;
        }
        self.bytes += line.len() as u64;
        if self.bytes >= rotate_bytes {
            if let Some(mut w) = self.file.take() {
                w.flush()?;
                w.get_ref().sync_all()?;
            }
            self.sequence += 1;
        }
        Ok(())
    }
}

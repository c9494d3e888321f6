//! Encoding records into a caller's buffer (no allocation): the writer side of the format.
//!
//! A task declares each of its formats once as a [`LogFormat`] const; the logger gives it an
//! index, writes its Format Definition and Comment, and then the task encodes Data Blocks
//! with a [`DataBlockWriter`] (typed, checked field by field against the parsed format) or
//! from a `&[Value]`.

use super::format::{Format, FormatError};
use super::printf::Value;

/// Record type bytes (`log-format.md`, "Records").
pub mod kind {
    pub const BEGIN_DATA: u8 = 0xBD;
    pub const END_DATA: u8 = 0xED;
    pub const FORMAT_COMMENT: u8 = 0xFC;
    pub const FORMAT_DEFINITION: u8 = 0xFD;
    pub const DATA_BLOCK: u8 = 0xDB;
    /// What writers emit for a Byte Array.
    pub const BYTE_ARRAY: u8 = 0xBA;
    /// The thesis's other name for a Byte Array; readers accept it.
    pub const BYTE_ARRAY_LEGACY: u8 = 0xDA;
}

/// Bytes of the record header (type, index, length).
pub const HEADER_LEN: usize = 4;
/// Bytes of a TIME field.
pub const TIME_LEN: usize = 8;
/// The longest variable part a record can declare.
pub const MAX_PAYLOAD_LEN: usize = u16::MAX as usize;
/// The longest record: a Data Block or Byte Array with the longest variable part.
pub const MAX_RECORD_LEN: usize = HEADER_LEN + TIME_LEN + MAX_PAYLOAD_LEN;

const NANOS_PER_SECOND: u64 = 1_000_000_000;

/// A record's TIME: a C `timespec` of an i32 and a u32.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Time {
    pub sec: i32,
    /// 0..=999 999 999 in a well-formed record.
    pub nsec: u32,
}

impl Time {
    /// The TIME of a clock reading in ns; `None` past `i32::MAX` seconds (year 2038 for a
    /// wall clock: the format's own limit).
    pub fn from_ns(t_ns: u64) -> Option<Time> {
        let sec = i32::try_from(t_ns / NANOS_PER_SECOND).ok()?;
        let nsec = u32::try_from(t_ns % NANOS_PER_SECOND).ok()?;
        Some(Time { sec, nsec })
    }

    pub fn to_bytes(self) -> [u8; TIME_LEN] {
        let mut bytes = [0u8; TIME_LEN];
        let (sec, nsec) = bytes.split_at_mut(4);
        sec.copy_from_slice(&self.sec.to_le_bytes());
        nsec.copy_from_slice(&self.nsec.to_le_bytes());
        bytes
    }

    pub fn from_bytes(bytes: [u8; TIME_LEN]) -> Time {
        let [s0, s1, s2, s3, n0, n1, n2, n3] = bytes;
        Time {
            sec: i32::from_le_bytes([s0, s1, s2, s3]),
            nsec: u32::from_le_bytes([n0, n1, n2, n3]),
        }
    }

    pub fn is_valid(self) -> bool {
        u64::from(self.nsec) < NANOS_PER_SECOND
    }
}

/// `<tv_sec>.<tv_nsec as 9 digits>`, as the CSV time column prints it.
impl core::fmt::Display for Time {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}.{:09}", self.sec, self.nsec)
    }
}

/// Why a record could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The buffer is smaller than the record.
    BufferTooSmall { needed: usize },
    /// Text or bytes longer than a record can hold.
    TooLong,
    /// Format index 0 is reserved for records without a format.
    ZeroIndex,
    /// The time is past what an i32 of seconds holds.
    TimeOutOfRange,
    /// A value of the wrong type for its field (`field` counts from 0).
    TypeMismatch { field: usize },
    /// More values than the format has fields.
    TooManyValues,
    /// Fewer values than the format has fields.
    MissingValues { given: usize },
    /// A byte array needs a format with exactly one one-byte conversion.
    NotByteArrayFormat,
    /// The format string is invalid.
    InvalidFormat(FormatError),
    /// The column names do not match the format's fields.
    ColumnCountMismatch { fields: usize, columns: usize },
    /// A column name that is not a short identifier (`[A-Za-z0-9_]`).
    InvalidColumnName,
}

/// A log format as a task declares it, once, as a const: the printf format string and the
/// comma-separated column names (with units, per conventions.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LogFormat {
    pub format: &'static str,
    pub columns: &'static str,
}

impl LogFormat {
    pub const fn new(format: &'static str, columns: &'static str) -> Self {
        Self { format, columns }
    }

    /// Parses the format and checks that there is one column name per field (a byte-array
    /// format has one column too). Tasks call this once at init; a test per task calls it on
    /// each of its consts.
    pub fn parse(&self) -> Result<Format, EncodeError> {
        let format = Format::parse(self.format).map_err(EncodeError::InvalidFormat)?;
        let columns = if self.columns.is_empty() {
            0
        } else {
            self.columns.split(',').count()
        };
        let fields = format.fields().len();
        if columns != fields {
            return Err(EncodeError::ColumnCountMismatch { fields, columns });
        }
        Ok(format)
    }

    /// Encodes this format's Format Definition followed by its Format Comment at `index`;
    /// returns the bytes written.
    pub fn encode_declaration(&self, buf: &mut [u8], index: u8) -> Result<usize, EncodeError> {
        let definition = encode_format_definition(buf, index, self.format)?;
        let rest = buf.get_mut(definition..).unwrap_or(&mut []);
        let comment = encode_format_comment(rest, index, self.columns)?;
        Ok(definition + comment)
    }
}

fn write_header(
    buf: &mut [u8],
    kind: u8,
    index: u8,
    len: usize,
    total: usize,
) -> Result<(), EncodeError> {
    let len = u16::try_from(len).map_err(|_| EncodeError::TooLong)?;
    if buf.len() < total {
        return Err(EncodeError::BufferTooSmall { needed: total });
    }
    let [l0, l1] = len.to_le_bytes();
    let header = buf
        .get_mut(..HEADER_LEN)
        .ok_or(EncodeError::BufferTooSmall { needed: total })?;
    header.copy_from_slice(&[kind, index, l0, l1]);
    Ok(())
}

fn write_at(buf: &mut [u8], offset: usize, bytes: &[u8]) -> Result<(), EncodeError> {
    let needed = offset + bytes.len();
    buf.get_mut(offset..needed)
        .ok_or(EncodeError::BufferTooSmall { needed })?
        .copy_from_slice(bytes);
    Ok(())
}

pub(crate) fn time_bytes(t_ns: u64) -> Result<[u8; TIME_LEN], EncodeError> {
    Ok(Time::from_ns(t_ns)
        .ok_or(EncodeError::TimeOutOfRange)?
        .to_bytes())
}

fn encode_marker(buf: &mut [u8], kind: u8, t_ns: u64) -> Result<usize, EncodeError> {
    let time = time_bytes(t_ns)?;
    let total = HEADER_LEN + TIME_LEN;
    write_header(buf, kind, 0, 0, total)?;
    write_at(buf, HEADER_LEN, &time)?;
    Ok(total)
}

/// The header and TIME of a Data Block whose `data_len` bytes of data are already in place
/// after them (the declared records' encoder writes the values first).
pub(crate) fn encode_data_header(
    buf: &mut [u8],
    index: u8,
    time: &[u8; TIME_LEN],
    data_len: usize,
) -> Result<(), EncodeError> {
    if index == 0 {
        return Err(EncodeError::ZeroIndex);
    }
    write_header(
        buf,
        kind::DATA_BLOCK,
        index,
        data_len,
        HEADER_LEN + TIME_LEN + data_len,
    )?;
    write_at(buf, HEADER_LEN, time)
}

/// Begin Data: a task started logging at `t_ns`. Returns the bytes written (12).
pub fn encode_begin_data(buf: &mut [u8], t_ns: u64) -> Result<usize, EncodeError> {
    encode_marker(buf, kind::BEGIN_DATA, t_ns)
}

/// End Data: a task stopped logging at `t_ns`. Returns the bytes written (12).
pub fn encode_end_data(buf: &mut [u8], t_ns: u64) -> Result<usize, EncodeError> {
    encode_marker(buf, kind::END_DATA, t_ns)
}

fn encode_text(buf: &mut [u8], kind: u8, index: u8, text: &str) -> Result<usize, EncodeError> {
    if index == 0 {
        return Err(EncodeError::ZeroIndex);
    }
    let total = HEADER_LEN + text.len();
    write_header(buf, kind, index, text.len(), total)?;
    write_at(buf, HEADER_LEN, text.as_bytes())?;
    Ok(total)
}

/// Format Definition: `text` is the printf format string of format `index` (checked).
pub fn encode_format_definition(
    buf: &mut [u8],
    index: u8,
    text: &str,
) -> Result<usize, EncodeError> {
    Format::parse(text).map_err(EncodeError::InvalidFormat)?;
    encode_text(buf, kind::FORMAT_DEFINITION, index, text)
}

/// Format Comment: the column names of format `index`, comma-separated.
pub fn encode_format_comment(buf: &mut [u8], index: u8, text: &str) -> Result<usize, EncodeError> {
    encode_text(buf, kind::FORMAT_COMMENT, index, text)
}

/// Byte Array (written as 0xBA): `bytes` each printed with format `index`'s one conversion.
pub fn encode_byte_array(
    buf: &mut [u8],
    index: u8,
    t_ns: u64,
    bytes: &[u8],
) -> Result<usize, EncodeError> {
    if index == 0 {
        return Err(EncodeError::ZeroIndex);
    }
    let time = time_bytes(t_ns)?;
    let total = HEADER_LEN + TIME_LEN + bytes.len();
    write_header(buf, kind::BYTE_ARRAY, index, bytes.len(), total)?;
    write_at(buf, HEADER_LEN, &time)?;
    write_at(buf, HEADER_LEN + TIME_LEN, bytes)?;
    Ok(total)
}

/// Data Block from values, each checked against its field's type.
pub fn encode_data_block(
    buf: &mut [u8],
    index: u8,
    t_ns: u64,
    format: &Format,
    values: &[Value],
) -> Result<usize, EncodeError> {
    values
        .iter()
        .fold(DataBlockWriter::new(buf, index, t_ns, format), |w, &v| {
            w.value(v)
        })
        .finish()
}

/// Builds a Data Block in place, one typed field at a time:
///
/// ```
/// # use skyframe_core::logfmt::{LogFormat, DataBlockWriter};
/// const IMU: LogFormat = LogFormat::new("%u,%f", "seq,p_rad_s");
/// let format = IMU.parse().unwrap();
/// let mut buf = [0u8; 64];
/// let len = DataBlockWriter::new(&mut buf, 3, 1_500_000_000, &format)
///     .u32(7)
///     .f32(0.25)
///     .finish()
///     .unwrap();
/// assert_eq!(len, 12 + 8);
/// ```
///
/// The first error (wrong type, too many values, small buffer) sticks and `finish` returns it.
pub struct DataBlockWriter<'b, 'f> {
    buf: &'b mut [u8],
    format: &'f Format,
    index: u8,
    next_field: usize,
    offset: usize,
    error: Option<EncodeError>,
}

impl<'b, 'f> DataBlockWriter<'b, 'f> {
    pub fn new(buf: &'b mut [u8], index: u8, t_ns: u64, format: &'f Format) -> Self {
        let mut writer = Self {
            buf,
            format,
            index,
            next_field: 0,
            offset: HEADER_LEN + TIME_LEN,
            error: None,
        };
        let result = if index == 0 {
            Err(EncodeError::ZeroIndex)
        } else {
            time_bytes(t_ns).and_then(|time| write_at(writer.buf, HEADER_LEN, &time))
        };
        writer.error = result.err();
        writer
    }

    /// Appends the next field's value; it must have the field's type.
    pub fn value(mut self, value: Value) -> Self {
        if self.error.is_some() {
            return self;
        }
        let field = self.next_field;
        match self.format.fields().get(field) {
            None => self.error = Some(EncodeError::TooManyValues),
            Some(f) if f.ty != value.field_type() => {
                self.error = Some(EncodeError::TypeMismatch { field })
            }
            Some(_) => match self
                .buf
                .get_mut(self.offset..)
                .and_then(|rest| value.encode(rest))
            {
                Some(written) => {
                    self.offset += written;
                    self.next_field += 1;
                }
                None => {
                    self.error = Some(EncodeError::BufferTooSmall {
                        needed: HEADER_LEN + TIME_LEN + self.format.data_len(),
                    })
                }
            },
        }
        self
    }

    pub fn i8(self, v: i8) -> Self {
        self.value(Value::I8(v))
    }
    pub fn u8(self, v: u8) -> Self {
        self.value(Value::U8(v))
    }
    pub fn i16(self, v: i16) -> Self {
        self.value(Value::I16(v))
    }
    pub fn u16(self, v: u16) -> Self {
        self.value(Value::U16(v))
    }
    pub fn i32(self, v: i32) -> Self {
        self.value(Value::I32(v))
    }
    pub fn u32(self, v: u32) -> Self {
        self.value(Value::U32(v))
    }
    pub fn i64(self, v: i64) -> Self {
        self.value(Value::I64(v))
    }
    pub fn u64(self, v: u64) -> Self {
        self.value(Value::U64(v))
    }
    pub fn f32(self, v: f32) -> Self {
        self.value(Value::F32(v))
    }
    pub fn f64(self, v: f64) -> Self {
        self.value(Value::F64(v))
    }

    /// Writes the header once every field has a value; returns the record's length.
    pub fn finish(self) -> Result<usize, EncodeError> {
        if let Some(error) = self.error {
            return Err(error);
        }
        if self.next_field != self.format.fields().len() {
            return Err(EncodeError::MissingValues {
                given: self.next_field,
            });
        }
        let data_len = self.offset - HEADER_LEN - TIME_LEN;
        write_header(
            self.buf,
            kind::DATA_BLOCK,
            self.index,
            data_len,
            self.offset,
        )?;
        Ok(self.offset)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spec_example_bytes() {
        let format = Format::parse("%u,%hd,%.3f,%lf").expect("valid");
        let mut buf = [0u8; 64];
        let len = DataBlockWriter::new(&mut buf, 1, 2_000_000_005, &format)
            .u32(7)
            .i16(-2)
            .f32(1.5)
            .f64(0.25)
            .finish()
            .expect("encodes");
        let mut expected = std::vec![
            0xDB, 1, 18, 0, 2, 0, 0, 0, 5, 0, 0, 0, 7, 0, 0, 0, 0xFE, 0xFF
        ];
        expected.extend_from_slice(&1.5f32.to_le_bytes());
        expected.extend_from_slice(&0.25f64.to_le_bytes());
        assert_eq!(&buf[..len], &expected[..]);
    }

    #[test]
    fn writer_checks_types_and_counts() {
        let format = Format::parse("%u,%f").expect("valid");
        let mut buf = [0u8; 64];
        assert_eq!(
            DataBlockWriter::new(&mut buf, 1, 0, &format)
                .u32(1)
                .f64(1.0)
                .finish(),
            Err(EncodeError::TypeMismatch { field: 1 })
        );
        assert_eq!(
            DataBlockWriter::new(&mut buf, 1, 0, &format)
                .u32(1)
                .finish(),
            Err(EncodeError::MissingValues { given: 1 })
        );
        assert_eq!(
            DataBlockWriter::new(&mut buf, 1, 0, &format)
                .u32(1)
                .f32(1.0)
                .u8(1)
                .finish(),
            Err(EncodeError::TooManyValues)
        );
        assert_eq!(
            DataBlockWriter::new(&mut buf[..15], 1, 0, &format)
                .u32(1)
                .f32(1.0)
                .finish(),
            Err(EncodeError::BufferTooSmall { needed: 20 })
        );
        assert_eq!(
            DataBlockWriter::new(&mut buf, 0, 0, &format)
                .u32(1)
                .f32(1.0)
                .finish(),
            Err(EncodeError::ZeroIndex)
        );
        assert_eq!(
            DataBlockWriter::new(&mut buf, 1, u64::MAX, &format)
                .u32(1)
                .f32(1.0)
                .finish(),
            Err(EncodeError::TimeOutOfRange)
        );
    }

    #[test]
    fn markers_and_texts() {
        let mut buf = [0u8; 64];
        assert_eq!(encode_begin_data(&mut buf, 1_000_000_001), Ok(12));
        assert_eq!(&buf[..12], &[0xBD, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0]);
        assert_eq!(encode_end_data(&mut buf, 0), Ok(12));
        assert_eq!(buf[0], 0xED);
        const F: LogFormat = LogFormat::new("%d", "x_m");
        assert_eq!(F.encode_declaration(&mut buf, 9), Ok(6 + 7));
        assert_eq!(&buf[..13], b"\xFD\x09\x02\x00%d\xFC\x09\x03\x00x_m");
        assert_eq!(
            encode_format_definition(&mut buf, 1, "%s"),
            Err(EncodeError::InvalidFormat(
                FormatError::UnsupportedConversion {
                    at: 0,
                    specifier: b's'
                }
            ))
        );
        assert_eq!(encode_byte_array(&mut buf, 2, 0, &[1, 2]), Ok(14));
        assert_eq!(&buf[..4], &[0xBA, 2, 2, 0]);
    }

    #[test]
    fn log_format_checks_columns() {
        assert!(LogFormat::new("%d,%f", "a,b").parse().is_ok());
        assert_eq!(
            LogFormat::new("%d,%f", "a").parse(),
            Err(EncodeError::ColumnCountMismatch {
                fields: 2,
                columns: 1
            })
        );
    }
}

//! The lines of a text log (`log-format.md`, "Text logs and CSV conversion"), written to a
//! caller's sink without allocating.
//!
//! `skyframe-log to-csv` writes its CSV files with these functions, and a task writing a text
//! log directly uses the same ones, so a text log and the conversion of the equivalent binary
//! log are identical by construction:
//!
//! - [`write_format_line`]: `% format <index>: <format string>\n`;
//! - [`write_columns_line`]: `% time,<comment>\n` (only where the format has a comment);
//! - [`write_header`]: both, in that order;
//! - [`write_data_line`]: `<tv_sec>.<tv_nsec, 9 digits>,<printf text of the data block>\n`;
//! - [`write_values_line`]: the same from the record's values (a task's text log: no binary
//!   record needed);
//! - [`write_byte_array_line`]: the same for a byte array (each byte formatted, joined by `,`).
//!
//! Every line ends with `\n`. The data lines write to a [`ByteWrite`] because C's `%c` prints
//! any byte; on an error part of the line may already be written, so a caller that must not
//! leave half a line renders into a line buffer first (as `to-csv` does).

use core::fmt::{self, Write};

use super::format::{Format, MAX_FIELDS};
use super::printf::{
    ByteWrite, RenderError, Value, render_byte_array_bytes, render_data_block_bytes,
};
use super::record::Time;

/// The largest data block a format can describe: every field 8 bytes.
const MAX_DATA_LEN: usize = MAX_FIELDS * 8;

/// Writes `% format <index>: <format text>\n`.
pub fn write_format_line<W: Write + ?Sized>(
    out: &mut W,
    index: u8,
    format_text: &str,
) -> fmt::Result {
    writeln!(out, "% format {index}: {format_text}")
}

/// Writes `% time,<columns>\n`, the column names of a format (the text of its Format
/// Comment).
pub fn write_columns_line<W: Write + ?Sized>(out: &mut W, columns: &str) -> fmt::Result {
    writeln!(out, "% time,{columns}")
}

/// Writes the header of a format's lines: the format line, then the columns line when the
/// format has a comment.
pub fn write_header<W: Write + ?Sized>(
    out: &mut W,
    index: u8,
    format_text: &str,
    columns: Option<&str>,
) -> fmt::Result {
    write_format_line(out, index, format_text)?;
    if let Some(columns) = columns {
        write_columns_line(out, columns)?;
    }
    Ok(())
}

/// Writes the line of a data block: `<time>,<printf text>\n`. `format` is `format_text`
/// parsed; `data` the block's packed fields.
pub fn write_data_line<W: ByteWrite + ?Sized>(
    out: &mut W,
    time: Time,
    format_text: &str,
    format: &Format,
    data: &[u8],
) -> Result<(), RenderError> {
    write_time(out, time)?;
    render_data_block_bytes(out, format_text, format, data)?;
    out.write_char('\n')?;
    Ok(())
}

/// Writes the line of a data block given as values, one per field of `format` and of its
/// type: the same bytes as [`write_data_line`] over the encoded block. Nothing is written
/// when the values do not fit the format ([`RenderError::DataMismatch`]).
pub fn write_values_line<W: ByteWrite + ?Sized>(
    out: &mut W,
    time: Time,
    format_text: &str,
    format: &Format,
    values: &[Value],
) -> Result<(), RenderError> {
    let fields = format.fields();
    if fields.len() != values.len() {
        return Err(RenderError::DataMismatch);
    }
    let mut data = [0u8; MAX_DATA_LEN];
    let mut len = 0;
    for (field, value) in fields.iter().zip(values) {
        if field.ty != value.field_type() {
            return Err(RenderError::DataMismatch);
        }
        let rest = data.get_mut(len..).ok_or(RenderError::DataMismatch)?;
        len += value.encode(rest).ok_or(RenderError::DataMismatch)?;
    }
    let data = data.get(..len).ok_or(RenderError::DataMismatch)?;
    write_data_line(out, time, format_text, format, data)
}

/// Writes the line of a byte array: `<time>,<byte>,<byte>,…\n`, each byte printed with the
/// format (which has exactly one one-byte conversion).
pub fn write_byte_array_line<W: ByteWrite + ?Sized>(
    out: &mut W,
    time: Time,
    format_text: &str,
    format: &Format,
    bytes: &[u8],
) -> Result<(), RenderError> {
    write_time(out, time)?;
    render_byte_array_bytes(out, format_text, format, bytes)?;
    out.write_char('\n')?;
    Ok(())
}

/// Writes `<tv_sec>.<tv_nsec, at least 9 digits>,`: exactly what `write!(out, "{time},")`
/// prints (`Time`'s `Display`), without core::fmt's machinery, which took a tenth of
/// `to-csv`'s time once the fields were fast.
fn write_time<W: ByteWrite + ?Sized>(out: &mut W, time: Time) -> fmt::Result {
    // Sign, 10 digits, point, 10 digits, comma: 23 bytes at most.
    let mut buf = [0u8; 32];
    let mut start = buf.len();
    let mut put = |byte: u8| -> fmt::Result {
        start = start.checked_sub(1).ok_or(fmt::Error)?;
        *buf.get_mut(start).ok_or(fmt::Error)? = byte;
        Ok(())
    };
    put(b',')?;
    let mut nsec = time.nsec;
    let mut digits = 0;
    while nsec > 0 || digits < 9 {
        put(b'0' + u8::try_from(nsec % 10).map_err(|_| fmt::Error)?)?;
        nsec /= 10;
        digits += 1;
    }
    put(b'.')?;
    let mut sec = time.sec.unsigned_abs();
    loop {
        put(b'0' + u8::try_from(sec % 10).map_err(|_| fmt::Error)?)?;
        sec /= 10;
        if sec == 0 {
            break;
        }
    }
    if time.sec < 0 {
        put(b'-')?;
    }
    let text = buf.get(start..).ok_or(fmt::Error)?;
    out.write_ascii(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fixed byte buffer, as a task would use.
    struct Buf {
        bytes: [u8; 128],
        len: usize,
    }

    impl Buf {
        fn new() -> Self {
            Self {
                bytes: [0; 128],
                len: 0,
            }
        }
        fn as_bytes(&self) -> &[u8] {
            &self.bytes[..self.len]
        }
    }

    impl Write for Buf {
        fn write_str(&mut self, s: &str) -> fmt::Result {
            s.bytes().try_for_each(|b| self.write_byte(b))
        }
    }

    impl ByteWrite for Buf {
        fn write_byte(&mut self, byte: u8) -> fmt::Result {
            let slot = self.bytes.get_mut(self.len).ok_or(fmt::Error)?;
            *slot = byte;
            self.len += 1;
            Ok(())
        }
    }

    #[test]
    fn the_time_prefix_is_what_display_prints() {
        // Extremes of both fields, one-digit seconds, negative times, and a tv_nsec above
        // 10⁹ (a damaged record's value, printed with all its digits as `{:09}` does).
        let secs = [0, 1, -1, 7, 1_700_000_000, i32::MAX, i32::MIN, -42];
        let nsecs = [
            0,
            1,
            5,
            10,
            999_999_999,
            123_456_789,
            1_000_000_000,
            u32::MAX,
        ];
        for sec in secs {
            for nsec in nsecs {
                let time = Time { sec, nsec };
                let mut ours = Buf::new();
                write_time(&mut ours, time).expect("fits");
                assert_eq!(ours.as_bytes(), std::format!("{time},").as_bytes());
            }
        }
    }

    #[test]
    fn header_lines() {
        let mut out = Buf::new();
        write_header(&mut out, 1, "%u,%hd,%.3f,%lf", Some("count,delta,x_m,y_m")).expect("valid");
        assert_eq!(
            out.as_bytes(),
            b"% format 1: %u,%hd,%.3f,%lf\n% time,count,delta,x_m,y_m\n"
        );
        let mut out = Buf::new();
        write_header(&mut out, 255, "%c", None).expect("valid");
        assert_eq!(out.as_bytes(), b"% format 255: %c\n");
    }

    #[test]
    fn data_line_of_the_spec_example() {
        let text = "%u,%hd,%.3f,%lf";
        let format = Format::parse(text).expect("valid");
        let mut data = [0u8; 18];
        data[..4].copy_from_slice(&7u32.to_le_bytes());
        data[4..6].copy_from_slice(&(-2i16).to_le_bytes());
        data[6..10].copy_from_slice(&1.5f32.to_le_bytes());
        data[10..].copy_from_slice(&0.25f64.to_le_bytes());
        let mut out = Buf::new();
        let time = Time { sec: 1, nsec: 5 };
        write_data_line(&mut out, time, text, &format, &data).expect("valid");
        assert_eq!(out.as_bytes(), b"1.000000005,7,-2,1.500,0.250000\n");
        // A block whose length contradicts its format is refused.
        assert_eq!(
            write_data_line(&mut Buf::new(), time, text, &format, &data[..17]),
            Err(RenderError::DataMismatch)
        );
    }

    #[test]
    fn values_lines_equal_data_lines() {
        let text = "%hhu,%.3f,%lld,%8.2lf";
        let format = Format::parse(text).expect("valid");
        let values = [
            Value::U8(200),
            Value::F32(-0.5),
            Value::I64(-3),
            Value::F64(f64::NAN),
        ];
        let mut data = [0u8; 21];
        let mut len = 0;
        for v in values {
            len += v.encode(&mut data[len..]).expect("fits");
        }
        assert_eq!(len, format.data_len());
        let time = Time { sec: 12, nsec: 340 };
        let mut from_values = Buf::new();
        write_values_line(&mut from_values, time, text, &format, &values).expect("valid");
        let mut from_bytes = Buf::new();
        write_data_line(&mut from_bytes, time, text, &format, &data).expect("valid");
        assert_eq!(
            from_values.as_bytes(),
            b"12.000000340,200,-0.500,-3,     nan\n"
        );
        assert_eq!(from_values.as_bytes(), from_bytes.as_bytes());
        // A value of the wrong type, or too few values, writes nothing.
        let mut out = Buf::new();
        let wrong = [
            Value::U8(1),
            Value::F64(0.0),
            Value::I64(0),
            Value::F64(0.0),
        ];
        assert_eq!(
            write_values_line(&mut out, time, text, &format, &wrong),
            Err(RenderError::DataMismatch)
        );
        assert_eq!(
            write_values_line(&mut out, time, text, &format, &values[..3]),
            Err(RenderError::DataMismatch)
        );
        assert_eq!(out.as_bytes(), b"");
    }

    #[test]
    fn byte_array_lines_print_raw_bytes() {
        let hex = Format::parse("%02hhx").expect("valid");
        let mut out = Buf::new();
        let time = Time {
            sec: 2,
            nsec: 999_999_999,
        };
        write_byte_array_line(&mut out, time, "%02hhx", &hex, &[0x0a, 0xff, 0]).expect("valid");
        assert_eq!(out.as_bytes(), b"2.999999999,0a,ff,00\n");
        // `%c` prints the byte itself, not UTF-8.
        let chars = Format::parse("%c").expect("valid");
        let mut out = Buf::new();
        write_byte_array_line(&mut out, Time::default(), "%c", &chars, &[b'A', 0xe9])
            .expect("valid");
        assert_eq!(out.as_bytes(), b"0.000000000,A,\xe9\n");
        // A format with two fields is no byte array format.
        let two = Format::parse("%hhu%hhu").expect("valid");
        assert_eq!(
            write_byte_array_line(&mut Buf::new(), time, "%hhu%hhu", &two, &[1]),
            Err(RenderError::DataMismatch)
        );
    }

    #[test]
    fn a_full_sink_is_an_error_not_a_panic() {
        let text = "%u";
        let format = Format::parse(text).expect("valid");
        let mut out = Buf::new();
        let long = [b'x'; 125];
        let columns = core::str::from_utf8(&long).expect("valid");
        assert_eq!(write_columns_line(&mut out, columns), Err(fmt::Error));
        assert_eq!(
            write_data_line(&mut out, Time::default(), text, &format, &[1, 0, 0, 0]),
            Err(RenderError::Write)
        );
    }
}

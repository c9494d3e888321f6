//! One declaration per logged record.
//!
//! A task's record is one Rust struct declared with [`log_record!`](crate::log_record): each
//! field names its column (with its unit, per `conventions.md`) and its printf conversion.
//! From that one declaration come the log's Format Definition and Format Comment
//! ([`LogRecord::FORMAT`]), the Data Block's bytes ([`encode_record`]), the CSV and ULog
//! columns (the converters read the Format Comment back) and the telemetry values
//! ([`LogRecord::each_value`]): nothing else lists a record's columns, and nothing parses the
//! bytes the log writer has just been given to find out what a task logged.
//!
//! ```
//! skyframe_core::log_record! {
//!     /// What a barometer logs each step.
//!     pub struct BaroLog {
//!         pressure_pa: f32 = "%.1f",
//!         temperature_c: f32 = "%.2f",
//!         healthy: u8 = "%hhu",
//!     }
//! }
//! use skyframe_core::logfmt::LogRecord;
//! assert_eq!(BaroLog::FORMAT.format, "%.1f,%.2f,%hhu");
//! assert_eq!(BaroLog::FORMAT.columns, "pressure_pa,temperature_c,healthy");
//! assert_eq!(BaroLog::check(), Ok(()));
//! ```

use super::format::Format;
use super::printf::Value;
use super::record::{EncodeError, HEADER_LEN, LogFormat, TIME_LEN, encode_data_header, time_bytes};

/// The most fields a declared record may have (a telemetry message carries as many).
pub const MAX_RECORD_FIELDS: usize = 32;

/// A Rust type that is a column of a log record.
pub trait LogField: Copy {
    fn log_value(self) -> Value;
}

macro_rules! log_fields {
    ($($ty:ty => $variant:ident),+ $(,)?) => {
        $(impl LogField for $ty {
            fn log_value(self) -> Value {
                Value::$variant(self)
            }
        })+
    };
}
log_fields!(i8 => I8, u8 => U8, i16 => I16, u16 => U16, i32 => I32, u32 => U32,
    i64 => I64, u64 => U64, f32 => F32, f64 => F64);

/// A flag logs as `%hhu`, 0 or 1.
impl LogField for bool {
    fn log_value(self) -> Value {
        Value::U8(u8::from(self))
    }
}

/// A record declared with [`log_record!`](crate::log_record).
pub trait LogRecord {
    /// The format string and the column names, as the log declares them.
    const FORMAT: LogFormat;

    /// Calls `f` with each field's value, in column order.
    fn each_value(&self, f: &mut impl FnMut(Value));

    /// Whether the declaration is sound: a valid format, one column per field, and each
    /// field's Rust type the type its conversion reads. Tasks call it when they declare the
    /// record; a test per record calls it too.
    fn check() -> Result<(), EncodeError>
    where
        Self: Default,
    {
        let format: Format = Self::FORMAT.parse()?;
        let mut field = 0usize;
        let mut result = Ok(());
        Self::default().each_value(&mut |value| {
            let expected = format.fields().get(field).map(|f| f.ty);
            if result.is_ok() && expected != Some(value.field_type()) {
                result = Err(EncodeError::TypeMismatch { field });
            }
            field += 1;
        });
        result?;
        if field != format.fields().len() || field > MAX_RECORD_FIELDS {
            return Err(EncodeError::ColumnCountMismatch {
                fields: format.fields().len(),
                columns: field,
            });
        }
        Ok(())
    }
}

/// Encodes `record` as a Data Block of format `index` at `t_ns` into `buf`; returns the bytes
/// written. The types were checked against the format once ([`LogRecord::check`]), so the
/// values are written as they come, without a parsed format.
pub fn encode_record<R: LogRecord>(
    buf: &mut [u8],
    index: u8,
    t_ns: u64,
    record: &R,
) -> Result<usize, EncodeError> {
    let time = time_bytes(t_ns)?;
    let mut offset = HEADER_LEN + TIME_LEN;
    let mut error = None;
    record.each_value(&mut |value| {
        if error.is_some() {
            return;
        }
        match buf.get_mut(offset..).and_then(|rest| value.encode(rest)) {
            Some(written) => offset += written,
            None => error = Some(EncodeError::BufferTooSmall { needed: offset + 8 }),
        }
    });
    if let Some(error) = error {
        return Err(error);
    }
    encode_data_header(buf, index, &time, offset - HEADER_LEN - TIME_LEN)?;
    Ok(offset)
}

/// The values of `record` in column order, for a sink that keeps them (the telemetry tap).
pub fn record_values<R: LogRecord>(record: &R) -> heapless::Vec<Value, MAX_RECORD_FIELDS> {
    let mut values = heapless::Vec::new();
    record.each_value(&mut |v| {
        // A declaration wider than this is refused by `check`.
        let _ = values.push(v);
    });
    values
}

/// Declares a logged record: a struct, its format string and column names, its encoder and
/// its telemetry values, from one list of `column: type = "conversion"`.
///
/// The column names are the field names, so they follow Rust's identifier rules, which are
/// the log's own (`[A-Za-z0-9_]`); a `bool` field logs as `%hhu`.
#[macro_export]
macro_rules! log_record {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $( $(#[$field_meta:meta])* $field:ident : $ty:ty = $conversion:literal ),+ $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, Default, PartialEq)]
        $vis struct $name {
            $( $(#[$field_meta])* pub $field: $ty, )+
        }

        impl $crate::logfmt::LogRecord for $name {
            const FORMAT: $crate::logfmt::LogFormat = $crate::logfmt::LogFormat::new(
                $crate::__log_join!($($conversion),+),
                $crate::__log_join!($(stringify!($field)),+),
            );

            fn each_value(&self, f: &mut impl FnMut($crate::logfmt::Value)) {
                $( f($crate::logfmt::LogField::log_value(self.$field)); )+
            }
        }
    };
}

/// `"a", "b", "c"` → `"a,b,c"` at compile time.
#[doc(hidden)]
#[macro_export]
macro_rules! __log_join {
    ($first:expr $(, $rest:expr)*) => {
        concat!($first $(, ",", $rest)*)
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::logfmt::record::DataBlockWriter;

    crate::log_record! {
        /// A record of every field type.
        struct Every {
            a_i8: i8 = "%hhd",
            b_u8: u8 = "%hhu",
            c_i16: i16 = "%hd",
            d_u16: u16 = "%hu",
            e_i32: i32 = "%d",
            f_u32: u32 = "%u",
            g_i64: i64 = "%lld",
            h_u64: u64 = "%llu",
            i_f32: f32 = "%.3f",
            j_f64: f64 = "%.8lf",
            k_flag: bool = "%hhu",
        }
    }

    crate::log_record! {
        struct Mistyped {
            x: f64 = "%.3f",
        }
    }

    #[test]
    fn the_declaration_gives_the_format_and_the_columns() {
        assert_eq!(
            Every::FORMAT.format,
            "%hhd,%hhu,%hd,%hu,%d,%u,%lld,%llu,%.3f,%.8lf,%hhu"
        );
        assert_eq!(
            Every::FORMAT.columns,
            "a_i8,b_u8,c_i16,d_u16,e_i32,f_u32,g_i64,h_u64,i_f32,j_f64,k_flag"
        );
        assert_eq!(Every::check(), Ok(()));
        assert_eq!(
            Mistyped::check(),
            Err(EncodeError::TypeMismatch { field: 0 })
        );
    }

    #[test]
    fn encoding_is_byte_for_byte_the_checked_writers() {
        let record = Every {
            a_i8: -3,
            b_u8: 200,
            c_i16: -30_000,
            d_u16: 60_000,
            e_i32: -2_000_000_000,
            f_u32: 4_000_000_000,
            g_i64: -9_000_000_000_000,
            h_u64: 18_000_000_000_000_000_000,
            i_f32: 1.25,
            j_f64: 47.397_742_1,
            k_flag: true,
        };
        let mut ours = [0u8; 128];
        let len = encode_record(&mut ours, 4, 12_345_678_901, &record).expect("encodes");
        let format = Every::FORMAT.parse().expect("parses");
        let mut theirs = [0u8; 128];
        let values = record_values(&record);
        let len_theirs = values
            .iter()
            .fold(
                DataBlockWriter::new(&mut theirs, 4, 12_345_678_901, &format),
                |w, &v| w.value(v),
            )
            .finish()
            .expect("encodes");
        assert_eq!(ours[..len], theirs[..len_theirs]);
        // Too small a buffer is an error, not a panic or a short record.
        let mut small = [0u8; 20];
        assert!(matches!(
            encode_record(&mut small, 4, 0, &record),
            Err(EncodeError::BufferTooSmall { .. })
        ));
    }
}

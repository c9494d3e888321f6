//! Printf format strings: which fields a data block holds, and how each one prints.
//!
//! The conversion specifications of a format, in order, are the fields of a data block
//! (`log-format.md`, "Format strings"). Anything the table there does not list makes the
//! whole format invalid, so a reader never guesses a field's size.

/// Most conversions one format may hold (a data block of more fields is refused as invalid).
pub const MAX_FIELDS: usize = 64;

/// Largest width or precision accepted. C accepts more, but a format asking for thousands of
/// characters per field is damage, not a log layout; refusing it bounds the rendering work.
pub const MAX_WIDTH: u16 = 4096;

/// Longest format text: its length must fit the record header's u16.
pub const MAX_FORMAT_TEXT: usize = u16::MAX as usize;

/// The binary type of one field of a data block (little-endian, packed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FieldType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl FieldType {
    /// Bytes the field takes in a data block.
    pub const fn size(self) -> usize {
        match self {
            FieldType::I8 | FieldType::U8 => 1,
            FieldType::I16 | FieldType::U16 => 2,
            FieldType::I32 | FieldType::U32 | FieldType::F32 => 4,
            FieldType::I64 | FieldType::U64 | FieldType::F64 => 8,
        }
    }

    /// The Rust name of the type, for messages.
    pub const fn name(self) -> &'static str {
        match self {
            FieldType::I8 => "i8",
            FieldType::U8 => "u8",
            FieldType::I16 => "i16",
            FieldType::U16 => "u16",
            FieldType::I32 => "i32",
            FieldType::U32 => "u32",
            FieldType::I64 => "i64",
            FieldType::U64 => "u64",
            FieldType::F32 => "f32",
            FieldType::F64 => "f64",
        }
    }
}

/// The conversion specifier of a field, which decides how its value prints.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Conversion {
    /// `d` or `i`
    Signed,
    /// `u`
    Unsigned,
    /// `x`
    HexLower,
    /// `X`
    HexUpper,
    /// `o`
    Octal,
    /// `c`
    Char,
    /// `f`
    FixedLower,
    /// `F`
    FixedUpper,
    /// `e`
    ExpLower,
    /// `E`
    ExpUpper,
    /// `g`
    GeneralLower,
    /// `G`
    GeneralUpper,
}

impl Conversion {
    /// Whether the conversion prints upper-case letters (`X`, `F`, `E`, `G`).
    pub const fn is_upper(self) -> bool {
        matches!(
            self,
            Conversion::HexUpper
                | Conversion::FixedUpper
                | Conversion::ExpUpper
                | Conversion::GeneralUpper
        )
    }
}

/// The printf flags of one conversion, as a bit set.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Flags(pub u8);

impl Flags {
    /// `-`: left-justify within the width.
    pub const LEFT: u8 = 1 << 0;
    /// `+`: always print a sign on signed conversions.
    pub const PLUS: u8 = 1 << 1;
    /// ` `: a space where a positive signed value has no sign.
    pub const SPACE: u8 = 1 << 2;
    /// `#`: the alternative form (`0x` prefix, forced decimal point, ...).
    pub const ALT: u8 = 1 << 3;
    /// `0`: pad with zeros after the sign instead of spaces before it.
    pub const ZERO: u8 = 1 << 4;

    pub const fn has(self, flag: u8) -> bool {
        self.0 & flag != 0
    }
}

/// One conversion specification of a format: a field of the data block and how it prints.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Field {
    pub ty: FieldType,
    pub conversion: Conversion,
    pub flags: Flags,
    /// Minimum width in characters (0: none).
    pub width: u16,
    pub precision: Option<u16>,
    /// Byte range of the whole specification (`%` to the specifier) in the format text, so
    /// the renderer can print the literal text between fields.
    pub span_start: u16,
    pub span_end: u16,
}

impl Field {
    const EMPTY: Field = Field {
        ty: FieldType::U8,
        conversion: Conversion::Unsigned,
        flags: Flags(0),
        width: 0,
        precision: None,
        span_start: 0,
        span_end: 0,
    };
}

/// Why a format string is invalid. `at` is the byte offset of the offending `%` in the text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FormatError {
    /// The text is not UTF-8.
    NotUtf8,
    /// The text is longer than a record can hold.
    TooLong,
    /// More than [`MAX_FIELDS`] conversions.
    TooManyFields,
    /// A `%` at the end of the text.
    Unterminated { at: u16 },
    /// A conversion the log format does not define (`%s`, `%p`, `%n`, `%a`, `%5%`, ...).
    UnsupportedConversion { at: u16, specifier: u8 },
    /// A length modifier the log format does not define (`L`, `j`, `z`, `t`, `q`), or one
    /// that does not fit the specifier (`%hf`, `%lc`, `%llf`).
    UnsupportedLength { at: u16 },
    /// A `*` width or precision: the value would come from the argument list.
    StarWidth { at: u16 },
    /// A `%n$` positional argument.
    Positional { at: u16 },
    /// A width or precision above [`MAX_WIDTH`].
    TooWide { at: u16 },
}

impl core::fmt::Display for FormatError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            FormatError::NotUtf8 => write!(f, "format text is not UTF-8"),
            FormatError::TooLong => write!(f, "format text longer than {MAX_FORMAT_TEXT} bytes"),
            FormatError::TooManyFields => write!(f, "more than {MAX_FIELDS} conversions"),
            FormatError::Unterminated { at } => write!(f, "unterminated conversion at byte {at}"),
            FormatError::UnsupportedConversion { at, specifier } => {
                if specifier.is_ascii_graphic() {
                    write!(
                        f,
                        "unsupported conversion '{}' at byte {at}",
                        char::from(specifier)
                    )
                } else {
                    write!(
                        f,
                        "unsupported conversion byte 0x{specifier:02x} at byte {at}"
                    )
                }
            }
            FormatError::UnsupportedLength { at } => {
                write!(f, "unsupported length modifier at byte {at}")
            }
            FormatError::StarWidth { at } => write!(f, "'*' width or precision at byte {at}"),
            FormatError::Positional { at } => write!(f, "positional argument at byte {at}"),
            FormatError::TooWide { at } => {
                write!(f, "width or precision above {MAX_WIDTH} at byte {at}")
            }
        }
    }
}

/// A parsed format: the fields of its data blocks, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Format {
    fields: [Field; MAX_FIELDS],
    field_count: u8,
    data_len: u16,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Length {
    None,
    Hh,
    H,
    L,
    Ll,
}

impl Format {
    /// A format with no fields (a placeholder for unused slots).
    pub const EMPTY: Format = Format {
        fields: [Field::EMPTY; MAX_FIELDS],
        field_count: 0,
        data_len: 0,
    };

    /// Parses format text as it appears in a Format Definition record (trailing NUL bytes
    /// ignored, as the spec says).
    pub fn parse_bytes(text: &[u8]) -> Result<Format, FormatError> {
        let text = core::str::from_utf8(trim_nuls(text)).map_err(|_| FormatError::NotUtf8)?;
        Format::parse(text)
    }

    /// Parses a printf format string into its fields.
    pub fn parse(text: &str) -> Result<Format, FormatError> {
        let bytes = text.as_bytes();
        if bytes.len() > MAX_FORMAT_TEXT {
            return Err(FormatError::TooLong);
        }
        let mut format = Format::EMPTY;
        let mut data_len: usize = 0;
        let mut i = 0;
        while let Some(&b) = bytes.get(i) {
            if b != b'%' {
                i += 1;
                continue;
            }
            if bytes.get(i + 1) == Some(&b'%') {
                i += 2;
                continue;
            }
            let (field, end) = parse_conversion(bytes, i)?;
            let slot = format
                .fields
                .get_mut(usize::from(format.field_count))
                .ok_or(FormatError::TooManyFields)?;
            *slot = field;
            format.field_count += 1;
            data_len += field.ty.size();
            i = end;
        }
        // At most 64 fields of 8 bytes: always fits.
        format.data_len = u16::try_from(data_len).map_err(|_| FormatError::TooManyFields)?;
        Ok(format)
    }

    /// The fields, in data-block order.
    pub fn fields(&self) -> &[Field] {
        self.fields
            .get(..usize::from(self.field_count))
            .unwrap_or(&[])
    }

    /// The size in bytes of a data block of this format (the sum of its fields' sizes).
    pub fn data_len(&self) -> usize {
        usize::from(self.data_len)
    }

    /// Whether a Byte Array record may use this format: exactly one one-byte conversion.
    pub fn is_byte_array_format(&self) -> bool {
        matches!(self.fields(), [only] if only.ty.size() == 1)
    }
}

/// The text of a Format Comment or Definition without its trailing NUL bytes.
pub fn trim_nuls(text: &[u8]) -> &[u8] {
    let mut end = text.len();
    while end > 0 && text.get(end - 1) == Some(&0) {
        end -= 1;
    }
    text.get(..end).unwrap_or(&[])
}

/// Parses the conversion specification starting at the `%` at `start`; returns the field and
/// the offset just past the specifier.
fn parse_conversion(bytes: &[u8], start: usize) -> Result<(Field, usize), FormatError> {
    // `start` < MAX_FORMAT_TEXT, checked by the caller.
    let at = u16::try_from(start).map_err(|_| FormatError::TooLong)?;
    let mut i = start + 1;
    let mut flags = 0u8;
    loop {
        let flag = match bytes.get(i) {
            Some(b'-') => Flags::LEFT,
            Some(b'+') => Flags::PLUS,
            Some(b' ') => Flags::SPACE,
            Some(b'#') => Flags::ALT,
            Some(b'0') => Flags::ZERO,
            _ => break,
        };
        flags |= flag;
        i += 1;
    }
    if bytes.get(i) == Some(&b'*') {
        return Err(FormatError::StarWidth { at });
    }
    let (width, after_width) = parse_number(bytes, i, at)?;
    if bytes.get(after_width) == Some(&b'$') {
        return Err(FormatError::Positional { at });
    }
    i = after_width;
    let mut precision = None;
    if bytes.get(i) == Some(&b'.') {
        i += 1;
        if bytes.get(i) == Some(&b'*') {
            return Err(FormatError::StarWidth { at });
        }
        let (value, after) = parse_number(bytes, i, at)?;
        precision = Some(value);
        i = after;
    }
    let length = match (bytes.get(i), bytes.get(i + 1)) {
        (Some(b'h'), Some(b'h')) => {
            i += 2;
            Length::Hh
        }
        (Some(b'h'), _) => {
            i += 1;
            Length::H
        }
        (Some(b'l'), Some(b'l')) => {
            i += 2;
            Length::Ll
        }
        (Some(b'l'), _) => {
            i += 1;
            Length::L
        }
        (Some(b'L' | b'j' | b'z' | b't' | b'q' | b'I'), _) => {
            return Err(FormatError::UnsupportedLength { at });
        }
        _ => Length::None,
    };
    let specifier = *bytes.get(i).ok_or(FormatError::Unterminated { at })?;
    let conversion = match specifier {
        b'd' | b'i' => Conversion::Signed,
        b'u' => Conversion::Unsigned,
        b'x' => Conversion::HexLower,
        b'X' => Conversion::HexUpper,
        b'o' => Conversion::Octal,
        b'c' => Conversion::Char,
        b'f' => Conversion::FixedLower,
        b'F' => Conversion::FixedUpper,
        b'e' => Conversion::ExpLower,
        b'E' => Conversion::ExpUpper,
        b'g' => Conversion::GeneralLower,
        b'G' => Conversion::GeneralUpper,
        _ => return Err(FormatError::UnsupportedConversion { at, specifier }),
    };
    let ty = match (conversion, length) {
        (Conversion::Signed, Length::Hh) => FieldType::I8,
        (Conversion::Signed, Length::H) => FieldType::I16,
        (Conversion::Signed, Length::None | Length::L) => FieldType::I32,
        (Conversion::Signed, Length::Ll) => FieldType::I64,
        (Conversion::Char, Length::None) => FieldType::U8,
        (Conversion::Char, _) => return Err(FormatError::UnsupportedLength { at }),
        (
            Conversion::FixedLower
            | Conversion::FixedUpper
            | Conversion::ExpLower
            | Conversion::ExpUpper
            | Conversion::GeneralLower
            | Conversion::GeneralUpper,
            length,
        ) => match length {
            Length::None => FieldType::F32,
            Length::L => FieldType::F64,
            _ => return Err(FormatError::UnsupportedLength { at }),
        },
        (_, Length::Hh) => FieldType::U8,
        (_, Length::H) => FieldType::U16,
        (_, Length::None | Length::L) => FieldType::U32,
        (_, Length::Ll) => FieldType::U64,
    };
    let end = i + 1;
    let field = Field {
        ty,
        conversion,
        flags: Flags(flags),
        width,
        precision,
        span_start: at,
        span_end: u16::try_from(end).map_err(|_| FormatError::TooLong)?,
    };
    Ok((field, end))
}

/// Parses decimal digits at `i` (none: 0); returns the value and the offset after them.
fn parse_number(bytes: &[u8], mut i: usize, at: u16) -> Result<(u16, usize), FormatError> {
    let mut value: u32 = 0;
    while let Some(&digit) = bytes.get(i).filter(|b| b.is_ascii_digit()) {
        value = value * 10 + u32::from(digit - b'0');
        if value > u32::from(MAX_WIDTH) {
            return Err(FormatError::TooWide { at });
        }
        i += 1;
    }
    let value = u16::try_from(value).map_err(|_| FormatError::TooWide { at })?;
    Ok((value, i))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn types(text: &str) -> std::vec::Vec<FieldType> {
        Format::parse(text)
            .expect("valid format")
            .fields()
            .iter()
            .map(|f| f.ty)
            .collect()
    }

    #[test]
    fn field_types_follow_the_spec_table() {
        use FieldType::*;
        assert_eq!(
            types("%hhd %hhi %hhu %hhx %hhX %hho %c"),
            [I8, I8, U8, U8, U8, U8, U8]
        );
        assert_eq!(
            types("%hd %hi %hu %hx %hX %ho"),
            [I16, I16, U16, U16, U16, U16]
        );
        assert_eq!(types("%d %ld %i %li"), [I32, I32, I32, I32]);
        assert_eq!(types("%u %lu %x %lx %X %o %lo"), [U32; 7]);
        assert_eq!(
            types("%lld %lli %llu %llx %llX %llo"),
            [I64, I64, U64, U64, U64, U64]
        );
        assert_eq!(types("%f %F %e %E %g %G"), [F32; 6]);
        assert_eq!(types("%lf %lF %le %lE %lg %lG"), [F64; 6]);
    }

    #[test]
    fn spec_example_layout() {
        let format = Format::parse("%u,%hd,%.3f,%lf").expect("valid");
        assert_eq!(format.data_len(), 4 + 2 + 4 + 8);
        let third = format.fields()[2];
        assert_eq!(third.precision, Some(3));
        assert_eq!((third.span_start, third.span_end), (7, 11));
    }

    #[test]
    fn flags_width_precision_and_percent() {
        let format = Format::parse("100%% %-+ #012.5lf%%").expect("valid");
        let [field] = format.fields() else {
            panic!("one field")
        };
        assert_eq!(field.flags.0, 0b11111);
        assert_eq!((field.width, field.precision), (12, Some(5)));
        assert_eq!(
            Format::parse("%.f").expect("valid").fields()[0].precision,
            Some(0)
        );
    }

    #[test]
    fn invalid_conversions_are_refused() {
        for text in [
            "%s", "%p", "%n", "%a", "%A", "%Lf", "%jd", "%zu", "%td", "%qd", "%*d", "%.*f", "%1$d",
            "%hf", "%llf", "%hhf", "%lc", "%hc", "%5%", "%", "abc%-", "%ls", "%C", "%S", "%m",
        ] {
            assert!(Format::parse(text).is_err(), "{text} should be invalid");
        }
        assert_eq!(
            Format::parse("%d%s"),
            Err(FormatError::UnsupportedConversion {
                at: 2,
                specifier: b's'
            })
        );
        assert_eq!(Format::parse("%4097d"), Err(FormatError::TooWide { at: 0 }));
        assert!(Format::parse("%4096d").is_ok());
    }

    #[test]
    fn too_many_fields() {
        let mut text = std::string::String::new();
        for _ in 0..MAX_FIELDS {
            text.push_str("%d");
        }
        assert!(Format::parse(&text).is_ok());
        text.push_str("%d");
        assert_eq!(Format::parse(&text), Err(FormatError::TooManyFields));
    }

    #[test]
    fn byte_array_formats_have_one_byte_field() {
        assert!(Format::parse("%02hhx").expect("ok").is_byte_array_format());
        assert!(Format::parse("%c").expect("ok").is_byte_array_format());
        assert!(!Format::parse("%hx").expect("ok").is_byte_array_format());
        assert!(
            !Format::parse("%hhx%hhx")
                .expect("ok")
                .is_byte_array_format()
        );
    }

    #[test]
    fn trailing_nuls_are_ignored() {
        assert_eq!(
            Format::parse_bytes(b"%d\0\0").expect("ok"),
            Format::parse("%d").expect("ok")
        );
        assert_eq!(Format::parse_bytes(b"%d\xff"), Err(FormatError::NotUtf8));
    }
}

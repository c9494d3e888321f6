//! Renders data blocks exactly as C's `printf` prints them (glibc), without allocating.
//!
//! Rust's float formatting is exactly rounded like glibc's; what differs is presentation, so
//! this module only rearranges Rust's output: the exponent of `%e` (sign and at least two
//! digits), the choice and trailing-zero removal of `%g`, padding, signs and the `#` forms.
//! Long outputs are never buffered: each float is formatted twice, once to measure it and once
//! to write it.

use core::fmt::{self, Write};

use super::format::{Conversion, Field, FieldType, Flags, Format};

/// A decoded field value.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Value {
    I8(i8),
    U8(u8),
    I16(i16),
    U16(u16),
    I32(i32),
    U32(u32),
    I64(i64),
    U64(u64),
    F32(f32),
    F64(f64),
}

impl Value {
    pub const fn field_type(self) -> FieldType {
        match self {
            Value::I8(_) => FieldType::I8,
            Value::U8(_) => FieldType::U8,
            Value::I16(_) => FieldType::I16,
            Value::U16(_) => FieldType::U16,
            Value::I32(_) => FieldType::I32,
            Value::U32(_) => FieldType::U32,
            Value::I64(_) => FieldType::I64,
            Value::U64(_) => FieldType::U64,
            Value::F32(_) => FieldType::F32,
            Value::F64(_) => FieldType::F64,
        }
    }

    /// Decodes a field of type `ty` from the start of `bytes` (little-endian); `None` when
    /// `bytes` is too short.
    pub fn decode(ty: FieldType, bytes: &[u8]) -> Option<Value> {
        Some(match ty {
            FieldType::I8 => Value::I8(i8::from_le_bytes(take(bytes)?)),
            FieldType::U8 => Value::U8(u8::from_le_bytes(take(bytes)?)),
            FieldType::I16 => Value::I16(i16::from_le_bytes(take(bytes)?)),
            FieldType::U16 => Value::U16(u16::from_le_bytes(take(bytes)?)),
            FieldType::I32 => Value::I32(i32::from_le_bytes(take(bytes)?)),
            FieldType::U32 => Value::U32(u32::from_le_bytes(take(bytes)?)),
            FieldType::I64 => Value::I64(i64::from_le_bytes(take(bytes)?)),
            FieldType::U64 => Value::U64(u64::from_le_bytes(take(bytes)?)),
            FieldType::F32 => Value::F32(f32::from_le_bytes(take(bytes)?)),
            FieldType::F64 => Value::F64(f64::from_le_bytes(take(bytes)?)),
        })
    }

    /// Writes the value little-endian at the start of `out`; returns the bytes written, or
    /// `None` when `out` is too short.
    pub fn encode(self, out: &mut [u8]) -> Option<usize> {
        match self {
            Value::I8(v) => put(out, &v.to_le_bytes()),
            Value::U8(v) => put(out, &v.to_le_bytes()),
            Value::I16(v) => put(out, &v.to_le_bytes()),
            Value::U16(v) => put(out, &v.to_le_bytes()),
            Value::I32(v) => put(out, &v.to_le_bytes()),
            Value::U32(v) => put(out, &v.to_le_bytes()),
            Value::I64(v) => put(out, &v.to_le_bytes()),
            Value::U64(v) => put(out, &v.to_le_bytes()),
            Value::F32(v) => put(out, &v.to_le_bytes()),
            Value::F64(v) => put(out, &v.to_le_bytes()),
        }
    }
}

fn take<const N: usize>(bytes: &[u8]) -> Option<[u8; N]> {
    bytes.get(..N)?.try_into().ok()
}

fn put(out: &mut [u8], bytes: &[u8]) -> Option<usize> {
    out.get_mut(..bytes.len())?.copy_from_slice(bytes);
    Some(bytes.len())
}

/// Why a record could not be rendered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RenderError {
    /// The data length differs from the format's fields (or a byte array's format is not a
    /// single one-byte conversion).
    DataMismatch,
    /// The format text does not match the parsed format.
    TextMismatch,
    /// The output refused the text.
    Write,
}

impl From<fmt::Error> for RenderError {
    fn from(_: fmt::Error) -> Self {
        RenderError::Write
    }
}

/// Where rendered text goes when it must be byte-exact: C's `%c` prints any byte, and a
/// byte above 0x7f on its own is not UTF-8, so it cannot go through [`Write`].
pub trait ByteWrite: Write {
    fn write_byte(&mut self, byte: u8) -> fmt::Result;

    /// Writes ASCII the renderer built as bytes (digits, signs, points). By default it is
    /// checked as text and goes through [`Write::write_str`]; a sink of bytes may take it as
    /// it is (`to-csv`'s does: the check was 7 % of its time).
    fn write_ascii(&mut self, ascii: &[u8]) -> fmt::Result {
        self.write_str(core::str::from_utf8(ascii).map_err(|_| fmt::Error)?)
    }
}

/// Adapts a [`Write`] (e.g. a `String`): `%c` of a byte above 0x7f becomes the Latin-1
/// character of that value, the only lossless stand-in text can hold.
struct Latin1<'a, W: Write + ?Sized>(&'a mut W);

impl<W: Write + ?Sized> Write for Latin1<'_, W> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        self.0.write_str(s)
    }
}

impl<W: Write + ?Sized> ByteWrite for Latin1<'_, W> {
    fn write_byte(&mut self, byte: u8) -> fmt::Result {
        self.0.write_char(char::from(byte))
    }
}

/// Writes what `printf(text, fields...)` prints for a data block of `format` (parsed from
/// `text`). A `%c` of a byte above 0x7f prints as its Latin-1 character; use
/// [`render_data_block_bytes`] for C's exact bytes.
pub fn render_data_block<W: Write + ?Sized>(
    out: &mut W,
    text: &str,
    format: &Format,
    data: &[u8],
) -> Result<(), RenderError> {
    render_data_block_bytes(&mut Latin1(out), text, format, data)
}

/// Writes exactly the bytes `printf(text, fields...)` prints for a data block of `format`.
pub fn render_data_block_bytes<W: ByteWrite + ?Sized>(
    out: &mut W,
    text: &str,
    format: &Format,
    data: &[u8],
) -> Result<(), RenderError> {
    if data.len() != format.data_len() {
        return Err(RenderError::DataMismatch);
    }
    let mut literal_start = 0usize;
    let mut data_offset = 0usize;
    for field in format.fields() {
        let literal = text
            .get(literal_start..usize::from(field.span_start))
            .ok_or(RenderError::TextMismatch)?;
        write_literal(out, literal)?;
        let bytes = data.get(data_offset..).ok_or(RenderError::DataMismatch)?;
        let value = Value::decode(field.ty, bytes).ok_or(RenderError::DataMismatch)?;
        render_field_bytes(out, field, value)?;
        data_offset += field.ty.size();
        literal_start = usize::from(field.span_end);
    }
    let tail = text.get(literal_start..).ok_or(RenderError::TextMismatch)?;
    write_literal(out, tail)?;
    Ok(())
}

/// Writes a byte array's text: each byte printed with the format, joined by `,` (`%c` above
/// 0x7f as Latin-1, as [`render_data_block`]).
pub fn render_byte_array<W: Write + ?Sized>(
    out: &mut W,
    text: &str,
    format: &Format,
    bytes: &[u8],
) -> Result<(), RenderError> {
    render_byte_array_bytes(&mut Latin1(out), text, format, bytes)
}

/// Writes exactly the bytes of a byte array's text.
pub fn render_byte_array_bytes<W: ByteWrite + ?Sized>(
    out: &mut W,
    text: &str,
    format: &Format,
    bytes: &[u8],
) -> Result<(), RenderError> {
    if !format.is_byte_array_format() {
        return Err(RenderError::DataMismatch);
    }
    for (i, byte) in bytes.iter().enumerate() {
        if i > 0 {
            out.write_char(',')?;
        }
        render_data_block_bytes(out, text, format, core::slice::from_ref(byte))?;
    }
    Ok(())
}

/// Literal text between conversions: `%%` prints `%` (the parser allows no other `%`).
fn write_literal<W: ByteWrite + ?Sized>(out: &mut W, literal: &str) -> fmt::Result {
    // Nearly every literal is a comma: skip the substring search (its set-up alone was 5 %
    // of `to-csv`) when there is no `%` at all.
    if !literal.as_bytes().contains(&b'%') {
        return out.write_str(literal);
    }
    let mut rest = literal;
    while let Some(percent) = rest.find("%%") {
        out.write_str(rest.get(..=percent).unwrap_or(""))?;
        rest = rest.get(percent + 2..).unwrap_or("");
    }
    out.write_str(rest)
}

/// Writes one field's value as its conversion specification prints it (`%c` above 0x7f as
/// Latin-1).
pub fn render_field<W: Write + ?Sized>(out: &mut W, field: &Field, value: Value) -> fmt::Result {
    render_field_bytes(&mut Latin1(out), field, value)
}

/// Writes exactly the bytes one field's conversion specification prints.
pub fn render_field_bytes<W: ByteWrite + ?Sized>(
    out: &mut W,
    field: &Field,
    value: Value,
) -> fmt::Result {
    match value {
        Value::F32(v) => render_float(out, field, f64::from(v)),
        Value::F64(v) => render_float(out, field, v),
        Value::I8(v) => render_integer(out, field, i128::from(v), u128::from(v as u8)),
        Value::U8(v) => render_integer(out, field, i128::from(v), u128::from(v)),
        Value::I16(v) => render_integer(out, field, i128::from(v), u128::from(v as u16)),
        Value::U16(v) => render_integer(out, field, i128::from(v), u128::from(v)),
        Value::I32(v) => render_integer(out, field, i128::from(v), u128::from(v as u32)),
        Value::U32(v) => render_integer(out, field, i128::from(v), u128::from(v)),
        Value::I64(v) => render_integer(out, field, i128::from(v), u128::from(v as u64)),
        Value::U64(v) => render_integer(out, field, i128::from(v), u128::from(v)),
    }
}

/// `signed` is the value as a C signed type of its width, `unsigned` as the unsigned type:
/// `%d` prints the first, `%u %x %o` the second (as C reinterprets the argument).
fn render_integer<W: ByteWrite + ?Sized>(
    out: &mut W,
    field: &Field,
    signed: i128,
    unsigned: u128,
) -> fmt::Result {
    let flags = field.flags;
    if field.conversion == Conversion::Char {
        let byte = u8::try_from(unsigned & 0xff).unwrap_or(b'?');
        return pad_around(out, flags.has(Flags::LEFT), field.width.into(), 1, |out| {
            out.write_byte(byte)
        });
    }
    let (negative, magnitude, radix) = match field.conversion {
        Conversion::Signed => (signed < 0, signed.unsigned_abs(), 10),
        Conversion::HexLower | Conversion::HexUpper => (false, unsigned, 16),
        Conversion::Octal => (false, unsigned, 8),
        _ => (false, unsigned, 10),
    };
    let mut digits_buf = [0u8; 48];
    let digits = if field.precision == Some(0) && magnitude == 0 {
        &[][..]
    } else {
        to_digits(
            magnitude,
            radix,
            field.conversion.is_upper(),
            &mut digits_buf,
        )
    };
    let precision = usize::from(field.precision.unwrap_or(0));
    let mut leading_zeros = precision.saturating_sub(digits.len());
    if flags.has(Flags::ALT)
        && field.conversion == Conversion::Octal
        && leading_zeros == 0
        && digits.first() != Some(&b'0')
    {
        leading_zeros = 1;
    }
    let prefix = match field.conversion {
        Conversion::HexLower if flags.has(Flags::ALT) && magnitude != 0 => "0x",
        Conversion::HexUpper if flags.has(Flags::ALT) && magnitude != 0 => "0X",
        _ => "",
    };
    let sign = if field.conversion == Conversion::Signed {
        sign_of(negative, flags)
    } else {
        ""
    };
    let body_len = sign.len() + prefix.len() + leading_zeros + digits.len();
    let width = usize::from(field.width);
    let zero_pad = flags.has(Flags::ZERO) && !flags.has(Flags::LEFT) && field.precision.is_none();
    if zero_pad {
        leading_zeros += width.saturating_sub(body_len);
    }
    pad_around(
        out,
        flags.has(Flags::LEFT),
        width,
        sign.len() + prefix.len() + leading_zeros + digits.len(),
        |out| {
            out.write_str(sign)?;
            out.write_str(prefix)?;
            repeat(out, '0', leading_zeros)?;
            out.write_ascii(digits)
        },
    )
}

fn sign_of(negative: bool, flags: Flags) -> &'static str {
    if negative {
        "-"
    } else if flags.has(Flags::PLUS) {
        "+"
    } else if flags.has(Flags::SPACE) {
        " "
    } else {
        ""
    }
}

/// The digits of `value` in `radix`, most significant first, in the end of `buf`.
fn to_digits(mut value: u128, radix: u128, upper: bool, buf: &mut [u8; 48]) -> &[u8] {
    let symbols: &[u8; 16] = if upper {
        b"0123456789ABCDEF"
    } else {
        b"0123456789abcdef"
    };
    let mut start = buf.len();
    // Every logged integer fits 64 bits: u64 division by a constant radix is a multiply,
    // u128 division a library call; the digits are the same.
    if let Ok(small) = u64::try_from(value) {
        let start = match radix {
            10 => digits_u64::<10>(small, symbols, buf),
            16 => digits_u64::<16>(small, symbols, buf),
            _ => digits_u64::<8>(small, symbols, buf),
        };
        return buf.get(start..).unwrap_or(&[]);
    }
    loop {
        let digit = usize::try_from(value % radix).unwrap_or(0);
        start -= 1;
        if let (Some(slot), Some(&symbol)) = (buf.get_mut(start), symbols.get(digit)) {
            *slot = symbol;
        }
        value /= radix;
        if value == 0 || start == 0 {
            break;
        }
    }
    buf.get(start..).unwrap_or(&[])
}

/// [`to_digits`] for a u64 (`RADIX` 8, 10 or 16); returns where the digits start in `buf`.
fn digits_u64<const RADIX: u64>(mut value: u64, symbols: &[u8; 16], buf: &mut [u8; 48]) -> usize {
    let mut start = buf.len();
    loop {
        let digit = usize::try_from(value % RADIX).unwrap_or(0);
        start -= 1;
        if let (Some(slot), Some(&symbol)) = (buf.get_mut(start), symbols.get(digit)) {
            *slot = symbol;
        }
        value /= RADIX;
        if value == 0 || start == 0 {
            return start;
        }
    }
}

/// Writes `body` (of `body_len` characters) padded with spaces to `width`.
fn pad_around<W: ByteWrite + ?Sized>(
    out: &mut W,
    left: bool,
    width: usize,
    body_len: usize,
    body: impl FnOnce(&mut W) -> fmt::Result,
) -> fmt::Result {
    let padding = width.saturating_sub(body_len);
    if !left {
        repeat(out, ' ', padding)?;
    }
    body(out)?;
    if left {
        repeat(out, ' ', padding)?;
    }
    Ok(())
}

fn repeat<W: ByteWrite + ?Sized>(out: &mut W, c: char, mut count: usize) -> fmt::Result {
    const SPACES: &str = "                                ";
    const ZEROS: &str = "00000000000000000000000000000000";
    let chunk = if c == '0' { ZEROS } else { SPACES };
    while count > 0 {
        let n = count.min(chunk.len());
        out.write_str(chunk.get(..n).unwrap_or(""))?;
        count -= n;
    }
    Ok(())
}

/// What a float's Rust rendering looks like, measured without storing it.
#[derive(Default)]
struct Probe {
    /// Characters before any `e`.
    mantissa_len: usize,
    /// Length of the mantissa without the trailing zeros of its fraction (and without the `.`
    /// when nothing remains of the fraction): what `%g` keeps.
    significant_len: usize,
    seen_point: bool,
    in_exponent: bool,
    exponent_negative: bool,
    exponent: i32,
}

impl Write for Probe {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for c in s.chars() {
            if self.in_exponent {
                match c {
                    '-' => self.exponent_negative = true,
                    '0'..='9' => {
                        let digit = i32::try_from(u32::from(c) - u32::from('0')).unwrap_or(0);
                        self.exponent = self.exponent.saturating_mul(10).saturating_add(digit);
                    }
                    _ => {}
                }
                continue;
            }
            match c {
                'e' => self.in_exponent = true,
                '.' => {
                    self.seen_point = true;
                    self.mantissa_len += 1;
                }
                '0' if self.seen_point => self.mantissa_len += 1,
                _ => {
                    self.mantissa_len += 1;
                    self.significant_len = self.mantissa_len;
                }
            }
        }
        Ok(())
    }
}

impl Probe {
    fn exponent(&self) -> i32 {
        if self.exponent_negative {
            -self.exponent
        } else {
            self.exponent
        }
    }
}

/// Passes the first `remaining` characters of the mantissa (everything before an `e`) through.
struct Prefix<'a, W: Write + ?Sized> {
    out: &'a mut W,
    remaining: usize,
}

impl<W: Write + ?Sized> Write for Prefix<'_, W> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for c in s.chars() {
            if self.remaining == 0 || c == 'e' {
                self.remaining = 0;
                return Ok(());
            }
            self.out.write_char(c)?;
            self.remaining -= 1;
        }
        Ok(())
    }
}

/// Room for the longest text [`fixed_digits`] makes: 37 integer digits (below 2¹²⁰), the
/// point and 17 decimals.
const FIXED_BUF: usize = 64;

/// 10ⁿ for the precisions the fast `%f` path takes (10¹⁷ < 2⁵⁷).
const POW10: [u64; 18] = [
    1,
    10,
    100,
    1_000,
    10_000,
    100_000,
    1_000_000,
    10_000_000,
    100_000_000,
    1_000_000_000,
    10_000_000_000,
    100_000_000_000,
    1_000_000_000_000,
    10_000_000_000_000,
    100_000_000_000_000,
    1_000_000_000_000_000,
    10_000_000_000_000_000,
    100_000_000_000_000_000,
];

/// The text `%.<precision>f` prints for a finite, non-negative `magnitude` (no sign, no
/// padding; `alt`: `#` keeps the point with no decimals), in `buf`; `None` outside the range
/// this path covers (precision above 17, or magnitude at or above 2⁶³), which the general
/// path then prints.
///
/// Why it is exact: an f64 is `m · 2^e` with an integer `m < 2⁵³`, so `magnitude · 10^p` is
/// the integer `m · 10^p` (< 2¹¹⁰, fits u128) shifted by `e`. Shifting right by `k = -e`
/// gives the quotient and the exact remainder; glibc rounds that remainder to nearest, ties
/// to even (the default rounding mode), which is what the comparison with `half` does. No
/// step rounds, so the digits are glibc's for every input (`logfmt/tests.rs` checks against
/// the C library's `snprintf`).
fn fixed_digits(
    magnitude: f64,
    precision: u16,
    alt: bool,
    buf: &mut [u8; FIXED_BUF],
) -> Option<&[u8]> {
    let p = usize::from(precision);
    let scale = u128::from(*POW10.get(p)?);
    let bits = magnitude.to_bits();
    let biased = i32::try_from((bits >> 52) & 0x7ff).ok()?;
    let fraction = bits & ((1u64 << 52) - 1);
    // magnitude = mantissa · 2^exponent, exactly (subnormals have no implicit bit).
    let (mantissa, exponent) = if biased == 0 {
        (fraction, -1074)
    } else {
        (fraction | (1u64 << 52), biased - 1075)
    };
    let scaled = u128::from(mantissa) * scale;
    let units = if exponent >= 0 {
        // Up to 2⁶³: `scaled << exponent` stays below 2¹²⁰.
        if exponent > 10 {
            return None;
        }
        scaled << exponent
    } else {
        let k = exponent.unsigned_abs();
        if k >= 112 {
            // scaled < 2¹¹⁰ < half of 2^k: below half a unit of the last decimal, rounds to
            // 0 (this also covers zero and the subnormals).
            0
        } else {
            let quotient = scaled >> k;
            let remainder = scaled & ((1u128 << k) - 1);
            let half = 1u128 << (k - 1);
            if remainder > half || (remainder == half && quotient & 1 == 1) {
                quotient + 1
            } else {
                quotient
            }
        }
    };
    // In u64 whenever it fits (every logged value): u128 division is a library call.
    let scale64 = *POW10.get(p)?;
    let (integer, mut decimals) = match u64::try_from(units) {
        Ok(u) => (u128::from(u / scale64), u % scale64),
        Err(_) => (units / scale, u64::try_from(units % scale).ok()?),
    };
    let mut digits = [0u8; 48];
    let integer_digits = to_digits(integer, 10, false, &mut digits);
    let mut len = integer_digits.len();
    buf.get_mut(..len)?.copy_from_slice(integer_digits);
    if p > 0 || alt {
        *buf.get_mut(len)? = b'.';
        len += 1;
    }
    // Exactly p decimals, leading zeros kept.
    for slot in buf.get_mut(len..len + p)?.iter_mut().rev() {
        *slot = b'0' + u8::try_from(decimals % 10).ok()?;
        decimals /= 10;
    }
    len += p;
    buf.get(..len)
}

#[derive(Clone, Copy, PartialEq)]
enum Style {
    Fixed,
    Exponent,
}

/// The decimal exponent of a positive finite value before any rounding (its shortest
/// representation never rounds across a power of ten).
fn unrounded_exponent(magnitude: f64) -> Result<i64, fmt::Error> {
    let mut probe = Probe::default();
    write!(probe, "{magnitude:e}")?;
    Ok(i64::from(probe.exponent()))
}

fn render_float<W: ByteWrite + ?Sized>(out: &mut W, field: &Field, value: f64) -> fmt::Result {
    let flags = field.flags;
    let upper = field.conversion.is_upper();
    let sign = sign_of(value.is_sign_negative(), flags);
    let width = usize::from(field.width);
    let left = flags.has(Flags::LEFT);
    if !value.is_finite() {
        let text = match (value.is_nan(), upper) {
            (true, false) => "nan",
            (true, true) => "NAN",
            (false, false) => "inf",
            (false, true) => "INF",
        };
        return pad_around(out, left, width, sign.len() + 3, |out| {
            out.write_str(sign)?;
            out.write_str(text)
        });
    }
    let magnitude = value.abs();
    let alt = flags.has(Flags::ALT);
    // `%f` (every float the shipped formats log) takes an integer-arithmetic path: core::fmt's
    // exact mode (Grisu, falling back to Dragon4 on bignums) was most of `to-csv`'s time.
    if matches!(
        field.conversion,
        Conversion::FixedLower | Conversion::FixedUpper
    ) {
        let mut buf = [0u8; FIXED_BUF];
        if let Some(body) = fixed_digits(magnitude, field.precision.unwrap_or(6), alt, &mut buf) {
            let zeros = if flags.has(Flags::ZERO) && !left {
                width.saturating_sub(sign.len() + body.len())
            } else {
                0
            };
            return pad_around(out, left, width, sign.len() + zeros + body.len(), |out| {
                out.write_str(sign)?;
                repeat(out, '0', zeros)?;
                out.write_ascii(body)
            });
        }
    }
    let (style, precision, strip_zeros) = match field.conversion {
        Conversion::FixedLower | Conversion::FixedUpper => (
            Style::Fixed,
            usize::from(field.precision.unwrap_or(6)),
            false,
        ),
        Conversion::ExpLower | Conversion::ExpUpper => (
            Style::Exponent,
            usize::from(field.precision.unwrap_or(6)),
            false,
        ),
        _ => {
            // C: P significant digits; X the exponent %e would print with P-1 decimals.
            let p = usize::from(field.precision.unwrap_or(6)).max(1);
            let mut probe = Probe::default();
            write!(probe, "{:.*e}", p - 1, magnitude)?;
            let x = i64::from(probe.exponent());
            let p_signed = i64::try_from(p).unwrap_or(i64::MAX);
            if x < p_signed && x >= -4 {
                let decimals = usize::try_from(p_signed - 1 - x).unwrap_or(0);
                (Style::Fixed, decimals, !alt)
            } else if alt && x == p_signed && unrounded_exponent(magnitude)? == x - 1 {
                // glibc quirk: it picks the style from the exponent before rounding; when
                // rounding then carries into one digit more than `P` (999999.5 with `%#g`),
                // it prints the exponent style with the fixed style's 0 decimals: `1.e+06`,
                // where ISO C says `1.00000e+06`. Without `#` both strip to `1e+06`.
                (Style::Exponent, 0, false)
            } else {
                (Style::Exponent, p - 1, !alt)
            }
        }
    };
    let mut probe = Probe::default();
    match style {
        Style::Fixed => write!(probe, "{magnitude:.precision$}")?,
        Style::Exponent => write!(probe, "{magnitude:.precision$e}")?,
    }
    let mantissa_len = if strip_zeros {
        probe.significant_len
    } else {
        probe.mantissa_len
    };
    // `#` keeps the decimal point even with no decimals.
    let forced_point = alt && precision == 0;
    let exponent = probe.exponent();
    let mut exponent_digits = [0u8; 48];
    let exponent_text = match style {
        Style::Fixed => "",
        Style::Exponent => {
            let digits = to_digits(
                u128::from(exponent.unsigned_abs()),
                10,
                false,
                &mut exponent_digits,
            );
            core::str::from_utf8(digits).map_err(|_| fmt::Error)?
        }
    };
    let exponent_len = match style {
        Style::Fixed => 0,
        Style::Exponent => 2 + exponent_text.len().max(2),
    };
    let body_len = mantissa_len + usize::from(forced_point) + exponent_len;
    let zeros = if flags.has(Flags::ZERO) && !left {
        width.saturating_sub(sign.len() + body_len)
    } else {
        0
    };
    pad_around(out, left, width, sign.len() + zeros + body_len, |out| {
        out.write_str(sign)?;
        repeat(out, '0', zeros)?;
        let mut prefix = Prefix {
            out: &mut *out,
            remaining: mantissa_len,
        };
        match style {
            Style::Fixed => write!(prefix, "{magnitude:.precision$}")?,
            Style::Exponent => write!(prefix, "{magnitude:.precision$e}")?,
        }
        if forced_point {
            out.write_char('.')?;
        }
        if style == Style::Exponent {
            out.write_char(if upper { 'E' } else { 'e' })?;
            out.write_char(if exponent < 0 { '-' } else { '+' })?;
            if exponent_text.len() < 2 {
                out.write_char('0')?;
            }
            out.write_str(exponent_text)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::String;

    fn render(text: &str, values: &[Value]) -> String {
        let format = Format::parse(text).expect("valid format");
        let mut data = std::vec![0u8; format.data_len()];
        let mut offset = 0;
        for v in values {
            offset += v.encode(&mut data[offset..]).expect("fits");
        }
        let mut out = String::new();
        render_data_block(&mut out, text, &format, &data).expect("renders");
        out
    }

    #[test]
    fn spec_example() {
        assert_eq!(
            render(
                "%u,%hd,%.3f,%lf",
                &[
                    Value::U32(7),
                    Value::I16(-2),
                    Value::F32(1.5),
                    Value::F64(0.25)
                ]
            ),
            "7,-2,1.500,0.250000"
        );
    }

    #[test]
    fn integers() {
        assert_eq!(
            render(
                "[%05c][%-05d][%#.0o][%#o][%#x][%+u][%.0d]",
                &[
                    Value::U8(b'a'),
                    Value::I32(3),
                    Value::U32(0),
                    Value::U32(0),
                    Value::U32(0),
                    Value::U32(5),
                    Value::I32(0)
                ]
            ),
            "[    a][3    ][0][0][0][5][]"
        );
        assert_eq!(
            render(
                "%hhd %hhu %hx %lld",
                &[
                    Value::I8(-128),
                    Value::U8(255),
                    Value::U16(0xbeef),
                    Value::I64(i64::MIN)
                ]
            ),
            "-128 255 beef -9223372036854775808"
        );
        assert_eq!(
            render(
                "%+08.3d|%08d|% d|%#X",
                &[
                    Value::I32(-5),
                    Value::I32(-5),
                    Value::I32(5),
                    Value::U32(255)
                ]
            ),
            "    -005|-0000005| 5|0XFF"
        );
    }

    #[test]
    fn floats() {
        assert_eq!(
            render(
                "%#.0lf %#.3lg %lg %lg %.0le %.0lf %.0lf %%",
                &[
                    Value::F64(2.0),
                    Value::F64(100.0),
                    Value::F64(1e-5),
                    Value::F64(123456789.0),
                    Value::F64(2.5),
                    Value::F64(2.5),
                    Value::F64(0.5)
                ]
            ),
            "2. 100. 1e-05 1.23457e+08 2e+00 2 0 %"
        );
        assert_eq!(
            render(
                "%le|%lE|%lG|%lg|%010.2lf|%-8.1le|",
                &[
                    Value::F64(0.0),
                    Value::F64(-1e-300),
                    Value::F64(f64::INFINITY),
                    Value::F64(-f64::NAN),
                    Value::F64(-3.25159),
                    Value::F64(1e100)
                ]
            ),
            "0.000000e+00|-1.000000E-300|INF|-nan|-000003.25|1.0e+100|"
        );
    }

    #[test]
    fn byte_arrays_join_with_commas() {
        let format = Format::parse("0x%02hhx").expect("ok");
        let mut out = String::new();
        render_byte_array(&mut out, "0x%02hhx", &format, &[1, 0xab, 0]).expect("renders");
        assert_eq!(out, "0x01,0xab,0x00");
    }
}

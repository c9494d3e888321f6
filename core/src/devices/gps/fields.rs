//! The fields of a sentence: comma-separated, empty meaning unknown, every number
//! range-checked.

use super::*;

/// The fields of a sentence body, with a cursor. Reading past the last field gives empty
/// fields, which is what receivers that omit trailing fields mean.
pub(super) struct Fields<'a> {
    pub(super) rest: Option<&'a [u8]>,
}

impl<'a> Fields<'a> {
    pub(super) fn new(body: &'a [u8]) -> Self {
        Self { rest: Some(body) }
    }

    pub(super) fn next_field(&mut self) -> &'a [u8] {
        let Some(rest) = self.rest else {
            return &[];
        };
        let split = rest
            .iter()
            .position(|&b| b == b',')
            .and_then(|comma| rest.split_at_checked(comma));
        match split {
            Some((field, tail)) => {
                self.rest = tail.get(1..);
                field
            }
            None => {
                self.rest = None;
                rest
            }
        }
    }

    pub(super) fn skip(&mut self, n: usize) {
        for _ in 0..n {
            self.next_field();
        }
    }

    /// A decimal number with optional sign and point, within `range`; empty is `None`.
    pub(super) fn number(
        &mut self,
        range: core::ops::RangeInclusive<f64>,
    ) -> FieldResult<Option<f64>> {
        let field = self.next_field();
        if field.is_empty() {
            return Ok(None);
        }
        parse_decimal(field)
            .filter(|value| range.contains(value))
            .map(Some)
            .ok_or(InvalidField)
    }

    pub(super) fn small_integer(&mut self) -> FieldResult<Option<u8>> {
        let field = self.next_field();
        if field.is_empty() {
            return Ok(None);
        }
        if !field.iter().all(u8::is_ascii_digit) {
            return Err(InvalidField);
        }
        let text = core::str::from_utf8(field).map_err(|_| InvalidField)?;
        text.parse::<u8>().map(Some).map_err(|_| InvalidField)
    }

    pub(super) fn character(&mut self) -> FieldResult<Option<u8>> {
        match self.next_field() {
            [] => Ok(None),
            [single] => Ok(Some(*single)),
            _ => Err(InvalidField),
        }
    }

    /// `hhmmss[.s…]` → milliseconds of the day.
    pub(super) fn utc_time(&mut self) -> FieldResult<Option<u32>> {
        let field = self.next_field();
        if field.is_empty() {
            return Ok(None);
        }
        let (whole, fraction) = match field.iter().position(|&b| b == b'.') {
            Some(point) => (field.get(..point), field.get(point + 1..)),
            None => (Some(field), Some(&[][..])),
        };
        let (Some(whole), Some(fraction)) = (whole, fraction) else {
            return Err(InvalidField);
        };
        let [h1, h0, m1, m0, s1, s0] = whole else {
            return Err(InvalidField);
        };
        let two = |tens: u8, ones: u8| -> FieldResult<u32> {
            if tens.is_ascii_digit() && ones.is_ascii_digit() {
                Ok(u32::from(tens - b'0') * 10 + u32::from(ones - b'0'))
            } else {
                Err(InvalidField)
            }
        };
        let (hours, minutes, seconds) = (two(*h1, *h0)?, two(*m1, *m0)?, two(*s1, *s0)?);
        // 60 s is a leap second.
        if hours > 23 || minutes > 59 || seconds > 60 || !fraction.iter().all(u8::is_ascii_digit) {
            return Err(InvalidField);
        }
        let millis = fraction
            .iter()
            .chain(core::iter::repeat(&b'0'))
            .take(3)
            .fold(0u32, |acc, digit| {
                acc * 10 + u32::from(digit.wrapping_sub(b'0'))
            });
        Ok(Some(
            ((hours * 60 + minutes) * 60 + seconds) * 1000 + millis,
        ))
    }

    /// `ddmmyy`; years 80–99 are 1980–1999 (GPS time starts in 1980).
    pub(super) fn utc_date(&mut self) -> FieldResult<Option<UtcDate>> {
        let field = self.next_field();
        if field.is_empty() {
            return Ok(None);
        }
        let [d1, d0, m1, m0, y1, y0] = field else {
            return Err(InvalidField);
        };
        if ![d1, d0, m1, m0, y1, y0].iter().all(|b| b.is_ascii_digit()) {
            return Err(InvalidField);
        }
        let two = |tens: u8, ones: u8| (tens - b'0') * 10 + (ones - b'0');
        let (day, month, year) = (two(*d1, *d0), two(*m1, *m0), two(*y1, *y0));
        if !(1..=31).contains(&day) || !(1..=12).contains(&month) {
            return Err(InvalidField);
        }
        let year = if year >= 80 {
            1900 + u16::from(year)
        } else {
            2000 + u16::from(year)
        };
        Ok(Some(UtcDate { year, month, day }))
    }

    /// `ddmm.mmmm,N` or `dddmm.mmmm,E` → signed degrees. Both empty is `None`; one without
    /// the other is invalid.
    pub(super) fn angle(
        &mut self,
        max_degrees: f64,
        positive: u8,
        negative: u8,
    ) -> FieldResult<Option<f64>> {
        let value = self.number(0.0..=max_degrees * 100.0)?;
        let hemisphere = self.character()?;
        let (value, hemisphere) = match (value, hemisphere) {
            (None, None) => return Ok(None),
            (Some(value), Some(hemisphere)) => (value, hemisphere),
            _ => return Err(InvalidField),
        };
        // `as` truncates toward zero: the whole degrees of a non-negative value.
        let degrees = (value / 100.0) as u32;
        let minutes = value - f64::from(degrees) * 100.0;
        let angle = f64::from(degrees) + minutes / 60.0;
        if minutes >= 60.0 || angle > max_degrees {
            return Err(InvalidField);
        }
        match hemisphere {
            h if h == positive => Ok(Some(angle)),
            h if h == negative => Ok(Some(-angle)),
            _ => Err(InvalidField),
        }
    }

    pub(super) fn position(&mut self, update: &mut Update) -> FieldResult<()> {
        update.fix.latitude_deg = self.angle(90.0, b'N', b'S')?;
        update.fix.longitude_deg = self.angle(180.0, b'E', b'W')?;
        Ok(())
    }
}

/// A plain decimal (`-12.345`, `7`, `.5`): no exponents, no `inf`/`nan`, so every accepted
/// value is finite.
pub(super) fn parse_decimal(field: &[u8]) -> Option<f64> {
    let digits = field
        .strip_prefix(b"-")
        .or_else(|| field.strip_prefix(b"+"))
        .unwrap_or(field);
    let mut seen_point = false;
    let mut seen_digit = false;
    for &byte in digits {
        match byte {
            b'0'..=b'9' => seen_digit = true,
            b'.' if !seen_point => seen_point = true,
            _ => return None,
        }
    }
    if !seen_digit {
        return None;
    }
    core::str::from_utf8(field)
        .ok()?
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
}

pub(super) const SPEED_KNOTS: core::ops::RangeInclusive<f64> = 0.0..=10_000.0;
pub(super) const COURSE_DEG: core::ops::RangeInclusive<f64> = 0.0..=360.0;
pub(super) const DOP: core::ops::RangeInclusive<f64> = 0.0..=100.0;
pub(super) const ALTITUDE_M: core::ops::RangeInclusive<f64> = -100_000.0..=100_000.0;
pub(super) const GEOID_SEPARATION_M: core::ops::RangeInclusive<f64> = -1_000.0..=1_000.0;
pub(super) const SD_M: core::ops::RangeInclusive<f64> = 0.0..=1.0e6;
pub(super) const VERTICAL_SPEED_MPS: core::ops::RangeInclusive<f64> = -10_000.0..=10_000.0;

pub(super) fn to_f32(value: Option<f64>) -> Option<f32> {
    value.map(|v| v as f32)
}

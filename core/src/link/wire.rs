//! Bounded little-endian writing and reading over byte slices.
//!
//! Every field of the link is encoded here, one primitive at a time, in an explicit byte
//! order: never a struct's memory layout (the seed's ground station and vehicle disagreed on
//! field alignment because they were built by different compilers). Running out of room or
//! input is an error, never a panic.

/// Why a field could not be written or read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WireError {
    /// The output buffer has no room for the field.
    BufferFull,
    /// The input ended in the middle of a field.
    Truncated,
    /// A field holds a value its type does not allow (unknown tag, bad text, …).
    Invalid,
}

/// Writes little-endian fields into a borrowed buffer, front to back.
pub struct Writer<'a> {
    buffer: &'a mut [u8],
    written: usize,
}

impl<'a> Writer<'a> {
    pub fn new(buffer: &'a mut [u8]) -> Self {
        Self { buffer, written: 0 }
    }

    /// Bytes written so far.
    pub fn position(&self) -> usize {
        self.written
    }

    /// The bytes written so far.
    pub fn written(&self) -> &[u8] {
        self.buffer.get(..self.written).unwrap_or(&[])
    }

    pub fn bytes(&mut self, bytes: &[u8]) -> Result<(), WireError> {
        let end = self
            .written
            .checked_add(bytes.len())
            .ok_or(WireError::BufferFull)?;
        let target = self
            .buffer
            .get_mut(self.written..end)
            .ok_or(WireError::BufferFull)?;
        target.copy_from_slice(bytes);
        self.written = end;
        Ok(())
    }

    /// Overwrites bytes already written (e.g. a length known only at the end).
    pub fn patch(&mut self, at: usize, bytes: &[u8]) -> Result<(), WireError> {
        let end = at.checked_add(bytes.len()).ok_or(WireError::BufferFull)?;
        if end > self.written {
            return Err(WireError::BufferFull);
        }
        let target = self.buffer.get_mut(at..end).ok_or(WireError::BufferFull)?;
        target.copy_from_slice(bytes);
        Ok(())
    }

    pub fn u8(&mut self, value: u8) -> Result<(), WireError> {
        self.bytes(&[value])
    }
    pub fn u16(&mut self, value: u16) -> Result<(), WireError> {
        self.bytes(&value.to_le_bytes())
    }
    pub fn u32(&mut self, value: u32) -> Result<(), WireError> {
        self.bytes(&value.to_le_bytes())
    }
    pub fn u64(&mut self, value: u64) -> Result<(), WireError> {
        self.bytes(&value.to_le_bytes())
    }
    pub fn i32(&mut self, value: i32) -> Result<(), WireError> {
        self.bytes(&value.to_le_bytes())
    }
    /// IEEE 754 binary32, little-endian bit pattern (NaN payloads survive).
    pub fn f32(&mut self, value: f32) -> Result<(), WireError> {
        self.u32(value.to_bits())
    }
    /// IEEE 754 binary64, little-endian bit pattern.
    pub fn f64(&mut self, value: f64) -> Result<(), WireError> {
        self.u64(value.to_bits())
    }
    pub fn bool(&mut self, value: bool) -> Result<(), WireError> {
        self.u8(u8::from(value))
    }
}

/// Reads little-endian fields from a borrowed slice, front to back.
pub struct Reader<'a> {
    input: &'a [u8],
    read: usize,
}

impl<'a> Reader<'a> {
    pub fn new(input: &'a [u8]) -> Self {
        Self { input, read: 0 }
    }

    pub fn position(&self) -> usize {
        self.read
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.input.len().saturating_sub(self.read)
    }

    /// Succeeds only if every byte was read: trailing bytes mean the two ends disagree on
    /// the layout, which is a malformed datagram, not something to skip.
    pub fn finish(&self) -> Result<(), WireError> {
        if self.remaining() == 0 {
            Ok(())
        } else {
            Err(WireError::Invalid)
        }
    }

    pub fn bytes(&mut self, count: usize) -> Result<&'a [u8], WireError> {
        let end = self.read.checked_add(count).ok_or(WireError::Truncated)?;
        let taken = self.input.get(self.read..end).ok_or(WireError::Truncated)?;
        self.read = end;
        Ok(taken)
    }

    pub fn array<const N: usize>(&mut self) -> Result<[u8; N], WireError> {
        let mut out = [0u8; N];
        out.copy_from_slice(self.bytes(N)?);
        Ok(out)
    }

    pub fn u8(&mut self) -> Result<u8, WireError> {
        Ok(u8::from_le_bytes(self.array()?))
    }
    pub fn u16(&mut self) -> Result<u16, WireError> {
        Ok(u16::from_le_bytes(self.array()?))
    }
    pub fn u32(&mut self) -> Result<u32, WireError> {
        Ok(u32::from_le_bytes(self.array()?))
    }
    pub fn u64(&mut self) -> Result<u64, WireError> {
        Ok(u64::from_le_bytes(self.array()?))
    }
    pub fn i32(&mut self) -> Result<i32, WireError> {
        Ok(i32::from_le_bytes(self.array()?))
    }
    pub fn f32(&mut self) -> Result<f32, WireError> {
        Ok(f32::from_bits(self.u32()?))
    }
    pub fn f64(&mut self) -> Result<f64, WireError> {
        Ok(f64::from_bits(self.u64()?))
    }
    /// Only 0 and 1: any other byte is a malformed field, so that one value has one encoding.
    pub fn bool(&mut self) -> Result<bool, WireError> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            _ => Err(WireError::Invalid),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_little_endian_and_round_trip() {
        let mut buffer = [0u8; 32];
        let mut w = Writer::new(&mut buffer);
        w.u8(0xAB).expect("fits");
        w.u16(0x1234).expect("fits");
        w.u32(0xDEAD_BEEF).expect("fits");
        w.u64(0x0102_0304_0506_0708).expect("fits");
        w.i32(-2).expect("fits");
        w.f32(1.0).expect("fits");
        w.bool(true).expect("fits");
        assert_eq!(w.position(), 24);
        assert_eq!(
            w.written(),
            [
                0xAB, 0x34, 0x12, 0xEF, 0xBE, 0xAD, 0xDE, 8, 7, 6, 5, 4, 3, 2, 1, 0xFE, 0xFF, 0xFF,
                0xFF, 0x00, 0x00, 0x80, 0x3F, 1
            ]
        );
        let mut r = Reader::new(&buffer[..24]);
        assert_eq!(r.u8(), Ok(0xAB));
        assert_eq!(r.u16(), Ok(0x1234));
        assert_eq!(r.u32(), Ok(0xDEAD_BEEF));
        assert_eq!(r.u64(), Ok(0x0102_0304_0506_0708));
        assert_eq!(r.i32(), Ok(-2));
        assert_eq!(r.f32(), Ok(1.0));
        assert_eq!(r.bool(), Ok(true));
        assert_eq!(r.finish(), Ok(()));
    }

    #[test]
    fn running_out_is_an_error_not_a_panic() {
        let mut buffer = [0u8; 3];
        let mut w = Writer::new(&mut buffer);
        assert_eq!(w.u32(1), Err(WireError::BufferFull));
        w.u16(1).expect("fits");
        assert_eq!(w.u16(1), Err(WireError::BufferFull));
        assert_eq!(w.patch(1, &[0, 0]), Err(WireError::BufferFull));
        let mut r = Reader::new(&[1, 2, 3]);
        assert_eq!(r.u32(), Err(WireError::Truncated));
        assert_eq!(r.u16(), Ok(0x0201));
        assert_eq!(r.finish(), Err(WireError::Invalid));
        assert_eq!(r.bool(), Err(WireError::Invalid));
        assert_eq!(r.bytes(usize::MAX), Err(WireError::Truncated));
    }
}

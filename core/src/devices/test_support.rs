//! Shared test helpers: chunked feeding and a serial port double that fails the test if
//! anything would block on it.

use super::Decoder;
use std::collections::VecDeque;
use std::vec::Vec;

/// Feeds `bytes` in chunks whose sizes cycle through `chunk_sizes` (zero means one byte),
/// all at `now_ns`; returns every frame.
pub fn decode_chunked<D: Decoder>(
    decoder: &mut D,
    bytes: &[u8],
    chunk_sizes: &[usize],
    now_ns: u64,
) -> Vec<D::Frame> {
    let mut frames = Vec::new();
    let mut rest = bytes;
    let mut sizes = chunk_sizes.iter().copied().cycle();
    while !rest.is_empty() {
        let size = sizes.next().unwrap_or(1).clamp(1, rest.len());
        let (chunk, tail) = rest.split_at(size);
        decoder.push(chunk, now_ns, &mut |frame| frames.push(frame));
        rest = tail;
    }
    frames
}

/// Feeds everything in one call.
pub fn decode_whole<D: Decoder>(decoder: &mut D, bytes: &[u8], now_ns: u64) -> Vec<D::Frame> {
    let mut frames = Vec::new();
    decoder.push(bytes, now_ns, &mut |frame| frames.push(frame));
    frames
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MockError;

impl embedded_io::Error for MockError {
    fn kind(&self) -> embedded_io::ErrorKind {
        embedded_io::ErrorKind::Other
    }
}

impl core::fmt::Display for MockError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("mock port error")
    }
}

impl core::error::Error for MockError {}

/// A UART double. Reading with nothing received, or writing while not ready, panics: those
/// calls would block on real hardware, and the adapter promises never to make them.
#[derive(Debug, Default)]
pub struct MockPort {
    pub received: VecDeque<u8>,
    /// Bytes the device could deliver per `read` call (0 = unlimited), like a FIFO.
    pub read_limit: usize,
    pub transmitted: Vec<u8>,
    /// Bytes the transmitter accepts per `write` call (0 = none, i.e. not ready).
    pub write_room: usize,
    pub reads: usize,
    pub fail_next_read: bool,
}

impl embedded_io::ErrorType for MockPort {
    type Error = MockError;
}

impl embedded_io::ReadReady for MockPort {
    fn read_ready(&mut self) -> Result<bool, MockError> {
        Ok(!self.received.is_empty() || self.fail_next_read)
    }
}

impl embedded_io::Read for MockPort {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, MockError> {
        if self.fail_next_read {
            self.fail_next_read = false;
            return Err(MockError);
        }
        assert!(!self.received.is_empty(), "read would block");
        self.reads += 1;
        let limit = if self.read_limit == 0 {
            usize::MAX
        } else {
            self.read_limit
        };
        let n = buf.len().min(self.received.len()).min(limit);
        for slot in buf.iter_mut().take(n) {
            *slot = self.received.pop_front().unwrap_or_default();
        }
        Ok(n)
    }
}

impl embedded_io::WriteReady for MockPort {
    fn write_ready(&mut self) -> Result<bool, MockError> {
        Ok(self.write_room > 0)
    }
}

impl embedded_io::Write for MockPort {
    fn write(&mut self, buf: &[u8]) -> Result<usize, MockError> {
        assert!(self.write_room > 0, "write would block");
        let n = buf.len().min(self.write_room);
        self.transmitted.extend_from_slice(&buf[..n]);
        self.write_room -= n;
        Ok(n)
    }

    fn flush(&mut self) -> Result<(), MockError> {
        Ok(())
    }
}

//! The envelope every binary frame (IMU, servo board, servo commands) travels in:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 1 | sync `0xA5` |
//! | 1 | 1 | frame type (one per stream direction) |
//! | 2 | 1 | payload length `N` |
//! | 3 | 1 | counter, +1 per frame, wrapping |
//! | 4 | N | payload |
//! | 4+N | 2 | CRC-16/CCITT-FALSE of bytes `0 .. 4+N`, little-endian |
//!
//! Each stream carries exactly one frame type with one length, so the type and length bytes
//! double as a second sync word: a stray `0xA5` in the data is rejected after two bytes
//! instead of after a whole frame and a CRC.

use super::{DecoderStats, bump, bump_by};
use crc::{CRC_16_IBM_3740, Crc};
use heapless::Vec;

pub const SYNC: u8 = 0xA5;
pub const HEADER_LEN: usize = 4;
pub const CRC_LEN: usize = 2;
/// The longest payload any binary protocol here uses, with room to grow.
pub const MAX_PAYLOAD_LEN: usize = 32;
pub const MAX_FRAME_LEN: usize = HEADER_LEN + MAX_PAYLOAD_LEN + CRC_LEN;

/// CRC-16/CCITT-FALSE (catalogued as CRC-16/IBM-3740): poly 0x1021, init 0xFFFF, no
/// reflection, no final XOR. Check value: `crc16(b"123456789") == 0x29B1`.
const CCITT_FALSE: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

pub fn crc16(bytes: &[u8]) -> u16 {
    CCITT_FALSE.checksum(bytes)
}

/// Writes one frame into `out`; returns its length, or `None` when the payload is longer
/// than [`MAX_PAYLOAD_LEN`] or `out` is too short.
pub fn encode_frame(frame_type: u8, counter: u8, payload: &[u8], out: &mut [u8]) -> Option<usize> {
    let payload_len = u8::try_from(payload.len())
        .ok()
        .filter(|&len| usize::from(len) <= MAX_PAYLOAD_LEN)?;
    let body_len = HEADER_LEN + payload.len();
    let frame_len = body_len + CRC_LEN;
    let frame = out.get_mut(..frame_len)?;
    let (body, crc_bytes) = frame.split_at_mut(body_len);
    let (header, payload_out) = body.split_at_mut(HEADER_LEN);
    header.copy_from_slice(&[SYNC, frame_type, payload_len, counter]);
    payload_out.copy_from_slice(payload);
    crc_bytes.copy_from_slice(&crc16(body).to_le_bytes());
    Some(frame_len)
}

/// What [`FrameAssembler`] hands on: a frame whose envelope and CRC checked out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CheckedFrame<'a> {
    pub counter: u8,
    pub payload: &'a [u8],
}

/// Reassembles one frame type from a byte stream, one byte at a time.
///
/// The buffer only ever holds a candidate frame that starts with a sync byte. When a
/// candidate fails (bad header, bad CRC) only its first byte is dropped and the rest is
/// searched again, so a real frame hiding inside the rejected bytes is still found, and the
/// result does not depend on how the stream was chunked.
#[derive(Clone, Debug)]
pub struct FrameAssembler {
    frame_type: u8,
    payload_len: u8,
    buffer: Vec<u8, MAX_FRAME_LEN>,
    last_counter: Option<u8>,
}

enum Step {
    NeedMore,
    Progress,
    Complete,
}

impl FrameAssembler {
    /// `payload_len` over [`MAX_PAYLOAD_LEN`] makes every frame an overflow: a configuration
    /// error the counters show at once rather than a panic.
    pub const fn new(frame_type: u8, payload_len: u8) -> Self {
        Self {
            frame_type,
            payload_len,
            buffer: Vec::new(),
            last_counter: None,
        }
    }

    fn frame_len(&self) -> usize {
        HEADER_LEN + usize::from(self.payload_len) + CRC_LEN
    }

    /// Feeds one byte; calls `on_frame` if it completed a good frame. `on_frame` returns
    /// whether the payload made sense, which decides between `frames` and `invalid_payload`.
    pub fn push_byte(
        &mut self,
        byte: u8,
        stats: &mut DecoderStats,
        on_frame: &mut dyn FnMut(CheckedFrame<'_>) -> bool,
    ) {
        if self.buffer.is_empty() && byte != SYNC {
            bump(&mut stats.bytes_discarded);
            return;
        }
        if self.buffer.push(byte).is_err() {
            // Unreachable while the header checks below hold, kept so a future change that
            // breaks them costs a counted resync instead of a stuck decoder.
            bump(&mut stats.overflows);
            bump_by(&mut stats.bytes_discarded, self.buffer.len() + 1);
            self.buffer.clear();
            return;
        }
        loop {
            match self.examine(stats) {
                Step::NeedMore => return,
                Step::Progress => continue,
                Step::Complete => break,
            }
        }
        let body = self
            .buffer
            .get(..self.frame_len() - CRC_LEN)
            .unwrap_or_default();
        let counter = body.get(3).copied().unwrap_or_default();
        let payload = body.get(HEADER_LEN..).unwrap_or_default();
        if let Some(last) = self.last_counter {
            if counter != last.wrapping_add(1) {
                bump(&mut stats.sequence_gaps);
            }
        }
        self.last_counter = Some(counter);
        if on_frame(CheckedFrame { counter, payload }) {
            bump(&mut stats.frames);
        } else {
            bump(&mut stats.invalid_payload);
        }
        self.buffer.clear();
    }

    /// Looks at the candidate in the buffer: rejects its first byte, waits for more, or
    /// declares it a complete frame with a good CRC.
    fn examine(&mut self, stats: &mut DecoderStats) -> Step {
        let mut header = self.buffer.iter().copied();
        match header.next() {
            None => return Step::NeedMore,
            Some(SYNC) => {}
            Some(_) => {
                // Left over after a rejected candidate: skip up to the next sync byte.
                let garbage = self
                    .buffer
                    .iter()
                    .position(|&b| b == SYNC)
                    .unwrap_or(self.buffer.len());
                self.drop_front(garbage, stats);
                return Step::Progress;
            }
        }
        match header.next() {
            None => return Step::NeedMore,
            Some(frame_type) if frame_type == self.frame_type => {}
            Some(_) => return self.reject(&mut stats.framing_errors, &mut stats.bytes_discarded),
        }
        match header.next() {
            None => return Step::NeedMore,
            Some(len) if usize::from(len) > MAX_PAYLOAD_LEN => {
                return self.reject(&mut stats.overflows, &mut stats.bytes_discarded);
            }
            Some(len) if len != self.payload_len => {
                return self.reject(&mut stats.framing_errors, &mut stats.bytes_discarded);
            }
            Some(_) => {}
        }
        if self.buffer.len() < self.frame_len() {
            return Step::NeedMore;
        }
        let body_len = self.frame_len() - CRC_LEN;
        let crc_ok = match self.buffer.split_at_checked(body_len) {
            Some((body, [low, high])) => crc16(body) == u16::from_le_bytes([*low, *high]),
            _ => false,
        };
        if crc_ok {
            Step::Complete
        } else {
            self.reject(&mut stats.bad_checksum, &mut stats.bytes_discarded)
        }
    }

    /// Counts a rejected candidate and drops its sync byte so the search resumes one byte on.
    fn reject(&mut self, counter: &mut u32, bytes_discarded: &mut u32) -> Step {
        bump(counter);
        bump(bytes_discarded);
        self.remove_front(1);
        Step::Progress
    }

    fn drop_front(&mut self, n: usize, stats: &mut DecoderStats) {
        bump_by(&mut stats.bytes_discarded, n);
        self.remove_front(n);
    }

    fn remove_front(&mut self, n: usize) {
        let kept = self.buffer.len().saturating_sub(n);
        let mut rest: Vec<u8, MAX_FRAME_LEN> = Vec::new();
        // Cannot fail: `rest` has the buffer's capacity and gets fewer bytes.
        let _ = rest.extend_from_slice(self.buffer.get(n..).unwrap_or_default());
        debug_assert_eq!(rest.len(), kept);
        self.buffer = rest;
    }
}

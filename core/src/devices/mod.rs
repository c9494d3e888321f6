//! The devices' wire protocols, from bytes on a serial port to typed, SI-unit frames.
//!
//! The data path, in module order:
//!
//! - [`port`]: drains an `embedded_io` port without blocking into a decoder, and writes
//!   command frames only as fast as the port accepts them;
//! - [`framing`]: the sync/length/counter/CRC envelope shared by the binary protocols;
//! - [`gps`]: NMEA 0183 and Ashtech `$PASHR,POS` sentences merged into one [`gps::GpsFix`]
//!   per epoch;
//! - [`imu`]: the 100 Hz IMU frames and the slow record rebuilt from 100 of them;
//! - [`servo`]: the servo board's 50 Hz pilot frames and the computer's commands.
//!
//! Every decoder is a byte-at-a-time state machine with fixed buffers, so any chunking of a
//! stream gives the same frames, memory is bounded, and garbage costs only the bytes it
//! occupies. Nothing here panics on any input; every problem is counted in
//! [`DecoderStats`] rather than reported as an error, because a flight task can do nothing
//! with a single bad frame except count it. The byte layouts are in `docs/protocols.md`.

// Flight code must not be able to panic on any input: enforced here, relaxed for tests.
#![cfg_attr(
    not(test),
    deny(
        clippy::indexing_slicing,
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::unreachable,
        clippy::todo
    )
)]

pub mod framing;
pub mod gps;
pub mod imu;
pub mod port;
pub mod servo;

/// What a decoder has seen since it was created. Counters saturate instead of wrapping, so
/// a ground station comparing two readings never sees a count go backwards.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct DecoderStats {
    /// Frames (sentences) that passed every check and were used.
    pub frames: u32,
    /// Frames whose checksum did not match.
    pub bad_checksum: u32,
    /// A frame start followed by something that cannot be a frame: an unknown type or wrong
    /// length byte, a missing or malformed checksum field, a non-printable byte in a sentence,
    /// a sentence cut short by the next `$`.
    pub framing_errors: u32,
    /// A frame longer than the decoder's buffer (an NMEA line over
    /// [`gps::MAX_SENTENCE_LEN`], a binary length byte over [`framing::MAX_PAYLOAD_LEN`]).
    pub overflows: u32,
    /// Bytes thrown away while hunting for the next frame start, including the bytes of
    /// frames rejected for framing, overflow or checksum (not those of `invalid_payload` or
    /// `ignored` frames, which were framed correctly).
    pub bytes_discarded: u32,
    /// Frames with a good checksum whose contents make no sense (a latitude of 97°, a slow
    /// record slot past the end). Their values are not used.
    pub invalid_payload: u32,
    /// Frames with a good checksum the decoder does not use (NMEA sentences other than the
    /// supported ones, talkers other than GP/GN/GL). Not an error: receivers send them.
    pub ignored: u32,
    /// Jumps in the frame counter: each one means at least one frame was lost on the way.
    pub sequence_gaps: u32,
    /// Times the device went from fresh to stale (see [`Staleness`]).
    pub stale_events: u32,
}

impl DecoderStats {
    pub const fn new() -> Self {
        Self {
            frames: 0,
            bad_checksum: 0,
            framing_errors: 0,
            overflows: 0,
            bytes_discarded: 0,
            invalid_payload: 0,
            ignored: 0,
            sequence_gaps: 0,
            stale_events: 0,
        }
    }

    /// Every problem counted, for "is this link healthy" at a glance.
    pub fn problems(&self) -> u32 {
        self.bad_checksum
            .saturating_add(self.framing_errors)
            .saturating_add(self.overflows)
            .saturating_add(self.invalid_payload)
            .saturating_add(self.stale_events)
    }
}

/// Adds one to a counter, stopping at the top instead of wrapping.
pub(crate) fn bump(counter: &mut u32) {
    *counter = counter.saturating_add(1);
}

/// Adds `n` to a counter, stopping at the top instead of wrapping.
pub(crate) fn bump_by(counter: &mut u32, n: usize) {
    *counter = counter.saturating_add(u32::try_from(n).unwrap_or(u32::MAX));
}

/// Whether a device has said anything valid recently.
///
/// A device that has never sent a valid frame is stale: at start-up nothing downstream
/// should trust a sensor before it has spoken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Staleness {
    timeout_ns: u64,
    last_valid_ns: Option<u64>,
    /// The state at the last [`Staleness::update`], to count fresh → stale transitions.
    was_stale: bool,
}

impl Staleness {
    pub const fn new(timeout_ns: u64) -> Self {
        Self {
            timeout_ns,
            last_valid_ns: None,
            was_stale: true,
        }
    }

    pub fn timeout_ns(&self) -> u64 {
        self.timeout_ns
    }

    /// When the last valid frame arrived, if ever.
    pub fn last_valid_ns(&self) -> Option<u64> {
        self.last_valid_ns
    }

    /// Records a valid frame at `now_ns`.
    pub fn mark_valid(&mut self, now_ns: u64) {
        self.last_valid_ns = Some(now_ns);
        self.was_stale = false;
    }

    /// True when no valid frame arrived within the timeout before `now_ns` (or ever).
    pub fn is_stale(&self, now_ns: u64) -> bool {
        match self.last_valid_ns {
            None => true,
            Some(last) => now_ns.saturating_sub(last) > self.timeout_ns,
        }
    }

    /// Re-evaluates staleness at `now_ns`; true when the device has just gone stale.
    pub fn update(&mut self, now_ns: u64) -> bool {
        let stale = self.is_stale(now_ns);
        let just_went_stale = stale && !self.was_stale;
        self.was_stale = stale;
        just_went_stale
    }
}

/// A byte-stream decoder: what [`port::drain`] feeds.
pub trait Decoder {
    type Frame;

    /// Feeds bytes that arrived by `now_ns`, calling `out` for each complete frame, in order.
    /// Call it with an empty slice when nothing arrived, so staleness is still evaluated.
    fn push(&mut self, bytes: &[u8], now_ns: u64, out: &mut dyn FnMut(Self::Frame));

    fn stats(&self) -> &DecoderStats;

    /// True when no valid frame arrived within the configured timeout before `now_ns`.
    fn is_stale(&self, now_ns: u64) -> bool;
}

#[cfg(test)]
pub(crate) mod test_support;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn never_heard_device_is_stale_and_not_counted_as_an_event() {
        let mut staleness = Staleness::new(100);
        assert!(staleness.is_stale(0));
        assert!(!staleness.update(50));
    }

    #[test]
    fn staleness_counts_each_fresh_to_stale_transition_once() {
        let mut staleness = Staleness::new(100);
        staleness.mark_valid(1_000);
        assert!(!staleness.is_stale(1_100));
        assert!(!staleness.update(1_100));
        assert!(staleness.is_stale(1_101));
        assert!(staleness.update(1_101));
        assert!(!staleness.update(1_200), "already stale: no second event");
        staleness.mark_valid(1_300);
        assert!(!staleness.update(1_300));
        assert!(staleness.update(5_000));
        assert_eq!(staleness.last_valid_ns(), Some(1_300));
    }

    #[test]
    fn counters_saturate() {
        let mut counter = u32::MAX - 1;
        bump(&mut counter);
        bump(&mut counter);
        assert_eq!(counter, u32::MAX);
        let mut other = 5;
        bump_by(&mut other, usize::MAX);
        assert_eq!(other, u32::MAX);
    }
}

//! The datagram around a message: header, payload, optional HMAC tag, CRC-32.
//!
//! ```text
//! | header (28) | payload (payload_len) | tag (32, if signed) | CRC-32 (4) |
//!  \________ HMAC-SHA256 covers ______/
//!  \_______________ CRC-32 covers ______________________________/
//! ```
//!
//! The CRC comes last and covers the tag too, so a datagram damaged anywhere counts as
//! `bad_crc` and `bad_signature` is left meaning what it says: an intact datagram whose
//! tag does not match (a wrong key or a forgery).

use super::auth::{self, LinkKey};
use super::messages::Message;
use super::wire::{Reader, WireError, Writer};

pub const MAGIC: [u8; 4] = *b"SKYF";
pub const VERSION: u8 = 1;
pub const HEADER_LEN: usize = 28;
pub const TAG_LEN: usize = 32;
pub const CRC_LEN: usize = 4;
/// The largest UDP payload that fits an Ethernet MTU of 1500 without IP fragmentation
/// (1500 − 20 IPv4 − 8 UDP): a fragment lost on a radio link loses the whole datagram.
pub const MAX_DATAGRAM_LEN: usize = 1472;
/// The largest payload, when signed.
pub const MAX_PAYLOAD_LEN: usize = MAX_DATAGRAM_LEN - HEADER_LEN - TAG_LEN - CRC_LEN;

/// Header flag bits; the others are reserved and must be zero.
pub mod flags {
    /// A 32-byte HMAC-SHA256 tag follows the payload.
    pub const SIGNED: u8 = 0x01;
    pub const KNOWN: u8 = SIGNED;
}

/// What a sender chooses for each datagram.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Envelope {
    /// Vehicle → ground: the vehicle's own id. Ground → vehicle: the vehicle addressed.
    pub vehicle_id: u16,
    /// Who sent it: 0 is the vehicle, ground stations take 1..=255.
    pub sender_id: u8,
    /// The vehicle's run: chosen by the vehicle at start, never repeated under one key,
    /// sent in all its telemetry; a command must carry the vehicle's current one. It is
    /// what stops a command recorded in one run being replayed in the next, when the
    /// replay windows have started afresh.
    pub run_id: u32,
    /// Per sender, +1 for each datagram. Signed commands must never reuse one under a key.
    pub sequence: u32,
    /// The sender's clock when the datagram was made.
    pub t_ns: u64,
}

/// A parsed header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Header {
    pub envelope: Envelope,
    pub message_type: u8,
    pub signed: bool,
    pub payload_len: u16,
}

/// Why a datagram could not be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The output buffer is too small, or the datagram would exceed [`MAX_DATAGRAM_LEN`].
    TooLong,
    /// The message has a field its encoding cannot carry.
    Invalid,
}

impl From<WireError> for EncodeError {
    fn from(e: WireError) -> Self {
        match e {
            WireError::BufferFull | WireError::Truncated => EncodeError::TooLong,
            WireError::Invalid => EncodeError::Invalid,
        }
    }
}

/// Why a datagram was refused, in the order the checks run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// The CRC does not match (damaged in transit, or not ours at all).
    BadCrc,
    /// Too short or long, wrong magic or version, reserved flags set, lengths that
    /// disagree, or a payload that does not decode.
    Malformed,
    /// Signing was required but the datagram carries no tag.
    Unsigned,
    /// The tag does not match the key.
    BadSignature,
}

/// The pieces of a datagram whose CRC and lengths have been checked.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Frame<'a> {
    pub header: Header,
    pub payload: &'a [u8],
    /// Header and payload: what the tag signs.
    pub signed_part: &'a [u8],
    pub tag: Option<&'a [u8]>,
}

/// CRC-32/ISO-HDLC (the Ethernet and zlib CRC, `crc`'s catalogue entry): reflected
/// polynomial 0xEDB88320, initial value and final XOR 0xFFFFFFFF. Check value:
/// `crc32(b"123456789") == 0xCBF43926`.
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// Writes a whole datagram into `out` and returns its length; signs it when given a key.
pub fn encode_datagram(
    envelope: &Envelope,
    message: &Message,
    key: Option<&LinkKey>,
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    let limit = out.len().min(MAX_DATAGRAM_LEN);
    let out = out.get_mut(..limit).ok_or(EncodeError::TooLong)?;
    let mut w = Writer::new(out);
    w.bytes(&MAGIC)?;
    w.u8(VERSION)?;
    w.u8(if key.is_some() { flags::SIGNED } else { 0 })?;
    w.u8(message.message_type())?;
    w.u8(envelope.sender_id)?;
    w.u16(envelope.vehicle_id)?;
    let payload_len_at = w.position();
    w.u16(0)?; // payload length, patched below
    w.u32(envelope.run_id)?;
    w.u32(envelope.sequence)?;
    w.u64(envelope.t_ns)?;
    message.encode_payload(&mut w)?;
    let payload_len = w.position().saturating_sub(HEADER_LEN);
    let payload_len = u16::try_from(payload_len).map_err(|_| EncodeError::TooLong)?;
    w.patch(payload_len_at, &payload_len.to_le_bytes())?;
    if let Some(key) = key {
        let tag = auth::sign(key, w.written()).ok_or(EncodeError::Invalid)?;
        w.bytes(&tag)?;
    }
    let crc = crc32(w.written());
    w.u32(crc)?;
    Ok(w.position())
}

/// Checks a datagram's length, CRC and header, and splits it. Does not look at the tag or
/// the payload.
pub fn parse_frame(datagram: &[u8]) -> Result<Frame<'_>, FrameError> {
    if datagram.len() < HEADER_LEN + CRC_LEN || datagram.len() > MAX_DATAGRAM_LEN {
        return Err(FrameError::Malformed);
    }
    let (covered, crc) = datagram
        .split_at_checked(datagram.len().saturating_sub(CRC_LEN))
        .ok_or(FrameError::Malformed)?;
    let crc = Reader::new(crc).u32().map_err(|_| FrameError::Malformed)?;
    if crc32(covered) != crc {
        return Err(FrameError::BadCrc);
    }
    let header = parse_header(covered).map_err(|_| FrameError::Malformed)?;
    let tag_len = if header.signed { TAG_LEN } else { 0 };
    if covered.len() != HEADER_LEN + usize::from(header.payload_len) + tag_len {
        return Err(FrameError::Malformed);
    }
    let (signed_part, tag) = covered
        .split_at_checked(covered.len().saturating_sub(tag_len))
        .ok_or(FrameError::Malformed)?;
    let payload = signed_part.get(HEADER_LEN..).ok_or(FrameError::Malformed)?;
    Ok(Frame {
        header,
        payload,
        signed_part,
        tag: header.signed.then_some(tag),
    })
}

fn parse_header(bytes: &[u8]) -> Result<Header, WireError> {
    let mut r = Reader::new(bytes);
    if r.array::<4>()? != MAGIC || r.u8()? != VERSION {
        return Err(WireError::Invalid);
    }
    let header_flags = r.u8()?;
    if header_flags & !flags::KNOWN != 0 {
        return Err(WireError::Invalid);
    }
    let message_type = r.u8()?;
    let sender_id = r.u8()?;
    let vehicle_id = r.u16()?;
    let payload_len = r.u16()?;
    let run_id = r.u32()?;
    let sequence = r.u32()?;
    let t_ns = r.u64()?;
    Ok(Header {
        envelope: Envelope {
            vehicle_id,
            sender_id,
            run_id,
            sequence,
            t_ns,
        },
        message_type,
        signed: header_flags & flags::SIGNED != 0,
        payload_len,
    })
}

/// Whether and how to check the tag when decoding.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Verify<'k> {
    /// Ignore any tag (e.g. a ground station without the key, showing telemetry).
    No,
    /// Check the tag if there is one; accept unsigned datagrams.
    IfSigned(&'k LinkKey),
    /// Refuse unsigned datagrams and check the tag.
    Required(&'k LinkKey),
}

impl Frame<'_> {
    /// Checks the tag as `verify` asks: the one place a datagram is authenticated.
    pub fn verify(&self, verify: Verify<'_>) -> Result<(), FrameError> {
        match (verify, self.tag) {
            (Verify::Required(_), None) => Err(FrameError::Unsigned),
            (Verify::Required(key) | Verify::IfSigned(key), Some(tag))
                if !auth::verify(key, self.signed_part, tag) =>
            {
                Err(FrameError::BadSignature)
            }
            _ => Ok(()),
        }
    }

    /// The typed message the payload holds.
    pub fn message(&self) -> Result<Message, FrameError> {
        Message::decode_payload(self.header.message_type, self.payload)
            .map_err(|_| FrameError::Malformed)
    }
}

/// Parses, authenticates (as asked) and decodes one datagram: the one decode path, parse →
/// verify → decode. The vehicle's command gate ([`super::auth::CommandGate`]) takes the same
/// three steps with its own checks between them (vehicle id before the tag, run id and
/// replay window before the payload).
pub fn decode_datagram(
    datagram: &[u8],
    verify: Verify<'_>,
) -> Result<(Header, Message), FrameError> {
    let frame = parse_frame(datagram)?;
    frame.verify(verify)?;
    Ok((frame.header, frame.message()?))
}

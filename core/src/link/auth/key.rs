//! The pre-shared link key and the HMAC-SHA256 tags it makes and checks.

use crate::link::frame;
use hmac::{Hmac, KeyInit, Mac};
use sha2::Sha256;

pub const KEY_LEN: usize = 32;

/// The pre-shared key. Its `Debug` does not print it.
#[derive(Clone, PartialEq, Eq)]
pub struct LinkKey([u8; KEY_LEN]);

impl LinkKey {
    pub const fn new(bytes: [u8; KEY_LEN]) -> Self {
        Self(bytes)
    }

    /// Exactly 64 hex digits (either case), as a key file or `--key` would hold them.
    pub fn from_hex(text: &str) -> Option<Self> {
        let text = text.as_bytes();
        if text.len() != 2 * KEY_LEN {
            return None;
        }
        let mut bytes = [0u8; KEY_LEN];
        for (byte, pair) in bytes.iter_mut().zip(text.chunks_exact(2)) {
            let (&high, &low) = (pair.first()?, pair.get(1)?);
            *byte = hex_digit(high)? << 4 | hex_digit(low)?;
        }
        Some(Self(bytes))
    }
}

fn hex_digit(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'a'..=b'f' => Some(c - b'a' + 10),
        b'A'..=b'F' => Some(c - b'A' + 10),
        _ => None,
    }
}

impl core::fmt::Debug for LinkKey {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("LinkKey(..)")
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for LinkKey {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "LinkKey(..)")
    }
}

fn mac(key: &LinkKey, signed_part: &[u8]) -> Option<Hmac<Sha256>> {
    // HMAC takes keys of any length, so this cannot fail; `None` just keeps it panic-free.
    let mut mac = Hmac::<Sha256>::new_from_slice(&key.0).ok()?;
    mac.update(signed_part);
    Some(mac)
}

/// The HMAC-SHA256 tag of `signed_part` (a datagram's header and payload).
pub fn sign(key: &LinkKey, signed_part: &[u8]) -> Option<[u8; frame::TAG_LEN]> {
    Some(mac(key, signed_part)?.finalize().into_bytes().into())
}

/// Constant-time check of a tag (the crate's `verify_slice`): the time taken does not tell
/// an attacker how many leading bytes were right.
pub fn verify(key: &LinkKey, signed_part: &[u8], tag: &[u8]) -> bool {
    mac(key, signed_part).is_some_and(|m| m.verify_slice(tag).is_ok())
}

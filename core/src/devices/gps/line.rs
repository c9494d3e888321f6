//! Line framing: a `$…*hh` sentence, its checksum, and what is wrong with a line that is not one.

pub(super) enum LineVerdict {
    /// The sentence body (before `*`) is `line[..body_len]` and its checksum matched.
    Good {
        body_len: usize,
    },
    BadChecksum,
    Framing,
}

/// The NMEA checksum: XOR of every byte between `$` and `*`.
pub fn nmea_checksum(body: &[u8]) -> u8 {
    body.iter().fold(0, |acc, &byte| acc ^ byte)
}

pub(super) fn hex_digit(byte: u8) -> Option<u8> {
    match byte {
        b'0'..=b'9' => Some(byte - b'0'),
        b'A'..=b'F' => Some(byte - b'A' + 10),
        b'a'..=b'f' => Some(byte - b'a' + 10),
        _ => None,
    }
}

pub(super) fn check_sentence(line: &[u8]) -> LineVerdict {
    let Some(star) = line.iter().rposition(|&b| b == b'*') else {
        return LineVerdict::Framing;
    };
    let Some((body, checksum_field)) = line.split_at_checked(star) else {
        return LineVerdict::Framing;
    };
    let expected = match checksum_field {
        [b'*', high, low] => match (hex_digit(*high), hex_digit(*low)) {
            (Some(high), Some(low)) => (high << 4) | low,
            _ => return LineVerdict::Framing,
        },
        _ => return LineVerdict::Framing,
    };
    if nmea_checksum(body) == expected {
        LineVerdict::Good { body_len: star }
    } else {
        LineVerdict::BadChecksum
    }
}

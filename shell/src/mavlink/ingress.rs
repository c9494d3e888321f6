//! The MAVLink receive path: one UDP datagram in, the messages that may act out, and every
//! refusal counted. Order, cheapest first (as the skyframe link's, `shell/src/link.rs`):
//! the source's share (token bucket, before any parsing), the frames (the `mavlink`
//! crate's parser: magic, length, CRC with the dialect's extra CRC), the signature and
//! its replay window (when a key is set), the target system. Only then is anything queued.

// MISSION_REQUEST is deprecated but still sent by ground stations (MAVProxy).
#![allow(deprecated)]

use super::mav::MavMessage;
use mavlink::{MAVLinkMessageRaw, MavHeader, MavlinkReader, MavlinkVersion, Message};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};

/// The endpoint's counters: what came in, what was refused and why, what went out. Shared
/// with the flight's report; also in SYS_STATUS (`errors_comm`, `drop_rate_comm`).
#[derive(Debug, Default)]
pub struct Counters {
    pub datagrams_in: AtomicU64,
    /// Datagrams dropped unread: their source was over its share.
    pub rate_limited: AtomicU64,
    /// Datagrams with no whole MAVLink frame with a good CRC.
    pub malformed: AtomicU64,
    /// Frames of a message the common dialect does not have, or whose payload did not parse.
    pub unknown: AtomicU64,
    /// Frames that would change something, unsigned while a key is set.
    pub unsigned: AtomicU64,
    pub bad_signature: AtomicU64,
    /// Signed with the key, but with a timestamp at or before the stream's last.
    pub replayed: AtomicU64,
    /// For another system (not ours and not broadcast).
    pub other_target: AtomicU64,
    pub accepted: AtomicU64,
    pub frames_out: AtomicU64,
    pub send_errors: AtomicU64,
    /// Vehicle telemetry the MAVLink thread had no room for (its queue was full).
    pub telemetry_dropped: AtomicU64,
}

impl Counters {
    /// Everything refused after the share: the frames that reached the parser and failed.
    pub fn rejected(&self) -> u64 {
        [
            &self.malformed,
            &self.unknown,
            &self.unsigned,
            &self.bad_signature,
            &self.replayed,
        ]
        .iter()
        .map(|c| c.load(Ordering::Relaxed))
        .sum()
    }

    pub fn snapshot(&self) -> CountersReport {
        let l = |c: &AtomicU64| c.load(Ordering::Relaxed);
        CountersReport {
            datagrams_in: l(&self.datagrams_in),
            rate_limited: l(&self.rate_limited),
            malformed: l(&self.malformed),
            unknown: l(&self.unknown),
            unsigned: l(&self.unsigned),
            bad_signature: l(&self.bad_signature),
            replayed: l(&self.replayed),
            other_target: l(&self.other_target),
            accepted: l(&self.accepted),
            frames_out: l(&self.frames_out),
            send_errors: l(&self.send_errors),
            telemetry_dropped: l(&self.telemetry_dropped),
        }
    }
}

/// The counters at one moment (the flight's report and JSON summary).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct CountersReport {
    pub datagrams_in: u64,
    pub rate_limited: u64,
    pub malformed: u64,
    pub unknown: u64,
    pub unsigned: u64,
    pub bad_signature: u64,
    pub replayed: u64,
    pub other_target: u64,
    pub accepted: u64,
    pub frames_out: u64,
    pub send_errors: u64,
    pub telemetry_dropped: u64,
}

/// Messages a ground station may send unsigned while a key is set: they read, they change
/// nothing (MAVLink's signing guide lets an autopilot choose which unsigned messages it
/// takes). Everything else — commands, parameter sets, mission writes, mode changes,
/// stream rates — must be signed.
fn reads_only(m: &MavMessage) -> bool {
    matches!(
        m,
        MavMessage::HEARTBEAT(_)
            | MavMessage::PARAM_REQUEST_LIST(_)
            | MavMessage::PARAM_REQUEST_READ(_)
            | MavMessage::MISSION_REQUEST_LIST(_)
            | MavMessage::MISSION_REQUEST_INT(_)
            | MavMessage::MISSION_REQUEST(_)
            | MavMessage::MISSION_ACK(_)
    )
}

/// Streams remembered for replay checks; past this the one heard from longest ago goes.
const STREAMS_KEPT: usize = 64;
/// A new stream's first timestamp may lag the newest seen by at most a minute (MAVLink's
/// signing rule), in the signature's 10 µs units.
const NEW_STREAM_LAG: u64 = 60 * 100_000;

/// The signature check with its replay windows, one per (link id, system, component).
pub struct Verifier {
    key: Option<[u8; 32]>,
    streams: HashMap<(u8, u8, u8), u64>,
    /// The newest timestamp accepted, or the local clock's if later.
    newest: u64,
}

/// MAVLink's signature clock: 10 µs units since 2015-01-01.
pub fn signing_clock() -> u64 {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros());
    u64::try_from(now.saturating_sub(1_420_070_400_000_000) / 10).unwrap_or(u64::MAX)
}

enum Signature {
    Unsigned,
    Good,
    Bad,
    Replayed,
}

impl Verifier {
    pub fn new(key: Option<[u8; 32]>) -> Self {
        Self {
            key,
            streams: HashMap::new(),
            newest: 0,
        }
    }

    pub fn keyed(&self) -> bool {
        self.key.is_some()
    }

    fn check(&mut self, raw: &MAVLinkMessageRaw, now: u64) -> Signature {
        let (Some(key), MAVLinkMessageRaw::V2(v2)) = (&self.key, raw) else {
            return Signature::Unsigned;
        };
        if v2.incompatibility_flags() & mavlink::consts::v2::IFLAG_SIGNED == 0 {
            return Signature::Unsigned;
        }
        let mut expected = [0u8; mavlink::consts::v2::SIGNATURE_VALUE_SIZE];
        v2.calculate_signature(key, &mut expected);
        if expected != v2.signature_value() {
            return Signature::Bad;
        }
        let timestamp = v2.signature_timestamp();
        let stream = (v2.signature_link_id(), v2.system_id(), v2.component_id());
        self.newest = self.newest.max(now);
        let fresh = match self.streams.get(&stream) {
            Some(last) => timestamp > *last,
            None => timestamp.saturating_add(NEW_STREAM_LAG) >= self.newest,
        };
        if !fresh {
            return Signature::Replayed;
        }
        if !self.streams.contains_key(&stream) && self.streams.len() >= STREAMS_KEPT {
            let oldest = self
                .streams
                .iter()
                .min_by_key(|(_, t)| **t)
                .map(|(s, _)| *s);
            if let Some(oldest) = oldest {
                self.streams.remove(&oldest);
            }
        }
        self.streams.insert(stream, timestamp);
        self.newest = self.newest.max(timestamp);
        Signature::Good
    }
}

/// One accepted message.
pub struct Accepted {
    pub header: MavHeader,
    pub message: MavMessage,
}

/// Screens one datagram (whose source already had its share): every frame in it that may
/// act goes to `out`; the rest are counted. `now` is [`signing_clock`]'s.
pub fn screen(
    datagram: &[u8],
    our_system: u8,
    verifier: &mut Verifier,
    counters: &Counters,
    now: u64,
    out: &mut Vec<Accepted>,
) {
    let mut reader = MavlinkReader::new(datagram);
    let mut frames = 0usize;
    // A datagram holds at most 1500 bytes: at most ~130 of the smallest frames.
    while frames < 256 {
        let Ok(raw) = reader.read_any_raw_message::<MavMessage>() else {
            break;
        };
        frames += 1;
        let signature = verifier.check(&raw, now);
        let version = match raw {
            MAVLinkMessageRaw::V1(_) => MavlinkVersion::V1,
            MAVLinkMessageRaw::V2(_) => MavlinkVersion::V2,
        };
        let Ok(message) = MavMessage::parse(version, raw.message_id(), raw.payload()) else {
            counters.unknown.fetch_add(1, Ordering::Relaxed);
            continue;
        };
        match signature {
            Signature::Bad => {
                counters.bad_signature.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            Signature::Replayed => {
                counters.replayed.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            Signature::Unsigned if verifier.keyed() && !reads_only(&message) => {
                counters.unsigned.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            Signature::Unsigned | Signature::Good => {}
        }
        if let Some(target) = message.target_system_id()
            && target != 0
            && target != our_system
        {
            counters.other_target.fetch_add(1, Ordering::Relaxed);
            continue;
        }
        counters.accepted.fetch_add(1, Ordering::Relaxed);
        out.push(Accepted {
            header: MavHeader {
                system_id: raw.system_id(),
                component_id: raw.component_id(),
                sequence: raw.sequence(),
            },
            message,
        });
    }
    if frames == 0 {
        counters.malformed.fetch_add(1, Ordering::Relaxed);
    }
}

/// One outgoing frame (MAVLink 2; signed when `signing` is given).
pub fn frame(
    header: MavHeader,
    message: &MavMessage,
    signing: Option<&mavlink::SigningData>,
) -> Vec<u8> {
    let mut out = Vec::with_capacity(64);
    // Writing into a Vec cannot fail.
    let _ = mavlink::write_v2_msg_signed(&mut out, header, message, signing);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mavlink::mav::{PARAM_REQUEST_LIST_DATA, PARAM_SET_DATA};

    const KEY: [u8; 32] = [7; 32];

    fn gcs() -> MavHeader {
        MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: 0,
        }
    }

    fn set() -> MavMessage {
        MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: 0.5,
            target_system: 1,
            target_component: 1,
            param_id: "CTL_ROLL_KP".into(),
            ..PARAM_SET_DATA::default()
        })
    }

    fn signer(key: [u8; 32]) -> mavlink::SigningData {
        mavlink::SigningData::from_config(mavlink::SigningConfig::new(key, 0, true, false))
    }

    fn run(verifier: &mut Verifier, bytes: &[u8], counters: &Counters) -> usize {
        let mut out = Vec::new();
        screen(bytes, 1, verifier, counters, signing_clock(), &mut out);
        out.len()
    }

    #[test]
    fn without_a_key_well_formed_frames_pass_and_junk_is_counted() {
        let counters = Counters::default();
        let mut v = Verifier::new(None);
        assert_eq!(run(&mut v, &frame(gcs(), &set(), None), &counters), 1);
        assert_eq!(run(&mut v, b"not mavlink at all", &counters), 0);
        let mut damaged = frame(gcs(), &set(), None);
        let last = damaged.len() - 1;
        damaged[last] ^= 0x55;
        assert_eq!(run(&mut v, &damaged, &counters), 0);
        let c = counters.snapshot();
        assert_eq!((c.accepted, c.malformed), (1, 2));
    }

    #[test]
    fn with_a_key_unsigned_changes_badly_signed_and_replayed_frames_are_dropped() {
        let counters = Counters::default();
        let mut v = Verifier::new(Some(KEY));
        // Unsigned: a set is dropped, a read passes.
        assert_eq!(run(&mut v, &frame(gcs(), &set(), None), &counters), 0);
        let list = MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
            target_system: 1,
            target_component: 1,
        });
        assert_eq!(run(&mut v, &frame(gcs(), &list, None), &counters), 1);
        // Another key.
        let wrong = frame(gcs(), &set(), Some(&signer([8; 32])));
        assert_eq!(run(&mut v, &wrong, &counters), 0);
        // The key: accepted once; the same bytes again are a replay.
        let good = frame(gcs(), &set(), Some(&signer(KEY)));
        assert_eq!(run(&mut v, &good, &counters), 1);
        assert_eq!(run(&mut v, &good, &counters), 0);
        let c = counters.snapshot();
        assert_eq!(
            (c.unsigned, c.bad_signature, c.replayed, c.accepted),
            (1, 1, 1, 2)
        );
    }

    #[test]
    fn frames_for_another_system_are_not_ours() {
        let counters = Counters::default();
        let mut v = Verifier::new(None);
        let other = MavMessage::PARAM_SET(PARAM_SET_DATA {
            target_system: 2,
            ..PARAM_SET_DATA::default()
        });
        assert_eq!(run(&mut v, &frame(gcs(), &other, None), &counters), 0);
        assert_eq!(counters.snapshot().other_target, 1);
    }
}

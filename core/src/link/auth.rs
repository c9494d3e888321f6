//! Command authentication: HMAC-SHA256 tags, per-sender replay windows, and the gate every
//! command datagram passes before the vehicle acts on it.

use super::frame::{self, FrameError};
use super::messages::{AckResult, Command, CommandAck, Value, message_type};
use super::params::{ParamTable, SetParamResult};
use super::wire::{Reader, WireError, Writer};
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

/// How far behind the newest sequence number a late datagram may still be accepted.
pub const REPLAY_WINDOW: u32 = 64;

/// Why a sequence number was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReplayError {
    /// Already accepted.
    Duplicate,
    /// More than [`REPLAY_WINDOW`] − 1 behind the newest: it can no longer be told apart
    /// from a replay.
    TooOld,
}

/// One sender's sliding window (RFC 4303 §3.4.3, as IPsec and DTLS do it): the newest
/// sequence number accepted, and a bit for each of the 64 numbers up to it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReplayWindow {
    /// `None` until the first datagram.
    newest: Option<u32>,
    /// Bit `i`: `newest − i` was accepted.
    seen: u64,
}

impl ReplayWindow {
    pub const fn new() -> Self {
        Self {
            newest: None,
            seen: 0,
        }
    }

    pub fn newest(&self) -> Option<u32> {
        self.newest
    }

    /// Whether `sequence` would be accepted; changes nothing.
    pub fn check(&self, sequence: u32) -> Result<(), ReplayError> {
        let Some(newest) = self.newest else {
            return Ok(());
        };
        if sequence > newest {
            return Ok(());
        }
        let behind = newest - sequence;
        if behind >= REPLAY_WINDOW {
            Err(ReplayError::TooOld)
        } else if self.seen & (1u64 << behind) != 0 {
            Err(ReplayError::Duplicate)
        } else {
            Ok(())
        }
    }

    /// Marks `sequence` accepted, sliding the window if it is the newest. Call only after
    /// the datagram is authenticated, or a forger could slide the window past real ones.
    pub fn accept(&mut self, sequence: u32) -> Result<(), ReplayError> {
        self.check(sequence)?;
        match self.newest {
            Some(newest) if sequence <= newest => {
                self.seen |= 1u64 << (newest - sequence);
            }
            Some(newest) => {
                let ahead = sequence - newest;
                self.seen = if ahead >= REPLAY_WINDOW {
                    0
                } else {
                    self.seen << ahead
                } | 1;
                self.newest = Some(sequence);
            }
            None => {
                self.seen = 1;
                self.newest = Some(sequence);
            }
        }
        Ok(())
    }
}

/// Most ground senders a vehicle keeps windows for.
pub const MAX_SENDERS: usize = 8;

/// Replay windows of up to [`MAX_SENDERS`] senders. A sender gets a window at its first
/// authenticated datagram, so strangers cannot fill the table.
#[derive(Clone, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReplayGuard {
    senders: [Option<(u8, ReplayWindow)>; MAX_SENDERS],
}

/// Why the guard refused a datagram.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GuardError {
    Replay(ReplayError),
    /// A new sender, and every slot is taken.
    TooManySenders,
}

impl ReplayGuard {
    pub const fn new() -> Self {
        Self {
            senders: [None; MAX_SENDERS],
        }
    }

    pub fn window(&self, sender_id: u8) -> Option<&ReplayWindow> {
        self.senders
            .iter()
            .flatten()
            .find(|(id, _)| *id == sender_id)
            .map(|(_, w)| w)
    }

    /// Checks and records an authenticated datagram's sequence number.
    pub fn accept(&mut self, sender_id: u8, sequence: u32) -> Result<(), GuardError> {
        if let Some((_, window)) = self
            .senders
            .iter_mut()
            .flatten()
            .find(|(id, _)| *id == sender_id)
        {
            return window.accept(sequence).map_err(GuardError::Replay);
        }
        let free = self
            .senders
            .iter_mut()
            .find(|slot| slot.is_none())
            .ok_or(GuardError::TooManySenders)?;
        let mut window = ReplayWindow::new();
        window.accept(sequence).map_err(GuardError::Replay)?;
        *free = Some((sender_id, window));
        Ok(())
    }
}

crate::log_record! {
    /// The link's counters, sent in every executive status and logged (`link.bin`) once a
    /// second and at the end, so what was refused and why is in the flight's log, not only
    /// on the ground. Saturating `u32`s; the field order is the wire order
    /// (`docs/link-protocol.md`) and the log's column order.
    ///
    /// The command side counts every datagram the gate sees: `received` equals `accepted`
    /// plus the sum of the rejection counters.
    #[derive(Eq)]
    #[cfg_attr(feature = "defmt", derive(defmt::Format))]
    pub struct LinkCounters {
        received: u32 = "%u",
        accepted: u32 = "%u",
        bad_crc: u32 = "%u",
        /// Bad length, magic, version or flags, a payload that does not decode, or not a
        /// command at all.
        malformed: u32 = "%u",
        wrong_vehicle: u32 = "%u",
        unsigned: u32 = "%u",
        bad_signature: u32 = "%u",
        /// Authentic, but from another run of the vehicle (a recording replayed, or a ground
        /// station that has not heard the vehicle since it restarted).
        wrong_run: u32 = "%u",
        /// Duplicate or too old for the sender's replay window.
        replayed: u32 = "%u",
        /// A new sender when every replay window is taken.
        too_many_senders: u32 = "%u",
        out_of_range: u32 = "%u",
        unknown_param: u32 = "%u",
        wrong_type: u32 = "%u",
        /// Telemetry datagrams handed to the socket, and ones it refused (counted by the
        /// sender, not the gate).
        telemetry_sent: u32 = "%u",
        telemetry_send_failed: u32 = "%u",
        /// Dropped unread by the shell because their source sent more than its share
        /// ([`crate::link::ingress`]): a flood, counted, never queued.
        rate_limited: u32 = "%u",
    }
}

/// Number of `u32` counters on the wire.
pub const LINK_COUNTERS: usize = 16;

impl LinkCounters {
    /// The counters in wire order (`docs/link-protocol.md`), which is also the column order of
    /// `link.bin`.
    pub fn as_array(&self) -> [u32; LINK_COUNTERS] {
        [
            self.received,
            self.accepted,
            self.bad_crc,
            self.malformed,
            self.wrong_vehicle,
            self.unsigned,
            self.bad_signature,
            self.wrong_run,
            self.replayed,
            self.too_many_senders,
            self.out_of_range,
            self.unknown_param,
            self.wrong_type,
            self.telemetry_sent,
            self.telemetry_send_failed,
            self.rate_limited,
        ]
    }

    /// Rejected commands of every kind.
    pub fn rejected(&self) -> u32 {
        [
            self.rate_limited,
            self.bad_crc,
            self.malformed,
            self.wrong_vehicle,
            self.unsigned,
            self.bad_signature,
            self.wrong_run,
            self.replayed,
            self.too_many_senders,
            self.out_of_range,
            self.unknown_param,
            self.wrong_type,
        ]
        .iter()
        .fold(0u32, |sum, &count| sum.saturating_add(count))
    }

    pub(crate) fn encode(&self, w: &mut Writer<'_>) -> Result<(), WireError> {
        self.as_array().iter().try_for_each(|&c| w.u32(c))
    }

    pub(crate) fn decode(r: &mut Reader<'_>) -> Result<Self, WireError> {
        Ok(Self {
            received: r.u32()?,
            accepted: r.u32()?,
            bad_crc: r.u32()?,
            malformed: r.u32()?,
            wrong_vehicle: r.u32()?,
            unsigned: r.u32()?,
            bad_signature: r.u32()?,
            wrong_run: r.u32()?,
            replayed: r.u32()?,
            too_many_senders: r.u32()?,
            out_of_range: r.u32()?,
            unknown_param: r.u32()?,
            wrong_type: r.u32()?,
            telemetry_sent: r.u32()?,
            telemetry_send_failed: r.u32()?,
            rate_limited: r.u32()?,
        })
    }

    fn count(&mut self, reason: RejectReason) {
        let counter = match reason {
            RejectReason::BadCrc => &mut self.bad_crc,
            RejectReason::Malformed => &mut self.malformed,
            RejectReason::WrongVehicle => &mut self.wrong_vehicle,
            RejectReason::Unsigned => &mut self.unsigned,
            RejectReason::BadSignature => &mut self.bad_signature,
            RejectReason::WrongRun => &mut self.wrong_run,
            RejectReason::Replayed => &mut self.replayed,
            RejectReason::TooManySenders => &mut self.too_many_senders,
            RejectReason::OutOfRange => &mut self.out_of_range,
            RejectReason::UnknownParam => &mut self.unknown_param,
            RejectReason::WrongType => &mut self.wrong_type,
        };
        *counter = counter.saturating_add(1);
    }
}

/// The checks that need no state: a whole datagram, a command, for this vehicle, signed
/// with our key. The gate runs them first; the shell's socket thread runs the same ones
/// before it queues anything, so a flood of forgeries never reaches the task
/// ([`crate::link::ingress`]).
pub fn screen_command<'d>(
    datagram: &'d [u8],
    key: &LinkKey,
    vehicle_id: u16,
) -> Result<frame::Frame<'d>, RejectReason> {
    let frame = frame::parse_frame(datagram).map_err(|e| match e {
        FrameError::BadCrc => RejectReason::BadCrc,
        _ => RejectReason::Malformed,
    })?;
    if !message_type::is_command(frame.header.message_type) {
        return Err(RejectReason::Malformed);
    }
    if frame.header.envelope.vehicle_id != vehicle_id {
        return Err(RejectReason::WrongVehicle);
    }
    let tag = frame.tag.ok_or(RejectReason::Unsigned)?;
    if !verify(key, frame.signed_part, tag) {
        return Err(RejectReason::BadSignature);
    }
    Ok(frame)
}

/// Why the gate dropped a datagram, in the order the checks run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RejectReason {
    BadCrc,
    Malformed,
    WrongVehicle,
    Unsigned,
    BadSignature,
    WrongRun,
    Replayed,
    TooManySenders,
    OutOfRange,
    UnknownParam,
    WrongType,
}

/// A dropped datagram. Only authenticated commands that failed a range or parameter check
/// get an acknowledgement to send back.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Rejected {
    pub reason: RejectReason,
    pub ack: Option<CommandAck>,
}

/// An authenticated, fresh, well-formed, in-range command: safe to act on.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AcceptedCommand {
    pub sender_id: u8,
    pub sequence: u32,
    /// The sender's clock when it sent the command.
    pub sent_t_ns: u64,
    pub command: Command,
}

impl AcceptedCommand {
    /// The acknowledgement to send once the command has been acted on.
    pub fn ack(&self, result: AckResult, value_in_force: Option<Value>) -> CommandAck {
        CommandAck {
            command_sender_id: self.sender_id,
            command_sequence: self.sequence,
            command_type: self.command.message_type(),
            result,
            value_in_force,
        }
    }
}

/// What the gate needs to know about the vehicle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GateConfig {
    pub vehicle_id: u16,
    /// This run's id (see [`Envelope::run_id`](super::frame::Envelope::run_id)).
    pub run_id: u32,
    /// Tasks in the frame table: a telemetry rate for a task past these is out of range.
    pub task_count: usize,
}

/// Every command datagram goes through here; nothing it rejects reaches the vehicle.
#[derive(Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CommandGate {
    key: LinkKey,
    config: GateConfig,
    senders: ReplayGuard,
    counters: LinkCounters,
    last_accepted_ns: Option<u64>,
}

impl CommandGate {
    pub fn new(key: LinkKey, config: GateConfig) -> Self {
        Self {
            key,
            config,
            senders: ReplayGuard::new(),
            counters: LinkCounters::default(),
            last_accepted_ns: None,
        }
    }

    pub fn counters(&self) -> &LinkCounters {
        &self.counters
    }

    /// For the telemetry sender's counters.
    pub fn counters_mut(&mut self) -> &mut LinkCounters {
        &mut self.counters
    }

    /// When (vehicle clock) the last command was accepted: how long the ground has been
    /// silent, for a lost-link policy.
    pub fn last_accepted_ns(&self) -> Option<u64> {
        self.last_accepted_ns
    }

    pub fn replay_guard(&self) -> &ReplayGuard {
        &self.senders
    }

    /// Checks one received datagram, in order: CRC, framing, direction, vehicle id,
    /// signature, run id, replay, payload, ranges (and for parameter commands, the table). Counts
    /// the outcome either way.
    pub fn accept(
        &mut self,
        datagram: &[u8],
        now_ns: u64,
        params: &ParamTable,
    ) -> Result<AcceptedCommand, Rejected> {
        self.counters.received = self.counters.received.saturating_add(1);
        let result = self.check(datagram, params);
        match &result {
            Ok(_) => {
                self.counters.accepted = self.counters.accepted.saturating_add(1);
                self.last_accepted_ns = Some(now_ns);
            }
            Err(rejected) => self.counters.count(rejected.reason),
        }
        result
    }

    fn check(&mut self, datagram: &[u8], params: &ParamTable) -> Result<AcceptedCommand, Rejected> {
        let drop = |reason| Rejected { reason, ack: None };
        let frame = screen_command(datagram, &self.key, self.config.vehicle_id).map_err(drop)?;
        let header = frame.header;
        let envelope = header.envelope;
        if envelope.run_id != self.config.run_id {
            return Err(drop(RejectReason::WrongRun));
        }
        // Authentic and meant for this run from here on: the sequence number is spent even if the payload turns
        // out unusable, so the same datagram replayed counts as a replay.
        self.senders
            .accept(envelope.sender_id, envelope.sequence)
            .map_err(|e| {
                drop(match e {
                    GuardError::Replay(_) => RejectReason::Replayed,
                    GuardError::TooManySenders => RejectReason::TooManySenders,
                })
            })?;
        let command = Command::decode_payload(header.message_type, frame.payload)
            .map_err(|_| drop(RejectReason::Malformed))?;
        let accepted = AcceptedCommand {
            sender_id: envelope.sender_id,
            sequence: envelope.sequence,
            sent_t_ns: envelope.t_ns,
            command,
        };
        let refuse = |reason, result, value_in_force| Rejected {
            reason,
            ack: Some(accepted.ack(result, value_in_force)),
        };
        if !command.arguments_in_range(self.config.task_count) {
            return Err(refuse(
                RejectReason::OutOfRange,
                AckResult::OutOfRange,
                None,
            ));
        }
        let param_check = match &command {
            Command::SetParam { name, value } => Some(params.check(name, value)),
            Command::GetParam { name } => params
                .index_of(name)
                .is_none()
                .then_some(SetParamResult::Unknown),
            _ => None,
        };
        match param_check {
            Some(SetParamResult::Unknown) => Err(refuse(
                RejectReason::UnknownParam,
                AckResult::UnknownParam,
                None,
            )),
            Some(SetParamResult::WrongType { in_force }) => Err(refuse(
                RejectReason::WrongType,
                AckResult::WrongType,
                Some(in_force),
            )),
            Some(SetParamResult::OutOfRange { in_force }) => Err(refuse(
                RejectReason::OutOfRange,
                AckResult::OutOfRange,
                Some(in_force),
            )),
            Some(SetParamResult::Accepted { .. }) | None => Ok(accepted),
        }
    }
}

//! The command gate every command datagram passes before the vehicle acts on it: the checks
//! that need no state (shared with the shell's socket thread), then the run id, the
//! per-sender replay windows, the payload and the ranges. Counts every outcome.

use super::key::LinkKey;
use crate::link::counters::LinkCounters;
use crate::link::frame::{self, FrameError};
use crate::link::messages::{AckResult, Command, CommandAck, Message, Value, message_type};
use crate::link::params::{ParamTable, SetParamResult};

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
    frame
        .verify(frame::Verify::Required(key))
        .map_err(|e| match e {
            FrameError::Unsigned => RejectReason::Unsigned,
            _ => RejectReason::BadSignature,
        })?;
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
        let Ok(Message::Command(command)) = frame.message() else {
            return Err(drop(RejectReason::Malformed));
        };
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

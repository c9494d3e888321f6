//! The ground's end of the link: one UDP socket that receives the vehicles' telemetry and
//! sends them signed commands, answering to the address their telemetry comes from (the
//! vehicle receives commands on the socket it sends from).

use crate::key::SequenceStore;
use crate::model::{GroundModel, Refused};
use skyframe_core::link::auth::LinkKey;
use skyframe_core::link::frame::{
    Envelope, FrameError, Header, MAX_DATAGRAM_LEN, Verify, decode_datagram, encode_datagram,
};
use skyframe_core::link::messages::{AckResult, Command, CommandAck, Message, Telemetry};
use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// How long to wait for an acknowledgement before sending the command again (with a new
/// sequence number, as the protocol asks).
pub const RESEND_AFTER: Duration = Duration::from_secs(1);
/// After the first vehicle is heard, how long to keep listening for others before
/// deciding which one a command is for: every vehicle sends a TaskStatus each second.
pub const DISCOVERY_GRACE: Duration = Duration::from_millis(1200);

/// The receive buffer asked for (the kernel doubles it for its bookkeeping).
pub const RECEIVE_BUFFER_BYTES: usize = 1 << 20;

/// What one datagram turned out to be.
// One at a time, gone once applied to the model: boxing the telemetry would only add an
// allocation per datagram.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Incoming {
    Telemetry {
        header: Header,
        telemetry: Telemetry,
    },
    /// A command heard on the ground's port (another ground station on a broadcast
    /// address): not ours to act on.
    Command {
        header: Header,
    },
    Refused(FrameError),
}

#[derive(Clone, Debug, PartialEq)]
pub struct Received {
    pub from: SocketAddr,
    pub incoming: Incoming,
}

/// Decodes one datagram; with a key, a signed datagram must verify (unsigned ones are
/// accepted: telemetry signing is the vehicle's option). Never panics, whatever the bytes.
pub fn decode(datagram: &[u8], key: Option<&LinkKey>) -> Incoming {
    let verify = match key {
        Some(key) => Verify::IfSigned(key),
        None => Verify::No,
    };
    match decode_datagram(datagram, verify) {
        Ok((header, Message::Telemetry(telemetry))) => Incoming::Telemetry { header, telemetry },
        Ok((header, Message::Command(_))) => Incoming::Command { header },
        Err(error) => Incoming::Refused(error),
    }
}

/// Applies a received datagram to the model.
pub fn apply(model: &mut GroundModel, received: &Received, now: Instant) {
    match &received.incoming {
        Incoming::Telemetry { header, telemetry } => {
            model.apply(header, telemetry, received.from, now);
        }
        Incoming::Command { .. } => {
            model.ignored_commands = model.ignored_commands.saturating_add(1);
        }
        Incoming::Refused(error) => model.refuse(Refused {
            from: received.from,
            error: *error,
        }),
    }
}

/// The socket and the key it decodes with.
#[derive(Debug)]
pub struct GroundLink {
    socket: UdpSocket,
    key: Option<LinkKey>,
    wait: Option<Duration>,
    buffer: Vec<u8>,
}

impl GroundLink {
    pub fn bind(address: SocketAddr, key: Option<LinkKey>) -> Result<Self, String> {
        let socket = UdpSocket::bind(address).map_err(|e| {
            let hint = if e.kind() == io::ErrorKind::AddrInUse {
                " (another skyframe-ground listening? pass --listen)"
            } else {
                ""
            };
            format!("cannot listen on {address}: {e}{hint}")
        })?;
        // Every vehicle sends its formats, statuses and data in one burst when it starts, and
        // the UI's receive thread may be descheduled for a while: the default buffer
        // (~200 kB, a few hundred datagrams with their overhead) overflows with 20
        // vehicles. The kernel caps the request at net.core.rmem_max; a smaller buffer
        // still works, so failure is not an error.
        let _ = nix::sys::socket::setsockopt(
            &socket,
            nix::sys::socket::sockopt::RcvBuf,
            &RECEIVE_BUFFER_BYTES,
        );
        Ok(Self {
            socket,
            key,
            wait: None,
            buffer: vec![0; MAX_DATAGRAM_LEN + 1],
        })
    }

    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// Another handle on the same socket (a receive thread's, while this one sends).
    pub fn try_clone(&self) -> io::Result<Self> {
        Ok(Self {
            socket: self.socket.try_clone()?,
            key: self.key.clone(),
            wait: None,
            buffer: vec![0; MAX_DATAGRAM_LEN + 1],
        })
    }

    pub fn key(&self) -> Option<&LinkKey> {
        self.key.as_ref()
    }

    /// One datagram, waiting at most `wait` (zero: only what is already there).
    pub fn receive(&mut self, wait: Duration) -> io::Result<Option<Received>> {
        // A read timeout of zero means "block forever" to the socket; 1 µs is "don't wait".
        let wait = wait.max(Duration::from_micros(1));
        if self.wait != Some(wait) {
            self.socket.set_read_timeout(Some(wait))?;
            self.wait = Some(wait);
        }
        match self.socket.recv_from(&mut self.buffer) {
            Ok((len, from)) => {
                let datagram = self.buffer.get(..len).unwrap_or(&[]);
                Ok(Some(Received {
                    from,
                    incoming: decode(datagram, self.key.as_ref()),
                }))
            }
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                Ok(None)
            }
            // A previous send to a vehicle that has gone answers with ICMP "port
            // unreachable", reported on the next receive: link loss, which is normal.
            Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Signs and sends a command to the vehicle at `target`; returns its sequence number.
    pub fn send_command(
        &self,
        target: &CommandTarget,
        sender: &mut CommandSender,
        command: &Command,
    ) -> Result<u32, String> {
        let sequence = sender.sequences.take_next()?;
        let envelope = Envelope {
            vehicle_id: target.vehicle_id,
            sender_id: sender.sender_id,
            run_id: target.run_id,
            sequence,
            t_ns: wall_clock_ns(),
        };
        let mut datagram = [0u8; MAX_DATAGRAM_LEN];
        let message = Message::Command(*command);
        let len = encode_datagram(&envelope, &message, Some(&sender.key), &mut datagram)
            .map_err(|e| format!("cannot encode {command:?}: {e:?}"))?;
        let bytes = datagram.get(..len).unwrap_or(&[]);
        self.socket
            .send_to(bytes, target.address)
            .map_err(|e| format!("cannot send to {}: {e}", target.address))?;
        Ok(sequence)
    }
}

fn wall_clock_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
        .unwrap_or(0)
}

/// Where and under which run a command goes: from the vehicle's latest telemetry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommandTarget {
    pub vehicle_id: u16,
    pub run_id: u32,
    pub address: SocketAddr,
}

/// What signing commands needs: the key, this station's sender id, its sequence numbers.
#[derive(Debug)]
pub struct CommandSender {
    pub key: LinkKey,
    pub sender_id: u8,
    pub sequences: SequenceStore,
}

/// How a command ended, short of success.
#[derive(Clone, Debug, PartialEq)]
pub enum CommandError {
    /// The vehicle answered, with something other than "accepted".
    Nacked(CommandAck),
    /// No answer in time (or no vehicle heard).
    TimedOut(String),
    /// Could not even try (no key, several vehicles, socket error): exit 2.
    Unusable(String),
}

/// A link, the model it feeds, and (with a key) the means to command.
#[derive(Debug)]
pub struct Session {
    pub link: GroundLink,
    pub model: GroundModel,
    pub sender: Option<CommandSender>,
}

impl Session {
    pub fn new(link: GroundLink, sender: Option<CommandSender>) -> Self {
        let model = GroundModel {
            verifies_signatures: link.key().is_some(),
            ..GroundModel::default()
        };
        Self {
            link,
            model,
            sender,
        }
    }

    /// Receives one datagram (waiting at most `wait`) and applies it to the model.
    pub fn pump(&mut self, wait: Duration) -> Result<Option<Received>, String> {
        let received = self
            .link
            .receive(wait)
            .map_err(|e| format!("receive failed: {e}"))?;
        if let Some(received) = &received {
            apply(&mut self.model, received, Instant::now());
        }
        Ok(received)
    }

    /// Listens until `deadline` or until `done` says so.
    pub fn pump_until(
        &mut self,
        deadline: Instant,
        mut done: impl FnMut(&GroundModel) -> bool,
    ) -> Result<bool, String> {
        loop {
            if done(&self.model) {
                return Ok(true);
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(false);
            }
            self.pump((deadline - now).min(Duration::from_millis(100)))?;
        }
    }

    /// The vehicle a command is for: `wanted` once heard, or the only one heard. Listens
    /// until `deadline` for the first telemetry, then a little longer for others.
    pub fn choose_vehicle(
        &mut self,
        wanted: Option<u16>,
        deadline: Instant,
    ) -> Result<u16, CommandError> {
        let heard = self
            .pump_until(deadline, |m| match wanted {
                Some(id) => m.vehicle(id).is_some(),
                None => !m.vehicles.is_empty(),
            })
            .map_err(CommandError::Unusable)?;
        if !heard {
            return Err(CommandError::TimedOut(match wanted {
                Some(id) => format!("vehicle {id} not heard"),
                None => "no vehicle heard".to_string(),
            }));
        }
        if let Some(id) = wanted {
            return Ok(id);
        }
        let grace = (Instant::now() + DISCOVERY_GRACE).min(deadline);
        self.pump_until(grace, |_| false)
            .map_err(CommandError::Unusable)?;
        match self.model.vehicle_ids().as_slice() {
            [only] => Ok(*only),
            ids => Err(CommandError::Unusable(format!(
                "several vehicles heard ({}): pass --vehicle ID",
                ids.iter()
                    .map(u16::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            ))),
        }
    }

    /// Sends `command` to vehicle `vehicle_id` and waits for its acknowledgement, sending
    /// it again (new sequence number) every [`RESEND_AFTER`] until `deadline`.
    pub fn command(
        &mut self,
        vehicle_id: u16,
        command: &Command,
        deadline: Instant,
    ) -> Result<CommandAck, CommandError> {
        let mut sent: Vec<u32> = Vec::new();
        loop {
            let target = self.target(vehicle_id)?;
            let sender = self.sender.as_mut().ok_or_else(no_key)?;
            let sender_id = sender.sender_id;
            let sequence = self
                .link
                .send_command(&target, sender, command)
                .map_err(CommandError::Unusable)?;
            sent.push(sequence);
            let resend_at = (Instant::now() + RESEND_AFTER).min(deadline);
            let answered = |m: &GroundModel| {
                m.vehicle(vehicle_id).and_then(|v| {
                    sent.iter()
                        .rev()
                        .find_map(|&s| v.ack_for(sender_id, s).copied())
                })
            };
            self.pump_until(resend_at, |m| answered(m).is_some())
                .map_err(CommandError::Unusable)?;
            if let Some(ack) = answered(&self.model) {
                return if ack.result == AckResult::Accepted {
                    Ok(ack)
                } else {
                    Err(CommandError::Nacked(ack))
                };
            }
            if Instant::now() >= deadline {
                return Err(CommandError::TimedOut(format!(
                    "no acknowledgement from vehicle {vehicle_id} ({} tries)",
                    sent.len()
                )));
            }
        }
    }

    pub fn target(&self, vehicle_id: u16) -> Result<CommandTarget, CommandError> {
        let vehicle = self
            .model
            .vehicle(vehicle_id)
            .ok_or_else(|| CommandError::TimedOut(format!("vehicle {vehicle_id} not heard")))?;
        Ok(CommandTarget {
            vehicle_id,
            run_id: vehicle.run_id,
            address: vehicle.address,
        })
    }
}

fn no_key() -> CommandError {
    CommandError::Unusable(
        "no link key: pass --key FILE or set SKYFRAME_KEY (commands must be signed)".to_string(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn garbage_is_refused_not_panicked_on() {
        let key = LinkKey::new([1; 32]);
        for len in [0usize, 1, 31, 32, 100, 1472, 2000] {
            let bytes: Vec<u8> = (0..len).map(|i| (i * 7 + 3) as u8).collect();
            assert!(matches!(decode(&bytes, None), Incoming::Refused(_)));
            assert!(matches!(decode(&bytes, Some(&key)), Incoming::Refused(_)));
        }
    }

    #[test]
    fn telemetry_signed_with_another_key_is_refused_with_ours_and_shown_without() {
        let mut buffer = [0u8; MAX_DATAGRAM_LEN];
        let envelope = Envelope {
            vehicle_id: 4,
            ..Envelope::default()
        };
        let message = Message::Telemetry(Telemetry::ExecutiveStatus(Default::default()));
        let theirs = LinkKey::new([2; 32]);
        let len = encode_datagram(&envelope, &message, Some(&theirs), &mut buffer).expect("fits");
        let datagram = &buffer[..len];
        let ours = LinkKey::new([3; 32]);
        assert_eq!(
            decode(datagram, Some(&ours)),
            Incoming::Refused(FrameError::BadSignature)
        );
        assert!(matches!(decode(datagram, None), Incoming::Telemetry { .. }));
        assert!(matches!(
            decode(datagram, Some(&theirs)),
            Incoming::Telemetry { .. }
        ));
    }
}

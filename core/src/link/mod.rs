//! The link between vehicle and ground: UDP datagrams with an explicit little-endian
//! encoding, a CRC on every datagram, and HMAC-SHA256 authenticated commands.
//! `docs/link-protocol.md` is the specification; this module is its core-side
//! implementation (encoding, decoding, authentication, replay protection, parameters).
//! Sockets are the shell's.
//!
//! - [`wire`]: bounded little-endian writer and reader;
//! - [`frame`]: header, CRC-32, signing and the datagram as a whole;
//! - [`messages`]: the typed messages in both directions;
//! - [`senders`]: the sender ids of skyframe's own command senders;
//! - [`params`]: the table of parameters the ground can read and set;
//! - [`counters`]: what the link received, accepted, refused (and why) and sent;
//! - [`auth`]: the key and its tags ([`auth::key`]), and the [`CommandGate`] with its replay
//!   windows ([`auth::gate`]);
//! - [`ingress`]: what the shell drops before queueing (screened out, rate limited);
//! - [`telemetry`]: when the vehicle sends what, and its datagrams' envelopes.

pub mod auth;
pub mod counters;
pub mod frame;
pub mod ingress;
pub mod messages;
pub mod params;
pub mod senders;
pub mod telemetry;
pub mod wire;

pub use auth::{
    AcceptedCommand, CommandGate, GateConfig, LinkKey, RejectReason, Rejected, ReplayWindow,
};
pub use counters::LinkCounters;
pub use frame::{
    Envelope, FrameError, Header, MAX_DATAGRAM_LEN, Verify, decode_datagram, encode_datagram,
};
pub use messages::{Command, Message, Telemetry, Value};
pub use params::{ParamTable, SetParamResult};
pub use telemetry::{Due, TelemetrySchedule, VehicleEnvelopes};

#[cfg(test)]
mod tests;

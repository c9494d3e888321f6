//! Command authentication, in two parts: the key ([`key`]: the pre-shared secret and its
//! HMAC-SHA256 tags) and the command gate ([`gate`]: what a datagram must pass, in order,
//! before the vehicle acts on it, with the per-sender replay windows).

pub mod gate;
pub mod key;

pub use gate::{
    AcceptedCommand, CommandGate, GateConfig, GuardError, MAX_SENDERS, REPLAY_WINDOW, RejectReason,
    Rejected, ReplayError, ReplayGuard, ReplayWindow, screen_command,
};
pub use key::{KEY_LEN, LinkKey, sign, verify};

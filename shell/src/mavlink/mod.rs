//! The MAVLink 2 endpoint (`--mavlink`, `docs/mavlink.md`): QGroundControl, MAVProxy and
//! pymavlink see the vehicle, read and set its parameters, read its mission, command it.
//!
//! It runs on its own shell thread ([`bridge`]), beside the skyframe link and built on it:
//! - **Out**: the link thread hands over every telemetry datagram the vehicle sends (the
//!   same datagrams the skyframe ground receives); [`view::VehicleView`] keeps the latest
//!   values by task and column, and [`encode`] turns them into MAVLink messages. No task
//!   knows MAVLink exists: nothing is added to a task's step.
//! - **In**: MAVLink requests that change anything become skyframe link commands (signed
//!   with the link's key, sender id [`LINK_SENDER_ID`]) queued to the vehicle through the
//!   link thread, so they pass the same gate and range checks as the skyframe ground's, and
//!   the vehicle's acknowledgement is what MAVLink is told.
//!
//! With `--no-link` the link thread still runs, without a socket, to carry exactly this.

pub mod bridge;
pub mod encode;
pub mod ingress;
pub mod mission;
pub mod params;
pub mod view;

pub use mavlink::dialects::common as mav;

use std::net::{SocketAddr, ToSocketAddrs};

/// A MAVLink signing secret; its `Debug` does not show it.
#[derive(Clone, Copy)]
pub struct Secret(pub [u8; 32]);

impl std::fmt::Debug for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Secret(..)")
    }
}

/// The skyframe link sender id the MAVLink endpoint's commands carry (ground stations pick
/// from 1..=255; this one is documented so that nobody else uses it).
pub const LINK_SENDER_ID: u8 = skyframe_core::link::senders::MAVLINK_ENDPOINT;

/// Where MAVLink goes: the endpoint syntax of MAVProxy and ArduPilot's SITL.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Endpoint {
    /// `udpout:HOST:PORT`: send to a ground station that listens (QGC on 14550); answer
    /// whoever talks back.
    UdpOut(SocketAddr),
    /// `udpin:ADDR:PORT`: listen; send to whoever talks.
    UdpIn(SocketAddr),
}

/// Parses `udpout:HOST:PORT` or `udpin:ADDR:PORT` (clap's value parser: one line on error).
pub fn parse_endpoint(text: &str) -> Result<Endpoint, String> {
    let (kind, rest) = text
        .split_once(':')
        .ok_or_else(|| format!("{text:?}: expected udpout:HOST:PORT or udpin:ADDR:PORT"))?;
    let addr = rest
        .to_socket_addrs()
        .map_err(|e| format!("{rest:?}: {e}"))?
        .next()
        .ok_or_else(|| format!("{rest:?}: no address"))?;
    match kind {
        "udpout" | "udp-out" if addr.port() != 0 => Ok(Endpoint::UdpOut(addr)),
        "udpout" | "udp-out" => Err(format!("{text:?}: udpout needs a port other than 0")),
        "udpin" | "udp-in" | "udp" => Ok(Endpoint::UdpIn(addr)),
        _ => Err(format!(
            "{text:?}: unknown kind {kind:?} (udpout:HOST:PORT or udpin:ADDR:PORT)"
        )),
    }
}

/// What `--mavlink*` asked for.
#[derive(Clone, Debug)]
pub struct MavlinkPlan {
    pub endpoints: Vec<Endpoint>,
    /// MAVLink system id (component 1, the autopilot).
    pub system_id: u8,
    /// The signing secret (`--mavlink-key`), read before the flight starts.
    pub key: Option<Secret>,
    /// The run's stop flag: MAVLink's shutdown command sets it directly, so a stop ends the
    /// run even while a task is stuck (the stop guard of `host.rs` does the rest).
    pub stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

/// The link thread's side of the MAVLink endpoint.
pub struct LinkHook {
    /// Each telemetry datagram the vehicle sends (a full queue drops it, counted).
    pub telemetry: std::sync::mpsc::SyncSender<Vec<u8>>,
    /// Link commands to queue to the vehicle.
    pub commands: std::sync::mpsc::Receiver<Vec<u8>>,
    pub counters: std::sync::Arc<ingress::Counters>,
}

impl LinkHook {
    /// Hands a telemetry datagram over without blocking the link thread.
    pub fn offer(&self, datagram: &[u8]) {
        if self.telemetry.try_send(datagram.to_vec()).is_err() {
            self.counters
                .telemetry_dropped
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    }
}

/// The MAVLink thread's side.
pub struct BridgeEnds {
    pub telemetry: std::sync::mpsc::Receiver<Vec<u8>>,
    pub commands: std::sync::mpsc::SyncSender<Vec<u8>>,
    pub counters: std::sync::Arc<ingress::Counters>,
}

/// Telemetry datagrams queued for the MAVLink thread: seconds of the link's output.
const TELEMETRY_QUEUE: usize = 4096;
const COMMAND_QUEUE: usize = 256;

/// The two ends that join the link thread and the MAVLink thread.
pub fn hook_pair() -> (LinkHook, BridgeEnds) {
    let (ttx, trx) = std::sync::mpsc::sync_channel(TELEMETRY_QUEUE);
    let (ctx, crx) = std::sync::mpsc::sync_channel(COMMAND_QUEUE);
    let counters = std::sync::Arc::new(ingress::Counters::default());
    (
        LinkHook {
            telemetry: ttx,
            commands: crx,
            counters: std::sync::Arc::clone(&counters),
        },
        BridgeEnds {
            telemetry: trx,
            commands: ctx,
            counters,
        },
    )
}

/// A link key that never leaves this process: `--no-link` with `--mavlink` still needs one
/// to sign the commands MAVLink hands the vehicle.
pub fn memory_key() -> Result<skyframe_core::link::auth::LinkKey, String> {
    use std::io::Read;
    let mut bytes = [0u8; 32];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut bytes))
        .map_err(|e| format!("no randomness from /dev/urandom: {e}"))?;
    Ok(skyframe_core::link::auth::LinkKey::new(bytes))
}

/// The MAVLink signing secret: the same file rules as `--key` (32 bytes, hex or raw, mode
/// 600).
pub fn load_key(path: &std::path::Path) -> Result<[u8; 32], String> {
    skyframe_input_files::read_key_bytes(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_parse_as_the_field_writes_them() {
        assert_eq!(
            parse_endpoint("udpout:127.0.0.1:14550"),
            Ok(Endpoint::UdpOut("127.0.0.1:14550".parse().expect("addr")))
        );
        assert_eq!(
            parse_endpoint("udpin:0.0.0.0:14551"),
            Ok(Endpoint::UdpIn("0.0.0.0:14551".parse().expect("addr")))
        );
        assert!(parse_endpoint("tcp:1.2.3.4:5760").is_err());
        assert!(parse_endpoint("udpout:127.0.0.1:0").is_err());
        assert!(parse_endpoint("udpout:127.0.0.1").is_err());
        assert!(parse_endpoint("nonsense").is_err());
    }
}

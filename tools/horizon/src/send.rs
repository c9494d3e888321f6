//! `detect --send`: each detected horizon goes to the vehicle as a signed HorizonAttitude
//! command (docs/link-protocol.md, message 0x87), over UDP.
//!
//! The protocol makes a command carry the vehicle's current run id and a capture time on the
//! vehicle's clock, so the sender first listens for one telemetry datagram (`--listen`): its
//! header gives the vehicle id, the run id and the vehicle's clock at that moment. A later
//! telemetry datagram with another run id (the vehicle restarted) restarts the sequence.
//! Without a vehicle to listen to, `--run-id` and `--vehicle-id` say them directly (the
//! capture times are then this process's clock, which the vehicle cannot align).

use crate::Error;
use skyframe_core::horizon::Horizon;
use skyframe_core::horizon::HorizonAttitude;
use skyframe_core::link::frame::{
    Envelope, MAX_DATAGRAM_LEN, Verify, decode_datagram, encode_datagram,
};
use skyframe_core::link::{Command, LinkKey, Message};
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(clap::Args, Debug, Clone)]
pub struct SendArgs {
    /// Send each result to the vehicle's command address (HOST:PORT) as a signed
    /// HorizonAttitude command. Frames without a horizon send nothing.
    #[arg(long, value_name = "ADDR", requires = "key")]
    pub send: Option<String>,
    /// The link's pre-shared key: a file holding 64 hex digits.
    #[arg(long, value_name = "FILE")]
    pub key: Option<PathBuf>,
    /// Where the vehicle's telemetry arrives (e.g. 0.0.0.0:14560): the first datagram
    /// gives the vehicle id, run id and clock. Needed unless --run-id and --vehicle-id are.
    #[arg(long, value_name = "ADDR")]
    pub listen: Option<String>,
    /// How long to wait for that first telemetry datagram.
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS")]
    pub wait: f64,
    /// This sender's id in commands (1..=255); not `skyframe-ground`'s, so both can command
    /// the same vehicle at once (`core/src/link/senders.rs`).
    #[arg(long, default_value_t = skyframe_core::link::senders::HORIZON_DETECTOR, value_parser = clap::value_parser!(u8).range(1..))]
    pub sender_id: u8,
    /// The vehicle's run id, instead of learning it from telemetry.
    #[arg(long, requires = "vehicle_id")]
    pub run_id: Option<u32>,
    /// The vehicle id, instead of learning it from telemetry.
    #[arg(long, requires = "run_id")]
    pub vehicle_id: Option<u16>,
}

/// What the vehicle's telemetry told us.
#[derive(Clone, Copy, Debug)]
struct VehicleState {
    vehicle_id: u16,
    run_id: u32,
    /// Vehicle clock minus ours (ns), at the last telemetry datagram.
    clock_offset_ns: i128,
}

pub struct Sender {
    socket: UdpSocket,
    target: SocketAddr,
    key: LinkKey,
    sender_id: u8,
    vehicle: VehicleState,
    listening: bool,
    sequence: u32,
    epoch: Instant,
    pub sent: u64,
}

fn read_key(path: &Path) -> Result<LinkKey, Error> {
    // The vehicle's and the ground's key reader: bounded, and a key others can read refused.
    skyframe_input_files::read_key_file(path).map_err(Error::input)
}

fn resolve(addr: &str) -> Result<SocketAddr, Error> {
    addr.to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| Error::input(format!("--send {addr}: not a HOST:PORT address")))
}

impl Sender {
    /// `None` without `--send`.
    pub fn open(args: &SendArgs) -> Result<Option<Sender>, Error> {
        let Some(target) = &args.send else {
            return Ok(None);
        };
        let key_path = args
            .key
            .as_ref()
            .ok_or_else(|| Error::input("--send needs --key FILE"))?;
        let key = read_key(key_path)?;
        let target = resolve(target)?;
        let epoch = Instant::now();
        let (socket, vehicle, listening) = match (args.run_id, args.vehicle_id, &args.listen) {
            (Some(run_id), Some(vehicle_id), listen) => {
                let bind = listen.as_deref().unwrap_or(if target.is_ipv4() {
                    "0.0.0.0:0"
                } else {
                    "[::]:0"
                });
                let socket = UdpSocket::bind(bind)
                    .map_err(|e| Error::input(format!("--listen {bind}: {e}")))?;
                (
                    socket,
                    VehicleState {
                        vehicle_id,
                        run_id,
                        clock_offset_ns: 0,
                    },
                    listen.is_some(),
                )
            }
            (_, _, Some(listen)) => {
                let socket = UdpSocket::bind(listen)
                    .map_err(|e| Error::input(format!("--listen {listen}: {e}")))?;
                let vehicle = wait_for_telemetry(&socket, &key, epoch, args.wait, listen)?;
                (socket, vehicle, true)
            }
            _ => {
                return Err(Error::input(
                    "--send needs --listen ADDR (the vehicle's telemetry gives its run id) or --run-id and --vehicle-id",
                ));
            }
        };
        socket
            .set_nonblocking(true)
            .map_err(|e| Error::failure(format!("UDP socket: {e}")))?;
        Ok(Some(Sender {
            socket,
            target,
            key,
            sender_id: args.sender_id,
            vehicle,
            listening,
            sequence: 0,
            epoch,
            sent: 0,
        }))
    }

    fn local_ns(&self, at: Instant) -> i128 {
        at.saturating_duration_since(self.epoch).as_nanos() as i128
    }

    fn vehicle_ns(&self, at: Instant) -> u64 {
        (self.local_ns(at) + self.vehicle.clock_offset_ns).clamp(0, u64::MAX as i128) as u64
    }

    /// Reads any telemetry that arrived since the last frame: a new run id restarts the
    /// sequence numbers, and the clock offset follows the vehicle's clock.
    fn drain_telemetry(&mut self) {
        if !self.listening {
            return;
        }
        let mut buffer = [0u8; MAX_DATAGRAM_LEN];
        while let Ok((n, _)) = self.socket.recv_from(&mut buffer) {
            let now = Instant::now();
            if let Some(state) = telemetry_state(
                buffer.get(..n).unwrap_or(&[]),
                &self.key,
                self.local_ns(now),
            ) {
                if state.run_id != self.vehicle.run_id {
                    self.sequence = 0;
                }
                self.vehicle = state;
            }
        }
    }

    /// Sends one result; `captured` is when the frame was read.
    pub fn send(&mut self, horizon: &Horizon, captured: Instant) -> Result<(), Error> {
        self.drain_telemetry();
        self.sequence = self.sequence.wrapping_add(1);
        let envelope = Envelope {
            vehicle_id: self.vehicle.vehicle_id,
            sender_id: self.sender_id,
            run_id: self.vehicle.run_id,
            sequence: self.sequence,
            t_ns: self.vehicle_ns(Instant::now()),
        };
        let command = Command::HorizonAttitude(HorizonAttitude {
            roll_rad: horizon.roll_rad,
            pitch_rad: horizon
                .pitch_rad
                .clamp(-std::f32::consts::FRAC_PI_2, std::f32::consts::FRAC_PI_2),
            confidence: horizon.confidence.clamp(0.0, 1.0),
            capture_t_ns: self.vehicle_ns(captured),
        });
        let mut datagram = [0u8; MAX_DATAGRAM_LEN];
        let len = encode_datagram(
            &envelope,
            &Message::Command(command),
            Some(&self.key),
            &mut datagram,
        )
        .map_err(|e| Error::failure(format!("encoding the horizon command: {e:?}")))?;
        match self
            .socket
            .send_to(datagram.get(..len).unwrap_or(&[]), self.target)
        {
            Ok(_) => {
                self.sent += 1;
                Ok(())
            }
            // A radio link loses datagrams; the next frame sends a fresh answer anyway.
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => Ok(()),
            Err(e) => Err(Error::failure(format!("--send {}: {e}", self.target))),
        }
    }
}

/// The vehicle's ids and clock from a telemetry datagram (signed ones must verify).
fn telemetry_state(datagram: &[u8], key: &LinkKey, local_ns: i128) -> Option<VehicleState> {
    let (header, message) = decode_datagram(datagram, Verify::IfSigned(key)).ok()?;
    if !matches!(message, Message::Telemetry(_)) || header.envelope.sender_id != 0 {
        return None;
    }
    Some(VehicleState {
        vehicle_id: header.envelope.vehicle_id,
        run_id: header.envelope.run_id,
        clock_offset_ns: header.envelope.t_ns as i128 - local_ns,
    })
}

fn wait_for_telemetry(
    socket: &UdpSocket,
    key: &LinkKey,
    epoch: Instant,
    wait_s: f64,
    listen: &str,
) -> Result<VehicleState, Error> {
    let deadline = Instant::now() + Duration::from_secs_f64(wait_s.clamp(0.01, 3600.0));
    let mut buffer = [0u8; MAX_DATAGRAM_LEN];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(Error::failure(format!(
                "--listen {listen}: no vehicle telemetry within {wait_s} s (or pass --run-id and --vehicle-id)"
            )));
        }
        socket
            .set_read_timeout(Some(left))
            .map_err(|e| Error::failure(format!("--listen {listen}: {e}")))?;
        if let Ok((n, _)) = socket.recv_from(&mut buffer) {
            let local = Instant::now().saturating_duration_since(epoch).as_nanos() as i128;
            if let Some(state) = telemetry_state(buffer.get(..n).unwrap_or(&[]), key, local) {
                return Ok(state);
            }
        }
    }
}

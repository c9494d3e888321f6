//! The servo board protocol (docs/protocols.md, "Servo board"): the board sends the pilot's
//! receiver channels, the auto/manual switch and two battery voltages at 50 Hz; the computer
//! sends eight servo commands back. Both directions have an encoder and a decoder: the flight
//! side uses [`ServoDecoder`] and [`encode_servo_command`], the simulator playing the board
//! uses [`ServoCommandDecoder`] and [`encode_pilot_frame`].
//!
//! Pulse widths in µs exist only here; the `*_to_pulse_us` / `pulse_us_to_*` functions are
//! the one place normalised commands (conventions.md) meet them.

use super::framing::{self, FrameAssembler, MAX_FRAME_LEN};
use super::imu::LeReader;
use super::{Decoder, DecoderStats, Staleness, bump};
use core::marker::PhantomData;

pub const PILOT_CHANNELS: usize = 8;
pub const SERVO_CHANNELS: usize = 8;

/// Frame type byte, board → computer (`'S'`).
pub const PILOT_FRAME_TYPE: u8 = 0x53;
pub const PILOT_PAYLOAD_LEN: usize = 23;
pub const PILOT_FRAME_LEN: usize = framing::HEADER_LEN + PILOT_PAYLOAD_LEN + framing::CRC_LEN;
/// Frame type byte, computer → board (`'C'`).
pub const COMMAND_FRAME_TYPE: u8 = 0x43;
pub const COMMAND_PAYLOAD_LEN: usize = 17;
pub const COMMAND_FRAME_LEN: usize = framing::HEADER_LEN + COMMAND_PAYLOAD_LEN + framing::CRC_LEN;

/// Centre and half-range of a surface channel; throttle runs over the whole range.
pub const PULSE_CENTRE_US: u16 = 1500;
pub const PULSE_HALF_RANGE_US: u16 = 500;
pub const PULSE_MIN_US: u16 = PULSE_CENTRE_US - PULSE_HALF_RANGE_US;
pub const PULSE_MAX_US: u16 = PULSE_CENTRE_US + PULSE_HALF_RANGE_US;
/// Widest pulse a hobby receiver or servo can plausibly mean; anything outside is corruption
/// the CRC happened to pass through the board (a failing receiver), not a command.
pub const PULSE_PLAUSIBLE_US: core::ops::RangeInclusive<u16> = 500..=2500;
/// The switch channel above this means "auto" (the usual two-position switch: 1000/2000 µs).
pub const AUTO_SWITCH_THRESHOLD_US: u16 = 1500;

/// Default staleness timeout: five missed board frames.
pub const DEFAULT_STALE_TIMEOUT_NS: u64 = 100_000_000;

/// Normalised surface command in [−1, 1] → pulse width; out-of-range values are clamped.
pub fn surface_to_pulse_us(command: f32) -> u16 {
    let clamped = if command.is_nan() {
        0.0
    } else {
        command.clamp(-1.0, 1.0)
    };
    let offset = libm::roundf(clamped * f32::from(PULSE_HALF_RANGE_US)) as i32;
    (i32::from(PULSE_CENTRE_US) + offset) as u16
}

/// Normalised throttle in [0, 1] → pulse width; out-of-range values are clamped.
pub fn throttle_to_pulse_us(throttle: f32) -> u16 {
    let clamped = if throttle.is_nan() {
        0.0
    } else {
        throttle.clamp(0.0, 1.0)
    };
    PULSE_MIN_US + libm::roundf(clamped * f32::from(PULSE_MAX_US - PULSE_MIN_US)) as u16
}

/// Pulse width → normalised surface command, clamped to [−1, 1].
pub fn pulse_us_to_surface(pulse_us: u16) -> f32 {
    let offset = f32::from(pulse_us) - f32::from(PULSE_CENTRE_US);
    (offset / f32::from(PULSE_HALF_RANGE_US)).clamp(-1.0, 1.0)
}

/// Pulse width → normalised throttle, clamped to [0, 1].
pub fn pulse_us_to_throttle(pulse_us: u16) -> f32 {
    let offset = f32::from(pulse_us) - f32::from(PULSE_MIN_US);
    (offset / f32::from(PULSE_MAX_US - PULSE_MIN_US)).clamp(0.0, 1.0)
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ControlMode {
    /// The board passes the pilot's channels to the servos.
    Manual,
    /// The pilot has handed control to the computer.
    Auto,
}

/// The board's status byte.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardStatus(pub u8);

impl BoardStatus {
    /// The receiver has lost the pilot's link and outputs failsafe values.
    pub const RECEIVER_FAILSAFE: u8 = 1 << 0;
    /// The servos are following the computer's commands right now.
    pub const COMPUTER_IN_CONTROL: u8 = 1 << 1;
    /// The switch says auto but no fresh command arrived, so the board fell back to the pilot.
    pub const COMMAND_TIMEOUT: u8 = 1 << 2;

    pub fn receiver_failsafe(self) -> bool {
        self.0 & Self::RECEIVER_FAILSAFE != 0
    }
    pub fn computer_in_control(self) -> bool {
        self.0 & Self::COMPUTER_IN_CONTROL != 0
    }
    pub fn command_timeout(self) -> bool {
        self.0 & Self::COMMAND_TIMEOUT != 0
    }
}

/// What the board reports every 20 ms.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PilotReport {
    /// The receiver's channels 1–8 as the pilot commands them. Which channel drives which
    /// surface is the airframe's configuration, not the protocol's.
    pub pilot_us: [u16; PILOT_CHANNELS],
    /// The auto/manual switch channel.
    pub switch_us: u16,
    /// Avionics (logic) battery.
    pub logic_battery_v: f32,
    /// Servo battery.
    pub servo_battery_v: f32,
    pub status: BoardStatus,
}

impl PilotReport {
    /// What the pilot's switch asks for (the board's [`BoardStatus`] says what it does).
    pub fn requested_mode(&self) -> ControlMode {
        if self.switch_us > AUTO_SWITCH_THRESHOLD_US {
            ControlMode::Auto
        } else {
            ControlMode::Manual
        }
    }
}

/// A decoded board frame.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PilotFrame {
    pub counter: u8,
    pub received_ns: u64,
    pub report: PilotReport,
}

/// One normalised channel command, converted to a pulse width at encoding.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ChannelCommand {
    /// Aileron, elevator, rudder… in [−1, 1].
    Surface(f32),
    /// In [0, 1].
    Throttle(f32),
}

impl ChannelCommand {
    pub fn to_pulse_us(self) -> u16 {
        match self {
            ChannelCommand::Surface(command) => surface_to_pulse_us(command),
            ChannelCommand::Throttle(throttle) => throttle_to_pulse_us(throttle),
        }
    }
}

/// What the computer sends the board.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ServoCommand {
    pub channels_us: [u16; SERVO_CHANNELS],
    /// The computer vouches for these commands; without it the board keeps the pilot in
    /// control whatever the switch says.
    pub autopilot_ready: bool,
}

impl ServoCommand {
    pub fn from_channels(
        channels: [ChannelCommand; SERVO_CHANNELS],
        autopilot_ready: bool,
    ) -> Self {
        Self {
            channels_us: channels.map(ChannelCommand::to_pulse_us),
            autopilot_ready,
        }
    }
}

/// A decoded command frame (the simulator's side).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ServoCommandFrame {
    pub counter: u8,
    pub received_ns: u64,
    pub command: ServoCommand,
}

const COMMAND_FLAG_AUTOPILOT_READY: u8 = 1 << 0;

fn volts_to_mv(volts: f32) -> u16 {
    libm::roundf(volts * 1000.0) as u16
}

/// Writes a board → computer frame; returns [`PILOT_FRAME_LEN`].
pub fn encode_pilot_frame(
    counter: u8,
    report: &PilotReport,
    out: &mut [u8; PILOT_FRAME_LEN],
) -> usize {
    let mut payload = [0u8; PILOT_PAYLOAD_LEN];
    let words = report
        .pilot_us
        .iter()
        .copied()
        .chain([
            report.switch_us,
            volts_to_mv(report.logic_battery_v),
            volts_to_mv(report.servo_battery_v),
        ])
        .flat_map(u16::to_le_bytes)
        .chain([report.status.0]);
    for (slot, byte) in payload.iter_mut().zip(words) {
        *slot = byte;
    }
    framing::encode_frame(PILOT_FRAME_TYPE, counter, &payload, out).unwrap_or(0)
}

/// Writes a computer → board frame; returns [`COMMAND_FRAME_LEN`].
pub fn encode_servo_command(
    counter: u8,
    command: &ServoCommand,
    out: &mut [u8; COMMAND_FRAME_LEN],
) -> usize {
    let mut payload = [0u8; COMMAND_PAYLOAD_LEN];
    let flags = if command.autopilot_ready {
        COMMAND_FLAG_AUTOPILOT_READY
    } else {
        0
    };
    let bytes = command
        .channels_us
        .iter()
        .copied()
        .flat_map(u16::to_le_bytes)
        .chain([flags]);
    for (slot, byte) in payload.iter_mut().zip(bytes) {
        *slot = byte;
    }
    framing::encode_frame(COMMAND_FRAME_TYPE, counter, &payload, out).unwrap_or(0)
}

fn pulse_plausible(pulse_us: u16) -> bool {
    PULSE_PLAUSIBLE_US.contains(&pulse_us)
}

/// One binary stream's payload: its frame type, length and meaning.
pub trait PayloadCodec {
    const FRAME_TYPE: u8;
    const PAYLOAD_LEN: u8;
    type Frame;
    /// `None` when the payload makes no sense (counted as `invalid_payload`).
    fn decode(counter: u8, payload: &[u8], received_ns: u64) -> Option<Self::Frame>;
}

/// Board → computer frames.
#[derive(Clone, Copy, Debug)]
pub struct PilotCodec;

impl PayloadCodec for PilotCodec {
    const FRAME_TYPE: u8 = PILOT_FRAME_TYPE;
    const PAYLOAD_LEN: u8 = PILOT_PAYLOAD_LEN as u8;
    type Frame = PilotFrame;

    fn decode(counter: u8, payload: &[u8], received_ns: u64) -> Option<PilotFrame> {
        if payload.len() != PILOT_PAYLOAD_LEN {
            return None;
        }
        let mut reader = LeReader(payload);
        let pilot_us = [(); PILOT_CHANNELS].map(|_| reader.u16());
        let switch_us = reader.u16();
        let logic_battery_v = f32::from(reader.u16()) * 1e-3;
        let servo_battery_v = f32::from(reader.u16()) * 1e-3;
        let status = BoardStatus(reader.u8());
        let plausible =
            pilot_us.iter().all(|&us| pulse_plausible(us)) && pulse_plausible(switch_us);
        // A receiver in failsafe may report anything; the flag already tells the consumer.
        if !plausible && !status.receiver_failsafe() {
            return None;
        }
        Some(PilotFrame {
            counter,
            received_ns,
            report: PilotReport {
                pilot_us,
                switch_us,
                logic_battery_v,
                servo_battery_v,
                status,
            },
        })
    }
}

/// Computer → board frames.
#[derive(Clone, Copy, Debug)]
pub struct CommandCodec;

impl PayloadCodec for CommandCodec {
    const FRAME_TYPE: u8 = COMMAND_FRAME_TYPE;
    const PAYLOAD_LEN: u8 = COMMAND_PAYLOAD_LEN as u8;
    type Frame = ServoCommandFrame;

    fn decode(counter: u8, payload: &[u8], received_ns: u64) -> Option<ServoCommandFrame> {
        if payload.len() != COMMAND_PAYLOAD_LEN {
            return None;
        }
        let mut reader = LeReader(payload);
        let channels_us = [(); SERVO_CHANNELS].map(|_| reader.u16());
        let flags = reader.u8();
        if !channels_us.iter().all(|&us| pulse_plausible(us))
            || flags & !COMMAND_FLAG_AUTOPILOT_READY != 0
        {
            return None;
        }
        Some(ServoCommandFrame {
            counter,
            received_ns,
            command: ServoCommand {
                channels_us,
                autopilot_ready: flags & COMMAND_FLAG_AUTOPILOT_READY != 0,
            },
        })
    }
}

/// A decoder for one binary stream whose frames need no state beyond the envelope.
#[derive(Clone, Debug)]
pub struct BinaryDecoder<C: PayloadCodec> {
    assembler: FrameAssembler,
    stats: DecoderStats,
    staleness: Staleness,
    codec: PhantomData<C>,
}

/// The flight side: board → computer.
pub type ServoDecoder = BinaryDecoder<PilotCodec>;
/// The simulator's side: computer → board.
pub type ServoCommandDecoder = BinaryDecoder<CommandCodec>;

impl<C: PayloadCodec> Default for BinaryDecoder<C> {
    fn default() -> Self {
        Self::new(DEFAULT_STALE_TIMEOUT_NS)
    }
}

impl<C: PayloadCodec> BinaryDecoder<C> {
    pub const fn new(stale_timeout_ns: u64) -> Self {
        Self {
            assembler: FrameAssembler::new(C::FRAME_TYPE, C::PAYLOAD_LEN),
            stats: DecoderStats::new(),
            staleness: Staleness::new(stale_timeout_ns),
            codec: PhantomData,
        }
    }

    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    pub fn staleness(&self) -> &Staleness {
        &self.staleness
    }

    pub fn push(&mut self, bytes: &[u8], now_ns: u64, mut out: impl FnMut(C::Frame)) {
        for &byte in bytes {
            let staleness = &mut self.staleness;
            self.assembler
                .push_byte(byte, &mut self.stats, &mut |frame| match C::decode(
                    frame.counter,
                    frame.payload,
                    now_ns,
                ) {
                    Some(decoded) => {
                        staleness.mark_valid(now_ns);
                        out(decoded);
                        true
                    }
                    None => false,
                });
        }
        if self.staleness.update(now_ns) {
            bump(&mut self.stats.stale_events);
        }
    }
}

impl<C: PayloadCodec> Decoder for BinaryDecoder<C> {
    type Frame = C::Frame;

    fn push(&mut self, bytes: &[u8], now_ns: u64, out: &mut dyn FnMut(C::Frame)) {
        BinaryDecoder::push(self, bytes, now_ns, out)
    }

    fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    fn is_stale(&self, now_ns: u64) -> bool {
        self.staleness.is_stale(now_ns)
    }
}

const _: () = assert!(PILOT_FRAME_LEN <= MAX_FRAME_LEN && COMMAND_FRAME_LEN <= MAX_FRAME_LEN);

#[cfg(test)]
mod tests;

//! The IMU protocol (docs/protocols.md, "IMU"): a 100 Hz fast frame with body rates and
//! specific force, each carrying one byte of a 100-byte slow record (temperature, supply,
//! high-resolution one-second means) that is rebuilt once a second.
//!
//! Axes are body FRD on the wire already, so decoding is only scaling: a level vehicle at
//! rest reads specific force (0, 0, −9.80665).

use super::framing::{self, FrameAssembler, MAX_FRAME_LEN};
use super::{Decoder, DecoderStats, Staleness, bump};

/// Frame type byte of IMU fast frames (`'I'`).
pub const IMU_FRAME_TYPE: u8 = 0x49;
pub const IMU_PAYLOAD_LEN: usize = 15;
pub const IMU_FRAME_LEN: usize = framing::HEADER_LEN + IMU_PAYLOAD_LEN + framing::CRC_LEN;
/// Fast frames per slow record: one record byte rides in each frame.
pub const SLOW_RECORD_LEN: usize = 100;

/// Wire resolution of the fast rates: ±32.767 rad/s (±1877 °/s) in an i16.
pub const RATE_LSB_RADPS: f32 = 1e-3;
/// Wire resolution of the fast specific force: ±163.8 m/s² (±16.7 g) in an i16.
pub const SPECIFIC_FORCE_LSB_MPS2: f32 = 5e-3;
/// Slow record: one-second mean rate, 1 µrad/s per LSB in an i32.
pub const MEAN_RATE_LSB_RADPS: f32 = 1e-6;
/// Slow record: one-second mean specific force, 10 µm/s² per LSB in an i32.
pub const MEAN_SPECIFIC_FORCE_LSB_MPS2: f32 = 1e-5;
pub const TEMPERATURE_LSB_C: f32 = 0.01;
pub const SUPPLY_LSB_V: f32 = 1e-3;

/// Default staleness timeout: five missed fast frames.
pub const DEFAULT_STALE_TIMEOUT_NS: u64 = 50_000_000;

/// The IMU's status byte in every fast frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuStatus(pub u8);

impl ImuStatus {
    pub const GYRO_SATURATED: u8 = 1 << 0;
    pub const ACCEL_SATURATED: u8 = 1 << 1;
    pub const BUILT_IN_TEST_FAILED: u8 = 1 << 2;

    pub fn gyro_saturated(self) -> bool {
        self.0 & Self::GYRO_SATURATED != 0
    }
    pub fn accel_saturated(self) -> bool {
        self.0 & Self::ACCEL_SATURATED != 0
    }
    pub fn built_in_test_failed(self) -> bool {
        self.0 & Self::BUILT_IN_TEST_FAILED != 0
    }
}

/// What one fast frame measures, in SI units, body FRD.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuMeasurement {
    /// p, q, r.
    pub rate_radps: [f32; 3],
    pub specific_force_mps2: [f32; 3],
    pub status: ImuStatus,
}

/// The period of the IMU's frames, which its 8-bit counter counts.
pub const IMU_FRAME_PERIOD_S: f64 = 0.01;
/// The longest gap (in frames) the counter measures; longer gaps are timed by the receive
/// times (the counter may have wrapped).
pub const MAX_COUNTED_GAP: u8 = 10;

/// Receive-time gap beyond the counted one that means an outage (s): five frames, more than
/// any scheduling jitter delays a read.
pub const OUTAGE_SLACK_S: f64 = 0.05;

/// The time step from the previous sample `(counter, received_ns)` to this one: from the
/// frame counter, so scheduling jitter does not enter the integration, or from the receive
/// times for a gap the counter cannot measure. `None`: the same frame again (nothing new).
/// The one rule for the estimator task, replay and the scoring tools.
pub fn imu_step_s(previous: Option<(u8, u64)>, counter: u8, received_ns: u64) -> Option<f64> {
    match previous {
        Some((last, _)) if last == counter => None,
        Some((last, last_ns)) if counter.wrapping_sub(last) <= MAX_COUNTED_GAP => {
            let counted_s = f64::from(counter.wrapping_sub(last)) * IMU_FRAME_PERIOD_S;
            // The counter cannot tell an outage of 256 frames (or a device that restarted,
            // or stopped counting while its link was down) from one frame: when the receive
            // times say far more time passed than the frames counted, they are right.
            let elapsed_s = received_ns.saturating_sub(last_ns) as f64 * 1e-9;
            Some(if elapsed_s > counted_s + OUTAGE_SLACK_S {
                elapsed_s
            } else {
                counted_s
            })
        }
        Some((_, last_ns)) => Some(received_ns.saturating_sub(last_ns) as f64 * 1e-9),
        None => Some(IMU_FRAME_PERIOD_S),
    }
}

/// A decoded fast frame.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuSample {
    pub counter: u8,
    /// `now_ns` of the `push` that completed the frame.
    pub received_ns: u64,
    pub measurement: ImuMeasurement,
}

/// The slow, high-resolution record, rebuilt from 100 consecutive fast frames.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuSlowRecord {
    /// +1 per record, wrapping: tells a lost record from a repeated one.
    pub record_counter: u16,
    pub temperature_c: f32,
    pub supply_v: f32,
    pub serial_number: u16,
    /// Mean over the second the record covers; what bias estimation wants.
    pub mean_rate_radps: [f32; 3],
    pub mean_specific_force_mps2: [f32; 3],
    /// Detailed built-in-test result; 0 is healthy. Bit meanings are the IMU vendor's.
    pub built_in_test: u16,
}

/// A decoded slow record and when its last byte arrived.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuSlowFrame {
    pub received_ns: u64,
    pub record: ImuSlowRecord,
}

#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImuFrame {
    Sample(ImuSample),
    /// Comes right after the sample that completed it.
    Slow(ImuSlowFrame),
}

/// One slot of the slow record, as a fast frame carries it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlowSlot {
    pub index: u8,
    pub byte: u8,
}

fn quantise_i16(value: f32, lsb: f32) -> i16 {
    // `as` saturates and maps NaN to 0: an encoder must not panic on a simulator's NaN.
    libm::roundf(value / lsb) as i16
}

fn quantise_i32(value: f32, lsb: f32) -> i32 {
    libm::roundf(value / lsb) as i32
}

fn quantise_u16(value: f32, lsb: f32) -> u16 {
    libm::roundf(value / lsb) as u16
}

impl ImuSlowRecord {
    /// The record's 100 bytes (docs/protocols.md, "IMU slow record").
    pub fn to_bytes(&self) -> [u8; SLOW_RECORD_LEN] {
        let mut bytes = [0u8; SLOW_RECORD_LEN];
        let mut fields = bytes.iter_mut();
        let mut put = |field: &[u8]| {
            for (&byte, slot) in field.iter().zip(fields.by_ref()) {
                *slot = byte;
            }
        };
        put(&self.record_counter.to_le_bytes());
        put(&quantise_i16(self.temperature_c, TEMPERATURE_LSB_C).to_le_bytes());
        put(&quantise_u16(self.supply_v, SUPPLY_LSB_V).to_le_bytes());
        put(&self.serial_number.to_le_bytes());
        for rate in self.mean_rate_radps {
            put(&quantise_i32(rate, MEAN_RATE_LSB_RADPS).to_le_bytes());
        }
        for force in self.mean_specific_force_mps2 {
            put(&quantise_i32(force, MEAN_SPECIFIC_FORCE_LSB_MPS2).to_le_bytes());
        }
        put(&self.built_in_test.to_le_bytes());
        bytes
    }

    /// Reads the record's fields; the reserved tail is ignored so the IMU can add fields.
    pub fn from_bytes(bytes: &[u8; SLOW_RECORD_LEN]) -> Self {
        let mut reader = LeReader(bytes);
        let record_counter = reader.u16();
        let temperature_c = f32::from(reader.i16()) * TEMPERATURE_LSB_C;
        let supply_v = f32::from(reader.u16()) * SUPPLY_LSB_V;
        let serial_number = reader.u16();
        let mean_rate_radps = [(); 3].map(|_| reader.i32() as f32 * MEAN_RATE_LSB_RADPS);
        let mean_specific_force_mps2 =
            [(); 3].map(|_| reader.i32() as f32 * MEAN_SPECIFIC_FORCE_LSB_MPS2);
        let built_in_test = reader.u16();
        Self {
            record_counter,
            temperature_c,
            supply_v,
            serial_number,
            mean_rate_radps,
            mean_specific_force_mps2,
            built_in_test,
        }
    }
}

/// Little-endian field reader over a payload; reads past the end give zeros instead of
/// panicking (callers check lengths first, this is the belt to those braces).
pub(crate) struct LeReader<'a>(pub(crate) &'a [u8]);

impl LeReader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        if let Some((head, rest)) = self.0.split_at_checked(N) {
            out.copy_from_slice(head);
            self.0 = rest;
        } else {
            self.0 = &[];
        }
        out
    }
    pub(crate) fn u8(&mut self) -> u8 {
        u8::from_le_bytes(self.take())
    }
    pub(crate) fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    pub(crate) fn i16(&mut self) -> i16 {
        i16::from_le_bytes(self.take())
    }
    pub(crate) fn i32(&mut self) -> i32 {
        i32::from_le_bytes(self.take())
    }
}

/// Writes one fast frame; returns [`IMU_FRAME_LEN`]. Values beyond the wire range saturate.
pub fn encode_imu_frame(
    counter: u8,
    measurement: &ImuMeasurement,
    slot: SlowSlot,
    out: &mut [u8; IMU_FRAME_LEN],
) -> usize {
    let mut payload = [0u8; IMU_PAYLOAD_LEN];
    let mut fields = payload.iter_mut();
    let mut put = |field: &[u8]| {
        for (&byte, slot) in field.iter().zip(fields.by_ref()) {
            *slot = byte;
        }
    };
    for rate in measurement.rate_radps {
        put(&quantise_i16(rate, RATE_LSB_RADPS).to_le_bytes());
    }
    for force in measurement.specific_force_mps2 {
        put(&quantise_i16(force, SPECIFIC_FORCE_LSB_MPS2).to_le_bytes());
    }
    put(&[measurement.status.0, slot.index, slot.byte]);
    framing::encode_frame(IMU_FRAME_TYPE, counter, &payload, out).unwrap_or(0)
}

/// What the simulator runs to speak as the IMU: counts frames and walks the slow record's
/// slots, so each call gives the next frame of a well-formed stream.
#[derive(Clone, Debug)]
pub struct ImuStreamEncoder {
    counter: u8,
    next_slot: u8,
    current: [u8; SLOW_RECORD_LEN],
    pending: Option<[u8; SLOW_RECORD_LEN]>,
}

impl Default for ImuStreamEncoder {
    fn default() -> Self {
        Self::new()
    }
}

impl ImuStreamEncoder {
    pub const fn new() -> Self {
        Self {
            counter: 0,
            next_slot: 0,
            current: [0; SLOW_RECORD_LEN],
            pending: None,
        }
    }

    /// The slow record to send from the next slot 0 on (a record is never sent half old,
    /// half new).
    pub fn set_slow_record(&mut self, record: &ImuSlowRecord) {
        self.pending = Some(record.to_bytes());
    }

    pub fn encode(&mut self, measurement: &ImuMeasurement, out: &mut [u8; IMU_FRAME_LEN]) -> usize {
        if self.next_slot == 0 {
            if let Some(record) = self.pending.take() {
                self.current = record;
            }
        }
        let slot = SlowSlot {
            index: self.next_slot,
            byte: self
                .current
                .get(usize::from(self.next_slot))
                .copied()
                .unwrap_or_default(),
        };
        let len = encode_imu_frame(self.counter, measurement, slot, out);
        self.counter = self.counter.wrapping_add(1);
        self.next_slot = if usize::from(self.next_slot) + 1 >= SLOW_RECORD_LEN {
            0
        } else {
            self.next_slot + 1
        };
        len
    }
}

/// Rebuilds the slow record: it only accepts slots 0, 1, … 99 in an unbroken run, so a lost
/// frame costs the record rather than splicing bytes of two seconds together.
#[derive(Clone, Debug)]
struct SlowAssembler {
    bytes: [u8; SLOW_RECORD_LEN],
    next_slot: Option<usize>,
    dropped: u32,
}

impl SlowAssembler {
    const fn new() -> Self {
        Self {
            bytes: [0; SLOW_RECORD_LEN],
            next_slot: None,
            dropped: 0,
        }
    }

    fn accept(&mut self, slot: SlowSlot) -> Option<ImuSlowRecord> {
        let index = usize::from(slot.index);
        let in_sequence = index == 0 || self.next_slot == Some(index);
        if !in_sequence {
            if self.next_slot.is_some() {
                bump(&mut self.dropped);
            }
            self.next_slot = None;
            return None;
        }
        if index == 0 && self.next_slot.is_some_and(|next| next != 0) {
            bump(&mut self.dropped);
        }
        let cell = self.bytes.get_mut(index)?;
        *cell = slot.byte;
        if index + 1 == SLOW_RECORD_LEN {
            self.next_slot = None;
            Some(ImuSlowRecord::from_bytes(&self.bytes))
        } else {
            self.next_slot = Some(index + 1);
            None
        }
    }

    fn abandon(&mut self) {
        if self.next_slot.is_some() {
            bump(&mut self.dropped);
        }
        self.next_slot = None;
    }
}

/// Decodes the IMU's byte stream into [`ImuFrame`]s.
#[derive(Clone, Debug)]
pub struct ImuDecoder {
    assembler: FrameAssembler,
    slow: SlowAssembler,
    stats: DecoderStats,
    staleness: Staleness,
}

impl Default for ImuDecoder {
    fn default() -> Self {
        Self::new(DEFAULT_STALE_TIMEOUT_NS)
    }
}

impl ImuDecoder {
    pub const fn new(stale_timeout_ns: u64) -> Self {
        Self {
            assembler: FrameAssembler::new(IMU_FRAME_TYPE, IMU_PAYLOAD_LEN as u8),
            slow: SlowAssembler::new(),
            stats: DecoderStats::new(),
            staleness: Staleness::new(stale_timeout_ns),
        }
    }

    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    pub fn staleness(&self) -> &Staleness {
        &self.staleness
    }

    /// Slow records abandoned because a slot went missing.
    pub fn slow_records_dropped(&self) -> u32 {
        self.slow.dropped
    }

    pub fn push(&mut self, bytes: &[u8], now_ns: u64, mut out: impl FnMut(ImuFrame)) {
        for &byte in bytes {
            let slow = &mut self.slow;
            let staleness = &mut self.staleness;
            self.assembler
                .push_byte(byte, &mut self.stats, &mut |frame| {
                    let Some((sample, slot)) =
                        decode_fast_payload(frame.counter, frame.payload, now_ns)
                    else {
                        return false;
                    };
                    staleness.mark_valid(now_ns);
                    out(ImuFrame::Sample(sample));
                    if usize::from(slot.index) >= SLOW_RECORD_LEN {
                        // The sample is still good (its CRC passed); only the slot is
                        // nonsense, so the record in progress cannot be trusted.
                        slow.abandon();
                        return false;
                    }
                    if let Some(record) = slow.accept(slot) {
                        out(ImuFrame::Slow(ImuSlowFrame {
                            received_ns: now_ns,
                            record,
                        }));
                    }
                    true
                });
        }
        if self.staleness.update(now_ns) {
            bump(&mut self.stats.stale_events);
        }
    }
}

fn decode_fast_payload(counter: u8, payload: &[u8], now_ns: u64) -> Option<(ImuSample, SlowSlot)> {
    if payload.len() != IMU_PAYLOAD_LEN {
        return None;
    }
    let mut reader = LeReader(payload);
    let rate_radps = [(); 3].map(|_| f32::from(reader.i16()) * RATE_LSB_RADPS);
    let specific_force_mps2 = [(); 3].map(|_| f32::from(reader.i16()) * SPECIFIC_FORCE_LSB_MPS2);
    let status = ImuStatus(reader.u8());
    let slot = SlowSlot {
        index: reader.u8(),
        byte: reader.u8(),
    };
    let sample = ImuSample {
        counter,
        received_ns: now_ns,
        measurement: ImuMeasurement {
            rate_radps,
            specific_force_mps2,
            status,
        },
    };
    Some((sample, slot))
}

impl Decoder for ImuDecoder {
    type Frame = ImuFrame;

    fn push(&mut self, bytes: &[u8], now_ns: u64, out: &mut dyn FnMut(ImuFrame)) {
        ImuDecoder::push(self, bytes, now_ns, out)
    }

    fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    fn is_stale(&self, now_ns: u64) -> bool {
        self.staleness.is_stale(now_ns)
    }
}

/// The frame length is small enough for the shared assembler's buffer.
const _: () = assert!(IMU_FRAME_LEN <= MAX_FRAME_LEN);

#[cfg(test)]
mod tests;

#[cfg(test)]
mod step_tests {
    use super::*;

    #[test]
    fn the_counter_times_short_gaps_and_the_clock_long_ones() {
        assert_eq!(imu_step_s(None, 7, 0), Some(0.01));
        assert_eq!(imu_step_s(Some((7, 0)), 7, 5_000_000), None);
        assert_eq!(imu_step_s(Some((7, 0)), 8, 13_000_000), Some(0.01));
        // Wrapping: 255 → 2 is three frames.
        assert_eq!(imu_step_s(Some((255, 0)), 2, 0), Some(0.03));
        // One frame counted, two seconds received: an outage the counter missed.
        let outage = imu_step_s(Some((7, 0)), 8, 2_010_000_000).expect("a step");
        assert!((outage - 2.01).abs() < 1e-12, "{outage}");
        // Eleven frames: the counter may have wrapped, the receive times decide.
        assert_eq!(
            imu_step_s(Some((0, 1_000_000_000)), 11, 1_250_000_000),
            Some(0.25)
        );
    }
}

//! Flying the simulated airplane: the world's devices talk to the device tasks through
//! in-process rings (the same `DevicePort`s serial threads fill on hardware), and the
//! executive's timer advances the world between frames.

use crate::logwriter::LogStream;
use crate::platform::{Platform, RtConfig, RtReport};
use crate::serial::{DevicePort, RX_RING, TX_RING};
use skyframe_core::logfmt::record::{
    EncodeError, MAX_RECORD_LEN, encode_begin_data, encode_end_data,
};
use skyframe_core::logfmt::{LogRecord, encode_record};
use skyframe_sim::VirtualClock;
use skyframe_sim::plant::{GeodeticPosition, Truth};
use skyframe_sim::timer::SimTimer;
use skyframe_sim::world::{Device, DeviceLink, SimWorld};
use std::sync::Mutex;

skyframe_core::log_record! {
    /// Ground truth, for scoring estimates (`docs/log-streams.md`, `truth.bin`), at 50 Hz.
    pub struct TruthRecord {
        north_m: f64 = "%.3lf",
        east_m: f64 = "%.3lf",
        down_m: f64 = "%.3lf",
        vn_m_s: f32 = "%.3f",
        ve_m_s: f32 = "%.3f",
        vd_m_s: f32 = "%.3f",
        roll_rad: f32 = "%.5f",
        pitch_rad: f32 = "%.5f",
        yaw_rad: f32 = "%.5f",
        p_rad_s: f32 = "%.5f",
        q_rad_s: f32 = "%.5f",
        r_rad_s: f32 = "%.5f",
        airspeed_m_s: f32 = "%.3f",
        alpha_rad: f32 = "%.5f",
        beta_rad: f32 = "%.5f",
        wind_n_m_s: f32 = "%.3f",
        wind_e_m_s: f32 = "%.3f",
        wind_d_m_s: f32 = "%.3f",
        on_ground: bool = "%hhu",
    }
}
skyframe_core::log_record! {
    /// Where truth positions are measured from, once after each Begin Data: scoring needs it to
    /// place the estimates, whose origin is their first GPS fix.
    pub struct TruthOriginRecord {
        origin_lat_deg: f64 = "%.8lf",
        origin_lon_deg: f64 = "%.8lf",
        origin_alt_m: f64 = "%.3lf",
    }
}
pub const TRUTH_INDEX: u8 = 1;
pub const TRUTH_ORIGIN_INDEX: u8 = 2;
/// Truth at 50 Hz: finer than the estimator's outputs need, coarse enough to stay small.
pub const TRUTH_INTERVAL_NS: u64 = 20_000_000;

/// The world's side of the device rings.
pub struct RingLink {
    imu: rtrb::Producer<u8>,
    gps: rtrb::Producer<u8>,
    servo: rtrb::Producer<u8>,
    commands: rtrb::Consumer<u8>,
    /// Bytes a full ring refused (the device task fell behind).
    pub overflow: u64,
}

/// The device ports for the tasks, and the link for the world.
pub fn device_rings() -> ([DevicePort; 3], RingLink) {
    let (imu_in, imu_out) = rtrb::RingBuffer::new(RX_RING);
    let (gps_in, gps_out) = rtrb::RingBuffer::new(RX_RING);
    let (servo_in, servo_out) = rtrb::RingBuffer::new(RX_RING);
    let (commands_in, commands_out) = rtrb::RingBuffer::new(TX_RING);
    // Nothing is ever sent to the IMU or the GPS: their tx rings are never read.
    let (imu_tx, _) = rtrb::RingBuffer::new(1);
    let (gps_tx, _) = rtrb::RingBuffer::new(1);
    (
        [
            DevicePort::new(imu_out, imu_tx),
            DevicePort::new(gps_out, gps_tx),
            DevicePort::new(servo_out, commands_in),
        ],
        RingLink {
            imu: imu_in,
            gps: gps_in,
            servo: servo_in,
            commands: commands_out,
            overflow: 0,
        },
    )
}

impl DeviceLink for RingLink {
    fn send_to_computer(&mut self, device: Device, bytes: &[u8]) {
        let ring = match device {
            Device::Imu => &mut self.imu,
            Device::Gps => &mut self.gps,
            Device::Servo => &mut self.servo,
        };
        let room = ring.slots().min(bytes.len());
        if let Ok(chunk) = ring.write_chunk_uninit(room) {
            chunk.fill_from_iter(bytes.iter().copied());
        }
        self.overflow += (bytes.len() - room) as u64;
    }

    fn receive_from_computer(&mut self, buf: &mut [u8]) -> usize {
        crate::ring::read_into(&mut self.commands, buf)
    }
}

/// Virtual time: runs as fast as the machine allows, deterministic for a seed.
#[derive(Default)]
pub struct VirtualTime;

impl Platform for VirtualTime {
    type Timer = VirtualClock;

    fn name(&self) -> &'static str {
        "virtual"
    }

    fn virtual_time(&self) -> bool {
        true
    }

    fn timer(&self) -> VirtualClock {
        VirtualClock::new()
    }

    fn make_realtime(&self, _config: &RtConfig) -> RtReport {
        RtReport::none()
    }

    fn serial_opener(&self) -> crate::serial::SerialOpener {
        crate::serial::no_serial_ports
    }
}

/// A host platform whose timer also advances a simulated world. The world is handed to the
/// first timer made (a flight makes one).
pub struct SimPlatform<'p, P> {
    host: &'p P,
    world: Mutex<Option<(SimWorld, RingLink, Option<LogStream>)>>,
    /// Log TIME of clock zero (`log-format.md`: wall clock in real time, 0 in virtual time).
    time_origin_ns: u64,
}

impl<'p, P: Platform> SimPlatform<'p, P> {
    pub fn new(
        host: &'p P,
        world: SimWorld,
        link: RingLink,
        truth: Option<LogStream>,
        time_origin_ns: u64,
    ) -> Self {
        Self {
            host,
            world: Mutex::new(Some((world, link, truth))),
            time_origin_ns,
        }
    }
}

/// The truth stream: declared and begun when made, ended when dropped (with the timer, at
/// the end of the flight), so `truth.bin` is closed cleanly like every other log.
struct TruthLog {
    stream: LogStream,
    buf: Vec<u8>,
    time_origin_ns: u64,
    last_t_ns: u64,
}

impl Drop for TruthLog {
    fn drop(&mut self) {
        if let Ok(n) = encode_end_data(&mut self.buf, self.time_origin_ns + self.last_t_ns) {
            self.stream
                .push_record(self.buf.get(..n).unwrap_or_default());
        }
    }
}

/// Encodes truth records into the truth stream, after the origin they are measured from.
fn truth_tap(
    mut stream: LogStream,
    time_origin_ns: u64,
    origin: GeodeticPosition,
) -> skyframe_sim::timer::TruthTap {
    let mut buf = vec![0u8; MAX_RECORD_LEN];
    fn push(stream: &mut LogStream, encoded: Result<usize, EncodeError>, buf: &[u8]) {
        if let Ok(n) = encoded {
            stream.push_record(buf.get(..n).unwrap_or_default());
        }
    }
    let encoded = TruthRecord::FORMAT.encode_declaration(&mut buf, TRUTH_INDEX);
    push(&mut stream, encoded, &buf);
    let encoded = TruthOriginRecord::FORMAT.encode_declaration(&mut buf, TRUTH_ORIGIN_INDEX);
    push(&mut stream, encoded, &buf);
    let encoded = encode_begin_data(&mut buf, time_origin_ns);
    push(&mut stream, encoded, &buf);
    let origin = TruthOriginRecord {
        origin_lat_deg: origin.lat_deg,
        origin_lon_deg: origin.lon_deg,
        origin_alt_m: origin.alt_msl_m,
    };
    let encoded = encode_record(&mut buf, TRUTH_ORIGIN_INDEX, time_origin_ns, &origin);
    push(&mut stream, encoded, &buf);
    let mut log = TruthLog {
        stream,
        buf,
        time_origin_ns,
        last_t_ns: 0,
    };
    Box::new(move |t_ns: u64, truth: &Truth| {
        log.last_t_ns = t_ns;
        let TruthLog { stream, buf, .. } = &mut log;
        let [north_m, east_m, down_m] = truth.position_ned_m;
        let [vn, ve, vd] = truth.velocity_ned_mps;
        let [p, q, r] = truth.rates_body_radps;
        let [wn, we, wd] = truth.wind_ned_mps;
        let f = |x: f64| x as f32;
        let record = TruthRecord {
            north_m,
            east_m,
            down_m,
            vn_m_s: f(vn),
            ve_m_s: f(ve),
            vd_m_s: f(vd),
            roll_rad: f(truth.roll_rad),
            pitch_rad: f(truth.pitch_rad),
            yaw_rad: f(truth.yaw_rad),
            p_rad_s: f(p),
            q_rad_s: f(q),
            r_rad_s: f(r),
            airspeed_m_s: f(truth.airspeed_mps),
            alpha_rad: f(truth.alpha_rad),
            beta_rad: f(truth.beta_rad),
            wind_n_m_s: f(wn),
            wind_e_m_s: f(we),
            wind_d_m_s: f(wd),
            on_ground: truth.on_ground,
        };
        if let Ok(len) = encode_record(buf, TRUTH_INDEX, time_origin_ns + t_ns, &record) {
            stream.push_record(buf.get(..len).unwrap_or_default());
        }
    })
}

impl<P: Platform> Platform for SimPlatform<'_, P> {
    type Timer = SimTimer<P::Timer, RingLink>;

    fn name(&self) -> &'static str {
        if self.host.virtual_time() {
            "sim (virtual time)"
        } else {
            "sim (real time)"
        }
    }

    fn virtual_time(&self) -> bool {
        self.host.virtual_time()
    }

    fn timer(&self) -> Self::Timer {
        let taken = self.world.lock().ok().and_then(|mut w| w.take());
        let inner = self.host.timer();
        match taken {
            Some((world, link, truth)) => {
                let origin = world.origin();
                let timer = SimTimer::new(inner, world, link);
                match truth {
                    Some(stream) => timer.with_truth(
                        TRUTH_INTERVAL_NS,
                        truth_tap(stream, self.time_origin_ns, origin),
                    ),
                    None => timer,
                }
            }
            // A second timer (not made by a flight) only keeps time.
            None => SimTimer::without_world(inner),
        }
    }

    fn make_realtime(&self, config: &RtConfig) -> RtReport {
        self.host.make_realtime(config)
    }

    fn serial_opener(&self) -> crate::serial::SerialOpener {
        self.host.serial_opener()
    }
}

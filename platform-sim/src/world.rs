//! The simulated world around the flight computer: the airplane, its three devices speaking
//! the exact wire protocols of `docs/protocols.md`, the pilot's sticks, and the servo board
//! that chooses between pilot and computer.
//!
//! [`SimWorld::advance_to`] moves everything to a point in time: the plant integrates in
//! 1 ms steps; the IMU sends a frame every 10 ms, the GPS its sentences whenever the receiver
//! model delivers a solution (jittery, as the seed's was), the board a report every 20 ms;
//! the computer's command frames are read back and applied with the board's rules. Where
//! the bytes go ([`DeviceLink`]) is the caller's: rings in process, pseudo-terminals for
//! `skyframe-sim --pty`.

use crate::pilot::SwitchPosition;
use crate::plant::jsbsim::{JsbsimConfig, JsbsimModel, JsbsimStart};
use crate::plant::sensors::{GpsFixType, SimGpsSolution};
use crate::plant::{
    ActuatorCommands, FlightModel, GeodeticPosition, Plant, PlantError, PlantKind, Truth,
};
pub use crate::scenario::Device;
use crate::scenario::{Fault, FaultKind, InitialCondition, Scenario, ScenarioPilot};
use crate::servo_board::{OutputSource, ServoBoard, TransmitterInput};
use skyframe_core::devices::gps::{
    FixDimension, FixQuality, GpsFix, SentenceKind, Talker, encode_sentence,
};
use skyframe_core::devices::imu::{
    IMU_FRAME_LEN, ImuMeasurement, ImuSlowRecord, ImuStatus, ImuStreamEncoder,
};
use skyframe_core::devices::servo::{
    BoardStatus, PILOT_FRAME_LEN, PilotReport, ServoCommandDecoder, encode_pilot_frame,
    pulse_us_to_surface, pulse_us_to_throttle, surface_to_pulse_us, throttle_to_pulse_us,
};

const MS: u64 = 1_000_000;
const PLANT_STEP_NS: u64 = MS;
const IMU_PERIOD_NS: u64 = 10 * MS;
const BOARD_PERIOD_NS: u64 = 20 * MS;
/// UTC time of day at simulation time zero (noon): GPS sentences carry time of day.
const UTC_START_MS: u64 = 12 * 3_600_000;

/// Where the devices' bytes go and where the computer's commands come from.
pub trait DeviceLink {
    /// Bytes a device sends to the flight computer.
    fn send_to_computer(&mut self, device: Device, bytes: &[u8]);
    /// Bytes the flight computer sent to the servo board since the last call, into `buf`.
    fn receive_from_computer(&mut self, buf: &mut [u8]) -> usize;
}

/// Whoever holds the pilot's transmitter: sticks, brakes and the auto/manual switch.
pub trait Transmitter {
    fn update(&mut self, truth: &Truth) -> TransmitterInput;
}

impl Transmitter for ScenarioPilot {
    fn update(&mut self, truth: &Truth) -> TransmitterInput {
        ScenarioPilot::update(self, truth)
    }
}

/// A transmitter whose sticks never move: enough for a trimmed airplane to fly straight.
pub struct SteadySticks(pub TransmitterInput);

impl Transmitter for SteadySticks {
    fn update(&mut self, _truth: &Truth) -> TransmitterInput {
        self.0
    }
}

/// What the devices are made to do wrong right now (scenario faults).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceFaults {
    /// The device sends nothing (IMU, GPS, servo board).
    pub silent: [bool; 3],
    /// The device sends garbage bytes between its frames.
    pub garbage: [bool; 3],
    /// The GPS reports no fix.
    pub gps_loss: bool,
    /// The servo board's port is gone: nothing either way.
    pub servo_vanished: bool,
}

fn device_slot(device: Device) -> usize {
    match device {
        Device::Imu => 0,
        Device::Gps => 1,
        Device::Servo => 2,
    }
}

impl DeviceFaults {
    /// The faults of `scenario` active at `t_s` (task overruns are the executive's).
    pub fn at(faults: &[Fault], t_s: f64) -> Self {
        let mut out = Self::default();
        for f in faults.iter().filter(|f| f.is_active(t_s)) {
            let slot = f.device.map(device_slot);
            match (f.kind, slot) {
                (FaultKind::SensorSilence, Some(i)) => {
                    if let Some(s) = out.silent.get_mut(i) {
                        *s = true;
                    }
                }
                (FaultKind::GarbageBurst, Some(i)) => {
                    if let Some(g) = out.garbage.get_mut(i) {
                        *g = true;
                    }
                }
                (FaultKind::GpsLoss, _) => out.gps_loss = true,
                (FaultKind::ServoPortVanish, _) => out.servo_vanished = true,
                _ => {}
            }
        }
        out
    }
}

/// Counters of what the world sent and did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WorldStats {
    pub imu_frames: u64,
    pub gps_epochs: u64,
    pub board_frames: u64,
    pub command_frames: u64,
    /// Plant steps during which the servos followed the computer.
    pub computer_steps: u64,
}

/// The airplane whichever flight model flies it.
pub type AnyPlant = Plant<Box<dyn FlightModel>>;

/// Told once when the airplane is lost mid-flight (JSBSim's process died or talks garbage).
pub type FailureHook = Box<dyn FnMut(&PlantError) + Send>;

pub struct SimWorld {
    plant: AnyPlant,
    transmitter: Box<dyn Transmitter + Send>,
    board: ServoBoard,
    imu: ImuStreamEncoder,
    next_imu_ns: u64,
    next_board_ns: u64,
    board_counter: u8,
    commands: ServoCommandDecoder,
    pilot_input: TransmitterInput,
    scheduled_faults: Vec<Fault>,
    /// The scheduled faults come round again every this many seconds (a soak); `None`: once.
    fault_period_s: Option<f64>,
    faults: DeviceFaults,
    garbage_state: u32,
    stats: WorldStats,
    /// Why the airplane was lost; from then on the world stands still.
    failure: Option<PlantError>,
    on_failure: Option<FailureHook>,
}

impl SimWorld {
    pub fn new<M: FlightModel + 'static>(
        plant: Plant<M>,
        transmitter: Box<dyn Transmitter + Send>,
    ) -> Self {
        let plant = plant.boxed();
        let start = plant.time_ns();
        Self {
            plant,
            transmitter,
            board: ServoBoard::new(),
            imu: ImuStreamEncoder::new(),
            next_imu_ns: start,
            next_board_ns: start,
            board_counter: 0,
            commands: ServoCommandDecoder::new(u64::MAX),
            pilot_input: TransmitterInput::default(),
            scheduled_faults: Vec::new(),
            fault_period_s: None,
            faults: DeviceFaults::default(),
            garbage_state: 0x9E37_79B9,
            stats: WorldStats::default(),
            failure: None,
            on_failure: None,
        }
    }

    /// `hook` is told when the airplane is lost mid-flight, so whoever runs the flight can
    /// stop it (logs closed) and report the plant's error.
    pub fn on_failure(&mut self, hook: FailureHook) {
        self.on_failure = Some(hook);
    }

    /// Why the airplane was lost, if it was: the world stopped at that time.
    pub fn failure(&self) -> Option<&PlantError> {
        self.failure.as_ref()
    }

    /// The world of a scenario: its airplane (on the scenario's plant), wind, GPS, pilot and
    /// faults; `seed` overrides the scenario's. Fails only when JSBSim cannot start.
    pub fn from_scenario(scenario: &Scenario, seed: Option<u64>) -> Result<Self, PlantError> {
        Self::from_scenario_on(scenario, seed, &scenario.plant)
    }

    /// [`from_scenario`](Self::from_scenario) on `plant` instead of the scenario's.
    pub fn from_scenario_on(
        scenario: &Scenario,
        seed: Option<u64>,
        plant: &PlantKind,
    ) -> Result<Self, PlantError> {
        let seed = seed.unwrap_or(scenario.seed);
        let config = scenario.plant_config();
        let (plant, pilot) = match plant {
            PlantKind::BuiltIn => {
                let initial = scenario.initial_state(&config.params);
                let pilot = ScenarioPilot::new(scenario, &config.params);
                (Plant::with_config(config, initial, seed).boxed(), pilot)
            }
            PlantKind::Jsbsim { aircraft } => {
                let start = match scenario.initial {
                    InitialCondition::OnRunway { heading_rad } => {
                        JsbsimStart::OnRunway { heading_rad }
                    }
                    InitialCondition::InFlight {
                        altitude_m,
                        airspeed_mps,
                        heading_rad,
                    } => JsbsimStart::InFlight {
                        altitude_m,
                        airspeed_mps,
                        heading_rad,
                    },
                };
                let cruise = match scenario.initial {
                    InitialCondition::InFlight { airspeed_mps, .. } => Some(airspeed_mps),
                    InitialCondition::OnRunway { .. } => scenario.pilot_cruise_airspeed_mps,
                };
                let jsbsim = JsbsimConfig {
                    trim_airspeed_mps: cruise,
                    ..JsbsimConfig::new(aircraft)
                };
                let model = JsbsimModel::start(jsbsim, &config, start, seed)?;
                let mut pilot = ScenarioPilot::new(scenario, &config.params);
                if let (Some((trim, pitch)), Some(cruise)) = (model.trim(), cruise) {
                    // The scripted pilot knows the Aerosonde; on another airplane it flies
                    // from the trim JSBSim found, at the scenario's cruise speed.
                    pilot.retrim(trim, pitch, cruise);
                }
                (Plant::with_model(config, model, seed).boxed(), pilot)
            }
        };
        let mut world = Self::new(plant, Box::new(pilot));
        world.scheduled_faults = scenario.faults.clone();
        Ok(world)
    }

    pub fn truth(&self) -> Truth {
        self.plant.truth()
    }

    /// Where the truth's NED positions are measured from (the GPS model's home).
    pub fn origin(&self) -> GeodeticPosition {
        self.plant.config().gps.home
    }

    pub fn time_ns(&self) -> u64 {
        self.plant.time_ns()
    }

    pub fn stats(&self) -> WorldStats {
        self.stats
    }

    /// What the pilot is doing with the transmitter.
    pub fn pilot_input(&self) -> TransmitterInput {
        self.pilot_input
    }

    /// Faults on top of the scenario's (tests).
    pub fn set_faults(&mut self, faults: DeviceFaults) {
        self.faults = faults;
    }

    /// Makes the scenario's device faults come round again every `period_s` (a soak flies
    /// them on a loop for hours). Periods that are not positive and finite are ignored.
    pub fn repeat_faults_every(&mut self, period_s: f64) {
        self.fault_period_s = (period_s.is_finite() && period_s > 0.0).then_some(period_s);
    }

    /// The time the scheduled faults are looked up at.
    fn fault_clock_s(&self) -> f64 {
        let t = self.plant.time_s();
        self.fault_period_s.map_or(t, |period| t.rem_euclid(period))
    }

    /// Moves the world to `t_ns`, exchanging bytes with the computer through `link`. After
    /// the airplane is lost ([`failure`](Self::failure)) nothing moves and the devices are
    /// silent.
    pub fn advance_to(&mut self, t_ns: u64, link: &mut dyn DeviceLink) {
        let forced = self.faults;
        while self.failure.is_none() && self.plant.time_ns() < t_ns {
            self.faults = merge(
                forced,
                DeviceFaults::at(&self.scheduled_faults, self.fault_clock_s()),
            );
            self.read_commands(link);
            let truth = self.plant.truth();
            self.pilot_input = self.transmitter.update(&truth);
            let (actuators, source) = self.board.mix(self.plant.time_ns(), &self.pilot_input);
            if source == OutputSource::Computer {
                self.stats.computer_steps += 1;
            }
            if let Err(e) = self.plant.try_step(PLANT_STEP_NS as f64 * 1e-9, &actuators) {
                // Nothing can fly on; whoever runs the flight decides how to stop.
                if let Some(hook) = self.on_failure.as_mut() {
                    hook(&e);
                }
                self.failure = Some(e);
                break;
            }
            let now = self.plant.time_ns();
            if now >= self.next_imu_ns {
                self.next_imu_ns += IMU_PERIOD_NS;
                self.send_imu(link);
            }
            while let Some(sample) = self.plant.sample_gps() {
                self.send_gps(&sample, link);
            }
            if now >= self.next_board_ns {
                self.next_board_ns += BOARD_PERIOD_NS;
                self.send_board_report(link);
            }
        }
        self.faults = forced;
    }

    fn read_commands(&mut self, link: &mut dyn DeviceLink) {
        let mut buf = [0u8; 256];
        loop {
            let n = link.receive_from_computer(&mut buf);
            if n == 0 {
                break;
            }
            if self.faults.servo_vanished {
                // Unplugged: the computer's bytes go nowhere.
                continue;
            }
            let now = self.plant.time_ns();
            let mut latest = None;
            self.commands
                .push(buf.get(..n).unwrap_or_default(), now, |frame| {
                    latest = Some(frame.command)
                });
            if let Some(command) = latest {
                self.stats.command_frames += 1;
                let ch = |i: usize| command.channels_us.get(i).copied().unwrap_or(1500);
                let commands = ActuatorCommands {
                    aileron: f64::from(pulse_us_to_surface(ch(0))),
                    elevator: f64::from(pulse_us_to_surface(ch(1))),
                    throttle: f64::from(pulse_us_to_throttle(ch(2))),
                    rudder: f64::from(pulse_us_to_surface(ch(3))),
                    brake: 0.0,
                };
                self.board
                    .receive_computer_command(now, commands, command.autopilot_ready);
            }
        }
    }

    fn garbage(&mut self, device: Device, link: &mut dyn DeviceLink) {
        if self
            .faults
            .garbage
            .get(device_slot(device))
            .copied()
            .unwrap_or(false)
        {
            let mut bytes = [0u8; 12];
            for b in &mut bytes {
                // xorshift: deterministic noise, no RNG state shared with the plant.
                self.garbage_state ^= self.garbage_state << 13;
                self.garbage_state ^= self.garbage_state >> 17;
                self.garbage_state ^= self.garbage_state << 5;
                *b = self.garbage_state as u8;
            }
            link.send_to_computer(device, &bytes);
        }
    }

    fn silent(&self, device: Device) -> bool {
        let vanished = device == Device::Servo && self.faults.servo_vanished;
        vanished
            || self
                .faults
                .silent
                .get(device_slot(device))
                .copied()
                .unwrap_or(false)
    }

    fn send_imu(&mut self, link: &mut dyn DeviceLink) {
        let sample = self.plant.sample_imu();
        if self.silent(Device::Imu) {
            return;
        }
        let f32s = |v: [f64; 3]| v.map(|x| x as f32);
        let measurement = ImuMeasurement {
            rate_radps: f32s(sample.gyro_radps),
            specific_force_mps2: f32s(sample.specific_force_mps2),
            status: ImuStatus(0),
        };
        if self.stats.imu_frames % 100 == 0 {
            // A new slow record each second: temperature and supply drift a little.
            let seconds = self.stats.imu_frames / 100;
            self.imu.set_slow_record(&ImuSlowRecord {
                record_counter: seconds as u16,
                temperature_c: 25.0 + (seconds as f32 * 0.01),
                supply_v: 5.02,
                serial_number: 4711,
                mean_rate_radps: measurement.rate_radps,
                mean_specific_force_mps2: measurement.specific_force_mps2,
                built_in_test: 0,
            });
        }
        let mut frame = [0u8; IMU_FRAME_LEN];
        let n = self.imu.encode(&measurement, &mut frame);
        link.send_to_computer(Device::Imu, frame.get(..n).unwrap_or_default());
        self.stats.imu_frames += 1;
        self.garbage(Device::Imu, link);
    }

    fn send_gps(&mut self, sample: &SimGpsSolution, link: &mut dyn DeviceLink) {
        if self.silent(Device::Gps) {
            return;
        }
        let fix = gps_fix(sample, self.faults.gps_loss);
        let mut buf = [0u8; 160];
        // POS last: the receiver is configured to end each epoch with it (core's `devices::gps::GpsConfig`).
        for kind in SentenceKind::ALL {
            if let Some(n) = encode_sentence(kind, Talker::Gp, &fix, &mut buf) {
                link.send_to_computer(Device::Gps, buf.get(..n).unwrap_or_default());
            }
        }
        self.stats.gps_epochs += 1;
        self.garbage(Device::Gps, link);
    }

    fn send_board_report(&mut self, link: &mut dyn DeviceLink) {
        let battery = self.plant.sample_battery();
        if self.silent(Device::Servo) {
            return;
        }
        let input = self.pilot_input;
        let s = input.sticks;
        let auto = input.switch == SwitchPosition::Auto;
        let computer = self.board.last_source() == Some(OutputSource::Computer);
        let report = PilotReport {
            pilot_us: [
                surface_to_pulse_us(s.aileron as f32),
                surface_to_pulse_us(s.elevator as f32),
                throttle_to_pulse_us(s.throttle as f32),
                surface_to_pulse_us(s.rudder as f32),
                1500,
                1500,
                1500,
                1500,
            ],
            switch_us: if auto { 1900 } else { 1100 },
            logic_battery_v: battery.avionics_voltage_v as f32,
            servo_battery_v: battery.propulsion_voltage_v as f32,
            status: BoardStatus(if computer {
                BoardStatus::COMPUTER_IN_CONTROL
            } else {
                0
            }),
        };
        let mut frame = [0u8; PILOT_FRAME_LEN];
        let n = encode_pilot_frame(self.board_counter, &report, &mut frame);
        self.board_counter = self.board_counter.wrapping_add(1);
        link.send_to_computer(Device::Servo, frame.get(..n).unwrap_or_default());
        self.stats.board_frames += 1;
        self.garbage(Device::Servo, link);
    }
}

/// The receiver's solution as the sentences will carry it.
pub fn gps_fix(sample: &SimGpsSolution, forced_loss: bool) -> GpsFix {
    let valid = sample.fix == GpsFixType::Fix3d && !forced_loss;
    let utc_ms = (UTC_START_MS + (sample.valid_at_s * 1000.0).round().max(0.0) as u64) % 86_400_000;
    let [vn, ve, vd] = sample.velocity_ned_mps;
    let speed = (vn * vn + ve * ve).sqrt();
    let mut course = ve.atan2(vn);
    if course < 0.0 {
        course += std::f64::consts::TAU;
    }
    let pdop = (sample.hdop * sample.hdop + sample.vdop * sample.vdop).sqrt();
    let horizontal_sd = sample.horizontal_std_m / std::f64::consts::SQRT_2;
    GpsFix {
        utc_time_ms: Some(utc_ms as u32),
        valid,
        quality: Some(if valid {
            FixQuality::Autonomous
        } else {
            FixQuality::NoFix
        }),
        dimension: Some(if valid {
            FixDimension::ThreeD
        } else {
            FixDimension::NoFix
        }),
        satellites: Some(if valid { sample.satellites } else { 0 }),
        latitude_deg: valid.then_some(sample.position.lat_deg),
        longitude_deg: valid.then_some(sample.position.lon_deg),
        altitude_msl_m: valid.then_some(sample.position.alt_msl_m),
        ground_speed_mps: valid.then_some(speed as f32),
        course_rad: valid.then_some(course as f32),
        velocity_ned_mps: if valid {
            [Some(vn as f32), Some(ve as f32), Some(vd as f32)]
        } else {
            [None; 3]
        },
        pdop: valid.then_some(pdop as f32),
        hdop: valid.then_some(sample.hdop as f32),
        vdop: valid.then_some(sample.vdop as f32),
        position_sd_m: if valid {
            [
                Some(horizontal_sd as f32),
                Some(horizontal_sd as f32),
                Some(sample.vertical_std_m as f32),
            ]
        } else {
            [None; 3]
        },
        ..GpsFix::default()
    }
}

fn merge(a: DeviceFaults, b: DeviceFaults) -> DeviceFaults {
    let or3 = |x: [bool; 3], y: [bool; 3]| [x[0] || y[0], x[1] || y[1], x[2] || y[2]];
    DeviceFaults {
        silent: or3(a.silent, b.silent),
        garbage: or3(a.garbage, b.garbage),
        gps_loss: a.gps_loss || b.gps_loss,
        servo_vanished: a.servo_vanished || b.servo_vanished,
    }
}

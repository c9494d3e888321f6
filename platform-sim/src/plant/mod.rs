//! The simulated airplane: a 6-DOF Aerosonde (Beard & McLain, *Small Unmanned Aircraft*) with
//! steady wind and Dryden gusts, ground contact, and IMU, GPS and battery models.
//!
//! Everything runs in plant time, advanced only by [`Plant::step`]; every random source is
//! a ChaCha stream derived from the one seed, so a run is a function of the seed and the
//! commands: same seed and commands, bit-identical trajectory and sensor readings.
//!
//! Types are plain SI data (no wire encoding): the byte protocols are built elsewhere.
//!
//! ```
//! use skyframe_sim::plant::{ActuatorCommands, AircraftParams, InitialState, Plant, WindConfig};
//!
//! let params = AircraftParams::aerosonde();
//! let start = InitialState::on_runway(&params, 0.0);
//! let mut plant = Plant::new(params, start, WindConfig::calm(), 42);
//! let full_throttle = ActuatorCommands { throttle: 1.0, ..Default::default() };
//! let mut fixes = 0;
//! for _ in 0..200 {
//!     plant.step(0.01, &full_throttle); // 10 ms of plant time, in 1 ms RK4 steps
//!     let imu = plant.sample_imu(); // rates (rad/s) and specific force (m/s²), FRD
//!     assert!(imu.specific_force_mps2[0] > 0.0); // pushed forward by the propeller
//!     while let Some(_fix) = plant.sample_gps() {
//!         fixes += 1;
//!     }
//! }
//! let truth = plant.truth();
//! assert!(truth.velocity_ned_mps[0] > 5.0 && truth.on_ground);
//! assert!(fixes >= 15);
//! ```

pub mod dynamics;
pub mod jsbsim;
pub mod math;
pub mod model;
pub mod params;
pub mod rng;
pub mod sensors;
pub mod sixdof;
pub mod trim;
pub mod wind;

#[cfg(test)]
mod tests;

use dynamics::RigidBodyState;
use math::{Quat, Vec3, quat_from_euler, quat_to_rotation};
pub use model::{FlightModel, PlantError, PlantKind};
pub use params::{AircraftParams, GRAVITY_MPS2};
use rng::{NoiseRng, stream};
pub use sensors::{
    BatteryConfig, BatterySample, GeodeticPosition, GpsFixType, SimGpsConfig, SimGpsSolution,
    SimImuConfig, SimImuReading,
};
use sensors::{SimBatteries, SimGpsReceiver, SimImu};
pub use sixdof::SixDofModel;
pub use wind::{DrydenParams, WindConfig};

/// What the autopilot (through the servo board) commands. Surfaces in [−1, 1], throttle and
/// brake in [0, 1], per `conventions.md`: positive aileron rolls right, positive elevator
/// pitches up, positive rudder yaws right (and steers the nose wheel right). Out-of-range values
/// are clamped; non-finite values count as neutral.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ActuatorCommands {
    pub aileron: f64,
    pub elevator: f64,
    pub rudder: f64,
    pub throttle: f64,
    /// Main-wheel brakes.
    pub brake: f64,
}

impl ActuatorCommands {
    /// Clamped to the ranges, with any non-finite value replaced by neutral (0).
    pub fn sanitized(&self) -> Self {
        let surface = |x: f64| {
            if x.is_finite() {
                x.clamp(-1.0, 1.0)
            } else {
                0.0
            }
        };
        let unit = |x: f64| {
            if x.is_finite() {
                x.clamp(0.0, 1.0)
            } else {
                0.0
            }
        };
        Self {
            aileron: surface(self.aileron),
            elevator: surface(self.elevator),
            rudder: surface(self.rudder),
            throttle: unit(self.throttle),
            brake: unit(self.brake),
        }
    }
}

/// Initial conditions in the terms a person sets them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InitialState {
    pub position_ned_m: Vec3,
    /// Ground velocity in NED (m/s).
    pub velocity_ned_mps: Vec3,
    /// 3-2-1 Euler angles (rad).
    pub roll_rad: f64,
    pub pitch_rad: f64,
    pub yaw_rad: f64,
    pub rates_body_radps: Vec3,
}

impl InitialState {
    /// Parked on the runway at the origin, level on its wheels, nose towards `yaw_rad`.
    pub fn on_runway(params: &AircraftParams, yaw_rad: f64) -> Self {
        Self {
            position_ned_m: [0.0, 0.0, -params.ground.rest_height_m(params.mass_kg)],
            velocity_ned_mps: [0.0; 3],
            roll_rad: 0.0,
            pitch_rad: 0.0,
            yaw_rad,
            rates_body_radps: [0.0; 3],
        }
    }

    /// Wings level at `altitude_m` above the field, flying towards `yaw_rad` at `speed_mps`
    /// with zero pitch (not trimmed: see [`trim::trim_level_flight`] for that).
    pub fn in_flight(altitude_m: f64, speed_mps: f64, yaw_rad: f64) -> Self {
        Self {
            position_ned_m: [0.0, 0.0, -altitude_m],
            velocity_ned_mps: [speed_mps * yaw_rad.cos(), speed_mps * yaw_rad.sin(), 0.0],
            roll_rad: 0.0,
            pitch_rad: 0.0,
            yaw_rad,
            rates_body_radps: [0.0; 3],
        }
    }

    fn to_rigid_body(self) -> RigidBodyState {
        let attitude = quat_from_euler(self.roll_rad, self.pitch_rad, self.yaw_rad);
        let r = quat_to_rotation(attitude);
        RigidBodyState {
            position_ned_m: self.position_ned_m,
            velocity_body_mps: math::mat_t_vec(&r, self.velocity_ned_mps),
            attitude,
            rates_body_radps: self.rates_body_radps,
        }
    }
}

/// Ground truth at the current plant time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Truth {
    pub t_s: f64,
    pub position_ned_m: Vec3,
    /// Ground velocity, NED and body axes (m/s).
    pub velocity_ned_mps: Vec3,
    pub velocity_body_mps: Vec3,
    /// Hamilton, scalar first, body → NED.
    pub attitude: Quat,
    pub roll_rad: f64,
    pub pitch_rad: f64,
    pub yaw_rad: f64,
    /// (p, q, r).
    pub rates_body_radps: Vec3,
    /// What a perfect accelerometer at the CG reads (m/s²): (0, 0, −g) level at rest.
    pub specific_force_body_mps2: Vec3,
    pub airspeed_mps: f64,
    pub alpha_rad: f64,
    pub beta_rad: f64,
    /// Total wind (steady + gust), NED (m/s).
    pub wind_ned_mps: Vec3,
    /// Gust alone, body axes (m/s).
    pub gust_body_mps: Vec3,
    pub thrust_n: f64,
    pub motor_speed_radps: f64,
    /// Surface and motor positions (normalised, like the commands; they lag the commands).
    pub actuators: ActuatorCommands,
    /// A landing-gear wheel touches the ground.
    pub on_ground: bool,
    /// Some other part of the airframe touches the ground: a tail or wing-tip strike, or a
    /// crash.
    pub airframe_strike: bool,
    /// Height of the CG above the ground plane (m).
    pub height_above_ground_m: f64,
}

impl Truth {
    /// Everything zero, level, at time zero: a placeholder until a model reports.
    pub fn at_rest() -> Self {
        Self {
            t_s: 0.0,
            position_ned_m: [0.0; 3],
            velocity_ned_mps: [0.0; 3],
            velocity_body_mps: [0.0; 3],
            attitude: [1.0, 0.0, 0.0, 0.0],
            roll_rad: 0.0,
            pitch_rad: 0.0,
            yaw_rad: 0.0,
            rates_body_radps: [0.0; 3],
            specific_force_body_mps2: [0.0, 0.0, -GRAVITY_MPS2],
            airspeed_mps: 0.0,
            alpha_rad: 0.0,
            beta_rad: 0.0,
            wind_ned_mps: [0.0; 3],
            gust_body_mps: [0.0; 3],
            thrust_n: 0.0,
            motor_speed_radps: 0.0,
            actuators: ActuatorCommands::default(),
            on_ground: true,
            airframe_strike: false,
            height_above_ground_m: 0.0,
        }
    }
}

/// The longest RK4 step the plant takes, whatever `PlantConfig::max_step_s` asks for.
pub const MAX_STEP_S: f64 = 0.01;

/// Everything the plant can be configured with.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantConfig {
    pub params: AircraftParams,
    pub wind: WindConfig,
    pub imu: SimImuConfig,
    pub gps: SimGpsConfig,
    pub battery: BatteryConfig,
    /// Longest RK4 step (s); [`Plant::step`] splits a longer `dt` into equal sub-steps.
    pub max_step_s: f64,
    /// Servo response: surfaces follow their commands with this first-order time constant (s);
    /// 0 for instant.
    pub surface_time_constant_s: f64,
    /// Motor spin-up: the effective throttle follows the command with this time constant (s),
    /// standing in for rotor inertia, which the steady-state motor model leaves out.
    pub throttle_time_constant_s: f64,
}

impl Default for PlantConfig {
    fn default() -> Self {
        Self {
            params: AircraftParams::aerosonde(),
            wind: WindConfig::calm(),
            imu: SimImuConfig::default(),
            gps: SimGpsConfig::default(),
            battery: BatteryConfig::default(),
            max_step_s: 0.001,
            surface_time_constant_s: 0.03,
            throttle_time_constant_s: 0.1,
        }
    }
}

/// The sensors on the airplane: IMU, GPS receiver and batteries, each with its own seeded
/// noise stream. They read [`Truth`] alone, so they work the same on any [`FlightModel`].
#[derive(Debug, Clone)]
pub struct SensorSuite {
    imu: SimImu,
    gps: SimGpsReceiver,
    battery: SimBatteries,
}

impl SensorSuite {
    /// The sensors of `config` (its IMU, GPS and battery settings), drawn from `seed`.
    pub fn new(config: &PlantConfig, seed: u64) -> Self {
        Self {
            imu: SimImu::new(config.imu, NoiseRng::new(seed, stream::IMU)),
            gps: SimGpsReceiver::new(config.gps, NoiseRng::new(seed, stream::GPS)),
            battery: SimBatteries::new(config.battery, NoiseRng::new(seed, stream::BATTERY)),
        }
    }

    /// After `h_s` of flight ending at `truth`: the GPS sees the new position, the batteries
    /// discharge for the throttle, the motor's current and the servos' effort.
    fn after_step(&mut self, h_s: f64, truth: &Truth, motor_current_a: f64) {
        self.imu
            .integrate(h_s, truth.rates_body_radps, truth.specific_force_body_mps2);
        self.gps
            .update(truth.t_s, truth.position_ned_m, truth.velocity_ned_mps);
        let a = truth.actuators;
        // The motor is taken to run, and shake the IMU, above 5 % throttle.
        self.imu.set_motor_running(a.throttle > 0.05);
        let effort = a.aileron.abs() + a.elevator.abs() + a.rudder.abs();
        self.battery.step(h_s, a.throttle, motor_current_a, effort);
    }
}

/// The simulated airplane: a flight model (by default the built-in [`SixDofModel`]) and the
/// sensors that read its truth.
#[derive(Debug, Clone)]
pub struct Plant<M = SixDofModel> {
    config: PlantConfig,
    model: M,
    sensors: SensorSuite,
}

impl Plant<SixDofModel> {
    /// A plant with default sensors (MEMS IMU, 10 Hz GPS, Aerosonde batteries), 1 ms RK4.
    pub fn new(params: AircraftParams, initial: InitialState, wind: WindConfig, seed: u64) -> Self {
        Self::with_config(
            PlantConfig {
                params,
                wind,
                ..PlantConfig::default()
            },
            initial,
            seed,
        )
    }

    /// The built-in model of `config` at `initial`, every noise stream drawn from `seed`.
    pub fn with_config(config: PlantConfig, initial: InitialState, seed: u64) -> Self {
        let model = SixDofModel::new(config.clone(), initial, seed);
        Self::with_model(config, model, seed)
    }

    pub fn rigid_body_state(&self) -> &dynamics::RigidBodyState {
        self.model.rigid_body_state()
    }

    /// The commands last applied (sanitised).
    pub fn commands(&self) -> &ActuatorCommands {
        self.model.commands()
    }

    /// Where the surfaces and the motor are now, normalised like the commands.
    pub fn actuators(&self) -> ActuatorCommands {
        self.model.actuators()
    }

    /// Advances the plant by `dt_s` (rounded to whole ns) with `commands` held, in RK4 sub-steps
    /// of at most `max_step_s`. Wind, GPS and batteries advance once per sub-step.
    pub fn step(&mut self, dt_s: f64, commands: &ActuatorCommands) {
        // The built-in model cannot fail.
        let _ = self.try_step(dt_s, commands);
    }
}

impl<M: FlightModel> Plant<M> {
    /// `model` with the sensors of `config` (IMU, GPS, batteries), drawn from `seed`.
    pub fn with_model(config: PlantConfig, model: M, seed: u64) -> Self {
        Self {
            sensors: SensorSuite::new(&config, seed),
            config,
            model,
        }
    }

    /// The same plant with its model behind a `Box<dyn FlightModel>` (the world holds any).
    pub fn boxed(self) -> Plant<Box<dyn FlightModel>>
    where
        M: 'static,
    {
        Plant {
            config: self.config,
            model: Box::new(self.model),
            sensors: self.sensors,
        }
    }

    pub fn config(&self) -> &PlantConfig {
        &self.config
    }

    pub fn params(&self) -> &AircraftParams {
        &self.config.params
    }

    pub fn model(&self) -> &M {
        &self.model
    }

    pub fn time_ns(&self) -> u64 {
        self.model.time_ns()
    }

    pub fn time_s(&self) -> f64 {
        self.time_ns() as f64 * 1e-9
    }

    /// Advances the plant by `dt_s` (rounded to whole ns) with `commands` held, in sub-steps
    /// of at most `max_step_s`; the GPS and batteries advance once per sub-step. A model that
    /// can no longer fly (JSBSim's process gone) says why.
    pub fn try_step(&mut self, dt_s: f64, commands: &ActuatorCommands) -> Result<(), PlantError> {
        let commands = commands.sanitized();
        for h_ns in sixdof::substeps_ns(dt_s, self.config.max_step_s) {
            let h = h_ns as f64 * 1e-9;
            self.model.step(h, &commands)?;
            let truth = self.model.truth();
            let current = self.model.motor_current_a();
            self.sensors.after_step(h, &truth, current);
        }
        Ok(())
    }

    /// Ground truth now.
    pub fn truth(&self) -> Truth {
        self.model.truth()
    }

    /// An IMU reading now.
    pub fn sample_imu(&mut self) -> SimImuReading {
        let t = self.time_s();
        let truth = self.model.truth();
        self.sensors
            .imu
            .sample(t, truth.rates_body_radps, truth.specific_force_body_mps2)
    }

    /// The oldest GPS solution delivered by now, if any; call until `None` to drain.
    pub fn sample_gps(&mut self) -> Option<SimGpsSolution> {
        let t = self.time_s();
        self.sensors.gps.take(t)
    }

    /// A reading of both battery packs now.
    pub fn sample_battery(&mut self) -> BatterySample {
        let t = self.time_s();
        self.sensors.battery.sample(t)
    }

    /// True battery state (charge, polarisation, current, voltage) of (avionics, propulsion).
    pub fn battery_truth(&self) -> (sensors::PackState, sensors::PackState) {
        (
            *self.sensors.battery.avionics(),
            *self.sensors.battery.propulsion(),
        )
    }

    /// The IMU's true biases (gyro rad/s, accel m/s²), for checking estimators.
    pub fn imu_biases(&self) -> (Vec3, Vec3) {
        self.sensors.imu.biases()
    }
}

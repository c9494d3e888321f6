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
pub mod math;
pub mod params;
pub mod rng;
pub mod sensors;
pub mod trim;
pub mod wind;

#[cfg(test)]
mod tests;

use dynamics::{AirMass, ControlInputs, ForcesAndMoments, RigidBodyState};
use math::{Quat, Vec3, add, mat_vec, quat_from_euler, quat_to_euler, quat_to_rotation, scale};
pub use params::{AircraftParams, GRAVITY_MPS2};
use rng::{NoiseRng, stream};
pub use sensors::{
    BatteryConfig, BatterySample, GeodeticPosition, GpsConfig, GpsFixType, GpsSample, ImuConfig,
    ImuSample,
};
use sensors::{BatteryModel, GpsModel, ImuModel};
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

/// The longest RK4 step the plant takes, whatever `PlantConfig::max_step_s` asks for.
pub const MAX_STEP_S: f64 = 0.01;

/// Everything the plant can be configured with.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantConfig {
    pub params: AircraftParams,
    pub wind: WindConfig,
    pub imu: ImuConfig,
    pub gps: GpsConfig,
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
            imu: ImuConfig::default(),
            gps: GpsConfig::default(),
            battery: BatteryConfig::default(),
            max_step_s: 0.001,
            surface_time_constant_s: 0.03,
            throttle_time_constant_s: 0.1,
        }
    }
}

/// The simulated airplane.
#[derive(Debug, Clone)]
pub struct Plant {
    config: PlantConfig,
    state: RigidBodyState,
    /// Plant time (ns), exact: sub-steps are whole nanoseconds.
    time_ns: u64,
    commands: ActuatorCommands,
    /// Where the surfaces and the motor actually are (normalised); `None` until the first
    /// command, which they take at once, so a run can start trimmed.
    actuators: Option<ActuatorCommands>,
    wind: wind::WindModel,
    imu: ImuModel,
    gps: GpsModel,
    battery: BatteryModel,
    /// Where each ground contact is held by static friction.
    anchors: dynamics::ContactAnchors,
    /// Forces at the current state, for the truth and the IMU.
    forces: ForcesAndMoments,
}

impl Plant {
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

    pub fn with_config(config: PlantConfig, initial: InitialState, seed: u64) -> Self {
        let state = initial.to_rigid_body();
        let mut plant = Self {
            wind: wind::WindModel::new(config.wind, NoiseRng::new(seed, stream::WIND)),
            imu: ImuModel::new(config.imu, NoiseRng::new(seed, stream::IMU)),
            gps: GpsModel::new(config.gps, NoiseRng::new(seed, stream::GPS)),
            battery: BatteryModel::new(config.battery, NoiseRng::new(seed, stream::BATTERY)),
            config,
            state,
            time_ns: 0,
            commands: ActuatorCommands::default(),
            actuators: None,
            anchors: Vec::new(),
            forces: ForcesAndMoments::default(),
        };
        plant.update_anchors();
        plant.forces = plant.current_forces();
        plant
    }

    pub fn config(&self) -> &PlantConfig {
        &self.config
    }

    pub fn params(&self) -> &AircraftParams {
        &self.config.params
    }

    pub fn time_ns(&self) -> u64 {
        self.time_ns
    }

    pub fn time_s(&self) -> f64 {
        self.time_ns as f64 * 1e-9
    }

    pub fn rigid_body_state(&self) -> &RigidBodyState {
        &self.state
    }

    /// The commands last applied (sanitised).
    pub fn commands(&self) -> &ActuatorCommands {
        &self.commands
    }

    /// Where the surfaces and the motor are now, normalised like the commands.
    pub fn actuators(&self) -> ActuatorCommands {
        self.actuators.unwrap_or(self.commands)
    }

    /// Moves the actuators towards the commands over `h` seconds (exact first-order lag).
    fn move_actuators(&mut self, h: f64) {
        let target = self.commands;
        let Some(a) = self.actuators.as_mut() else {
            self.actuators = Some(target);
            return;
        };
        let follow = |tau: f64| {
            if tau > 0.0 {
                1.0 - (-h / tau).exp()
            } else {
                1.0
            }
        };
        let ks = follow(self.config.surface_time_constant_s);
        let kt = follow(self.config.throttle_time_constant_s);
        a.aileron += ks * (target.aileron - a.aileron);
        a.elevator += ks * (target.elevator - a.elevator);
        a.rudder += ks * (target.rudder - a.rudder);
        a.throttle += kt * (target.throttle - a.throttle);
        a.brake = target.brake;
    }

    fn air_mass(&self) -> AirMass {
        AirMass {
            steady_wind_ned_mps: self.wind.steady_ned_mps(),
            gust_body_mps: self.wind.gust_body_mps(),
        }
    }

    fn control_inputs(&self) -> ControlInputs {
        let c = self.actuators();
        ControlInputs::from_commands(
            &self.config.params,
            c.aileron,
            c.elevator,
            c.rudder,
            c.throttle,
            c.brake,
        )
    }

    fn current_forces(&self) -> ForcesAndMoments {
        dynamics::forces_and_moments(
            &self.config.params,
            &self.state,
            &self.control_inputs(),
            &self.air_mass(),
            &self.anchors,
        )
    }

    fn update_anchors(&mut self) {
        let u = self.control_inputs();
        dynamics::update_contact_anchors(&self.config.params, &self.state, &u, &mut self.anchors);
    }

    /// Advances the plant by `dt_s` (rounded to whole ns) with `commands` held, in RK4 sub-steps
    /// of at most `max_step_s`. Wind, GPS and batteries advance once per sub-step.
    pub fn step(&mut self, dt_s: f64, commands: &ActuatorCommands) {
        self.commands = commands.sanitized();
        let dt_ns = (dt_s.max(0.0) * 1e9).round() as u64;
        if dt_ns == 0 {
            return;
        }
        let max_step_s = self.config.max_step_s.min(MAX_STEP_S);
        let max_ns = ((max_step_s * 1e9).round() as u64).max(1);
        let substeps = dt_ns.div_ceil(max_ns);
        let mut done_ns = 0;
        for k in 0..substeps {
            // Spread the remainder so the sub-steps add up to exactly dt.
            let end_ns = dt_ns * (k + 1) / substeps;
            let h_ns = end_ns - done_ns;
            done_ns = end_ns;
            let h = h_ns as f64 * 1e-9;
            self.move_actuators(h);
            let u = self.control_inputs();
            let a = self.actuators();
            let effort = a.aileron.abs() + a.elevator.abs() + a.rudder.abs();
            self.wind.step(h, self.forces.air.airspeed_mps);
            self.state = dynamics::rk4_step(
                &self.config.params,
                &self.state,
                &u,
                &self.air_mass(),
                &self.anchors,
                h,
            );
            self.update_anchors();
            self.time_ns += h_ns;
            self.forces = self.current_forces();
            let t = self.time_s();
            let r = quat_to_rotation(self.state.attitude);
            let v_ned = mat_vec(&r, self.state.velocity_body_mps);
            self.gps.update(t, self.state.position_ned_m, v_ned);
            self.battery.step(
                h,
                u.throttle,
                self.forces.propulsion.motor_current_a,
                effort,
            );
        }
    }

    /// Ground truth now.
    pub fn truth(&self) -> Truth {
        let s = &self.state;
        let r = quat_to_rotation(s.attitude);
        let [roll, pitch, yaw] = quat_to_euler(s.attitude);
        let gust = self.wind.gust_body_mps();
        let f = &self.forces;
        Truth {
            t_s: self.time_s(),
            position_ned_m: s.position_ned_m,
            velocity_ned_mps: mat_vec(&r, s.velocity_body_mps),
            velocity_body_mps: s.velocity_body_mps,
            attitude: s.attitude,
            roll_rad: roll,
            pitch_rad: pitch,
            yaw_rad: yaw,
            rates_body_radps: s.rates_body_radps,
            specific_force_body_mps2: scale(
                f.contact_and_aero_force_body_n,
                1.0 / self.config.params.mass_kg,
            ),
            airspeed_mps: f.air.airspeed_mps,
            alpha_rad: f.air.alpha_rad,
            beta_rad: f.air.beta_rad,
            wind_ned_mps: add(self.wind.steady_ned_mps(), mat_vec(&r, gust)),
            gust_body_mps: gust,
            thrust_n: f.propulsion.thrust_n,
            motor_speed_radps: f.propulsion.motor_speed_radps,
            actuators: self.actuators(),
            on_ground: f.wheels_on_ground,
            airframe_strike: f.airframe_on_ground,
            height_above_ground_m: -s.position_ned_m[2],
        }
    }

    /// An IMU reading now.
    pub fn sample_imu(&mut self) -> ImuSample {
        let t = self.time_s();
        let specific_force = scale(
            self.forces.contact_and_aero_force_body_n,
            1.0 / self.config.params.mass_kg,
        );
        self.imu
            .sample(t, self.state.rates_body_radps, specific_force)
    }

    /// The oldest GPS solution delivered by now, if any; call until `None` to drain.
    pub fn sample_gps(&mut self) -> Option<GpsSample> {
        let t = self.time_s();
        self.gps.take(t)
    }

    /// A reading of both battery packs now.
    pub fn sample_battery(&mut self) -> BatterySample {
        let t = self.time_s();
        self.battery.sample(t)
    }

    /// True battery state (charge, polarisation, current, voltage) of (avionics, propulsion).
    pub fn battery_truth(&self) -> (sensors::PackState, sensors::PackState) {
        (*self.battery.avionics(), *self.battery.propulsion())
    }

    /// The IMU's true biases (gyro rad/s, accel m/s²), for checking estimators.
    pub fn imu_biases(&self) -> (Vec3, Vec3) {
        self.imu.biases()
    }
}

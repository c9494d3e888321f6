//! The built-in flight model: our 6-DOF Aerosonde ([`dynamics`](super::dynamics)) with servo
//! and motor lags, steady wind and Dryden gusts, and ground contact, in RK4 sub-steps.

use super::dynamics::{self, AirMass, ControlInputs, ForcesAndMoments, RigidBodyState};
use super::math::{add, mat_vec, quat_to_euler, quat_to_rotation, scale};
use super::model::{FlightModel, PlantError};
use super::rng::{NoiseRng, stream};
use super::{ActuatorCommands, InitialState, MAX_STEP_S, PlantConfig, Truth, wind};

/// The built-in 6-DOF model.
#[derive(Debug, Clone)]
pub struct SixDofModel {
    config: PlantConfig,
    state: RigidBodyState,
    /// Plant time (ns), exact: sub-steps are whole nanoseconds.
    time_ns: u64,
    commands: ActuatorCommands,
    /// Where the surfaces and the motor actually are (normalised); `None` until the first
    /// command, which they take at once, so a run can start trimmed.
    actuators: Option<ActuatorCommands>,
    wind: wind::WindModel,
    /// Where each ground contact is held by static friction.
    anchors: dynamics::ContactAnchors,
    /// Forces at the current state, for the truth and the IMU.
    forces: ForcesAndMoments,
}

impl SixDofModel {
    /// The model of `config` (its airframe, wind, step and lags) at `initial`; the gusts are
    /// drawn from `seed`'s wind stream.
    pub fn new(config: PlantConfig, initial: InitialState, seed: u64) -> Self {
        let state = initial.to_rigid_body();
        let mut model = Self {
            wind: wind::WindModel::new(config.wind, NoiseRng::new(seed, stream::WIND)),
            config,
            state,
            time_ns: 0,
            commands: ActuatorCommands::default(),
            actuators: None,
            anchors: Vec::new(),
            forces: ForcesAndMoments::default(),
        };
        model.update_anchors();
        model.forces = model.current_forces();
        model
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

    /// One RK4 step of `h_ns`.
    fn substep(&mut self, h_ns: u64) {
        let h = h_ns as f64 * 1e-9;
        self.move_actuators(h);
        let u = self.control_inputs();
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
    }
}

/// `dt_s` in whole ns, split into equal sub-steps of at most `max_step_s` (and
/// [`MAX_STEP_S`]): the sub-steps' lengths in ns, which add up to exactly `dt`.
pub(super) fn substeps_ns(dt_s: f64, max_step_s: f64) -> impl Iterator<Item = u64> {
    let dt_ns = (dt_s.max(0.0) * 1e9).round() as u64;
    let max_ns = ((max_step_s.min(MAX_STEP_S) * 1e9).round() as u64).max(1);
    let substeps = dt_ns.div_ceil(max_ns);
    // Spread the remainder so the sub-steps add up to exactly dt.
    (0..substeps).map(move |k| dt_ns * (k + 1) / substeps - dt_ns * k / substeps)
}

impl FlightModel for SixDofModel {
    fn step(&mut self, dt_s: f64, commands: &ActuatorCommands) -> Result<(), PlantError> {
        self.commands = commands.sanitized();
        for h_ns in substeps_ns(dt_s, self.config.max_step_s) {
            self.substep(h_ns);
        }
        Ok(())
    }

    fn truth(&self) -> Truth {
        let s = &self.state;
        let r = quat_to_rotation(s.attitude);
        let [roll, pitch, yaw] = quat_to_euler(s.attitude);
        let gust = self.wind.gust_body_mps();
        let f = &self.forces;
        Truth {
            t_s: self.time_ns as f64 * 1e-9,
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

    fn time_ns(&self) -> u64 {
        self.time_ns
    }

    fn motor_current_a(&self) -> f64 {
        self.forces.propulsion.motor_current_a
    }
}

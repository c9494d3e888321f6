//! A scripted human pilot: the simulator's stand-in for the person holding the transmitter.
//!
//! The pilot looks at the airplane (the plant's [`Truth`], seen a reaction time late) and moves
//! the sticks to fly one [`Manoeuvre`] at a time: take-off, climbs, turns, holds, an aileron
//! roll, a loop, an approach and a landing, or raw stick values. Like a person it moves the
//! sticks at a limited rate and reacts late, so it is a plausible pilot rather than a perfect
//! autopilot. It is deterministic: the same truths in give the same sticks out.
//!
//! A manoeuvre that ends by itself (a take-off reaching its altitude, a turn reaching its
//! heading, a roll or loop completed) leaves the pilot holding altitude, heading and airspeed
//! until the next one is given.

use crate::plant::math::{Mat3, Vec3, cross, dot, quat_to_rotation};
use crate::plant::trim::trim_level_flight;
use crate::plant::{ActuatorCommands, AircraftParams, Truth};
use std::collections::VecDeque;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// The transmitter's auto/manual switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SwitchPosition {
    #[default]
    Manual,
    Auto,
}

/// Which way a turn or roll goes, seen from behind the airplane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    Left,
    Right,
}

impl Direction {
    fn sign(self) -> f64 {
        match self {
            Direction::Left => -1.0,
            Direction::Right => 1.0,
        }
    }
}

/// A runway as the pilot uses it: the touchdown point and the landing direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Runway {
    /// Touchdown point (north, east) in the local NED frame (m).
    pub touchdown_ne_m: [f64; 2],
    /// Landing direction (rad, 0 = north, clockwise).
    pub heading_rad: f64,
}

impl Runway {
    /// The point `along_m` past the touchdown point and `cross_m` right of the centreline,
    /// (north, east).
    pub fn point_at(&self, along_m: f64, cross_m: f64) -> [f64; 2] {
        let (s, c) = self.heading_rad.sin_cos();
        [
            self.touchdown_ne_m[0] + along_m * c - cross_m * s,
            self.touchdown_ne_m[1] + along_m * s + cross_m * c,
        ]
    }

    /// (along, cross) of a point: metres past the touchdown point along the landing direction,
    /// and metres right of the centreline.
    pub fn along_cross_m(&self, north_m: f64, east_m: f64) -> (f64, f64) {
        let (dn, de) = (
            north_m - self.touchdown_ne_m[0],
            east_m - self.touchdown_ne_m[1],
        );
        let (s, c) = self.heading_rad.sin_cos();
        (dn * c + de * s, -dn * s + de * c)
    }
}

/// One thing the pilot is asked to fly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Manoeuvre {
    /// Full power along the runway the airplane stands on, rudder on the centreline, rotate at
    /// `rotate_speed_mps`, climb out at `climb_pitch_rad` up to `climb_to_m`, then hold.
    Takeoff {
        rotate_speed_mps: f64,
        climb_pitch_rad: f64,
        climb_to_m: f64,
    },
    /// Climb or descend to `altitude_m` (above the field) on the present heading, then hold.
    Climb {
        altitude_m: f64,
        airspeed_mps: Option<f64>,
    },
    /// A coordinated turn to `heading_rad`, banked at most `max_bank_rad`, the short way round
    /// unless `direction` says otherwise.
    Turn {
        heading_rad: f64,
        max_bank_rad: f64,
        direction: Option<Direction>,
    },
    /// Hold altitude, heading and airspeed; each `None` keeps the present value.
    Hold {
        altitude_m: Option<f64>,
        heading_rad: Option<f64>,
        airspeed_mps: Option<f64>,
    },
    /// An aileron roll: a pull to a nose-up attitude, full aileron through 360°, recover.
    Roll { direction: Direction },
    /// A loop: dive for speed, pull through 360° in the vertical plane, recover.
    Loop,
    /// Join the runway's final approach (downwind, base, final as needed), then [`Manoeuvre::Land`].
    Approach {
        runway: Runway,
        glide_slope_rad: f64,
        final_length_m: f64,
    },
    /// Follow the glide path to the touchdown point, flare with power, touch down, brake to a
    /// stop.
    Land {
        runway: Runway,
        glide_slope_rad: f64,
    },
    /// Raw stick values for `duration_s`, then hold (airborne) or idle with brakes (on the
    /// ground).
    Sticks {
        sticks: ActuatorCommands,
        duration_s: f64,
    },
}

impl Manoeuvre {
    /// The default take-off: rotate at 18 m/s, climb at 10° to 50 m.
    pub fn takeoff() -> Self {
        Manoeuvre::Takeoff {
            rotate_speed_mps: 18.0,
            climb_pitch_rad: 10f64.to_radians(),
            climb_to_m: 50.0,
        }
    }
}

/// How the pilot flies: speeds and human limits.
#[derive(Debug, Clone, PartialEq)]
pub struct PilotConfig {
    /// Seconds between looking at the airplane and the sticks moving.
    pub reaction_delay_s: f64,
    /// How fast the surface sticks move (full scale per second).
    pub surface_stick_rate_per_s: f64,
    /// How fast the throttle moves (full scale per second).
    pub throttle_rate_per_s: f64,
    pub cruise_airspeed_mps: f64,
    pub approach_airspeed_mps: f64,
    /// Bank used to hold a heading or line up (rad).
    pub max_bank_rad: f64,
    /// Pitch limits in normal flight (rad).
    pub max_climb_pitch_rad: f64,
    pub max_dive_pitch_rad: f64,
    /// Below this the pilot lowers the nose whatever else it wants (m/s).
    pub min_airspeed_mps: f64,
    /// Airspeed to build up before a loop (m/s).
    pub loop_entry_airspeed_mps: f64,
}

impl Default for PilotConfig {
    fn default() -> Self {
        Self {
            reaction_delay_s: 0.1,
            surface_stick_rate_per_s: 5.0,
            throttle_rate_per_s: 2.0,
            cruise_airspeed_mps: 23.0,
            approach_airspeed_mps: 20.0,
            max_bank_rad: 30f64.to_radians(),
            max_climb_pitch_rad: 15f64.to_radians(),
            max_dive_pitch_rad: -12f64.to_radians(),
            min_airspeed_mps: 18.0,
            loop_entry_airspeed_mps: 32.0,
        }
    }
}

/// Where the pilot is inside a manoeuvre.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    /// Altitude, heading and airspeed held (also the end of every finished manoeuvre).
    Holding,
    TakeoffRoll {
        runway: Runway,
        rotate_speed_mps: f64,
        climb_pitch_rad: f64,
        climb_to_m: f64,
    },
    Climbing,
    Turning {
        direction: Option<Direction>,
        max_bank_rad: f64,
    },
    RollEntry {
        direction: Direction,
    },
    Rolling {
        direction: Direction,
        rolled_rad: f64,
        last_roll_rad: f64,
    },
    LoopEntry {
        wing_axis_ned: Vec3,
        since_s: f64,
    },
    LoopPull {
        wing_axis_ned: Vec3,
        pitched_rad: f64,
        since_s: f64,
    },
    Downwind {
        runway: Runway,
        glide_slope_rad: f64,
        final_length_m: f64,
        side: f64,
    },
    Base {
        runway: Runway,
        glide_slope_rad: f64,
        final_length_m: f64,
        side: f64,
    },
    Final {
        runway: Runway,
        glide_slope_rad: f64,
    },
    Rollout {
        runway: Runway,
    },
    Sticks {
        sticks: ActuatorCommands,
        until_s: f64,
    },
    /// Stopped on the ground: throttle closed, brakes on.
    Parked,
}

/// The scripted pilot. Call [`Pilot::update`] at a steady rate (every 10–20 ms) with the
/// present truth; give manoeuvres with [`Pilot::fly`] and the switch with [`Pilot::set_switch`].
#[derive(Debug, Clone)]
pub struct Pilot {
    config: PilotConfig,
    rest_height_m: f64,
    /// Trim at the cruise airspeed: the pilot knows roughly where the sticks sit.
    trim: ActuatorCommands,
    trim_pitch_rad: f64,
    /// What the pilot has seen, oldest first, for the reaction delay.
    seen: VecDeque<Truth>,
    last_update_s: Option<f64>,
    sticks: ActuatorCommands,
    switch: SwitchPosition,
    phase: Phase,
    /// Held targets.
    altitude_m: f64,
    heading_rad: f64,
    airspeed_mps: f64,
    /// Slow throttle correction, as a pilot re-trims power for the airspeed it wants.
    throttle_trim: f64,
    /// A manoeuvre given before the first update, started on the first truth seen.
    pending: Option<Manoeuvre>,
}

/// Wraps an angle to (−π, π].
pub fn wrap_pi(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w <= -PI { w + TAU } else { w }
}

const ROLLOUT_ELEVATOR: f64 = 0.5;
const ROLLOUT_BRAKE: f64 = 0.6;

/// How far to the side of the runway the pilot flies the downwind leg (m): a few turn radii.
const DOWNWIND_OFFSET_M: f64 = 350.0;

/// Bearing (rad, 0 = north) from the airplane to a (north, east) point.
fn bearing_to(t: &Truth, point_ne_m: [f64; 2]) -> f64 {
    (point_ne_m[1] - t.position_ned_m[1]).atan2(point_ne_m[0] - t.position_ned_m[0])
}

fn rate_limit(from: f64, to: f64, max_step: f64) -> f64 {
    from + (to - from).clamp(-max_step, max_step)
}

fn column(r: &Mat3, i: usize) -> Vec3 {
    [r[0][i], r[1][i], r[2][i]]
}

impl Pilot {
    /// Flies from `trim` (commands for level flight at `cruise_airspeed_mps`, pitch
    /// `trim_pitch_rad`) instead of the Aerosonde's: another airplane's trim (JSBSim's).
    /// The speeds the pilot keeps scale with the cruise speed.
    pub fn retrim(
        &mut self,
        trim: ActuatorCommands,
        trim_pitch_rad: f64,
        cruise_airspeed_mps: f64,
    ) {
        let k = cruise_airspeed_mps / self.config.cruise_airspeed_mps;
        self.config.cruise_airspeed_mps = cruise_airspeed_mps;
        self.config.approach_airspeed_mps *= k;
        self.config.min_airspeed_mps *= k;
        self.config.loop_entry_airspeed_mps *= k;
        self.airspeed_mps = cruise_airspeed_mps;
        self.trim = trim;
        self.trim_pitch_rad = trim_pitch_rad;
    }

    pub fn new(params: &AircraftParams, config: PilotConfig) -> Self {
        // A pilot who cannot trim at cruise (a broken airframe model) still flies, badly, with
        // the Aerosonde's known trim.
        let (trim, trim_pitch_rad) =
            match trim_level_flight(params, config.cruise_airspeed_mps, 100.0, 0.0) {
                Ok(t) => (t.commands, t.pitch_rad),
                Err(_) => (
                    ActuatorCommands {
                        elevator: 0.28,
                        throttle: 0.75,
                        ..Default::default()
                    },
                    0.03,
                ),
            };
        Self {
            airspeed_mps: config.cruise_airspeed_mps,
            config,
            rest_height_m: params.ground.rest_height_m(params.mass_kg),
            trim,
            trim_pitch_rad,
            seen: VecDeque::new(),
            last_update_s: None,
            sticks: ActuatorCommands::default(),
            switch: SwitchPosition::Manual,
            phase: Phase::Parked,
            altitude_m: 0.0,
            heading_rad: 0.0,
            throttle_trim: 0.0,
            pending: None,
        }
    }

    pub fn switch(&self) -> SwitchPosition {
        self.switch
    }

    pub fn set_switch(&mut self, switch: SwitchPosition) {
        self.switch = switch;
    }

    /// The sticks as they are now.
    pub fn sticks(&self) -> ActuatorCommands {
        self.sticks
    }

    /// True when the last manoeuvre has ended and the pilot is just holding (or parked).
    pub fn is_idle(&self) -> bool {
        matches!(self.phase, Phase::Holding | Phase::Parked)
    }

    /// True once a landing has ended with the airplane stopped.
    pub fn is_parked(&self) -> bool {
        matches!(self.phase, Phase::Parked)
    }

    /// A short name of what the pilot is doing, for logs and tests.
    pub fn phase_name(&self) -> &'static str {
        match self.phase {
            Phase::Holding => "hold",
            Phase::TakeoffRoll { .. } => "takeoff",
            Phase::Climbing => "climb",
            Phase::Turning { .. } => "turn",
            Phase::RollEntry { .. } | Phase::Rolling { .. } => "roll",
            Phase::LoopEntry { .. } | Phase::LoopPull { .. } => "loop",
            Phase::Downwind { .. } => "downwind",
            Phase::Base { .. } => "base",
            Phase::Final { .. } => "final",
            Phase::Rollout { .. } => "rollout",
            Phase::Sticks { .. } => "sticks",
            Phase::Parked => "parked",
        }
    }

    /// Starts flying `manoeuvre` (from what the pilot last saw).
    pub fn fly(&mut self, manoeuvre: Manoeuvre) {
        match self.seen.back().copied() {
            Some(t) => self.start(manoeuvre, &t),
            None => self.pending = Some(manoeuvre),
        }
    }

    fn start(&mut self, manoeuvre: Manoeuvre, t: &Truth) {
        let height = t.height_above_ground_m;
        self.phase = match manoeuvre {
            Manoeuvre::Takeoff {
                rotate_speed_mps,
                climb_pitch_rad,
                climb_to_m,
            } => {
                self.heading_rad = t.yaw_rad;
                self.altitude_m = climb_to_m;
                self.airspeed_mps = self.config.cruise_airspeed_mps;
                Phase::TakeoffRoll {
                    runway: Runway {
                        touchdown_ne_m: [t.position_ned_m[0], t.position_ned_m[1]],
                        heading_rad: t.yaw_rad,
                    },
                    rotate_speed_mps,
                    climb_pitch_rad,
                    climb_to_m,
                }
            }
            Manoeuvre::Climb {
                altitude_m,
                airspeed_mps,
            } => {
                self.altitude_m = altitude_m;
                if let Some(v) = airspeed_mps {
                    self.airspeed_mps = v;
                }
                Phase::Climbing
            }
            Manoeuvre::Turn {
                heading_rad,
                max_bank_rad,
                direction,
            } => {
                self.heading_rad = wrap_pi(heading_rad);
                Phase::Turning {
                    direction,
                    max_bank_rad,
                }
            }
            Manoeuvre::Hold {
                altitude_m,
                heading_rad,
                airspeed_mps,
            } => {
                self.altitude_m = altitude_m.unwrap_or(height);
                self.heading_rad = wrap_pi(heading_rad.unwrap_or(t.yaw_rad));
                if let Some(v) = airspeed_mps {
                    self.airspeed_mps = v;
                }
                Phase::Holding
            }
            Manoeuvre::Roll { direction } => {
                self.altitude_m = height;
                self.heading_rad = t.yaw_rad;
                Phase::RollEntry { direction }
            }
            Manoeuvre::Loop => {
                self.altitude_m = height;
                self.heading_rad = t.yaw_rad;
                let (s, c) = t.yaw_rad.sin_cos();
                Phase::LoopEntry {
                    wing_axis_ned: [-s, c, 0.0],
                    since_s: t.t_s,
                }
            }
            Manoeuvre::Approach {
                runway,
                glide_slope_rad,
                final_length_m,
            } => {
                let (along, cross) = runway.along_cross_m(t.position_ned_m[0], t.position_ned_m[1]);
                let heading_error = wrap_pi(t.yaw_rad - runway.heading_rad).abs();
                let side = if cross >= 0.0 { 1.0 } else { -1.0 };
                self.airspeed_mps = self.config.approach_airspeed_mps;
                if heading_error < FRAC_PI_2 && along < -0.4 * final_length_m {
                    Phase::Final {
                        runway,
                        glide_slope_rad,
                    }
                } else if along < -final_length_m {
                    self.altitude_m = final_length_m * glide_slope_rad.tan();
                    Phase::Base {
                        runway,
                        glide_slope_rad,
                        final_length_m,
                        side,
                    }
                } else {
                    // Circuit height on the downwind leg (at most 100 m, at least the gate's
                    // height), down to the gate's on base.
                    let gate_height = final_length_m * glide_slope_rad.tan();
                    self.altitude_m = t.height_above_ground_m.min(100.0).max(gate_height);
                    Phase::Downwind {
                        runway,
                        glide_slope_rad,
                        final_length_m,
                        side,
                    }
                }
            }
            Manoeuvre::Land {
                runway,
                glide_slope_rad,
            } => {
                self.airspeed_mps = self.config.approach_airspeed_mps;
                Phase::Final {
                    runway,
                    glide_slope_rad,
                }
            }
            Manoeuvre::Sticks { sticks, duration_s } => Phase::Sticks {
                sticks: sticks.sanitized(),
                until_s: t.t_s + duration_s.max(0.0),
            },
        };
    }

    /// Looks at the airplane and moves the sticks; returns where they are now.
    pub fn update(&mut self, truth: &Truth) -> ActuatorCommands {
        let dt = match self.last_update_s {
            Some(last) => (truth.t_s - last).max(0.0),
            None => 0.0,
        };
        self.last_update_s = Some(truth.t_s);
        self.seen.push_back(*truth);
        // Keep the newest truth at least a reaction time old (and nothing older).
        while self.seen.len() > 1
            && self
                .seen
                .get(1)
                .is_some_and(|t| t.t_s <= truth.t_s - self.config.reaction_delay_s)
        {
            self.seen.pop_front();
        }
        let Some(seen) = self.seen.front().copied() else {
            return self.sticks;
        };
        if let Some(m) = self.pending.take() {
            self.start(m, &seen);
        }
        let wanted = self.decide(&seen, dt);
        let s = self.config.surface_stick_rate_per_s * dt;
        let th = self.config.throttle_rate_per_s * dt;
        let first = dt == 0.0;
        let limited = |from: f64, to: f64, step: f64| {
            if first {
                to
            } else {
                rate_limit(from, to, step)
            }
        };
        let wanted = wanted.sanitized();
        self.sticks = ActuatorCommands {
            aileron: limited(self.sticks.aileron, wanted.aileron, s),
            elevator: limited(self.sticks.elevator, wanted.elevator, s),
            rudder: limited(self.sticks.rudder, wanted.rudder, s),
            throttle: limited(self.sticks.throttle, wanted.throttle, th),
            // Brakes are a switch on the transmitter: instant.
            brake: wanted.brake,
        };
        self.sticks
    }

    fn wheel_height_m(&self, t: &Truth) -> f64 {
        t.height_above_ground_m - self.rest_height_m
    }

    /// Aileron to reach `roll_cmd` (rad).
    fn aileron_for_roll(&self, t: &Truth, roll_cmd: f64) -> f64 {
        self.trim.aileron + 1.5 * wrap_pi(roll_cmd - t.roll_rad) - 0.25 * t.rates_body_radps[0]
    }

    /// Elevator to reach `pitch_cmd` (rad); a little extra in a bank for the extra lift.
    fn elevator_for_pitch(&self, t: &Truth, pitch_cmd: f64) -> f64 {
        let bank_load = (1.0 / t.roll_rad.cos().abs().max(0.5)) - 1.0;
        self.trim.elevator + 2.5 * (pitch_cmd - t.pitch_rad) - 0.5 * t.rates_body_radps[1]
            + 0.3 * bank_load
    }

    /// Rudder that keeps the ball in the middle (no sideslip).
    fn coordinating_rudder(&self, t: &Truth) -> f64 {
        self.trim.rudder + 2.0 * t.beta_rad - 0.1 * t.rates_body_radps[2]
    }

    /// Pitch for a climb rate (m/s).
    fn pitch_for_climb(&self, t: &Truth, climb_cmd: f64) -> f64 {
        let climb = -t.velocity_ned_mps[2];
        let v = t.airspeed_mps.max(10.0);
        let mut pitch = self.trim_pitch_rad
            + (climb_cmd / v).clamp(-0.5, 0.5).asin()
            + 0.08 * (climb_cmd - climb);
        // Too slow: lower the nose, whatever the altitude wants.
        pitch -= 0.05 * (self.config.min_airspeed_mps - t.airspeed_mps).max(0.0);
        pitch.clamp(
            self.config.max_dive_pitch_rad,
            self.config.max_climb_pitch_rad,
        )
    }

    fn climb_for_altitude(&self, t: &Truth, altitude_m: f64) -> f64 {
        (0.25 * (altitude_m - t.height_above_ground_m)).clamp(-3.0, 3.0)
    }

    /// Throttle for the wanted airspeed and climb rate.
    fn throttle_for(&mut self, t: &Truth, airspeed_mps: f64, climb_cmd: f64, dt: f64) -> f64 {
        let error = airspeed_mps - t.airspeed_mps;
        self.throttle_trim = (self.throttle_trim + 0.01 * error * dt).clamp(-0.3, 0.3);
        self.trim.throttle + self.throttle_trim + 0.08 * error + 0.06 * climb_cmd
    }

    fn bank_for_heading(&self, t: &Truth, heading_rad: f64, max_bank_rad: f64) -> f64 {
        (1.5 * wrap_pi(heading_rad - t.yaw_rad)).clamp(-max_bank_rad, max_bank_rad)
    }

    /// Bank to bring the ground track onto `course_rad` (the heading when barely moving).
    fn bank_for_course(&self, t: &Truth, course_rad: f64, max_bank_rad: f64) -> f64 {
        let [vn, ve, _] = t.velocity_ned_mps;
        let course = if vn.hypot(ve) > 5.0 {
            ve.atan2(vn)
        } else {
            t.yaw_rad
        };
        (1.5 * wrap_pi(course_rad - course)).clamp(-max_bank_rad, max_bank_rad)
    }

    /// Flies altitude, heading and airspeed targets with the given bank limit.
    fn hold(&mut self, t: &Truth, dt: f64, bank_rad: f64) -> ActuatorCommands {
        let climb_cmd = self.climb_for_altitude(t, self.altitude_m);
        let pitch = self.pitch_for_climb(t, climb_cmd);
        ActuatorCommands {
            aileron: self.aileron_for_roll(t, bank_rad),
            elevator: self.elevator_for_pitch(t, pitch),
            rudder: self.coordinating_rudder(t),
            throttle: self.throttle_for(t, self.airspeed_mps, climb_cmd, dt),
            brake: 0.0,
        }
    }

    fn decide(&mut self, t: &Truth, dt: f64) -> ActuatorCommands {
        match self.phase {
            Phase::Holding | Phase::Climbing => {
                if self.phase == Phase::Climbing
                    && (self.altitude_m - t.height_above_ground_m).abs() < 3.0
                {
                    self.phase = Phase::Holding;
                }
                let bank = self.bank_for_heading(t, self.heading_rad, self.config.max_bank_rad);
                self.hold(t, dt, bank)
            }
            Phase::Turning {
                direction,
                max_bank_rad,
            } => {
                let error = wrap_pi(self.heading_rad - t.yaw_rad);
                let bank = match direction {
                    // The long way round: full bank until within 30° of the heading.
                    Some(d) if error.abs() > 30f64.to_radians() && error * d.sign() < 0.0 => {
                        d.sign() * max_bank_rad
                    }
                    _ => self.bank_for_heading(t, self.heading_rad, max_bank_rad),
                };
                if error.abs() < 5f64.to_radians() {
                    self.phase = Phase::Holding;
                }
                self.hold(t, dt, bank)
            }
            Phase::TakeoffRoll {
                runway,
                rotate_speed_mps,
                climb_pitch_rad,
                climb_to_m,
            } => self.takeoff(t, runway, rotate_speed_mps, climb_pitch_rad, climb_to_m),
            Phase::RollEntry { direction } => {
                // Nose up first, so the roll ends near where it started.
                if t.pitch_rad > 15f64.to_radians() {
                    self.phase = Phase::Rolling {
                        direction,
                        rolled_rad: 0.0,
                        last_roll_rad: t.roll_rad,
                    };
                }
                ActuatorCommands {
                    aileron: self.aileron_for_roll(t, 0.0),
                    elevator: self.elevator_for_pitch(t, 25f64.to_radians()),
                    rudder: self.coordinating_rudder(t),
                    throttle: 1.0,
                    brake: 0.0,
                }
            }
            Phase::Rolling {
                direction,
                rolled_rad,
                last_roll_rad,
            } => {
                let rolled_rad = rolled_rad + wrap_pi(t.roll_rad - last_roll_rad);
                self.phase = if rolled_rad.abs() > TAU - 40f64.to_radians() {
                    Phase::Holding
                } else {
                    Phase::Rolling {
                        direction,
                        rolled_rad,
                        last_roll_rad: t.roll_rad,
                    }
                };
                ActuatorCommands {
                    aileron: direction.sign(),
                    // Less up-elevator than trim: relative to trim a push, which keeps the nose
                    // up while inverted.
                    elevator: 0.1,
                    rudder: 0.0,
                    throttle: 1.0,
                    brake: 0.0,
                }
            }
            Phase::LoopEntry {
                wing_axis_ned,
                since_s,
            } => {
                // Dive at 15° for speed while there is height for it (above 60 m), else
                // accelerate level; pull after 15 s whatever the speed.
                if t.airspeed_mps >= self.config.loop_entry_airspeed_mps || t.t_s - since_s > 15.0 {
                    self.phase = Phase::LoopPull {
                        wing_axis_ned,
                        pitched_rad: 0.0,
                        since_s: t.t_s,
                    };
                }
                let pitch = if t.height_above_ground_m > 60.0 {
                    -15f64.to_radians()
                } else {
                    0.0
                };
                ActuatorCommands {
                    aileron: self.aileron_for_roll(t, 0.0),
                    elevator: self.elevator_for_pitch(t, pitch),
                    rudder: self.coordinating_rudder(t),
                    throttle: 1.0,
                    brake: 0.0,
                }
            }
            Phase::LoopPull {
                wing_axis_ned,
                pitched_rad,
                since_s,
            } => {
                let pitched_rad = pitched_rad + t.rates_body_radps[1] * dt;
                let done = pitched_rad > TAU - 50f64.to_radians() || t.t_s - since_s > 25.0;
                self.phase = if done {
                    Phase::Holding
                } else {
                    Phase::LoopPull {
                        wing_axis_ned,
                        pitched_rad,
                        since_s,
                    }
                };
                // Keep the wings on the entry wing axis, so the loop stays in its plane:
                // the rotation that takes the body's wing axis onto it, about the body's roll
                // and yaw axes.
                let r = quat_to_rotation(t.attitude);
                let error = cross(column(&r, 1), wing_axis_ned);
                let roll_error = dot(error, column(&r, 0));
                let yaw_error = dot(error, column(&r, 2));
                ActuatorCommands {
                    aileron: 2.0 * roll_error - 0.25 * t.rates_body_radps[0],
                    elevator: 1.0,
                    rudder: self.trim.rudder + 2.0 * yaw_error,
                    throttle: 1.0,
                    brake: 0.0,
                }
            }
            Phase::Downwind {
                runway,
                glide_slope_rad,
                final_length_m,
                side,
            } => {
                // Head for the base turn: abeam the final approach gate, a few turn radii to
                // the side, by ground track (so the wind does not push the circuit about).
                let (along, _) = runway.along_cross_m(t.position_ned_m[0], t.position_ned_m[1]);
                let base_turn = runway.point_at(-final_length_m, side * DOWNWIND_OFFSET_M);
                let distance =
                    (base_turn[0] - t.position_ned_m[0]).hypot(base_turn[1] - t.position_ned_m[1]);
                if along < -final_length_m || distance < 100.0 {
                    self.altitude_m = final_length_m * glide_slope_rad.tan();
                    self.phase = Phase::Base {
                        runway,
                        glide_slope_rad,
                        final_length_m,
                        side,
                    };
                }
                let bank =
                    self.bank_for_course(t, bearing_to(t, base_turn), self.config.max_bank_rad);
                self.hold(t, dt, bank)
            }
            Phase::Base {
                runway,
                glide_slope_rad,
                final_length_m,
                side,
            } => {
                let (_, cross) = runway.along_cross_m(t.position_ned_m[0], t.position_ned_m[1]);
                if cross.abs() < 120.0 || cross * side < 0.0 {
                    self.phase = Phase::Final {
                        runway,
                        glide_slope_rad,
                    };
                }
                let gate = runway.point_at(-final_length_m, 0.0);
                let bank = self.bank_for_course(t, bearing_to(t, gate), self.config.max_bank_rad);
                self.hold(t, dt, bank)
            }
            Phase::Final {
                runway,
                glide_slope_rad,
            } => self.final_approach(t, dt, runway, glide_slope_rad),
            Phase::Rollout { runway } => self.rollout(t, runway),
            Phase::Sticks { sticks, until_s } => {
                if t.t_s >= until_s {
                    self.altitude_m = t.height_above_ground_m;
                    self.heading_rad = t.yaw_rad;
                    self.phase = if t.on_ground {
                        Phase::Parked
                    } else {
                        Phase::Holding
                    };
                }
                sticks
            }
            Phase::Parked => ActuatorCommands {
                brake: 1.0,
                ..Default::default()
            },
        }
    }

    /// Rudder (and nose wheel) that keeps the airplane on the runway's centreline.
    fn centreline_rudder(&self, t: &Truth, runway: Runway) -> f64 {
        let (_, cross) = runway.along_cross_m(t.position_ned_m[0], t.position_ned_m[1]);
        let heading = runway.heading_rad - (0.1 * cross).clamp(-0.2, 0.2);
        1.5 * wrap_pi(heading - t.yaw_rad) - 0.3 * t.rates_body_radps[2]
    }

    fn takeoff(
        &mut self,
        t: &Truth,
        runway: Runway,
        rotate_speed_mps: f64,
        climb_pitch_rad: f64,
        climb_to_m: f64,
    ) -> ActuatorCommands {
        let height = self.wheel_height_m(t);
        if height > 5.0 && t.height_above_ground_m > climb_to_m - 10.0 {
            self.heading_rad = runway.heading_rad;
            self.phase = Phase::Climbing;
        }
        let rotating = t.airspeed_mps > rotate_speed_mps || !t.on_ground;
        let elevator = if rotating {
            // Slow: lower the nose (a human would), else hold the climb attitude.
            let slow = if height > 3.0 {
                (self.config.min_airspeed_mps - t.airspeed_mps).max(0.0)
            } else {
                0.0
            };
            self.elevator_for_pitch(t, climb_pitch_rad - 0.05 * slow)
        } else {
            0.0
        };
        let (_, cross) = runway.along_cross_m(t.position_ned_m[0], t.position_ned_m[1]);
        let (aileron, rudder) = if height < 3.0 {
            (
                self.aileron_for_roll(t, 0.0),
                self.centreline_rudder(t, runway),
            )
        } else {
            // Airborne: stay over the extended centreline with small banks.
            let heading = runway.heading_rad - (0.01 * cross).clamp(-0.3, 0.3);
            let bank = self.bank_for_heading(t, heading, 15f64.to_radians());
            (self.aileron_for_roll(t, bank), self.coordinating_rudder(t))
        };
        ActuatorCommands {
            aileron,
            elevator,
            rudder,
            throttle: 1.0,
            brake: 0.0,
        }
    }

    fn final_approach(
        &mut self,
        t: &Truth,
        dt: f64,
        runway: Runway,
        glide_slope_rad: f64,
    ) -> ActuatorCommands {
        let height = self.wheel_height_m(t);
        let climb = -t.velocity_ned_mps[2];
        let (along, cross) = runway.along_cross_m(t.position_ned_m[0], t.position_ned_m[1]);
        if t.on_ground && height < 0.1 {
            self.phase = Phase::Rollout { runway };
            return self.rollout(t, runway);
        }
        // Lateral: track the centreline by ground course; gentler banks low down.
        let course = t.velocity_ned_mps[1].atan2(t.velocity_ned_mps[0]);
        let course_cmd = runway.heading_rad - (0.012 * cross).clamp(-0.7, 0.7);
        let max_bank = if height < 15.0 {
            8f64.to_radians()
        } else {
            25f64.to_radians()
        };
        let bank = (1.5 * wrap_pi(course_cmd - course)).clamp(-max_bank, max_bank);
        let flare = height < 4.0;
        if flare {
            // The elevator alone cannot flare this airframe much (its pitch stiffness is
            // high), so power stays on and holds the sink rate down.
            let target_climb = -0.2 - 0.2 * height;
            let pitch = self.trim_pitch_rad + 0.15 * (target_climb - climb);
            let throttle =
                (0.6 * self.trim.throttle + 0.5 * (target_climb - climb)).clamp(0.0, 1.0);
            return ActuatorCommands {
                aileron: self.aileron_for_roll(t, bank.clamp(-0.05, 0.05)),
                elevator: self.elevator_for_pitch(t, pitch),
                rudder: self.centreline_rudder(t, runway),
                throttle,
                brake: 0.0,
            };
        }
        let glide_height = (-along).max(0.0) * glide_slope_rad.tan();
        let ground_speed = t.velocity_ned_mps[0].hypot(t.velocity_ned_mps[1]);
        let climb_cmd = (-ground_speed * glide_slope_rad.sin()
            + 0.3 * (glide_height - t.height_above_ground_m))
            .clamp(-4.0, 1.5);
        let pitch = self.pitch_for_climb(t, climb_cmd);
        ActuatorCommands {
            aileron: self.aileron_for_roll(t, bank),
            elevator: self.elevator_for_pitch(t, pitch),
            rudder: self.coordinating_rudder(t),
            throttle: self.throttle_for(t, self.config.approach_airspeed_mps, climb_cmd, dt),
            brake: 0.0,
        }
    }

    fn rollout(&mut self, t: &Truth, runway: Runway) -> ActuatorCommands {
        let ground_speed = t.velocity_ned_mps[0].hypot(t.velocity_ned_mps[1]);
        if ground_speed < 0.05 {
            self.phase = Phase::Parked;
        }
        // Stick back and moderate brakes: full brakes with the stick forward can tip the
        // airplane onto its nose and a wing tip when a gust lifts a wing.
        ActuatorCommands {
            aileron: self.aileron_for_roll(t, 0.0),
            elevator: ROLLOUT_ELEVATOR,
            rudder: self.centreline_rudder(t, runway),
            throttle: 0.0,
            brake: if ground_speed < 15.0 {
                ROLLOUT_BRAKE
            } else {
                0.0
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::{InitialState, Plant, PlantConfig, WindConfig};

    const DT: f64 = 0.02;

    fn plant_at(initial: InitialState) -> Plant {
        let config = PlantConfig {
            wind: WindConfig::calm(),
            max_step_s: 0.005,
            ..PlantConfig::default()
        };
        Plant::with_config(config, initial, 3)
    }

    /// Trimmed level flight north at `altitude_m`, the pilot holding, then `manoeuvre` after
    /// 2 s; returns the truth every step.
    fn fly_from_trim(altitude_m: f64, manoeuvre: Manoeuvre, seconds: f64) -> (Vec<Truth>, Pilot) {
        let params = AircraftParams::aerosonde();
        let trim = trim_level_flight(&params, 23.0, altitude_m, 0.0).expect("trim");
        let mut plant = plant_at(trim.initial);
        let mut pilot = Pilot::new(&params, PilotConfig::default());
        pilot.fly(Manoeuvre::Hold {
            altitude_m: None,
            heading_rad: None,
            airspeed_mps: None,
        });
        let mut history = vec![];
        for k in 0..(seconds / DT).round() as usize {
            let t = plant.truth();
            if k == (2.0 / DT) as usize {
                pilot.fly(manoeuvre);
            }
            let c = pilot.update(&t);
            plant.step(DT, &c);
            history.push(plant.truth());
        }
        (history, pilot)
    }

    #[test]
    fn turns_to_a_heading_within_its_bank_limit_and_holds_altitude() {
        let bank = 20f64.to_radians();
        let (h, pilot) = fly_from_trim(
            100.0,
            Manoeuvre::Turn {
                heading_rad: -FRAC_PI_2,
                max_bank_rad: bank,
                direction: None,
            },
            40.0,
        );
        let end = h.last().expect("history");
        assert!(
            wrap_pi(end.yaw_rad + FRAC_PI_2).abs() < 3f64.to_radians(),
            "{end:?}"
        );
        let max_roll = h.iter().map(|t| t.roll_rad.abs()).fold(0.0, f64::max);
        assert!(max_roll < bank + 4f64.to_radians(), "banked {max_roll}");
        assert!(
            max_roll > bank - 4f64.to_radians(),
            "barely banked {max_roll}"
        );
        // The short way round: a left turn.
        assert!(h.iter().all(|t| t.roll_rad < 3f64.to_radians()));
        for t in &h {
            assert!((t.height_above_ground_m - 100.0).abs() < 8.0, "{t:?}");
        }
        assert!(pilot.is_idle());
    }

    #[test]
    fn turns_the_long_way_round_when_told() {
        let (h, _) = fly_from_trim(
            100.0,
            Manoeuvre::Turn {
                heading_rad: -FRAC_PI_2,
                max_bank_rad: 30f64.to_radians(),
                direction: Some(Direction::Right),
            },
            50.0,
        );
        assert!(h.iter().all(|t| t.roll_rad > -5f64.to_radians()));
        let end = h.last().expect("history");
        assert!(wrap_pi(end.yaw_rad + FRAC_PI_2).abs() < 3f64.to_radians());
    }

    #[test]
    fn climbs_to_an_altitude_and_levels_off() {
        let (h, _) = fly_from_trim(
            80.0,
            Manoeuvre::Climb {
                altitude_m: 140.0,
                airspeed_mps: Some(22.0),
            },
            60.0,
        );
        let end = h.last().expect("history");
        assert!((end.height_above_ground_m - 140.0).abs() < 3.0, "{end:?}");
        assert!((end.airspeed_mps - 22.0).abs() < 1.5, "{end:?}");
        assert!(
            h.iter()
                .all(|t| t.airspeed_mps > 17.0 && t.height_above_ground_m < 150.0)
        );
    }

    #[test]
    fn rolls_left_through_a_full_turn_and_recovers() {
        let (h, pilot) = fly_from_trim(
            150.0,
            Manoeuvre::Roll {
                direction: Direction::Left,
            },
            25.0,
        );
        let rolled: f64 = h
            .windows(2)
            .map(|w| wrap_pi(w[1].roll_rad - w[0].roll_rad))
            .take((12.0 / DT) as usize)
            .sum();
        assert!(rolled < -300f64.to_radians(), "{}", rolled.to_degrees());
        let end = h.last().expect("history");
        assert!(end.roll_rad.abs() < 5f64.to_radians(), "{end:?}");
        let lowest = h
            .iter()
            .map(|t| t.height_above_ground_m)
            .fold(f64::MAX, f64::min);
        assert!(lowest > 100.0, "lost {} m", 150.0 - lowest);
        assert!(pilot.is_idle());
    }

    #[test]
    fn sticks_move_no_faster_than_a_hand() {
        let params = AircraftParams::aerosonde();
        let config = PilotConfig::default();
        let mut plant = plant_at(InitialState::on_runway(&params, 0.0));
        let mut pilot = Pilot::new(&params, config.clone());
        let full = ActuatorCommands {
            aileron: 1.0,
            elevator: -1.0,
            rudder: 1.0,
            throttle: 1.0,
            brake: 0.0,
        };
        // Parked, brakes on; then told to move every stick to its end at once.
        let mut last = pilot.update(&plant.truth());
        assert_eq!(last.brake, 1.0);
        pilot.fly(Manoeuvre::Sticks {
            sticks: full,
            duration_s: 5.0,
        });
        let mut reached_at = None;
        for _ in 0..100 {
            plant.step(DT, &last);
            let now = pilot.update(&plant.truth());
            for (a, b, rate) in [
                (last.aileron, now.aileron, config.surface_stick_rate_per_s),
                (last.elevator, now.elevator, config.surface_stick_rate_per_s),
                (last.rudder, now.rudder, config.surface_stick_rate_per_s),
                (last.throttle, now.throttle, config.throttle_rate_per_s),
            ] {
                assert!((b - a).abs() <= rate * DT + 1e-12, "{a} -> {b}");
            }
            if now == full && reached_at.is_none() {
                reached_at = Some(plant.time_s());
            }
            last = now;
        }
        // Half a second for the throttle's full travel (raw sticks need no looking, so no
        // reaction time).
        let t = reached_at.expect("never reached the raw sticks");
        assert!((0.49..0.6).contains(&t), "{t}");
    }

    #[test]
    fn reacts_a_reaction_time_late() {
        let params = AircraftParams::aerosonde();
        let trim = trim_level_flight(&params, 23.0, 100.0, 0.0).expect("trim");
        let plant = plant_at(trim.initial);
        let mut pilot = Pilot::new(&params, PilotConfig::default());
        pilot.fly(Manoeuvre::Hold {
            altitude_m: None,
            heading_rad: None,
            airspeed_mps: None,
        });
        let steady = plant.truth();
        let mut quiet = None;
        for k in 0..50 {
            let mut t = steady;
            t.t_s = k as f64 * DT;
            // A gust rolls the airplane 30° right at 0.5 s.
            if t.t_s >= 0.5 - 1e-9 {
                t.roll_rad = 30f64.to_radians();
            }
            let c = pilot.update(&t);
            let before = *quiet.get_or_insert(c.aileron);
            if t.t_s < 0.5 + 0.1 - 1e-9 {
                assert_eq!(c.aileron, before, "reacted at {} s", t.t_s);
            } else if t.t_s > 0.7 {
                assert!(c.aileron < before - 0.1, "no left aileron at {} s", t.t_s);
            }
        }
    }

    #[test]
    fn same_truths_same_sticks() {
        let run = || fly_from_trim(120.0, Manoeuvre::Loop, 20.0).0;
        assert!(run() == run());
    }
}

//! The successive-loop autopilot of Beard & McLain, ch. 6, in `conventions.md` signs:
//!
//! - lateral: course → roll angle (PI, limited to the bank limit), roll → aileron (PID with
//!   the roll rate as derivative); a yaw damper drives the yaw rate towards the coordinated
//!   turn's `g·sin φ / V` with the rudder;
//! - longitudinal: pitch → elevator (PID with the pitch rate as derivative, around the trim);
//!   altitude → pitch (PID with the climb rate as derivative) and airspeed → throttle (PI
//!   around the trim) in the altitude-hold zone; above/below the zone, full/idle throttle
//!   and airspeed → pitch (climb/descend zones, §6.4.3).
//!
//! Airspeed: the airplane has no pitot; the autopilot flies on the airspeed of its
//! [`WindEstimator`] (ground velocity less the wind learnt from the velocity across the nose,
//! `control/wind.rs`), which it keeps up to date in every mode through [`Autopilot::observe`].

use super::pid::{Pid, PidGains, PidTerms};
use super::wind::WindEstimator;
use crate::angles::wrap_pi_f32;
use crate::control::controls::Controls;
use crate::estimation::Estimate;

const G: f32 = 9.806_65;

/// Gains, limits and trims of all loops (the control task fills these from parameters).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AutopilotGains {
    /// Roll error (rad) → aileron; `kd` per rad/s of roll rate.
    pub roll: PidGains,
    /// Pitch error (rad) → elevator about the trim; `kd` per rad/s of pitch rate.
    pub pitch: PidGains,
    /// Course error (rad) → roll command (rad); its limits are the bank limit.
    pub course: PidGains,
    /// Altitude error (m) → pitch command (rad); `kd` per m/s of climb rate.
    pub altitude: PidGains,
    /// Airspeed error (m/s) → throttle about the trim.
    pub airspeed_throttle: PidGains,
    /// Airspeed error (m/s) → pitch command (rad) in the climb/descend zones (negative
    /// gains: too slow, pitch down).
    pub airspeed_pitch: PidGains,
    /// Rudder per rad/s of yaw-rate error.
    pub yaw_damper: f32,
    pub trim_elevator: f32,
    pub trim_throttle: f32,
    /// Half-height of the altitude-hold zone (m).
    pub altitude_zone_m: f32,
    pub climb_throttle: f32,
    pub descend_throttle: f32,
    /// Pitch command limit (rad), both ways.
    pub max_pitch_rad: f32,
}

impl Default for AutopilotGains {
    fn default() -> Self {
        let bank = 30f32.to_radians();
        let pitch = 15f32.to_radians();
        Self {
            roll: PidGains::new(1.2, 0.1, 0.15, -1.0, 1.0).with_rate_limit(4.0),
            pitch: PidGains::new(2.0, 0.5, 0.3, -1.0, 1.0).with_rate_limit(4.0),
            course: PidGains::new(1.0, 0.02, 0.0, -bank, bank),
            altitude: PidGains::new(0.04, 0.004, 0.04, -pitch, pitch),
            airspeed_throttle: PidGains::new(0.08, 0.02, 0.0, -1.0, 1.0),
            airspeed_pitch: PidGains::new(-0.04, -0.005, 0.0, -pitch, pitch),
            yaw_damper: 0.3,
            trim_elevator: 0.0,
            trim_throttle: 0.5,
            altitude_zone_m: 15.0,
            climb_throttle: 1.0,
            descend_throttle: 0.2,
            max_pitch_rad: pitch,
        }
    }
}

impl AutopilotGains {
    /// The Aerosonde of `platform-sim` (trim at 25 m/s: throttle 0.77, elevator +0.28).
    pub fn aerosonde() -> Self {
        Self {
            trim_elevator: 0.28,
            trim_throttle: 0.77,
            ..Self::default()
        }
    }
}

/// The altitude state machine's zone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum AltitudeZone {
    Hold = 0,
    Climb = 1,
    Descend = 2,
}

/// What the loops aimed at in the last step (NaN where a loop did not run).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Targets {
    pub course_rad: f32,
    pub altitude_m: f32,
    pub airspeed_mps: f32,
    pub roll_rad: f32,
    pub pitch_rad: f32,
    pub zone: AltitudeZone,
}

impl Default for Targets {
    fn default() -> Self {
        Self {
            course_rad: f32::NAN,
            altitude_m: f32::NAN,
            airspeed_mps: f32::NAN,
            roll_rad: f32::NAN,
            pitch_rad: f32::NAN,
            zone: AltitudeZone::Hold,
        }
    }
}

#[derive(Clone, Debug)]
pub struct Autopilot {
    gains: AutopilotGains,
    roll: Pid,
    pitch: Pid,
    course: Pid,
    altitude: Pid,
    speed_throttle: Pid,
    speed_pitch: Pid,
    zone: AltitudeZone,
    /// Not reset with the loops: the wind does not change with the mode.
    wind: WindEstimator,
}

impl Autopilot {
    pub fn new(gains: AutopilotGains) -> Self {
        let mut ap = Self {
            gains,
            roll: Pid::new(gains.roll),
            pitch: Pid::new(gains.pitch),
            course: Pid::new(gains.course),
            altitude: Pid::new(gains.altitude),
            speed_throttle: Pid::new(gains.airspeed_throttle),
            speed_pitch: Pid::new(gains.airspeed_pitch),
            zone: AltitudeZone::Hold,
            wind: WindEstimator::new(),
        };
        ap.set_gains(gains);
        ap
    }

    pub fn gains(&self) -> &AutopilotGains {
        &self.gains
    }

    /// New gains; the loops keep their state. Output limits account for the trims so the
    /// surfaces stay in [−1, 1] and the throttle in [0, 1].
    pub fn set_gains(&mut self, gains: AutopilotGains) {
        self.gains = gains;
        self.roll.gains = gains.roll;
        let mut pitch = gains.pitch;
        pitch.out_min = pitch.out_min.max(-1.0 - gains.trim_elevator);
        pitch.out_max = pitch.out_max.min(1.0 - gains.trim_elevator);
        self.pitch.gains = pitch;
        self.course.gains = gains.course;
        self.altitude.gains = gains.altitude;
        let mut thr = gains.airspeed_throttle;
        thr.out_min = thr.out_min.max(-gains.trim_throttle);
        thr.out_max = thr.out_max.min(1.0 - gains.trim_throttle);
        self.speed_throttle.gains = thr;
        self.speed_pitch.gains = gains.airspeed_pitch;
    }

    /// Forgets every loop's state (on entering a computer mode).
    pub fn reset(&mut self) {
        for pid in [
            &mut self.roll,
            &mut self.pitch,
            &mut self.course,
            &mut self.altitude,
            &mut self.speed_throttle,
            &mut self.speed_pitch,
        ] {
            pid.reset();
        }
        self.zone = AltitudeZone::Hold;
    }

    pub fn zone(&self) -> AltitudeZone {
        self.zone
    }

    /// Learns the wind from an estimate; the control task calls this every step, in every
    /// mode, so AUTO starts with the wind known.
    pub fn observe(&mut self, est: &Estimate, dt_s: f32) {
        self.wind.observe(est, dt_s);
    }

    pub fn wind(&self) -> &WindEstimator {
        &self.wind
    }

    /// The inner loops' terms (roll, pitch), for logs.
    pub fn inner_terms(&self) -> (PidTerms, PidTerms) {
        (self.roll.terms(), self.pitch.terms())
    }

    /// Inner loops: roll and pitch angles (rad) → aileron, elevator, rudder.
    pub fn attitude(&mut self, est: &Estimate, roll_c: f32, pitch_c: f32, dt_s: f32) -> Controls {
        let [p, q, r] = est.rates_radps;
        let aileron = self.roll.update_with_rate(roll_c - est.roll_rad, p, dt_s);
        let elevator = self.gains.trim_elevator
            + self
                .pitch
                .update_with_rate(pitch_c - est.pitch_rad, q, dt_s);
        // A coordinated turn's yaw rate is set by the airspeed.
        let speed = self.wind.airspeed_mps(est).max(5.0);
        let r_ref = G * libm::sinf(est.roll_rad) / speed;
        let rudder = (self.gains.yaw_damper * (r_ref - r)).clamp(-1.0, 1.0);
        Controls {
            aileron: finite_or(aileron, 0.0).clamp(-1.0, 1.0),
            elevator: finite_or(elevator, self.gains.trim_elevator).clamp(-1.0, 1.0),
            throttle: self.gains.trim_throttle,
            rudder: finite_or(rudder, 0.0),
        }
    }

    /// Outer loops: hold `course_c` (rad), `altitude_c` (m above home) and `airspeed_c`
    /// (m/s), then the inner loops.
    pub fn auto(
        &mut self,
        est: &Estimate,
        course_c: f32,
        altitude_c: f32,
        airspeed_c: f32,
        dt_s: f32,
    ) -> (Controls, Targets) {
        let g = self.gains;
        let course = est.course_rad();
        let course_rate = G * libm::tanf(est.roll_rad) / est.ground_speed_mps().max(5.0);
        let roll_c =
            self.course
                .update_with_rate(wrap_pi_f32(course_c - course), course_rate, dt_s);
        let altitude = est.altitude_m();
        let climb_rate = -est.velocity_ned_mps[2];
        let speed = self.wind.airspeed_mps(est);
        let error = altitude_c - altitude;
        let zone = if error > g.altitude_zone_m {
            AltitudeZone::Climb
        } else if error < -g.altitude_zone_m {
            AltitudeZone::Descend
        } else {
            AltitudeZone::Hold
        };
        if zone != self.zone {
            // Bumpless: the loop taking over the pitch starts from the current command.
            let current = self.altitude.terms().output;
            let current_speed = self.speed_pitch.terms().output;
            match zone {
                AltitudeZone::Hold => self.altitude.preset(current_speed),
                _ => self.speed_pitch.preset(current),
            }
            self.zone = zone;
        }
        let (pitch_c, throttle) = match zone {
            AltitudeZone::Hold => {
                let pitch_c = self.altitude.update_with_rate(error, climb_rate, dt_s);
                let thr = g.trim_throttle + self.speed_throttle.update(airspeed_c, speed, dt_s);
                (pitch_c, thr)
            }
            AltitudeZone::Climb => (
                self.speed_pitch.update(airspeed_c, speed, dt_s),
                g.climb_throttle,
            ),
            AltitudeZone::Descend => (
                self.speed_pitch.update(airspeed_c, speed, dt_s),
                g.descend_throttle,
            ),
        };
        let pitch_c = pitch_c.clamp(-g.max_pitch_rad, g.max_pitch_rad);
        let mut controls = self.attitude(est, roll_c, pitch_c, dt_s);
        controls.throttle = finite_or(throttle, g.trim_throttle).clamp(0.0, 1.0);
        (
            controls,
            Targets {
                course_rad: course_c,
                altitude_m: altitude_c,
                airspeed_mps: airspeed_c,
                roll_rad: roll_c,
                pitch_rad: pitch_c,
                zone,
            },
        )
    }
}

fn finite_or(x: f32, fallback: f32) -> f32 {
    if x.is_finite() { x } else { fallback }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(roll: f32, pitch: f32, yaw: f32, speed: f32, alt: f32) -> Estimate {
        let v = [speed * libm::cosf(yaw), speed * libm::sinf(yaw)];
        crate::control::test_estimate(roll, pitch, yaw, v, alt)
    }

    #[test]
    fn signs_follow_the_conventions() {
        let mut ap = Autopilot::new(AutopilotGains::aerosonde());
        // Wanting more right roll: positive aileron. Wanting nose up: more up elevator.
        let c = ap.attitude(&estimate(0.0, 0.0, 0.0, 25.0, 100.0), 0.2, 0.1, 0.02);
        assert!(c.aileron > 0.0 && c.elevator > 0.28, "{c:?}");
        // A target to the east of a north-flying airplane: bank right. Too low: pitch up.
        // Too slow (in the hold zone): more throttle than trim.
        let (c, t) = ap.auto(&estimate(0.0, 0.0, 0.0, 20.0, 95.0), 1.0, 100.0, 25.0, 0.02);
        assert!(t.roll_rad > 0.0 && t.pitch_rad > 0.0, "{t:?}");
        assert!(c.throttle > 0.77 && c.aileron > 0.0, "{c:?}");
        assert_eq!(t.zone, AltitudeZone::Hold);
        // Far below: climb zone, full throttle.
        let (c, t) = ap.auto(&estimate(0.0, 0.0, 0.0, 25.0, 50.0), 0.0, 100.0, 25.0, 0.02);
        assert_eq!((t.zone, c.throttle), (AltitudeZone::Climb, 1.0));
        // Course error wraps: from 170° to −170° is a right turn of 20°.
        let (_, t) = ap.auto(
            &estimate(0.0, 0.0, 170f32.to_radians(), 25.0, 100.0),
            -170f32.to_radians(),
            100.0,
            25.0,
            0.02,
        );
        assert!(t.roll_rad > 0.0);
    }

    #[test]
    fn outputs_stay_in_range_whatever_the_inputs() {
        let mut ap = Autopilot::new(AutopilotGains::aerosonde());
        for &(roll, pitch, alt) in &[(3.0, 1.5, -1e4), (-3.0, -1.5, 1e5), (f32::NAN, 0.0, 0.0)] {
            for _ in 0..100 {
                let (c, _) = ap.auto(
                    &estimate(roll, pitch, 0.0, 25.0, alt),
                    0.0,
                    100.0,
                    25.0,
                    0.02,
                );
                assert!((-1.0..=1.0).contains(&c.aileron), "{c:?}");
                assert!((-1.0..=1.0).contains(&c.elevator), "{c:?}");
                assert!((-1.0..=1.0).contains(&c.rudder), "{c:?}");
                assert!((0.0..=1.0).contains(&c.throttle), "{c:?}");
            }
        }
    }
}

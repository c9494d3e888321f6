//! Missions: a fixed-capacity list of waypoints in the local NED frame (the std side parses
//! the mission file into it), flown one after the other with a switching radius, then a
//! loiter circle around the last one.
//!
//! Guidance is "fly to": the commanded course points at the active waypoint, which is
//! reached when within the switching radius. The loiter follows a circle with the orbit law
//! of Beard & McLain (§10.3): `χ_c = γ + λ(π/2 + atan(k·(d − ρ)/ρ))`, where `γ` is the
//! bearing from the centre, `d` the distance to it, `ρ` the radius, `λ` = +1 clockwise.

use crate::angles::wrap_pi_f32;
use heapless::Vec;

pub const MAX_WAYPOINTS: usize = 32;

#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Waypoint {
    pub north_m: f32,
    pub east_m: f32,
    /// Above home, up.
    pub altitude_m: f32,
    pub airspeed_mps: f32,
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Mission {
    pub waypoints: Vec<Waypoint, MAX_WAYPOINTS>,
    pub switch_radius_m: f32,
    pub loiter_radius_m: f32,
    pub loiter_clockwise: bool,
}

/// The default loiter radius, 150 m, is above the tightest circle the airplane can fly at
/// cruise within the bank limit: `V²/(g·tan φ_max)` = 110 m at 25 m/s and 30°.
impl Default for Mission {
    fn default() -> Self {
        Self {
            waypoints: Vec::new(),
            switch_radius_m: 30.0,
            loiter_radius_m: 150.0,
            loiter_clockwise: true,
        }
    }
}

impl Mission {
    /// A mission of `waypoints` (at most [`MAX_WAYPOINTS`]; `None` if more).
    pub fn new(waypoints: &[Waypoint]) -> Option<Self> {
        Some(Self {
            waypoints: Vec::from_slice(waypoints).ok()?,
            ..Self::default()
        })
    }
}

/// What guidance asks of the autopilot.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Guidance {
    pub course_rad: f32,
    pub altitude_m: f32,
    pub airspeed_mps: f32,
    /// The active waypoint (the loiter centre's index once loitering).
    pub waypoint: u8,
    pub loitering: bool,
    pub distance_m: f32,
}

/// Progress through a mission.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MissionProgress {
    pub index: usize,
    pub loitering: bool,
    /// The course the airplane arrived on at the loiter's centre, held until it is a quarter
    /// radius out: at the centre the bearing the orbit law steers by is undefined, and
    /// flying through it would swing the command by up to 180°. `None` once on the circle.
    pub loiter_entry_course_rad: Option<f32>,
}

/// Orbit gain `k` of the loiter law.
const ORBIT_GAIN: f32 = 2.0;

impl MissionProgress {
    pub fn restart(&mut self) {
        *self = Self::default();
    }

    /// Guidance from the current position (north, east, m); `None` for an empty mission.
    pub fn guide(&mut self, mission: &Mission, north_m: f32, east_m: f32) -> Option<Guidance> {
        let last = mission.waypoints.len().checked_sub(1)?;
        if !self.loitering {
            let wp = mission.waypoints.get(self.index.min(last))?;
            let (dn, de) = (wp.north_m - north_m, wp.east_m - east_m);
            let distance = libm::sqrtf(dn * dn + de * de);
            if distance < mission.switch_radius_m {
                if self.index >= last {
                    self.loitering = true;
                    self.loiter_entry_course_rad = Some(libm::atan2f(de, dn));
                } else {
                    self.index += 1;
                }
            }
        }
        let index = self.index.min(last);
        let wp = *mission.waypoints.get(index)?;
        let (dn, de) = (wp.north_m - north_m, wp.east_m - east_m);
        let distance = libm::sqrtf(dn * dn + de * de);
        let rho = mission.loiter_radius_m.max(1.0);
        if distance >= 0.25 * rho {
            self.loiter_entry_course_rad = None;
        }
        let course = if let (true, Some(entry)) = (self.loitering, self.loiter_entry_course_rad) {
            // Straight on out of the centre; the orbit law takes over a quarter radius out (half
            // a radius overshot the circle by a third before it converged).
            entry
        } else if self.loitering {
            let gamma = libm::atan2f(-de, -dn);
            let lambda = if mission.loiter_clockwise { 1.0 } else { -1.0 };
            gamma
                + lambda
                    * (core::f32::consts::FRAC_PI_2
                        + libm::atanf(ORBIT_GAIN * (distance - rho) / rho))
        } else {
            libm::atan2f(de, dn)
        };
        Some(Guidance {
            course_rad: wrap_pi_f32(course),
            altitude_m: wp.altitude_m,
            airspeed_mps: wp.airspeed_mps,
            waypoint: u8::try_from(index).unwrap_or(u8::MAX),
            loitering: self.loitering,
            distance_m: distance,
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A waypoint at 100 m and 25 m/s (the mission store's tests use it too).
    pub(crate) fn wp(n: f32, e: f32) -> Waypoint {
        Waypoint {
            north_m: n,
            east_m: e,
            altitude_m: 100.0,
            airspeed_mps: 25.0,
        }
    }

    #[test]
    fn flies_to_each_waypoint_then_loiters_at_the_last() {
        let m = Mission::new(&[wp(500.0, 0.0), wp(500.0, 500.0)]).expect("fits");
        let mut p = MissionProgress::default();
        let g = p.guide(&m, 0.0, 0.0).expect("guidance");
        assert!(g.course_rad.abs() < 1e-6 && g.waypoint == 0 && !g.loitering);
        let g = p.guide(&m, 490.0, 0.0).expect("guidance");
        assert_eq!(g.waypoint, 1);
        assert!((g.course_rad - core::f32::consts::FRAC_PI_2).abs() < 0.05);
        let g = p.guide(&m, 500.0, 480.0).expect("guidance");
        assert!(g.loitering);
        // On the circle, north of the centre, clockwise: fly east.
        let g = p.guide(&m, 650.0, 500.0).expect("guidance");
        assert!(
            (g.course_rad - core::f32::consts::FRAC_PI_2).abs() < 1e-3,
            "{}",
            g.course_rad
        );
        // Far outside: head (mostly) towards the centre.
        let g = p.guide(&m, 2500.0, 500.0).expect("guidance");
        assert!(
            (g.course_rad.abs() - core::f32::consts::PI).abs() < 0.6,
            "{}",
            g.course_rad
        );
    }

    #[test]
    fn the_loiter_is_entered_straight_out_of_its_centre_not_through_it() {
        let m = Mission::new(&[wp(0.0, 0.0), wp(500.0, 0.0)]).expect("fits");
        let mut p = MissionProgress::default();
        // Arriving northbound at the last waypoint (the loiter's centre).
        p.guide(&m, 0.0, 0.0).expect("guidance");
        p.guide(&m, 300.0, 0.0).expect("guidance");
        let g = p.guide(&m, 480.0, 0.5).expect("guidance");
        assert!(g.loitering);
        // Through the centre and out to just under a quarter radius (37.5 m): the command
        // stays the arrival course (north), where the orbit law would swing it by ~180°.
        for north in [490.0, 500.0, 505.0, 520.0, 530.0, 537.0] {
            let g = p.guide(&m, north, 0.5).expect("guidance");
            assert!(g.course_rad.abs() < 0.05, "at {north} m: {}", g.course_rad);
        }
        // Beyond it the orbit law steers, right of the bearing from the centre (clockwise):
        // 90° + atan(2·(40 − 150)/150) = 34.3° at 40 m; and it keeps steering back inside.
        let g = p.guide(&m, 540.0, 0.0).expect("guidance");
        assert!(
            (g.course_rad - 34.3f32.to_radians()).abs() < 0.02,
            "{}",
            g.course_rad
        );
        let g = p.guide(&m, 520.0, 0.0).expect("guidance");
        assert!(g.course_rad > 0.4, "{}", g.course_rad);
    }

    #[test]
    fn empty_and_oversized_missions() {
        assert!(
            MissionProgress::default()
                .guide(&Mission::default(), 0.0, 0.0)
                .is_none()
        );
        let many = [wp(0.0, 0.0); MAX_WAYPOINTS + 1];
        assert!(Mission::new(&many).is_none());
    }
}

//! Wind, and so airspeed, without an airspeed sensor.
//!
//! The airplane has no pitot tube. In coordinated flight (no sideslip) the air-relative
//! velocity points along the nose, so the part of the GPS ground velocity across the nose can
//! only be wind: `v_ground · n = W · n` with `n` the unit vector to the right of the nose.
//! Each step gives one such component of the wind along a different direction as the heading
//! changes; a least-mean-squares update with a time constant of [`TIME_CONSTANT_S`] collects
//! them into the horizontal wind. Airspeed is then the ground velocity less the wind, along
//! the nose.
//!
//! Flying on ground speed instead (what the autopilot did before) leaves the airplane slow
//! downwind: in the simulator's 2 m/s wind plus moderate gusts, true airspeed fell to 18 m/s
//! while the ground speed held 23, the altitude loop saturated its pitch and lost 9 m.

use crate::estimation::Estimate;

/// How quickly the estimate follows the wind. Slow enough to average gusts and the
/// estimator's yaw noise, quick enough to converge within one loiter circle (≈ 40 s).
pub const TIME_CONSTANT_S: f32 = 20.0;
/// Learn only when flying: on the ground the wheels, not the air, set the velocity's
/// direction (m above home, m/s).
pub const MIN_HEIGHT_M: f32 = 10.0;
pub const MIN_GROUND_SPEED_MPS: f32 = 10.0;
/// Beyond this bank the no-sideslip assumption is poor.
pub const MAX_BANK_RAD: f32 = 0.8;
/// A wind estimate is clamped to this (m/s): larger means the assumptions broke, and an
/// airspeed computed from it would be worse than the ground speed.
pub const MAX_WIND_MPS: f32 = 15.0;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WindEstimator {
    /// Horizontal wind (m/s, the direction the air moves to: north, east).
    wind_ne_mps: [f32; 2],
    /// Seconds of flight the estimate has learnt from.
    learnt_s: f32,
}

impl WindEstimator {
    pub fn new() -> Self {
        Self::default()
    }

    /// The wind the air moves with (north, east; m/s).
    pub fn wind_ne_mps(&self) -> [f32; 2] {
        self.wind_ne_mps
    }

    pub fn learnt_s(&self) -> f32 {
        self.learnt_s
    }

    /// Learns from one estimate, `dt_s` after the previous; ignores it on the ground, in
    /// steep banks, or when anything it needs is not finite.
    pub fn observe(&mut self, est: &Estimate, dt_s: f32) {
        let [vn, ve, _] = est.velocity_ned_mps;
        let usable = dt_s.is_finite()
            && dt_s > 0.0
            && vn.is_finite()
            && ve.is_finite()
            && est.yaw_rad.is_finite()
            && est.altitude_m() > MIN_HEIGHT_M
            && est.ground_speed_mps() > MIN_GROUND_SPEED_MPS
            && libm::fabsf(est.roll_rad) < MAX_BANK_RAD;
        if !usable {
            return;
        }
        let (s, c) = (libm::sinf(est.yaw_rad), libm::cosf(est.yaw_rad));
        let right = [-s, c];
        let [wn, we] = self.wind_ne_mps;
        let residual = (vn * right[0] + ve * right[1]) - (wn * right[0] + we * right[1]);
        let k = (dt_s / TIME_CONSTANT_S).min(1.0);
        let clamp = |w: f32| w.clamp(-MAX_WIND_MPS, MAX_WIND_MPS);
        self.wind_ne_mps = [
            clamp(wn + k * residual * right[0]),
            clamp(we + k * residual * right[1]),
        ];
        self.learnt_s += dt_s;
    }

    /// Airspeed (m/s): the ground velocity less the wind, along the nose; the climb rate is
    /// counted too. Never below zero; the ground speed when something is not finite.
    pub fn airspeed_mps(&self, est: &Estimate) -> f32 {
        let [vn, ve, vd] = est.velocity_ned_mps;
        let [wn, we] = self.wind_ne_mps;
        let (s, c) = (libm::sinf(est.yaw_rad), libm::cosf(est.yaw_rad));
        let along = (vn - wn) * c + (ve - we) * s;
        let airspeed = libm::sqrtf(along * along + vd * vd);
        if airspeed.is_finite() {
            airspeed
        } else {
            est.ground_speed_mps()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Flying at `airspeed` with the nose at `yaw`, in `wind`, at `alt` m.
    fn flying(yaw: f32, airspeed: f32, wind: [f32; 2], alt: f32) -> Estimate {
        let v = [
            airspeed * libm::cosf(yaw) + wind[0],
            airspeed * libm::sinf(yaw) + wind[1],
        ];
        crate::control::test_estimate(0.3, 0.0, yaw, v, alt)
    }

    #[test]
    fn circling_in_a_steady_wind_finds_it_and_the_true_airspeed() {
        let wind = [3.0, -2.0];
        let mut w = WindEstimator::new();
        // A 40 s circle at 23 m/s airspeed, 50 Hz, for three circles.
        for k in 0..6000 {
            let yaw = k as f32 * 0.02 * core::f32::consts::TAU / 40.0;
            w.observe(&flying(yaw, 23.0, wind, 100.0), 0.02);
        }
        let [wn, we] = w.wind_ne_mps();
        assert!(
            (wn - 3.0).abs() < 0.2 && (we + 2.0).abs() < 0.2,
            "{wn} {we}"
        );
        // Downwind the ground speed is 26.6 m/s; the airspeed is still 23.
        let downwind = flying(libm::atan2f(-2.0, 3.0), 23.0, wind, 100.0);
        assert!(downwind.ground_speed_mps() > 26.0);
        assert!((w.airspeed_mps(&downwind) - 23.0).abs() < 0.3);
        assert!((w.learnt_s() - 120.0).abs() < 0.1);
    }

    #[test]
    fn nothing_is_learnt_on_the_ground_slowly_or_from_nan() {
        let mut w = WindEstimator::new();
        for _ in 0..1000 {
            // Taxiing: wheels on the ground (1 m up), velocity across the nose from a crab.
            w.observe(&flying(0.0, 20.0, [0.0, 5.0], 1.0), 0.02);
            // Slow.
            w.observe(&flying(0.0, 5.0, [0.0, 3.0], 100.0), 0.02);
            let mut bad = flying(0.0, 23.0, [0.0, 3.0], 100.0);
            bad.yaw_rad = f32::NAN;
            w.observe(&bad, 0.02);
            w.observe(&flying(0.0, 23.0, [0.0, 3.0], 100.0), f32::NAN);
        }
        assert_eq!(w, WindEstimator::new());
        // With no wind learnt, airspeed is the ground speed along the nose.
        let e = flying(1.0, 21.0, [0.0, 0.0], 100.0);
        assert!((w.airspeed_mps(&e) - 21.0).abs() < 1e-4);
    }

    #[test]
    fn a_wild_velocity_cannot_drive_the_wind_past_its_limit() {
        let mut w = WindEstimator::new();
        for _ in 0..100_000 {
            let mut e = flying(0.0, 23.0, [0.0, 0.0], 100.0);
            e.velocity_ned_mps = [23.0, 500.0, 0.0];
            w.observe(&e, 0.02);
        }
        let [wn, we] = w.wind_ne_mps();
        assert!(wn.abs() <= MAX_WIND_MPS && we.abs() <= MAX_WIND_MPS);
    }
}

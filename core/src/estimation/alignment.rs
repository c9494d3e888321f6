//! The static start-up: with the airplane at rest, average the IMU for a few seconds.
//!
//! - Gyro bias = the mean rate (the Earth's rotation, ≤ 7.3e-5 rad/s, is left in it: below
//!   the bias stability of the IMUs this flies with).
//! - Roll and pitch from the mean specific force `f̄`, which at rest is `−Rᵀg + b_a`:
//!   `φ = atan2(−f̄_y, −f̄_z)`, `θ = atan2(f̄_x, √(f̄_y² + f̄_z²))`.
//! - Accelerometer bias: only its component along gravity is observable at rest, as
//!   `|f̄| − g` along `f̄`; a bias across gravity is indistinguishable from a tilt and ends up
//!   in roll/pitch (0.05 m/s² ≈ 0.3°). The filter's initial accelerometer-bias covariance says
//!   so, and GPS velocity in manoeuvres separates the two later.
//! - Yaw is not observable from an IMU at rest (no magnetometer): either configured, or
//!   taken from the first GPS course over ground above a speed threshold (the estimator
//!   does that, see `estimator.rs`).
//!
//! Motion during the averaging (a rate or a specific-force deviation beyond the thresholds)
//! restarts it, counted: a bump on the airframe must not become a bias.

use nalgebra::{UnitQuaternion, Vector3};

use super::ekf::GRAVITY_MPS2;

#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AlignmentConfig {
    /// Samples to average (at 100 Hz, 1000 = 10 s).
    pub samples: u32,
    /// A sample whose rate norm exceeds this (rad/s) means the vehicle moved.
    pub max_rate_radps: f32,
    /// A sample whose specific-force norm differs from g by more than this (m/s²) means the
    /// vehicle moved.
    pub max_accel_deviation_mps2: f32,
}

impl Default for AlignmentConfig {
    fn default() -> Self {
        Self {
            samples: 1000,
            max_rate_radps: 0.1,
            max_accel_deviation_mps2: 1.5,
        }
    }
}

/// What the alignment found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlignmentResult {
    pub gyro_bias_radps: Vector3<f64>,
    pub accel_bias_mps2: Vector3<f64>,
    pub roll_rad: f64,
    pub pitch_rad: f64,
    /// Standard deviation of one sample's rate and specific force during the averaging.
    pub rate_sd_radps: f64,
    pub accel_sd_mps2: f64,
}

impl AlignmentResult {
    /// The attitude with the given yaw.
    pub fn attitude(&self, yaw_rad: f64) -> UnitQuaternion<f64> {
        UnitQuaternion::from_euler_angles(self.roll_rad, self.pitch_rad, yaw_rad)
    }
}

#[derive(Clone, Debug)]
pub struct Alignment {
    config: AlignmentConfig,
    count: u32,
    sum_rate: Vector3<f64>,
    sum_rate_sq: Vector3<f64>,
    sum_force: Vector3<f64>,
    sum_force_sq: Vector3<f64>,
    restarts: u32,
    /// The longest stretch at rest that motion cut short: (samples, mean rate, rate σ of one
    /// sample). A vehicle that never rests the whole time still rested this long, and its
    /// mean rate is the best gyro bias there is for a start in motion.
    longest_rest: Option<Rest>,
}

impl Alignment {
    pub fn new(config: AlignmentConfig) -> Self {
        Self {
            config,
            count: 0,
            sum_rate: Vector3::zeros(),
            sum_rate_sq: Vector3::zeros(),
            sum_force: Vector3::zeros(),
            sum_force_sq: Vector3::zeros(),
            restarts: 0,
            longest_rest: None,
        }
    }

    pub fn restart(&mut self) {
        let restarts = self.restarts;
        let longest = longer(self.longest_rest, self.current_rest());
        *self = Self::new(self.config);
        self.restarts = restarts;
        self.longest_rest = longest;
    }

    /// The stretch at rest under way: (samples, mean rate, rate σ of one sample).
    fn current_rest(&self) -> Option<Rest> {
        (self.count > 0).then(|| {
            let n = f64::from(self.count);
            let mean = self.sum_rate / n;
            (self.count, mean, sd_of(&self.sum_rate_sq, &mean, n))
        })
    }

    /// The mean rate of the longest stretch at rest so far (the one under way included) and
    /// its 1-σ as a bias estimate, if it lasted at least `min_samples`.
    pub fn rest_gyro_bias(&self, min_samples: u32) -> Option<(Vector3<f64>, f64)> {
        longer(self.current_rest(), self.longest_rest)
            .filter(|(n, _, _)| *n >= min_samples.max(1))
            .map(|(n, mean, sd)| (mean, sd / libm::sqrt(f64::from(n))))
    }

    /// Motion restarts so far.
    pub fn restarts(&self) -> u32 {
        self.restarts
    }

    /// 0–100.
    pub fn progress_percent(&self) -> u8 {
        let total = u64::from(self.config.samples.max(1));
        let done = u64::from(self.count).min(total);
        u8::try_from(done * 100 / total).unwrap_or(100)
    }

    pub fn is_done(&self) -> bool {
        self.count >= self.config.samples.max(1)
    }

    /// Adds one sample. A non-finite sample is ignored; motion restarts the averaging.
    /// Returns `false` if the sample was not used.
    pub fn add(&mut self, rates_radps: Vector3<f64>, specific_force_mps2: Vector3<f64>) -> bool {
        if !rates_radps.iter().all(|x| x.is_finite())
            || !specific_force_mps2.iter().all(|x| x.is_finite())
        {
            return false;
        }
        let moving = rates_radps.norm() > f64::from(self.config.max_rate_radps)
            || (specific_force_mps2.norm() - GRAVITY_MPS2).abs()
                > f64::from(self.config.max_accel_deviation_mps2);
        if moving {
            if self.count > 0 {
                self.restarts = self.restarts.wrapping_add(1);
            }
            self.restart();
            return false;
        }
        if self.is_done() {
            return true;
        }
        self.count += 1;
        self.sum_rate += rates_radps;
        self.sum_rate_sq += rates_radps.component_mul(&rates_radps);
        self.sum_force += specific_force_mps2;
        self.sum_force_sq += specific_force_mps2.component_mul(&specific_force_mps2);
        true
    }

    /// The result once [`is_done`](Self::is_done).
    pub fn result(&self) -> Option<AlignmentResult> {
        if !self.is_done() {
            return None;
        }
        let n = f64::from(self.count);
        let rate = self.sum_rate / n;
        let force = self.sum_force / n;
        let norm = force.norm();
        if norm.is_nan() || norm <= 1.0 {
            return None;
        }
        let (roll, pitch) = level(&force);
        Some(AlignmentResult {
            gyro_bias_radps: rate,
            accel_bias_mps2: force * ((norm - GRAVITY_MPS2) / norm),
            roll_rad: roll,
            pitch_rad: pitch,
            rate_sd_radps: sd_of(&self.sum_rate_sq, &rate, n),
            accel_sd_mps2: sd_of(&self.sum_force_sq, &force, n),
        })
    }
}

/// Roll and pitch (rad) of a vehicle whose specific force, gravity only, is `f` (body FRD).
pub(crate) fn level(f: &Vector3<f64>) -> (f64, f64) {
    (
        libm::atan2(-f.y, -f.z),
        libm::atan2(f.x, libm::sqrt(f.y * f.y + f.z * f.z)),
    )
}

/// A stretch at rest: (samples, mean rate, rate σ of one sample).
type Rest = (u32, Vector3<f64>, f64);

/// The longer of two stretches at rest, `a` on a tie.
fn longer(a: Option<Rest>, b: Option<Rest>) -> Option<Rest> {
    match (a, b) {
        (Some(a), Some(b)) => Some(if b.0 > a.0 { b } else { a }),
        (a, b) => a.or(b),
    }
}

/// The axes' mean 1-σ of `n` samples of mean `mean` whose squares sum to `sum_sq`.
fn sd_of(sum_sq: &Vector3<f64>, mean: &Vector3<f64>, n: f64) -> f64 {
    let var = sum_sq / n - mean.component_mul(mean);
    libm::sqrt(var.iter().map(|v| v.max(0.0)).sum::<f64>() / 3.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_at_rest_gives_bias_and_zero_tilt() {
        let mut a = Alignment::new(AlignmentConfig {
            samples: 100,
            ..Default::default()
        });
        let bias = Vector3::new(0.01, -0.02, 0.005);
        for i in 0..100 {
            assert_eq!(a.progress_percent(), i);
            assert!(a.add(bias, Vector3::new(0.0, 0.0, -GRAVITY_MPS2 - 0.1)));
        }
        assert!(a.is_done());
        assert_eq!(a.progress_percent(), 100);
        let r = a.result().expect("done");
        assert!((r.gyro_bias_radps - bias).norm() < 1e-12);
        assert!(r.roll_rad.abs() < 1e-12 && r.pitch_rad.abs() < 1e-12);
        // Bias along gravity: measured |f| is g + 0.1 along −z.
        assert!((r.accel_bias_mps2 - Vector3::new(0.0, 0.0, -0.1)).norm() < 1e-9);
    }

    #[test]
    fn tilted_at_rest_recovers_roll_and_pitch() {
        let (roll, pitch) = (0.1f64, -0.05f64);
        let q = UnitQuaternion::from_euler_angles(roll, pitch, 1.0);
        let f = -(q.inverse() * Vector3::new(0.0, 0.0, GRAVITY_MPS2));
        let mut a = Alignment::new(AlignmentConfig {
            samples: 10,
            ..Default::default()
        });
        for _ in 0..10 {
            a.add(Vector3::zeros(), f);
        }
        let r = a.result().expect("done");
        assert!((r.roll_rad - roll).abs() < 1e-9 && (r.pitch_rad - pitch).abs() < 1e-9);
        let (r2, p2, y2) = r.attitude(1.0).euler_angles();
        assert!((r2 - roll).abs() < 1e-9 && (p2 - pitch).abs() < 1e-9 && (y2 - 1.0).abs() < 1e-9);
    }

    #[test]
    fn motion_restarts_and_nan_is_ignored() {
        let mut a = Alignment::new(AlignmentConfig {
            samples: 10,
            ..Default::default()
        });
        let g = Vector3::new(0.0, 0.0, -GRAVITY_MPS2);
        for _ in 0..5 {
            a.add(Vector3::zeros(), g);
        }
        assert_eq!(a.progress_percent(), 50);
        assert!(!a.add(Vector3::new(f64::NAN, 0.0, 0.0), g));
        assert_eq!(a.progress_percent(), 50);
        assert!(!a.add(Vector3::new(0.5, 0.0, 0.0), g));
        assert_eq!((a.progress_percent(), a.restarts()), (0, 1));
        assert!(a.result().is_none());
    }
}

//! The IMU: scale errors, turn-on biases with a random walk, white noise.

use super::super::math::Vec3;
use super::super::rng::NoiseRng;

/// IMU error model, per axis. Noise figures are standard deviations of one sample at the
/// configured rate; bias and scale errors are drawn once per run (a seed is one IMU unit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimImuConfig {
    /// Nominal output rate (Hz). The caller decides when to sample; this documents the rate the
    /// noise figures are meant for and sets the period [`SimImu::period_s`] reports.
    pub rate_hz: f64,
    pub gyro_noise_std_radps: f64,
    /// Standard deviation of the turn-on bias.
    pub gyro_bias_std_radps: f64,
    /// Bias random walk: the bias changes by this × √(elapsed s) (1σ).
    pub gyro_bias_walk_radps_per_sqrt_s: f64,
    /// Standard deviation of the scale-factor error (dimensionless, 0.01 = 1 %).
    pub gyro_scale_error_std: f64,
    pub accel_noise_std_mps2: f64,
    pub accel_bias_std_mps2: f64,
    pub accel_bias_walk_mps2_per_sqrt_s: f64,
    pub accel_scale_error_std: f64,
}

impl SimImuConfig {
    /// A hobby-grade MEMS IMU (MPU-6000 class) at 100 Hz.
    pub fn mems_100hz() -> Self {
        Self {
            rate_hz: 100.0,
            gyro_noise_std_radps: 0.002,
            gyro_bias_std_radps: 0.005,
            gyro_bias_walk_radps_per_sqrt_s: 1e-4,
            gyro_scale_error_std: 0.005,
            accel_noise_std_mps2: 0.03,
            accel_bias_std_mps2: 0.05,
            accel_bias_walk_mps2_per_sqrt_s: 5e-4,
            accel_scale_error_std: 0.005,
        }
    }

    /// No errors at all: the IMU reads the truth.
    pub fn ideal() -> Self {
        Self {
            rate_hz: 100.0,
            gyro_noise_std_radps: 0.0,
            gyro_bias_std_radps: 0.0,
            gyro_bias_walk_radps_per_sqrt_s: 0.0,
            gyro_scale_error_std: 0.0,
            accel_noise_std_mps2: 0.0,
            accel_bias_std_mps2: 0.0,
            accel_bias_walk_mps2_per_sqrt_s: 0.0,
            accel_scale_error_std: 0.0,
        }
    }
}

impl Default for SimImuConfig {
    fn default() -> Self {
        Self::mems_100hz()
    }
}

/// One IMU reading, body FRD axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimImuReading {
    /// Plant time of the reading (s).
    pub t_s: f64,
    /// (p, q, r) (rad/s).
    pub gyro_radps: Vec3,
    /// Specific force (m/s²): (0, 0, −9.80665) level at rest.
    pub specific_force_mps2: Vec3,
}

#[derive(Debug, Clone)]
pub struct SimImu {
    config: SimImuConfig,
    rng: NoiseRng,
    gyro_bias: Vec3,
    accel_bias: Vec3,
    gyro_scale: Vec3,
    accel_scale: Vec3,
    last_t_s: Option<f64>,
}

impl SimImu {
    pub fn new(config: SimImuConfig, mut rng: NoiseRng) -> Self {
        let mut draw = |std: f64| {
            let z = rng.normal3();
            [z[0] * std, z[1] * std, z[2] * std]
        };
        let gyro_bias = draw(config.gyro_bias_std_radps);
        let accel_bias = draw(config.accel_bias_std_mps2);
        let gs = draw(config.gyro_scale_error_std);
        let a_s = draw(config.accel_scale_error_std);
        Self {
            config,
            rng,
            gyro_bias,
            accel_bias,
            gyro_scale: [1.0 + gs[0], 1.0 + gs[1], 1.0 + gs[2]],
            accel_scale: [1.0 + a_s[0], 1.0 + a_s[1], 1.0 + a_s[2]],
            last_t_s: None,
        }
    }

    pub fn config(&self) -> &SimImuConfig {
        &self.config
    }

    pub fn period_s(&self) -> f64 {
        1.0 / self.config.rate_hz
    }

    /// Current true biases (gyro rad/s, accel m/s²), for estimator tests.
    pub fn biases(&self) -> (Vec3, Vec3) {
        (self.gyro_bias, self.accel_bias)
    }

    /// A reading of the true rates and specific force at `t_s`: scale error, bias (after its
    /// random walk since the previous reading), white noise.
    pub fn sample(
        &mut self,
        t_s: f64,
        rates_radps: Vec3,
        specific_force_mps2: Vec3,
    ) -> SimImuReading {
        let dt = self.last_t_s.map_or(0.0, |last| (t_s - last).max(0.0));
        self.last_t_s = Some(t_s);
        let c = self.config;
        let walk_g = c.gyro_bias_walk_radps_per_sqrt_s * dt.sqrt();
        let walk_a = c.accel_bias_walk_mps2_per_sqrt_s * dt.sqrt();
        let mut gyro = [0.0; 3];
        let mut accel = [0.0; 3];
        for i in 0..3 {
            self.gyro_bias[i] += walk_g * self.rng.normal();
            self.accel_bias[i] += walk_a * self.rng.normal();
            gyro[i] = self.gyro_scale[i] * rates_radps[i]
                + self.gyro_bias[i]
                + c.gyro_noise_std_radps * self.rng.normal();
            accel[i] = self.accel_scale[i] * specific_force_mps2[i]
                + self.accel_bias[i]
                + c.accel_noise_std_mps2 * self.rng.normal();
        }
        SimImuReading {
            t_s,
            gyro_radps: gyro,
            specific_force_mps2: accel,
        }
    }
}

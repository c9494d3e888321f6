//! The IMU: scale errors, turn-on biases with a random walk, white noise, and the airframe's
//! vibration. Each reading is the mean of the truth over its period, as a real IMU's delta
//! angle / internal low-pass gives it, not the value at the instant it is read.

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
    /// White noise the airframe adds to one reading while the motor runs (motor and
    /// propeller vibration), per axis, on top of the sensor's own noise.
    pub vibration_gyro_std_radps: Vec3,
    pub vibration_accel_std_mps2: Vec3,
}

impl SimImuConfig {
    /// A hobby-grade MEMS IMU (MPU-6000 class) at 100 Hz, on a bench: the sensor's own noise
    /// only. A Cube Orange at rest (`tests/data/px4-cubeorange-vtol-ground-6s.ulg`) shows
    /// 1.5-1.9e-4 rad/√s and 1.3-2.2e-3 m/s/√s, i.e. 0.0019 rad/s and 0.02 m/s² per 10 ms.
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
            vibration_gyro_std_radps: [0.0; 3],
            vibration_accel_std_mps2: [0.0; 3],
        }
    }

    /// The same IMU in a flying airframe: the vibration a real one shows. From the PX4
    /// fixed-wing flight `shared/data/real-flights/px4-fixedwing-zurich-100s.ulg` (136 Hz
    /// `sensor_combined`, ground speed over 8 m/s, 11 224 samples): the first differences of
    /// successive samples / √2 give white-noise densities of 1.2e-3, 2.3e-3, 4.0e-4 rad/√s
    /// (x, y, z) and 8.7e-3, 7.3e-3, 3.8e-2 m/s/√s, i.e. per 10 ms reading the figures below,
    /// 6-11× the bench gyro and 3-13× the bench accelerometer.
    pub fn airframe_100hz() -> Self {
        Self {
            vibration_gyro_std_radps: [0.012, 0.023, 0.004],
            vibration_accel_std_mps2: [0.087, 0.073, 0.38],
            ..Self::mems_100hz()
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
            vibration_gyro_std_radps: [0.0; 3],
            vibration_accel_std_mps2: [0.0; 3],
        }
    }
}

impl Default for SimImuConfig {
    fn default() -> Self {
        Self::airframe_100hz()
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
    /// The truth integrated since the last reading (∫ω dt, ∫f dt, ∫dt).
    rate_integral: Vec3,
    force_integral: Vec3,
    integrated_s: f64,
    motor_running: bool,
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
            rate_integral: [0.0; 3],
            force_integral: [0.0; 3],
            integrated_s: 0.0,
            motor_running: false,
        }
    }

    /// Whether the motor runs, and so shakes the IMU (the vibration figures).
    pub fn set_motor_running(&mut self, running: bool) {
        self.motor_running = running;
    }

    /// The truth over a plant step of `h_s` ending now: the next reading is the mean of
    /// these steps.
    pub fn integrate(&mut self, h_s: f64, rates_radps: Vec3, specific_force_mps2: Vec3) {
        if h_s.is_nan() || h_s <= 0.0 {
            return;
        }
        for i in 0..3 {
            self.rate_integral[i] += rates_radps[i] * h_s;
            self.force_integral[i] += specific_force_mps2[i] * h_s;
        }
        self.integrated_s += h_s;
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

    /// A reading at `t_s`: the mean of the truth [`integrate`](Self::integrate)d since the
    /// previous reading (the given instantaneous truth if none was), with scale error, bias
    /// (after its random walk since the previous reading), white noise and vibration.
    pub fn sample(
        &mut self,
        t_s: f64,
        rates_radps: Vec3,
        specific_force_mps2: Vec3,
    ) -> SimImuReading {
        let dt = self.last_t_s.map_or(0.0, |last| (t_s - last).max(0.0));
        self.last_t_s = Some(t_s);
        let c = self.config;
        let shaking = if self.motor_running { 1.0 } else { 0.0 };
        let (rates_radps, specific_force_mps2) = if self.integrated_s > 0.0 {
            let mean = |v: Vec3| v.map(|x| x / self.integrated_s);
            (mean(self.rate_integral), mean(self.force_integral))
        } else {
            (rates_radps, specific_force_mps2)
        };
        self.rate_integral = [0.0; 3];
        self.force_integral = [0.0; 3];
        self.integrated_s = 0.0;
        let walk_g = c.gyro_bias_walk_radps_per_sqrt_s * dt.sqrt();
        let walk_a = c.accel_bias_walk_mps2_per_sqrt_s * dt.sqrt();
        let mut gyro = [0.0; 3];
        let mut accel = [0.0; 3];
        for i in 0..3 {
            self.gyro_bias[i] += walk_g * self.rng.normal();
            self.accel_bias[i] += walk_a * self.rng.normal();
            gyro[i] = self.gyro_scale[i] * rates_radps[i]
                + self.gyro_bias[i]
                + c.gyro_noise_std_radps * self.rng.normal()
                + shaking * c.vibration_gyro_std_radps[i] * self.rng.normal();
            accel[i] = self.accel_scale[i] * specific_force_mps2[i]
                + self.accel_bias[i]
                + c.accel_noise_std_mps2 * self.rng.normal()
                + shaking * c.vibration_accel_std_mps2[i] * self.rng.normal();
        }
        SimImuReading {
            t_s,
            gyro_radps: gyro,
            specific_force_mps2: accel,
        }
    }
}

//! Sensor models: IMU, GPS receiver and the two battery packs. Each owns a seeded noise
//! stream, so a run is reproducible for a seed however often each sensor is read.

use std::collections::VecDeque;

use super::math::Vec3;
use super::rng::NoiseRng;

// ---------------------------------------------------------------------------------------
// IMU
// ---------------------------------------------------------------------------------------

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

// ---------------------------------------------------------------------------------------
// GPS
// ---------------------------------------------------------------------------------------

/// A WGS-84 geodetic position: latitude and longitude in degrees, altitude above mean sea
/// level in metres (the geoid is not modelled: MSL = ellipsoid height here).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeodeticPosition {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_msl_m: f64,
}

impl Default for GeodeticPosition {
    /// The usual software-in-the-loop home field (Zurich), as good as any.
    fn default() -> Self {
        Self {
            lat_deg: 47.397742,
            lon_deg: 8.545594,
            alt_msl_m: 488.0,
        }
    }
}

const WGS84_A_M: f64 = 6_378_137.0;
const WGS84_E2: f64 = 6.694_379_990_14e-3;

/// Meridian and prime-vertical radii of curvature at `lat` (rad).
fn radii_of_curvature(lat: f64) -> (f64, f64) {
    let s = lat.sin();
    let w = (1.0 - WGS84_E2 * s * s).sqrt();
    (WGS84_A_M * (1.0 - WGS84_E2) / (w * w * w), WGS84_A_M / w)
}

impl GeodeticPosition {
    /// The point `ned_m` from this one, on the tangent plane (good to centimetres within a few
    /// kilometres, which is the simulator's flying field).
    pub fn offset_by_ned(&self, ned_m: Vec3) -> GeodeticPosition {
        let lat0 = self.lat_deg.to_radians();
        let (r_n, r_e) = radii_of_curvature(lat0);
        let h = self.alt_msl_m;
        GeodeticPosition {
            lat_deg: self.lat_deg + (ned_m[0] / (r_n + h)).to_degrees(),
            lon_deg: self.lon_deg + (ned_m[1] / ((r_e + h) * lat0.cos())).to_degrees(),
            alt_msl_m: h - ned_m[2],
        }
    }

    /// The inverse of [`offset_by_ned`](Self::offset_by_ned): `other` in NED from `self`.
    pub fn ned_to(&self, other: &GeodeticPosition) -> Vec3 {
        let lat0 = self.lat_deg.to_radians();
        let (r_n, r_e) = radii_of_curvature(lat0);
        let h = self.alt_msl_m;
        [
            (other.lat_deg - self.lat_deg).to_radians() * (r_n + h),
            (other.lon_deg - self.lon_deg).to_radians() * (r_e + h) * lat0.cos(),
            h - other.alt_msl_m,
        ]
    }
}

/// GPS receiver model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimGpsConfig {
    pub home: GeodeticPosition,
    /// Mean time between fixes (s), peaks included.
    pub mean_interval_s: f64,
    /// Ordinary intervals vary uniformly by ± this (s).
    pub interval_jitter_s: f64,
    /// Probability that an interval is a peak (a late fix).
    pub peak_probability: f64,
    /// Length of a peak interval (s).
    pub peak_interval_s: f64,
    /// Delay from the time a fix is valid to the time it is available (s).
    pub latency_s: f64,
    /// White position noise at the nominal DOP (1σ, m).
    pub horizontal_noise_std_m: f64,
    pub vertical_noise_std_m: f64,
    /// Gauss–Markov position drift (1σ, m) and its correlation time (s).
    pub horizontal_drift_std_m: f64,
    pub vertical_drift_std_m: f64,
    pub drift_time_constant_s: f64,
    /// White velocity noise (1σ, m/s), horizontal and vertical.
    pub horizontal_velocity_noise_std_mps: f64,
    pub vertical_velocity_noise_std_mps: f64,
    /// Probability, per fix, that an outage (no valid fix) begins.
    pub outage_probability: f64,
    /// Outage length drawn uniformly from this range (s).
    pub outage_duration_s: (f64, f64),
    /// Probability, per fix, that the constellation changes (satellite count and DOPs).
    pub constellation_change_probability: f64,
    /// Satellite count drawn uniformly from this range on a change.
    pub satellites: (u8, u8),
    /// HDOP and VDOP with `nominal_satellites` in view; they scale as √(nominal/count).
    pub nominal_hdop: f64,
    pub nominal_vdop: f64,
    pub nominal_satellites: u8,
}

impl SimGpsConfig {
    /// A u-blox-class receiver at a clean 10 Hz.
    pub fn nominal_10hz() -> Self {
        Self {
            home: GeodeticPosition::default(),
            mean_interval_s: 0.1,
            interval_jitter_s: 0.005,
            peak_probability: 0.0,
            peak_interval_s: 0.3,
            latency_s: 0.08,
            horizontal_noise_std_m: 0.4,
            vertical_noise_std_m: 0.8,
            horizontal_drift_std_m: 1.5,
            vertical_drift_std_m: 3.0,
            drift_time_constant_s: 60.0,
            horizontal_velocity_noise_std_mps: 0.08,
            vertical_velocity_noise_std_mps: 0.15,
            outage_probability: 0.0005,
            outage_duration_s: (0.5, 3.0),
            constellation_change_probability: 0.01,
            satellites: (7, 14),
            nominal_hdop: 0.9,
            nominal_vdop: 1.4,
            nominal_satellites: 10,
        }
    }

    /// What the seed airframe's receiver did: nominally 10 Hz, but a 140 ms mean interval with
    /// 300 ms peaks.
    pub fn seed_receiver() -> Self {
        Self {
            mean_interval_s: 0.14,
            interval_jitter_s: 0.02,
            peak_probability: 0.1,
            peak_interval_s: 0.3,
            ..Self::nominal_10hz()
        }
    }

    /// No noise, drift, jitter, outages or constellation changes: exact fixes every 100 ms
    /// (latency kept).
    pub fn ideal() -> Self {
        Self {
            interval_jitter_s: 0.0,
            horizontal_noise_std_m: 0.0,
            vertical_noise_std_m: 0.0,
            horizontal_drift_std_m: 0.0,
            vertical_drift_std_m: 0.0,
            horizontal_velocity_noise_std_mps: 0.0,
            vertical_velocity_noise_std_mps: 0.0,
            outage_probability: 0.0,
            constellation_change_probability: 0.0,
            ..Self::nominal_10hz()
        }
    }
}

impl Default for SimGpsConfig {
    fn default() -> Self {
        Self::nominal_10hz()
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GpsFixType {
    NoFix,
    Fix3d,
}

/// One receiver solution. When `fix` is [`GpsFixType::NoFix`], position and velocity repeat
/// the last valid solution (or home and zero) and the standard deviations are large: a
/// consumer must check `fix`, but nothing here is ever NaN.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimGpsSolution {
    /// Plant time at which the solution is valid (s).
    pub valid_at_s: f64,
    /// Plant time from which the receiver delivers it (s): `valid_at_s + latency`.
    pub available_at_s: f64,
    pub fix: GpsFixType,
    pub position: GeodeticPosition,
    pub velocity_ned_mps: Vec3,
    pub hdop: f64,
    pub vdop: f64,
    pub satellites: u8,
    /// Reported 1σ accuracies.
    pub horizontal_std_m: f64,
    pub vertical_std_m: f64,
    pub speed_std_mps: f64,
}

/// Accuracy a receiver reports when it has no fix.
const NO_FIX_STD_M: f64 = 9_999.0;

#[derive(Debug, Clone)]
pub struct SimGpsReceiver {
    config: SimGpsConfig,
    rng: NoiseRng,
    next_fix_s: f64,
    last_fix_s: Option<f64>,
    drift_ned_m: Vec3,
    outage_until_s: f64,
    satellites: u8,
    pending: VecDeque<SimGpsSolution>,
    last_valid: Option<(GeodeticPosition, Vec3)>,
}

impl SimGpsReceiver {
    pub fn new(config: SimGpsConfig, mut rng: NoiseRng) -> Self {
        // Draw the start of the drift from its stationary distribution, and the first fix
        // somewhere in the first interval, so runs do not all start in phase.
        let drift = [
            config.horizontal_drift_std_m * rng.normal(),
            config.horizontal_drift_std_m * rng.normal(),
            config.vertical_drift_std_m * rng.normal(),
        ];
        let first = rng.uniform() * config.mean_interval_s;
        Self {
            config,
            rng,
            next_fix_s: first,
            last_fix_s: None,
            drift_ned_m: drift,
            outage_until_s: f64::NEG_INFINITY,
            satellites: config.nominal_satellites,
            pending: VecDeque::new(),
            last_valid: None,
        }
    }

    pub fn config(&self) -> &SimGpsConfig {
        &self.config
    }

    /// Length of the next interval between fixes: ordinary intervals are shortened so that,
    /// with the peaks, the mean is `mean_interval_s`.
    fn draw_interval(&mut self) -> f64 {
        let c = &self.config;
        let p = c.peak_probability.clamp(0.0, 0.999);
        let base = ((c.mean_interval_s - p * c.peak_interval_s) / (1.0 - p)).max(1e-3);
        let (jitter, peak) = (c.interval_jitter_s, c.peak_interval_s);
        if self.rng.chance(p) {
            peak
        } else {
            (base + self.rng.uniform_in(-jitter, jitter)).max(1e-3)
        }
    }

    /// Advances the receiver to `t_s` with the true position and velocity there: produces the
    /// fixes that fall due (each is delivered `latency_s` later by [`Self::take`]).
    pub fn update(&mut self, t_s: f64, position_ned_m: Vec3, velocity_ned_mps: Vec3) {
        while t_s >= self.next_fix_s {
            let valid_at = self.next_fix_s;
            // The fix fell due up to one plant step ago: take the position back to then.
            let back = t_s - valid_at;
            let position_then = [
                position_ned_m[0] - velocity_ned_mps[0] * back,
                position_ned_m[1] - velocity_ned_mps[1] * back,
                position_ned_m[2] - velocity_ned_mps[2] * back,
            ];
            let sample = self.make_fix(valid_at, position_then, velocity_ned_mps);
            self.pending.push_back(sample);
            self.last_fix_s = Some(valid_at);
            let interval = self.draw_interval();
            self.next_fix_s += interval;
        }
    }

    fn make_fix(&mut self, t_s: f64, pos: Vec3, vel: Vec3) -> SimGpsSolution {
        let c = self.config;
        let dt = self.last_fix_s.map_or(0.0, |last| t_s - last);
        // First-order Gauss–Markov drift, stepped exactly over the interval.
        let phi = (-dt / c.drift_time_constant_s.max(1e-9)).exp();
        let k = (1.0 - phi * phi).sqrt();
        let stds = [
            c.horizontal_drift_std_m,
            c.horizontal_drift_std_m,
            c.vertical_drift_std_m,
        ];
        for (d, s) in self.drift_ned_m.iter_mut().zip(stds) {
            *d = phi * *d + s * k * self.rng.normal();
        }
        if self.rng.chance(c.constellation_change_probability) {
            let (lo, hi) = c.satellites;
            let n = self.rng.uniform_in(lo as f64, hi as f64 + 1.0).floor();
            self.satellites = (n as u8).clamp(lo.min(hi), hi.max(lo));
        }
        if t_s >= self.outage_until_s && self.rng.chance(c.outage_probability) {
            let (lo, hi) = c.outage_duration_s;
            self.outage_until_s = t_s + self.rng.uniform_in(lo, hi);
        }
        let available_at_s = t_s + c.latency_s;
        if t_s < self.outage_until_s {
            let (position, velocity) = self.last_valid.unwrap_or((c.home, [0.0; 3]));
            return SimGpsSolution {
                valid_at_s: t_s,
                available_at_s,
                fix: GpsFixType::NoFix,
                position,
                velocity_ned_mps: velocity,
                hdop: 99.99,
                vdop: 99.99,
                satellites: self.satellites.min(3),
                horizontal_std_m: NO_FIX_STD_M,
                vertical_std_m: NO_FIX_STD_M,
                speed_std_mps: NO_FIX_STD_M,
            };
        }
        let dop_scale = (c.nominal_satellites.max(1) as f64 / self.satellites.max(4) as f64).sqrt();
        let hdop = c.nominal_hdop * dop_scale;
        let vdop = c.nominal_vdop * dop_scale;
        let h_std = c.horizontal_noise_std_m * dop_scale;
        let v_std = c.vertical_noise_std_m * dop_scale;
        let noisy_pos = [
            pos[0] + self.drift_ned_m[0] + h_std * self.rng.normal(),
            pos[1] + self.drift_ned_m[1] + h_std * self.rng.normal(),
            pos[2] + self.drift_ned_m[2] + v_std * self.rng.normal(),
        ];
        let hv = c.horizontal_velocity_noise_std_mps;
        let vv = c.vertical_velocity_noise_std_mps;
        let noisy_vel = [
            vel[0] + hv * self.rng.normal(),
            vel[1] + hv * self.rng.normal(),
            vel[2] + vv * self.rng.normal(),
        ];
        let position = c.home.offset_by_ned(noisy_pos);
        self.last_valid = Some((position, noisy_vel));
        // What a receiver reports: its error budget (drift and noise together), scaled by DOP.
        let h_total =
            (c.horizontal_drift_std_m.powi(2) * dop_scale * dop_scale + h_std * h_std).sqrt();
        let v_total =
            (c.vertical_drift_std_m.powi(2) * dop_scale * dop_scale + v_std * v_std).sqrt();
        SimGpsSolution {
            valid_at_s: t_s,
            available_at_s,
            fix: GpsFixType::Fix3d,
            position,
            velocity_ned_mps: noisy_vel,
            hdop,
            vdop,
            satellites: self.satellites,
            horizontal_std_m: h_total,
            vertical_std_m: v_total,
            speed_std_mps: hv.max(vv) * dop_scale,
        }
    }

    /// The oldest fix available at `t_s`, if any (call until `None` to drain).
    pub fn take(&mut self, t_s: f64) -> Option<SimGpsSolution> {
        if self.pending.front()?.available_at_s <= t_s {
            self.pending.pop_front()
        } else {
            None
        }
    }
}

// ---------------------------------------------------------------------------------------
// Batteries
// ---------------------------------------------------------------------------------------

/// One lithium-polymer pack: open-circuit voltage from the state of charge, an ohmic drop and
/// a first-order polarisation (RC) drop, so the voltage sags at once under load, sags a bit
/// more over seconds, and recovers when the load goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackConfig {
    pub cells: u32,
    pub capacity_ah: f64,
    pub internal_resistance_ohm: f64,
    pub polarisation_resistance_ohm: f64,
    pub polarisation_time_constant_s: f64,
    /// State of charge at start, 0..1.
    pub initial_charge: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatteryConfig {
    /// Flight computer, radios, sensors.
    pub avionics: PackConfig,
    /// Avionics draw (A); it varies a little around this.
    pub avionics_load_a: f64,
    /// Motor (through the ESC) and servos.
    pub propulsion: PackConfig,
    /// Servo draw (A): idle plus a part proportional to how hard the surfaces are held over.
    pub servo_idle_a: f64,
    pub servo_load_a_per_unit_command: f64,
    /// Measurement noise (1σ).
    pub voltage_noise_std_v: f64,
    pub current_noise_std_a: f64,
}

impl BatteryConfig {
    pub fn aerosonde() -> Self {
        Self {
            avionics: PackConfig {
                cells: 3,
                capacity_ah: 2.2,
                internal_resistance_ohm: 0.03,
                polarisation_resistance_ohm: 0.02,
                polarisation_time_constant_s: 20.0,
                initial_charge: 1.0,
            },
            avionics_load_a: 1.2,
            propulsion: PackConfig {
                cells: 12,
                capacity_ah: 10.0,
                internal_resistance_ohm: 0.04,
                polarisation_resistance_ohm: 0.025,
                polarisation_time_constant_s: 30.0,
                initial_charge: 1.0,
            },
            servo_idle_a: 0.3,
            servo_load_a_per_unit_command: 0.8,
            voltage_noise_std_v: 0.02,
            current_noise_std_a: 0.1,
        }
    }
}

impl Default for BatteryConfig {
    fn default() -> Self {
        Self::aerosonde()
    }
}

/// Open-circuit voltage of one LiPo cell against state of charge (piecewise linear).
pub fn lipo_cell_ocv_v(charge: f64) -> f64 {
    const TABLE: [(f64, f64); 8] = [
        (0.0, 3.0),
        (0.05, 3.3),
        (0.1, 3.5),
        (0.2, 3.65),
        (0.5, 3.8),
        (0.8, 3.95),
        (0.9, 4.05),
        (1.0, 4.2),
    ];
    let x = charge.clamp(0.0, 1.0);
    for w in TABLE.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if x <= x1 {
            return y0 + (y1 - y0) * (x - x0) / (x1 - x0);
        }
    }
    TABLE[TABLE.len() - 1].1
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackState {
    pub charge: f64,
    pub polarisation_v: f64,
    pub current_a: f64,
    pub voltage_v: f64,
}

fn pack_step(cfg: &PackConfig, s: &mut PackState, current_a: f64, dt_s: f64) {
    s.current_a = current_a;
    s.charge = (s.charge - current_a * dt_s / (3600.0 * cfg.capacity_ah)).clamp(0.0, 1.0);
    let tau = cfg.polarisation_time_constant_s.max(1e-6);
    let phi = (-dt_s / tau).exp();
    s.polarisation_v =
        phi * s.polarisation_v + (1.0 - phi) * current_a * cfg.polarisation_resistance_ohm;
    s.voltage_v = (cfg.cells as f64 * lipo_cell_ocv_v(s.charge)
        - current_a * cfg.internal_resistance_ohm
        - s.polarisation_v)
        .max(0.0);
}

fn pack_at_rest(cfg: &PackConfig) -> PackState {
    let charge = cfg.initial_charge.clamp(0.0, 1.0);
    PackState {
        charge,
        polarisation_v: 0.0,
        current_a: 0.0,
        voltage_v: cfg.cells as f64 * lipo_cell_ocv_v(charge),
    }
}

/// A reading of both packs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatterySample {
    pub t_s: f64,
    pub avionics_voltage_v: f64,
    pub avionics_current_a: f64,
    pub propulsion_voltage_v: f64,
    pub propulsion_current_a: f64,
}

#[derive(Debug, Clone)]
pub struct SimBatteries {
    config: BatteryConfig,
    rng: NoiseRng,
    avionics: PackState,
    propulsion: PackState,
}

impl SimBatteries {
    pub fn new(config: BatteryConfig, rng: NoiseRng) -> Self {
        Self {
            avionics: pack_at_rest(&config.avionics),
            propulsion: pack_at_rest(&config.propulsion),
            config,
            rng,
        }
    }

    /// Advances both packs by `dt_s`. `motor_current_a` is the motor winding current; the ESC
    /// draws `throttle ×` that from the pack (power in ≈ power out). `surface_effort` is the
    /// sum of |aileron|, |elevator|, |rudder| commands. A motor driven by the windmilling
    /// propeller does not charge the pack (the ESC does not regenerate).
    pub fn step(&mut self, dt_s: f64, throttle: f64, motor_current_a: f64, surface_effort: f64) {
        let c = &self.config;
        let esc_a = throttle * motor_current_a.max(0.0);
        let servo_a = c.servo_idle_a + c.servo_load_a_per_unit_command * surface_effort;
        pack_step(&c.propulsion, &mut self.propulsion, esc_a + servo_a, dt_s);
        pack_step(&c.avionics, &mut self.avionics, c.avionics_load_a, dt_s);
    }

    pub fn avionics(&self) -> &PackState {
        &self.avionics
    }

    pub fn propulsion(&self) -> &PackState {
        &self.propulsion
    }

    /// A noisy reading of both packs' voltage and current.
    pub fn sample(&mut self, t_s: f64) -> BatterySample {
        let vn = self.config.voltage_noise_std_v;
        let cn = self.config.current_noise_std_a;
        BatterySample {
            t_s,
            avionics_voltage_v: self.avionics.voltage_v + vn * self.rng.normal(),
            avionics_current_a: self.avionics.current_a + cn * self.rng.normal(),
            propulsion_voltage_v: self.propulsion.voltage_v + vn * self.rng.normal(),
            propulsion_current_a: self.propulsion.current_a + cn * self.rng.normal(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::rng::{NoiseRng, stream};
    use super::*;

    #[test]
    fn ideal_imu_reads_the_truth() {
        let mut imu = SimImu::new(SimImuConfig::ideal(), NoiseRng::new(3, stream::IMU));
        let s = imu.sample(0.01, [0.1, -0.2, 0.3], [0.0, 0.0, -9.80665]);
        assert_eq!(s.gyro_radps, [0.1, -0.2, 0.3]);
        assert_eq!(s.specific_force_mps2, [0.0, 0.0, -9.80665]);
    }

    #[test]
    fn imu_noise_and_bias_have_the_configured_size() {
        let cfg = SimImuConfig {
            gyro_bias_walk_radps_per_sqrt_s: 0.0,
            accel_bias_walk_mps2_per_sqrt_s: 0.0,
            ..SimImuConfig::mems_100hz()
        };
        let mut imu = SimImu::new(cfg, NoiseRng::new(5, stream::IMU));
        let (gb, _) = imu.biases();
        let n = 20_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for k in 0..n {
            let x = imu.sample(k as f64 * 0.01, [0.0; 3], [0.0; 3]).gyro_radps[0] - gb[0];
            s += x;
            s2 += x * x;
        }
        let std = (s2 / n as f64 - (s / n as f64).powi(2)).sqrt();
        assert!(
            (std - cfg.gyro_noise_std_radps).abs() < 0.1 * cfg.gyro_noise_std_radps,
            "{std}"
        );
        assert!((s / n as f64).abs() < 1e-4);
        // The bias walks when the walk is on.
        let mut walking = SimImu::new(SimImuConfig::mems_100hz(), NoiseRng::new(5, stream::IMU));
        let before = walking.biases().0;
        walking.sample(0.0, [0.0; 3], [0.0; 3]);
        walking.sample(100.0, [0.0; 3], [0.0; 3]);
        assert_ne!(before, walking.biases().0);
    }

    #[test]
    fn geodetic_offsets_round_trip_and_have_the_right_size() {
        let home = GeodeticPosition::default();
        let p = home.offset_by_ned([1000.0, -500.0, -120.0]);
        // A degree of latitude is about 111.2 km at 47°.
        assert!(((p.lat_deg - home.lat_deg) * 111_200.0 - 1000.0).abs() < 5.0);
        assert!(p.lon_deg < home.lon_deg);
        assert!((p.alt_msl_m - (home.alt_msl_m + 120.0)).abs() < 1e-9);
        let back = home.ned_to(&p);
        for (a, b) in back.iter().zip([1000.0, -500.0, -120.0]) {
            assert!((a - b).abs() < 1e-6, "{back:?}");
        }
    }

    fn fix_times(cfg: SimGpsConfig, seconds: f64) -> Vec<f64> {
        let mut gps = SimGpsReceiver::new(cfg, NoiseRng::new(11, stream::GPS));
        let dt = 0.001;
        let mut times = Vec::new();
        for k in 0..(seconds / dt) as usize {
            let t = k as f64 * dt;
            gps.update(t, [0.0; 3], [0.0; 3]);
            while let Some(s) = gps.take(t) {
                assert!(s.available_at_s - s.valid_at_s - cfg.latency_s < 1e-9);
                assert!(s.available_at_s <= t);
                times.push(s.valid_at_s);
            }
        }
        times
    }

    #[test]
    fn gps_interval_statistics_match_the_configuration() {
        for cfg in [SimGpsConfig::nominal_10hz(), SimGpsConfig::seed_receiver()] {
            let times = fix_times(cfg, 600.0);
            let intervals: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
            let mean = intervals.iter().sum::<f64>() / intervals.len() as f64;
            let max = intervals.iter().cloned().fold(0.0, f64::max);
            assert!(
                (mean - cfg.mean_interval_s).abs() < 0.03 * cfg.mean_interval_s,
                "mean {mean} vs {}",
                cfg.mean_interval_s
            );
            if cfg.peak_probability > 0.0 {
                assert!((max - cfg.peak_interval_s).abs() < 1e-9, "max {max}");
            } else {
                assert!(
                    max <= cfg.mean_interval_s + cfg.interval_jitter_s + 1e-9,
                    "max {max}"
                );
            }
        }
    }

    #[test]
    fn gps_has_outages_and_dop_changes_but_never_nan() {
        let cfg = SimGpsConfig {
            outage_probability: 0.01,
            constellation_change_probability: 0.05,
            ..SimGpsConfig::nominal_10hz()
        };
        let mut gps = SimGpsReceiver::new(cfg, NoiseRng::new(2, stream::GPS));
        let (mut no_fix, mut fixes) = (0, 0);
        let mut hdops = Vec::new();
        for k in 0..60_000 {
            let t = k as f64 * 0.01;
            gps.update(t, [10.0, 20.0, -30.0], [25.0, 0.0, 0.0]);
            while let Some(s) = gps.take(t) {
                assert!(s.position.lat_deg.is_finite() && s.hdop.is_finite());
                match s.fix {
                    GpsFixType::NoFix => no_fix += 1,
                    GpsFixType::Fix3d => {
                        fixes += 1;
                        hdops.push(s.hdop);
                    }
                }
            }
        }
        // Outages start on 1 % of fixes and last 1.75 s on average: about a sixth of the time.
        assert!(
            no_fix > 300 && no_fix < 2_000 && fixes > 4_000,
            "{no_fix} {fixes}"
        );
        let lo = hdops.iter().cloned().fold(f64::MAX, f64::min);
        let hi = hdops.iter().cloned().fold(0.0, f64::max);
        assert!(hi > lo * 1.2, "DOP never changed: {lo}..{hi}");
    }

    #[test]
    fn gps_error_is_of_the_configured_size() {
        let cfg = SimGpsConfig::nominal_10hz();
        let mut gps = SimGpsReceiver::new(cfg, NoiseRng::new(4, stream::GPS));
        let home = cfg.home;
        let mut sum2 = 0.0;
        let mut n = 0;
        for k in 0..360_000 {
            let t = k as f64 * 0.01;
            gps.update(t, [0.0; 3], [0.0; 3]);
            while let Some(s) = gps.take(t) {
                if s.fix == GpsFixType::Fix3d {
                    let e = home.ned_to(&s.position);
                    sum2 += e[0] * e[0];
                    n += 1;
                }
            }
        }
        let rms = (sum2 / n as f64).sqrt();
        let want = (cfg.horizontal_drift_std_m.powi(2) + cfg.horizontal_noise_std_m.powi(2)).sqrt();
        // Drift with a 60 s correlation time over an hour: a loose check.
        assert!(
            rms > 0.5 * want && rms < 2.0 * want,
            "rms {rms} want {want}"
        );
    }

    #[test]
    fn battery_sags_under_load_and_recovers() {
        let mut b = SimBatteries::new(
            BatteryConfig::aerosonde(),
            NoiseRng::new(1, stream::BATTERY),
        );
        let rest = b.propulsion().voltage_v;
        assert!((rest - 12.0 * 4.2).abs() < 1e-9);
        b.step(0.01, 1.0, 40.0, 0.0);
        let loaded = b.propulsion().voltage_v;
        assert!(rest - loaded > 1.0, "instant sag {rest} → {loaded}");
        for _ in 0..3000 {
            b.step(0.01, 1.0, 40.0, 0.0);
        }
        let later = b.propulsion().voltage_v;
        assert!(later < loaded, "discharge and polarisation");
        for _ in 0..100 {
            b.step(0.01, 0.0, 0.0, 0.0);
        }
        assert!(
            b.propulsion().voltage_v > later + 1.0,
            "recovers without load"
        );
        assert!(b.propulsion().charge < 1.0 && b.avionics().charge < 1.0);
        let s = b.sample(31.0);
        assert!((s.propulsion_voltage_v - b.propulsion().voltage_v).abs() < 0.2);
    }
}

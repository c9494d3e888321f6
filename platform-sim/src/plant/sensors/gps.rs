//! The GPS receiver: WGS-84 positions, jittery fix intervals, latency, noise and outages.

use std::collections::VecDeque;

use super::super::math::Vec3;
use super::super::rng::NoiseRng;

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

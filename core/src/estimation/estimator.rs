//! The estimator: the start-up alignment, the heading, the home point and the EKF, from raw
//! IMU samples, GPS fixes and horizon measurements to an [`Estimate`] with its health.
//!
//! Phases: [`Phase::Aligning`] (the vehicle must be at rest; progress 0–100 %) →
//! [`Phase::AwaitingHeading`] (the filter runs, but its yaw is a guess: GPS updates only
//! while at rest, and the estimate is not healthy) → [`Phase::Running`]. The heading comes from
//! [`HeadingSource`]: configured, or the first GPS course over ground above a speed.
//!
//! A vehicle that never rests for the alignment (a hand launch, a gust rocking it on the
//! runway, a take-off straight away) starts **in motion** instead: at the first GPS course
//! above the heading speed, yaw from that course, roll and pitch from the recent specific
//! force with the GPS-measured acceleration taken out of it, the gyro bias from the longest
//! stretch it did rest (else unknown), and a wide tilt σ that the GPS velocity updates narrow
//! before the estimate is called healthy.

use nalgebra::Vector3;

use super::alignment::{Alignment, AlignmentConfig, AlignmentResult, level};
use super::ekf::{
    BA, BG, Ekf, EkfConfig, EkfCounters, GRAVITY_MPS2, GpsMeasurement, NominalState, P, TH,
    UpdateOutcome, V,
};
use super::geo::{GeoPoint, LocalFrame};
use crate::devices::gps::GpsFix;
use crate::horizon::HorizonAttitude;

/// Where the initial yaw comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HeadingSource {
    /// A known heading (rad, from north, clockwise), e.g. the runway's.
    Configured { yaw_rad: f32 },
    /// The first GPS course over ground at or above this ground speed (m/s): on the take-off
    /// run the course is the heading; in the air it is off by the crab angle.
    GpsCourse { min_speed_mps: f32 },
}

#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EstimatorConfig {
    pub ekf: EkfConfig,
    pub alignment: AlignmentConfig,
    pub heading: HeadingSource,
    /// Yaw 1-σ once the heading is known (rad).
    pub heading_sd_rad: f32,
    /// Time from the receiver's measurement to the fix reaching the estimator (ns).
    pub gps_latency_ns: u64,
    /// The local frame's origin; `None`: the first valid fix.
    pub home: Option<GeoPoint>,
    /// Position σ assumed from a fix that reports none (m): horizontal × HDOP if known.
    pub gps_default_pos_sd_m: f32,
    pub gps_default_vel_sd_mps: f32,
    /// Health thresholds: roll/pitch 1-σ (rad), horizontal position 1-σ (m), GPS silence (ns).
    pub healthy_max_tilt_sd_rad: f32,
    pub healthy_max_pos_sd_m: f32,
    pub healthy_gps_timeout_ns: u64,
    /// Accepted GPS updates needed after a whole-filter reset before healthy again.
    pub updates_after_reset: u32,
    /// Start in motion (module comment) when the alignment has not finished by the first GPS
    /// course at the heading speed; roll/pitch 1-σ of that start (rad).
    pub start_in_motion: bool,
    pub in_motion_tilt_sd_rad: f32,
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        Self {
            ekf: EkfConfig::default(),
            alignment: AlignmentConfig::default(),
            heading: HeadingSource::GpsCourse { min_speed_mps: 5.0 },
            heading_sd_rad: 10f32.to_radians(),
            // The receiver's own latency (80 ms for a u-blox class receiver; the seed measured
            // 140 ms periods) plus, on average, half the 100 ms GPS task period before the
            // fix is read: `sim --score` fits 120-150 ms between a logged fix and the truth.
            gps_latency_ns: 140_000_000,
            home: None,
            gps_default_pos_sd_m: 2.5,
            gps_default_vel_sd_mps: 0.3,
            healthy_max_tilt_sd_rad: 5f32.to_radians(),
            healthy_max_pos_sd_m: 30.0,
            healthy_gps_timeout_ns: 5_000_000_000,
            updates_after_reset: 10,
            start_in_motion: true,
            // The levelling's error: the GPS acceleration (differenced 10 Hz velocities,
            // smoothed over 0.5 s) is good to ~0.3 m/s², ~2° of tilt, and the vehicle turns
            // while the specific force is averaged.
            in_motion_tilt_sd_rad: 5f32.to_radians(),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Phase {
    Aligning = 0,
    AwaitingHeading = 1,
    Running = 2,
}

/// Why the estimate is (not) healthy; the first that applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum HealthReason {
    Ok = 0,
    Aligning = 1,
    AwaitingHeading = 2,
    NoImu = 3,
    AttitudeUncertain = 4,
    PositionUncertain = 5,
    NoGps = 6,
    ReconvergingAfterReset = 7,
}

impl HealthReason {
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Ok => "ok",
            Self::Aligning => "aligning",
            Self::AwaitingHeading => "awaiting heading",
            Self::NoImu => "no IMU",
            Self::AttitudeUncertain => "attitude uncertain",
            Self::PositionUncertain => "position uncertain",
            Self::NoGps => "no GPS",
            Self::ReconvergingAfterReset => "reconverging after reset",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EstimatorHealth {
    pub phase: Phase,
    pub alignment_percent: u8,
    pub alignment_restarts: u32,
    pub healthy: bool,
    pub reason: HealthReason,
    pub counters: EkfCounters,
    /// Normalised innovation squared of the last GPS position and velocity updates (NaN if
    /// none).
    pub gps_pos_nis: f32,
    pub gps_vel_nis: f32,
}

/// What the estimator publishes: SI units, `conventions.md` frames, `f32` for the consumers.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Estimate {
    /// Executive time of the IMU sample the estimate is for.
    pub t_ns: u64,
    pub roll_rad: f32,
    pub pitch_rad: f32,
    pub yaw_rad: f32,
    /// Hamilton, scalar first (w, x, y, z), body FRD → NED.
    pub quaternion: [f32; 4],
    /// Bias-corrected body rates p, q, r.
    pub rates_radps: [f32; 3],
    pub velocity_ned_mps: [f32; 3],
    pub position_ned_m: [f32; 3],
    pub gyro_bias_radps: [f32; 3],
    pub accel_bias_mps2: [f32; 3],
    /// Error-state variances: δp, δv, δθ (NED), δb_g, δb_a.
    pub covariance_diag: [f32; 15],
    pub health: EstimatorHealth,
}

impl Estimate {
    /// Course over ground (rad, from north, clockwise) from the velocity.
    pub fn course_rad(&self) -> f32 {
        let [vn, ve, _] = self.velocity_ned_mps;
        libm::atan2f(ve, vn)
    }
    pub fn ground_speed_mps(&self) -> f32 {
        let [vn, ve, _] = self.velocity_ned_mps;
        libm::sqrtf(vn * vn + ve * ve)
    }
    /// Altitude above home (m, up).
    pub fn altitude_m(&self) -> f32 {
        -self.position_ned_m[2]
    }
}

fn f32s<const K: usize>(v: &nalgebra::SVector<f64, K>) -> [f32; K] {
    let mut out = [0f32; K];
    for (o, x) in out.iter_mut().zip(v.iter()) {
        *o = *x as f32;
    }
    out
}

fn vec3(a: [f32; 3]) -> Vector3<f64> {
    Vector3::new(f64::from(a[0]), f64::from(a[1]), f64::from(a[2]))
}

pub struct Estimator {
    config: EstimatorConfig,
    alignment: Alignment,
    aligned: Option<AlignmentResult>,
    ekf: Option<Ekf>,
    phase: Phase,
    frame: Option<LocalFrame>,
    has_position: bool,
    last_gps_accept_ns: Option<u64>,
    resets_seen: u32,
    accepted_since_reset: u32,
    gps_pos_nis: f32,
    gps_vel_nis: f32,
    t_ns: u64,
    /// While aligning, for a start in motion: the specific force and the GPS acceleration
    /// (NED), both smoothed over [`MOTION_SMOOTHING_S`], and the last fix's velocity.
    force_mean: Option<Vector3<f64>>,
    gps_accel_mean: Option<Vector3<f64>>,
    last_fix_velocity: Option<(u64, Vector3<f64>)>,
}

/// Time constant of the smoothing of the specific force and the GPS acceleration for a start
/// in motion (s): long enough to average the GPS velocity noise, short against a take-off run.
const MOTION_SMOOTHING_S: f64 = 0.5;

/// A stretch at rest shorter than this (samples) gives no gyro bias for a start in motion.
const MIN_REST_SAMPLES: u32 = 100;

/// Exponential smoothing of `mean` towards `x` over `dt_s`.
fn smooth(mean: &mut Option<Vector3<f64>>, x: Vector3<f64>, dt_s: f64) {
    let k = (dt_s / MOTION_SMOOTHING_S).clamp(0.0, 1.0);
    *mean = Some(match *mean {
        Some(m) => m + (x - m) * k,
        None => x,
    });
}

impl Estimator {
    pub fn new(config: EstimatorConfig) -> Self {
        Self {
            config,
            alignment: Alignment::new(config.alignment),
            aligned: None,
            ekf: None,
            phase: Phase::Aligning,
            frame: config.home.and_then(LocalFrame::new),
            has_position: false,
            last_gps_accept_ns: None,
            resets_seen: 0,
            accepted_since_reset: u32::MAX,
            gps_pos_nis: f32::NAN,
            gps_vel_nis: f32::NAN,
            t_ns: 0,
            force_mean: None,
            gps_accel_mean: None,
            last_fix_velocity: None,
        }
    }

    /// Back to the start: alignment again (the vehicle must be at rest).
    pub fn restart(&mut self) {
        *self = Self::new(self.config);
    }

    pub fn config(&self) -> &EstimatorConfig {
        &self.config
    }
    pub fn phase(&self) -> Phase {
        self.phase
    }
    pub fn ekf(&self) -> Option<&Ekf> {
        self.ekf.as_ref()
    }
    pub fn ekf_mut(&mut self) -> Option<&mut Ekf> {
        self.ekf.as_mut()
    }
    pub fn local_frame(&self) -> Option<&LocalFrame> {
        self.frame.as_ref()
    }

    /// One IMU sample (FRD rates rad/s, specific force m/s²) ending at `t_ns`, `dt_s` after
    /// the previous one.
    pub fn imu(&mut self, t_ns: u64, dt_s: f64, rates_radps: [f32; 3], specific_force: [f32; 3]) {
        self.t_ns = t_ns;
        let w = vec3(rates_radps);
        let f = vec3(specific_force);
        match self.phase {
            Phase::Aligning => {
                if f.iter().all(|x| x.is_finite()) && dt_s > 0.0 {
                    smooth(&mut self.force_mean, f, dt_s);
                }
                self.alignment.add(w, f);
                if let Some(result) = self.alignment.result() {
                    self.aligned = Some(result);
                    self.start_filter(t_ns, result);
                }
            }
            Phase::AwaitingHeading | Phase::Running => {
                if let Some(ekf) = self.ekf.as_mut() {
                    // A sample after an outage (the filter takes steps up to 0.1 s): bridge
                    // the outage, then the sample over its own frame.
                    if dt_s > 0.1 {
                        let frame_s = crate::devices::imu::IMU_FRAME_PERIOD_S;
                        let gap_s = dt_s - frame_s;
                        let gap_end_ns = t_ns.saturating_sub((frame_s * 1e9) as u64);
                        if ekf.bridge_gap(gap_end_ns, gap_s) {
                            ekf.propagate(t_ns, frame_s, w, f);
                            // Dead-reckoned: healthy again only once the GPS agrees, as
                            // after a reset.
                            self.accepted_since_reset = 0;
                        }
                    } else {
                        ekf.propagate(t_ns, dt_s, w, f);
                    }
                    let resets = ekf.counters().resets;
                    if resets != self.resets_seen {
                        self.resets_seen = resets;
                        self.accepted_since_reset = 0;
                    }
                }
            }
        }
    }

    fn start_filter(&mut self, t_ns: u64, a: AlignmentResult) {
        let (yaw, yaw_sd, phase) = match self.config.heading {
            HeadingSource::Configured { yaw_rad } => (
                f64::from(yaw_rad),
                f64::from(self.config.heading_sd_rad),
                Phase::Running,
            ),
            HeadingSource::GpsCourse { .. } => (0.0, core::f64::consts::PI, Phase::AwaitingHeading),
        };
        let mut x = NominalState::at_rest(a.attitude(yaw));
        x.gyro_bias_radps = a.gyro_bias_radps;
        x.accel_bias_mps2 = a.accel_bias_mps2;
        let mut config = self.config.ekf;
        // What the averaging left: the bias across gravity looks like a tilt, so roll and
        // pitch are known to about that bias over g.
        config.init_att_sd_rad = config
            .init_att_sd_rad
            .min((config.init_accel_bias_sd_mps2 / GRAVITY_MPS2).max(0.2f64.to_radians()));
        config.init_gyro_bias_sd_radps = config.init_gyro_bias_sd_radps.min(
            (a.rate_sd_radps / libm::sqrt(f64::from(self.config.alignment.samples.max(1))))
                .max(2e-4)
                * 3.0,
        );
        let ekf = Ekf::new(config, x, t_ns, yaw_sd);
        self.ekf = Some(ekf);
        self.phase = phase;
    }

    /// The start in motion (module comment) at a GPS course `course_rad`; `false` if there is
    /// no specific force to level with yet.
    fn start_in_motion(&mut self, course_rad: f64, velocity: Vector3<f64>) -> bool {
        let Some(f) = self.force_mean else {
            return false;
        };
        let a = self.gps_accel_mean.unwrap_or_else(Vector3::zeros);
        // f = Rᵀ(a − g): take the acceleration out in the body frame of the attitude found so
        // far; three rounds converge for accelerations well below g.
        let (mut roll, mut pitch) = level(&f);
        for _ in 0..3 {
            let q = nalgebra::UnitQuaternion::from_euler_angles(roll, pitch, course_rad);
            (roll, pitch) = level(&(f - q.inverse() * a));
        }
        let mut x = NominalState::at_rest(nalgebra::UnitQuaternion::from_euler_angles(
            roll, pitch, course_rad,
        ));
        x.velocity_ned_mps = velocity;
        let mut config = self.config.ekf;
        config.init_att_sd_rad = f64::from(self.config.in_motion_tilt_sd_rad);
        if let Some((bias, sd)) = self.alignment.rest_gyro_bias(MIN_REST_SAMPLES) {
            x.gyro_bias_radps = bias;
            config.init_gyro_bias_sd_radps =
                config.init_gyro_bias_sd_radps.min((3.0 * sd).max(2e-4));
        }
        let yaw_sd = f64::from(self.config.heading_sd_rad);
        self.ekf = Some(Ekf::new(config, x, self.t_ns, yaw_sd));
        self.phase = Phase::Running;
        self.has_position = false;
        // Healthy only after the GPS has had its say on the guessed tilt.
        self.accepted_since_reset = 0;
        true
    }

    /// While aligning: the GPS acceleration for a start in motion, and the start itself at
    /// the first course above the heading speed. `true` if the filter started.
    fn maybe_start_in_motion(&mut self, fix: &GpsFix) -> bool {
        let velocity = match fix.velocity_ned_mps {
            [Some(n), Some(e), d] => Some(Vector3::new(
                f64::from(n),
                f64::from(e),
                f64::from(d.unwrap_or(0.0)),
            )),
            _ => None,
        }
        .filter(|v| v.iter().all(|x| x.is_finite()));
        if let Some(v) = velocity {
            if let Some((t0, v0)) = self.last_fix_velocity {
                let dt = fix.received_ns.saturating_sub(t0) as f64 * 1e-9;
                if dt > 0.05 && dt < 1.0 {
                    smooth(&mut self.gps_accel_mean, (v - v0) / dt, dt);
                }
            }
            self.last_fix_velocity = Some((fix.received_ns, v));
        }
        let c = &self.config;
        let (true, HeadingSource::GpsCourse { min_speed_mps }, Some(speed), Some(course)) = (
            c.start_in_motion,
            c.heading,
            fix.ground_speed_mps,
            fix.course_rad,
        ) else {
            return false;
        };
        let Some(v) = velocity else {
            return false;
        };
        speed >= min_speed_mps && course.is_finite() && self.start_in_motion(f64::from(course), v)
    }

    /// Starts the filter at a known state, skipping the alignment and the heading (a warm
    /// start in flight, or a simulation started in the air). Position and velocity still
    /// wait for the first GPS fix as usual.
    pub fn start_from(&mut self, t_ns: u64, x: NominalState, yaw_sd_rad: f64) {
        self.t_ns = t_ns;
        self.ekf = Some(Ekf::new(self.config.ekf, x, t_ns, yaw_sd_rad));
        self.phase = Phase::Running;
        self.has_position = false;
    }

    /// A GPS epoch. Sets the home point on the first valid fix if none is configured.
    pub fn gps(&mut self, fix: &GpsFix) {
        if !fix.valid {
            return;
        }
        let point = match (fix.latitude_deg, fix.longitude_deg, fix.altitude_msl_m) {
            (Some(lat), Some(lon), Some(alt)) => Some(GeoPoint {
                latitude_deg: lat,
                longitude_deg: lon,
                altitude_m: alt,
            }),
            _ => None,
        };
        if self.frame.is_none() {
            self.frame = point.and_then(LocalFrame::new);
        }
        if self.phase == Phase::Aligning && self.ekf.is_none() {
            self.maybe_start_in_motion(fix);
        }
        let (Some(frame), Some(ekf)) = (self.frame.as_ref(), self.ekf.as_mut()) else {
            return;
        };
        let c = &self.config;
        let hdop = fix
            .hdop
            .filter(|h| h.is_finite() && *h > 0.0)
            .unwrap_or(1.0);
        let vdop = fix
            .vdop
            .filter(|h| h.is_finite() && *h > 0.0)
            .unwrap_or(1.5 * hdop);
        let [sn, se, sd] = fix.position_sd_m;
        let position_sd = Vector3::new(
            f64::from(sn.unwrap_or(c.gps_default_pos_sd_m * hdop)),
            f64::from(se.unwrap_or(c.gps_default_pos_sd_m * hdop)),
            f64::from(sd.unwrap_or(c.gps_default_pos_sd_m * vdop)),
        );
        let v = c.gps_default_vel_sd_mps;
        let m = GpsMeasurement {
            t_ns: fix.received_ns.saturating_sub(c.gps_latency_ns),
            position_ned_m: point
                .filter(GeoPoint::is_plausible)
                .map(|p| frame.to_ned(&p)),
            position_sd_m: position_sd,
            velocity_ned_mps: fix.velocity_ned_mps.map(|v| v.map(f64::from)),
            velocity_sd_mps: Vector3::new(f64::from(v), f64::from(v), f64::from(2.0 * v)),
        };

        if self.phase == Phase::AwaitingHeading {
            if let (HeadingSource::GpsCourse { min_speed_mps }, Some(speed), Some(course)) =
                (c.heading, fix.ground_speed_mps, fix.course_rad)
            {
                if speed >= min_speed_mps && course.is_finite() {
                    ekf.set_yaw(f64::from(course), f64::from(c.heading_sd_rad));
                    self.phase = Phase::Running;
                    // The velocity since the vehicle started moving was integrated with a
                    // guessed yaw: take position and velocity from the GPS.
                    if ekf.reset_to_gps(&m) {
                        self.has_position = true;
                        self.last_gps_accept_ns = Some(self.t_ns);
                    }
                    return;
                }
            }
            // While the yaw is a guess, velocity integrated along it is wrong as soon as the
            // vehicle moves, and the update would explain that with a tilt: no updates then.
            if self.phase == Phase::AwaitingHeading && fix.ground_speed_mps.is_none_or(|s| s > 0.5)
            {
                return;
            }
        }

        if !self.has_position {
            if ekf.reset_to_gps(&m) {
                self.has_position = true;
                self.last_gps_accept_ns = Some(self.t_ns);
            }
            return;
        }
        let out = ekf.update_gps(&m);
        self.gps_pos_nis = out.position_nis;
        self.gps_vel_nis = out.velocity_nis;
        if matches!(
            out.position,
            UpdateOutcome::Accepted | UpdateOutcome::ResetToMeasurement
        ) {
            self.last_gps_accept_ns = Some(self.t_ns);
            self.accepted_since_reset = self.accepted_since_reset.saturating_add(1);
        }
    }

    /// A horizon roll/pitch measurement from the link.
    pub fn horizon(&mut self, h: &HorizonAttitude) -> Option<UpdateOutcome> {
        if self.phase == Phase::Aligning {
            return None;
        }
        let ekf = self.ekf.as_mut()?;
        Some(ekf.update_horizon(
            h.capture_t_ns,
            f64::from(h.roll_rad),
            f64::from(h.pitch_rad),
            f64::from(h.confidence),
        ))
    }

    fn health(&self) -> EstimatorHealth {
        let c = &self.config;
        let reason = match (&self.ekf, self.phase) {
            (_, Phase::Aligning) | (None, _) => HealthReason::Aligning,
            (_, Phase::AwaitingHeading) => HealthReason::AwaitingHeading,
            (Some(ekf), Phase::Running) => {
                let p = ekf.covariance();
                let tilt_var = p[(TH, TH)].max(p[(TH + 1, TH + 1)]);
                let pos_var = p[(P, P)].max(p[(P + 1, P + 1)]);
                let max_tilt = f64::from(c.healthy_max_tilt_sd_rad);
                let max_pos = f64::from(c.healthy_max_pos_sd_m);
                let gps_silent = self
                    .last_gps_accept_ns
                    .is_none_or(|t| self.t_ns.saturating_sub(t) > c.healthy_gps_timeout_ns);
                if tilt_var > max_tilt * max_tilt {
                    HealthReason::AttitudeUncertain
                } else if gps_silent {
                    HealthReason::NoGps
                } else if pos_var > max_pos * max_pos {
                    HealthReason::PositionUncertain
                } else if self.accepted_since_reset < c.updates_after_reset {
                    HealthReason::ReconvergingAfterReset
                } else {
                    HealthReason::Ok
                }
            }
        };
        EstimatorHealth {
            phase: self.phase,
            alignment_percent: self.alignment.progress_percent(),
            alignment_restarts: self.alignment.restarts(),
            healthy: reason == HealthReason::Ok,
            reason,
            counters: self.ekf.as_ref().map(|e| *e.counters()).unwrap_or_default(),
            gps_pos_nis: self.gps_pos_nis,
            gps_vel_nis: self.gps_vel_nis,
        }
    }

    /// The current estimate. Before the alignment ends, the attitude is level, north, and
    /// the health says so.
    pub fn estimate(&self) -> Estimate {
        let health = self.health();
        let Some(ekf) = self.ekf.as_ref() else {
            return Estimate {
                t_ns: self.t_ns,
                roll_rad: 0.0,
                pitch_rad: 0.0,
                yaw_rad: 0.0,
                quaternion: [1.0, 0.0, 0.0, 0.0],
                rates_radps: [0.0; 3],
                velocity_ned_mps: [0.0; 3],
                position_ned_m: [0.0; 3],
                gyro_bias_radps: [0.0; 3],
                accel_bias_mps2: [0.0; 3],
                covariance_diag: [f32::NAN; 15],
                health,
            };
        };
        let x = ekf.state();
        let (roll, pitch, yaw) = x.euler();
        let q = x.attitude.quaternion();
        Estimate {
            t_ns: self.t_ns,
            roll_rad: roll as f32,
            pitch_rad: pitch as f32,
            yaw_rad: yaw as f32,
            quaternion: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
            rates_radps: f32s(&ekf.rates()),
            velocity_ned_mps: f32s(&x.velocity_ned_mps),
            position_ned_m: f32s(&x.position_ned_m),
            gyro_bias_radps: f32s(&x.gyro_bias_radps),
            accel_bias_mps2: f32s(&x.accel_bias_mps2),
            covariance_diag: f32s(&ekf.covariance().diagonal()),
            health,
        }
    }
}

// The block offsets are part of the published covariance layout.
const _: () = assert!(P == 0 && V == 3 && TH == 6 && BG == 9 && BA == 12);

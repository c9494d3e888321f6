//! The 15-state error-state (multiplicative) extended Kalman filter.
//!
//! Nominal state: position and velocity in NED, attitude `q` (Hamilton, scalar first, body
//! FRD → NED, `conventions.md`), gyro bias, accelerometer bias. Error state, in this order:
//! `δp (0..3), δv (3..6), δθ (6..9), δb_g (9..12), δb_a (12..15)`. The attitude error is a
//! small rotation in the **NED** frame (`q_true = Exp(δθ) ⊗ q`), so a yaw error is exactly
//! `δθ_z` and the error dynamics need no body-rate term:
//!
//! ```text
//! δṗ = δv
//! δv̇ = −[R(f − b_a)]× δθ − R δb_a − R n_a
//! δθ̇ = −R δb_g − R n_g
//! δḃ_g = n_bg,   δḃ_a = n_ba
//! ```
//!
//! Discretised to first order at the IMU rate (`F = I + A·dt`, `Q = diag(σ²·dt)` from the
//! noise densities). Everything runs in `f64`: it costs little on the flight computer and
//! keeps the covariance well conditioned over long flights.
//!
//! **Measurement delay**: the GPS solution (and a horizon image) describes the vehicle some
//! 100 ms before it reaches the filter. The filter keeps a ring of its past nominal states
//! (100 × 10 ms: a GPS fix is ~0.1 s old, a horizon measured on the ground and sent back
//! over the link may be several tenths); an update forms its innovation against the stored state nearest the
//! measurement time and applies the correction to the current state (the *delayed-state
//! correction*, not re-propagation). For position, the measurement model accounts for the
//! velocity error over the delay (`δp(t_m) ≈ δp(now) − Δt·δv(now)`); the other error states
//! are taken as constant over the delay (≤ 1 s; they change only through the biases and
//! the process noise). Each correction is also applied to the ring, so the
//! next delayed innovation does not count it twice.
//!
//! **Covariance hygiene**: Joseph-form updates (one scalar at a time, exact for the diagonal
//! measurement noise used here), symmetrisation after every propagation and update, a floor
//! on each diagonal element, correlations clamped to |ρ| ≤ 1, and once a second a Cholesky
//! test that adds a small multiple of the diagonal if P has lost definiteness.
//!
//! **Gating and resets**: GPS position and velocity, and horizon roll/pitch, are gated on
//! their normalised innovation squared (χ² thresholds in [`EkfConfig`]); rejections are
//! counted. After [`EkfConfig::gps_reset_after`] position rejections in a row the filter
//! believes the GPS (a persistent jump) and resets position and velocity to it (counted).
//! Non-finite inputs are refused and counted without touching the state. A non-finite state
//! or covariance, or a covariance beyond [`EkfConfig`]'s divergence limits, resets the filter
//! to its last healthy snapshot with the initial covariance (counted, with the reason).

use crate::angles::wrap_pi;
use nalgebra::{Cholesky, Matrix3, SMatrix, SVector, UnitQuaternion, Vector3};

pub const N: usize = 15;
pub type Cov = SMatrix<f64, N, N>;
pub type ErrorVec = SVector<f64, N>;
type Row = SMatrix<f64, 1, N>;

pub const P: usize = 0;
pub const V: usize = 3;
pub const TH: usize = 6;
pub const BG: usize = 9;
pub const BA: usize = 12;

/// Standard gravity (m/s²), down in NED.
pub const GRAVITY_MPS2: f64 = 9.806_65;

/// Past nominal states kept for delayed measurements: 100 steps, 1 s at 100 Hz
/// (~8 KiB).
pub const HISTORY_LEN: usize = 100;

/// Filter tuning. Noise figures are continuous densities (per √s), so the filter is
/// independent of the IMU rate.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EkfConfig {
    /// Gyro white noise density (rad/s/√Hz = rad/√s).
    pub gyro_noise: f64,
    /// Gyro scale-factor and cross-axis error (dimensionless, 1-σ): an error proportional to
    /// the rate that the filter has no state for, so it enters as attitude process noise
    /// that grows with the rotation rate (see `propagate_covariance`).
    pub gyro_scale_error: f64,
    /// Accelerometer white noise density (m/s/√s).
    pub accel_noise: f64,
    /// Gyro bias random walk (rad/s/√s).
    pub gyro_bias_walk: f64,
    /// Accelerometer bias random walk (m/s²/√s).
    pub accel_bias_walk: f64,
    /// 1-σ of the initial covariance, per block.
    pub init_pos_sd_m: f64,
    pub init_vel_sd_mps: f64,
    pub init_att_sd_rad: f64,
    pub init_yaw_sd_rad: f64,
    pub init_gyro_bias_sd_radps: f64,
    pub init_accel_bias_sd_mps2: f64,
    /// Smallest 1-σ the GPS is believed to (m, m/s), whatever it says of itself.
    pub gps_min_pos_sd_m: f64,
    pub gps_min_vel_sd_mps: f64,
    /// χ² gates on the normalised innovation squared (3 degrees of freedom each).
    pub gps_pos_gate: f64,
    pub gps_vel_gate: f64,
    /// Consecutive position rejections after which the filter resets to the GPS.
    pub gps_reset_after: u32,
    /// χ² gate of a horizon roll/pitch update (2 degrees of freedom).
    pub horizon_gate: f64,
    /// Horizon 1-σ at confidence 1 (rad); divided by the confidence.
    pub horizon_sd_rad: f64,
    /// Horizon measurements below this confidence are ignored.
    pub horizon_min_confidence: f64,
    /// Divergence limits on the variances (position m², roll/pitch rad²).
    pub max_pos_var: f64,
    pub max_att_var: f64,
    /// Across an IMU outage (see [`Ekf::bridge_gap`]): how far the body rates and the
    /// specific force may drift from their last values, 1-σ per axis (rad/s, m/s²), and the
    /// longest outage bridged (s).
    pub gap_rate_sd_radps: f64,
    pub gap_accel_sd_mps2: f64,
    pub max_gap_s: f64,
}

impl Default for EkfConfig {
    fn default() -> Self {
        Self {
            // What real airframes show, not the datasheet: 10 ms means of the gyro vary by
            // ~0.025 rad/s in flight on the Zurich fixed-wing log (vibration; the datasheet's
            // 0.002 rad/s per sample is 2e-4 rad/√s). 5e-4 made the filter so sure of its
            // attitude that on the 2015 copter log it rejected 50 good fixes in a row and ran
            // 80 m away; 2.5e-3 rejects none (docs/replay.md).
            gyro_noise: 2.5e-3,
            // MPU-6000 class: ±1 % scale and ±2 % cross-axis are datasheet limits; 0.5 % is
            // the 1-σ of the simulated IMU and a typical calibrated unit.
            gyro_scale_error: 5e-3,
            // The same log's accelerometer: 8.7e-3, 7.3e-3, 3.8e-2 m/s/√s (x, y, z) in flight;
            // the largest, so the velocity is never believed beyond what vibration allows.
            accel_noise: 4e-2,
            gyro_bias_walk: 2e-4,
            accel_bias_walk: 2e-3,
            init_pos_sd_m: 5.0,
            init_vel_sd_mps: 1.0,
            init_att_sd_rad: 2.0f64.to_radians(),
            init_yaw_sd_rad: 15.0f64.to_radians(),
            init_gyro_bias_sd_radps: 0.01,
            init_accel_bias_sd_mps2: 0.1,
            gps_min_pos_sd_m: 0.5,
            gps_min_vel_sd_mps: 0.1,
            // χ²(3) at 1 − 1e-5: a good fix is almost never rejected, a 50 m jump always is.
            gps_pos_gate: 25.9,
            gps_vel_gate: 25.9,
            gps_reset_after: 50,
            // χ²(2) at 1 − 1e-4.
            horizon_gate: 18.4,
            horizon_sd_rad: 2.0f64.to_radians(),
            horizon_min_confidence: 0.3,
            max_pos_var: 1e8,
            max_att_var: 1.0,
            // A small airplane's autopilot or pilot changes the rates by a few °/s and the
            // load by ~1 m/s² within a second or two of a steady turn or climb.
            gap_rate_sd_radps: 0.05,
            gap_accel_sd_mps2: 1.0,
            max_gap_s: 10.0,
        }
    }
}

/// The nominal (whole) state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NominalState {
    pub position_ned_m: Vector3<f64>,
    pub velocity_ned_mps: Vector3<f64>,
    /// Body FRD → NED.
    pub attitude: UnitQuaternion<f64>,
    pub gyro_bias_radps: Vector3<f64>,
    pub accel_bias_mps2: Vector3<f64>,
}

impl NominalState {
    pub fn at_rest(attitude: UnitQuaternion<f64>) -> Self {
        Self {
            position_ned_m: Vector3::zeros(),
            velocity_ned_mps: Vector3::zeros(),
            attitude,
            gyro_bias_radps: Vector3::zeros(),
            accel_bias_mps2: Vector3::zeros(),
        }
    }

    pub fn is_finite(&self) -> bool {
        let q = self.attitude.quaternion();
        self.position_ned_m.iter().all(|x| x.is_finite())
            && self.velocity_ned_mps.iter().all(|x| x.is_finite())
            && q.coords.iter().all(|x| x.is_finite())
            && self.gyro_bias_radps.iter().all(|x| x.is_finite())
            && self.accel_bias_mps2.iter().all(|x| x.is_finite())
    }

    /// (roll, pitch, yaw) in radians, 3-2-1.
    pub fn euler(&self) -> (f64, f64, f64) {
        self.attitude.euler_angles()
    }
}

/// A GPS measurement in the local frame. A component that is `None` is not used.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpsMeasurement {
    /// When the receiver measured (executive clock): reception time minus its latency.
    pub t_ns: u64,
    pub position_ned_m: Option<Vector3<f64>>,
    pub position_sd_m: Vector3<f64>,
    pub velocity_ned_mps: [Option<f64>; 3],
    pub velocity_sd_mps: Vector3<f64>,
}

/// What became of one update.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum UpdateOutcome {
    Accepted,
    /// Gated out; the normalised innovation squared.
    Rejected {
        nis: f32,
    },
    /// Older than the history, in the future, or otherwise unusable.
    Unusable,
    /// Too many rejections in a row: the filter was reset to the measurement.
    ResetToMeasurement,
}

/// What the GPS update did to position and velocity.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GpsOutcome {
    pub position: UpdateOutcome,
    pub velocity: UpdateOutcome,
    pub position_nis: f32,
    pub velocity_nis: f32,
}

/// Why the filter reset itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResetReason {
    NonFiniteState,
    NonFiniteCovariance,
    Divergence,
}

impl ResetReason {
    pub fn as_str(self) -> &'static str {
        match self {
            Self::NonFiniteState => "non-finite state",
            Self::NonFiniteCovariance => "non-finite covariance",
            Self::Divergence => "covariance diverged",
        }
    }
}

/// The filter's counters: nothing it refuses or repairs goes unreported.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EkfCounters {
    pub imu_steps: u32,
    /// IMU samples refused (non-finite values or time step).
    pub imu_rejected: u32,
    pub gps_pos_accepted: u32,
    pub gps_pos_rejected: u32,
    pub gps_vel_accepted: u32,
    pub gps_vel_rejected: u32,
    /// GPS measurements older than the history or non-finite.
    pub gps_unusable: u32,
    /// Resets of position/velocity to the GPS after a run of rejections.
    pub gps_resets: u32,
    pub horizon_accepted: u32,
    pub horizon_rejected: u32,
    pub horizon_unusable: u32,
    /// Whole-filter resets (NaN, divergence).
    pub resets: u32,
    /// Times the once-a-second Cholesky test found P indefinite and repaired it.
    pub covariance_repairs: u32,
}

#[derive(Clone, Copy, Debug)]
struct HistoryEntry {
    t_ns: u64,
    position: Vector3<f64>,
    velocity: Vector3<f64>,
    attitude: UnitQuaternion<f64>,
}

/// A fixed ring of past nominal states, newest last.
#[derive(Clone, Debug)]
struct History {
    entries: [Option<HistoryEntry>; HISTORY_LEN],
    next: usize,
}

impl History {
    fn new() -> Self {
        Self {
            entries: [None; HISTORY_LEN],
            next: 0,
        }
    }

    fn push(&mut self, entry: HistoryEntry) {
        if let Some(slot) = self.entries.get_mut(self.next) {
            *slot = Some(entry);
        }
        self.next = (self.next + 1) % HISTORY_LEN;
    }

    /// The entry closest in time to `t_ns`, if `t_ns` is within the covered span (half a
    /// step of slack at either end).
    fn nearest(&self, t_ns: u64, slack_ns: u64) -> Option<HistoryEntry> {
        let mut best: Option<(u64, HistoryEntry)> = None;
        let mut oldest = u64::MAX;
        let mut newest = 0u64;
        for e in self.entries.iter().flatten() {
            oldest = oldest.min(e.t_ns);
            newest = newest.max(e.t_ns);
            let d = e.t_ns.abs_diff(t_ns);
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, *e));
            }
        }
        if t_ns.saturating_add(slack_ns) < oldest || t_ns > newest.saturating_add(slack_ns) {
            return None;
        }
        best.map(|(_, e)| e)
    }

    /// The newest stored state.
    fn newest(&self) -> Option<HistoryEntry> {
        self.entries
            .iter()
            .flatten()
            .max_by_key(|e| e.t_ns)
            .copied()
    }

    /// Applies a correction to every stored state (see the module comment).
    fn correct(&mut self, dp: &Vector3<f64>, dv: &Vector3<f64>, dq: &UnitQuaternion<f64>) {
        for e in self.entries.iter_mut().flatten() {
            e.position += dp;
            e.velocity += dv;
            e.attitude = dq * e.attitude;
        }
    }
}

/// The error-state EKF.
#[derive(Clone, Debug)]
pub struct Ekf {
    config: EkfConfig,
    x: NominalState,
    p: Cov,
    t_ns: u64,
    history: History,
    counters: EkfCounters,
    consecutive_pos_rejections: u32,
    last_good: NominalState,
    last_reset: Option<ResetReason>,
    /// Bias-corrected body rates and specific force of the last step.
    rates: Vector3<f64>,
    specific_force: Vector3<f64>,
    /// The same, smoothed over [`GAP_HOLD_SMOOTHING_S`]: what an outage holds (one 10 ms
    /// sample of a vibrating IMU held for seconds would be its noise, integrated).
    held_rates: Vector3<f64>,
    held_force: Vector3<f64>,
    steps_since_check: u32,
}

/// Time constant of the rates and specific force held across an IMU outage (s): short
/// against a manoeuvre, long against the vibration (averages ~25 samples).
const GAP_HOLD_SMOOTHING_S: f64 = 0.25;

fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    v.cross_matrix()
}

fn finite_matrix<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> bool {
    m.iter().all(|x| x.is_finite())
}

impl Ekf {
    /// A filter started at `x` at time `t_ns`, with the initial covariance of `config` and
    /// the given yaw 1-σ.
    pub fn new(config: EkfConfig, x: NominalState, t_ns: u64, yaw_sd_rad: f64) -> Self {
        let mut ekf = Self {
            config,
            x,
            p: Cov::zeros(),
            t_ns,
            history: History::new(),
            counters: EkfCounters::default(),
            consecutive_pos_rejections: 0,
            last_good: x,
            last_reset: None,
            rates: Vector3::zeros(),
            specific_force: Vector3::zeros(),
            held_rates: Vector3::zeros(),
            held_force: x.attitude.inverse() * Vector3::new(0.0, 0.0, -GRAVITY_MPS2),
            steps_since_check: 0,
        };
        ekf.p = ekf.initial_covariance(yaw_sd_rad);
        ekf.remember();
        ekf
    }

    fn initial_covariance(&self, yaw_sd_rad: f64) -> Cov {
        let c = &self.config;
        let mut d = ErrorVec::zeros();
        let blocks = [
            (P, c.init_pos_sd_m),
            (V, c.init_vel_sd_mps),
            (TH, c.init_att_sd_rad),
            (BG, c.init_gyro_bias_sd_radps),
            (BA, c.init_accel_bias_sd_mps2),
        ];
        for (start, sd) in blocks {
            d.fixed_rows_mut::<3>(start).fill(sd * sd);
        }
        d[TH + 2] = yaw_sd_rad * yaw_sd_rad;
        Cov::from_diagonal(&d)
    }

    pub fn config(&self) -> &EkfConfig {
        &self.config
    }
    pub fn state(&self) -> &NominalState {
        &self.x
    }
    pub fn covariance(&self) -> &Cov {
        &self.p
    }
    pub fn counters(&self) -> &EkfCounters {
        &self.counters
    }
    pub fn time_ns(&self) -> u64 {
        self.t_ns
    }
    /// Body rates with the gyro bias removed (rad/s), from the last step.
    pub fn rates(&self) -> Vector3<f64> {
        self.rates
    }
    /// Specific force with the accelerometer bias removed (m/s²), from the last step.
    pub fn specific_force(&self) -> Vector3<f64> {
        self.specific_force
    }
    /// The reason of the latest whole-filter reset.
    pub fn last_reset(&self) -> Option<ResetReason> {
        self.last_reset
    }

    fn remember(&mut self) {
        self.history.push(HistoryEntry {
            t_ns: self.t_ns,
            position: self.x.position_ned_m,
            velocity: self.x.velocity_ned_mps,
            attitude: self.x.attitude,
        });
    }

    /// One IMU step: body rates (rad/s) and specific force (m/s²), FRD, over `dt_s` ending at
    /// `t_ns`. Returns `false` if the sample was refused (non-finite, or a time step outside
    /// (0, 0.1] s) — counted, state untouched.
    pub fn propagate(
        &mut self,
        t_ns: u64,
        dt_s: f64,
        rates_radps: Vector3<f64>,
        specific_force_mps2: Vector3<f64>,
    ) -> bool {
        let usable = dt_s > 0.0
            && dt_s <= 0.1
            && rates_radps.iter().all(|x| x.is_finite())
            && specific_force_mps2.iter().all(|x| x.is_finite());
        if !usable {
            self.counters.imu_rejected = self.counters.imu_rejected.wrapping_add(1);
            return false;
        }
        let x = &mut self.x;
        let w = rates_radps - x.gyro_bias_radps;
        let f = specific_force_mps2 - x.accel_bias_mps2;
        self.rates = w;
        self.specific_force = f;
        let k = (dt_s / GAP_HOLD_SMOOTHING_S).min(1.0);
        self.held_rates += (w - self.held_rates) * k;
        self.held_force += (f - self.held_force) * k;
        // The specific force is rotated with the mid-interval attitude (second order in the
        // rotation over the step: a turn does not leak into a tilt through the integration).
        let half = x.attitude * UnitQuaternion::from_scaled_axis(w * (0.5 * dt_s));
        let r = half.to_rotation_matrix().into_inner();
        let f_ned = r * f;
        let a = f_ned + Vector3::new(0.0, 0.0, GRAVITY_MPS2);
        x.position_ned_m += x.velocity_ned_mps * dt_s + a * (0.5 * dt_s * dt_s);
        x.velocity_ned_mps += a * dt_s;
        x.attitude *= UnitQuaternion::from_scaled_axis(w * dt_s);
        x.attitude.renormalize();
        self.propagate_covariance(dt_s, &r, &f_ned);
        self.t_ns = t_ns;
        self.counters.imu_steps = self.counters.imu_steps.wrapping_add(1);
        self.condition();
        if self.check_health() {
            self.remember();
            self.steps_since_check += 1;
            if self.steps_since_check >= 100 {
                self.steps_since_check = 0;
                self.ensure_positive_definite();
                self.last_good = self.x;
            }
        }
        true
    }

    /// Carries the filter across an IMU outage of `gap_s` ending at `t_ns` (the sample that
    /// ends it comes after): the last bias-corrected rates and specific force (smoothed over
    /// the last quarter second) held over the gap, 10 ms at a time, as dead reckoning would, and the attitude and velocity
    /// uncertainty grown by what they may have changed by meanwhile (`σ·gap` each). Without
    /// this the filter would stand still while the vehicle flew on, then reject the GPS as a
    /// jump and keep the turn it missed as a tilt. `false` (counted as a refused sample,
    /// state untouched) for a gap beyond [`EkfConfig::max_gap_s`] or not finite.
    pub fn bridge_gap(&mut self, t_ns: u64, gap_s: f64) -> bool {
        if !(gap_s > 0.0 && gap_s <= self.config.max_gap_s) {
            self.counters.imu_rejected = self.counters.imu_rejected.wrapping_add(1);
            return false;
        }
        let w = self.held_rates + self.x.gyro_bias_radps;
        let f = self.held_force + self.x.accel_bias_mps2;
        let step_ns = 10_000_000u64;
        let gap_ns = (gap_s * 1e9) as u64;
        let start_ns = t_ns.saturating_sub(gap_ns);
        let mut done_ns = 0u64;
        while done_ns < gap_ns {
            let h_ns = step_ns.min(gap_ns - done_ns);
            done_ns += h_ns;
            if !self.propagate(start_ns + done_ns, h_ns as f64 * 1e-9, w, f) {
                return false;
            }
        }
        let c = self.config;
        let (var_th, var_v) = (
            (c.gap_rate_sd_radps * gap_s) * (c.gap_rate_sd_radps * gap_s),
            (c.gap_accel_sd_mps2 * gap_s) * (c.gap_accel_sd_mps2 * gap_s),
        );
        for k in 0..3 {
            self.p[(TH + k, TH + k)] += var_th;
            self.p[(V + k, V + k)] += var_v;
            // The velocity error integrates into position: half the velocity spread.
            self.p[(P + k, P + k)] += var_v * gap_s * gap_s / 4.0;
        }
        self.condition();
        true
    }

    /// `P ← F P Fᵀ + Q` with `F = I + A·dt`, using the sparsity of `A` (four 3×3 blocks):
    /// ~1 100 multiplications instead of 6 750 for the dense product.
    fn propagate_covariance(&mut self, dt_s: f64, r: &Matrix3<f64>, f_ned: &Vector3<f64>) {
        let f_vth = -skew(f_ned) * dt_s;
        let f_vba = -r * dt_s;
        let f_thbg = -r * dt_s;
        let p = &self.p;
        // M = F P: row blocks.
        let mut m = *p;
        m.fixed_rows_mut::<3>(P)
            .copy_from(&(p.fixed_rows::<3>(P) + p.fixed_rows::<3>(V) * dt_s));
        m.fixed_rows_mut::<3>(V).copy_from(
            &(p.fixed_rows::<3>(V) + f_vth * p.fixed_rows::<3>(TH) + f_vba * p.fixed_rows::<3>(BA)),
        );
        m.fixed_rows_mut::<3>(TH)
            .copy_from(&(p.fixed_rows::<3>(TH) + f_thbg * p.fixed_rows::<3>(BG)));
        // P' = M Fᵀ: column blocks.
        let mut out = m;
        out.fixed_columns_mut::<3>(P)
            .copy_from(&(m.fixed_columns::<3>(P) + m.fixed_columns::<3>(V) * dt_s));
        out.fixed_columns_mut::<3>(V).copy_from(
            &(m.fixed_columns::<3>(V)
                + m.fixed_columns::<3>(TH) * f_vth.transpose()
                + m.fixed_columns::<3>(BA) * f_vba.transpose()),
        );
        out.fixed_columns_mut::<3>(TH)
            .copy_from(&(m.fixed_columns::<3>(TH) + m.fixed_columns::<3>(BG) * f_thbg.transpose()));
        let c = &self.config;
        // The scale-factor error turns a rotation into an attitude error of `s·ω·t`: coherent,
        // not white, but the filter only needs to know the attitude is that much less certain
        // over the ~1 s a GPS velocity update takes to see it, so it enters as white noise of
        // density `s·|ω_i|·√(1 s)` about each body axis, rotated to NED (the error state's frame).
        let scale_var = self
            .rates
            .map(|w| (c.gyro_scale_error * w) * (c.gyro_scale_error * w) * dt_s);
        let q_scale = r * Matrix3::from_diagonal(&scale_var) * r.transpose();
        out.fixed_view_mut::<3, 3>(TH, TH)
            .iter_mut()
            .zip(q_scale.iter())
            .for_each(|(p, q)| *p += q);
        // Position picks up the velocity noise integrated once more; negligible next to the
        // velocity term at 100 Hz but keeps P's position block from being singular.
        let qa = c.accel_noise * c.accel_noise * dt_s;
        let qs = [
            qa * dt_s * dt_s / 3.0,
            qa,
            c.gyro_noise * c.gyro_noise * dt_s,
            c.gyro_bias_walk * c.gyro_bias_walk * dt_s,
            c.accel_bias_walk * c.accel_bias_walk * dt_s,
        ];
        for (block, q) in qs.iter().enumerate() {
            for k in 0..3 {
                let i = block * 3 + k;
                out[(i, i)] += q;
            }
        }
        self.p = out;
    }

    /// Symmetrises P, floors its diagonal and clamps its correlations.
    fn condition(&mut self) {
        let pt = self.p.transpose();
        self.p = (self.p + pt) * 0.5;
        const FLOORS: [f64; 5] = [1e-6, 1e-8, 1e-12, 1e-16, 1e-14];
        for i in 0..N {
            let floor = FLOORS.get(i / 3).copied().unwrap_or(1e-12);
            if self.p[(i, i)] < floor {
                self.p[(i, i)] = floor;
            }
        }
        for i in 0..N {
            for j in (i + 1)..N {
                let lim = libm::sqrt(self.p[(i, i)] * self.p[(j, j)]) * 0.999_999;
                let v = self.p[(i, j)].clamp(-lim, lim);
                self.p[(i, j)] = v;
                self.p[(j, i)] = v;
            }
        }
    }

    /// Cholesky test; on failure, inflates the diagonal until P factors (counted).
    fn ensure_positive_definite(&mut self) {
        if Cholesky::new(self.p).is_some() {
            return;
        }
        self.counters.covariance_repairs = self.counters.covariance_repairs.wrapping_add(1);
        let mut eps = 1e-9;
        for _ in 0..12 {
            let mut repaired = self.p;
            for i in 0..N {
                repaired[(i, i)] += eps * (1.0 + self.p[(i, i)]);
            }
            if Cholesky::new(repaired).is_some() {
                self.p = repaired;
                return;
            }
            eps *= 10.0;
        }
        let yaw_sd = libm::sqrt(self.p[(TH + 2, TH + 2)]);
        self.p = self.initial_covariance(yaw_sd);
    }

    /// `true` if the filter is sane; otherwise resets it and returns `false`.
    fn check_health(&mut self) -> bool {
        let reason = if !self.x.is_finite() {
            Some(ResetReason::NonFiniteState)
        } else if !finite_matrix(&self.p) {
            Some(ResetReason::NonFiniteCovariance)
        } else if (0..3).any(|i| self.p[(P + i, P + i)] > self.config.max_pos_var)
            || (0..2).any(|i| self.p[(TH + i, TH + i)] > self.config.max_att_var)
            // Yaw may legitimately be unknown (±π) before the heading is set.
            || self.p[(TH + 2, TH + 2)] > 100.0
            || self.x.velocity_ned_mps.norm() > 300.0
        {
            Some(ResetReason::Divergence)
        } else {
            None
        };
        match reason {
            None => true,
            Some(reason) => {
                self.reset(reason);
                false
            }
        }
    }

    /// Restarts with the initial covariance from the newest sane state: position, velocity
    /// and attitude of the last step that passed the checks (the history only ever holds
    /// such steps), biases from the last healthy snapshot (taken once a second). The history
    /// is kept, so delayed updates go on at once. Counted.
    pub fn reset(&mut self, reason: ResetReason) {
        self.counters.resets = self.counters.resets.wrapping_add(1);
        self.last_reset = Some(reason);
        self.x = self.last_good;
        if let Some(e) = self.history.newest() {
            self.x.position_ned_m = e.position;
            self.x.velocity_ned_mps = e.velocity;
            self.x.attitude = e.attitude;
        }
        self.p = self.initial_covariance(self.config.init_yaw_sd_rad);
        self.consecutive_pos_rejections = 0;
        self.steps_since_check = 0;
        self.rates = Vector3::zeros();
        self.specific_force = Vector3::zeros();
        self.remember();
    }

    /// Sets the yaw (rad) keeping roll and pitch, e.g. from the first GPS course, and its
    /// variance, with no correlation to the other states.
    pub fn set_yaw(&mut self, yaw_rad: f64, yaw_sd_rad: f64) {
        let (_, _, yaw) = self.x.euler();
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_rad - yaw);
        self.x.attitude = turn * self.x.attitude;
        self.x.attitude.renormalize();
        let k = TH + 2;
        for i in 0..N {
            self.p[(i, k)] = 0.0;
            self.p[(k, i)] = 0.0;
        }
        self.p[(k, k)] = yaw_sd_rad * yaw_sd_rad;
        self.history
            .correct(&Vector3::zeros(), &Vector3::zeros(), &turn);
    }

    /// Moves position and velocity by `dp`, `dv` (a reset to the GPS), their variance set to
    /// `pos_var` and the initial velocity variance, with no correlation.
    pub fn set_position_velocity(&mut self, dp: Vector3<f64>, dv: Vector3<f64>, pos_var: f64) {
        self.x.position_ned_m += dp;
        self.x.velocity_ned_mps += dv;
        self.history.correct(&dp, &dv, &UnitQuaternion::identity());
        for k in P..(V + 3) {
            for i in 0..N {
                self.p[(i, k)] = 0.0;
                self.p[(k, i)] = 0.0;
            }
        }
        let vel_var = self.config.init_vel_sd_mps * self.config.init_vel_sd_mps;
        for k in 0..3 {
            self.p[(P + k, P + k)] = pos_var;
            self.p[(V + k, V + k)] = vel_var;
        }
    }

    /// Normalised innovation squared `yᵀ S⁻¹ y`; `None` if `S` does not factor.
    fn nis3(y: &Vector3<f64>, s: &Matrix3<f64>) -> Option<f64> {
        let v = Cholesky::new(*s)?.solve(y);
        let nis = y.dot(&v);
        nis.is_finite().then_some(nis)
    }

    fn nis2(y: &nalgebra::Vector2<f64>, s: &nalgebra::Matrix2<f64>) -> Option<f64> {
        let v = Cholesky::new(*s)?.solve(y);
        let nis = y.dot(&v);
        nis.is_finite().then_some(nis)
    }

    /// Sequential scalar updates in Joseph form; returns the accumulated error-state
    /// correction (not yet injected).
    fn joseph_updates(&mut self, rows: &[(Row, f64, f64)], dx: &mut ErrorVec) {
        let identity = Cov::identity();
        for (h, y, r) in rows {
            let ph = self.p * h.transpose();
            let s = (h * ph)[(0, 0)] + r;
            if !(s > 0.0 && s.is_finite()) {
                continue;
            }
            let k = ph / s;
            let innovation = y - (h * *dx)[(0, 0)];
            *dx += k * innovation;
            let a = identity - k * h;
            self.p = a * self.p * a.transpose() + k * k.transpose() * *r;
        }
        self.condition();
    }

    /// Injects an error-state correction into the nominal state and the history.
    fn inject(&mut self, dx: &ErrorVec) {
        let dp: Vector3<f64> = dx.fixed_rows::<3>(P).into_owned();
        let dv: Vector3<f64> = dx.fixed_rows::<3>(V).into_owned();
        let dth: Vector3<f64> = dx.fixed_rows::<3>(TH).into_owned();
        let dq = UnitQuaternion::from_scaled_axis(dth);
        self.x.position_ned_m += dp;
        self.x.velocity_ned_mps += dv;
        self.x.attitude = dq * self.x.attitude;
        self.x.attitude.renormalize();
        self.x.gyro_bias_radps += dx.fixed_rows::<3>(BG);
        self.x.accel_bias_mps2 += dx.fixed_rows::<3>(BA);
        self.history.correct(&dp, &dv, &dq);
    }

    fn slack_ns() -> u64 {
        15_000_000
    }

    /// Moves position and velocity onto a GPS measurement (at its time, through the
    /// history), dropping their correlations: the first fix, a heading just set (the
    /// velocity was integrated with a guessed yaw), or a persistent jump. `false` if the
    /// measurement has no usable position or is older than the history.
    pub fn reset_to_gps(&mut self, m: &GpsMeasurement) -> bool {
        let Some(z) = m.position_ned_m.filter(|z| z.iter().all(|x| x.is_finite())) else {
            return false;
        };
        let Some(past) = self
            .history
            .nearest(m.t_ns.min(self.t_ns), Self::slack_ns())
        else {
            return false;
        };
        let dv = m
            .velocity_ned_mps
            .iter()
            .zip(past.velocity.iter())
            .map(|(z, v)| z.filter(|z| z.is_finite()).map_or(0.0, |z| z - v));
        let dv = Vector3::from_iterator(dv);
        let var = m
            .position_sd_m
            .iter()
            .map(|sd| {
                if sd.is_finite() {
                    sd.max(self.config.gps_min_pos_sd_m)
                } else {
                    10.0
                }
            })
            .fold(0.0f64, f64::max);
        self.set_position_velocity(z - past.position, dv, var * var);
        self.consecutive_pos_rejections = 0;
        true
    }

    /// A GPS position/velocity update at the measurement's time (see the module comment).
    pub fn update_gps(&mut self, m: &GpsMeasurement) -> GpsOutcome {
        let mut out = GpsOutcome {
            position: UpdateOutcome::Unusable,
            velocity: UpdateOutcome::Unusable,
            position_nis: f32::NAN,
            velocity_nis: f32::NAN,
        };
        let t_m = m.t_ns.min(self.t_ns);
        let Some(past) = self.history.nearest(t_m, Self::slack_ns()) else {
            self.counters.gps_unusable = self.counters.gps_unusable.wrapping_add(1);
            return out;
        };
        let delay_s = (self.t_ns.saturating_sub(past.t_ns)) as f64 * 1e-9;
        let c = self.config;
        let mut dx = ErrorVec::zeros();

        if let Some(z) = m.position_ned_m.filter(|z| z.iter().all(|x| x.is_finite())) {
            let y = z - past.position;
            let mut h = SMatrix::<f64, 3, N>::zeros();
            h.fixed_view_mut::<3, 3>(0, P).fill_with_identity();
            h.fixed_view_mut::<3, 3>(0, V)
                .copy_from(&(Matrix3::identity() * -delay_s));
            let r_diag = m.position_sd_m.map(|sd| {
                let sd = if sd.is_finite() { sd } else { 10.0 };
                let sd = sd.max(c.gps_min_pos_sd_m);
                sd * sd
            });
            let s = h * self.p * h.transpose() + Matrix3::from_diagonal(&r_diag);
            match Self::nis3(&y, &s) {
                Some(nis) if nis <= c.gps_pos_gate => {
                    self.consecutive_pos_rejections = 0;
                    self.counters.gps_pos_accepted = self.counters.gps_pos_accepted.wrapping_add(1);
                    out.position = UpdateOutcome::Accepted;
                    out.position_nis = nis as f32;
                    let rows =
                        [0, 1, 2].map(|i| (h.fixed_rows::<1>(i).into_owned(), y[i], r_diag[i]));
                    self.joseph_updates(&rows, &mut dx);
                }
                Some(nis) => {
                    self.consecutive_pos_rejections += 1;
                    self.counters.gps_pos_rejected = self.counters.gps_pos_rejected.wrapping_add(1);
                    out.position = UpdateOutcome::Rejected { nis: nis as f32 };
                    out.position_nis = nis as f32;
                    if self.consecutive_pos_rejections >= c.gps_reset_after {
                        self.counters.gps_resets = self.counters.gps_resets.wrapping_add(1);
                        self.reset_to_gps(m);
                        out.position = UpdateOutcome::ResetToMeasurement;
                        out.velocity = UpdateOutcome::ResetToMeasurement;
                        return out;
                    }
                }
                None => {
                    self.counters.gps_unusable = self.counters.gps_unusable.wrapping_add(1);
                }
            }
        }

        let present: [bool; 3] = m.velocity_ned_mps.map(|v| v.is_some_and(f64::is_finite));
        if present.iter().any(|&p| p) {
            let mut y = Vector3::zeros();
            let mut r_diag = Vector3::zeros();
            for i in 0..3 {
                let sd = m.velocity_sd_mps[i];
                let sd = if sd.is_finite() { sd } else { 1.0 };
                let sd = sd.max(c.gps_min_vel_sd_mps);
                match m.velocity_ned_mps[i].filter(|v| v.is_finite()) {
                    Some(z) => {
                        y[i] = z - past.velocity[i];
                        r_diag[i] = sd * sd;
                    }
                    // A missing component: zero innovation with a huge variance adds
                    // nothing to the NIS and is not applied below.
                    None => r_diag[i] = 1e12,
                }
            }
            let mut h = SMatrix::<f64, 3, N>::zeros();
            h.fixed_view_mut::<3, 3>(0, V).fill_with_identity();
            let s = h * self.p * h.transpose() + Matrix3::from_diagonal(&r_diag);
            match Self::nis3(&y, &s) {
                Some(nis) if nis <= c.gps_vel_gate => {
                    self.counters.gps_vel_accepted = self.counters.gps_vel_accepted.wrapping_add(1);
                    out.velocity = UpdateOutcome::Accepted;
                    out.velocity_nis = nis as f32;
                    let mut rows: heapless::Vec<(Row, f64, f64), 3> = heapless::Vec::new();
                    for i in (0..3).filter(|&i| present[i]) {
                        let _ = rows.push((h.fixed_rows::<1>(i).into_owned(), y[i], r_diag[i]));
                    }
                    self.joseph_updates(&rows, &mut dx);
                }
                Some(nis) => {
                    self.counters.gps_vel_rejected = self.counters.gps_vel_rejected.wrapping_add(1);
                    out.velocity = UpdateOutcome::Rejected { nis: nis as f32 };
                    out.velocity_nis = nis as f32;
                }
                None => {
                    self.counters.gps_unusable = self.counters.gps_unusable.wrapping_add(1);
                }
            }
        }
        self.inject(&dx);
        self.check_health();
        out
    }

    /// A horizon roll/pitch update (radians) captured at `capture_t_ns`.
    pub fn update_horizon(
        &mut self,
        capture_t_ns: u64,
        roll_rad: f64,
        pitch_rad: f64,
        confidence: f64,
    ) -> UpdateOutcome {
        let c = self.config;
        let past = self.history.nearest(capture_t_ns, Self::slack_ns());
        let usable = roll_rad.is_finite()
            && pitch_rad.is_finite()
            && confidence.is_finite()
            && confidence >= c.horizon_min_confidence
            && pitch_rad.abs() < 80f64.to_radians();
        let Some(past) = past.filter(|_| usable) else {
            self.counters.horizon_unusable = self.counters.horizon_unusable.wrapping_add(1);
            return UpdateOutcome::Unusable;
        };
        let euler = |q: &UnitQuaternion<f64>| {
            let (r, p, _) = q.euler_angles();
            nalgebra::Vector2::new(r, p)
        };
        let h0 = euler(&past.attitude);
        if h0.y.abs() > 80f64.to_radians() {
            self.counters.horizon_unusable = self.counters.horizon_unusable.wrapping_add(1);
            return UpdateOutcome::Unusable;
        }
        // Numerical Jacobian of (roll, pitch) with respect to the NED-frame attitude error.
        let mut h = SMatrix::<f64, 2, N>::zeros();
        let eps = 1e-6;
        for k in 0..3 {
            let mut d = Vector3::zeros();
            d[k] = eps;
            let hk = euler(&(UnitQuaternion::from_scaled_axis(d) * past.attitude));
            let mut diff = hk - h0;
            diff.x = wrap_pi(diff.x);
            h.fixed_view_mut::<2, 1>(0, TH + k).copy_from(&(diff / eps));
        }
        let y = nalgebra::Vector2::new(wrap_pi(roll_rad - h0.x), pitch_rad - h0.y);
        let sd = c.horizon_sd_rad / confidence;
        let r = sd * sd;
        let s = h * self.p * h.transpose() + nalgebra::Matrix2::identity() * r;
        match Self::nis2(&y, &s) {
            Some(nis) if nis <= c.horizon_gate => {
                self.counters.horizon_accepted = self.counters.horizon_accepted.wrapping_add(1);
                let rows = [0, 1].map(|i| (h.fixed_rows::<1>(i).into_owned(), y[i], r));
                let mut dx = ErrorVec::zeros();
                self.joseph_updates(&rows, &mut dx);
                self.inject(&dx);
                self.check_health();
                UpdateOutcome::Accepted
            }
            Some(nis) => {
                self.counters.horizon_rejected = self.counters.horizon_rejected.wrapping_add(1);
                UpdateOutcome::Rejected { nis: nis as f32 }
            }
            None => {
                self.counters.horizon_unusable = self.counters.horizon_unusable.wrapping_add(1);
                UpdateOutcome::Unusable
            }
        }
    }

    /// For tests of the reset path: poisons the state as a numerical blow-up would.
    #[doc(hidden)]
    pub fn inject_fault_for_test(&mut self) {
        self.x.velocity_ned_mps.x = f64::NAN;
        self.check_health();
    }
}

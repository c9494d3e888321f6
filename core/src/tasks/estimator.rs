//! The estimator task: each 10 ms step takes the IMU's fresh sample, any fresh GPS fix and
//! horizon measurement, runs the [`Estimator`], publishes the [`Estimate`] and logs it
//! (`docs/log-streams.md`, `estimator.bin`): the state every step (format 1), its standard
//! deviations every step (format 3), health/alignment/gate counters once a second and
//! whenever the phase or health changes (format 2).
//!
//! The IMU's time step comes from its frame counter (100 Hz frames), not from when the task
//! saw the sample, so scheduling jitter does not enter the integration. Without a fresh
//! sample for [`IMU_TIMEOUT_STEPS`] steps the published estimate is marked unhealthy
//! ("no IMU").

use super::task_log::TaskLog;
use crate::comm::{LatestSlot, SlotReader};
use crate::devices::gps::GpsFix;
use crate::devices::imu::{ImuSample, imu_step_s};
use crate::estimation::{Estimate, Estimator, EstimatorConfig, HealthReason, Phase};
use crate::executive::{Task, TaskContext, TaskFault};
use crate::horizon::HorizonAttitude;
use crate::logfmt::RecordSink;

crate::log_record! {
    /// The state, every step (format 1).
    pub struct EstimatorStateLog {
        roll_rad: f32 = "%.5f",
        pitch_rad: f32 = "%.5f",
        yaw_rad: f32 = "%.5f",
        qw: f32 = "%.6f",
        qx: f32 = "%.6f",
        qy: f32 = "%.6f",
        qz: f32 = "%.6f",
        vn_m_s: f32 = "%.3f",
        ve_m_s: f32 = "%.3f",
        vd_m_s: f32 = "%.3f",
        pn_m: f32 = "%.3f",
        pe_m: f32 = "%.3f",
        pd_m: f32 = "%.3f",
        bgx_rad_s: f32 = "%.6f",
        bgy_rad_s: f32 = "%.6f",
        bgz_rad_s: f32 = "%.6f",
        bax_m_s2: f32 = "%.5f",
        bay_m_s2: f32 = "%.5f",
        baz_m_s2: f32 = "%.5f",
        healthy: bool = "%hhu",
    }
}

crate::log_record! {
    /// Health, alignment and gate counters, once a second and on every change (format 2).
    pub struct EstimatorHealthLog {
        phase: u8 = "%hhu",
        align_pct: u8 = "%hhu",
        align_restarts: u32 = "%u",
        healthy: bool = "%hhu",
        reason: u8 = "%hhu",
        imu_steps: u32 = "%u",
        imu_rejected: u32 = "%u",
        imu_missed: u32 = "%u",
        gps_pos_ok: u32 = "%u",
        gps_pos_rejected: u32 = "%u",
        gps_vel_ok: u32 = "%u",
        gps_vel_rejected: u32 = "%u",
        gps_unusable: u32 = "%u",
        gps_resets: u32 = "%u",
        horizon_ok: u32 = "%u",
        horizon_rejected: u32 = "%u",
        horizon_unusable: u32 = "%u",
        resets: u32 = "%u",
        cov_repairs: u32 = "%u",
        gps_pos_nis: f32 = "%.2f",
        gps_vel_nis: f32 = "%.2f",
    }
}

crate::log_record! {
    /// The state's standard deviations, every step (format 3).
    pub struct EstimatorSdLog {
        sd_pn_m: f32 = "%.3f",
        sd_pe_m: f32 = "%.3f",
        sd_pd_m: f32 = "%.3f",
        sd_vn_m_s: f32 = "%.4f",
        sd_ve_m_s: f32 = "%.4f",
        sd_vd_m_s: f32 = "%.4f",
        sd_thn_rad: f32 = "%.6f",
        sd_the_rad: f32 = "%.6f",
        sd_thd_rad: f32 = "%.6f",
        sd_bgx_rad_s: f32 = "%.7f",
        sd_bgy_rad_s: f32 = "%.7f",
        sd_bgz_rad_s: f32 = "%.7f",
        sd_bax_m_s2: f32 = "%.5f",
        sd_bay_m_s2: f32 = "%.5f",
        sd_baz_m_s2: f32 = "%.5f",
    }
}

pub const STATE_INDEX: u8 = 1;
pub const HEALTH_INDEX: u8 = 2;
pub const SD_INDEX: u8 = 3;

/// Steps without a fresh IMU sample before the estimate is marked unhealthy.
pub const IMU_TIMEOUT_STEPS: u32 = 5;
const HEALTH_LOG_INTERVAL_NS: u64 = 1_000_000_000;

pub struct EstimatorTask<'a, S: RecordSink> {
    estimator: Estimator,
    log: TaskLog<S>,
    imu: SlotReader<'a, ImuSample>,
    gps: SlotReader<'a, GpsFix>,
    horizon: Option<SlotReader<'a, HorizonAttitude>>,
    out: &'a LatestSlot<Estimate>,
    last_imu: Option<(u8, u64)>,
    steps_without_imu: u32,
    imu_missed: u32,
    last_health_log_ns: Option<u64>,
    last_health_key: Option<(Phase, bool, HealthReason)>,
    last: Option<Estimate>,
}

impl<'a, S: RecordSink> EstimatorTask<'a, S> {
    pub fn new(
        config: EstimatorConfig,
        log: S,
        imu: &'a LatestSlot<ImuSample>,
        gps: &'a LatestSlot<GpsFix>,
        horizon: Option<&'a LatestSlot<HorizonAttitude>>,
        out: &'a LatestSlot<Estimate>,
    ) -> Self {
        Self {
            estimator: Estimator::new(config),
            log: TaskLog::new(log),
            imu: imu.reader(),
            gps: gps.reader(),
            horizon: horizon.map(LatestSlot::reader),
            out,
            last_imu: None,
            steps_without_imu: 0,
            imu_missed: 0,
            last_health_log_ns: None,
            last_health_key: None,
            last: None,
        }
    }

    pub fn estimator(&self) -> &Estimator {
        &self.estimator
    }

    /// The filter itself, for a warm start ([`Estimator::start_from`]) by a host that knows
    /// the state better than an alignment could (`skyframe replay` of a log that starts in
    /// motion).
    pub fn estimator_mut(&mut self) -> &mut Estimator {
        &mut self.estimator
    }

    /// Steps that found no fresh IMU sample.
    pub fn imu_missed(&self) -> u32 {
        self.imu_missed
    }

    fn take_imu(&mut self) {
        let Some(sample) = self.imu.take_fresh() else {
            self.imu_missed = self.imu_missed.wrapping_add(1);
            self.steps_without_imu = self.steps_without_imu.saturating_add(1);
            return;
        };
        self.steps_without_imu = 0;
        // A repeated publication of the same frame is nothing new; a gap the counter cannot
        // measure, or an outage it missed, is timed by the receive times (`imu_step_s`).
        let Some(dt) = imu_step_s(self.last_imu, sample.counter, sample.received_ns) else {
            return;
        };
        self.last_imu = Some((sample.counter, sample.received_ns));
        let m = sample.measurement;
        self.estimator
            .imu(sample.received_ns, dt, m.rate_radps, m.specific_force_mps2);
    }

    fn log_estimate(&mut self, cx: &TaskContext<'_>, e: &Estimate) {
        let [qw, qx, qy, qz] = e.quaternion;
        let [vn_m_s, ve_m_s, vd_m_s] = e.velocity_ned_mps;
        let [pn_m, pe_m, pd_m] = e.position_ned_m;
        let [bgx_rad_s, bgy_rad_s, bgz_rad_s] = e.gyro_bias_radps;
        let [bax_m_s2, bay_m_s2, baz_m_s2] = e.accel_bias_mps2;
        let state = EstimatorStateLog {
            roll_rad: e.roll_rad,
            pitch_rad: e.pitch_rad,
            yaw_rad: e.yaw_rad,
            qw,
            qx,
            qy,
            qz,
            vn_m_s,
            ve_m_s,
            vd_m_s,
            pn_m,
            pe_m,
            pd_m,
            bgx_rad_s,
            bgy_rad_s,
            bgz_rad_s,
            bax_m_s2,
            bay_m_s2,
            baz_m_s2,
            healthy: e.health.healthy,
        };
        self.log.log(cx, STATE_INDEX, &state);
        let sd = e.covariance_diag.map(|v| libm::sqrtf(v.max(0.0)));
        // The covariance diagonal is in the state order the columns follow.
        let sd = EstimatorSdLog {
            sd_pn_m: sd[0],
            sd_pe_m: sd[1],
            sd_pd_m: sd[2],
            sd_vn_m_s: sd[3],
            sd_ve_m_s: sd[4],
            sd_vd_m_s: sd[5],
            sd_thn_rad: sd[6],
            sd_the_rad: sd[7],
            sd_thd_rad: sd[8],
            sd_bgx_rad_s: sd[9],
            sd_bgy_rad_s: sd[10],
            sd_bgz_rad_s: sd[11],
            sd_bax_m_s2: sd[12],
            sd_bay_m_s2: sd[13],
            sd_baz_m_s2: sd[14],
        };
        self.log.log(cx, SD_INDEX, &sd);
        let h = e.health;
        let key = (h.phase, h.healthy, h.reason);
        let due = self
            .last_health_log_ns
            .is_none_or(|t| cx.now_ns.saturating_sub(t) >= HEALTH_LOG_INTERVAL_NS);
        if due || self.last_health_key != Some(key) {
            self.last_health_log_ns = Some(cx.now_ns);
            self.last_health_key = Some(key);
            let c = h.counters;
            let health = EstimatorHealthLog {
                phase: h.phase as u8,
                align_pct: h.alignment_percent,
                align_restarts: h.alignment_restarts,
                healthy: h.healthy,
                reason: h.reason as u8,
                imu_steps: c.imu_steps,
                imu_rejected: c.imu_rejected,
                imu_missed: self.imu_missed,
                gps_pos_ok: c.gps_pos_accepted,
                gps_pos_rejected: c.gps_pos_rejected,
                gps_vel_ok: c.gps_vel_accepted,
                gps_vel_rejected: c.gps_vel_rejected,
                gps_unusable: c.gps_unusable,
                gps_resets: c.gps_resets,
                horizon_ok: c.horizon_accepted,
                horizon_rejected: c.horizon_rejected,
                horizon_unusable: c.horizon_unusable,
                resets: c.resets,
                cov_repairs: c.covariance_repairs,
                gps_pos_nis: h.gps_pos_nis,
                gps_vel_nis: h.gps_vel_nis,
            };
            self.log.log(cx, HEALTH_INDEX, &health);
        }
    }
}

impl<S: RecordSink> Task for EstimatorTask<'_, S> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let bad = |_| TaskFault::new("estimator log format");
        self.log
            .declare::<EstimatorStateLog>(cx, STATE_INDEX)
            .map_err(bad)?;
        self.log
            .declare::<EstimatorHealthLog>(cx, HEALTH_INDEX)
            .map_err(bad)?;
        self.log
            .declare::<EstimatorSdLog>(cx, SD_INDEX)
            .map_err(bad)?;
        self.log.begin(cx);
        self.last_health_log_ns = None;
        self.last_health_key = None;
        Ok(())
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let cx = &*cx;
        self.take_imu();
        if let Some(fix) = self.gps.take_fresh() {
            self.estimator.gps(&fix);
        }
        if let Some(h) = self.horizon.as_mut().and_then(SlotReader::take_fresh) {
            self.estimator.horizon(&h);
        }
        let mut e = self.estimator.estimate();
        if self.steps_without_imu >= IMU_TIMEOUT_STEPS {
            e.health.healthy = false;
            e.health.reason = HealthReason::NoImu;
        }
        self.out.publish(e);
        self.last = Some(e);
        self.log_estimate(cx, &e);
        Ok(())
    }

    /// The filter's state survives a task reset (it resets itself on NaN or divergence;
    /// re-aligning in flight is impossible): recovering only closes this logging section.
    fn recover(&mut self, cx: &mut TaskContext<'_>) {
        self.log.end(cx);
    }

    fn shutdown(&mut self, cx: &mut TaskContext<'_>) {
        self.log.end(cx);
    }
}

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
use crate::comm::{LatestSlot, RecordSink, SlotReader};
use crate::devices::gps::GpsFix;
use crate::devices::imu::ImuSample;
use crate::estimation::{Estimate, Estimator, EstimatorConfig, HealthReason, Phase};
use crate::executive::{Task, TaskContext, TaskFault};
use crate::link::messages::HorizonAttitude;
use crate::logfmt::format::Format;
use crate::logfmt::record::LogFormat;

pub const ESTIMATOR_STATE_LOG: LogFormat = LogFormat::new(
    "%.5f,%.5f,%.5f,%.6f,%.6f,%.6f,%.6f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.6f,%.6f,%.6f,%.5f,%.5f,%.5f,%hhu",
    "roll_rad,pitch_rad,yaw_rad,qw,qx,qy,qz,vn_m_s,ve_m_s,vd_m_s,pn_m,pe_m,pd_m,\
     bgx_rad_s,bgy_rad_s,bgz_rad_s,bax_m_s2,bay_m_s2,baz_m_s2,healthy",
);
pub const ESTIMATOR_HEALTH_LOG: LogFormat = LogFormat::new(
    "%hhu,%hhu,%u,%hhu,%hhu,%u,%u,%u,%u,%u,%u,%u,%u,%u,%u,%u,%u,%u,%u,%.2f,%.2f",
    "phase,align_pct,align_restarts,healthy,reason,imu_steps,imu_rejected,imu_missed,\
     gps_pos_ok,gps_pos_rejected,gps_vel_ok,gps_vel_rejected,gps_unusable,gps_resets,\
     horizon_ok,horizon_rejected,horizon_unusable,resets,cov_repairs,gps_pos_nis,gps_vel_nis",
);
pub const ESTIMATOR_SD_LOG: LogFormat = LogFormat::new(
    "%.3f,%.3f,%.3f,%.4f,%.4f,%.4f,%.6f,%.6f,%.6f,%.7f,%.7f,%.7f,%.5f,%.5f,%.5f",
    "sd_pn_m,sd_pe_m,sd_pd_m,sd_vn_m_s,sd_ve_m_s,sd_vd_m_s,sd_thn_rad,sd_the_rad,sd_thd_rad,\
     sd_bgx_rad_s,sd_bgy_rad_s,sd_bgz_rad_s,sd_bax_m_s2,sd_bay_m_s2,sd_baz_m_s2",
);
pub const STATE_INDEX: u8 = 1;
pub const HEALTH_INDEX: u8 = 2;
pub const SD_INDEX: u8 = 3;

/// The IMU frame period the counter counts.
pub const IMU_PERIOD_S: f64 = 0.01;
/// Steps without a fresh IMU sample before the estimate is marked unhealthy.
pub const IMU_TIMEOUT_STEPS: u32 = 5;
const HEALTH_LOG_INTERVAL_NS: u64 = 1_000_000_000;

pub struct EstimatorTask<'a, S: RecordSink> {
    estimator: Estimator,
    log: TaskLog<S>,
    state_format: Format,
    health_format: Format,
    sd_format: Format,
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
            state_format: Format::EMPTY,
            health_format: Format::EMPTY,
            sd_format: Format::EMPTY,
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
        let dt = match self.last_imu {
            Some((counter, _)) if sample.counter == counter => {
                // The same frame again (a repeated publication): nothing new.
                return;
            }
            Some((counter, _)) if sample.counter.wrapping_sub(counter) <= 10 => {
                f64::from(sample.counter.wrapping_sub(counter)) * IMU_PERIOD_S
            }
            // A gap the counter cannot measure: the receive times can (the filter refuses
            // steps over 0.1 s).
            Some((_, received)) => sample.received_ns.saturating_sub(received) as f64 * 1e-9,
            None => IMU_PERIOD_S,
        };
        self.last_imu = Some((sample.counter, sample.received_ns));
        let m = sample.measurement;
        self.estimator
            .imu(sample.received_ns, dt, m.rate_radps, m.specific_force_mps2);
    }

    fn log_estimate(&mut self, cx: &TaskContext<'_>, e: &Estimate) {
        let [qw, qx, qy, qz] = e.quaternion;
        let [vn, ve, vd] = e.velocity_ned_mps;
        let [pn, pe, pd] = e.position_ned_m;
        let [gx, gy, gz] = e.gyro_bias_radps;
        let [ax, ay, az] = e.accel_bias_mps2;
        self.log.record(cx, STATE_INDEX, &self.state_format, |w| {
            w.f32(e.roll_rad)
                .f32(e.pitch_rad)
                .f32(e.yaw_rad)
                .f32(qw)
                .f32(qx)
                .f32(qy)
                .f32(qz)
                .f32(vn)
                .f32(ve)
                .f32(vd)
                .f32(pn)
                .f32(pe)
                .f32(pd)
                .f32(gx)
                .f32(gy)
                .f32(gz)
                .f32(ax)
                .f32(ay)
                .f32(az)
                .u8(u8::from(e.health.healthy))
        });
        let sd = e.covariance_diag.map(|v| libm::sqrtf(v.max(0.0)));
        self.log.record(cx, SD_INDEX, &self.sd_format, |w| {
            sd.iter().fold(w, |w, &s| w.f32(s))
        });
        let h = e.health;
        let key = (h.phase, h.healthy, h.reason);
        let due = self
            .last_health_log_ns
            .is_none_or(|t| cx.now_ns.saturating_sub(t) >= HEALTH_LOG_INTERVAL_NS);
        if due || self.last_health_key != Some(key) {
            self.last_health_log_ns = Some(cx.now_ns);
            self.last_health_key = Some(key);
            let c = h.counters;
            let missed = self.imu_missed;
            self.log.record(cx, HEALTH_INDEX, &self.health_format, |w| {
                w.u8(h.phase as u8)
                    .u8(h.alignment_percent)
                    .u32(h.alignment_restarts)
                    .u8(u8::from(h.healthy))
                    .u8(h.reason as u8)
                    .u32(c.imu_steps)
                    .u32(c.imu_rejected)
                    .u32(missed)
                    .u32(c.gps_pos_accepted)
                    .u32(c.gps_pos_rejected)
                    .u32(c.gps_vel_accepted)
                    .u32(c.gps_vel_rejected)
                    .u32(c.gps_unusable)
                    .u32(c.gps_resets)
                    .u32(c.horizon_accepted)
                    .u32(c.horizon_rejected)
                    .u32(c.horizon_unusable)
                    .u32(c.resets)
                    .u32(c.covariance_repairs)
                    .f32(h.gps_pos_nis)
                    .f32(h.gps_vel_nis)
            });
        }
    }
}

impl<S: RecordSink> Task for EstimatorTask<'_, S> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let bad = |_| TaskFault::new("estimator log format");
        self.state_format = self
            .log
            .declare(cx, STATE_INDEX, &ESTIMATOR_STATE_LOG)
            .map_err(bad)?;
        self.health_format = self
            .log
            .declare(cx, HEALTH_INDEX, &ESTIMATOR_HEALTH_LOG)
            .map_err(bad)?;
        self.sd_format = self
            .log
            .declare(cx, SD_INDEX, &ESTIMATOR_SD_LOG)
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

//! The estimator's step time. In virtual time the executive's clock does not move while a
//! task runs, so the flight itself cannot say; the logged IMU samples and GPS fixes are
//! replayed through the same `Estimator` the task runs, each step timed with the host's
//! monotonic clock.

use skyframe_core::devices::imu::imu_step_s;
use std::time::Instant;

use serde::Serialize;
use skyframe_core::devices::gps::GpsFix;
use skyframe_core::estimation::{Estimator, EstimatorConfig};
use skyframe_logtable::Table;

use super::column;

/// How long one estimator step (an IMU sample, the GPS fix that arrived with it, and the
/// estimate) takes on this machine.
#[derive(Clone, Debug, Serialize)]
pub struct StepTime {
    pub steps: u64,
    pub mean_us: f64,
    pub p99_us: f64,
    pub max_us: f64,
    pub budget_us: f64,
    /// `release` or `debug`: debug builds are many times slower.
    pub build: &'static str,
}

pub fn time_estimator(imu: &Table, fixes: &[GpsFix], budget_ns: u64) -> Result<StepTime, String> {
    let c = |name| column(imu, "imu", name);
    let (counter, p, q, r) = (c("counter")?, c("p_rad_s")?, c("q_rad_s")?, c("r_rad_s")?);
    let (fx, fy, fz) = (c("fx_m_s2")?, c("fy_m_s2")?, c("fz_m_s2")?);
    let mut estimator = Estimator::new(EstimatorConfig::default());
    let mut next_fix = fixes.iter().peekable();
    let mut last: Option<(u8, u64)> = None;
    let mut durations_ns: Vec<u64> = Vec::with_capacity(imu.times_ns.len());
    for (i, &t) in imu.times_ns.iter().enumerate() {
        let at = |col: &[f64]| col.get(i).copied().unwrap_or(f64::NAN);
        // The logged counter is a %hhu column: a whole number 0..=255.
        let count = at(counter) as u8;
        let t_ns = u64::try_from(t).unwrap_or(0);
        // As the task does (one rule, `imu_step_s`).
        let Some(dt) = imu_step_s(last, count, t_ns) else {
            continue;
        };
        last = Some((count, t_ns));
        let rates = [at(p) as f32, at(q) as f32, at(r) as f32];
        let force = [at(fx) as f32, at(fy) as f32, at(fz) as f32];
        let start = Instant::now();
        estimator.imu(t_ns, dt, rates, force);
        while let Some(fix) = next_fix.next_if(|f| f.received_ns <= t_ns) {
            estimator.gps(fix);
        }
        std::hint::black_box(estimator.estimate());
        durations_ns.push(u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX));
    }
    if durations_ns.is_empty() {
        return Err("imu.bin holds no samples: nothing to time the estimator on".into());
    }
    let steps = durations_ns.len() as u64;
    let mean_us = durations_ns.iter().map(|&d| d as f64).sum::<f64>() / steps as f64 / 1e3;
    durations_ns.sort_unstable();
    let p99_index = (durations_ns.len() * 99 / 100).min(durations_ns.len() - 1);
    Ok(StepTime {
        steps,
        mean_us,
        p99_us: durations_ns
            .get(p99_index)
            .map_or(f64::NAN, |&d| d as f64 / 1e3),
        max_us: durations_ns.last().map_or(f64::NAN, |&d| d as f64 / 1e3),
        budget_us: budget_ns as f64 / 1e3,
        build: if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        },
    })
}

/// The logged fixes as the GPS task published them (`docs/log-streams.md`, gps.bin 1); NaN
/// columns are fields the receiver did not give.
pub fn gps_fixes(gps: &Table) -> Result<Vec<GpsFix>, String> {
    let c = |name| column(gps, "gps", name);
    let (valid, lat, lon, alt) = (c("valid")?, c("lat_deg")?, c("lon_deg")?, c("alt_m")?);
    let (vn, ve, vd) = (c("vn_m_s")?, c("ve_m_s")?, c("vd_m_s")?);
    let (hdop, vdop) = (c("hdop")?, c("vdop")?);
    let (sd_n, sd_e, sd_d) = (c("sd_n_m")?, c("sd_e_m")?, c("sd_d_m")?);
    let mut fixes = Vec::with_capacity(gps.times_ns.len());
    for (i, &t) in gps.times_ns.iter().enumerate() {
        let at = |col: &[f64]| col.get(i).copied().filter(|v| v.is_finite());
        let f32_at = |col: &[f64]| at(col).map(|v| v as f32);
        let velocity = [f32_at(vn), f32_at(ve), f32_at(vd)];
        let (course, speed) = match (velocity[0], velocity[1]) {
            (Some(n), Some(e)) => (Some(e.atan2(n)), Some(n.hypot(e))),
            _ => (None, None),
        };
        fixes.push(GpsFix {
            received_ns: u64::try_from(t).unwrap_or(0),
            valid: at(valid) == Some(1.0),
            latitude_deg: at(lat),
            longitude_deg: at(lon),
            altitude_msl_m: at(alt),
            velocity_ned_mps: velocity,
            course_rad: course,
            ground_speed_mps: speed,
            hdop: f32_at(hdop),
            vdop: f32_at(vdop),
            position_sd_m: [f32_at(sd_n), f32_at(sd_e), f32_at(sd_d)],
            ..GpsFix::default()
        });
    }
    Ok(fixes)
}

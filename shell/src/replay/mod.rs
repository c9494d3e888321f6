//! `skyframe replay LOG`: skyframe's estimator on a real flight.
//!
//! ```text
//! LOG (PX4 .ulg | ArduPilot .bin) ─▶ ulog / dataflash ─▶ FlightLog (raw IMU, GPS, onboard estimate)
//!   raw IMU + GPS ─▶ run: the shipped frame table, the airplane's estimator task ─▶ estimates
//!   estimates vs onboard estimate ─▶ agreement: RMS and max per flight phase (+ figures)
//! ```
//!
//! The onboard estimate is another filter, not the truth: replay reports agreement, and
//! counts what the estimator did on its own (resets, rejections, non-finite estimates).

pub mod agreement;
pub mod dataflash;
pub mod flightlog;
pub mod plot;
pub mod run;
pub mod ulog;

use std::path::Path;

use serde::Serialize;

pub use agreement::{Agreement, PhaseAgreement};
pub use flightlog::FlightLog;
pub use run::{RunOptions, StartMode};

/// Reads a flight log of either format from its bytes (`path` only names it in errors).
pub fn read_log(path: &str, bytes: &[u8]) -> Result<FlightLog, String> {
    if ulog::looks_like_ulog(bytes) {
        ulog::read(path, bytes)
    } else if dataflash::looks_like_dataflash(bytes) {
        dataflash::read(path, bytes)
    } else {
        Err(flightlog::error_at(
            path,
            0,
            "neither a PX4 ULog (ULog header) nor an ArduPilot DataFlash log (0xA3 0x95)",
        ))
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct LogSummary {
    pub path: String,
    pub format: &'static str,
    pub duration_s: f64,
    pub imu_source: String,
    pub imu_records: usize,
    pub imu_rate_hz: f64,
    pub gps_source: String,
    pub gps_fixes: usize,
    pub gps_rate_hz: f64,
    pub attitude_source: String,
    pub onboard_attitude_records: usize,
    pub nav_source: String,
    pub onboard_nav_records: usize,
    pub airspeed_samples: usize,
    /// Present in the log, not used: the estimator has no magnetometer.
    pub magnetometer_samples: usize,
    pub gps_velocity_check: flightlog::GpsVelocityCheck,
    pub warnings: Vec<String>,
}

/// The GPS velocity 1-σ the estimator is told when the velocity is differenced positions.
const DERIVED_VELOCITY_SD_M_S: f64 = 1.0;

#[derive(Clone, Debug, Serialize)]
pub struct Counts {
    /// Whole-filter resets (non-finite state or covariance, divergence).
    pub resets: u32,
    /// Resets of position and velocity to the GPS after a run of rejections.
    pub gps_resets: u32,
    pub gps_position_accepted: u32,
    pub gps_position_rejected: u32,
    pub gps_velocity_accepted: u32,
    pub gps_velocity_rejected: u32,
    pub gps_unusable: u32,
    pub imu_rejected: u32,
    pub covariance_repairs: u32,
    pub alignment_restarts: u32,
    pub non_finite_estimates: u64,
}

#[derive(Clone, Debug, Serialize)]
pub struct EstimatorSummary {
    pub frame_table: &'static str,
    pub imu_frames: u64,
    /// 10 ms frames the log left without IMU data (dropouts).
    pub imu_frames_empty: u64,
    pub gps_fixes_published: u64,
    pub gps_latency_ms: f64,
    pub start: Option<run::StartInfo>,
    /// Seconds with our estimate running (heading known).
    pub running_s: f64,
    pub counts: Counts,
    pub events: Vec<run::Event>,
    /// No non-finite estimate, no whole-filter reset.
    pub stayed_finite_without_reset: bool,
}

#[derive(Clone, Debug, Serialize)]
pub struct ReplayReport {
    pub log: LogSummary,
    pub estimator: EstimatorSummary,
    /// Our estimate minus the onboard estimate: agreement, not accuracy.
    pub agreement: Agreement,
    /// Which heading the airspeed and GPS velocity support (logs with airspeed).
    pub heading_check: Option<agreement::HeadingCheck>,
    pub notes: Vec<String>,
}

fn rate_hz(times: impl Iterator<Item = u64> + Clone) -> f64 {
    let n = times.clone().count();
    let (Some(first), Some(last)) = (times.clone().next(), times.last()) else {
        return f64::NAN;
    };
    if n < 2 || last <= first {
        return f64::NAN;
    }
    (n - 1) as f64 / ((last - first) as f64 * 1e-6)
}

/// Replays a log already read.
pub fn replay(
    path: &str,
    log: &FlightLog,
    options: RunOptions,
) -> Result<(ReplayReport, agreement::Series), String> {
    let mut log = log.clone();
    let velocity_check = log.check_gps_velocity();
    let log = &log;
    if log.gps.is_empty() {
        return Err(format!(
            "{path}: no GPS records: the estimator needs GPS position and velocity"
        ));
    }
    let mut options = options;
    if velocity_check.replaced && options.gps_velocity_sd_m_s.is_none() {
        // Differenced positions are noisier than a receiver's Doppler velocity.
        options.gps_velocity_sd_m_s = Some(DERIVED_VELOCITY_SD_M_S);
    }
    let result = run::run(log, options).map_err(|e| format!("{path}: {e}"))?;
    let (agreement, series) = agreement::compare(log, &result);
    let heading_check = agreement::heading_check(log, &result);
    let c = result.counters;
    let duration_s = match (log.imu.first(), log.imu.last()) {
        (Some(a), Some(b)) => b.t_us.saturating_sub(a.t_us) as f64 * 1e-6,
        _ => 0.0,
    };
    let mut notes = vec![
        "Agreement with the onboard estimator, which is not truth.".to_string(),
        "Yaw: skyframe's estimator uses no magnetometer; its heading comes from the GPS \
         course (at launch) and from GPS velocity in manoeuvres, the onboard estimator's \
         from its magnetometer (and GPS)."
            .to_string(),
        format!(
            "Euler angles are not scored where the onboard pitch exceeds {:.0} degrees; the \
             rotation angle is.",
            60.0
        ),
    ];
    if log.onboard_nav.is_empty() {
        notes.push(
            "The log has no onboard position or velocity: position is compared with the GPS \
             fixes only."
                .into(),
        );
    }
    let report = ReplayReport {
        log: LogSummary {
            path: path.to_string(),
            format: log.format,
            duration_s,
            imu_source: log.imu_source.clone(),
            imu_records: log.imu.len(),
            imu_rate_hz: rate_hz(log.imu.iter().map(|r| r.t_us)),
            gps_source: log.gps_source.clone(),
            gps_fixes: log.gps.len(),
            gps_rate_hz: rate_hz(log.gps.iter().map(|r| r.t_us)),
            attitude_source: log.attitude_source.clone(),
            onboard_attitude_records: log.onboard_attitude.len(),
            nav_source: log.nav_source.clone(),
            onboard_nav_records: log.onboard_nav.len(),
            airspeed_samples: log.airspeed.len(),
            magnetometer_samples: log.magnetometer_samples,
            gps_velocity_check: velocity_check,
            warnings: log.warnings.clone(),
        },
        estimator: EstimatorSummary {
            frame_table: "schedule.toml as shipped (imu, estimator and gps tasks at their \
                          periods and offsets)",
            imu_frames: result.imu_frames,
            imu_frames_empty: result.imu_frames_empty,
            gps_fixes_published: result.gps_fixes_published,
            gps_latency_ms: result.gps_latency_ms,
            start: result.start.clone(),
            running_s: agreement.all.seconds,
            counts: Counts {
                resets: c.resets,
                gps_resets: c.gps_resets,
                gps_position_accepted: c.gps_pos_accepted,
                gps_position_rejected: c.gps_pos_rejected,
                gps_velocity_accepted: c.gps_vel_accepted,
                gps_velocity_rejected: c.gps_vel_rejected,
                gps_unusable: c.gps_unusable,
                imu_rejected: c.imu_rejected,
                covariance_repairs: c.covariance_repairs,
                alignment_restarts: result.alignment_restarts,
                non_finite_estimates: result.non_finite_estimates,
            },
            events: result.events.clone(),
            stayed_finite_without_reset: result.non_finite_estimates == 0 && c.resets == 0,
        },
        agreement,
        heading_check,
        notes,
    };
    Ok((report, series))
}

/// Reads and replays the log at `path`.
pub fn replay_file(
    path: &Path,
    options: RunOptions,
) -> Result<(ReplayReport, agreement::Series, FlightLog), String> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| format!("{name}: {e}"))?;
    let log = read_log(&name, &bytes)?;
    let (report, series) = replay(&name, &log, options)?;
    Ok((report, series, log))
}

fn cell(d: &agreement::Difference) -> String {
    if d.samples == 0 {
        "      -      ".into()
    } else {
        format!("{:6.2} {:6.2}", d.rms, d.max)
    }
}

/// The report as text: where the data came from, what the estimator did, the agreement
/// table.
pub fn render(r: &ReplayReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let l = &r.log;
    let _ = writeln!(s, "{} ({}, {:.1} s)", l.path, l.format, l.duration_s);
    let _ = writeln!(
        s,
        "  IMU {} records at {:.0} Hz: {}",
        l.imu_records, l.imu_rate_hz, l.imu_source
    );
    let _ = writeln!(
        s,
        "  GPS {} fixes at {:.1} Hz: {}",
        l.gps_fixes, l.gps_rate_hz, l.gps_source
    );
    let _ = writeln!(
        s,
        "  onboard: {} attitudes ({}), {} position/velocity records ({})",
        l.onboard_attitude_records,
        l.attitude_source,
        l.onboard_nav_records,
        if l.nav_source.is_empty() {
            "none"
        } else {
            &l.nav_source
        }
    );
    for w in &l.warnings {
        let _ = writeln!(s, "  warning: {w}");
    }
    let e = &r.estimator;
    let c = &e.counts;
    match &e.start {
        Some(st) => {
            let _ = writeln!(
                s,
                "estimator: started at {:.2} s by {}: {}",
                st.at_s, st.how, st.why
            );
        }
        None => {
            let _ = writeln!(s, "estimator: never started (no alignment, no launch)");
        }
    }
    let _ = writeln!(
        s,
        "  {} IMU frames ({} empty), {} GPS fixes published, GPS latency {:.0} ms, running {:.1} s",
        e.imu_frames, e.imu_frames_empty, e.gps_fixes_published, e.gps_latency_ms, e.running_s
    );
    let _ = writeln!(
        s,
        "  resets {} (to GPS {}), GPS position {} accepted / {} rejected, velocity {} / {}, \
         unusable {}, IMU rejected {}, covariance repairs {}, non-finite estimates {}",
        c.resets,
        c.gps_resets,
        c.gps_position_accepted,
        c.gps_position_rejected,
        c.gps_velocity_accepted,
        c.gps_velocity_rejected,
        c.gps_unusable,
        c.imu_rejected,
        c.covariance_repairs,
        c.non_finite_estimates
    );
    let _ = writeln!(
        s,
        "agreement with the onboard estimate (ours − onboard; RMS max):"
    );
    let _ = writeln!(
        s,
        "  {:<8} {:>6}  {:^13} {:^13} {:^13} {:^13} {:^13} {:^13} {:^13}",
        "phase",
        "s",
        "roll deg",
        "pitch deg",
        "yaw deg",
        "horiz m",
        "vert m",
        "vel m/s",
        "vs GPS horiz m"
    );
    let mut line = |name: &str, p: &PhaseAgreement| {
        let _ = writeln!(
            s,
            "  {:<8} {:>6.1}  {} {} {} {} {} {} {}",
            name,
            p.seconds,
            cell(&p.roll_deg),
            cell(&p.pitch_deg),
            cell(&p.yaw_deg),
            cell(&p.horizontal_position_m),
            cell(&p.vertical_position_m),
            cell(&p.velocity_m_s),
            cell(&p.gps_horizontal_m)
        );
    };
    line("all", &r.agreement.all);
    for name in agreement::PHASES {
        if let Some(p) = r.agreement.phases.get(name) {
            line(name, p);
        }
    }
    if let Some(h) = &r.heading_check {
        let _ = writeln!(
            s,
            "heading check (wind triangle: GPS velocity = k * airspeed along the heading + a constant wind):"
        );
        let fits =
            std::iter::once(("ours", Some(h.ours))).chain(std::iter::once(("onboard", h.onboard)));
        for (name, f) in fits {
            if let Some(f) = f {
                let _ = writeln!(
                    s,
                    "  {name:<8} residual {:.2} m/s, heading vs air track {:.1} deg RMS \
                     (k {:.2}, wind N {:.1} E {:.1} m/s, {} fixes)",
                    f.residual_rms_m_s,
                    f.heading_vs_air_track_rms_deg,
                    f.airspeed_scale,
                    f.wind_north_m_s,
                    f.wind_east_m_s,
                    f.fixes
                );
            }
        }
    }
    for n in &r.notes {
        let _ = writeln!(s, "note: {n}");
    }
    s
}

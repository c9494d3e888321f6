//! What replay takes from a real flight log, whatever wrote it (PX4 ULog, ArduPilot
//! DataFlash): the raw IMU and GPS the estimator is fed, and the onboard estimate the result
//! is compared with. Times are the log's own microseconds; units and frames are
//! `conventions.md`'s (SI, body FRD, NED, Hamilton quaternions body → NED).

/// One IMU record as the log has it: the increments of angle and velocity over the interval
/// `(t_us − dt_s, t_us]`. A log of rates (mean or instantaneous) is turned into increments
/// with the interval since its previous sample; a log of delta angles/velocities is taken as
/// it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuRecord {
    pub t_us: u64,
    pub dt_s: f64,
    pub delta_angle_rad: [f64; 3],
    pub delta_velocity_m_s: [f64; 3],
}

/// One GPS epoch, stamped with the time the autopilot received it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpsRecord {
    pub t_us: u64,
    /// A 3-D fix (or better).
    pub fix_3d: bool,
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    /// Above mean sea level.
    pub altitude_m: f64,
    pub velocity_ned_m_s: [Option<f64>; 3],
    /// The receiver's own accuracy estimates (m), when it gave them.
    pub horizontal_accuracy_m: Option<f64>,
    pub vertical_accuracy_m: Option<f64>,
    pub hdop: Option<f64>,
    pub satellites: Option<u8>,
}

/// The onboard estimator's attitude.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AttitudeRecord {
    pub t_us: u64,
    /// Hamilton, scalar first, body FRD → NED.
    pub quaternion: [f64; 4],
}

/// The onboard estimator's position and velocity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NavRecord {
    pub t_us: u64,
    /// Geodetic: degrees, metres above mean sea level (`None` if the log only has a local
    /// position without its origin).
    pub geodetic: Option<[f64; 3]>,
    pub velocity_ned_m_s: Option<[f64; 3]>,
}

/// A real flight, reduced to what replay uses.
#[derive(Clone, Debug, Default)]
pub struct FlightLog {
    /// `PX4 ULog` or `ArduPilot DataFlash`.
    pub format: &'static str,
    /// Where the IMU came from and how (e.g. `sensor_combined: mean rates over
    /// gyro_integral_dt`).
    pub imu_source: String,
    pub gps_source: String,
    pub attitude_source: String,
    pub nav_source: String,
    pub imu: Vec<ImuRecord>,
    pub gps: Vec<GpsRecord>,
    pub onboard_attitude: Vec<AttitudeRecord>,
    pub onboard_nav: Vec<NavRecord>,
    /// Airspeed samples (t_us, equivalent airspeed m/s): not used by the estimator (it has
    /// no air data), kept for the flight phases and the figures.
    pub airspeed: Vec<(u64, f64)>,
    /// Magnetometer samples in the log: counted only (the estimator uses no magnetometer).
    pub magnetometer_samples: usize,
    /// Problems met while reading that did not stop it (a truncated tail): one line each,
    /// naming the byte offset.
    pub warnings: Vec<String>,
}

impl FlightLog {
    /// Sorts every series by time (a log written by several threads, or with appended
    /// sections, need not be in order) and drops records with non-finite times or values
    /// the estimator could not take anyway.
    pub fn normalise(&mut self) {
        self.imu.retain(|r| {
            r.dt_s.is_finite()
                && r.dt_s > 0.0
                && r.delta_angle_rad.iter().all(|v| v.is_finite())
                && r.delta_velocity_m_s.iter().all(|v| v.is_finite())
        });
        self.imu.sort_by_key(|r| r.t_us);
        self.imu.dedup_by_key(|r| r.t_us);
        self.gps.sort_by_key(|r| r.t_us);
        self.onboard_attitude
            .retain(|r| r.quaternion.iter().all(|v| v.is_finite()));
        self.onboard_attitude.sort_by_key(|r| r.t_us);
        self.onboard_nav.sort_by_key(|r| r.t_us);
        self.airspeed.retain(|(_, v)| v.is_finite());
        self.airspeed.sort_by_key(|(t, _)| *t);
    }
}

/// One IMU sample as a log of rates has it: time (µs), its own interval (s) if the log
/// gives one, rates (rad/s), specific force (m/s²).
pub type RateSample = (u64, Option<f64>, [f64; 3], [f64; 3]);

/// Turns rate samples (rad/s, m/s²) stamped at `t_us` into increments over the interval since
/// the previous sample. `interval_us` gives a sample's own interval when the log has one
/// (PX4's `gyro_integral_dt`); without it the gap to the previous sample is used, and a gap
/// longer than `max_gap_s` (a logging dropout) gives the sample no interval at all, so a
/// dropout is a gap in the IMU, not a 2-second sample.
pub fn rates_to_increments(samples: &[RateSample], max_gap_s: f64) -> Vec<ImuRecord> {
    let mut out = Vec::with_capacity(samples.len());
    let mut previous: Option<u64> = None;
    for &(t_us, interval_s, rate, force) in samples {
        let gap = previous.map(|p| t_us.saturating_sub(p) as f64 * 1e-6);
        previous = Some(t_us);
        let dt = match (interval_s, gap) {
            (Some(dt), _) if dt.is_finite() && dt > 0.0 && dt <= max_gap_s => dt,
            (None, Some(gap)) if gap > 0.0 && gap <= max_gap_s => gap,
            _ => continue,
        };
        out.push(ImuRecord {
            t_us,
            dt_s: dt,
            delta_angle_rad: rate.map(|w| w * dt),
            delta_velocity_m_s: force.map(|f| f * dt),
        });
    }
    out
}

/// The 3-2-1 quaternion (body → NED) of roll, pitch, yaw in radians: the simulator's.
pub use skyframe_sim::plant::math::quat_from_euler as quaternion_from_euler;

/// One line naming the file and the byte offset, as every reader error reads.
pub fn error_at(path: &str, offset: usize, what: impl core::fmt::Display) -> String {
    // The parser's text may quote bytes of the file: control characters are escaped so the
    // message stays one line.
    let what: String = what
        .to_string()
        .chars()
        .flat_map(|c| {
            if c.is_control() {
                c.escape_default().collect::<Vec<_>>()
            } else {
                vec![c]
            }
        })
        .collect();
    format!("{path}: byte {offset}: {what}")
}

/// How far a log's GPS velocity may disagree with the velocity its own positions show
/// (RMS of the horizontal vector difference, m/s, over fixes moving faster than 3 m/s)
/// before replay stops believing it.
pub const GPS_VELOCITY_CONSISTENCY_M_S: f64 = 3.0;

/// The GPS velocity check: the logged horizontal velocity against the central difference of
/// the fixes' positions.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GpsVelocityCheck {
    pub rms_difference_m_s: f64,
    pub fixes_compared: usize,
    /// The logged horizontal velocity was replaced by the position differences.
    pub replaced: bool,
}

/// Horizontal velocity (north, east, m/s) from the positions of the fixes before and after
/// fix `i` (a central difference: no lag), `None` at the ends, across gaps over 1 s, or
/// without 3-D fixes.
fn position_velocity(gps: &[GpsRecord], i: usize) -> Option<[f64; 2]> {
    let a = gps.get(i.checked_sub(1)?)?;
    let b = gps.get(i + 1)?;
    let dt = b.t_us.checked_sub(a.t_us)? as f64 * 1e-6;
    if !(a.fix_3d && b.fix_3d && (0.05..=1.0).contains(&dt)) {
        return None;
    }
    // Metres per degree on the sphere: plenty over the tens of metres between fixes.
    let r = 6_371_000.0 * std::f64::consts::PI / 180.0;
    let north = (b.latitude_deg - a.latitude_deg) * r;
    let east = (b.longitude_deg - a.longitude_deg) * r * a.latitude_deg.to_radians().cos();
    Some([north / dt, east / dt])
}

impl FlightLog {
    /// Checks the logged GPS velocity against the positions and, if they disagree beyond
    /// [`GPS_VELOCITY_CONSISTENCY_M_S`], replaces the horizontal velocity with the position
    /// differences (warning once). A receiver's velocity is normally far better than
    /// differenced positions; a log whose velocity contradicts its positions (a conversion
    /// or unit error) would otherwise pull the estimator's heading and tilt wherever the
    /// wrong velocity points.
    pub fn check_gps_velocity(&mut self) -> GpsVelocityCheck {
        let mut sum = 0.0;
        let mut n = 0usize;
        for i in 0..self.gps.len() {
            let (Some(r), Some(d)) = (self.gps.get(i), position_velocity(&self.gps, i)) else {
                continue;
            };
            if let [Some(vn), Some(ve), _] = r.velocity_ned_m_s {
                if vn.hypot(ve) > 3.0 {
                    sum += (vn - d[0]).powi(2) + (ve - d[1]).powi(2);
                    n += 1;
                }
            }
        }
        let rms = if n == 0 {
            f64::NAN
        } else {
            (sum / n as f64).sqrt()
        };
        let replaced = n >= 10 && rms > GPS_VELOCITY_CONSISTENCY_M_S;
        if replaced {
            let derived: Vec<_> = (0..self.gps.len())
                .map(|i| position_velocity(&self.gps, i))
                .collect();
            for (r, d) in self.gps.iter_mut().zip(derived) {
                r.velocity_ned_m_s[0] = d.map(|d| d[0]);
                r.velocity_ned_m_s[1] = d.map(|d| d[1]);
            }
            self.warnings.push(format!(
                "the GPS horizontal velocity disagrees with the GPS positions by {rms:.1} m/s \
                 RMS over {n} moving fixes: replaced by the central difference of the \
                 positions"
            ));
            self.gps_source
                .push_str("; horizontal velocity from position differences (see warnings)");
        }
        GpsVelocityCheck {
            rms_difference_m_s: rms,
            fixes_compared: n,
            replaced,
        }
    }
}

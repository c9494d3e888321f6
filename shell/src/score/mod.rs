//! `skyframe sim --score`: a simulated flight's estimates and control against the
//! simulator's ground truth, read back from the flight's own logs.
//!
//! ```text
//! truth.bin ─────┐
//! estimator.bin ─┼─▶ attitude / position / velocity errors (at each estimate's log TIME)
//! gps.bin ───────┤   the GPS's own error, the baseline the estimate must beat
//! control.bin ───┘   altitude and heading hold in AUTO
//! imu.bin + gps.bin ─▶ replay through the estimator, timed: its step time
//! imu.bin ─▶ python3 + ahrs (EKF, Madgwick) ─▶ their roll/pitch errors beside ours
//! ```
//!
//! Working from the logs (not from memory inside the run) means the score describes what a
//! researcher gets on disk, and any flight directory can be scored again.

mod course;
mod reference;
mod replay;
mod truth;

use crate::stats::ErrorStats;
use std::path::Path;

use serde::Serialize;
use skyframe_core::devices::gps::GpsFix;
use skyframe_core::estimation::geo::{GeoPoint, LocalFrame};
use skyframe_core::estimation::nalgebra::{UnitQuaternion, Vector3};
use skyframe_logtable::{Stream, Table, load_stream, problem_line};
use skyframe_sim::plant::GeodeticPosition;

use course::{BankLimit, CourseRow, TurnWindow};
pub use reference::ReferenceFilters;
pub use replay::StepTime;
use skyframe_core::angles::wrap_pi;
use truth::TruthSeries;

/// What scoring needs besides the flight directory.
pub struct ScoreSetup<'a> {
    pub flight_dir: &'a Path,
    /// The estimator task's budget in the schedule.
    pub estimator_budget_ns: u64,
    /// Run the `ahrs` package's filters on the same IMU data (needs python3 with ahrs).
    pub reference_filters: bool,
}

/// Roll and pitch errors of one filter (degrees).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct RollPitch {
    pub roll_rms_deg: f64,
    pub roll_max_deg: f64,
    pub pitch_rms_deg: f64,
    pub pitch_max_deg: f64,
    pub samples: u64,
}

impl RollPitch {
    fn from_stats(roll: &ErrorStats, pitch: &ErrorStats) -> Self {
        Self {
            roll_rms_deg: roll.rms().to_degrees(),
            roll_max_deg: roll.max_abs.to_degrees(),
            pitch_rms_deg: pitch.rms().to_degrees(),
            pitch_max_deg: pitch.max_abs.to_degrees(),
            samples: roll.n,
        }
    }
}

/// The stretch scored: from the estimator's first healthy estimate to the end of the log,
/// healthy estimates only.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Window {
    pub from_s: f64,
    pub to_s: f64,
    pub estimates: u64,
    /// Of those, with the airplane off the ground.
    pub airborne_estimates: u64,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct AttitudeScore {
    /// Euler-angle errors, over the estimates with the true pitch within ±60°: nearer the
    /// vertical (a loop) roll and yaw stop being separate angles and their errors mean
    /// nothing.
    pub roll_rms_deg: f64,
    pub roll_max_deg: f64,
    pub pitch_rms_deg: f64,
    pub pitch_max_deg: f64,
    pub yaw_rms_deg: f64,
    pub yaw_max_deg: f64,
    pub euler_estimates: u64,
    /// The angle of the rotation from the true attitude to the estimated one, over every
    /// scored estimate (no singularity).
    pub rotation_rms_deg: f64,
    pub rotation_max_deg: f64,
}

/// Beyond this true pitch, Euler-angle errors are not scored (see [`AttitudeScore`]).
pub const EULER_MAX_PITCH_RAD: f64 = 60.0 * std::f64::consts::PI / 180.0;

/// The 3-2-1 attitude as a rotation (body → NED).
fn attitude(roll: f64, pitch: f64, yaw: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(roll, pitch, yaw)
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct PositionScore {
    pub horizontal_rms_m: f64,
    pub horizontal_max_m: f64,
    pub vertical_rms_m: f64,
    pub vertical_max_m: f64,
    /// Of the 3-D velocity error.
    pub velocity_rms_m_s: f64,
    /// The baseline: the GPS fixes' own horizontal error against truth, each compared with
    /// truth `gps_lag_ms` earlier than it was logged (the lag that fits best, so this is the
    /// receiver's noise, not its latency).
    pub gps_horizontal_rms_m: f64,
    pub gps_vertical_rms_m: f64,
    pub gps_lag_ms: f64,
    pub gps_fixes: u64,
    /// Estimate horizontal RMS over GPS horizontal RMS (below 1: the filter beats the GPS).
    pub horizontal_ratio_to_gps: f64,
}

/// How the autopilot held its targets in AUTO.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ControlScore {
    /// Seconds flown in AUTO.
    pub auto_s: f64,
    /// True altitude against the commanded one while holding: from 10 s after AUTO engaged,
    /// in the altitude loop's hold zone, and from when the loop first came within 1 m of each
    /// new altitude command (climbs and descents to a new waypoint altitude are not holds).
    pub altitude_hold_rms_m: f64,
    pub altitude_hold_max_m: f64,
    pub altitude_hold_s: f64,
    /// Over the same samples, the loop's own error: the estimated altitude against the
    /// command. The difference to `altitude_hold_rms_m` is the estimator's (GPS's) altitude
    /// error, which no control loop can see.
    pub altitude_hold_loop_rms_m: f64,
    /// True course over ground against the commanded course (the autopilot holds course: no
    /// magnetometer), from 10 s after AUTO engaged, while the command has been steady (within
    /// 5° over 5 s) and once the turn to it is over: captured, or the time a turn at the bank
    /// limit takes passed (`score/course.rs`).
    pub heading_hold_rms_deg: f64,
    pub heading_hold_max_deg: f64,
    pub heading_hold_s: f64,
    /// The same errors over all of AUTO, turns and climbs included.
    pub altitude_error_auto_rms_m: f64,
    pub course_error_auto_rms_deg: f64,
}

/// One target of the issue, and whether this flight met it.
#[derive(Clone, Debug, Serialize)]
pub struct Target {
    pub name: &'static str,
    pub value: f64,
    pub limit: f64,
    pub met: bool,
}

#[derive(Debug, Serialize)]
pub struct Score {
    pub window: Window,
    pub attitude: AttitudeScore,
    pub position: PositionScore,
    pub control: ControlScore,
    pub estimator_step: StepTime,
    pub reference_filters: ReferenceFilters,
    pub targets: Vec<Target>,
    pub targets_met: bool,
    /// Damaged records met while reading the logs (each printed on stderr).
    pub log_problems: usize,
}

/// Seconds of a log TIME.
fn seconds(t_ns: i64) -> f64 {
    t_ns as f64 * 1e-9
}

struct Logs {
    truth: Stream,
    estimator: Stream,
    gps: Stream,
    control: Stream,
    imu: Stream,
}

impl Logs {
    fn load(dir: &Path) -> Result<Self, String> {
        let load = |name: &str| {
            let path = dir.join(format!("{name}.bin"));
            if !path.is_file() {
                return Err(format!("no {name}.bin (is this a simulated flight?)"));
            }
            load_stream(&path, |p| eprintln!("{}", problem_line(&path, p)))
        };
        Ok(Self {
            truth: load("truth")?,
            estimator: load("estimator")?,
            gps: load("gps")?,
            control: load("control")?,
            imu: load("imu")?,
        })
    }

    fn problems(&self) -> usize {
        [
            &self.truth,
            &self.estimator,
            &self.gps,
            &self.control,
            &self.imu,
        ]
        .iter()
        .map(|s| s.problems)
        .sum()
    }
}

/// Format 1 of `stream`, or why not.
fn table<'s>(stream: &'s Stream, what: &str) -> Result<&'s Table, String> {
    stream
        .table(1)
        .ok_or_else(|| format!("{}: no {what} records", stream.path.display()))
}

/// A named column, or why not.
fn column<'t>(table: &'t Table, stream: &str, name: &str) -> Result<&'t [f64], String> {
    table
        .column(name)
        .ok_or_else(|| format!("{stream}.bin has no column `{name}`"))
}

/// Scores the flight in `setup.flight_dir`.
pub fn score_flight(setup: &ScoreSetup<'_>) -> Result<Score, String> {
    let dir = setup.flight_dir.display();
    score_logs(setup).map_err(|e| format!("{dir}: {e}"))
}

fn score_logs(setup: &ScoreSetup<'_>) -> Result<Score, String> {
    let logs = Logs::load(setup.flight_dir)?;
    let truth = TruthSeries::from_table(table(&logs.truth, "truth")?)?;
    if truth.is_empty() {
        return Err("truth.bin holds no samples".into());
    }
    let truth_origin = truth_origin(&logs.truth)?;
    // gps.bin read once: the estimator's home, the GPS's own error and the replay use it.
    let fixes = replay::gps_fixes(table(&logs.gps, "GPS")?)?;
    let imu = table(&logs.imu, "IMU")?;
    let home = gps_home(&fixes)?;
    let frame = LocalFrame::new(home)
        .ok_or_else(|| format!("the first GPS fix is not a plausible home: {home:?}"))?;
    let estimator = table(&logs.estimator, "estimate")?;
    let (window, attitude, position_error) =
        score_estimates(estimator, &truth, &frame, &truth_origin)?;
    let position = score_gps(&fixes, &truth, &truth_origin, window, position_error);
    // Flights logged before the gains record carried the bank limit: the default.
    let bank_limit = logs
        .control
        .table(2)
        .and_then(|gains| {
            Some(BankLimit::new(
                &gains.times_ns,
                gains.column("max_bank_deg")?,
            ))
        })
        .unwrap_or_else(|| BankLimit::new(&[], &[]));
    let control = score_control(
        table(&logs.control, "control")?,
        &bank_limit,
        &truth,
        home.altitude_m,
        truth_origin.alt_msl_m,
    )?;
    let estimator_step = replay::time_estimator(imu, &fixes, setup.estimator_budget_ns)?;
    let reference_filters = if setup.reference_filters {
        reference::score(
            setup.flight_dir,
            imu,
            &truth,
            window,
            RollPitch {
                roll_rms_deg: attitude.roll_rms_deg,
                roll_max_deg: attitude.roll_max_deg,
                pitch_rms_deg: attitude.pitch_rms_deg,
                pitch_max_deg: attitude.pitch_max_deg,
                samples: attitude.euler_estimates,
            },
        )
    } else {
        ReferenceFilters::NotRun
    };
    let targets = vec![
        target("roll_rms_deg", attitude.roll_rms_deg, 0.5),
        target("pitch_rms_deg", attitude.pitch_rms_deg, 0.5),
        target("yaw_rms_deg", attitude.yaw_rms_deg, 2.0),
        target(
            "horizontal_rms_m below gps_horizontal_rms_m",
            position.horizontal_rms_m,
            position.gps_horizontal_rms_m,
        ),
        target("altitude_hold_rms_m", control.altitude_hold_rms_m, 3.0),
        target("heading_hold_rms_deg", control.heading_hold_rms_deg, 3.0),
        // "Far below its budget": a tenth of it on average.
        target(
            "estimator_step_mean_us below a tenth of the budget",
            estimator_step.mean_us,
            estimator_step.budget_us / 10.0,
        ),
    ];
    let targets_met = targets.iter().all(|t| t.met);
    Ok(Score {
        window,
        attitude,
        position,
        control,
        estimator_step,
        reference_filters,
        targets,
        targets_met,
        log_problems: logs.problems(),
    })
}

fn target(name: &'static str, value: f64, limit: f64) -> Target {
    Target {
        name,
        value,
        limit,
        // NaN (nothing measured) is not a target met.
        met: value <= limit,
    }
}

/// Where `truth.bin` positions are measured from (its format 2). Flights logged before the
/// origin was written all used the simulator's default home.
fn truth_origin(truth: &Stream) -> Result<GeodeticPosition, String> {
    let Some(origins) = truth.table(2) else {
        return Ok(GeodeticPosition::default());
    };
    let first = |name| column(origins, "truth", name).map(|c| c.first().copied());
    match (
        first("origin_lat_deg")?,
        first("origin_lon_deg")?,
        first("origin_alt_m")?,
    ) {
        (Some(lat_deg), Some(lon_deg), Some(alt_msl_m)) => Ok(GeodeticPosition {
            lat_deg,
            lon_deg,
            alt_msl_m,
        }),
        _ => Err("truth.bin has an empty origin record".into()),
    }
}

/// The estimator's home: the first valid GPS fix (`docs/log-streams.md`, estimator.bin).
fn gps_home(fixes: &[GpsFix]) -> Result<GeoPoint, String> {
    fixes
        .iter()
        .find_map(|f| {
            let p = GeoPoint {
                latitude_deg: f.latitude_deg?,
                longitude_deg: f.longitude_deg?,
                altitude_m: f.altitude_msl_m?,
            };
            (f.valid && p.is_plausible()).then_some(p)
        })
        .ok_or_else(|| "gps.bin has no valid fix: nothing to place the estimates".to_string())
}

/// An estimate's position in the simulator's frame: through geodetic coordinates, since the
/// estimator's origin (its first GPS fix) is not the simulator's.
fn to_truth_frame(frame: &LocalFrame, origin: &GeodeticPosition, ned: [f64; 3]) -> [f64; 3] {
    let p = frame.to_geodetic(&Vector3::new(ned[0], ned[1], ned[2]));
    origin.ned_to(&GeodeticPosition {
        lat_deg: p.latitude_deg,
        lon_deg: p.longitude_deg,
        alt_msl_m: p.altitude_m,
    })
}

/// Position and velocity error statistics of the estimates, for `score_gps` to complete.
struct PositionError {
    horizontal: ErrorStats,
    vertical: ErrorStats,
    velocity: ErrorStats,
}

fn score_estimates(
    est: &Table,
    truth: &TruthSeries,
    frame: &LocalFrame,
    origin: &GeodeticPosition,
) -> Result<(Window, AttitudeScore, PositionError), String> {
    let c = |name| column(est, "estimator", name);
    let (roll, pitch, yaw) = (c("roll_rad")?, c("pitch_rad")?, c("yaw_rad")?);
    let (vn, ve, vd) = (c("vn_m_s")?, c("ve_m_s")?, c("vd_m_s")?);
    let (pn, pe, pd) = (c("pn_m")?, c("pe_m")?, c("pd_m")?);
    let healthy = c("healthy")?;
    let first = healthy
        .iter()
        .position(|&h| h == 1.0)
        .ok_or("the estimator never became healthy: nothing to score")?;
    let mut stats = [ErrorStats::default(); 4];
    let mut pos = PositionError {
        horizontal: ErrorStats::default(),
        vertical: ErrorStats::default(),
        velocity: ErrorStats::default(),
    };
    let mut window = Window {
        from_s: est.times_ns.get(first).copied().map_or(f64::NAN, seconds),
        to_s: est.times_ns.last().copied().map_or(f64::NAN, seconds),
        estimates: 0,
        airborne_estimates: 0,
    };
    for (i, &t) in est.times_ns.iter().enumerate().skip(first) {
        let at = |col: &[f64]| col.get(i).copied().unwrap_or(f64::NAN);
        if at(healthy) != 1.0 {
            continue;
        }
        let Some(tr) = truth.at(t) else { continue };
        window.estimates += 1;
        window.airborne_estimates += u64::from(!tr.on_ground);
        let [r, p, y, rotation] = &mut stats;
        if tr.pitch_rad.abs() < EULER_MAX_PITCH_RAD {
            r.push(wrap_pi(at(roll) - tr.roll_rad));
            p.push(wrap_pi(at(pitch) - tr.pitch_rad));
            y.push(wrap_pi(at(yaw) - tr.yaw_rad));
        }
        let estimated = attitude(at(roll), at(pitch), at(yaw));
        rotation.push(estimated.angle_to(&attitude(tr.roll_rad, tr.pitch_rad, tr.yaw_rad)));
        let ned = to_truth_frame(frame, origin, [at(pn), at(pe), at(pd)]);
        pos.horizontal
            .push((ned[0] - tr.ned_m[0]).hypot(ned[1] - tr.ned_m[1]));
        pos.vertical.push(ned[2] - tr.ned_m[2]);
        let dv = [
            at(vn) - tr.vel_ned_mps[0],
            at(ve) - tr.vel_ned_mps[1],
            at(vd) - tr.vel_ned_mps[2],
        ];
        pos.velocity
            .push((dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]).sqrt());
    }
    let [r, p, y, rotation] = stats;
    Ok((
        window,
        AttitudeScore {
            roll_rms_deg: r.rms().to_degrees(),
            roll_max_deg: r.max_abs.to_degrees(),
            pitch_rms_deg: p.rms().to_degrees(),
            pitch_max_deg: p.max_abs.to_degrees(),
            yaw_rms_deg: y.rms().to_degrees(),
            yaw_max_deg: y.max_abs.to_degrees(),
            euler_estimates: r.n,
            rotation_rms_deg: rotation.rms().to_degrees(),
            rotation_max_deg: rotation.max_abs.to_degrees(),
        },
        pos,
    ))
}

/// The GPS's own error over the window, at the lag that fits it best (0–500 ms).
fn score_gps(
    fixes: &[GpsFix],
    truth: &TruthSeries,
    origin: &GeodeticPosition,
    window: Window,
    est: PositionError,
) -> PositionScore {
    let in_window = |t: i64| seconds(t) >= window.from_s && seconds(t) <= window.to_s;
    let fixes: Vec<(i64, [f64; 3])> = fixes
        .iter()
        .filter_map(|f| {
            let t = i64::try_from(f.received_ns).ok()?;
            let p = GeodeticPosition {
                lat_deg: f.latitude_deg?,
                lon_deg: f.longitude_deg.unwrap_or(f64::NAN),
                alt_msl_m: f.altitude_msl_m.unwrap_or(f64::NAN),
            };
            (f.valid && in_window(t)).then(|| (t, origin.ned_to(&p)))
        })
        .collect();
    let errors_at = |lag_ns: i64| {
        let (mut h, mut v) = (ErrorStats::default(), ErrorStats::default());
        for (t, ned) in &fixes {
            if let Some(tr) = truth.at(t - lag_ns) {
                h.push((ned[0] - tr.ned_m[0]).hypot(ned[1] - tr.ned_m[1]));
                v.push(ned[2] - tr.ned_m[2]);
            }
        }
        (h, v)
    };
    let (lag_ns, (h, v)) = (0..=50)
        .map(|k| k * 10_000_000)
        .map(|lag| (lag, errors_at(lag)))
        .min_by(|a, b| a.1.0.rms().total_cmp(&b.1.0.rms()))
        .unwrap_or((0, errors_at(0)));
    PositionScore {
        horizontal_rms_m: est.horizontal.rms(),
        horizontal_max_m: est.horizontal.max_abs,
        vertical_rms_m: est.vertical.rms(),
        vertical_max_m: est.vertical.max_abs,
        velocity_rms_m_s: est.velocity.rms(),
        gps_horizontal_rms_m: h.rms(),
        gps_vertical_rms_m: v.rms(),
        gps_lag_ms: lag_ns as f64 * 1e-6,
        gps_fixes: h.n,
        horizontal_ratio_to_gps: est.horizontal.rms() / h.rms(),
    }
}

/// Altitude and course hold in AUTO (`control.bin` format 1, 50 Hz).
fn score_control(
    control: &Table,
    bank_limit: &BankLimit,
    truth: &TruthSeries,
    home_alt_msl_m: f64,
    origin_alt_msl_m: f64,
) -> Result<ControlScore, String> {
    const AUTO: f64 = 2.0;
    const ZONE_HOLD: f64 = 0.0;
    const SETTLE_NS: i64 = 10_000_000_000;
    const CAPTURE_M: f64 = 1.0;
    let c = |name| column(control, "control", name);
    let (mode, zone) = (c("mode")?, c("zone")?);
    let (alt_c, course_c) = (c("alt_c_m")?, c("course_c_rad")?);
    let (alt_est, course_est) = (c("alt_m")?, c("course_rad")?);
    let times = &control.times_ns;
    let mut auto_since: Option<i64> = None;
    let mut last_t: Option<i64> = None;
    let mut auto_ns = 0i64;
    let (mut alt_hold, mut alt_all) = (ErrorStats::default(), ErrorStats::default());
    let mut alt_hold_loop = ErrorStats::default();
    let (mut last_alt_c, mut captured) = (f64::NAN, false);
    let (mut course_hold, mut course_all) = (ErrorStats::default(), ErrorStats::default());
    let mut turn = TurnWindow::new();
    for (i, &t) in times.iter().enumerate() {
        let at = |col: &[f64]| col.get(i).copied().unwrap_or(f64::NAN);
        let in_auto = at(mode) == AUTO;
        if in_auto {
            auto_ns += last_t.filter(|_| auto_since.is_some()).map_or(0, |l| t - l);
        }
        auto_since = match (in_auto, auto_since) {
            (true, None) => {
                turn = TurnWindow::new();
                Some(t)
            }
            (true, since) => since,
            (false, _) => None,
        };
        last_t = Some(t);
        let (Some(since), Some(tr)) = (auto_since, truth.at(t)) else {
            continue;
        };
        let settled = t - since >= SETTLE_NS;
        // Altitudes as MSL: the command is above the estimator's home, truth below the
        // simulator's origin.
        let alt_err = (origin_alt_msl_m - tr.ned_m[2]) - (home_alt_msl_m + at(alt_c));
        alt_all.push(alt_err);
        // Holding starts once the loop has captured a new altitude command (its own error
        // within CAPTURE_M); the way there is a climb or descent, not a hold.
        if (at(alt_c) - last_alt_c).abs() > 0.5 || t == since {
            captured = false;
        }
        last_alt_c = at(alt_c);
        captured |= (at(alt_est) - at(alt_c)).abs() < CAPTURE_M;
        if settled && captured && at(zone) == ZONE_HOLD {
            alt_hold.push(alt_err);
            alt_hold_loop.push(at(alt_est) - at(alt_c));
        }
        let [vn, ve, _] = tr.vel_ned_mps;
        let row = CourseRow {
            t_ns: t,
            command_rad: at(course_c),
            estimated_rad: at(course_est),
            true_rad: ve.atan2(vn),
            ground_speed_mps: vn.hypot(ve),
            bank_limit_rad: bank_limit.at(t),
        };
        let course_err = wrap_pi(row.true_rad - row.command_rad);
        course_all.push(course_err);
        // Evaluated on every row: the turn state follows each command change.
        let turn_over = turn.turn_over(&row);
        if settled && turn_over && course::steady(times, course_c, i, since) {
            course_hold.push(course_err);
        }
    }
    // 50 Hz rows: each stands for 20 ms.
    let seconds_of = |s: &ErrorStats| s.n as f64 * 0.02;
    Ok(ControlScore {
        auto_s: seconds(auto_ns),
        altitude_hold_rms_m: alt_hold.rms(),
        altitude_hold_max_m: alt_hold.max_abs,
        altitude_hold_s: seconds_of(&alt_hold),
        altitude_hold_loop_rms_m: alt_hold_loop.rms(),
        heading_hold_rms_deg: course_hold.rms().to_degrees(),
        heading_hold_max_deg: course_hold.max_abs.to_degrees(),
        heading_hold_s: seconds_of(&course_hold),
        altitude_error_auto_rms_m: alt_all.rms(),
        course_error_auto_rms_deg: course_all.rms().to_degrees(),
    })
}

/// The score for people: one line per figure, each target with ok/MISSED.
pub fn render_score(s: &Score) -> String {
    let mut out = format!(
        "score against ground truth, {:.1}-{:.1} s ({} healthy estimates, {} airborne)\n",
        s.window.from_s, s.window.to_s, s.window.estimates, s.window.airborne_estimates
    );
    let a = &s.attitude;
    out += &format!(
        "  attitude error  roll {:.2} deg RMS ({:.2} max), pitch {:.2} ({:.2}), yaw {:.2} ({:.2}) with |pitch| < 60 deg; rotation {:.2} deg RMS ({:.2} max) throughout\n",
        a.roll_rms_deg,
        a.roll_max_deg,
        a.pitch_rms_deg,
        a.pitch_max_deg,
        a.yaw_rms_deg,
        a.yaw_max_deg,
        a.rotation_rms_deg,
        a.rotation_max_deg
    );
    let p = &s.position;
    out += &format!(
        "  position error  horizontal {:.2} m RMS vs GPS {:.2} m (x{:.2}), vertical {:.2} m vs GPS {:.2} m; velocity {:.3} m/s RMS\n",
        p.horizontal_rms_m,
        p.gps_horizontal_rms_m,
        p.horizontal_ratio_to_gps,
        p.vertical_rms_m,
        p.gps_vertical_rms_m,
        p.velocity_rms_m_s
    );
    let c = &s.control;
    out += &format!(
        "  auto ({:.0} s)   altitude hold {:.2} m RMS over {:.0} s, heading hold {:.2} deg RMS over {:.0} s\n",
        c.auto_s,
        c.altitude_hold_rms_m,
        c.altitude_hold_s,
        c.heading_hold_rms_deg,
        c.heading_hold_s
    );
    let e = &s.estimator_step;
    out += &format!(
        "  estimator step  {:.1} us mean, {:.1} us p99, {:.1} us max of a {:.0} us budget ({} build, replayed)\n",
        e.mean_us, e.p99_us, e.max_us, e.budget_us, e.build
    );
    out += &reference::render(&s.reference_filters);
    for t in &s.targets {
        out += &format!(
            "  {} {}: {:.3} (limit {:.3})\n",
            if t.met { "ok    " } else { "MISSED" },
            t.name,
            t.value,
            t.limit
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A table of `columns` with one row per entry of `rows`, 20 ms apart.
    fn table(columns: &[&str], rows: &[Vec<f64>]) -> Table {
        Table {
            index: 1,
            format_text: String::new(),
            columns: columns.iter().map(|c| c.to_string()).collect(),
            times_ns: (0..rows.len() as i64).map(|i| i * 20_000_000).collect(),
            sessions: vec![1; rows.len()],
            values: (0..columns.len())
                .map(|c| {
                    rows.iter()
                        .map(|r| r.get(c).copied().unwrap_or(0.0))
                        .collect()
                })
                .collect(),
        }
    }

    const TRUTH: [&str; 19] = [
        "north_m",
        "east_m",
        "down_m",
        "vn_m_s",
        "ve_m_s",
        "vd_m_s",
        "roll_rad",
        "pitch_rad",
        "yaw_rad",
        "p_rad_s",
        "q_rad_s",
        "r_rad_s",
        "airspeed_m_s",
        "alpha_rad",
        "beta_rad",
        "wind_n_m_s",
        "wind_e_m_s",
        "wind_d_m_s",
        "on_ground",
    ];
    const ESTIMATE: [&str; 10] = [
        "roll_rad",
        "pitch_rad",
        "yaw_rad",
        "vn_m_s",
        "ve_m_s",
        "vd_m_s",
        "pn_m",
        "pe_m",
        "pd_m",
        "healthy",
    ];

    /// Truth and estimate through the top of a loop: the same rotation, written with other
    /// Euler angles near the vertical, plus a 0.2° pitch error everywhere.
    fn loop_flight() -> (TruthSeries, Table) {
        let mut truth = Vec::new();
        let mut est = Vec::new();
        for k in 0..100 {
            let pitch = (40.0 + 0.5 * f64::from(k)).min(89.6).to_radians();
            truth.push(vec![
                0.0, 0.0, -100.0, 20.0, 0.0, 0.0, 0.0, pitch, 0.0, 0.0, 0.0, 0.0, 20.0, 0.0, 0.0,
                0.0, 0.0, 0.0, 0.0,
            ]);
            // Near the vertical (pitch 89.6°), roll 30° and yaw 30° are almost the truth's
            // 0/0: only their difference matters there.
            let (roll, yaw) = if pitch > 89.0f64.to_radians() {
                (30f64.to_radians(), 30f64.to_radians())
            } else {
                (0.0, 0.0)
            };
            est.push(vec![
                roll,
                pitch + 0.2f64.to_radians(),
                yaw,
                20.0,
                0.0,
                0.0,
                0.0,
                0.0,
                -100.0,
                1.0,
            ]);
        }
        let truth = TruthSeries::from_table(&table(&TRUTH, &truth)).expect("truth");
        (truth, table(&ESTIMATE, &est))
    }

    #[test]
    fn euler_errors_skip_the_vertical_and_the_rotation_error_covers_it() {
        let (truth, est) = loop_flight();
        let origin = GeodeticPosition::default();
        let frame = LocalFrame::new(GeoPoint {
            latitude_deg: origin.lat_deg,
            longitude_deg: origin.lon_deg,
            altitude_m: origin.alt_msl_m,
        })
        .expect("home");
        let (window, a, pos) = score_estimates(&est, &truth, &frame, &origin).expect("scores");
        assert_eq!(window.estimates, 100);
        // Pitch 40°..60° in 0.5° steps: 40 estimates have Euler errors scored.
        assert_eq!(a.euler_estimates, 40);
        assert!((a.pitch_rms_deg - 0.2).abs() < 1e-6, "{a:?}");
        assert!(a.roll_max_deg < 1e-9 && a.yaw_max_deg < 1e-9, "{a:?}");
        // The 30°/30° Euler pairs at 89.6° are a small rotation from the truth, not 30°.
        assert!(a.rotation_max_deg < 1.0, "{a:?}");
        assert!(a.rotation_rms_deg > 0.19, "{a:?}");
        // Same place, same velocity.
        assert!(pos.horizontal.max_abs < 1e-6 && pos.velocity.max_abs < 1e-6);
    }

    const CONTROL: [&str; 6] = [
        "mode",
        "zone",
        "alt_c_m",
        "alt_m",
        "course_c_rad",
        "course_rad",
    ];

    /// 70 s of AUTO at 20 m/s and 100 m, the course command and the flown course (degrees,
    /// the estimate equal to the truth) as functions of time (s); default bank limit (30°,
    /// so a turn at the limit runs at g·tan 30° / 20 m/s = 16.2°/s).
    fn fly_course(
        command_deg: impl Fn(f64) -> f64,
        course_deg: impl Fn(f64) -> f64,
    ) -> ControlScore {
        let rows = 3500;
        let mut control = Vec::new();
        let mut truth = Vec::new();
        for k in 0..rows {
            let t = k as f64 * 0.02;
            let course = course_deg(t).to_radians();
            control.push(vec![
                2.0,
                0.0,
                100.0,
                100.0,
                command_deg(t).to_radians(),
                course,
            ]);
            let mut row = vec![0.0; TRUTH.len()];
            row[2] = -100.0;
            row[3] = 20.0 * course.cos();
            row[4] = 20.0 * course.sin();
            row[12] = 20.0;
            truth.push(row);
        }
        let truth = TruthSeries::from_table(&table(&TRUTH, &truth)).expect("truth");
        score_control(
            &table(&CONTROL, &control),
            &BankLimit::new(&[], &[]),
            &truth,
            0.0,
            0.0,
        )
        .expect("scores")
    }

    /// A new command at 30 s: north to east.
    fn east_from_30_s(t: f64) -> f64 {
        if t < 30.0 { 0.0 } else { 90.0 }
    }

    #[test]
    fn a_roll_out_that_overshoots_is_hold_error() {
        // Turning at 18°/s to 100° (10° past the command, reached at 35.6 s), back at 1°/s.
        let peak_s = 30.0 + 100.0 / 18.0;
        let c = fly_course(east_from_30_s, |t| {
            if t < 30.0 {
                0.0
            } else if t < peak_s {
                18.0 * (t - 30.0)
            } else {
                (100.0 - (t - peak_s)).max(90.0)
            }
        });
        // Captured (within 5°) at 34.7 s, the command steady from 35 s: held 10-30 s and
        // 35-70 s, and the 10° overshoot is in it.
        assert!((c.heading_hold_max_deg - 10.0).abs() < 0.05, "{c:?}");
        assert!((c.heading_hold_s - 55.0).abs() < 0.05, "{c:?}");
    }

    #[test]
    fn an_airplane_that_never_captures_is_held_from_when_it_could_have_turned() {
        // 10°/s to 80°, then a standing 10° error: never within 5°.
        let c = fly_course(east_from_30_s, |t| (10.0 * (t - 30.0)).clamp(0.0, 80.0));
        // A 90° turn at 30° of bank and 20 m/s, plus 2 s to roll in and out; the first 50 Hz
        // row from then on is the first held.
        let turn_s = 90f64.to_radians() / (9.80665 * 30f64.to_radians().tan() / 20.0) + 2.0;
        let first_held_s = ((30.0 + turn_s) / 0.02).ceil() * 0.02;
        assert!((first_held_s - 37.56).abs() < 1e-9);
        let error_then = 90.0 - 10.0 * (first_held_s - 30.0);
        assert!((c.heading_hold_max_deg - error_then).abs() < 1e-3, "{c:?}");
        assert!(
            (c.heading_hold_s - (20.0 + 70.0 - first_held_s)).abs() < 0.01,
            "{c:?}"
        );
    }

    #[test]
    fn a_command_that_swings_away_and_back_is_not_a_hold() {
        // The command at 150° for 1 s (a loiter entry's swing); the airplane starts after it
        // and is 20° off from 33 s to 35 s.
        let c = fly_course(
            |t| {
                if (30.0..31.0).contains(&t) {
                    150.0
                } else {
                    0.0
                }
            },
            |t| if (33.0..35.0).contains(&t) { 20.0 } else { 0.0 },
        );
        // Steady again 5 s after the swing: held 10-30 s and 36-70 s, none of the 20°.
        assert!(c.heading_hold_max_deg < 1e-6, "{c:?}");
        assert!((c.heading_hold_s - 54.0).abs() < 0.05, "{c:?}");
    }

    #[test]
    fn a_target_not_measured_is_not_met() {
        assert!(!target("x", f64::NAN, 1.0).met);
        assert!(target("x", 1.0, 1.0).met);
        assert!(!target("x", 1.01, 1.0).met);
    }

    #[test]
    fn a_directory_without_the_logs_says_which_is_missing() {
        let dir = std::env::temp_dir().join(format!("skyframe-score-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let e = score_flight(&ScoreSetup {
            flight_dir: &dir,
            estimator_budget_ns: 1,
            reference_filters: false,
        })
        .expect_err("no logs");
        assert!(e.contains("no truth.bin"), "{e}");
        assert!(e.starts_with(&dir.display().to_string()), "{e}");
        let _ = std::fs::remove_dir(&dir);
    }
}

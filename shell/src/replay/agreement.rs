//! Our estimate against the onboard estimate of the same flight, by flight phase.
//!
//! The onboard estimator is another filter, not the truth: these are **agreement** figures.
//! Where both are right they agree; where they disagree, either may be wrong.
//!
//! Phases come from the log's GPS alone (neither estimator decides them), each fix's phase
//! held until the next fix:
//! - `ground`: ground speed below 4 m/s (before launch, after landing, or carried);
//! - `turn`: the course over ground turning faster than 8°/s (over ±1 fix);
//! - `climb` / `descent`: vertical speed beyond ±1.5 m/s;
//! - `cruise`: the rest.

use crate::stats::ErrorStats;
use std::collections::BTreeMap;

use serde::Serialize;
use skyframe_core::estimation::Phase;
use skyframe_core::estimation::geo::{GeoPoint, LocalFrame};
use skyframe_core::estimation::nalgebra::{Quaternion, UnitQuaternion, Vector3};

use super::flightlog::FlightLog;
use super::run::{EstimateRow, RunResult, onboard_attitude_at};

pub const PHASES: [&str; 5] = ["ground", "climb", "cruise", "turn", "descent"];
const GROUND_SPEED_M_S: f64 = 4.0;
const TURN_RATE_RAD_S: f64 = 8.0 * std::f64::consts::PI / 180.0;
const CLIMB_M_S: f64 = 1.5;
/// Beyond this onboard pitch, Euler roll and yaw stop being separate angles: not scored
/// (the rotation angle still is).
const EULER_MAX_PITCH_RAD: f64 = 60.0 * std::f64::consts::PI / 180.0;

/// RMS and largest difference; NaN (JSON null) with no samples.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Difference {
    pub rms: f64,
    pub max: f64,
    pub samples: u64,
}

impl From<ErrorStats> for Difference {
    fn from(s: ErrorStats) -> Self {
        Self {
            rms: s.rms(),
            max: if s.n == 0 { f64::NAN } else { s.max_abs },
            samples: s.n,
        }
    }
}

#[derive(Clone, Copy, Debug, Default)]
struct Accumulator {
    seconds: f64,
    roll: ErrorStats,
    pitch: ErrorStats,
    yaw: ErrorStats,
    rotation: ErrorStats,
    horizontal: ErrorStats,
    vertical: ErrorStats,
    velocity: ErrorStats,
    gps_horizontal: ErrorStats,
    gps_vertical: ErrorStats,
}

/// The agreement over one phase (or the whole run). Angles in degrees, positions in metres,
/// velocities in m/s.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PhaseAgreement {
    pub seconds: f64,
    pub roll_deg: Difference,
    pub pitch_deg: Difference,
    pub yaw_deg: Difference,
    /// The angle of the whole rotation between the two attitudes.
    pub rotation_deg: Difference,
    pub horizontal_position_m: Difference,
    pub vertical_position_m: Difference,
    /// Of the 3-D velocity difference.
    pub velocity_m_s: Difference,
    /// Our position against the GPS fixes themselves (at each fix's log time, so it
    /// includes the receiver's latency): the baseline where the log has no onboard
    /// position.
    pub gps_horizontal_m: Difference,
    pub gps_vertical_m: Difference,
}

impl From<Accumulator> for PhaseAgreement {
    fn from(a: Accumulator) -> Self {
        Self {
            seconds: a.seconds,
            roll_deg: a.roll.into(),
            pitch_deg: a.pitch.into(),
            yaw_deg: a.yaw.into(),
            rotation_deg: a.rotation.into(),
            horizontal_position_m: a.horizontal.into(),
            vertical_position_m: a.vertical.into(),
            velocity_m_s: a.velocity.into(),
            gps_horizontal_m: a.gps_horizontal.into(),
            gps_vertical_m: a.gps_vertical.into(),
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct Agreement {
    /// From our estimator's start (its yaw known) to the end of the log.
    pub all: PhaseAgreement,
    pub phases: BTreeMap<&'static str, PhaseAgreement>,
}

/// Per-sample differences kept for the figures (seconds from the first IMU record).
#[derive(Clone, Debug, Default)]
pub struct Series {
    pub t_s: Vec<f64>,
    /// Ours and onboard, degrees: roll, pitch, yaw.
    pub ours_deg: Vec<[f64; 3]>,
    pub onboard_deg: Vec<[f64; 3]>,
    pub phase: Vec<&'static str>,
    /// Every published estimate: (seconds, estimate).
    pub estimates: Vec<(f64, skyframe_core::estimation::Estimate)>,
}

/// The flight phase of each GPS fix (see the module doc).
pub fn gps_phases(log: &FlightLog) -> Vec<(u64, &'static str)> {
    let g = &log.gps;
    let course = |k: usize| {
        g.get(k).and_then(|r| match r.velocity_ned_m_s {
            [Some(n), Some(e), _] if n.hypot(e) >= GROUND_SPEED_M_S => Some(e.atan2(n)),
            _ => None,
        })
    };
    (0..g.len())
        .filter_map(|i| {
            let r = g.get(i)?;
            let speed = match r.velocity_ned_m_s {
                [Some(n), Some(e), _] => n.hypot(e),
                _ => return Some((r.t_us, "ground")),
            };
            if speed < GROUND_SPEED_M_S || !r.fix_3d {
                return Some((r.t_us, "ground"));
            }
            let (a, b) = (i.saturating_sub(1), (i + 1).min(g.len() - 1));
            let turn = match (course(a), course(b), g.get(a), g.get(b)) {
                (Some(ca), Some(cb), Some(ra), Some(rb)) if rb.t_us > ra.t_us => {
                    let d = wrap(cb - ca);
                    (d / ((rb.t_us - ra.t_us) as f64 * 1e-6)).abs() > TURN_RATE_RAD_S
                }
                _ => false,
            };
            let climb = r.velocity_ned_m_s[2].map(|vd| -vd);
            Some((
                r.t_us,
                if turn {
                    "turn"
                } else if climb.is_some_and(|c| c > CLIMB_M_S) {
                    "climb"
                } else if climb.is_some_and(|c| c < -CLIMB_M_S) {
                    "descent"
                } else {
                    "cruise"
                },
            ))
        })
        .collect()
}

pub use skyframe_core::angles::wrap_pi as wrap;

fn phase_at(phases: &[(u64, &'static str)], t_us: u64) -> &'static str {
    let i = phases.partition_point(|p| p.0 <= t_us);
    i.checked_sub(1)
        .and_then(|k| phases.get(k))
        .map_or("ground", |p| p.1)
}

/// Our estimate at `t_us`, interpolated between the 10 ms estimates around it; `None`
/// before our estimator runs (yaw known) or across a gap.
struct Ours {
    attitude: UnitQuaternion<f64>,
    position: Vector3<f64>,
    velocity: Vector3<f64>,
}

fn ours_at(rows: &[EstimateRow], t_us: u64) -> Option<Ours> {
    let i = rows.partition_point(|r| r.t_us < t_us);
    let b = rows.get(i)?;
    let a = rows.get(i.checked_sub(1)?)?;
    if b.t_us.saturating_sub(a.t_us) > 50_000
        || a.estimate.health.phase != Phase::Running
        || b.estimate.health.phase != Phase::Running
    {
        return None;
    }
    let f = (t_us.saturating_sub(a.t_us)) as f64 / (b.t_us.saturating_sub(a.t_us)).max(1) as f64;
    let q = |r: &EstimateRow| {
        let [w, x, y, z] = r.estimate.quaternion.map(f64::from);
        Quaternion::new(w, x, y, z)
    };
    let (qa, qb) = (q(a), q(b));
    let qb = if qa.dot(&qb) < 0.0 { -qb } else { qb };
    let qm = qa * (1.0 - f) + qb * f;
    if qm.norm().partial_cmp(&1e-6) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let v3 = |x: [f32; 3]| Vector3::new(f64::from(x[0]), f64::from(x[1]), f64::from(x[2]));
    let lerp = |x: [f32; 3], y: [f32; 3]| v3(x) * (1.0 - f) + v3(y) * f;
    Some(Ours {
        attitude: UnitQuaternion::from_quaternion(qm),
        position: lerp(a.estimate.position_ned_m, b.estimate.position_ned_m),
        velocity: lerp(a.estimate.velocity_ned_mps, b.estimate.velocity_ned_mps),
    })
}

fn euler_deg(q: &UnitQuaternion<f64>) -> [f64; 3] {
    let (r, p, y) = q.euler_angles();
    [r.to_degrees(), p.to_degrees(), y.to_degrees()]
}

pub fn compare(log: &FlightLog, run: &RunResult) -> (Agreement, Series) {
    let phases = gps_phases(log);
    let mut all = Accumulator::default();
    let mut by_phase: BTreeMap<&'static str, Accumulator> = BTreeMap::new();
    let mut series = Series::default();
    let seconds = |t_us: u64| t_us.saturating_sub(run.t0_us) as f64 * 1e-6;

    series.estimates = run
        .rows
        .iter()
        .map(|r| (seconds(r.t_us), r.estimate))
        .collect();
    // Time per phase, over our running estimates (10 ms each).
    for r in &run.rows {
        if r.estimate.health.phase == Phase::Running {
            let dt = 0.01;
            all.seconds += dt;
            by_phase
                .entry(phase_at(&phases, r.t_us))
                .or_default()
                .seconds += dt;
        }
    }

    for a in &log.onboard_attitude {
        let Some(ours) = ours_at(&run.rows, a.t_us) else {
            continue;
        };
        let Some(onboard) = onboard_attitude_at(log, a.t_us) else {
            continue;
        };
        let phase = phase_at(&phases, a.t_us);
        let o = euler_deg(&onboard);
        let m = euler_deg(&ours.attitude);
        let rotation = onboard.angle_to(&ours.attitude).to_degrees();
        let acc = by_phase.entry(phase).or_default();
        for acc in [&mut all, acc] {
            acc.rotation.push(rotation);
            if o[1].to_radians().abs() <= EULER_MAX_PITCH_RAD {
                acc.roll.push(wrap((m[0] - o[0]).to_radians()).to_degrees());
                acc.pitch.push(m[1] - o[1]);
                acc.yaw.push(wrap((m[2] - o[2]).to_radians()).to_degrees());
            }
        }
        series.t_s.push(seconds(a.t_us));
        series.ours_deg.push(m);
        series.onboard_deg.push(o);
        series.phase.push(phase);
    }

    if let Some(frame) = run.frame.as_ref() {
        let ned = |g: [f64; 3], frame: &LocalFrame| {
            frame.to_ned(&GeoPoint {
                latitude_deg: g[0],
                longitude_deg: g[1],
                altitude_m: g[2],
            })
        };
        for n in &log.onboard_nav {
            let Some(ours) = ours_at(&run.rows, n.t_us) else {
                continue;
            };
            let phase = phase_at(&phases, n.t_us);
            let acc = by_phase.entry(phase).or_default();
            for acc in [&mut all, &mut *acc] {
                if let Some(g) = n.geodetic {
                    let d = ours.position - ned(g, frame);
                    acc.horizontal.push(d.x.hypot(d.y));
                    acc.vertical.push(d.z);
                }
                if let Some(v) = n.velocity_ned_m_s {
                    acc.velocity
                        .push((ours.velocity - Vector3::new(v[0], v[1], v[2])).norm());
                }
            }
        }
        for g in log.gps.iter().filter(|g| g.fix_3d) {
            let Some(ours) = ours_at(&run.rows, g.t_us) else {
                continue;
            };
            let d = ours.position - ned([g.latitude_deg, g.longitude_deg, g.altitude_m], frame);
            let phase = phase_at(&phases, g.t_us);
            let acc = by_phase.entry(phase).or_default();
            for acc in [&mut all, &mut *acc] {
                acc.gps_horizontal.push(d.x.hypot(d.y));
                acc.gps_vertical.push(d.z);
            }
        }
    }
    let phases = by_phase
        .into_iter()
        .map(|(k, v)| (k, PhaseAgreement::from(v)))
        .collect();
    (
        Agreement {
            all: all.into(),
            phases,
        },
        series,
    )
}

/// An arbiter for yaw that neither estimator uses: the wind triangle. With the airspeed
/// sensor, ground velocity = k · airspeed · (cos ψ, sin ψ) + wind, for a heading ψ, an
/// airspeed scale k and a wind constant over the flight; fitted by least squares over the
/// airborne GPS fixes, the heading that leaves the smaller residual is the more consistent
/// one (sideslip and a changing wind add to both alike).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct WindTriangleFit {
    pub airspeed_scale: f64,
    pub wind_north_m_s: f64,
    pub wind_east_m_s: f64,
    /// RMS of the ground-velocity residual (per component).
    pub residual_rms_m_s: f64,
    /// The heading against the direction of (ground velocity − wind): RMS, degrees.
    pub heading_vs_air_track_rms_deg: f64,
    pub fixes: usize,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct HeadingCheck {
    pub ours: WindTriangleFit,
    pub onboard: Option<WindTriangleFit>,
}

fn airspeed_at(log: &FlightLog, t_us: u64) -> Option<f64> {
    let a = &log.airspeed;
    let i = a.partition_point(|s| s.0 < t_us);
    [i.checked_sub(1), Some(i)]
        .into_iter()
        .flatten()
        .filter_map(|k| a.get(k))
        .filter(|s| s.0.abs_diff(t_us) <= 200_000)
        .min_by_key(|s| s.0.abs_diff(t_us))
        .map(|s| s.1)
}

fn fit(samples: &[(f64, f64, f64, f64)]) -> Option<WindTriangleFit> {
    // Unknowns x = (k, Wn, We); rows: vn = k·va·cosψ + Wn, ve = k·va·sinψ + We.
    let mut ata = [[0f64; 3]; 3];
    let mut atb = [0f64; 3];
    let mut rows = Vec::with_capacity(samples.len() * 2);
    for &(vn, ve, va, yaw) in samples {
        rows.push(([va * yaw.cos(), 1.0, 0.0], vn));
        rows.push(([va * yaw.sin(), 0.0, 1.0], ve));
    }
    for (a, b) in &rows {
        for i in 0..3 {
            for j in 0..3 {
                ata[i][j] += a[i] * a[j];
            }
            atb[i] += a[i] * b;
        }
    }
    let m = skyframe_core::estimation::nalgebra::Matrix3::from_fn(|i, j| ata[i][j]);
    let x = m.lu().solve(&Vector3::new(atb[0], atb[1], atb[2]))?;
    if samples.len() < 10 || !x.iter().all(|v| v.is_finite()) {
        return None;
    }
    let residual = (rows
        .iter()
        .map(|(a, b)| (a[0] * x[0] + a[1] * x[1] + a[2] * x[2] - b).powi(2))
        .sum::<f64>()
        / rows.len() as f64)
        .sqrt();
    let heading = (samples
        .iter()
        .map(|&(vn, ve, _, yaw)| wrap((ve - x[2]).atan2(vn - x[1]) - yaw).powi(2))
        .sum::<f64>()
        / samples.len() as f64)
        .sqrt()
        .to_degrees();
    Some(WindTriangleFit {
        airspeed_scale: x[0],
        wind_north_m_s: x[1],
        wind_east_m_s: x[2],
        residual_rms_m_s: residual,
        heading_vs_air_track_rms_deg: heading,
        fixes: samples.len(),
    })
}

/// The wind-triangle fit of our heading and of the onboard one, over the same fixes (those
/// moving faster than 5 m/s with airspeed, our estimate running and an onboard attitude);
/// `None` without airspeed or with too few such fixes.
pub fn heading_check(log: &FlightLog, run: &RunResult) -> Option<HeadingCheck> {
    let mut ours = Vec::new();
    let mut onboard = Vec::new();
    for g in log.gps.iter().filter(|g| g.fix_3d) {
        let [Some(vn), Some(ve), _] = g.velocity_ned_m_s else {
            continue;
        };
        if vn.hypot(ve) < 5.0 {
            continue;
        }
        let (Some(va), Some(m)) = (airspeed_at(log, g.t_us), ours_at(&run.rows, g.t_us)) else {
            continue;
        };
        let Some(o) = onboard_attitude_at(log, g.t_us) else {
            continue;
        };
        ours.push((vn, ve, va, m.attitude.euler_angles().2));
        onboard.push((vn, ve, va, o.euler_angles().2));
    }
    Some(HeadingCheck {
        ours: fit(&ours)?,
        onboard: fit(&onboard),
    })
}

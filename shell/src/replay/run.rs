//! The log through the airplane's own frame table: the real [`Executive`] steps the shipped
//! [`SHIPPED`] table in virtual time; the `estimator` slot is the airplane's
//! [`EstimatorTask`]; the `imu` and `gps` slots are replaced by tasks that publish what the
//! log recorded, when the airplane's tasks would have published it; every other task idles
//! (none of them feeds the estimator).
//!
//! - **IMU**: each 10 ms release publishes one sample, the mean rate and specific force over
//!   the last whole 10 ms of the log: every log record's angle and velocity increment is
//!   split over the frames its interval overlaps (exact for a record that is a mean over its
//!   interval, as PX4's `sensor_combined` and ArduPilot's `IMT` are; coning and sculling
//!   within 10 ms are lost, as they are on the airplane's 100 Hz IMU). The window that ends
//!   at log time `t` is published at `t + 10 ms`: a record is only known once it has
//!   ended. A window less than half covered (a logging dropout) publishes nothing, and the
//!   estimator counts the missed frame as it would a silent IMU.
//! - **GPS**: a fix is there for the GPS task from its log time (+10 ms, the same shift), and
//!   the task publishes it at its next release (100 ms period, offset 10 ms), stamped with
//!   that release's time, as the airplane's GPS task stamps a fix when it drains it. The
//!   estimator then dates the measurement `gps_latency_ns` earlier (its configuration).

use skyframe_core::comm::{LatestSlot, Sink};
use skyframe_core::devices::gps::GpsFix;
use skyframe_core::devices::imu::{ImuMeasurement, ImuSample};
use skyframe_core::estimation::ekf::{EkfCounters, NominalState};
use skyframe_core::estimation::geo::LocalFrame;
use skyframe_core::estimation::nalgebra::{Quaternion, UnitQuaternion, Vector3};
use skyframe_core::estimation::{Estimate, EstimatorConfig, Phase};
use skyframe_core::executive::{Executive, FrameRecord, Task, TaskContext, TaskFault};
use skyframe_core::logfmt::NoLog;
use skyframe_core::schedule::SHIPPED;
use skyframe_core::tasks::estimator::EstimatorTask;
use skyframe_sim::VirtualClock;

use super::flightlog::{FlightLog, GpsRecord, ImuRecord};

/// The IMU task's period in the shipped table (µs); replay refuses a table where it differs.
const FRAME_US: u64 = 10_000;
/// The delivery shift: log time `t` is executive time `t − t0 + SHIFT_US`.
const SHIFT_US: u64 = FRAME_US;
/// The GPS course speed the estimator takes its heading from (its default configuration):
/// also when replay's warm start happens, if the alignment has not finished by then.
const LAUNCH_SPEED_M_S: f64 = 5.0;

/// The longest log replay runs: a day, so a damaged time stamp is an error, not a run of
/// billions of empty frames.
const MAX_SPAN_US: u64 = 24 * 3600 * 1_000_000;

/// How the estimator starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StartMode {
    /// The estimator's own static alignment; if the log never rests long enough for it (a
    /// hand launch, a log cut in flight), a warm start from the onboard attitude at the
    /// first GPS speed of 5 m/s.
    Auto,
    /// The estimator's own alignment only (it may never start).
    Align,
    /// Always the warm start from the onboard attitude at the first GPS speed of 5 m/s.
    Onboard,
}

#[derive(Clone, Copy, Debug)]
pub struct RunOptions {
    pub start: StartMode,
    /// Overrides the estimator's GPS latency (its configuration's value otherwise).
    pub gps_latency_ms: Option<f64>,
    /// Overrides the estimator's GPS velocity 1-σ (set by replay when the velocity is
    /// differenced positions).
    pub gps_velocity_sd_m_s: Option<f64>,
}

/// One published estimate, at the log time its IMU window ended.
#[derive(Clone, Copy, Debug)]
pub struct EstimateRow {
    pub t_us: u64,
    pub estimate: Estimate,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct StartInfo {
    /// `alignment` (the estimator's own static one), `in-motion` (the estimator's own start
    /// at the first GPS course, having never rested long enough) or `onboard-attitude`
    /// (replay's warm start).
    pub how: &'static str,
    /// Log time of the start, seconds from the first IMU record.
    pub at_s: f64,
    pub why: String,
}

/// Something the estimator did that replay counts: a whole-filter reset or a reset to the
/// GPS, with its log time.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Event {
    pub at_s: f64,
    pub what: &'static str,
}

pub struct RunResult {
    pub t0_us: u64,
    pub rows: Vec<EstimateRow>,
    pub frame: Option<LocalFrame>,
    pub counters: EkfCounters,
    pub alignment_restarts: u32,
    pub imu_frames: u64,
    pub imu_frames_empty: u64,
    pub gps_fixes_published: u64,
    pub start: Option<StartInfo>,
    pub events: Vec<Event>,
    pub gps_latency_ms: f64,
    pub non_finite_estimates: u64,
}

/// Discards the executive's frame records (replay runs in virtual time: timing is not what
/// it measures).
struct Discard;

impl Sink<FrameRecord> for Discard {
    fn try_send(&mut self, _item: FrameRecord) -> Result<(), FrameRecord> {
        Ok(())
    }
}

struct Idle;

impl Task for Idle {
    fn init(&mut self, _cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        Ok(())
    }
    fn step(&mut self, _cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        Ok(())
    }
}

struct ReplayImu<'a> {
    imu: &'a [ImuRecord],
    t0_us: u64,
    next: usize,
    out: &'a LatestSlot<ImuSample>,
    published: u64,
    empty: u64,
}

impl Task for ReplayImu<'_> {
    fn init(&mut self, _cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        Ok(())
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let now_us = cx.now_ns / 1000;
        let Some(end) = (self.t0_us + now_us).checked_sub(SHIFT_US) else {
            return Ok(());
        };
        let Some(start) = end.checked_sub(FRAME_US) else {
            return Ok(());
        };
        // Records wholly before the window are done.
        while self.imu.get(self.next).is_some_and(|r| r.t_us <= start) {
            self.next += 1;
        }
        let (mut angle, mut velocity, mut covered_us) = ([0f64; 3], [0f64; 3], 0f64);
        for r in self.imu.iter().skip(self.next) {
            let r_end = r.t_us as f64;
            let r_start = r_end - r.dt_s * 1e6;
            if r_start >= end as f64 {
                break;
            }
            let overlap = r_end.min(end as f64) - r_start.max(start as f64);
            if overlap <= 0.0 {
                continue;
            }
            let share = overlap / (r.dt_s * 1e6);
            for k in 0..3 {
                angle[k] += r.delta_angle_rad[k] * share;
                velocity[k] += r.delta_velocity_m_s[k] * share;
            }
            covered_us += overlap;
        }
        if covered_us < 0.5 * FRAME_US as f64 {
            self.empty += 1;
            return Ok(());
        }
        let seconds = covered_us * 1e-6;
        self.out.publish(ImuSample {
            // The frame count: the estimator task measures a gap in frames by it.
            counter: (cx.frame & 0xff) as u8,
            received_ns: cx.now_ns,
            measurement: ImuMeasurement {
                rate_radps: angle.map(|a| (a / seconds) as f32),
                specific_force_mps2: velocity.map(|v| (v / seconds) as f32),
                ..ImuMeasurement::default()
            },
        });
        self.published += 1;
        Ok(())
    }
}

struct ReplayGps<'a> {
    gps: &'a [GpsRecord],
    t0_us: u64,
    next: usize,
    out: &'a LatestSlot<GpsFix>,
    published: u64,
}

fn fix_of(r: &GpsRecord, received_ns: u64) -> GpsFix {
    let [vn, ve, vd] = r.velocity_ned_m_s;
    let (course, speed) = match (vn, ve) {
        (Some(n), Some(e)) => (Some(e.atan2(n) as f32), Some(n.hypot(e) as f32)),
        _ => (None, None),
    };
    let h = r.horizontal_accuracy_m.map(|v| v as f32);
    GpsFix {
        received_ns,
        valid: r.fix_3d,
        latitude_deg: Some(r.latitude_deg),
        longitude_deg: Some(r.longitude_deg),
        altitude_msl_m: Some(r.altitude_m),
        velocity_ned_mps: [vn, ve, vd].map(|v| v.map(|x| x as f32)),
        course_rad: course,
        ground_speed_mps: speed,
        hdop: r.hdop.map(|v| v as f32),
        satellites: r.satellites,
        position_sd_m: [h, h, r.vertical_accuracy_m.map(|v| v as f32)],
        ..GpsFix::default()
    }
}

impl Task for ReplayGps<'_> {
    fn init(&mut self, _cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        Ok(())
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let now_us = cx.now_ns / 1000;
        while let Some(r) = self.gps.get(self.next) {
            if r.t_us.saturating_sub(self.t0_us) + SHIFT_US > now_us {
                break;
            }
            self.next += 1;
            // Fixes from before the first IMU record are older than the run.
            if r.t_us >= self.t0_us {
                self.out.publish(fix_of(r, cx.now_ns));
                self.published += 1;
            }
        }
        Ok(())
    }
}

/// The airplane's estimator task, with replay's warm start in front of its step.
struct Estimator<'a> {
    task: EstimatorTask<'a, NoLog>,
    warm_start: Option<(u64, NominalState)>,
    started: Option<StartInfo>,
}

impl Task for Estimator<'_> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        self.task.init(cx)
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        if let Some((at_ns, state)) = self.warm_start {
            if cx.now_ns >= at_ns {
                self.warm_start = None;
                let estimator = self.task.estimator_mut();
                if estimator.phase() == Phase::Aligning {
                    let yaw_sd = f64::from(estimator.config().heading_sd_rad);
                    estimator.start_from(cx.now_ns, state, yaw_sd);
                    self.started = Some(StartInfo {
                        how: "onboard-attitude",
                        at_s: (cx.now_ns / 1000).saturating_sub(SHIFT_US) as f64 * 1e-6,
                        why: "the estimator had not aligned (it needs 10 s at rest) by launch \
                              (the first GPS speed of 5 m/s; with --start onboard on a log \
                              that never moves, the first fix): warm start from the onboard \
                              attitude and the GPS velocity, zero biases"
                            .into(),
                    });
                }
            }
        }
        self.task.step(cx)
    }
}

/// The onboard attitude at `t_us`, interpolated (normalised linear) between its records.
pub fn onboard_attitude_at(log: &FlightLog, t_us: u64) -> Option<UnitQuaternion<f64>> {
    let att = &log.onboard_attitude;
    let i = att.partition_point(|a| a.t_us < t_us);
    let q = |k: usize| {
        att.get(k).map(|a| {
            let [w, x, y, z] = a.quaternion;
            Quaternion::new(w, x, y, z)
        })
    };
    let (before, after) = (i.checked_sub(1).and_then(&q), q(i));
    let chosen = match (
        before,
        after,
        i.checked_sub(1).and_then(|k| att.get(k)),
        att.get(i),
    ) {
        (Some(a), Some(b), Some(ra), Some(rb)) => {
            if rb.t_us.saturating_sub(ra.t_us) > 500_000 {
                return None;
            }
            let span = rb.t_us.saturating_sub(ra.t_us).max(1) as f64;
            let f = t_us.saturating_sub(ra.t_us) as f64 / span;
            let b = if a.dot(&b) < 0.0 { -b } else { b };
            a * (1.0 - f) + b * f
        }
        (None, Some(b), _, Some(rb)) if rb.t_us.abs_diff(t_us) < 100_000 => b,
        (Some(a), None, Some(ra), _) if ra.t_us.abs_diff(t_us) < 100_000 => a,
        _ => return None,
    };
    (chosen.norm() > 1e-6 && chosen.coords.iter().all(|c| c.is_finite()))
        .then(|| UnitQuaternion::from_quaternion(chosen))
}

/// Replays `log` through the shipped frame table.
pub fn run(log: &FlightLog, options: RunOptions) -> Result<RunResult, String> {
    let table = &SHIPPED;
    let imu_slot_ok = table
        .task_index("imu")
        .and_then(|i| table.tasks.get(i))
        .is_some_and(|t| t.period_ns == FRAME_US * 1000 && table.minor_frame_ns == FRAME_US * 1000);
    if !imu_slot_ok || table.task_index("estimator").is_none() {
        return Err(
            "the shipped frame table has no 10 ms imu and estimator tasks: replay \
                    assumes the airplane's 10 ms IMU frame"
                .into(),
        );
    }
    let (Some(first), Some(last)) = (log.imu.first(), log.imu.last()) else {
        return Err("the log has no IMU records replay can use".into());
    };
    let t0_us = first.t_us.saturating_sub((first.dt_s * 1e6) as u64);
    if last.t_us.saturating_sub(t0_us) > MAX_SPAN_US {
        return Err(format!(
            "the IMU records span {:.1} h: a damaged time stamp? (replay takes at most 24 h)",
            last.t_us.saturating_sub(t0_us) as f64 / 3.6e9
        ));
    }
    let frames = (last.t_us.saturating_sub(t0_us) + SHIFT_US) / FRAME_US + 1;

    let mut config = EstimatorConfig::default();
    if let Some(ms) = options.gps_latency_ms {
        config.gps_latency_ns = (ms.max(0.0) * 1e6) as u64;
    }
    let gps_latency_ms = config.gps_latency_ns as f64 * 1e-6;
    if let Some(sd) = options.gps_velocity_sd_m_s {
        config.gps_default_vel_sd_mps = sd as f32;
    }
    if options.start == StartMode::Onboard {
        // The alignment must not finish first on a log that rests: it never does.
        config.alignment.samples = u32::MAX;
    }

    // The warm start: at the first fix at launch speed, from the onboard attitude then.
    let launch = log
        .gps
        .iter()
        .find(|g| {
            g.fix_3d
                && matches!(g.velocity_ned_m_s, [Some(n), Some(e), _] if n.hypot(e) >= LAUNCH_SPEED_M_S)
                && g.t_us >= t0_us
        })
        .or_else(|| {
            // Asked for a warm start on a log that never moves (a ground test): the first
            // fix will do, as the heading then comes from the onboard attitude anyway.
            (options.start == StartMode::Onboard)
                .then(|| log.gps.iter().find(|g| g.fix_3d && g.t_us >= t0_us))
                .flatten()
        });
    let warm_start = match (options.start, launch) {
        (StartMode::Align, _) | (_, None) => None,
        (StartMode::Auto | StartMode::Onboard, Some(g)) => {
            onboard_attitude_at(log, g.t_us).map(|attitude| {
                let [vn, ve, vd] = g.velocity_ned_m_s;
                let mut x = NominalState::at_rest(attitude);
                x.velocity_ned_mps =
                    Vector3::new(vn.unwrap_or(0.0), ve.unwrap_or(0.0), vd.unwrap_or(0.0));
                let at_ns = (g.t_us - t0_us + SHIFT_US) * 1000;
                (at_ns, x)
            })
        }
    };

    let imu_slot = LatestSlot::<ImuSample>::new();
    let gps_slot = LatestSlot::<GpsFix>::new();
    let out = LatestSlot::<Estimate>::new();
    let mut imu_task = ReplayImu {
        imu: &log.imu,
        t0_us,
        next: 0,
        out: &imu_slot,
        published: 0,
        empty: 0,
    };
    let mut gps_task = ReplayGps {
        gps: &log.gps,
        t0_us,
        next: 0,
        out: &gps_slot,
        published: 0,
    };
    let mut estimator = Estimator {
        task: EstimatorTask::new(config, NoLog, &imu_slot, &gps_slot, None, &out),
        warm_start,
        started: None,
    };
    let mut idles: Vec<Idle> = table.tasks.iter().map(|_| Idle).collect();

    let clock = VirtualClock::new();
    let mut executive = Executive::new(table, &clock);
    let mut rows = Vec::with_capacity(usize::try_from(frames).unwrap_or(0));
    let mut events = Vec::new();
    let mut last_counters = EkfCounters::default();
    let mut non_finite = 0u64;
    let mut last_t = None;
    // When the estimator started by itself, and whether its static alignment had finished.
    let mut alignment_started: Option<(f64, bool)> = None;
    {
        let mut tasks: Vec<&mut dyn Task> = Vec::with_capacity(table.tasks.len());
        let mut imu_ref = Some(&mut imu_task as &mut dyn Task);
        let mut gps_ref = Some(&mut gps_task as &mut dyn Task);
        let mut est_ref = Some(&mut estimator as &mut dyn Task);
        for (slot, idle) in table.tasks.iter().zip(idles.iter_mut()) {
            let task = match slot.name {
                "imu" => imu_ref.take(),
                "gps" => gps_ref.take(),
                "estimator" => est_ref.take(),
                _ => None,
            };
            tasks.push(task.unwrap_or(idle));
        }
        if gps_ref.is_some() {
            return Err("the shipped frame table has no gps task".into());
        }
        executive
            .start(&mut tasks, 0)
            .map_err(|e| format!("the executive refused to start: {e:?}"))?;
        for _ in 0..frames {
            use skyframe_core::executive::FrameTimer;
            clock.sleep_until(executive.next_release_ns());
            executive.run_frame(&mut tasks, &mut Discard);
            let Some(e) = out.peek() else { continue };
            if last_t == Some(e.t_ns) {
                continue;
            }
            last_t = Some(e.t_ns);
            let Some(t_us) = (t0_us + e.t_ns / 1000).checked_sub(SHIFT_US) else {
                continue;
            };
            let at_s = t_us.saturating_sub(t0_us) as f64 * 1e-6;
            if e.health.phase != Phase::Aligning && alignment_started.is_none() {
                alignment_started = Some((at_s, e.health.alignment_percent >= 100));
            }
            let c = e.health.counters;
            if c.resets > last_counters.resets {
                events.push(Event {
                    at_s,
                    what: "filter reset (non-finite or diverged)",
                });
            }
            if c.gps_resets > last_counters.gps_resets {
                events.push(Event {
                    at_s,
                    what: "reset to GPS after rejections",
                });
            }
            last_counters = c;
            let finite = e.quaternion.iter().all(|v| v.is_finite())
                && e.velocity_ned_mps.iter().all(|v| v.is_finite())
                && e.position_ned_m.iter().all(|v| v.is_finite());
            if !finite {
                non_finite += 1;
            }
            rows.push(EstimateRow { t_us, estimate: e });
        }
    }
    let start = estimator.started.clone().or_else(|| {
        alignment_started.map(|(at_s, aligned)| {
            if aligned {
                StartInfo {
                    how: "alignment",
                    at_s,
                    why: "the estimator's own static alignment (10 s at rest)".into(),
                }
            } else {
                StartInfo {
                    how: "in-motion",
                    at_s,
                    why: "the estimator's own start in motion: it never rested 10 s, so at \
                          the first GPS course at 5 m/s it levelled on the specific force \
                          less the GPS acceleration"
                        .into(),
                }
            }
        })
    });
    Ok(RunResult {
        t0_us,
        rows,
        frame: estimator.task.estimator().local_frame().copied(),
        counters: last_counters,
        alignment_restarts: out.peek().map_or(0, |e| e.health.alignment_restarts),
        imu_frames: imu_task.published,
        imu_frames_empty: imu_task.empty,
        gps_fixes_published: gps_task.published,
        start,
        events,
        gps_latency_ms,
        non_finite_estimates: non_finite,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use skyframe_core::executive::HealthBoard;

    /// Each published 10 ms sample is the mean of the log's rate over exactly that window:
    /// checked against a brute-force integration of the same piecewise-constant rate at 1 µs
    /// steps, with records at the irregular intervals of the Zurich flight's IMU.
    #[test]
    fn frames_publish_the_exact_mean_over_their_window() {
        let intervals_us = [
            7353u64, 8211, 6300, 5911, 7178, 7400, 6890, 7702, 6523, 7010,
        ];
        let rate_of = |k: usize| [0.1 * k as f64, -0.05 * k as f64, 0.3];
        let force_of = |k: usize| [1.0 + k as f64, 0.0, -9.8];
        let mut t = 1_000_000u64;
        let mut imu = Vec::new();
        for k in 0..60 {
            let dt = intervals_us[k % intervals_us.len()];
            t += dt;
            let s = dt as f64 * 1e-6;
            imu.push(ImuRecord {
                t_us: t,
                dt_s: s,
                delta_angle_rad: rate_of(k).map(|w| w * s),
                delta_velocity_m_s: force_of(k).map(|f| f * s),
            });
        }
        let t0_us = imu[0].t_us - intervals_us[0];
        // The rate in force at log time `u` (µs), brute force.
        let at = |u: u64| {
            imu.iter()
                .position(|r| u > r.t_us - (r.dt_s * 1e6).round() as u64 && u <= r.t_us)
                .map(|k| (rate_of(k), force_of(k)))
        };
        let slot = LatestSlot::<ImuSample>::new();
        let mut task = ReplayImu {
            imu: &imu,
            t0_us,
            next: 0,
            out: &slot,
            published: 0,
            empty: 0,
        };
        let health = HealthBoard::new(1);
        let mut reader = slot.reader();
        let mut checked = 0;
        for frame in 2..40u64 {
            let mut cx = TaskContext {
                now_ns: frame * FRAME_US * 1000,
                frame,
                task: 0,
                health: &health,
                log_time_origin_ns: 0,
            };
            task.step(&mut cx).expect("steps");
            let Some(sample) = reader.take_fresh() else {
                continue;
            };
            let end = t0_us + frame * FRAME_US - SHIFT_US;
            let (mut w, mut f, mut n) = ([0f64; 3], [0f64; 3], 0f64);
            for u in (end - FRAME_US + 1)..=end {
                if let Some((wr, fr)) = at(u) {
                    for i in 0..3 {
                        w[i] += wr[i];
                        f[i] += fr[i];
                    }
                    n += 1.0;
                }
            }
            for i in 0..3 {
                let m = sample.measurement;
                assert!(
                    (f64::from(m.rate_radps[i]) - w[i] / n).abs() < 1e-5,
                    "frame {frame}"
                );
                assert!(
                    (f64::from(m.specific_force_mps2[i]) - f[i] / n).abs() < 1e-4,
                    "frame {frame}"
                );
            }
            assert_eq!(sample.counter, frame as u8);
            checked += 1;
        }
        assert!(checked >= 30, "{checked} frames checked");
    }
}

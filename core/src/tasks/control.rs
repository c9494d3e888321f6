//! The control task: each step decides who flies ([`decide`]), computes the commands of the
//! active mode and publishes them for the servo task, with `ready` set only when the
//! computer computed them (stabilise, auto). Logs inputs, targets and outputs every step and
//! the gains whenever they change (`docs/log-streams.md`, `control.bin`).
//!
//! - Manual: the pilot's sticks are passed through (the board does that itself anyway).
//! - Stabilise: the pilot's aileron/elevator sticks command roll/pitch angles (full stick =
//!   `control.stab_roll_deg` / `control.stab_pitch_deg`); throttle and rudder are the
//!   pilot's.
//! - Auto: the mission's waypoints, then a loiter around the last; without a mission, hold
//!   the course and altitude the airplane had when auto began at `control.cruise_mps`.
//!
//! Gains are parameters (`control.*`, [`define_params`]) read each step from the table the
//! telemetry task shares through a `RefCell`: `try_borrow`, and if the table is busy the
//! step keeps the gains it had.

use super::servo::PilotInput;
use super::task_log::TaskLog;
use crate::angles::wrap_pi_f32;
use crate::comm::{LatestSlot, SlotReader};
use crate::control::autopilot::{Autopilot, AutopilotGains, Targets};
use crate::control::controls::ComputerCommand;
use crate::control::controls::Controls;
use crate::control::mission::{Mission, MissionProgress};
use crate::control::mission_store::MissionStore;
use crate::control::mode::FlightMode;
use crate::control::mode::{ModeDecision, ModeInputs, decide};
use crate::control::pid::PidGains;
use crate::estimation::Estimate;
use crate::executive::{Task, TaskContext, TaskFault};
use crate::link::messages::Value;
use crate::link::params::{DefineError, ParamTable};
use crate::logfmt::RecordSink;
use core::cell::RefCell;

crate::log_record! {
    /// Each control step: the mode and why, the estimate it used, the pilot's sticks, the
    /// targets and the commands (format 1).
    pub struct ControlLog {
        mode: u8 = "%hhu",
        reason: u8 = "%hhu",
        roll_rad: f32 = "%.4f",
        pitch_rad: f32 = "%.4f",
        course_rad: f32 = "%.4f",
        alt_m: f32 = "%.2f",
        speed_m_s: f32 = "%.2f",
        stick_aileron: f32 = "%.3f",
        stick_elevator: f32 = "%.3f",
        stick_throttle: f32 = "%.3f",
        stick_rudder: f32 = "%.3f",
        roll_c_rad: f32 = "%.4f",
        pitch_c_rad: f32 = "%.4f",
        course_c_rad: f32 = "%.4f",
        alt_c_m: f32 = "%.2f",
        speed_c_m_s: f32 = "%.2f",
        zone: u8 = "%hhu",
        waypoint: u8 = "%hhu",
        aileron: f32 = "%.3f",
        elevator: f32 = "%.3f",
        throttle: f32 = "%.3f",
        rudder: f32 = "%.3f",
        ready: bool = "%hhu",
        wind_n_m_s: f32 = "%.2f",
        wind_e_m_s: f32 = "%.2f",
    }
}
crate::log_record! {
    /// The parameters in force, whenever they change (format 2); the columns are the
    /// `control.*` parameters' names, in `param_specs` order.
    pub struct ControlGainsLog {
        roll_kp: f32 = "%.4f",
        roll_ki: f32 = "%.4f",
        roll_kd: f32 = "%.4f",
        pitch_kp: f32 = "%.4f",
        pitch_ki: f32 = "%.4f",
        pitch_kd: f32 = "%.4f",
        course_kp: f32 = "%.4f",
        course_ki: f32 = "%.4f",
        alt_kp: f32 = "%.4f",
        alt_ki: f32 = "%.4f",
        alt_kd: f32 = "%.4f",
        speed_kp: f32 = "%.4f",
        speed_ki: f32 = "%.4f",
        speed_pitch_kp: f32 = "%.4f",
        speed_pitch_ki: f32 = "%.4f",
        yaw_damper: f32 = "%.4f",
        trim_elevator: f32 = "%.4f",
        trim_throttle: f32 = "%.4f",
        max_bank_deg: f32 = "%.2f",
        max_pitch_deg: f32 = "%.2f",
        stab_roll_deg: f32 = "%.2f",
        stab_pitch_deg: f32 = "%.2f",
        cruise_m_s: f32 = "%.2f",
    }
}
pub const CONTROL_INDEX: u8 = 1;
pub const GAINS_INDEX: u8 = 2;

/// An estimate older than this (from its IMU time) is treated as unhealthy.
pub const ESTIMATE_TIMEOUT_NS: u64 = 100_000_000;
/// A pilot report older than this: the board is silent, the pilot is assumed in control.
pub const PILOT_TIMEOUT_NS: u64 = 200_000_000;

/// Everything the parameters set.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControlSettings {
    pub gains: AutopilotGains,
    pub stab_roll_rad: f32,
    pub stab_pitch_rad: f32,
    pub cruise_mps: f32,
}

impl Default for ControlSettings {
    fn default() -> Self {
        Self {
            gains: AutopilotGains::default(),
            stab_roll_rad: 30f32.to_radians(),
            stab_pitch_rad: 15f32.to_radians(),
            cruise_mps: 25.0,
        }
    }
}

/// (name, default, min, max) of each `control.*` parameter, in the gains log's order.
fn param_specs(s: &ControlSettings) -> [(&'static str, f32, f32, f32); 23] {
    let g = &s.gains;
    [
        ("control.roll_kp", g.roll.kp, 0.0, 10.0),
        ("control.roll_ki", g.roll.ki, 0.0, 5.0),
        ("control.roll_kd", g.roll.kd, 0.0, 5.0),
        ("control.pitch_kp", g.pitch.kp, 0.0, 10.0),
        ("control.pitch_ki", g.pitch.ki, 0.0, 5.0),
        ("control.pitch_kd", g.pitch.kd, 0.0, 5.0),
        ("control.course_kp", g.course.kp, 0.0, 10.0),
        ("control.course_ki", g.course.ki, 0.0, 2.0),
        ("control.alt_kp", g.altitude.kp, 0.0, 1.0),
        ("control.alt_ki", g.altitude.ki, 0.0, 0.5),
        ("control.alt_kd", g.altitude.kd, 0.0, 1.0),
        ("control.speed_kp", g.airspeed_throttle.kp, 0.0, 2.0),
        ("control.speed_ki", g.airspeed_throttle.ki, 0.0, 1.0),
        ("control.speed_pitch_kp", g.airspeed_pitch.kp, -1.0, 0.0),
        ("control.speed_pitch_ki", g.airspeed_pitch.ki, -0.5, 0.0),
        ("control.yaw_damper", g.yaw_damper, 0.0, 5.0),
        ("control.trim_elevator", g.trim_elevator, -1.0, 1.0),
        ("control.trim_throttle", g.trim_throttle, 0.0, 1.0),
        (
            "control.max_bank_deg",
            g.course.out_max.to_degrees(),
            5.0,
            60.0,
        ),
        (
            "control.max_pitch_deg",
            g.max_pitch_rad.to_degrees(),
            2.0,
            30.0,
        ),
        (
            "control.stab_roll_deg",
            s.stab_roll_rad.to_degrees(),
            5.0,
            60.0,
        ),
        (
            "control.stab_pitch_deg",
            s.stab_pitch_rad.to_degrees(),
            2.0,
            30.0,
        ),
        ("control.cruise_mps", s.cruise_mps, 12.0, 40.0),
    ]
}

/// Adds the `control.*` parameters, with `defaults`' values, to `table`.
pub fn define_params(
    table: &mut ParamTable,
    defaults: &ControlSettings,
) -> Result<(), DefineError> {
    for (name, value, min, max) in param_specs(defaults) {
        table.define(name, Value::F32(value), Value::F32(min), Value::F32(max))?;
    }
    Ok(())
}

/// The settings in `table` (a parameter missing or of another type keeps `base`'s value).
pub fn settings_from(table: &ParamTable, base: &ControlSettings) -> ControlSettings {
    let mut v = param_specs(base).map(|(_, default, _, _)| default);
    for ((name, _, _, _), slot) in param_specs(base).iter().zip(v.iter_mut()) {
        if let Some(Value::F32(x)) = table.get(name).map(|p| p.value()) {
            *slot = x;
        }
    }
    let [
        roll_kp,
        roll_ki,
        roll_kd,
        pitch_kp,
        pitch_ki,
        pitch_kd,
        course_kp,
        course_ki,
        alt_kp,
        alt_ki,
        alt_kd,
        speed_kp,
        speed_ki,
        speed_pitch_kp,
        speed_pitch_ki,
        yaw_damper,
        trim_elevator,
        trim_throttle,
        max_bank_deg,
        max_pitch_deg,
        stab_roll_deg,
        stab_pitch_deg,
        cruise_mps,
    ] = v;
    let b = &base.gains;
    let bank = max_bank_deg.to_radians();
    let pitch = max_pitch_deg.to_radians();
    let with = |g: PidGains, kp, ki, kd| PidGains { kp, ki, kd, ..g };
    ControlSettings {
        gains: AutopilotGains {
            roll: with(b.roll, roll_kp, roll_ki, roll_kd),
            pitch: with(b.pitch, pitch_kp, pitch_ki, pitch_kd),
            course: PidGains {
                out_min: -bank,
                out_max: bank,
                ..with(b.course, course_kp, course_ki, b.course.kd)
            },
            altitude: PidGains {
                out_min: -pitch,
                out_max: pitch,
                ..with(b.altitude, alt_kp, alt_ki, alt_kd)
            },
            airspeed_throttle: with(b.airspeed_throttle, speed_kp, speed_ki, 0.0),
            airspeed_pitch: PidGains {
                out_min: -pitch,
                out_max: pitch,
                ..with(b.airspeed_pitch, speed_pitch_kp, speed_pitch_ki, 0.0)
            },
            yaw_damper,
            trim_elevator,
            trim_throttle,
            max_pitch_rad: pitch,
            ..*b
        },
        stab_roll_rad: stab_roll_deg.to_radians(),
        stab_pitch_rad: stab_pitch_deg.to_radians(),
        cruise_mps,
    }
}

/// What one step computed, for the log and the link.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControlStep {
    pub decision: ModeDecision,
    pub sticks: Controls,
    pub targets: Targets,
    pub command: ComputerCommand,
    pub waypoint: u8,
}

pub struct ControlTask<'a, S: RecordSink> {
    base: ControlSettings,
    settings: ControlSettings,
    autopilot: Autopilot,
    /// The mission flown (a copy of the store's, taken when its generation moves on).
    mission: Option<Mission>,
    progress: MissionProgress,
    /// Where a mission taken in flight comes from, and the generation last taken.
    store: Option<&'a RefCell<MissionStore>>,
    generation: Option<u32>,
    hold: Option<(f32, f32)>,
    log: TaskLog<S>,
    estimate: SlotReader<'a, Estimate>,
    pilot: SlotReader<'a, PilotInput>,
    requested: SlotReader<'a, FlightMode>,
    params: &'a RefCell<ParamTable>,
    out: &'a LatestSlot<ComputerCommand>,
    last_mode: FlightMode,
    /// Where the mode flown is published for the link (`None`: nobody asks).
    mode_out: Option<&'a LatestSlot<FlightMode>>,
    last_ns: Option<u64>,
    gains_logged: bool,
    last: Option<ControlStep>,
}

impl<'a, S: RecordSink> ControlTask<'a, S> {
    /// `defaults` are what a parameter missing from the table falls back to.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        defaults: ControlSettings,
        log: S,
        estimate: &'a LatestSlot<Estimate>,
        pilot: &'a LatestSlot<PilotInput>,
        requested: &'a LatestSlot<FlightMode>,
        mission: Option<&'a Mission>,
        params: &'a RefCell<ParamTable>,
        out: &'a LatestSlot<ComputerCommand>,
    ) -> Self {
        Self {
            base: defaults,
            settings: defaults,
            autopilot: Autopilot::new(defaults.gains),
            mission: mission.filter(|m| !m.waypoints.is_empty()).cloned(),
            progress: MissionProgress::default(),
            store: None,
            generation: None,
            hold: None,
            log: TaskLog::new(log),
            estimate: estimate.reader(),
            pilot: pilot.reader(),
            requested: requested.reader(),
            params,
            out,
            last_mode: FlightMode::Manual,
            mode_out: None,
            last_ns: None,
            gains_logged: false,
            last: None,
        }
    }

    /// Publishes the mode flown at every step into `slot` (the link reports it).
    pub fn publishing_mode(mut self, slot: &'a LatestSlot<FlightMode>) -> Self {
        self.mode_out = Some(slot);
        self
    }

    /// Flies the mission in `store`, and each one put in force there in flight (from the
    /// waypoint it says), in place of the mission given to [`Self::new`].
    pub fn flying_missions_from(mut self, store: &'a RefCell<MissionStore>) -> Self {
        self.store = Some(store);
        self.generation = None;
        self
    }

    /// Takes the store's mission when it changed: a new mission, or a new current waypoint.
    fn refresh_mission(&mut self) {
        let Some(store) = self.store else {
            return;
        };
        // Busy (the telemetry task is writing it): the mission of the last step.
        let Ok(store) = store.try_borrow() else {
            return;
        };
        if self.generation == Some(store.generation()) {
            return;
        }
        self.generation = Some(store.generation());
        let m = store.mission();
        if m.waypoints.is_empty() {
            self.mission = None;
        } else if let Some(mine) = self.mission.as_mut() {
            mine.clone_from(m);
        } else {
            self.mission = Some(m.clone());
        }
        self.progress = MissionProgress {
            index: store.start_index(),
            ..MissionProgress::default()
        };
    }

    pub fn last_step(&self) -> Option<&ControlStep> {
        self.last.as_ref()
    }

    pub fn settings(&self) -> &ControlSettings {
        &self.settings
    }

    /// Reads the gains; logs them if they changed (or were never logged).
    fn refresh_settings(&mut self, cx: &TaskContext<'_>) {
        if let Ok(table) = self.params.try_borrow() {
            let s = settings_from(&table, &self.base);
            if s != self.settings {
                self.settings = s;
                self.autopilot.set_gains(s.gains);
                self.gains_logged = false;
            }
        }
        if !self.gains_logged {
            self.gains_logged = true;
            let values = param_specs(&self.settings).map(|(_, v, _, _)| v);
            // `param_specs` order, which the columns follow (a test checks the names).
            let v = values;
            let record = ControlGainsLog {
                roll_kp: v[0],
                roll_ki: v[1],
                roll_kd: v[2],
                pitch_kp: v[3],
                pitch_ki: v[4],
                pitch_kd: v[5],
                course_kp: v[6],
                course_ki: v[7],
                alt_kp: v[8],
                alt_ki: v[9],
                alt_kd: v[10],
                speed_kp: v[11],
                speed_ki: v[12],
                speed_pitch_kp: v[13],
                speed_pitch_ki: v[14],
                yaw_damper: v[15],
                trim_elevator: v[16],
                trim_throttle: v[17],
                max_bank_deg: v[18],
                max_pitch_deg: v[19],
                stab_roll_deg: v[20],
                stab_pitch_deg: v[21],
                cruise_m_s: v[22],
            };
            self.log.log(cx, GAINS_INDEX, &record);
        }
    }

    fn compute(&mut self, now_ns: u64, dt_s: f32) -> ControlStep {
        let estimate = self.estimate.read().map(|l| l.value);
        let pilot = self
            .pilot
            .read()
            .map(|l| l.value)
            .filter(|p| now_ns.saturating_sub(p.received_ns) <= PILOT_TIMEOUT_NS);
        let requested = self
            .requested
            .read()
            .map_or(FlightMode::Stabilise, |l| l.value);
        let fresh_estimate = estimate
            .filter(|e| e.health.healthy && now_ns.saturating_sub(e.t_ns) <= ESTIMATE_TIMEOUT_NS);
        if let Some(e) = &fresh_estimate {
            self.autopilot.observe(e, dt_s);
        }
        let decision = decide(&ModeInputs {
            pilot_switch: pilot.map(|p| p.mode),
            requested,
            estimator_healthy: fresh_estimate.is_some(),
            has_mission: self.mission.is_some(),
        });
        let sticks = pilot.map(|p| p.sticks).unwrap_or_default();
        if decision.mode != self.last_mode {
            self.autopilot.reset();
            self.hold = None;
        }
        self.last_mode = decision.mode;
        if let Some(slot) = self.mode_out {
            slot.publish(decision.mode);
        }
        let mut targets = Targets::default();
        let mut waypoint = u8::MAX;
        let command = match (decision.mode, fresh_estimate) {
            (FlightMode::Stabilise, Some(e)) => {
                let roll_c = sticks.aileron.clamp(-1.0, 1.0) * self.settings.stab_roll_rad;
                let pitch_c = sticks.elevator.clamp(-1.0, 1.0) * self.settings.stab_pitch_rad;
                let mut c = self.autopilot.attitude(&e, roll_c, pitch_c, dt_s);
                c.throttle = sticks.throttle.clamp(0.0, 1.0);
                c.rudder = (c.rudder + sticks.rudder).clamp(-1.0, 1.0);
                targets.roll_rad = roll_c;
                targets.pitch_rad = pitch_c;
                ComputerCommand {
                    controls: c,
                    ready: true,
                }
            }
            (FlightMode::Auto, Some(e)) => {
                let [n, east, _] = e.position_ned_m;
                let guidance = self
                    .mission
                    .as_ref()
                    .and_then(|m| self.progress.guide(m, n, east));
                let (course_c, alt_c, speed_c) = match guidance {
                    Some(g) => {
                        waypoint = g.waypoint;
                        (g.course_rad, g.altitude_m, g.airspeed_mps)
                    }
                    None => {
                        let (course, alt) =
                            *self.hold.get_or_insert((e.course_rad(), e.altitude_m()));
                        (course, alt, self.settings.cruise_mps)
                    }
                };
                let (c, t) = self
                    .autopilot
                    .auto(&e, wrap_pi_f32(course_c), alt_c, speed_c, dt_s);
                targets = t;
                ComputerCommand {
                    controls: c,
                    ready: true,
                }
            }
            _ => ComputerCommand {
                controls: sticks,
                ready: false,
            },
        };
        ControlStep {
            decision,
            sticks,
            targets,
            command,
            waypoint,
        }
    }

    fn log_step(&mut self, cx: &TaskContext<'_>, s: &ControlStep) {
        let e = self.estimate.read().map(|l| l.value);
        let (roll, pitch, course, alt, speed) =
            e.map_or((f32::NAN, f32::NAN, f32::NAN, f32::NAN, f32::NAN), |e| {
                (
                    e.roll_rad,
                    e.pitch_rad,
                    e.course_rad(),
                    e.altitude_m(),
                    self.autopilot.wind().airspeed_mps(&e),
                )
            });
        let [wind_n, wind_e] = self.autopilot.wind().wind_ne_mps();
        let (st, t, c) = (s.sticks, s.targets, s.command.controls);
        let record = ControlLog {
            mode: s.decision.mode as u8,
            reason: s.decision.reason as u8,
            roll_rad: roll,
            pitch_rad: pitch,
            course_rad: course,
            alt_m: alt,
            speed_m_s: speed,
            stick_aileron: st.aileron,
            stick_elevator: st.elevator,
            stick_throttle: st.throttle,
            stick_rudder: st.rudder,
            roll_c_rad: t.roll_rad,
            pitch_c_rad: t.pitch_rad,
            course_c_rad: t.course_rad,
            alt_c_m: t.altitude_m,
            speed_c_m_s: t.airspeed_mps,
            zone: t.zone as u8,
            waypoint: s.waypoint,
            aileron: c.aileron,
            elevator: c.elevator,
            throttle: c.throttle,
            rudder: c.rudder,
            ready: s.command.ready,
            wind_n_m_s: wind_n,
            wind_e_m_s: wind_e,
        };
        self.log.log(cx, CONTROL_INDEX, &record);
    }
}

impl<S: RecordSink> Task for ControlTask<'_, S> {
    fn init(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let bad = |_| TaskFault::new("control log format");
        self.log
            .declare::<ControlLog>(cx, CONTROL_INDEX)
            .map_err(bad)?;
        self.log
            .declare::<ControlGainsLog>(cx, GAINS_INDEX)
            .map_err(bad)?;
        self.log.begin(cx);
        self.gains_logged = false;
        self.last_mode = FlightMode::Manual;
        self.last_ns = None;
        self.autopilot.reset();
        Ok(())
    }

    fn step(&mut self, cx: &mut TaskContext<'_>) -> Result<(), TaskFault> {
        let cx = &*cx;
        self.refresh_settings(cx);
        self.refresh_mission();
        let dt_s = self.last_ns.map_or(0.02, |t| {
            (cx.now_ns.saturating_sub(t) as f32 * 1e-9).clamp(0.001, 0.1)
        });
        self.last_ns = Some(cx.now_ns);
        let s = self.compute(cx.now_ns, dt_s);
        self.out.publish(s.command);
        self.last = Some(s);
        self.log_step(cx, &s);
        Ok(())
    }

    /// Hands the airplane back to the pilot before the reset.
    fn recover(&mut self, cx: &mut TaskContext<'_>) {
        self.out.publish(ComputerCommand::default());
        self.log.end(cx);
    }

    fn shutdown(&mut self, cx: &mut TaskContext<'_>) {
        self.recover(cx);
    }
}

//! Which course errors in AUTO are *hold* error, and which belong to a turn still under way.
//!
//! A row of `control.bin` counts as course hold when all of these are true:
//!
//! - **steady command**: over the last [`STEADY_NS`] every command was within [`STEADY_RAD`] of
//!   the current one (a loiter's turning command, or a bearing swinging past a waypoint, is
//!   never a hold);
//! - **the turn is over**: after a new command (AUTO engaging, or the command stepping by more
//!   than [`STEP_RAD`] between two rows), either the airplane's course has *captured* it (the
//!   loop's own course within [`CAPTURE_RAD`]), or the time the turn takes at the airplane's
//!   bank limit has passed: `|course error at the step| / (g·tan(bank limit) / ground speed)`
//!   plus [`ROLL_MARGIN_NS`] for rolling in and out.
//!
//! Capture comes first for an airplane that turns as fast as its bank limit allows, and
//! everything after it counts, so a roll-out that overshoots the new course is hold error; the
//! turn-time bound makes an airplane that never captures (a standing error, a slow turn) count
//! from the moment it could have. The same rule for every airplane: only its bank limit (the
//! `control.max_bank_deg` in force, from `control.bin` format 2) and its speed enter.

use skyframe_core::angles::wrap_pi;
use skyframe_core::control::autopilot::AutopilotGains;
use skyframe_core::estimation::ekf::GRAVITY_MPS2;

/// How long the command must have been steady.
pub const STEADY_NS: i64 = 5_000_000_000;
pub const STEADY_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;
/// A change between two 50 Hz rows larger than this (50°/s) is a new command, not a drift.
pub const STEP_RAD: f64 = 1.0 * std::f64::consts::PI / 180.0;
pub const CAPTURE_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;
/// Rolling into the turn and out of it: 2 s, a 45° bank reached and left at 45°/s.
pub const ROLL_MARGIN_NS: i64 = 2_000_000_000;

/// The bank limit in force over a flight, from `control.bin` format 2 (`max_bank_deg` at
/// each change).
pub struct BankLimit {
    changes: Vec<(i64, f64)>,
}

impl BankLimit {
    pub fn new(times_ns: &[i64], max_bank_deg: &[f64]) -> Self {
        let changes = times_ns
            .iter()
            .zip(max_bank_deg)
            .filter(|(_, deg)| deg.is_finite() && **deg > 0.0)
            .map(|(&t, &deg)| (t, deg.to_radians()))
            .collect();
        Self { changes }
    }

    /// In force at `t_ns` (the first logged before any was logged). Flights logged without
    /// the gains record: the autopilot's default.
    pub fn at(&self, t_ns: i64) -> f64 {
        let i = self.changes.partition_point(|&(t, _)| t <= t_ns);
        self.changes
            .get(i.saturating_sub(1))
            .map_or(f64::from(AutopilotGains::default().course.out_max), |c| c.1)
    }
}

/// One row of AUTO, as the window needs it.
#[derive(Clone, Copy, Debug)]
pub struct CourseRow {
    pub t_ns: i64,
    pub command_rad: f64,
    /// The loop's own (estimated) course.
    pub estimated_rad: f64,
    /// The true course over ground and ground speed at the row's time.
    pub true_rad: f64,
    pub ground_speed_mps: f64,
    pub bank_limit_rad: f64,
}

/// The turn state carried from row to row within one stretch of AUTO.
pub struct TurnWindow {
    last_command_rad: Option<f64>,
    captured: bool,
    turn_over_ns: i64,
}

impl TurnWindow {
    /// At AUTO engaging: the first row is a new command.
    pub fn new() -> Self {
        Self {
            last_command_rad: None,
            captured: false,
            turn_over_ns: i64::MAX,
        }
    }

    /// Whether the turn to the current command is over at `row` (see the module's rule).
    pub fn turn_over(&mut self, row: &CourseRow) -> bool {
        let new_command = self
            .last_command_rad
            .is_none_or(|last| wrap_pi(row.command_rad - last).abs() > STEP_RAD);
        self.last_command_rad = Some(row.command_rad);
        if new_command {
            self.captured = false;
            let turn_rad = wrap_pi(row.command_rad - row.true_rad).abs();
            let rate = GRAVITY_MPS2 * row.bank_limit_rad.tan() / row.ground_speed_mps.max(5.0);
            let turn_s = turn_rad / rate;
            self.turn_over_ns = if turn_s.is_finite() && turn_s >= 0.0 {
                row.t_ns
                    .saturating_add((turn_s * 1e9) as i64)
                    .saturating_add(ROLL_MARGIN_NS)
            } else {
                i64::MAX
            };
        }
        self.captured |= wrap_pi(row.estimated_rad - row.command_rad).abs() < CAPTURE_RAD;
        self.captured || row.t_ns >= self.turn_over_ns
    }
}

/// Whether the command at row `i` has been steady: every command in the [`STEADY_NS`] before
/// it (and none before `since`, AUTO engaging) within [`STEADY_RAD`] of it.
pub fn steady(times_ns: &[i64], commands_rad: &[f64], i: usize, since_ns: i64) -> bool {
    let (Some(&t), Some(&now)) = (times_ns.get(i), commands_rad.get(i)) else {
        return false;
    };
    let first = times_ns.partition_point(|&x| x < t - STEADY_NS);
    if times_ns.get(first).is_none_or(|&t0| t0 < since_ns) {
        return false;
    }
    commands_rad
        .get(first..=i)
        .is_some_and(|window| window.iter().all(|&c| wrap_pi(now - c).abs() < STEADY_RAD))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bank_limit_in_force_is_the_last_one_logged() {
        let limit = BankLimit::new(&[1_000, 5_000], &[45.0, 20.0]);
        let deg = |t| limit.at(t).to_degrees();
        assert!((deg(0) - 45.0).abs() < 1e-9);
        assert!((deg(4_999) - 45.0).abs() < 1e-9);
        assert!((deg(5_000) - 20.0).abs() < 1e-9);
        // No gains record: the autopilot's default, 30°.
        assert!((BankLimit::new(&[], &[]).at(0).to_degrees() - 30.0).abs() < 1e-4);
    }

    #[test]
    fn a_command_that_swung_away_and_back_is_not_steady() {
        let times: Vec<i64> = (0..400).map(|i| i * 20_000_000).collect();
        // 0 rad, except 1.5° of wobble and one row at 150° 4 s before the end.
        let commands: Vec<f64> = (0..400)
            .map(|i| match i {
                200 => 150f64.to_radians(),
                _ if i % 2 == 0 => 1.5f64.to_radians(),
                _ => 0.0,
            })
            .collect();
        assert!(steady(&times, &commands, 199, 0));
        assert!(!steady(&times, &commands, 399, 0));
        // Less than 5 s of AUTO behind it is not steady either.
        assert!(!steady(&times, &commands, 199, 1_000_000_000));
    }
}

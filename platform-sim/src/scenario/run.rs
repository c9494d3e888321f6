//! Playing a scenario: its timeline handed to the scripted pilot, and pilot-only runs (with
//! an optional stand-in flight computer) in virtual time, for tests.

use super::{InitialCondition, Scenario, TimelineAction, TimelineEntry};
use crate::pilot::{Manoeuvre, Pilot, PilotConfig, SwitchPosition};
use crate::plant::{ActuatorCommands, AircraftParams, Plant, PlantConfig, Truth};
use crate::servo_board::{OutputSource, ServoBoard, TransmitterInput};

impl Scenario {
    /// A timeline player for this scenario.
    pub fn player(&self) -> TimelinePlayer {
        TimelinePlayer {
            timeline: self.timeline.clone(),
            next: 0,
        }
    }
}

/// Hands the timeline's entries to a [`Pilot`] as their times come.
#[derive(Debug, Clone)]
pub struct TimelinePlayer {
    timeline: Vec<TimelineEntry>,
    next: usize,
}

impl TimelinePlayer {
    /// Applies every entry due by `t_s` (in order); returns how many.
    pub fn advance(&mut self, t_s: f64, pilot: &mut Pilot) -> usize {
        let mut applied = 0;
        while let Some(e) = self.timeline.get(self.next) {
            if e.t_s > t_s {
                break;
            }
            match e.action {
                TimelineAction::Pilot(m) => pilot.fly(m),
                TimelineAction::Switch(s) => pilot.set_switch(s),
            }
            self.next += 1;
            applied += 1;
        }
        applied
    }

    pub fn is_finished(&self) -> bool {
        self.next >= self.timeline.len()
    }
}

/// The person with the transmitter in a scenario: the scripted pilot, fed by the timeline.
/// Call [`ScenarioPilot::update`] at the control rate with the plant's truth; it returns what
/// the radio receiver hands the servo board.
#[derive(Debug, Clone)]
pub struct ScenarioPilot {
    pilot: Pilot,
    player: TimelinePlayer,
}

impl ScenarioPilot {
    pub fn new(scenario: &Scenario, params: &AircraftParams) -> Self {
        let mut pilot = Pilot::new(params, PilotConfig::default());
        // Starting in the air, the pilot already has the sticks and holds what it finds.
        if matches!(scenario.initial, InitialCondition::InFlight { .. }) {
            pilot.fly(Manoeuvre::Hold {
                altitude_m: None,
                heading_rad: None,
                airspeed_mps: None,
            });
        }
        Self {
            pilot,
            player: scenario.player(),
        }
    }

    /// Applies the timeline entries due by `truth.t_s`, then looks and moves the sticks.
    pub fn update(&mut self, truth: &Truth) -> TransmitterInput {
        self.player.advance(truth.t_s, &mut self.pilot);
        let sticks = self.pilot.update(truth);
        TransmitterInput {
            sticks,
            switch: self.pilot.switch(),
        }
    }

    pub fn pilot(&self) -> &Pilot {
        &self.pilot
    }

    /// See [`Pilot::retrim`].
    pub fn retrim(
        &mut self,
        trim: ActuatorCommands,
        trim_pitch_rad: f64,
        cruise_airspeed_mps: f64,
    ) {
        self.pilot.retrim(trim, trim_pitch_rad, cruise_airspeed_mps);
    }
}

// ------------------------------------------------------------------------------------------
// Pilot-only runs
// ------------------------------------------------------------------------------------------

/// How a pilot-only run steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunOptions {
    /// How often the pilot looks and the board updates the servos (s).
    pub control_period_s: f64,
    /// The plant's longest integration step (s); coarser is faster and a little less exact.
    pub plant_max_step_s: f64,
    /// How often the summary records a sample (s).
    pub sample_period_s: f64,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            control_period_s: 0.02,
            plant_max_step_s: 0.001,
            sample_period_s: 0.1,
        }
    }
}

/// One recorded moment of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectorySample {
    pub t_s: f64,
    pub position_ned_m: [f64; 3],
    pub height_m: f64,
    pub airspeed_mps: f64,
    pub roll_rad: f64,
    pub pitch_rad: f64,
    pub yaw_rad: f64,
    pub on_ground: bool,
    pub switch: SwitchPosition,
    pub source: OutputSource,
    pub pilot_phase: &'static str,
}

/// What a pilot-only run did.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightSummary {
    pub samples: Vec<TrajectorySample>,
    /// First time the wheels left the ground (wheels off and above 1 m), and where.
    pub liftoff: Option<(f64, [f64; 3])>,
    /// First time the wheels touched again after lift-off, and where.
    pub touchdown: Option<(f64, [f64; 3])>,
    pub final_truth: Truth,
    pub max_height_m: f64,
    /// Furthest horizontal distance from the origin (m).
    pub max_distance_m: f64,
    /// An airframe strike (tail, wing tip, crash) at any moment.
    pub airframe_strike: bool,
    /// The first one's time and the truth then.
    pub first_strike: Option<Truth>,
    /// The pilot's landing ended with the airplane stopped.
    pub parked: bool,
    /// Time the board spent on each source (s): pilot, computer, failsafe.
    pub time_on_pilot_s: f64,
    pub time_on_computer_s: f64,
    pub time_on_failsafe_s: f64,
}

impl FlightSummary {
    /// Time in the air (s).
    pub fn flight_time_s(&self) -> Option<f64> {
        match (self.liftoff, self.touchdown) {
            (Some((a, _)), Some((b, _))) => Some(b - a),
            _ => None,
        }
    }
}

/// A command from a stand-in flight computer: what it wants the servos to do and whether it
/// says it is ready to fly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StandInCommand {
    pub commands: ActuatorCommands,
    pub autopilot_ready: bool,
}

/// Flies `scenario` with the scripted pilot alone: no flight computer, so whatever the switch
/// says the servo board gives the pilot the servos. Deterministic for the scenario's seed.
pub fn run_pilot_only(scenario: &Scenario, options: RunOptions) -> FlightSummary {
    run_with_computer(scenario, options, |_| None)
}

/// Flies `scenario` with the scripted pilot and a stand-in flight computer: `computer` is
/// asked once per control period, seeing the truth; `None` means it sent nothing then (a
/// computer that stops answering makes the board fail safe to the pilot after 100 ms).
pub fn run_with_computer(
    scenario: &Scenario,
    options: RunOptions,
    mut computer: impl FnMut(&Truth) -> Option<StandInCommand>,
) -> FlightSummary {
    let params = AircraftParams::aerosonde();
    let config = PlantConfig {
        max_step_s: options.plant_max_step_s,
        ..scenario.plant_config()
    };
    let mut plant = Plant::with_config(config, scenario.initial_state(&params), scenario.seed);
    let mut pilot = ScenarioPilot::new(scenario, &params);
    let mut board = ServoBoard::new();
    let dt = options.control_period_s.max(1e-3);
    let steps = (scenario.duration_s / dt).round() as u64;
    let sample_every = ((options.sample_period_s / dt).round() as u64).max(1);

    let start = plant.truth();
    let mut summary = FlightSummary {
        samples: Vec::new(),
        liftoff: None,
        touchdown: None,
        final_truth: start,
        max_height_m: start.height_above_ground_m,
        max_distance_m: 0.0,
        airframe_strike: false,
        first_strike: None,
        parked: false,
        time_on_pilot_s: 0.0,
        time_on_computer_s: 0.0,
        time_on_failsafe_s: 0.0,
    };
    let mut was_airborne = !start.on_ground;
    for k in 0..steps {
        let truth = plant.truth();
        let input = pilot.update(&truth);
        if let Some(c) = computer(&truth) {
            board.receive_computer_command(plant.time_ns(), c.commands, c.autopilot_ready);
        }
        let (out, source) = board.mix(plant.time_ns(), &input);
        match source {
            OutputSource::Pilot => summary.time_on_pilot_s += dt,
            OutputSource::Computer => summary.time_on_computer_s += dt,
            OutputSource::Failsafe => summary.time_on_failsafe_s += dt,
        }
        if k % sample_every == 0 {
            summary.samples.push(TrajectorySample {
                t_s: truth.t_s,
                position_ned_m: truth.position_ned_m,
                height_m: truth.height_above_ground_m,
                airspeed_mps: truth.airspeed_mps,
                roll_rad: truth.roll_rad,
                pitch_rad: truth.pitch_rad,
                yaw_rad: truth.yaw_rad,
                on_ground: truth.on_ground,
                switch: input.switch,
                source,
                pilot_phase: pilot.pilot().phase_name(),
            });
        }
        plant.step(dt, &out);
        let t = plant.truth();
        if t.airframe_strike && !summary.airframe_strike {
            summary.airframe_strike = true;
            summary.first_strike = Some(t);
        }
        summary.max_height_m = summary.max_height_m.max(t.height_above_ground_m);
        summary.max_distance_m = summary
            .max_distance_m
            .max(t.position_ned_m[0].hypot(t.position_ned_m[1]));
        if !t.on_ground && t.height_above_ground_m > 1.0 && !was_airborne {
            was_airborne = true;
            if summary.liftoff.is_none() {
                summary.liftoff = Some((t.t_s, t.position_ned_m));
            }
        }
        if t.on_ground && was_airborne && summary.touchdown.is_none() {
            summary.touchdown = Some((t.t_s, t.position_ned_m));
        }
    }
    summary.final_truth = plant.truth();
    summary.parked = pilot.pilot().is_parked();
    summary
}

//! Scenario files (TOML): the initial state, the wind, the GPS receiver, a timeline of pilot
//! manoeuvres and switch changes, and injected faults. `scenarios/README.md` documents the
//! format; [`Scenario::parse`] reads it and [`run_pilot_only`] flies it with the scripted pilot
//! alone (no flight computer), in virtual time, for tests.
//!
//! Faults are data here: parsed, validated and offered through [`Scenario::active_faults`];
//! applying them is the business of whoever simulates the device or the executive.
//!
//! Errors are one line and say where: `line 12, column 1: timeline entry 3: unknown pilot
//! manoeuvre "barrel", expected one of ...`. Parsing never panics.

use crate::pilot::{Manoeuvre, Runway};
use crate::plant::sensors::SimGpsConfig;
use crate::plant::trim::trim_level_flight;
use crate::plant::{
    AircraftParams, DrydenParams, InitialState, PlantConfig, PlantKind, WindConfig,
};
use std::fmt;

mod file;
mod locate;
mod run;

pub use crate::pilot::SwitchPosition;
pub use run::{
    FlightSummary, RunOptions, ScenarioPilot, StandInCommand, TimelinePlayer, TrajectorySample,
    run_pilot_only, run_with_computer,
};

/// Seed used when the file gives none.
pub const DEFAULT_SEED: u64 = 1;

/// A scenario file that could not be read, and where.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScenarioError {
    /// 1-based; 0 when the place is unknown.
    pub line: usize,
    pub column: usize,
    pub message: String,
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}", self.message)
        } else {
            write!(
                f,
                "line {}, column {}: {}",
                self.line, self.column, self.message
            )
        }
    }
}

impl std::error::Error for ScenarioError {}

// ------------------------------------------------------------------------------------------
// The scenario as used
// ------------------------------------------------------------------------------------------

/// Where the airplane starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InitialCondition {
    /// Parked at the origin, nose towards `heading_rad`.
    OnRunway { heading_rad: f64 },
    /// Trimmed level flight over the origin.
    InFlight {
        altitude_m: f64,
        airspeed_mps: f64,
        heading_rad: f64,
    },
}

impl InitialCondition {
    pub fn heading_rad(&self) -> f64 {
        match *self {
            InitialCondition::OnRunway { heading_rad }
            | InitialCondition::InFlight { heading_rad, .. } => heading_rad,
        }
    }
}

/// Turbulence level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Turbulence {
    #[default]
    None,
    Light,
    Moderate,
}

/// The GPS receiver model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GpsPreset {
    /// A clean 10 Hz receiver.
    #[default]
    Nominal,
    /// The seed airframe's: 140 ms mean interval, 300 ms peaks.
    SeedReceiver,
    /// Exact fixes every 100 ms.
    Ideal,
}

impl GpsPreset {
    pub fn config(self) -> SimGpsConfig {
        match self {
            GpsPreset::Nominal => SimGpsConfig::nominal_10hz(),
            GpsPreset::SeedReceiver => SimGpsConfig::seed_receiver(),
            GpsPreset::Ideal => SimGpsConfig::ideal(),
        }
    }
}

/// What happens at a timeline entry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TimelineAction {
    Pilot(Manoeuvre),
    Switch(SwitchPosition),
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimelineEntry {
    pub t_s: f64,
    pub action: TimelineAction,
    /// Line in the scenario file, for messages.
    pub line: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultKind {
    /// The device sends nothing.
    SensorSilence,
    /// The device sends random bytes.
    GarbageBurst,
    /// The GPS receiver loses its fix (it reports no fix, or nothing).
    GpsLoss,
    /// A task is made to run `extra_us` longer than it would.
    TaskOverrun,
    /// The servo board's serial port disappears (unplugged).
    ServoPortVanish,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Device {
    Imu,
    Gps,
    Servo,
}

/// An injected fault, active over `[t_s, t_s + duration_s)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Fault {
    pub t_s: f64,
    pub duration_s: f64,
    pub kind: FaultKind,
    /// The device it hits: always set for sensor silence and garbage bursts, `Gps` for GPS
    /// loss and `Servo` for a vanished servo port; `None` for a task overrun.
    pub device: Option<Device>,
    /// The task made to overrun (task overrun only).
    pub task: Option<String>,
    /// How much longer the task runs (task overrun only), µs.
    pub extra_us: Option<u64>,
    pub line: usize,
}

impl Fault {
    pub fn is_active(&self, t_s: f64) -> bool {
        t_s >= self.t_s && t_s < self.t_s + self.duration_s
    }

    pub fn end_s(&self) -> f64 {
        self.t_s + self.duration_s
    }
}

/// A parsed, validated scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    pub seed: u64,
    pub duration_s: f64,
    pub initial: InitialCondition,
    pub wind_ned_mps: [f64; 3],
    pub turbulence: Turbulence,
    pub gps: GpsPreset,
    /// Where approaches and landings go.
    pub runway: Runway,
    /// The flight model and aircraft (`[plant]`; default the built-in Aerosonde).
    pub plant: PlantKind,
    /// The scripted pilot's cruise speed on the scenario's aircraft (`[plant]`), when it is not
    /// the Aerosonde's: the pilot flies from the trim the plant finds there.
    pub pilot_cruise_airspeed_mps: Option<f64>,
    /// Flight-computer parameters set before the flight (`[parameters]`), by name.
    pub parameters: Vec<(String, f64)>,
    /// In time order.
    pub timeline: Vec<TimelineEntry>,
    /// In start-time order.
    pub faults: Vec<Fault>,
}

impl Scenario {
    /// Reads a scenario file; errors start with the path.
    pub fn load(path: &std::path::Path) -> Result<Self, ScenarioError> {
        let src =
            skyframe_input_files::read_text(path, "scenario", skyframe_input_files::CONFIG_LIMIT)
                .map_err(|message| ScenarioError {
                line: 0,
                column: 0,
                message,
            })?;
        Self::parse(&src).map_err(|e| ScenarioError {
            message: format!("{}: {}", path.display(), e.message),
            ..e
        })
    }

    /// The faults active at `t_s`.
    pub fn active_faults(&self, t_s: f64) -> impl Iterator<Item = &Fault> {
        self.faults.iter().filter(move |f| f.is_active(t_s))
    }

    /// The wind model this scenario asks for.
    pub fn wind_config(&self) -> WindConfig {
        WindConfig {
            steady_ned_mps: self.wind_ned_mps,
            turbulence: match self.turbulence {
                Turbulence::None => None,
                Turbulence::Light => Some(DrydenParams::light_low_altitude()),
                Turbulence::Moderate => Some(DrydenParams::moderate_low_altitude()),
            },
        }
    }

    /// The plant configuration: default airframe and sensors with this wind and GPS.
    pub fn plant_config(&self) -> PlantConfig {
        PlantConfig {
            wind: self.wind_config(),
            gps: self.gps.config(),
            ..PlantConfig::default()
        }
    }

    /// The plant's initial state; in flight it is trimmed level flight (falling back to an
    /// untrimmed state at that speed if the airframe cannot trim there).
    pub fn initial_state(&self, params: &AircraftParams) -> InitialState {
        match self.initial {
            InitialCondition::OnRunway { heading_rad } => {
                InitialState::on_runway(params, heading_rad)
            }
            InitialCondition::InFlight {
                altitude_m,
                airspeed_mps,
                heading_rad,
            } => trim_level_flight(params, airspeed_mps, altitude_m, heading_rad)
                .map(|t| t.initial)
                .unwrap_or_else(|_| InitialState::in_flight(altitude_m, airspeed_mps, heading_rad)),
        }
    }

    /// Checks every task-overrun fault names one of `task_names` (the schedule's tasks).
    pub fn check_tasks(&self, task_names: &[&str]) -> Result<(), ScenarioError> {
        for f in &self.faults {
            if let Some(task) = &f.task {
                if !task_names.contains(&task.as_str()) {
                    return Err(ScenarioError {
                        line: f.line,
                        column: 1,
                        message: format!(
                            "task_overrun: no task \"{task}\" in the schedule (it has {})",
                            task_names.join(", ")
                        ),
                    });
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;

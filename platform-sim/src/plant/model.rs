//! The flight model behind the simulated airplane, as a trait: the built-in 6-DOF model
//! ([`SixDofModel`](super::sixdof::SixDofModel)) and JSBSim
//! ([`JsbsimModel`](super::jsbsim::JsbsimModel)) both implement it, and everything above
//! (sensors, servo board, pilot, world) sees only [`Truth`].

use super::{ActuatorCommands, Truth};
use std::fmt;

/// A flight model that can no longer fly: its child process died, wrote garbage, or could
/// not start. One line, for the command line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlantError(pub String);

impl fmt::Display for PlantError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for PlantError {}

/// Which flight model flies the airplane.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum PlantKind {
    /// Our own 6-DOF Aerosonde (no outside dependency).
    #[default]
    BuiltIn,
    /// JSBSim (the `jsbsim` Python package) with one of its aircraft, or ours (`skyframe-uav`).
    Jsbsim { aircraft: String },
}

impl PlantKind {
    /// `builtin`, or `jsbsim` with an aircraft (default `c172x`).
    pub fn from_names(plant: &str, aircraft: Option<&str>) -> Result<Self, String> {
        match plant {
            "builtin" => match aircraft {
                None | Some("aerosonde") => Ok(PlantKind::BuiltIn),
                Some(other) => Err(format!(
                    "the builtin plant flies only \"aerosonde\", not \"{other}\" (use --plant jsbsim)"
                )),
            },
            "jsbsim" => Ok(PlantKind::Jsbsim {
                aircraft: aircraft.unwrap_or("c172x").to_string(),
            }),
            other => Err(format!(
                "unknown plant \"{other}\", expected \"builtin\" or \"jsbsim\""
            )),
        }
    }

    pub fn plant_name(&self) -> &'static str {
        match self {
            PlantKind::BuiltIn => "builtin",
            PlantKind::Jsbsim { .. } => "jsbsim",
        }
    }

    pub fn aircraft_name(&self) -> &str {
        match self {
            PlantKind::BuiltIn => "aerosonde",
            PlantKind::Jsbsim { aircraft } => aircraft,
        }
    }
}

/// The airplane's dynamics, advanced in plant time by whoever owns the sensors.
pub trait FlightModel: Send {
    /// Advances by `dt_s` (rounded to whole ns) with `commands` held (sanitised by the caller).
    fn step(&mut self, dt_s: f64, commands: &ActuatorCommands) -> Result<(), PlantError>;
    /// Ground truth now.
    fn truth(&self) -> Truth;
    /// Plant time (ns).
    fn time_ns(&self) -> u64;
    /// Current the propulsion motor draws now (A), for the battery model; 0 for engines that
    /// do not run on the propulsion pack.
    fn motor_current_a(&self) -> f64;
}

impl<M: FlightModel + ?Sized> FlightModel for Box<M> {
    fn step(&mut self, dt_s: f64, commands: &ActuatorCommands) -> Result<(), PlantError> {
        (**self).step(dt_s, commands)
    }
    fn truth(&self) -> Truth {
        (**self).truth()
    }
    fn time_ns(&self) -> u64 {
        (**self).time_ns()
    }
    fn motor_current_a(&self) -> f64 {
        (**self).motor_current_a()
    }
}

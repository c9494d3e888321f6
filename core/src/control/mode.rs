//! Who flies: the pilot's switch on the servo board always wins, at once; with the switch
//! on "auto" the computer flies in the mode the ground requested, unless the estimator is
//! unhealthy, in which case control goes back to the pilot and says why.

use crate::devices::servo::ControlMode;

/// What the vehicle flies in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum FlightMode {
    /// The pilot's commands go straight to the servos.
    Manual = 0,
    /// The pilot's sticks command attitude; the controller holds it.
    Stabilise = 1,
    /// The controller flies.
    Auto = 2,
}

impl FlightMode {
    pub fn from_u8(value: u8) -> Option<Self> {
        match value {
            0 => Some(Self::Manual),
            1 => Some(Self::Stabilise),
            2 => Some(Self::Auto),
            _ => None,
        }
    }
}

/// Why the active mode is what it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum ModeReason {
    /// The requested mode is in force.
    Requested = 0,
    /// The pilot's switch is on manual.
    PilotSwitch = 1,
    /// No (fresh) report from the servo board: the pilot is assumed in control.
    NoPilotReport = 2,
    /// The estimator is not healthy.
    EstimatorUnhealthy = 3,
    /// Auto was requested without a mission or position: holding what the vehicle had.
    AutoWithoutMission = 4,
}

impl ModeReason {
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Requested => "requested",
            Self::PilotSwitch => "pilot switch on manual",
            Self::NoPilotReport => "no report from the servo board",
            Self::EstimatorUnhealthy => "estimator unhealthy",
            Self::AutoWithoutMission => "auto without mission: holding",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ModeInputs {
    /// The switch as the board last reported it; `None` if no fresh report.
    pub pilot_switch: Option<ControlMode>,
    /// What the ground asked for.
    pub requested: FlightMode,
    pub estimator_healthy: bool,
    pub has_mission: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ModeDecision {
    pub mode: FlightMode,
    pub reason: ModeReason,
}

/// The mode truth table (pure: the tests enumerate it).
pub fn decide(i: &ModeInputs) -> ModeDecision {
    let manual = |reason| ModeDecision {
        mode: FlightMode::Manual,
        reason,
    };
    match i.pilot_switch {
        None => return manual(ModeReason::NoPilotReport),
        Some(ControlMode::Manual) => return manual(ModeReason::PilotSwitch),
        Some(ControlMode::Auto) => {}
    }
    if i.requested == FlightMode::Manual {
        return manual(ModeReason::Requested);
    }
    if !i.estimator_healthy {
        return manual(ModeReason::EstimatorUnhealthy);
    }
    let reason = if i.requested == FlightMode::Auto && !i.has_mission {
        ModeReason::AutoWithoutMission
    } else {
        ModeReason::Requested
    };
    ModeDecision {
        mode: i.requested,
        reason,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_table() {
        use ControlMode as S;
        use FlightMode as F;
        use ModeReason as R;
        let switches = [None, Some(S::Manual), Some(S::Auto)];
        let requests = [F::Manual, F::Stabilise, F::Auto];
        let mut rows = 0;
        for pilot_switch in switches {
            for requested in requests {
                for estimator_healthy in [false, true] {
                    for has_mission in [false, true] {
                        let d = decide(&ModeInputs {
                            pilot_switch,
                            requested,
                            estimator_healthy,
                            has_mission,
                        });
                        let expected = match (pilot_switch, requested, estimator_healthy) {
                            (None, _, _) => (F::Manual, R::NoPilotReport),
                            (Some(S::Manual), _, _) => (F::Manual, R::PilotSwitch),
                            (Some(S::Auto), F::Manual, _) => (F::Manual, R::Requested),
                            (Some(S::Auto), _, false) => (F::Manual, R::EstimatorUnhealthy),
                            (Some(S::Auto), F::Auto, true) if !has_mission => {
                                (F::Auto, R::AutoWithoutMission)
                            }
                            (Some(S::Auto), m, true) => (m, R::Requested),
                        };
                        assert_eq!(
                            (d.mode, d.reason),
                            expected,
                            "{pilot_switch:?} {requested:?} {estimator_healthy} {has_mission}"
                        );
                        rows += 1;
                    }
                }
            }
        }
        assert_eq!(rows, 36);
    }
}

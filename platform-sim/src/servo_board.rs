//! The servo board's mixing logic: which of the pilot (the radio receiver) and the flight
//! computer drives the servos.
//!
//! - Switch on MANUAL: the pilot, at once, whatever the computer says. Manual always wins.
//! - Switch on AUTO and the computer's latest command said `autopilot_ready`: the computer.
//! - Switch on AUTO but the computer has not said it is ready: the pilot.
//! - Switch on AUTO, ready, but no command for more than [`FAILSAFE_TIMEOUT_NS`]: the flight
//!   computer is taken for dead and the pilot flies (failsafe) until commands come again.
//!
//! Commands are normalised ([`ActuatorCommands`]); turning them into pulse widths and bytes is
//! the protocol's business, not this module's. The board also reports what it sees to the
//! computer: the pilot's sticks and switch, which source drives the servos, and the battery
//! voltages (from [`Plant::sample_battery`](crate::plant::Plant::sample_battery)).

use crate::pilot::SwitchPosition;
use crate::plant::{ActuatorCommands, BatterySample};

/// Computer commands older than this are ignored and the pilot flies (ns).
pub const FAILSAFE_TIMEOUT_NS: u64 = 100_000_000;

/// What the radio receiver gives the board.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TransmitterInput {
    pub sticks: ActuatorCommands,
    pub switch: SwitchPosition,
}

/// Who drives the servos.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputSource {
    /// The switch is on MANUAL, or the computer has not said it is ready.
    Pilot,
    Computer,
    /// The switch is on AUTO and the computer was ready, but its commands stopped.
    Failsafe,
}

/// What the board reports to the flight computer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardReport {
    pub pilot: TransmitterInput,
    pub source: OutputSource,
    pub avionics_voltage_v: f64,
    pub propulsion_voltage_v: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct LatchedCommand {
    commands: ActuatorCommands,
    autopilot_ready: bool,
    received_at_ns: u64,
}

/// The board's state: the computer's latest command and what the servos were last given.
#[derive(Debug, Clone, Default)]
pub struct ServoBoard {
    computer: Option<LatchedCommand>,
    last_source: Option<OutputSource>,
}

impl ServoBoard {
    pub fn new() -> Self {
        Self::default()
    }

    /// A command from the flight computer arrived at `now_ns`.
    pub fn receive_computer_command(
        &mut self,
        now_ns: u64,
        commands: ActuatorCommands,
        autopilot_ready: bool,
    ) {
        self.computer = Some(LatchedCommand {
            commands: commands.sanitized(),
            autopilot_ready,
            received_at_ns: now_ns,
        });
    }

    /// Who would drive the servos at `now_ns` with the switch at `switch`.
    pub fn source(&self, now_ns: u64, switch: SwitchPosition) -> OutputSource {
        match (switch, self.computer) {
            (SwitchPosition::Manual, _) => OutputSource::Pilot,
            (SwitchPosition::Auto, None) => OutputSource::Pilot,
            (SwitchPosition::Auto, Some(c)) if !c.autopilot_ready => OutputSource::Pilot,
            (SwitchPosition::Auto, Some(c)) => {
                if now_ns.saturating_sub(c.received_at_ns) > FAILSAFE_TIMEOUT_NS {
                    OutputSource::Failsafe
                } else {
                    OutputSource::Computer
                }
            }
        }
    }

    /// The servo outputs at `now_ns` and who set them.
    pub fn mix(
        &mut self,
        now_ns: u64,
        pilot: &TransmitterInput,
    ) -> (ActuatorCommands, OutputSource) {
        let source = self.source(now_ns, pilot.switch);
        self.last_source = Some(source);
        let commands = match (source, self.computer) {
            (OutputSource::Computer, Some(c)) => c.commands,
            _ => pilot.sticks.sanitized(),
        };
        (commands, source)
    }

    /// Who drove the servos at the last [`ServoBoard::mix`].
    pub fn last_source(&self) -> Option<OutputSource> {
        self.last_source
    }

    /// The report to the flight computer at `now_ns`.
    pub fn status(
        &self,
        now_ns: u64,
        pilot: &TransmitterInput,
        battery: &BatterySample,
    ) -> BoardReport {
        BoardReport {
            pilot: *pilot,
            source: self.source(now_ns, pilot.switch),
            avionics_voltage_v: battery.avionics_voltage_v,
            propulsion_voltage_v: battery.propulsion_voltage_v,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::{AircraftParams, InitialState, Plant, WindConfig};

    const MS: u64 = 1_000_000;

    fn sticks() -> ActuatorCommands {
        ActuatorCommands {
            aileron: -0.3,
            elevator: 0.2,
            rudder: 0.1,
            throttle: 0.6,
            brake: 0.0,
        }
    }

    fn computer() -> ActuatorCommands {
        ActuatorCommands {
            aileron: 0.5,
            elevator: -0.4,
            rudder: -0.2,
            throttle: 0.9,
            brake: 0.0,
        }
    }

    fn input(switch: SwitchPosition) -> TransmitterInput {
        TransmitterInput {
            sticks: sticks(),
            switch,
        }
    }

    #[test]
    fn mixing_truth_table() {
        use OutputSource::*;
        use SwitchPosition::*;
        // (switch, computer sent?, ready?, command age in ms) → source
        let cases = [
            (Manual, false, false, 0, Pilot),
            (Manual, true, false, 0, Pilot),
            (Manual, true, true, 0, Pilot),
            (Manual, true, true, 500, Pilot),
            (Auto, false, false, 0, Pilot),
            (Auto, true, false, 0, Pilot),
            (Auto, true, false, 500, Pilot),
            (Auto, true, true, 0, Computer),
            (Auto, true, true, 100, Computer),
            (Auto, true, true, 101, Failsafe),
            (Auto, true, true, 5000, Failsafe),
        ];
        for (switch, sent, ready, age_ms, want) in cases {
            let mut board = ServoBoard::new();
            let t0 = 1000 * MS;
            if sent {
                board.receive_computer_command(t0, computer(), ready);
            }
            let (out, source) = board.mix(t0 + age_ms * MS, &input(switch));
            assert_eq!(
                source, want,
                "{switch:?} sent {sent} ready {ready} age {age_ms} ms"
            );
            let expected = if want == Computer {
                computer()
            } else {
                sticks()
            };
            assert_eq!(out, expected, "{switch:?} {sent} {ready} {age_ms}");
            assert_eq!(board.last_source(), Some(want));
        }
    }

    #[test]
    fn manual_wins_at_once_and_auto_resumes() {
        let mut board = ServoBoard::new();
        board.receive_computer_command(0, computer(), true);
        assert_eq!(
            board.mix(10 * MS, &input(SwitchPosition::Auto)).1,
            OutputSource::Computer
        );
        // Same instant, fresh command, switch flipped: the pilot has it.
        board.receive_computer_command(20 * MS, computer(), true);
        let (out, source) = board.mix(20 * MS, &input(SwitchPosition::Manual));
        assert_eq!((out, source), (sticks(), OutputSource::Pilot));
        let (out, source) = board.mix(30 * MS, &input(SwitchPosition::Auto));
        assert_eq!((out, source), (computer(), OutputSource::Computer));
    }

    #[test]
    fn failsafe_when_the_computer_goes_quiet_and_recovery_when_it_returns() {
        let mut board = ServoBoard::new();
        let auto = input(SwitchPosition::Auto);
        // Commands every 20 ms up to 200 ms.
        for k in 0..=10 {
            board.receive_computer_command(k * 20 * MS, computer(), true);
            assert_eq!(board.mix(k * 20 * MS + MS, &auto).1, OutputSource::Computer);
        }
        // Then silence: the computer still drives for 100 ms, the pilot after.
        assert_eq!(board.mix(300 * MS, &auto).1, OutputSource::Computer);
        let (out, source) = board.mix(301 * MS, &auto);
        assert_eq!((out, source), (sticks(), OutputSource::Failsafe));
        assert_eq!(board.mix(2000 * MS, &auto).1, OutputSource::Failsafe);
        // It comes back.
        board.receive_computer_command(2010 * MS, computer(), true);
        assert_eq!(board.mix(2011 * MS, &auto).1, OutputSource::Computer);
        // And says it is not ready any more: the pilot.
        board.receive_computer_command(2030 * MS, computer(), false);
        assert_eq!(board.mix(2031 * MS, &auto).1, OutputSource::Pilot);
    }

    #[test]
    fn bad_commands_are_sanitised() {
        let mut board = ServoBoard::new();
        let wild = ActuatorCommands {
            aileron: f64::NAN,
            elevator: 3.0,
            rudder: -3.0,
            throttle: 2.0,
            brake: -1.0,
        };
        board.receive_computer_command(0, wild, true);
        let (out, _) = board.mix(0, &input(SwitchPosition::Auto));
        assert_eq!(out, wild.sanitized());
        let (out, _) = board.mix(
            0,
            &TransmitterInput {
                sticks: wild,
                switch: SwitchPosition::Manual,
            },
        );
        assert_eq!(out, wild.sanitized());
    }

    #[test]
    fn status_reports_battery_voltages_that_sag_with_load() {
        let params = AircraftParams::aerosonde();
        let mut plant = Plant::new(
            params.clone(),
            InitialState::on_runway(&params, 0.0),
            WindConfig::calm(),
            7,
        );
        let mut board = ServoBoard::new();
        let mut voltage_with = |throttle: f64, plant: &mut Plant| {
            let pilot = TransmitterInput {
                sticks: ActuatorCommands {
                    throttle,
                    brake: 1.0,
                    ..Default::default()
                },
                switch: SwitchPosition::Manual,
            };
            for _ in 0..50 {
                let (out, _) = board.mix(plant.time_ns(), &pilot);
                plant.step(0.01, &out);
            }
            board.status(plant.time_ns(), &pilot, &plant.sample_battery())
        };
        let idle = voltage_with(0.0, &mut plant);
        let full = voltage_with(1.0, &mut plant);
        assert_eq!(full.source, OutputSource::Pilot);
        assert!(
            idle.propulsion_voltage_v - full.propulsion_voltage_v > 1.0,
            "{idle:?} {full:?}"
        );
        assert!(idle.avionics_voltage_v > 11.0 && idle.avionics_voltage_v < 12.8);
    }
}

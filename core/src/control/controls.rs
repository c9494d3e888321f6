//! What control commands and the servo task sends: the four controls in their normalised
//! units (`conventions.md`), and whether the controller vouches for them.

/// The four controls, normalised (`conventions.md`: surfaces in [−1, 1], throttle in [0, 1]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Controls {
    pub aileron: f32,
    pub elevator: f32,
    pub throttle: f32,
    pub rudder: f32,
}

/// What the computer wants the servos to do.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ComputerCommand {
    pub controls: Controls,
    /// The controller vouches for these commands; without it the board keeps the pilot in
    /// control.
    pub ready: bool,
}

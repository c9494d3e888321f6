//! Control: who flies ([`mode`]), what to fly ([`mission`]), and how ([`autopilot`] built of
//! [`pid`] loops, flying on the airspeed of the [`wind`] estimate). The control task (`tasks/control.rs`) ties them to the estimate, the
//! pilot and the parameters.

pub mod autopilot;
pub mod mission;
pub mod mode;
pub mod pid;
pub mod wind;

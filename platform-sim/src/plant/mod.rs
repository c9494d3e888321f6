//! The simulated airplane: a 6-DOF Aerosonde with wind, ground contact and sensor models.

pub mod dynamics;
pub mod math;
pub mod params;
pub mod rng;
pub mod wind;

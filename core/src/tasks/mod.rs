//! The tasks the schedule can name (the catalogue in `schedule/analysis.rs`), one module
//! each, following the data: device tasks (`imu`, `gps`, `servo`) turn bytes into frames,
//! publish them in latest-value slots and log them; `health` watches everyone; `logging`
//! snapshots health; `estimator` turns IMU, GPS and horizon into an estimate; `control`
//! turns the estimate, the pilot and the mission into servo commands. Telemetry arrives with
//! its issue; until then the shell fills its slot with an idle task.

pub mod control;
pub mod device_status;
pub mod estimator;
pub mod gps;
pub mod health;
pub mod imu;
pub mod logging;
pub mod servo;
pub mod task_log;
pub mod telemetry;

#[cfg(test)]
mod device_tests;
#[cfg(test)]
mod flight_tests;
#[cfg(test)]
pub(crate) mod test_support;

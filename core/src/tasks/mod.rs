//! The tasks the schedule can name (registered in `shell/src/tasks.rs`), one module
//! each, following the data: device tasks (`imu`, `gps`, `servo`) turn bytes into frames,
//! publish them in latest-value slots and log them; `watchdog` watches everyone; `health`
//! snapshots every task's health; `estimator` turns IMU, GPS and horizon into an estimate; `control`
//! turns the estimate, the pilot and the mission into servo commands; `telemetry` is the
//! vehicle's end of the link, and `tap` hands it each task's latest logged records.

pub mod control;
pub mod device_status;
pub mod estimator;
pub mod gps;
pub mod health;
pub mod imu;
#[cfg(test)]
mod record_tests;
pub mod servo;
pub mod tap;
pub mod task_log;
pub mod telemetry;
pub mod watchdog;

#[cfg(test)]
mod device_tests;
#[cfg(test)]
mod flight_tests;
#[cfg(test)]
pub(crate) mod test_support;

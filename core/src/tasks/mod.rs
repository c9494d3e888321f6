//! The tasks the schedule can name (the catalogue in `schedule/analysis.rs`), one module
//! each, following the data: device tasks (`imu`, `gps`, `servo`) turn bytes into frames,
//! publish them in latest-value slots and log them; `health` watches everyone; `logging`
//! snapshots health. Estimation, control and telemetry arrive with their issues; until then
//! the shell fills their slots with idle tasks.

pub mod device_status;
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
pub(crate) mod test_support;

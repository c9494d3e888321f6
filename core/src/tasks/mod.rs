//! The tasks the schedule can name (the catalogue in `schedule/analysis.rs`), one module
//! each. Device, estimation, control, logging and telemetry tasks arrive with their issues;
//! until then the shell fills their slots with idle tasks.

pub mod health;
pub mod logging;
pub mod task_log;

#[cfg(test)]
pub(crate) mod test_support;

//! State estimation: where the airplane is, how fast it goes and which way it points.
//!
//! - [`alignment`]: the static start-up (gyro bias, roll and pitch, the observable part of
//!   the accelerometer bias);
//! - [`ekf`]: the 15-state error-state EKF at the IMU rate with delayed GPS and horizon
//!   updates;
//! - [`geo`]: WGS-84 to the local NED frame around home;
//! - [`estimator`]: all of it together, from device frames to an [`Estimate`] with health.
//!
//! The filter's algebra is `nalgebra` fixed-size matrices in `f64`, on the stack; no heap.
//! nalgebra types carry no `defmt::Format`, so the filter's internals don't either; the
//! published [`Estimate`] is plain `f32` arrays and does.

pub mod alignment;
pub mod ekf;
pub mod estimator;
pub mod geo;

pub use estimator::{
    Estimate, Estimator, EstimatorConfig, EstimatorHealth, HeadingSource, HealthReason, Phase,
};
/// The linear algebra the filter's API speaks, for users without their own dependency.
pub use nalgebra;

#[cfg(test)]
mod tests;

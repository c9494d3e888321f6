//! Control: who flies ([`mode`]), what to fly ([`mission`]), and how ([`autopilot`] built of
//! [`pid`] loops, flying on the airspeed of the [`wind`] estimate). The control task (`tasks/control.rs`) ties them to the estimate, the
//! pilot and the parameters.

pub mod autopilot;
pub mod controls;
pub mod mission;
pub mod mission_store;
pub mod mode;
pub mod pid;
pub mod wind;

/// An estimate for the control tests: healthy, running, level rates, at `alt` m above home
/// with horizontal velocity `v_ne`.
#[cfg(test)]
pub(crate) fn test_estimate(
    roll: f32,
    pitch: f32,
    yaw: f32,
    v_ne: [f32; 2],
    alt: f32,
) -> crate::estimation::Estimate {
    use crate::estimation::estimator::{EstimatorHealth, HealthReason, Phase};
    crate::estimation::Estimate {
        t_ns: 0,
        roll_rad: roll,
        pitch_rad: pitch,
        yaw_rad: yaw,
        quaternion: [1.0, 0.0, 0.0, 0.0],
        rates_radps: [0.0; 3],
        velocity_ned_mps: [v_ne[0], v_ne[1], 0.0],
        position_ned_m: [0.0, 0.0, -alt],
        gyro_bias_radps: [0.0; 3],
        accel_bias_mps2: [0.0; 3],
        covariance_diag: [0.0; 15],
        health: EstimatorHealth {
            phase: Phase::Running,
            alignment_percent: 100,
            alignment_restarts: 0,
            healthy: true,
            reason: HealthReason::Ok,
            counters: Default::default(),
            gps_pos_nis: 0.0,
            gps_vel_nis: 0.0,
        },
    }
}

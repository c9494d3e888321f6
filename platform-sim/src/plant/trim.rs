//! Trim for straight, level flight (Beard & McLain ch. 5): the attitude and commands at which
//! all six body accelerations vanish at a given airspeed in calm air.
//!
//! Unknowns: α, φ, δe, δt, δa, δr with zero sideslip and zero flight-path angle; a bank φ is
//! allowed because the propeller torque and the rudder's side force need a little of it to fly
//! straight. Solved by Newton's method with a finite-difference Jacobian.

use super::dynamics::{self, AirMass, ControlInputs, RigidBodyState};
use super::math::{quat_from_euler, quat_to_rotation};
use super::{ActuatorCommands, AircraftParams, InitialState};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trim {
    pub commands: ActuatorCommands,
    pub alpha_rad: f64,
    pub roll_rad: f64,
    pub pitch_rad: f64,
    /// The trimmed state as initial conditions.
    pub initial: InitialState,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TrimError {
    /// Newton's method did not bring the accelerations below tolerance.
    DidNotConverge { residual: f64 },
    /// Trimmed, but a command would be outside its range.
    OutOfRange { commands: ActuatorCommands },
}

const UNKNOWNS: usize = 6;

/// State and inputs for the unknowns `x = [α, φ, δe, δt, δa, δr]`.
fn trimmed_state(
    x: &[f64; UNKNOWNS],
    airspeed_mps: f64,
    altitude_m: f64,
    yaw_rad: f64,
) -> (RigidBodyState, ControlInputs) {
    let [alpha, roll, de, dt, da, dr] = *x;
    // Zero flight-path angle with zero sideslip: tan θ = cos φ · tan α.
    let pitch = (roll.cos() * alpha.tan()).atan();
    let state = RigidBodyState {
        position_ned_m: [0.0, 0.0, -altitude_m],
        velocity_body_mps: [airspeed_mps * alpha.cos(), 0.0, airspeed_mps * alpha.sin()],
        attitude: quat_from_euler(roll, pitch, yaw_rad),
        rates_body_radps: [0.0; 3],
    };
    let u = ControlInputs {
        aileron_rad: da,
        elevator_rad: de,
        rudder_rad: dr,
        throttle: dt,
        brake: 0.0,
        steering_rad: 0.0,
    };
    (state, u)
}

fn residual(
    p: &AircraftParams,
    x: &[f64; UNKNOWNS],
    va: f64,
    alt: f64,
    yaw: f64,
) -> [f64; UNKNOWNS] {
    let (s, u) = trimmed_state(x, va, alt, yaw);
    let (d, _) = dynamics::derivative(p, &s, &u, &AirMass::default(), &[]);
    let [a, b, c] = d.velocity_body_mps;
    let [e, f, g] = d.rates_body_radps;
    [a, b, c, e, f, g]
}

/// Solves `a·x = b` by Gaussian elimination with partial pivoting; None if singular.
fn solve(mut a: [[f64; UNKNOWNS]; UNKNOWNS], mut b: [f64; UNKNOWNS]) -> Option<[f64; UNKNOWNS]> {
    for col in 0..UNKNOWNS {
        let pivot = (col..UNKNOWNS).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() < 1e-12 {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..UNKNOWNS {
            let k = a[row][col] / a[col][col];
            let pivot_row = a[col];
            for (x, p) in a[row].iter_mut().zip(pivot_row).skip(col) {
                *x -= k * p;
            }
            b[row] -= k * b[col];
        }
    }
    let mut x = [0.0; UNKNOWNS];
    for row in (0..UNKNOWNS).rev() {
        let s: f64 = (row + 1..UNKNOWNS).map(|c| a[row][c] * x[c]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    Some(x)
}

/// Trim for straight and level flight at `airspeed_mps`, `altitude_m` above the field,
/// heading `yaw_rad`, in calm air. The result flies without any control input change.
pub fn trim_level_flight(
    p: &AircraftParams,
    airspeed_mps: f64,
    altitude_m: f64,
    yaw_rad: f64,
) -> Result<Trim, TrimError> {
    let mut x = [0.05, 0.0, -0.05, 0.5, 0.0, 0.0];
    let norm = |r: &[f64; UNKNOWNS]| r.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut r = residual(p, &x, airspeed_mps, altitude_m, yaw_rad);
    for _ in 0..50 {
        if norm(&r) < 1e-10 {
            break;
        }
        let mut jac = [[0.0; UNKNOWNS]; UNKNOWNS];
        for j in 0..UNKNOWNS {
            let h = 1e-6;
            let mut xp = x;
            xp[j] += h;
            let rp = residual(p, &xp, airspeed_mps, altitude_m, yaw_rad);
            for i in 0..UNKNOWNS {
                jac[i][j] = (rp[i] - r[i]) / h;
            }
        }
        let neg_r = r.map(|v| -v);
        let Some(step) = solve(jac, neg_r) else {
            return Err(TrimError::DidNotConverge { residual: norm(&r) });
        };
        // Damped: halve the step until the residual falls (Newton can overshoot the stall).
        let mut lambda = 1.0;
        loop {
            let mut xn = x;
            for i in 0..UNKNOWNS {
                xn[i] += lambda * step[i];
            }
            let rn = residual(p, &xn, airspeed_mps, altitude_m, yaw_rad);
            if norm(&rn) < norm(&r) || lambda < 1e-3 {
                x = xn;
                r = rn;
                break;
            }
            lambda *= 0.5;
        }
    }
    let res = norm(&r);
    if res.is_nan() || res > 1e-6 {
        return Err(TrimError::DidNotConverge { residual: res });
    }
    let [alpha, roll, de, dt, da, dr] = x;
    let commands = ActuatorCommands {
        aileron: da / p.max_aileron_rad,
        elevator: -de / p.max_elevator_rad,
        rudder: -dr / p.max_rudder_rad,
        throttle: dt,
        brake: 0.0,
    };
    let in_range = [commands.aileron, commands.elevator, commands.rudder]
        .iter()
        .all(|c| c.abs() <= 1.0)
        && (0.0..=1.0).contains(&commands.throttle);
    if !in_range {
        return Err(TrimError::OutOfRange { commands });
    }
    let (state, _) = trimmed_state(&x, airspeed_mps, altitude_m, yaw_rad);
    let r_nb = quat_to_rotation(state.attitude);
    let v_ned = super::math::mat_vec(&r_nb, state.velocity_body_mps);
    let pitch = (roll.cos() * alpha.tan()).atan();
    Ok(Trim {
        commands,
        alpha_rad: alpha,
        roll_rad: roll,
        pitch_rad: pitch,
        initial: InitialState {
            position_ned_m: state.position_ned_m,
            velocity_ned_mps: v_ned,
            roll_rad: roll,
            pitch_rad: pitch,
            yaw_rad,
            rates_body_radps: [0.0; 3],
        },
    })
}

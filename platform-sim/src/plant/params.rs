//! Airframe parameters: the Aerosonde UAV of Beard & McLain, *Small Unmanned Aircraft*
//! (2nd edition, uavbook `aerosonde_parameters`), plus the things the book leaves out that a
//! take-off roll needs (landing gear) and the mapping from normalised commands to deflections.
//!
//! ## Sign conventions: book vs. ours
//! The book's coefficients fix what a positive deflection does:
//! - `C_m_δe = −0.99`: a positive δe pitches the nose **down**. Our positive elevator command
//!   pitches up, so `δe = −elevator_cmd · max_elevator`.
//! - `C_ℓ_δa = +0.17`: a positive δa rolls right, as our positive aileron command does, so
//!   `δa = +aileron_cmd · max_aileron`.
//! - `C_n_δr = −0.069`: a positive δr yaws **left**. Our positive rudder command yaws right, so
//!   `δr = −rudder_cmd · max_rudder`.
//!
//! The sign tests in `plant/mod.rs` check each of these on the full model.

use std::f64::consts::PI;

/// Standard gravity (m/s²), the value `conventions.md` uses for the IMU at rest.
pub const GRAVITY_MPS2: f64 = 9.80665;

/// Propeller and motor: the 2nd-edition model (Beard & McLain 2nd ed., §4.3), an electric
/// motor driving a propeller whose thrust and torque coefficients are quadratic in the
/// advance ratio `J = 2π·Va / (Ω·D)`. The motor speed Ω is the steady state where motor torque
/// equals propeller torque (eq. 4.22–4.25 of the 2nd edition).
#[derive(Debug, Clone, PartialEq)]
pub struct PropulsionParams {
    /// Propeller diameter (m): 20 in.
    pub prop_diameter_m: f64,
    /// Motor speed constant, as back-EMF per rad/s (V·s/rad); from K_V = 145 rpm/V.
    pub motor_kv_vs_per_rad: f64,
    /// Motor torque constant (N·m/A); equal to K_V in SI units.
    pub motor_kq_nm_per_a: f64,
    /// Motor winding resistance (Ω).
    pub motor_resistance_ohm: f64,
    /// No-load current (A).
    pub motor_no_load_current_a: f64,
    /// Supply voltage at full throttle (V): 12 cells × 3.7 V.
    pub max_voltage_v: f64,
    /// `C_Q(J) = c_q2·J² + c_q1·J + c_q0`.
    pub c_q2: f64,
    pub c_q1: f64,
    pub c_q0: f64,
    /// `C_T(J) = c_t2·J² + c_t1·J + c_t0`.
    pub c_t2: f64,
    pub c_t1: f64,
    pub c_t0: f64,
}

impl PropulsionParams {
    pub fn aerosonde() -> Self {
        let kv_rpm_per_v = 145.0;
        let kv = 60.0 / (2.0 * PI * kv_rpm_per_v);
        Self {
            prop_diameter_m: 20.0 * 0.0254,
            motor_kv_vs_per_rad: kv,
            motor_kq_nm_per_a: kv,
            motor_resistance_ohm: 0.042,
            motor_no_load_current_a: 1.5,
            max_voltage_v: 3.7 * 12.0,
            c_q2: -0.01664,
            c_q1: 0.004970,
            c_q0: 0.005230,
            c_t2: -0.1079,
            c_t1: -0.06044,
            c_t0: 0.09357,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactKind {
    /// Landing gear: meant to touch the ground.
    Wheel,
    /// Any other part of the airframe: touching the ground is a strike (or a crash).
    Skid,
}

/// One point where the airframe can touch the ground: a wheel, a wing tip, the tail.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactPoint {
    pub kind: ContactKind,
    /// Position relative to the centre of gravity, body FRD (m).
    pub position_body_m: [f64; 3],
    /// Vertical spring stiffness (N/m).
    pub stiffness_n_per_m: f64,
    /// Vertical damping (N·s/m).
    pub damping_ns_per_m: f64,
    /// Horizontal spring (N/m) and damper (N·s/m) of static friction (see
    /// `dynamics::ContactAnchors`): how far a tyre flexes before it slides.
    pub tangential_stiffness_n_per_m: f64,
    pub tangential_damping_ns_per_m: f64,
    /// Friction coefficient along the rolling direction (rolling resistance for a wheel).
    pub rolling_friction: f64,
    /// Friction coefficient across the rolling direction (tyre side force, or skid).
    pub side_friction: f64,
    /// Added along-track friction coefficient at full brake (0 for no brake).
    pub brake_friction: f64,
    /// Steered by the rudder command (nose wheel).
    pub steerable: bool,
}

/// Landing gear and other ground contacts. The book's Aerosonde has no gear (it is launched);
/// these are plausible tricycle numbers for an 11 kg airframe so it can sit, roll and land.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundParams {
    pub contacts: Vec<ContactPoint>,
    /// Nose-wheel steering angle at full rudder command (rad); positive command steers right.
    pub max_steering_rad: f64,
}

impl GroundParams {
    pub fn tricycle() -> Self {
        // Each wheel's spring is sized to its share of the static load, so that all three
        // compress the same 1.5 cm and the airplane sits level; damping ratio ≈ 0.7.
        const NOSE_X_M: f64 = 0.60;
        const MAIN_X_M: f64 = -0.12;
        const TOTAL_STIFFNESS_N_PER_M: f64 = 7_200.0;
        const TOTAL_DAMPING_NS_PER_M: f64 = 390.0;
        let nose_share = -MAIN_X_M / (NOSE_X_M - MAIN_X_M);
        let main_share = (1.0 - nose_share) / 2.0;
        let wheel = |x: f64, y: f64, share: f64, steerable: bool, brake: f64| ContactPoint {
            kind: ContactKind::Wheel,
            position_body_m: [x, y, 0.30],
            stiffness_n_per_m: share * TOTAL_STIFFNESS_N_PER_M,
            damping_ns_per_m: share * TOTAL_DAMPING_NS_PER_M,
            tangential_stiffness_n_per_m: share * TOTAL_STIFFNESS_N_PER_M,
            tangential_damping_ns_per_m: share * TOTAL_DAMPING_NS_PER_M,
            rolling_friction: 0.03,
            side_friction: 0.8,
            brake_friction: brake,
            steerable,
        };
        // Wing tips, tail and nose: high-friction skids, touching only in a crash, a tail
        // strike or a hard wing-low landing; they keep the airframe out of the ground whatever
        // happens. No stiffer than this: a wing-tip spring acts on the small roll inertia
        // through a 1.45 m arm, and stiffer springs or dampers make RK4 at the coarsest
        // allowed step (10 ms) unstable in a crash.
        let skid = |x: f64, y: f64, z: f64| ContactPoint {
            kind: ContactKind::Skid,
            position_body_m: [x, y, z],
            stiffness_n_per_m: 8_000.0,
            damping_ns_per_m: 200.0,
            tangential_stiffness_n_per_m: 4_000.0,
            tangential_damping_ns_per_m: 100.0,
            rolling_friction: 0.6,
            side_friction: 0.6,
            brake_friction: 0.0,
            steerable: false,
        };
        Self {
            contacts: vec![
                wheel(NOSE_X_M, 0.0, nose_share, true, 0.0),
                wheel(MAIN_X_M, -0.45, main_share, false, 0.5),
                wheel(MAIN_X_M, 0.45, main_share, false, 0.5),
                skid(-0.10, -1.45, 0.0),
                skid(-0.10, 1.45, 0.0),
                skid(-1.20, 0.0, 0.05),
                skid(0.75, 0.0, 0.05),
            ],
            max_steering_rad: 20f64.to_radians(),
        }
    }

    /// Height of the CG above flat ground when the airplane rests level on its wheels (m):
    /// the wheel offset less the static spring deflection.
    pub fn rest_height_m(&self, mass_kg: f64) -> f64 {
        let wheels: Vec<&ContactPoint> = self
            .contacts
            .iter()
            .filter(|c| c.kind == ContactKind::Wheel)
            .collect();
        let stiffness: f64 = wheels.iter().map(|c| c.stiffness_n_per_m).sum();
        let depth = wheels
            .iter()
            .map(|c| c.position_body_m[2])
            .fold(0.0, f64::max);
        if stiffness > 0.0 {
            depth - mass_kg * GRAVITY_MPS2 / stiffness
        } else {
            depth
        }
    }
}

/// The full parameter set. Coefficient names follow the book: `c_l_*` lift, `c_d_*` drag,
/// `c_m_*` pitching moment, `c_y_*` side force, `c_ell_*` rolling moment, `c_n_*` yawing moment.
#[derive(Debug, Clone, PartialEq)]
pub struct AircraftParams {
    pub mass_kg: f64,
    /// Inertia about body axes (kg·m²); `jxz` is the product of inertia (xz symmetry plane).
    pub jx: f64,
    pub jy: f64,
    pub jz: f64,
    pub jxz: f64,
    pub wing_area_m2: f64,
    pub wingspan_m: f64,
    pub chord_m: f64,
    /// Air density (kg/m³), the book's value.
    pub air_density_kgpm3: f64,
    /// Oswald efficiency factor.
    pub oswald_e: f64,

    pub c_l_0: f64,
    pub c_d_0: f64,
    pub c_m_0: f64,
    pub c_l_alpha: f64,
    pub c_d_alpha: f64,
    pub c_m_alpha: f64,
    pub c_l_q: f64,
    pub c_d_q: f64,
    pub c_m_q: f64,
    pub c_l_delta_e: f64,
    pub c_d_delta_e: f64,
    pub c_m_delta_e: f64,
    /// Steepness of the stall sigmoid (eq. 4.10).
    pub stall_sigmoid_m: f64,
    /// Stall angle of attack where the blend is half-way (rad).
    pub stall_alpha0_rad: f64,
    pub epsilon: f64,
    pub c_d_p: f64,

    pub c_y_0: f64,
    pub c_ell_0: f64,
    pub c_n_0: f64,
    pub c_y_beta: f64,
    pub c_ell_beta: f64,
    pub c_n_beta: f64,
    pub c_y_p: f64,
    pub c_ell_p: f64,
    pub c_n_p: f64,
    pub c_y_r: f64,
    pub c_ell_r: f64,
    pub c_n_r: f64,
    pub c_y_delta_a: f64,
    pub c_ell_delta_a: f64,
    pub c_n_delta_a: f64,
    pub c_y_delta_r: f64,
    pub c_ell_delta_r: f64,
    pub c_n_delta_r: f64,

    /// Surface deflection at a normalised command of ±1 (rad).
    pub max_aileron_rad: f64,
    pub max_elevator_rad: f64,
    pub max_rudder_rad: f64,

    pub propulsion: PropulsionParams,
    pub ground: GroundParams,
}

impl AircraftParams {
    /// The Aerosonde of Beard & McLain (2nd edition values, mass 11 kg as the issue states).
    pub fn aerosonde() -> Self {
        Self {
            mass_kg: 11.0,
            jx: 0.824,
            jy: 1.135,
            jz: 1.759,
            jxz: 0.120,
            wing_area_m2: 0.55,
            wingspan_m: 2.9,
            chord_m: 0.19,
            air_density_kgpm3: 1.2682,
            oswald_e: 0.9,

            c_l_0: 0.23,
            c_d_0: 0.043,
            c_m_0: 0.0135,
            c_l_alpha: 5.61,
            c_d_alpha: 0.03,
            c_m_alpha: -2.74,
            c_l_q: 7.95,
            c_d_q: 0.0,
            c_m_q: -38.21,
            c_l_delta_e: 0.13,
            c_d_delta_e: 0.0135,
            c_m_delta_e: -0.99,
            stall_sigmoid_m: 50.0,
            stall_alpha0_rad: 0.47,
            epsilon: 0.16,
            c_d_p: 0.0,

            c_y_0: 0.0,
            c_ell_0: 0.0,
            c_n_0: 0.0,
            c_y_beta: -0.98,
            c_ell_beta: -0.13,
            c_n_beta: 0.073,
            c_y_p: 0.0,
            c_ell_p: -0.51,
            c_n_p: -0.069,
            c_y_r: 0.0,
            c_ell_r: 0.25,
            c_n_r: -0.095,
            c_y_delta_a: 0.075,
            c_ell_delta_a: 0.17,
            c_n_delta_a: -0.011,
            c_y_delta_r: 0.19,
            c_ell_delta_r: 0.0024,
            c_n_delta_r: -0.069,

            max_aileron_rad: 25f64.to_radians(),
            max_elevator_rad: 25f64.to_radians(),
            max_rudder_rad: 25f64.to_radians(),

            propulsion: PropulsionParams::aerosonde(),
            ground: GroundParams::tricycle(),
        }
    }

    pub fn aspect_ratio(&self) -> f64 {
        self.wingspan_m * self.wingspan_m / self.wing_area_m2
    }

    /// The Γ constants of the rotational equations (Beard & McLain eq. 3.13).
    pub fn gammas(&self) -> [f64; 8] {
        let (jx, jy, jz, jxz) = (self.jx, self.jy, self.jz, self.jxz);
        let g = jx * jz - jxz * jxz;
        [
            jxz * (jx - jy + jz) / g,
            (jz * (jz - jy) + jxz * jxz) / g,
            jz / g,
            jxz / g,
            (jz - jx) / jy,
            jxz / jy,
            ((jx - jy) * jx + jxz * jxz) / g,
            jx / g,
        ]
    }
}

impl Default for AircraftParams {
    fn default() -> Self {
        Self::aerosonde()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aerosonde_geometry() {
        let p = AircraftParams::aerosonde();
        assert!((p.aspect_ratio() - 2.9 * 2.9 / 0.55).abs() < 1e-12);
        assert_eq!(p.mass_kg, 11.0);
        // The rest height is below the wheel offset by the static deflection.
        let h = p.ground.rest_height_m(p.mass_kg);
        assert!(h > 0.25 && h < 0.30, "{h}");
    }
}

//! Six-degree-of-freedom rigid-body dynamics of the airplane (Beard & McLain ch. 3 and 4).
//!
//! State (13): position NED, velocity in body axes (u, v, w), attitude quaternion body→NED,
//! body rates (p, q, r). The quaternion form (book appendix B) has no gimbal lock, so loops
//! and tumbles after a stall integrate as well as level flight.
//!
//! Forces: gravity, aerodynamics (ch. 4, with the post-stall lift blend of eq. 4.9–4.10),
//! the propeller (2nd-edition motor/propeller model, §4.3), and ground contact (a
//! spring–damper with friction at each landing-gear wheel and skid point; not in the book).

use super::math::{
    Mat3, Quat, Vec3, add, cross, mat_t_vec, mat_vec, norm, quat_derivative, quat_normalize,
    quat_to_rotation, scale, sub,
};
use super::params::{AircraftParams, ContactKind, ContactPoint, GRAVITY_MPS2};

/// The integrated state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidBodyState {
    pub position_ned_m: Vec3,
    /// (u, v, w): velocity of the CG relative to the ground, in body axes.
    pub velocity_body_mps: Vec3,
    /// Hamilton, scalar first, rotating body vectors into NED.
    pub attitude: Quat,
    /// (p, q, r).
    pub rates_body_radps: Vec3,
}

impl RigidBodyState {
    /// `self + h · d`, where `d` holds time derivatives in the same layout.
    fn add_scaled(&self, d: &RigidBodyState, h: f64) -> RigidBodyState {
        let a = self.attitude;
        let da = d.attitude;
        RigidBodyState {
            position_ned_m: add(self.position_ned_m, scale(d.position_ned_m, h)),
            velocity_body_mps: add(self.velocity_body_mps, scale(d.velocity_body_mps, h)),
            attitude: [
                a[0] + h * da[0],
                a[1] + h * da[1],
                a[2] + h * da[2],
                a[3] + h * da[3],
            ],
            rates_body_radps: add(self.rates_body_radps, scale(d.rates_body_radps, h)),
        }
    }

    pub fn is_finite(&self) -> bool {
        self.position_ned_m
            .iter()
            .chain(&self.velocity_body_mps)
            .chain(&self.attitude)
            .chain(&self.rates_body_radps)
            .all(|x| x.is_finite())
    }
}

/// Control inputs in the book's conventions (radians, book signs), made from the normalised
/// commands by [`ControlInputs::from_commands`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ControlInputs {
    /// δa (rad): positive rolls right (C_ℓ_δa > 0).
    pub aileron_rad: f64,
    /// δe (rad): positive pitches the nose down (C_m_δe < 0).
    pub elevator_rad: f64,
    /// δr (rad): positive yaws left (C_n_δr < 0).
    pub rudder_rad: f64,
    /// δt in [0, 1].
    pub throttle: f64,
    /// Wheel brake in [0, 1].
    pub brake: f64,
    /// Nose-wheel steering (rad), positive turns right.
    pub steering_rad: f64,
}

impl ControlInputs {
    /// Normalised commands (our conventions) to deflections (book conventions). Commands are
    /// clamped to their ranges; a non-finite command counts as neutral so that a bad value
    /// upstream can never poison the integrator.
    pub fn from_commands(
        p: &AircraftParams,
        aileron: f64,
        elevator: f64,
        rudder: f64,
        throttle: f64,
        brake: f64,
    ) -> Self {
        let c = super::ActuatorCommands {
            aileron,
            elevator,
            rudder,
            throttle,
            brake,
        }
        .sanitized();
        Self {
            aileron_rad: c.aileron * p.max_aileron_rad,
            elevator_rad: -c.elevator * p.max_elevator_rad,
            rudder_rad: -c.rudder * p.max_rudder_rad,
            throttle: c.throttle,
            brake: c.brake,
            steering_rad: c.rudder * p.ground.max_steering_rad,
        }
    }
}

/// The air the airplane flies in at this instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AirMass {
    pub steady_wind_ned_mps: Vec3,
    pub gust_body_mps: Vec3,
}

/// Airspeed vector and the aerodynamic angles.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AirData {
    /// Velocity relative to the air, body axes (m/s).
    pub relative_velocity_body_mps: Vec3,
    pub airspeed_mps: f64,
    pub alpha_rad: f64,
    pub beta_rad: f64,
}

/// Motor and propeller operating point.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PropulsionOutput {
    pub thrust_n: f64,
    /// Torque the air exerts on the propeller (N·m); the airframe feels −this about body x.
    pub prop_torque_nm: f64,
    pub motor_speed_radps: f64,
    /// Motor current (A); negative while the windmilling propeller drives the motor.
    pub motor_current_a: f64,
}

/// Everything the force model computes for one state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ForcesAndMoments {
    /// Sum of non-gravitational forces, body axes (N): what an accelerometer senses × mass.
    pub contact_and_aero_force_body_n: Vec3,
    /// Total moment about the CG, body axes (N·m).
    pub moment_body_nm: Vec3,
    pub air: AirData,
    pub propulsion: PropulsionOutput,
    /// Sum of ground normal forces (N); > 0 means some point touches the ground.
    pub ground_normal_force_n: f64,
    /// Whether a landing-gear wheel touches the ground.
    pub wheels_on_ground: bool,
    /// Whether another part of the airframe (wing tip, tail, nose) touches the ground.
    pub airframe_on_ground: bool,
}

/// What the ground does to the airplane.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct GroundReaction {
    force_body_n: Vec3,
    moment_body_nm: Vec3,
    normal_force_n: f64,
    wheels: bool,
    airframe: bool,
}

/// Airspeed and the angles of attack and sideslip (Beard & McLain eq. 2.8 and 4.x).
pub fn air_data(state: &RigidBodyState, air: &AirMass) -> AirData {
    let r_nb = quat_to_rotation(state.attitude);
    let wind_body = add(mat_t_vec(&r_nb, air.steady_wind_ned_mps), air.gust_body_mps);
    let vr = sub(state.velocity_body_mps, wind_body);
    let va = norm(vr);
    // Below a millimetre per second the angles are meaningless; zero keeps them defined.
    let (alpha, beta) = if va > 1e-3 {
        (vr[2].atan2(vr[0]), (vr[1] / va).clamp(-1.0, 1.0).asin())
    } else {
        (0.0, 0.0)
    };
    AirData {
        relative_velocity_body_mps: vr,
        airspeed_mps: va,
        alpha_rad: alpha,
        beta_rad: beta,
    }
}

/// The stall blending function σ(α) of eq. 4.10: ≈0 in attached flow, ≈1 past ±α0.
pub fn stall_blend(p: &AircraftParams, alpha: f64) -> f64 {
    let m = p.stall_sigmoid_m;
    let a0 = p.stall_alpha0_rad;
    // exp(M·(|α|+α0)) ≤ exp(50·(π+0.47)) ≈ 1e78: far from overflow for |α| ≤ π.
    let e_minus = (-m * (alpha - a0)).exp();
    let e_plus = (m * (alpha + a0)).exp();
    (1.0 + e_minus + e_plus) / ((1.0 + e_minus) * (1.0 + e_plus))
}

/// Lift coefficient with the post-stall blend to a flat plate (eq. 4.9).
pub fn lift_coefficient(p: &AircraftParams, alpha: f64) -> f64 {
    lift_blended(p, alpha, stall_blend(p, alpha))
}

fn lift_blended(p: &AircraftParams, alpha: f64, sigma: f64) -> f64 {
    let linear = p.c_l_0 + p.c_l_alpha * alpha;
    let (s, c) = alpha.sin_cos();
    let flat_plate = 2.0 * alpha.signum() * s * s * c;
    (1.0 - sigma) * linear + sigma * flat_plate
}

/// Drag coefficient: the book's linear model `C_D0 + C_Dα·α` (§4.2.1) in attached flow,
/// blended with the same σ(α) to flat-plate drag `C_D0 + 2 sin²α` past the stall, so that
/// drag stays positive and grows as the wing goes broadside to the flow. `C_D_p` is added as
/// the book's parasitic term (zero for the Aerosonde).
pub fn drag_coefficient(p: &AircraftParams, alpha: f64) -> f64 {
    drag_blended(p, alpha, stall_blend(p, alpha))
}

fn drag_blended(p: &AircraftParams, alpha: f64, sigma: f64) -> f64 {
    let linear = p.c_d_0 + p.c_d_alpha * alpha;
    let s = alpha.sin();
    let flat_plate = p.c_d_0 + 2.0 * s * s;
    p.c_d_p + (1.0 - sigma) * linear + sigma * flat_plate
}

/// Pitching-moment coefficient against α: the book's linear `C_m0 + C_mα·α` in attached
/// flow, blended with the same σ(α) to `C_mα·sin α` past the stall. The linear law alone
/// would jump from −8.6 to +8.6 when the air comes from behind and α wraps from +π to −π (a
/// parked airplane in a tailwind would shake on its nose wheel); `sin α` is continuous there
/// and still pitches the nose into the wind.
pub fn pitching_moment_coefficient(p: &AircraftParams, alpha: f64) -> f64 {
    pitching_moment_blended(p, alpha, stall_blend(p, alpha))
}

fn pitching_moment_blended(p: &AircraftParams, alpha: f64, sigma: f64) -> f64 {
    (1.0 - sigma) * (p.c_m_0 + p.c_m_alpha * alpha) + sigma * p.c_m_alpha * alpha.sin()
}

/// Motor speed, thrust and torque (Beard & McLain 2nd ed. §4.3): the motor speed solves
/// `a Ω² + b Ω + c = 0` (motor torque = propeller torque), then
/// `T = ρ n² D⁴ C_T(J)`, `Q = ρ n² D⁵ C_Q(J)` with `n = Ω/2π`, `J = Va/(n D)`. Expanded so
/// that nothing divides by Ω: `n² J² = Va²/D²`.
pub fn propulsion(p: &AircraftParams, airspeed_mps: f64, throttle: f64) -> PropulsionOutput {
    let m = &p.propulsion;
    let rho = p.air_density_kgpm3;
    let d = m.prop_diameter_m;
    let va = airspeed_mps;
    let two_pi = 2.0 * std::f64::consts::PI;
    let v_in = m.max_voltage_v * throttle;
    let r = m.motor_resistance_ohm;

    let a = m.c_q0 * rho * d.powi(5) / (two_pi * two_pi);
    let b =
        m.c_q1 * rho * d.powi(4) * va / two_pi + m.motor_kq_nm_per_a * m.motor_kv_vs_per_rad / r;
    let c = m.c_q2 * rho * d.powi(3) * va * va - m.motor_kq_nm_per_a * v_in / r
        + m.motor_kq_nm_per_a * m.motor_no_load_current_a;
    // A negative root would mean the motor cannot overcome its own friction: it stands still
    // (the book's formula would spin it backwards and still produce forward thrust).
    let discriminant = (b * b - 4.0 * a * c).max(0.0);
    let omega = ((-b + discriminant.sqrt()) / (2.0 * a)).max(0.0);
    let n = omega / two_pi;

    let thrust =
        rho * (m.c_t0 * d.powi(4) * n * n + m.c_t1 * d.powi(3) * va * n + m.c_t2 * d * d * va * va);
    let torque = rho
        * (m.c_q0 * d.powi(5) * n * n + m.c_q1 * d.powi(4) * va * n + m.c_q2 * d.powi(3) * va * va);
    let current = (v_in - m.motor_kv_vs_per_rad * omega) / r;
    PropulsionOutput {
        thrust_n: thrust,
        prop_torque_nm: torque,
        motor_speed_radps: omega,
        motor_current_a: current,
    }
}

/// Aerodynamic force and moment, body axes (Beard & McLain eq. 4.18–4.20). The rate terms
/// `C·(c q / 2Va)` are multiplied out by `½ρVa²S` so that nothing divides by Va at rest.
fn aerodynamics(
    p: &AircraftParams,
    state: &RigidBodyState,
    u: &ControlInputs,
    air: &AirData,
) -> (Vec3, Vec3) {
    let va = air.airspeed_mps;
    let alpha = air.alpha_rad;
    let beta = air.beta_rad;
    let [pr, qr, rr] = state.rates_body_radps;
    // One σ(α) for lift, drag and moment: its exponentials are the costliest part here.
    let sigma = stall_blend(p, alpha);
    let half_rho_s = 0.5 * p.air_density_kgpm3 * p.wing_area_m2;
    let qbar_s = half_rho_s * va * va;
    // ½ρS·Va²·(c q/2Va) = ½ρS·Va·c·q/2, and likewise with b for p and r.
    let q_term = half_rho_s * va * p.chord_m * qr / 2.0;
    let p_term = half_rho_s * va * p.wingspan_m * pr / 2.0;
    let r_term = half_rho_s * va * p.wingspan_m * rr / 2.0;

    let lift = qbar_s * (lift_blended(p, alpha, sigma) + p.c_l_delta_e * u.elevator_rad)
        + p.c_l_q * q_term;
    // The book writes C_D_δe·δe; |δe| makes a deflected elevator add drag either way rather
    // than give free thrust at up-elevator.
    let drag = qbar_s * (drag_blended(p, alpha, sigma) + p.c_d_delta_e * u.elevator_rad.abs())
        + p.c_d_q * q_term;
    let (sa, ca) = alpha.sin_cos();
    let fx = -drag * ca + lift * sa;
    let fz = -drag * sa - lift * ca;
    let fy = qbar_s
        * (p.c_y_0
            + p.c_y_beta * beta
            + p.c_y_delta_a * u.aileron_rad
            + p.c_y_delta_r * u.rudder_rad)
        + p.c_y_p * p_term
        + p.c_y_r * r_term;

    let b = p.wingspan_m;
    let roll = qbar_s
        * b
        * (p.c_ell_0
            + p.c_ell_beta * beta
            + p.c_ell_delta_a * u.aileron_rad
            + p.c_ell_delta_r * u.rudder_rad)
        + b * (p.c_ell_p * p_term + p.c_ell_r * r_term);
    let pitch = qbar_s
        * p.chord_m
        * (pitching_moment_blended(p, alpha, sigma) + p.c_m_delta_e * u.elevator_rad)
        + p.chord_m * p.c_m_q * q_term;
    let yaw = qbar_s
        * b
        * (p.c_n_0
            + p.c_n_beta * beta
            + p.c_n_delta_a * u.aileron_rad
            + p.c_n_delta_r * u.rudder_rad)
        + b * (p.c_n_p * p_term + p.c_n_r * r_term);
    ([fx, fy, fz], [roll, pitch, yaw])
}

/// Where each contact point is stuck to the ground, NED (north, east) in metres, by index in
/// `GroundParams::contacts`; `None` while it does not touch. Friction is a stiff spring to this
/// anchor, limited to μN, and the anchor slides when the limit is reached (elasto-plastic
/// friction): a parked airplane is held by static friction instead of creeping, and a rolling
/// or skidding one feels Coulomb friction. The plant moves the anchors after each step with
/// [`update_contact_anchors`]; an empty slice means "anchored where it stands".
pub type ContactAnchors = Vec<Option<[f64; 2]>>;

/// One touching contact point, in NED.
struct ContactGeometry {
    point_ned: Vec3,
    velocity_ned: Vec3,
    normal_n: f64,
    /// Unit ground vectors along and across the rolling direction.
    along: [f64; 2],
    across: [f64; 2],
}

fn contact_geometry(
    c: &ContactPoint,
    state: &RigidBodyState,
    r_nb: &Mat3,
    steering_rad: f64,
) -> Option<ContactGeometry> {
    let r = c.position_body_m;
    let point_ned = add(state.position_ned_m, mat_vec(r_nb, r));
    let depth = point_ned[2];
    if depth <= 0.0 {
        return None;
    }
    let velocity_ned = mat_vec(
        r_nb,
        add(state.velocity_body_mps, cross(state.rates_body_radps, r)),
    );
    // A spring–damper that only pushes: the ground never pulls the airplane down, so it
    // leaves the ground cleanly instead of sticking (and the damping cannot fling it up).
    let normal_n = (c.stiffness_n_per_m * depth + c.damping_ns_per_m * velocity_ned[2]).max(0.0);
    if normal_n == 0.0 {
        return None;
    }
    // Rolling direction: the wheel's heading projected on the ground.
    let steer = if c.steerable { steering_rad } else { 0.0 };
    let h = mat_vec(r_nb, [steer.cos(), steer.sin(), 0.0]);
    let h_len = h[0].hypot(h[1]);
    // A point whose heading is near vertical (nose-down crash) skids with no preferred
    // direction: any orthonormal pair of ground axes will do.
    let along = if h_len > 1e-3 {
        [h[0] / h_len, h[1] / h_len]
    } else {
        [1.0, 0.0]
    };
    Some(ContactGeometry {
        point_ned,
        velocity_ned,
        normal_n,
        along,
        across: [-along[1], along[0]],
    })
}

/// Friction limits (N) along and across the rolling direction.
fn friction_limits(c: &ContactPoint, normal_n: f64, brake: f64) -> (f64, f64) {
    (
        (c.rolling_friction + brake * c.brake_friction) * normal_n,
        c.side_friction * normal_n,
    )
}

fn dot2(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// Ground reaction at every contact point below the ground plane (NED z = 0, flat).
fn ground_contact(
    p: &AircraftParams,
    state: &RigidBodyState,
    u: &ControlInputs,
    anchors: &[Option<[f64; 2]>],
) -> GroundReaction {
    let r_nb = quat_to_rotation(state.attitude);
    let mut reaction = GroundReaction::default();
    for (i, c) in p.ground.contacts.iter().enumerate() {
        let Some(g) = contact_geometry(c, state, &r_nb, u.steering_rad) else {
            continue;
        };
        reaction.normal_force_n += g.normal_n;
        match c.kind {
            ContactKind::Wheel => reaction.wheels = true,
            ContactKind::Skid => reaction.airframe = true,
        }
        let here = [g.point_ned[0], g.point_ned[1]];
        let anchor = anchors.get(i).copied().flatten().unwrap_or(here);
        let stretch = [here[0] - anchor[0], here[1] - anchor[1]];
        let v = [g.velocity_ned[0], g.velocity_ned[1]];
        let (limit_along, limit_across) = friction_limits(c, g.normal_n, u.brake);
        let k = c.tangential_stiffness_n_per_m;
        let d = c.tangential_damping_ns_per_m;
        let f_along =
            (-k * dot2(stretch, g.along) - d * dot2(v, g.along)).clamp(-limit_along, limit_along);
        let f_across = (-k * dot2(stretch, g.across) - d * dot2(v, g.across))
            .clamp(-limit_across, limit_across);
        let f_ned = [
            f_along * g.along[0] + f_across * g.across[0],
            f_along * g.along[1] + f_across * g.across[1],
            -g.normal_n,
        ];
        let f_body = mat_t_vec(&r_nb, f_ned);
        reaction.force_body_n = add(reaction.force_body_n, f_body);
        reaction.moment_body_nm = add(reaction.moment_body_nm, cross(c.position_body_m, f_body));
    }
    reaction
}

/// Moves the friction anchors after a step: a point that touches keeps its anchor unless the
/// spring to it would pull harder than friction allows, in which case the anchor is dragged
/// along (the point slides); a point that does not touch has none.
pub fn update_contact_anchors(
    p: &AircraftParams,
    state: &RigidBodyState,
    u: &ControlInputs,
    anchors: &mut ContactAnchors,
) {
    let contacts = &p.ground.contacts;
    anchors.resize(contacts.len(), None);
    let r_nb = quat_to_rotation(state.attitude);
    for (c, anchor) in contacts.iter().zip(anchors.iter_mut()) {
        let Some(g) = contact_geometry(c, state, &r_nb, u.steering_rad) else {
            *anchor = None;
            continue;
        };
        let here = [g.point_ned[0], g.point_ned[1]];
        let a = anchor.unwrap_or(here);
        let stretch = [here[0] - a[0], here[1] - a[1]];
        let (limit_along, limit_across) = friction_limits(c, g.normal_n, u.brake);
        let k = c.tangential_stiffness_n_per_m.max(1e-9);
        let s_along = dot2(stretch, g.along).clamp(-limit_along / k, limit_along / k);
        let s_across = dot2(stretch, g.across).clamp(-limit_across / k, limit_across / k);
        *anchor = Some([
            here[0] - s_along * g.along[0] - s_across * g.across[0],
            here[1] - s_along * g.along[1] - s_across * g.across[1],
        ]);
    }
}

/// All forces except gravity, and all moments, at one state.
pub fn forces_and_moments(
    p: &AircraftParams,
    state: &RigidBodyState,
    u: &ControlInputs,
    air_mass: &AirMass,
    anchors: &[Option<[f64; 2]>],
) -> ForcesAndMoments {
    let air = air_data(state, air_mass);
    let (f_aero, m_aero) = aerodynamics(p, state, u, &air);
    let prop = propulsion(p, air.airspeed_mps, u.throttle);
    let ground = ground_contact(p, state, u, anchors);
    // Thrust along body x through the CG; the propeller (turning clockwise seen from behind)
    // twists the airframe the other way: −Q about x (book eq. 4.25).
    let force = add(add(f_aero, [prop.thrust_n, 0.0, 0.0]), ground.force_body_n);
    let moment = add(
        add(m_aero, [-prop.prop_torque_nm, 0.0, 0.0]),
        ground.moment_body_nm,
    );
    ForcesAndMoments {
        contact_and_aero_force_body_n: force,
        moment_body_nm: moment,
        air,
        propulsion: prop,
        ground_normal_force_n: ground.normal_force_n,
        wheels_on_ground: ground.wheels,
        airframe_on_ground: ground.airframe,
    }
}

/// The state derivative (Beard & McLain eq. 3.14–3.17, with the quaternion kinematics of
/// appendix B), and the forces that produced it.
pub fn derivative(
    p: &AircraftParams,
    state: &RigidBodyState,
    u: &ControlInputs,
    air_mass: &AirMass,
    anchors: &[Option<[f64; 2]>],
) -> (RigidBodyState, ForcesAndMoments) {
    let fm = forces_and_moments(p, state, u, air_mass, anchors);
    let r_nb = quat_to_rotation(state.attitude);
    let gravity_body = mat_t_vec(&r_nb, [0.0, 0.0, p.mass_kg * GRAVITY_MPS2]);
    let force = add(fm.contact_and_aero_force_body_n, gravity_body);
    let v = state.velocity_body_mps;
    let omega = state.rates_body_radps;
    // v̇ = −ω × v + F/m
    let v_dot = add(scale(cross(omega, v), -1.0), scale(force, 1.0 / p.mass_kg));
    let [g1, g2, g3, g4, g5, g6, g7, g8] = p.gammas();
    let [pr, qr, rr] = omega;
    let [l, m, n] = fm.moment_body_nm;
    let omega_dot = [
        g1 * pr * qr - g2 * qr * rr + g3 * l + g4 * n,
        g5 * pr * rr - g6 * (pr * pr - rr * rr) + m / p.jy,
        g7 * pr * qr - g1 * qr * rr + g4 * l + g8 * n,
    ];
    let d = RigidBodyState {
        position_ned_m: mat_vec(&r_nb, v),
        velocity_body_mps: v_dot,
        attitude: quat_derivative(state.attitude, omega),
        rates_body_radps: omega_dot,
    };
    (d, fm)
}

/// One classical fourth-order Runge–Kutta step of `dt_s`, inputs and air mass held constant;
/// the quaternion is renormalised afterwards.
pub fn rk4_step(
    p: &AircraftParams,
    state: &RigidBodyState,
    u: &ControlInputs,
    air_mass: &AirMass,
    anchors: &[Option<[f64; 2]>],
    dt_s: f64,
) -> RigidBodyState {
    let (k1, _) = derivative(p, state, u, air_mass, anchors);
    let (k2, _) = derivative(p, &state.add_scaled(&k1, dt_s / 2.0), u, air_mass, anchors);
    let (k3, _) = derivative(p, &state.add_scaled(&k2, dt_s / 2.0), u, air_mass, anchors);
    let (k4, _) = derivative(p, &state.add_scaled(&k3, dt_s), u, air_mass, anchors);
    let mut next = *state;
    next = next.add_scaled(&k1, dt_s / 6.0);
    next = next.add_scaled(&k2, dt_s / 3.0);
    next = next.add_scaled(&k3, dt_s / 3.0);
    next = next.add_scaled(&k4, dt_s / 6.0);
    next.attitude = quat_normalize(next.attitude);
    next
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lift_drops_past_the_stall() {
        let p = AircraftParams::aerosonde();
        let below = lift_coefficient(&p, 0.35);
        let peak = (0..100)
            .map(|i| lift_coefficient(&p, i as f64 * 0.01))
            .fold(f64::MIN, f64::max);
        let above = lift_coefficient(&p, 0.6);
        // Linear below the stall, then a sharp drop to the flat-plate value (≈ 0.54 at 0.6 rad).
        assert!(
            (below - (p.c_l_0 + p.c_l_alpha * 0.35)).abs() < 0.01,
            "{below}"
        );
        assert!(above < 0.6 * peak, "peak {peak}, post-stall {above}");
        assert!(drag_coefficient(&p, 0.6) > 3.0 * drag_coefficient(&p, 0.1));
        // Symmetric behaviour at negative stall, and drag positive everywhere.
        assert!(lift_coefficient(&p, -0.8) < 0.0);
        for i in -314..=314 {
            assert!(drag_coefficient(&p, i as f64 * 0.01) > 0.0);
        }
    }

    #[test]
    fn pitching_moment_is_linear_in_attached_flow_and_continuous_in_reverse_flow() {
        let p = AircraftParams::aerosonde();
        let at = |a: f64| pitching_moment_coefficient(&p, a);
        assert!((at(0.1) - (p.c_m_0 + p.c_m_alpha * 0.1)).abs() < 1e-6);
        assert!((at(std::f64::consts::PI - 1e-9) - at(-std::f64::consts::PI + 1e-9)).abs() < 1e-6);
        // Stable everywhere that matters: nose-down past the stall, nose-up below −stall.
        assert!(at(1.0) < 0.0 && at(-1.0) > 0.0);
    }

    #[test]
    fn propeller_is_still_at_zero_throttle_and_pushes_at_full() {
        let p = AircraftParams::aerosonde();
        let idle = propulsion(&p, 0.0, 0.0);
        assert_eq!(idle.thrust_n, 0.0);
        assert_eq!(idle.motor_speed_radps, 0.0);
        let full = propulsion(&p, 0.0, 1.0);
        // Static thrust of the 2nd-edition motor model is ≈ 84 N, below the 108 N weight.
        assert!(full.thrust_n > 70.0 && full.thrust_n < 100.0, "{full:?}");
        assert!(full.prop_torque_nm > 0.0);
        assert!(full.motor_current_a > 0.0);
        // Thrust falls with airspeed.
        assert!(propulsion(&p, 25.0, 1.0).thrust_n < full.thrust_n);
    }
}

//! Small fixed-size vector and quaternion helpers on plain `f64` arrays.
//!
//! The plant needs only 3-vectors, 3×3 rotations and unit quaternions; plain arrays keep it
//! dependency-free and fast to build. Frames follow `conventions.md`: NED world, FRD body,
//! Hamilton quaternions scalar first `[w, x, y, z]` rotating body vectors into NED.

pub type Vec3 = [f64; 3];
/// Hamilton quaternion, scalar first: `[w, x, y, z]`.
pub type Quat = [f64; 4];
/// Row-major 3×3 matrix.
pub type Mat3 = [[f64; 3]; 3];

pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn scale(a: Vec3, k: f64) -> Vec3 {
    [a[0] * k, a[1] * k, a[2] * k]
}

pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

pub fn mat_vec(m: &Mat3, v: Vec3) -> Vec3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// `mᵀ v`: for a rotation, the inverse rotation.
pub fn mat_t_vec(m: &Mat3, v: Vec3) -> Vec3 {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

/// `R_nb`: the rotation that turns body (FRD) vectors into NED, from a unit quaternion.
pub fn quat_to_rotation(q: Quat) -> Mat3 {
    let [w, x, y, z] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Unit quaternion from 3-2-1 Euler angles (roll φ, pitch θ, yaw ψ), so that
/// `R_nb = Rz(ψ)·Ry(θ)·Rx(φ)` (Beard & McLain, appendix B).
pub fn quat_from_euler(roll: f64, pitch: f64, yaw: f64) -> Quat {
    let (sr, cr) = (roll * 0.5).sin_cos();
    let (sp, cp) = (pitch * 0.5).sin_cos();
    let (sy, cy) = (yaw * 0.5).sin_cos();
    [
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ]
}

/// 3-2-1 Euler angles `[roll, pitch, yaw]` (rad) of a unit quaternion; yaw in (−π, π].
pub fn quat_to_euler(q: Quat) -> Vec3 {
    let [w, x, y, z] = q;
    let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
    // Clamped: rounding can push the argument a hair past ±1 at ±90° pitch.
    let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    [roll, pitch, yaw]
}

/// `q̇ = ½ q ⊗ (0, ω)` for body rates ω (Beard & McLain eq. 3.x, quaternion form, appendix B).
pub fn quat_derivative(q: Quat, omega: Vec3) -> Quat {
    let [w, x, y, z] = q;
    let [p, qr, r] = omega;
    [
        0.5 * (-x * p - y * qr - z * r),
        0.5 * (w * p + y * r - z * qr),
        0.5 * (w * qr - x * r + z * p),
        0.5 * (w * r + x * qr - y * p),
    ]
}

/// The quaternion scaled to unit length; the identity if it has degenerated to zero.
pub fn quat_normalize(q: Quat) -> Quat {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if n > 1e-12 && n.is_finite() {
        [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
    } else {
        [1.0, 0.0, 0.0, 0.0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn euler_round_trip() {
        for &(r, p, y) in &[(0.3, -0.2, 2.5), (-1.0, 0.7, -3.0), (0.0, 0.0, 0.0)] {
            let e = quat_to_euler(quat_from_euler(r, p, y));
            assert!(close(e[0], r) && close(e[1], p) && close(e[2], y), "{e:?}");
        }
    }

    #[test]
    fn rotation_matches_conventions() {
        // Yaw 90° (nose east): the body x axis points east in NED.
        let r = quat_to_rotation(quat_from_euler(0.0, 0.0, std::f64::consts::FRAC_PI_2));
        let x = mat_vec(&r, [1.0, 0.0, 0.0]);
        assert!(close(x[0], 0.0) && close(x[1], 1.0) && close(x[2], 0.0));
        // Pitch up 90°: the nose points up, i.e. −down.
        let r = quat_to_rotation(quat_from_euler(0.0, std::f64::consts::FRAC_PI_2, 0.0));
        let x = mat_vec(&r, [1.0, 0.0, 0.0]);
        assert!(close(x[2], -1.0));
        // Roll right 90°: the right wing points down.
        let r = quat_to_rotation(quat_from_euler(std::f64::consts::FRAC_PI_2, 0.0, 0.0));
        let y = mat_vec(&r, [0.0, 1.0, 0.0]);
        assert!(close(y[2], 1.0));
        let back = mat_t_vec(&r, y);
        assert!(close(back[1], 1.0));
    }
}

//! The plant's vector and quaternion operations, on nalgebra (as the estimator in core), except
//! three whose nalgebra versions round differently (rotation matrix, Euler angles,
//! normalisation): those stay written out, so trajectories and scores stay bit-identical.
//!
//! The plant's state and its public types stay plain arrays (`Vec3`, `Quat`, `Mat3`: `Copy`,
//! printable, comparable, free to construct in tests); these functions convert at the edge and
//! let nalgebra do the algebra. Frames follow `conventions.md`: NED world, FRD body, Hamilton
//! quaternions scalar first `[w, x, y, z]` rotating body vectors into NED.

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};

pub type Vec3 = [f64; 3];
/// Hamilton quaternion, scalar first: `[w, x, y, z]`.
pub type Quat = [f64; 4];
/// Row-major 3×3 matrix.
pub type Mat3 = [[f64; 3]; 3];

fn v(a: Vec3) -> Vector3<f64> {
    Vector3::from(a)
}

fn arr(a: Vector3<f64>) -> Vec3 {
    a.into()
}

fn m(a: &Mat3) -> Matrix3<f64> {
    Matrix3::from_row_slice(&[
        a[0][0], a[0][1], a[0][2], a[1][0], a[1][1], a[1][2], a[2][0], a[2][1], a[2][2],
    ])
}

fn quat(q: Quat) -> Quaternion<f64> {
    Quaternion::new(q[0], q[1], q[2], q[3])
}

fn from_quat(q: Quaternion<f64>) -> Quat {
    [q.w, q.i, q.j, q.k]
}

pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    arr(v(a) + v(b))
}

pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    arr(v(a) - v(b))
}

pub fn scale(a: Vec3, k: f64) -> Vec3 {
    arr(v(a) * k)
}

pub fn dot(a: Vec3, b: Vec3) -> f64 {
    v(a).dot(&v(b))
}

pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    arr(v(a).cross(&v(b)))
}

pub fn norm(a: Vec3) -> f64 {
    v(a).norm()
}

pub fn mat_vec(a: &Mat3, x: Vec3) -> Vec3 {
    arr(m(a) * v(x))
}

/// `mᵀ v`: for a rotation, the inverse rotation.
pub fn mat_t_vec(a: &Mat3, x: Vec3) -> Vec3 {
    arr(m(a).tr_mul(&v(x)))
}

/// `R_nb`: the rotation that turns body (FRD) vectors into NED, from a unit quaternion.
///
/// Written out rather than nalgebra's `to_rotation_matrix`, which rounds differently (it uses
/// `w² + x² − y² − z²` where this uses `1 − 2(y² + z²)`): every recorded trajectory and score
/// depends on these last bits, and a refactor must not change them.
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
    from_quat(*UnitQuaternion::from_euler_angles(roll, pitch, yaw).quaternion())
}

/// 3-2-1 Euler angles `[roll, pitch, yaw]` (rad) of a unit quaternion; yaw in (−π, π].
///
/// From the quaternion directly; nalgebra's `euler_angles` goes through the rotation matrix
/// and rounds differently (see [`quat_to_rotation`]).
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
    from_quat(quat(q) * Quaternion::from_imag(v(omega)) * 0.5)
}

/// The quaternion scaled to unit length; the identity if it has degenerated to zero.
pub fn quat_normalize(q: Quat) -> Quat {
    // Written out: nalgebra's norm and division round differently in the last bit (see
    // `quat_to_rotation` for why that matters).
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

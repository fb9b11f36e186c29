//! Unit quaternions `(x, y, z, w)` (scalar last, model §1) and the attitude kinematics of the
//! base: rotation matrices, the Hamilton product, `Exp`/`Log`, the rate `½ quat ⊗ (ω, 0)` and
//! renormalisation. The one home of rotation arithmetic in the crate.

use super::{Mat3, Vec3};
use std::ops::Range;

/// Where the position `r` (m) sits in a pose `[r; quat]` of 7 numbers (the base pose, an EE
/// pose, the first block of the state).
pub const POSE_POSITION: Range<usize> = 0..3;
/// Where the unit quaternion `(x, y, z, w)` sits in a pose `[r; quat]` of 7 numbers.
pub const POSE_QUATERNION: Range<usize> = 3..7;

/// Rotation matrix of a unit quaternion `(x, y, z, w)` (scalar last, model §1): it maps base-frame
/// components to inertial-frame components. The quaternion is normalised first.
#[inline]
pub fn quaternion_to_rotation(quat: &[f64]) -> Mat3 {
    let q = nalgebra::Quaternion::new(quat[3], quat[0], quat[1], quat[2]);
    nalgebra::UnitQuaternion::from_quaternion(q)
        .to_rotation_matrix()
        .into_inner()
}

/// `d quat / dt = ½ quat ⊗ (ω, 0)` (Hamilton product, scalar last) for a quaternion mapping body
/// to inertial components and the body-frame angular velocity `ω`.
#[inline]
pub fn quaternion_rate(quat: &[f64], omega: &Vec3) -> [f64; 4] {
    let v = Vec3::new(quat[0], quat[1], quat[2]);
    let d = (omega * quat[3] + v.cross(omega)) * 0.5;
    [d.x, d.y, d.z, -0.5 * v.dot(omega)]
}

/// The rate of the base pose `[r_B; quat_B]` (model §4): `ṙ_B = R_B v_B` (inertial frame, m/s)
/// and `quat_B' = ½ quat_B ⊗ (ω_B, 0)` ([`quaternion_rate`]), from the base twist `[ω_B; v_B]`
/// in base-frame components, into `out` (7). The one statement of the base's kinematics: the
/// state derivative and the planner's pose integration both use it.
#[inline]
pub fn base_pose_rate(quat: &[f64], omega: &Vec3, v: &Vec3, out: &mut [f64]) {
    let r_dot = quaternion_to_rotation(quat) * v;
    out[POSE_POSITION].copy_from_slice(r_dot.as_slice());
    out[POSE_QUATERNION].copy_from_slice(&quaternion_rate(quat, omega));
}

/// The Hamilton product `a ⊗ b` of quaternions `(x, y, z, w)`, scalar last.
#[inline]
pub fn quaternion_product(a: &[f64], b: &[f64]) -> [f64; 4] {
    let (av, aw) = (Vec3::new(a[0], a[1], a[2]), a[3]);
    let (bv, bw) = (Vec3::new(b[0], b[1], b[2]), b[3]);
    let v = bv * aw + av * bw + av.cross(&bv);
    [v.x, v.y, v.z, aw * bw - av.dot(&bv)]
}

/// `Exp(φ)`: the unit quaternion of the rotation by `|φ|` about `φ/|φ|` (a rotation vector, rad).
#[inline]
pub fn quaternion_exp(phi: &Vec3) -> [f64; 4] {
    let angle = phi.norm();
    // sin(θ/2)/θ by its series near 0, where the division would lose digits
    let scale = if angle < 1e-4 {
        0.5 - angle * angle / 48.0
    } else {
        (0.5 * angle).sin() / angle
    };
    [
        phi.x * scale,
        phi.y * scale,
        phi.z * scale,
        (0.5 * angle).cos(),
    ]
}

/// `Log(quat)`: the rotation vector (rad, `|φ| ≤ π`) of a unit quaternion, taken with `w ≥ 0`
/// (the same rotation as `−quat`).
#[inline]
pub fn quaternion_log(quat: &[f64]) -> Vec3 {
    let sign = if quat[3] < 0.0 { -1.0 } else { 1.0 };
    let v = Vec3::new(quat[0], quat[1], quat[2]) * sign;
    let w = quat[3] * sign;
    let s = v.norm();
    // θ/sin(θ/2) with θ = 2 atan2(s, w), by its series where s is tiny
    let scale = if s < 1e-8 {
        2.0 / w * (1.0 - s * s / (3.0 * w * w))
    } else {
        2.0 * s.atan2(w) / s
    };
    v * scale
}

/// Scales a quaternion to unit norm. The norm is taken after dividing by the largest component,
/// so huge but finite components do not overflow into a zero quaternion; a zero or non-finite
/// quaternion is left as it is (and is then caught as a diverged state).
pub fn normalise_quaternion(quat: &mut [f64]) {
    let squares: f64 = quat.iter().map(|v| v * v).sum();
    let norm = if squares.is_finite() && squares > f64::MIN_POSITIVE {
        squares.sqrt()
    } else {
        let scale = quat.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if !(scale.is_finite() && scale > 0.0) {
            return;
        }
        scale * quat.iter().map(|v| (v / scale).powi(2)).sum::<f64>().sqrt()
    };
    quat.iter_mut().for_each(|v| *v /= norm);
}

/// The intrinsic z-y′-x″ Euler angles `[yaw, pitch, roll]` (rad) of a unit quaternion
/// `(x, y, z, w)`: `R = R_z(yaw) R_y(pitch) R_x(roll)`, `yaw, roll ∈ (−π, π]`,
/// `pitch ∈ [−π/2, π/2]` (at `±π/2`, gimbal lock: yaw and roll are then not separable).
#[inline]
pub fn euler_zyx(quat: &[f64]) -> [f64; 3] {
    let (x, y, z, w) = (quat[0], quat[1], quat[2], quat[3]);
    let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
    let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    [yaw, pitch, roll]
}

/// The angle (rad, in `[0, π]`) of the rotation from attitude `a` to attitude `b` (unit
/// quaternions `(x, y, z, w)`): `2 atan2(|vec(a* ⊗ b)|, |w(a* ⊗ b)|)`, accurate for tiny angles
/// too (the arccosine of `a · b` loses them below about 1e-8 rad).
#[inline]
pub fn rotation_angle(a: &[f64], b: &[f64]) -> f64 {
    let conjugate = [-a[0], -a[1], -a[2], a[3]];
    let relative = quaternion_product(&conjugate, b);
    let v = Vec3::new(relative[0], relative[1], relative[2]);
    2.0 * v.norm().atan2(relative[3].abs())
}

//! Spatial algebra in the paper's conventions (model §1).
//!
//! Motions are `V = [ω; v]` and forces `f = [n; F]`, angular part first, in the body's own frame;
//! `v` is the velocity of the frame origin and `n` the moment about it. A [`Transform`] is the
//! paper's `Φ_{i+1,i}` (A.5), acting on motions; its transpose acts on forces. An [`Inertia`] is the
//! paper's `M_i` (A.9), stored as mass, centre of mass and rotational inertia about the frame origin.
//!
//! An [`ArticulatedInertia`] is the ABA's symmetric `I^A`, kept as 3×3 blocks.
//!
//! All operations are closed-form on 3-vectors and 3×3 blocks; every type also has a dense 6×6 or
//! 6-vector form (`matrix()`, `to_vector()`) used by the operator form and by the tests that check
//! each compact operation against its matrix.
//!
//! ```
//! use orbitflex::spatial::{Force, Motion, Transform, Vec3};
//! // frame i+1 sits 2 m along x of frame i, turned 90° about z
//! let phi = Transform::from_xyz_rpy([2.0, 0.0, 0.0], [0.0, 0.0, std::f64::consts::FRAC_PI_2]);
//! // a pure rotation of frame i about its z axis at 1 rad/s...
//! let v = Motion::new(Vec3::z(), Vec3::zeros());
//! // ...moves origin i+1 at 2 m/s along y of frame i, which is +x of frame i+1 (A.4, A.5)
//! let seen = phi.apply_motion(&v);
//! assert!((seen.angular - Vec3::z()).norm() < 1e-12);
//! assert!((seen.linear - Vec3::new(2.0, 0.0, 0.0)).norm() < 1e-12);
//! // power is frame-independent: (Φ V)ᵀ f' = Vᵀ (Φᵀ f')
//! let f = Force::new(Vec3::new(0.3, -1.0, 2.0), Vec3::new(1.0, 0.5, -0.2));
//! assert!((seen.dot(&f) - v.dot(&phi.apply_force_transpose(&f))).abs() < 1e-12);
//! ```

mod articulated;
mod inertia;
mod quaternion;
mod transform;
mod vectors;

pub use articulated::{ArticulatedInertia, Symmetric3};
pub use inertia::{bias_force, coriolis_acceleration, Inertia};
pub use quaternion::{
    base_pose_rate, euler_zyx, normalise_quaternion, quaternion_exp, quaternion_log,
    quaternion_product, quaternion_rate, quaternion_to_rotation, rotation_angle, POSE_POSITION,
    POSE_QUATERNION,
};
pub use transform::{congruence, rotation_about_axis, Transform};
pub use vectors::{Force, Motion};

/// 3-vector of `f64`.
pub type Vec3 = nalgebra::Vector3<f64>;
/// 3×3 matrix of `f64`.
pub type Mat3 = nalgebra::Matrix3<f64>;
/// 6-vector of `f64` (a motion or force in dense form, `[angular; linear]`).
pub type Vec6 = nalgebra::Vector6<f64>;
/// 6×6 matrix of `f64` (a spatial transform or inertia in dense form).
pub type Mat6 = nalgebra::Matrix6<f64>;

/// The cross-product matrix `[p]×`, with `[p]× x = p × x`.
#[inline]
pub fn skew(p: &Vec3) -> Mat3 {
    Mat3::new(0.0, -p.z, p.y, p.z, 0.0, -p.x, -p.y, p.x, 0.0)
}

/// Builds a 6×6 matrix from its four 3×3 blocks `[[a, b], [c, d]]`.
pub fn blocks(a: &Mat3, b: &Mat3, c: &Mat3, d: &Mat3) -> Mat6 {
    let mut m = Mat6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(a);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(b);
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(c);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(d);
    m
}

#[cfg(test)]
mod tests;

//! Velocity kinematics (A.4, A.7), the EE Jacobian, momentum and kinetic energy.

use super::data::{check_data, Data};
use crate::args::{check_vector, RigidState};
use crate::error::Result;
use crate::model::Robot;
use crate::spatial::{bias_force, Force, Motion, Transform, Vec3};

/// Fills `x[i] = Φ_{i,λ(i)}(q)`, `v[i] = V_i` (A.4) and `c[i] = a_i` (A.7), base to tip.
pub fn velocities(robot: &Robot, data: &mut Data, state: &RigidState) -> Result<()> {
    check_data(robot, data)?;
    state.check(robot)?;
    velocities_unchecked(robot, data, state);
    Ok(())
}

#[inline]
pub(crate) fn velocities_unchecked(robot: &Robot, data: &mut Data, state: &RigidState) {
    data.v[0] = Motion::from_slice(state.base_twist);
    data.c[0] = Motion::zero();
    for i in 1..=robot.dof() {
        body_velocity(robot, data, i, state);
    }
}

/// (A.4) and (A.7) for body `i` in joint frames (`H_i = [e_z; 0]`), from its parent's velocity
/// (already in `data.v`): `V_i = Φ V_λ + H_i q̇_i = [R ω_λ + e_z q̇_i; R (v_λ + ω_λ × p)]` and
/// `a_i = [(R ω_λ) × ω_i; R (ω_λ × (ω_λ × p))]`, sharing `R ω_λ` and `ω_λ × p`; the angular part
/// of `a_i` is `q̇_i (R ω_λ) × e_z`.
#[inline(always)]
pub(crate) fn body_velocity(robot: &Robot, data: &mut Data, i: usize, state: &RigidState) {
    let parent = data.v[robot.parents()[i]];
    let w_cross_p = body_rates(robot, data, i, state);
    data.v[i].linear = data.x[i].rotation * (parent.linear + w_cross_p);
}

/// The part of [`body_velocity`] that the classical-acceleration recursions (ABA, RNEA) use:
/// `x[i]`, the angular velocity `ω_i` and `c[i] = a_i` (A.7), which depend on the angular
/// velocities alone (and so do the bias forces `b_i`, A.10). The linear part of `v[i]` is set
/// to NaN, not computed: nothing downstream of these recursions reads it, and a stale value
/// would be a silent error for a caller reading [`Data::v`] afterwards. Returns `ω_λ × p` for
/// [`body_velocity`].
#[inline(always)]
pub(crate) fn body_rates(robot: &Robot, data: &mut Data, i: usize, state: &RigidState) -> Vec3 {
    let x = robot.joint_transform(i, state.q[i - 1]);
    let qd = state.qd[i - 1];
    let parent = data.v[robot.parents()[i]].angular;
    let w_rotated = x.rotation * parent;
    let w_cross_p = parent.cross(&x.translation);
    let mut omega = w_rotated;
    omega.z += qd;
    data.v[i] = Motion::new(omega, Vec3::repeat(f64::NAN));
    data.c[i] = Motion::new(
        Vec3::new(qd * w_rotated.y, -qd * w_rotated.x, 0.0),
        x.rotation * parent.cross(&w_cross_p),
    );
    data.x[i] = x;
    w_cross_p
}

/// Fills `data.jacobian = J_e` (6×n, column `k` is `Φ_{e,k} H_k` for the joints that move the
/// body carrying end-effector `ee` and zero for the others, model §2) and
/// `data.ee_base = Φ_{e,B}`, so that `V_e = Φ_{e,B} V_B + J_e q̇` in the frame of end-effector
/// `ee` (an index into [`Robot::end_effectors`]; `0` for a chain).
pub fn ee_jacobian(robot: &Robot, data: &mut Data, q: &[f64], ee: usize) -> Result<()> {
    check_data(robot, data)?;
    check_vector("q", q, robot.dof())?;
    let ee = robot.ee_choice(Some(ee))?;
    data.jacobian.fill(0.0);
    let mut to_ee = *robot.frame_ee_transform(ee);
    for k in robot.path_to_base(robot.end_effectors()[ee].body) {
        let column = to_ee.apply_motion(&Motion::new(Vec3::z(), Vec3::zeros()));
        data.jacobian
            .column_mut(k - 1)
            .copy_from_slice(&column.to_array());
        to_ee = to_ee.compose(&robot.joint_transform(k, q[k - 1]));
    }
    data.ee_base = to_ee.matrix();
    Ok(())
}

/// `Φ_{e,B}(q)`: end-effector `ee`'s frame seen from the base frame, composed along the path
/// from its body to the base. Allocation-free.
pub(crate) fn ee_from_base(robot: &Robot, q: &[f64], ee: usize) -> Transform {
    let mut to_ee = *robot.frame_ee_transform(ee);
    for k in robot.path_to_base(robot.end_effectors()[ee].body) {
        to_ee = to_ee.compose(&robot.joint_transform(k, q[k - 1]));
    }
    to_ee
}

/// `[position; quaternion (x, y, z, w), w ≥ 0]` of a frame whose origin is at `position` and
/// whose axes are the columns of `rotation` (frame to inertial components).
pub fn pose(position: &Vec3, rotation: &crate::spatial::Mat3) -> [f64; 7] {
    let quat = nalgebra::UnitQuaternion::from_rotation_matrix(
        &nalgebra::Rotation3::from_matrix_unchecked(*rotation),
    );
    let c = quat.coords; // (i, j, k, w)
    let sign = if c[3] < 0.0 { -1.0 } else { 1.0 };
    [
        position.x,
        position.y,
        position.z,
        sign * c[0],
        sign * c[1],
        sign * c[2],
        sign * c[3],
    ]
}

/// The inertial poses of the base, of every body `1..=n` and of every end-effector frame
/// (`n + 1 + k` rows of [`pose`], `n + 2` on a chain), for the base pose `[r_B; quat_B (x, y, z, w)]` and joint angles `q`: body `i`'s
/// origin is `o_λ + E_λ p_{λ,i}` and its axes `E_i = E_λ R_{i,λ}ᵀ`. Checks its arguments.
pub fn body_poses(robot: &Robot, base_pose: &[f64], q: &[f64]) -> Result<Vec<[f64; 7]>> {
    crate::args::check_base_pose(base_pose)?;
    check_vector("q", q, robot.dof())?;
    let n = robot.dof();
    let mut rotations = Vec::with_capacity(n + 1);
    let mut origins = Vec::with_capacity(n + 1);
    rotations.push(crate::spatial::quaternion_to_rotation(
        &base_pose[crate::spatial::POSE_QUATERNION],
    ));
    origins.push(Vec3::new(base_pose[0], base_pose[1], base_pose[2]));
    for i in 1..=n {
        let x = robot.joint_transform(i, q[i - 1]);
        let parent = robot.parents()[i];
        let (e, o) = (rotations[parent], origins[parent]);
        origins.push(o + e * x.translation);
        rotations.push(e * x.rotation.transpose());
    }
    // joint-frame axes E'_i = E_i Q_iᵀ back to the link frame's E_i = E'_i Q_i
    let mut poses: Vec<[f64; 7]> = origins
        .iter()
        .zip(&rotations)
        .enumerate()
        .map(|(i, (o, e))| pose(o, &(e * robot.joint_frame_rotation(i))))
        .collect();
    for (k, end) in robot.end_effectors().iter().enumerate() {
        let ee = robot.frame_ee_transform(k);
        let (e, o) = (rotations[end.body], origins[end.body]);
        poses.push(pose(
            &(o + e * ee.translation),
            &(e * ee.rotation.transpose()),
        ));
    }
    Ok(poses)
}

/// Writes the inertial pose `[position (m); quaternion (x, y, z, w), w ≥ 0]` of every named
/// frame ([`Robot::frames`]: every URDF link, merged ones included) into `out`, 7 numbers per
/// frame in frame order, for the base pose `[r_B; quat_B (x, y, z, w)]` and joint angles `q`.
///
/// Body `i` is placed from its parent, base to tips: origin `o_i = o_λ + E_λ p_{λ,i}`, axes
/// `E_i = E_λ R_{i,λ}(q)ᵀ` (kept in `data.placements`); a frame on body `b` with placement
/// `Φ_{f,b}` is at `o_b + E_b p_{b,f}` with axes `E_b R_{f,b}ᵀ`. Links behind a locked joint
/// sit at the locked value (zero). Checks its arguments, then allocates nothing.
///
/// ```
/// use orbitflex::{algorithms::{self, Data}, Robot};
/// let robot = Robot::space_arm();
/// let mut data = Data::new(&robot);
/// let mut poses = vec![0.0; 7 * robot.frames().len()];
/// let base = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
/// algorithms::frame_poses(&robot, &mut data, &base, &[0.0; 7], &mut poses)?;
/// assert_eq!(&poses[..7], &base); // the bus frame is the base
/// # Ok::<(), orbitflex::Error>(())
/// ```
pub fn frame_poses(
    robot: &Robot,
    data: &mut Data,
    base_pose: &[f64],
    q: &[f64],
    out: &mut [f64],
) -> Result<()> {
    check_data(robot, data)?;
    crate::args::check_base_pose(base_pose)?;
    check_vector("q", q, robot.dof())?;
    check_vector("frame poses (out)", out, 7 * robot.frames().len())?;
    frame_poses_unchecked(robot, data, base_pose, q, out);
    Ok(())
}

/// [`frame_poses`] after its checks.
pub(crate) fn frame_poses_unchecked(
    robot: &Robot,
    data: &mut Data,
    base_pose: &[f64],
    q: &[f64],
    out: &mut [f64],
) {
    data.placements[0] = (
        crate::spatial::quaternion_to_rotation(&base_pose[crate::spatial::POSE_QUATERNION]),
        Vec3::new(base_pose[0], base_pose[1], base_pose[2]),
    );
    for i in 1..=robot.dof() {
        let x = robot.joint_transform(i, q[i - 1]);
        let (e, o) = data.placements[robot.parents()[i]];
        data.placements[i] = (e * x.rotation.transpose(), o + e * x.translation);
    }
    let frames = robot.frames().iter().zip(robot.frame_link_transforms());
    for ((frame, placement), out) in frames.zip(out.chunks_exact_mut(7)) {
        let (e, o) = data.placements[frame.body];
        let pose = pose(
            &(o + e * placement.translation),
            &(e * placement.rotation.transpose()),
        );
        out.copy_from_slice(&pose);
    }
}

/// Total spatial momentum of base and links about the base origin, in the base frame:
/// `Σ_i Φ_{iB}ᵀ M_i V_i` (model §6.1), accumulated from the tips towards the base. Use
/// [`crate::dynamics::momentum_in_inertial_frame`] to express it about the inertial origin.
pub fn momentum(robot: &Robot, data: &mut Data, state: &RigidState) -> Result<Force> {
    velocities(robot, data, state)?;
    Ok(momentum_from_velocities(robot, data))
}

#[inline]
pub(crate) fn momentum_from_velocities(robot: &Robot, data: &mut Data) -> Force {
    for (i, inertia) in robot.frame_inertias().iter().enumerate() {
        data.h[i] = inertia.apply(&data.v[i]);
    }
    for i in (1..=robot.dof()).rev() {
        let moved = data.x[i].apply_force_transpose(&data.h[i]);
        data.h[robot.parents()[i]] += moved;
    }
    data.h[0]
}

/// Kinetic energy `½ Σ_i V_iᵀ M_i V_i` of base and links (J), equal to `½ νᵀ 𝓜 ν`.
pub fn kinetic_energy(robot: &Robot, data: &mut Data, state: &RigidState) -> Result<f64> {
    velocities(robot, data, state)?;
    Ok(kinetic_energy_from_velocities(robot, data))
}

#[inline]
pub(crate) fn kinetic_energy_from_velocities(robot: &Robot, data: &Data) -> f64 {
    robot
        .frame_inertias()
        .iter()
        .zip(&data.v)
        .map(|(inertia, v)| 0.5 * v.dot(&inertia.apply(v)))
        .sum()
}

/// `b_i` (A.10) for body `i` at the velocities in `data`.
#[inline(always)]
pub(crate) fn body_bias(robot: &Robot, data: &Data, i: usize) -> Force {
    bias_force(&robot.frame_inertias()[i], &data.v[i].angular)
}

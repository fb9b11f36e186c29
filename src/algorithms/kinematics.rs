//! Velocity kinematics (A.4, A.7), the EE Jacobian, momentum and kinetic energy.

use super::{check_data, Data};
use crate::error::{check_vector, Result};
use crate::model::Robot;
use crate::operators::check_state;
use crate::spatial::{bias_force, Force, Motion, Vec3};

/// Fills `x[i] = Φ_{i,i-1}(q)`, `v[i] = V_i` (A.4) and `c[i] = a_i` (A.7), base to tip.
/// `base_twist = [ω_B; v_B]` in the base frame.
pub fn velocities(
    robot: &Robot,
    data: &mut Data,
    q: &[f64],
    base_twist: &[f64],
    qd: &[f64],
) -> Result<()> {
    check_data(robot, data)?;
    check_state(robot, q, base_twist, qd)?;
    velocities_unchecked(robot, data, q, base_twist, qd);
    Ok(())
}

#[inline]
pub(crate) fn velocities_unchecked(
    robot: &Robot,
    data: &mut Data,
    q: &[f64],
    base_twist: &[f64],
    qd: &[f64],
) {
    data.v[0] = Motion::from_slice(base_twist);
    data.c[0] = Motion::zero();
    for (i, joint) in robot.joints().iter().enumerate() {
        let x = joint.transform(q[i]);
        let parent = data.v[i];
        // (A.4) V_i = Φ_{i,i-1} V_{i-1} + H_i q̇_i = [R ω_{i-1} + h q̇_i; R (v_{i-1} + ω_{i-1} × p)]
        // and (A.7) a_i = [(R ω_{i-1}) × ω_i; R (ω_{i-1} × (ω_{i-1} × p))]
        // (`coriolis_acceleration`), sharing R ω_{i-1} and ω_{i-1} × p.
        let w_rotated = x.rotation * parent.angular;
        let w_cross_p = parent.angular.cross(&x.translation);
        let omega = w_rotated + joint.axis * qd[i];
        data.v[i + 1] = Motion::new(omega, x.rotation * (parent.linear + w_cross_p));
        data.c[i + 1] = Motion::new(
            w_rotated.cross(&omega),
            x.rotation * parent.angular.cross(&w_cross_p),
        );
        data.x[i + 1] = x;
    }
}

/// Fills `data.jacobian = J` (6×n, columns `Φ_{n+1,k} H_k`, SPEC §2) and
/// `data.ee_base = Φ_{n+1,B}`, so that `V_{n+1} = Φ_{n+1,B} V_B + J q̇` in the EE frame.
pub fn ee_jacobian(robot: &Robot, data: &mut Data, q: &[f64]) -> Result<()> {
    check_data(robot, data)?;
    check_vector("q", q, robot.dof())?;
    let mut to_ee = *robot.ee_transform();
    for (k, joint) in robot.joints().iter().enumerate().rev() {
        let h = Motion::new(joint.axis, Vec3::zeros());
        let column = to_ee.apply_motion(&h);
        data.jacobian
            .fixed_view_mut::<3, 1>(0, k)
            .copy_from(&column.angular);
        data.jacobian
            .fixed_view_mut::<3, 1>(3, k)
            .copy_from(&column.linear);
        to_ee = to_ee.compose(&joint.transform(q[k]));
    }
    data.ee_base = to_ee.matrix();
    Ok(())
}

/// Total spatial momentum of base and links about the base origin, in the base frame:
/// `Σ_i Φ_{iB}ᵀ M_i V_i` (SPEC §6.1), accumulated tip to base. Use
/// [`crate::dynamics::momentum_in_inertial_frame`] to express it about the inertial origin.
pub fn momentum(
    robot: &Robot,
    data: &mut Data,
    q: &[f64],
    base_twist: &[f64],
    qd: &[f64],
) -> Result<Force> {
    velocities(robot, data, q, base_twist, qd)?;
    Ok(momentum_from_velocities(robot, data))
}

#[inline]
pub(crate) fn momentum_from_velocities(robot: &Robot, data: &Data) -> Force {
    let inertias = robot.inertias();
    let n = robot.dof();
    let mut h = Force::zero();
    for i in (1..=n).rev() {
        h += inertias[i].apply(&data.v[i]);
        h = data.x[i].apply_force_transpose(&h);
    }
    h + inertias[0].apply(&data.v[0])
}

/// Kinetic energy `½ Σ_i V_iᵀ M_i V_i` of base and links (J), equal to `½ νᵀ 𝓜 ν`.
pub fn kinetic_energy(
    robot: &Robot,
    data: &mut Data,
    q: &[f64],
    base_twist: &[f64],
    qd: &[f64],
) -> Result<f64> {
    velocities(robot, data, q, base_twist, qd)?;
    Ok(kinetic_energy_from_velocities(robot, data))
}

#[inline]
pub(crate) fn kinetic_energy_from_velocities(robot: &Robot, data: &Data) -> f64 {
    robot
        .inertias()
        .iter()
        .zip(&data.v)
        .map(|(inertia, v)| 0.5 * v.dot(&inertia.apply(v)))
        .sum()
}

/// `b_i` (A.10) for body `i` at the velocities in `data`.
#[inline]
pub(crate) fn body_bias(robot: &Robot, data: &Data, i: usize) -> Force {
    bias_force(&robot.inertias()[i], &data.v[i].angular)
}

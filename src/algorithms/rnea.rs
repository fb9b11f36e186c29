//! Recursive Newton–Euler inverse dynamics (A.6, A.8, A.12), O(n).

use super::kinematics::{body_bias, velocities_unchecked};
use super::{check_data, Data};
use crate::error::{check_vector, Result};
use crate::model::Robot;
use crate::operators::check_state;
use crate::spatial::{Force, Motion};
use nalgebra::DVector;

/// Inverse dynamics: `[f_B; τ] = 𝓜 [α_B; q̈] + [C_B; C_r] + [Φ_{n+1,B}ᵀ; Jᵀ] f` (A.19) computed
/// recursively. `base_acc = α_B` (classical, base frame), `ee_wrench = f` (the force the EE exerts
/// on its environment, EE frame). Result in `data.out` (length 6+n).
#[allow(clippy::too_many_arguments)]
pub fn rnea<'a>(
    robot: &Robot,
    data: &'a mut Data,
    q: &[f64],
    base_twist: &[f64],
    qd: &[f64],
    base_acc: &[f64],
    qdd: &[f64],
    ee_wrench: &[f64],
) -> Result<&'a DVector<f64>> {
    check_data(robot, data)?;
    check_state(robot, q, base_twist, qd)?;
    check_vector("base_acc", base_acc, 6)?;
    check_vector("qdd", qdd, robot.dof())?;
    check_vector("ee_wrench", ee_wrench, 6)?;
    velocities_unchecked(robot, data, q, base_twist, qd);
    rnea_from_velocities(
        robot,
        data,
        Motion::from_slice(base_acc),
        qdd,
        &Force::from_slice(ee_wrench),
    );
    Ok(&data.out)
}

/// The bias `[C_B; C_r]` (A.19): inverse dynamics with `α_B = 0`, `q̈ = 0`, `f = 0`.
pub fn bias_forces<'a>(
    robot: &Robot,
    data: &'a mut Data,
    q: &[f64],
    base_twist: &[f64],
    qd: &[f64],
) -> Result<&'a DVector<f64>> {
    check_data(robot, data)?;
    check_state(robot, q, base_twist, qd)?;
    velocities_unchecked(robot, data, q, base_twist, qd);
    rnea_acceleration_free(robot, data);
    Ok(&data.out)
}

fn rnea_acceleration_free(robot: &Robot, data: &mut Data) {
    let n = robot.dof();
    // With α_B = 0 and q̈ = 0, (A.6) leaves α_i = Φ α_{i-1} + a_i.
    data.acc[0] = Motion::zero();
    for i in 1..=n {
        data.acc[i] = data.x[i].apply_motion(&data.acc[i - 1]) + data.c[i];
    }
    backward(robot, data, &Force::zero());
}

pub(crate) fn rnea_from_velocities(
    robot: &Robot,
    data: &mut Data,
    base_acc: Motion,
    qdd: &[f64],
    ee_wrench: &Force,
) {
    let n = robot.dof();
    data.acc[0] = base_acc;
    for i in 1..=n {
        // (A.6) α_i = Φ_{i,i-1} α_{i-1} + H_i q̈_i + a_i
        let mut acc = data.x[i].apply_motion(&data.acc[i - 1]) + data.c[i];
        acc.angular += robot.joints()[i - 1].axis * qdd[i - 1];
        data.acc[i] = acc;
    }
    backward(robot, data, ee_wrench);
}

/// (A.8) backwards from the tip: `f_i = M_i α_i + b_i + Φ_{i+1,i}ᵀ f_{i+1}`, with `f_{n+1} = f`
/// (A.3); `τ_i = H_iᵀ f_i` (A.2) and `f_B = f_0`.
fn backward(robot: &Robot, data: &mut Data, ee_wrench: &Force) {
    let n = robot.dof();
    let inertias = robot.inertias();
    let mut child = robot.ee_transform().apply_force_transpose(ee_wrench);
    for i in (0..=n).rev() {
        let f = inertias[i].apply(&data.acc[i]) + body_bias(robot, data, i) + child;
        data.f[i] = f;
        if i > 0 {
            data.out[5 + i] = robot.joints()[i - 1].axis.dot(&f.angular);
            child = data.x[i].apply_force_transpose(&f);
        }
    }
    data.f[0].write_to(data.out.as_mut_slice());
}

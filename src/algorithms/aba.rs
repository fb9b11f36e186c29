//! Floating-base articulated-body forward dynamics in the seed's conventions, O(n).

use super::kinematics::{body_bias, velocities_unchecked};
use super::{check_data, Data};
use crate::error::{check_vector, Error, Result};
use crate::model::Robot;
use crate::operators::check_state;
use crate::spatial::{congruence, Force, Motion, Vec6};
use nalgebra::DVector;

/// Forward dynamics `[α_B; q̈]` of (A.19) without forming `𝓜`:
/// given joint torques `tau`, base wrench `f_B` (base frame) and EE wrench `f` (EE frame, the
/// force the EE exerts on its environment). Result in `data.out` (length 6+n).
///
/// Articulated inertias and bias forces start from `M_i` and `b_i` (A.9, A.10), with
/// `Φ_{n+1,n}ᵀ f` added to link `n` (A.3, A.8). Backwards: `U = I^A H`, `D = Hᵀ U`,
/// `u = τ − Hᵀ p^A`, and the parent receives `Φᵀ (I^A − U Uᵀ/D) Φ` and
/// `Φᵀ (p^A + I^a a + U u/D)`. The base solves `I^A_B α_B = f_B − p^A_B`; then forwards
/// `α' = Φ α_{i-1} + a_i`, `q̈_i = (u − Uᵀ α')/D`, `α_i = α' + H q̈_i` (A.6).
#[allow(clippy::too_many_arguments)]
pub fn aba<'a>(
    robot: &Robot,
    data: &'a mut Data,
    q: &[f64],
    base_twist: &[f64],
    qd: &[f64],
    tau: &[f64],
    base_wrench: &[f64],
    ee_wrench: &[f64],
) -> Result<&'a DVector<f64>> {
    check_data(robot, data)?;
    check_state(robot, q, base_twist, qd)?;
    check_vector("tau", tau, robot.dof())?;
    check_vector("base_wrench", base_wrench, 6)?;
    check_vector("ee_wrench", ee_wrench, 6)?;
    velocities_unchecked(robot, data, q, base_twist, qd);
    aba_from_velocities(
        robot,
        data,
        tau,
        &Force::from_slice(base_wrench),
        &Force::from_slice(ee_wrench),
    )?;
    Ok(&data.out)
}

/// The articulated-body passes after [`velocities_unchecked`]; no allocation.
pub(crate) fn aba_from_velocities(
    robot: &Robot,
    data: &mut Data,
    tau: &[f64],
    base_wrench: &Force,
    ee_wrench: &Force,
) -> Result<()> {
    let n = robot.dof();
    let joints = robot.joints();
    for i in 0..=n {
        data.ia[i] = robot.inertias()[i].matrix();
        data.f[i] = body_bias(robot, data, i);
    }
    let ee_load = robot.ee_transform().apply_force_transpose(ee_wrench);
    data.f[n] += ee_load;

    for i in (1..=n).rev() {
        let h = &joints[i - 1].axis;
        let ia = &data.ia[i];
        // U = I^A H: the first three columns of I^A times h.
        let u_col: Vec6 = ia.fixed_columns::<3>(0) * h;
        let d = h.dot(&u_col.fixed_rows::<3>(0));
        let u = tau[i - 1] - h.dot(&data.f[i].angular);
        let reduced = ia - u_col * (u_col.transpose() / d);
        let c = data.c[i].to_vector();
        let pa = data.f[i].to_vector() + reduced * c + u_col * (u / d);
        let to_parent = congruence(&data.x[i], &reduced);
        data.ia[i - 1] += to_parent;
        let pa = data.x[i].apply_force_transpose(&Force::from_vector(&pa));
        data.f[i - 1] += pa;
        data.u_col[i] = u_col;
        data.d[i] = d;
        data.u[i] = u;
    }

    let rhs = (*base_wrench - data.f[0]).to_vector();
    let base_acc = data.ia[0]
        .cholesky()
        .ok_or_else(|| Error::InvalidArgument {
            what: "articulated base inertia".into(),
            message: "not positive definite (the model's mass matrix is singular here)".into(),
        })?;
    let base_acc = Motion::from_vector(&base_acc.solve(&rhs));
    data.acc[0] = base_acc;
    base_acc.write_to(data.out.as_mut_slice());
    for i in 1..=n {
        let mut acc = data.x[i].apply_motion(&data.acc[i - 1]) + data.c[i];
        let qdd = (data.u[i] - data.u_col[i].dot(&acc.to_vector())) / data.d[i];
        acc.angular += joints[i - 1].axis * qdd;
        data.acc[i] = acc;
        data.out[5 + i] = qdd;
    }
    Ok(())
}

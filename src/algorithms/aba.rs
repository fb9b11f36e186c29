//! Floating-base articulated-body forward dynamics in the seed's conventions, O(n).

use super::kinematics::{body_bias, velocities_unchecked};
use super::{check_data, Data};
use crate::error::{check_vector, Error, Result};
use crate::model::Robot;
use crate::operators::check_state;
use crate::spatial::{ArticulatedInertia, Force, Motion};
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
///
/// The chain is serial, so body `i−1` receives the articulated inertia of body `i` only: the
/// backward pass carries `I^A` and `p^A` in locals and writes them to `data.ia`/`data.f` as it
/// goes. All spatial operations are closed-form on 3×3 blocks ([`ArticulatedInertia`]).
pub(crate) fn aba_from_velocities(
    robot: &Robot,
    data: &mut Data,
    tau: &[f64],
    base_wrench: &Force,
    ee_wrench: &Force,
) -> Result<()> {
    let n = robot.dof();
    let joints = robot.joints();
    let inertias = robot.inertias();

    // Tip body: M_n (A.9), b_n (A.10) and the EE load Φ_{n+1,n}ᵀ f (A.3, A.8).
    let mut ia = ArticulatedInertia::from(&inertias[n]);
    let mut pa = body_bias(robot, data, n) + robot.ee_transform().apply_force_transpose(ee_wrench);
    for i in (1..=n).rev() {
        data.ia[i] = ia;
        data.f[i] = pa;
        let h = &joints[i - 1].axis;
        // U = I^A H, D = Hᵀ U, u = τ − Hᵀ p^A
        let u_col = ia.apply_angular(h);
        let d = h.dot(&u_col.angular);
        // D_i > 0 for every physical model; a pivot at round-off level means the links beyond
        // joint i have no inertia about its axis here, and q̈ would be garbage (~1/ε).
        let scale = ia.angular.xx + ia.angular.yy + ia.angular.zz;
        if d.is_nan() || d <= 1e-12 * scale {
            return Err(Error::InvalidArgument {
                what: "mass matrix".into(),
                message: format!(
                    "singular at this configuration: the links moved by joint '{}' have no \
                     inertia about its axis (articulated pivot D = {d:e})",
                    joints[i - 1].name
                ),
            });
        }
        let u = tau[i - 1] - h.dot(&pa.angular);
        // I^a = I^A − U Uᵀ/D and p^a = p^A + I^a a + U u/D = p^A + I^A a + U (u − Uᵀ a)/D
        let c = &data.c[i];
        let reduced = ia.minus_outer(&u_col, 1.0 / d);
        let pa_child = pa + ia.apply(c) + u_col * ((u - c.dot(&u_col)) / d);
        let x = &data.x[i];
        ia = ArticulatedInertia::from(&inertias[i - 1]) + reduced.transformed_to_parent(x);
        pa = body_bias(robot, data, i - 1) + x.apply_force_transpose(&pa_child);
        data.u_col[i] = u_col.to_vector();
        data.d[i] = d;
        data.u[i] = u;
    }
    data.ia[0] = ia;
    data.f[0] = pa;

    let rhs = (*base_wrench - pa).to_vector();
    let base_acc = ia
        .matrix()
        .cholesky()
        .ok_or_else(|| Error::InvalidArgument {
            what: "articulated base inertia".into(),
            message: "not positive definite (the model's mass matrix is singular here)".into(),
        })?;
    let mut acc = Motion::from_vector(&base_acc.solve(&rhs));
    data.acc[0] = acc;
    acc.write_to(data.out.as_mut_slice());
    for i in 1..=n {
        // (A.6) α_i = Φ α_{i−1} + a_i + H q̈_i, with q̈_i = (u − Uᵀ (Φ α_{i−1} + a_i))/D
        acc = data.x[i].apply_motion(&acc) + data.c[i];
        let qdd = (data.u[i] - acc.dot(&Force::from_vector(&data.u_col[i]))) / data.d[i];
        acc.angular += joints[i - 1].axis * qdd;
        data.acc[i] = acc;
        data.out[5 + i] = qdd;
    }
    Ok(())
}

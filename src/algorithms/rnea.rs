//! Recursive Newton–Euler inverse dynamics (A.6, A.8, A.12), O(n).

use super::data::{check_data, Data};
use super::kinematics::{body_bias, body_rates};
use crate::args::{check_vector, RigidState};
use crate::error::Result;
use crate::model::Robot;
use crate::spatial::Motion;
use nalgebra::DVector;

/// Inverse dynamics: `[f_B; τ] = 𝓜 [α_B; q̈] + [C_B; C_r] + Σ_e [Φ_{e,B}ᵀ; J_eᵀ] f_e` (A.19),
/// computed recursively. `base_acc = α_B` (classical, base frame); `ee_wrench = [f_1; …; f_k]`,
/// the force each end-effector exerts on its environment in its own frame (6 numbers per
/// end-effector, or empty for none). Result in `data.tau` (length 6+n).
pub fn rnea<'a>(
    robot: &Robot,
    data: &'a mut Data,
    state: &RigidState,
    base_acc: &[f64],
    qdd: &[f64],
    ee_wrench: &[f64],
) -> Result<&'a DVector<f64>> {
    check_data(robot, data)?;
    state.check(robot)?;
    check_vector("base_acc", base_acc, 6)?;
    check_vector("qdd", qdd, robot.dof())?;
    crate::args::check_ee_wrench(robot, ee_wrench)?;
    rnea_unchecked(
        robot,
        data,
        state,
        Motion::from_slice(base_acc),
        Some(qdd),
        ee_wrench,
    );
    Ok(&data.tau)
}

/// The bias `[C_B; C_r]` (A.19): inverse dynamics with `α_B = 0`, `q̈ = 0`, `f = 0`.
pub fn bias_forces<'a>(
    robot: &Robot,
    data: &'a mut Data,
    state: &RigidState,
) -> Result<&'a DVector<f64>> {
    check_data(robot, data)?;
    state.check(robot)?;
    rnea_unchecked(robot, data, state, Motion::zero(), None, &[]);
    Ok(&data.tau)
}

/// RNEA without argument checks; `qdd = None` means `q̈ = 0`.
///
/// In joint frames (`H_i = [e_z; 0]`, so `H_iᵀ f = f_z` of the moment). Forwards, per body: (A.4), (A.7), then (A.6) `α_i = Φ α_λ + a_i + H_i q̈_i` and the body's own
/// `M_i α_i + b_i` (A.8). Each EE body also carries `Φ_{e,b}ᵀ f_e` (A.3). Backwards, each body's
/// force is complete once its children have added theirs: `τ_i = H_iᵀ f_i` (A.2), and the parent
/// receives `Φᵀ f_i` (A.8, A.12). `f_B = f_0`.
///
/// Runs as AVX2 code where the processor has it, with the same bits (`crate::simd`).
#[inline]
pub(crate) fn rnea_unchecked(
    robot: &Robot,
    data: &mut Data,
    state: &RigidState,
    base_acc: Motion,
    qdd: Option<&[f64]>,
    ee_wrench: &[f64],
) {
    crate::simd::dispatch!(rnea_kernel(robot: &Robot, data: &mut Data, state: &RigidState, base_acc: Motion, qdd: Option<&[f64]>, ee_wrench: &[f64]))
}

#[inline(always)]
pub(crate) fn rnea_kernel(
    robot: &Robot,
    data: &mut Data,
    state: &RigidState,
    base_acc: Motion,
    qdd: Option<&[f64]>,
    ee_wrench: &[f64],
) {
    let n = robot.dof();
    let inertias = robot.frame_inertias();
    let parents = robot.parents();
    data.v[0] = Motion::from_slice(state.base_twist);
    data.c[0] = Motion::zero();
    data.acc[0] = base_acc;
    data.f[0] = inertias[0].apply(&base_acc) + body_bias(robot, data, 0);
    for i in 1..=n {
        body_rates(robot, data, i, state);
        // (A.6) α_i = Φ_{i,λ} α_λ + H_i q̈_i + a_i
        let mut acc = data.x[i].apply_motion(&data.acc[parents[i]]) + data.c[i];
        if let Some(qdd) = qdd {
            acc.angular.z += qdd[i - 1];
        }
        data.acc[i] = acc;
        data.f[i] = inertias[i].apply(&acc) + body_bias(robot, data, i);
    }
    robot.add_ee_wrenches(&mut data.f, ee_wrench);
    for i in (1..=n).rev() {
        let f = data.f[i];
        data.tau[5 + i] = f.angular.z;
        let moved = data.x[i].apply_force_transpose(&f);
        data.f[parents[i]] += moved;
    }
    data.f[0].write_to(data.tau.as_mut_slice());
}

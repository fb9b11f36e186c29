//! Floating-base articulated-body forward dynamics in the paper's conventions, O(n).

use super::data::{check_data, Data};
use super::kinematics::{body_bias, body_rates};
use crate::args::{check_vector, Loads, RigidState};
use crate::error::{Error, Result};
use crate::model::Robot;
use crate::spatial::{ArticulatedInertia, Motion};
use nalgebra::DVector;

/// Forward dynamics `[α_B; q̈]` of (A.19) without forming `𝓜`: given joint torques `tau`
/// (N·m) and the external [`Loads`]. Result in `data.ddq` (length 6+n); `α_B` is the base's
/// classical acceleration in the base frame.
pub fn aba<'a>(
    robot: &Robot,
    data: &'a mut Data,
    state: &RigidState,
    tau: &[f64],
    loads: &Loads,
) -> Result<&'a DVector<f64>> {
    check_data(robot, data)?;
    state.check(robot)?;
    check_vector("tau", tau, robot.dof())?;
    loads.check_for(robot)?;
    aba_unchecked(robot, data, state, tau, loads)?;
    Ok(&data.ddq)
}

/// The three ABA passes without argument checks; no allocation. In joint frames, where
/// `H_i = [e_z; 0]` (`crate::model` joint frames).
///
/// 1. Forwards: velocities (A.4), Coriolis terms (A.7), and each body's starting `I^A = M_i`
///    (A.9) and `p^A = b_i` (A.10); each EE body also carries `Φ_{e,b}ᵀ f_e` (A.3, A.8).
/// 2. Backwards: `U = I^A H`, `D = Hᵀ U`, `u = τ − Hᵀ p^A`; the parent receives
///    `Φᵀ (I^A − U Uᵀ/D) Φ` and `Φᵀ (p^A + I^a a + U u/D)`.
/// 3. The base solves `I^A_B α_B = f_B − p^A_B`; then forwards
///    `α' = Φ α_λ + a_i`, `q̈_i = (u − Uᵀ α')/D`, `α_i = α' + H q̈_i` (A.6).
// `i` is the body index of the equations; iterator chains would hide it.
///
/// On x86-64 processors with AVX2 (detected at run time) the same code runs compiled for AVX2:
/// three-operand instructions and 256-bit registers, but no fused multiply-add, so both versions
/// give the same bits (`crate::simd`).
#[inline]
pub(crate) fn aba_unchecked(
    robot: &Robot,
    data: &mut Data,
    state: &RigidState,
    tau: &[f64],
    loads: &Loads,
) -> Result<()> {
    crate::simd::dispatch!(aba_kernel(robot: &Robot, data: &mut Data, state: &RigidState, tau: &[f64], loads: &Loads) -> Result<()>)
}

#[allow(clippy::needless_range_loop)]
#[inline(always)]
pub(crate) fn aba_kernel(
    robot: &Robot,
    data: &mut Data,
    state: &RigidState,
    tau: &[f64],
    loads: &Loads,
) -> Result<()> {
    let n = robot.dof();
    let articulated = robot.frame_articulated();
    let parents = robot.parents();

    data.v[0] = Motion::from_slice(state.base_twist);
    data.c[0] = Motion::zero();
    data.ia[0] = articulated[0];
    data.pa[0] = body_bias(robot, data, 0);
    for i in 1..=n {
        body_rates(robot, data, i, state);
        data.ia[i] = articulated[i];
        data.pa[i] = body_bias(robot, data, i);
    }
    robot.add_ee_wrenches(&mut data.pa, loads.ee_wrench);

    for i in (1..=n).rev() {
        let (ia, pa, c) = (data.ia[i], data.pa[i], data.c[i]);
        // U = I^A H, D = Hᵀ U, u = τ − Hᵀ p^A with H = [e_z; 0]: a column and two entries
        let u_col = ia.column_z();
        let d = u_col.angular.z;
        check_pivot(robot, i, d, &ia)?;
        let u = tau[i - 1] - pa.angular.z;
        // I^a = I^A − U Uᵀ/D and p^a = p^A + I^a a + U u/D = p^A + I^A a + U (u − Uᵀ a)/D
        let reduced = ia.minus_outer(&u_col, 1.0 / d);
        let pa_child = pa + ia.apply(&c) + u_col * ((u - c.dot(&u_col)) / d);
        let x = &data.x[i];
        data.ia[parents[i]] += if robot.is_tilted(i) {
            reduced.tilted_to_parent(x)
        } else {
            reduced.transformed_to_parent(x)
        };
        data.pa[parents[i]] += x.apply_force_transpose(&pa_child);
        data.u_col[i] = u_col;
        data.d[i] = d;
        data.u[i] = u;
    }

    let base_acc = data.ia[0]
        .solve(&(loads.base_wrench - data.pa[0]))
        .ok_or_else(|| Error::InvalidArgument {
            what: "articulated base inertia".into(),
            message: "not positive definite (the model's mass matrix is singular here)".into(),
        })?;
    data.acc[0] = base_acc;
    base_acc.write_to(data.ddq.as_mut_slice());
    for i in 1..=n {
        // (A.6) α_i = Φ α_λ + a_i + H q̈_i, with q̈_i = (u − Uᵀ (Φ α_λ + a_i))/D
        let mut acc = data.x[i].apply_motion(&data.acc[parents[i]]) + data.c[i];
        let qdd = (data.u[i] - acc.dot(&data.u_col[i])) / data.d[i];
        acc.angular.z += qdd;
        data.acc[i] = acc;
        data.ddq[5 + i] = qdd;
    }
    Ok(())
}

/// `D_i > 0` for every physical model. A pivot at round-off level means that the links moved by
/// joint `i` have no inertia about its axis here, and `q̈` would be garbage (~1/ε); a pivot that
/// is not a number means that the state or the inputs overflowed.
#[inline]
fn check_pivot(robot: &Robot, i: usize, d: f64, ia: &ArticulatedInertia) -> Result<()> {
    let scale = ia.angular.xx + ia.angular.yy + ia.angular.zz;
    if d > 1e-12 * scale && d.is_finite() {
        return Ok(());
    }
    Err(singular_pivot(robot, i, d))
}

#[cold]
fn singular_pivot(robot: &Robot, i: usize, d: f64) -> Error {
    let joint = &robot.joints()[i - 1].name;
    if !d.is_finite() {
        return Error::InvalidArgument {
            what: "state".into(),
            message: format!(
                "the dynamics overflowed: the articulated inertia at joint '{joint}' is not \
                 finite (D = {d:e}); the state or the inputs are too large"
            ),
        };
    }
    Error::InvalidArgument {
        what: "mass matrix".into(),
        message: format!(
            "singular at this configuration: the links moved by joint '{joint}' have no inertia \
             about its axis (articulated pivot D = {d:e})"
        ),
    }
}

//! The capture event: an instantaneous, perfectly inelastic grasp that welds the end-effector
//! frame `e` and a [`Target`] into one rigid body at their current relative pose.
//!
//! **The impulse–momentum balance.** With `ν = [V_B; q̇]` the arm's generalized velocity, `𝓜` its
//! mass matrix (A.19) and `G = [Φ_{e,B}  J_e]` the map `V_e = G ν` to the EE twist (model §2), let
//! `X = Φ_{e,t}` carry motions from the target frame `t` to `e` at the current poses. The target's
//! twist seen at `e` is `W_e = X W`, its spatial inertia there `Y_e = X⁻ᵀ Y X⁻¹`. The grasp's
//! impulse `F` (`[moment; force]`, EE frame, about the EE origin) is what the EE exerts ON the
//! target, the sign of an EE wrench (model §2): the arm receives `−F` and the target `+F`.
//!
//! ```text
//! 𝓜 Δν = −Gᵀ F          Y_e ΔW_e = F          G ν⁺ = W_e⁺          (KKT)
//! ⇒ (Λ_e⁻¹ + Y_e⁻¹) F = G ν − W_e = V_rel,    Λ_e⁻¹ = G 𝓜⁻¹ Gᵀ
//! ν⁺ = ν − 𝓜⁻¹ Gᵀ F,   W⁺ = X⁻¹ G ν⁺
//! ΔE = ½ V_relᵀ (Λ_e⁻¹ + Y_e⁻¹)⁻¹ V_rel = ½ V_relᵀ F ≥ 0
//! ```
//!
//! `Λ_e⁻¹` is the inverse operational-space inertia of the floating arm at the EE, with the base
//! free: Yoshida's extended inversed inertia tensor. Both it and `Y_e⁻¹` are positive definite,
//! so `ΔE = 0` iff `V_rel = 0`.
//!
//! **Why the motor rates do not jump.** Over the zero duration of an impulse only infinite forces
//! do work. The spring torque `k (θ − q) + d (θ̇ − q̇)` stays finite (angles do not jump, rates
//! jump by finite amounts), so no impulse passes through a spring: the motors, coupled to the
//! links only through the springs, keep `θ̇`, and the angles `q`, `θ` and every pose are
//! unchanged. Only `V_B` and `q̇` jump. The energy lost is the rigid kinetic energy; motor and
//! spring energies are untouched.
//!
//! **Cost.** `𝓜⁻¹ Gᵀ` is six articulated-body solves at rest with unit EE wrenches (at zero
//! velocity the forward dynamics is `−𝓜⁻¹ Gᵀ f`, and the EE's acceleration is `G` of it), so
//! the capture is O(n) plus 6×6 factorisations.

use super::target::Target;
use crate::algorithms::{self, Data};
use crate::args::{Loads, RigidState};
use crate::error::{Error, Result};
use crate::flex::FlexibleArm;
use crate::model::Robot;
use crate::spatial::{quaternion_to_rotation, Force, Inertia, Mat6, Motion, Transform, Vec3};
use nalgebra::{DMatrix, DVector};

/// What a capture produced ([`capture`]).
#[derive(Debug, Clone)]
pub struct Capture {
    /// The combined arm: the target joined to the EE's body as a payload at the relative pose of
    /// the moment of capture ([`Robot::with_payload_at`] with [`payload`](Self::payload)), the
    /// same joints and dynamics method.
    pub arm: FlexibleArm,
    /// The state just after: the same poses, `q`, `θ` and `θ̇`; the new base twist and `q̇`.
    pub x: Vec<f64>,
    /// `F`: the impulse `[moment (N·m·s); force (N·s)]` the end-effector exerts on the target,
    /// EE frame, about the EE origin (the sign of an EE wrench).
    pub impulse: Force,
    /// `½ V_relᵀ F ≥ 0` (J): the kinetic energy the grasp dissipates.
    pub energy_loss: f64,
    /// `V_rel = V_e − X W`, the EE's twist relative to the target just before, EE frame.
    pub relative_twist: Motion,
    /// `W⁺`, the target's twist just after (`t` frame): the EE's twist carried to `t`.
    pub target_twist: Motion,
    /// The target as the payload joined to the EE: mass, centre of mass and rotational inertia
    /// about the EE origin, EE frame, built by [`Inertia::from_com`] from
    /// [`payload_com`](Self::payload_com) and [`payload_inertia`](Self::payload_inertia).
    pub payload: Inertia,
    /// The target's centre of mass in the EE frame (m).
    pub payload_com: Vec3,
    /// The target's rotational inertia about its centre of mass, EE axes (kg·m², symmetric).
    pub payload_inertia: crate::spatial::Mat3,
    /// Which end-effector grasped (an index into [`Robot::end_effectors`]).
    pub ee: usize,
}

/// Captures `target` with end-effector `ee` (an index into [`Robot::end_effectors`]; `None` is
/// the only one) of `arm` at state `x` (model §4): the impulse–momentum balance of the module
/// docs. The target's pose and twist are those it holds.
///
/// ```
/// use orbitflex::capture::{capture, Target};
/// use orbitflex::spatial::{Mat3, Vec3};
/// use orbitflex::{FlexibleArm, FlexibleJoints, Robot};
/// let robot = Robot::space_arm();
/// let arm = FlexibleArm::new(robot, FlexibleJoints::space_arm())?;
/// let x = arm.rest_state();
/// let handle = arm.ee_pose(&x, 0); // grasp exactly at the EE, the target drifting at 1 cm/s
/// let target = Target::new(200.0, Mat3::from_diagonal(&Vec3::new(40.0, 50.0, 60.0)),
///     &handle, &[0.0, 0.0, 0.0, 0.01, 0.0, 0.0], &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])?;
/// let after = capture(&arm, &x, &target, None)?;
/// assert!(after.energy_loss > 0.0);
/// let layout = arm.layout();
/// assert_eq!(&after.x[layout.theta_dot()], &x[layout.theta_dot()]); // motors keep their rates
/// // momentum is kept: arm and target before, the combined arm after
/// let before = arm.momentum(&mut arm.workspace(), &x);
/// let after_h = after.arm.momentum(&mut after.arm.workspace(), &after.x);
/// for i in 0..6 {
///     assert!((after_h[i] - before[i] - target.momentum()[i]).abs() < 1e-12);
/// }
/// # Ok::<(), orbitflex::Error>(())
/// ```
pub fn capture(
    arm: &FlexibleArm,
    x: &[f64],
    target: &Target,
    ee: Option<usize>,
) -> Result<Capture> {
    arm.check_state(x)?;
    // with reaction wheels the bus carries their locked parts (mass, transverse inertia); their
    // free spin takes no impulse (no impulsive torque about a wheel's axis), so the grasp sees
    // the augmented bus, and each wheel keeps its absolute axial rate a·ω_B + Ω
    let robot = arm.rigid_model();
    let ee = robot.ee_choice(ee)?;
    let layout = arm.layout();
    let s = layout.split(x);
    let mut data = Data::new(robot);
    let to_ee = *robot.frame_ee_transform(ee);
    let body = robot.end_effectors()[ee].body;

    let x_et = target_to_ee(robot, &x[layout.base_pose()], s.q, target, ee);
    let (payload_com, payload_inertia) = payload_in_ee(target, &x_et);
    let payload = Inertia::from_com(target.mass(), payload_com, payload_inertia);

    // V_rel = G ν − X W
    let relative_twist =
        ee_twist(robot, &mut data, x, &layout, ee) - x_et.apply_motion(target.twist());

    let (solves, lambda_inv) = unit_impulse_responses(robot, &mut data, s.q, ee)?;
    let y_inv = payload
        .matrix()
        .cholesky()
        .ok_or_else(|| singular("the target's spatial inertia at the EE"))?
        .inverse();
    let a = symmetric(&(lambda_inv + y_inv));
    let factor = a.cholesky().ok_or_else(|| {
        singular("Λ_e⁻¹ + Y_e⁻¹ (the arm's and target's inverse inertias at the EE)")
    })?;
    let v_rel = relative_twist.to_vector();
    let impulse = factor.solve(&v_rel);
    // ½ V_relᵀ A⁻¹ V_rel = ½ |L⁻¹ V_rel|², non-negative in floating point too
    let whitened = factor
        .l()
        .solve_lower_triangular(&v_rel)
        .expect("a Cholesky factor has a positive diagonal");
    let energy_loss = 0.5 * whitened.norm_squared();

    let after = jump(arm, x, &solves, impulse.as_slice());
    let s_after = layout.split(&after);
    algorithms::velocities_unchecked(
        robot,
        &mut data,
        &RigidState::new(s_after.q, s_after.base_twist, s_after.qd),
    );
    let target_twist = x_et.apply_motion_inverse(&to_ee.apply_motion(&data.v[body]));

    let combined = combined_arm(arm, payload, ee)?;
    Ok(Capture {
        arm: combined,
        x: after,
        impulse: Force::from_vector(&impulse),
        energy_loss,
        relative_twist,
        target_twist,
        payload,
        payload_com,
        payload_inertia,
        ee,
    })
}

/// The state just after the grasp: `ν⁺ = ν − 𝓜⁻¹ Gᵀ F` (`solves` = `𝓜⁻¹ Gᵀ`, `impulse` = `F`)
/// with the motors, poses and angles at their values; each reaction wheel keeps its absolute
/// axial rate `a·ω_B + Ω`, so its speed relative to the bus drops by `a·Δω_B`.
fn jump(arm: &FlexibleArm, x: &[f64], solves: &DMatrix<f64>, impulse: &[f64]) -> Vec<f64> {
    let layout = arm.layout();
    let s = layout.split(x);
    let mut after = x.to_vec();
    let nu = DVector::from_iterator(solves.nrows(), s.base_twist.iter().chain(s.qd).copied());
    let nu_after = nu - solves * DVector::from_column_slice(impulse);
    after[layout.base_twist()].copy_from_slice(&nu_after.as_slice()[..6]);
    after[layout.qd()].copy_from_slice(&nu_after.as_slice()[6..]);
    if let Some(wheels) = arm.wheels() {
        let d_omega = Vec3::from_column_slice(&nu_after.as_slice()[..3])
            - Vec3::from_column_slice(&s.base_twist[..3]);
        for (speed, wheel) in after[layout.wheel_speed()].iter_mut().zip(wheels.wheels()) {
            *speed -= Vec3::from(wheel.axis).dot(&d_omega);
        }
    }
    after
}

/// The arm after the grasp: `payload` joined to end-effector `ee`'s body, the same joints,
/// dynamics method and reaction wheels.
fn combined_arm(arm: &FlexibleArm, payload: Inertia, ee: usize) -> Result<FlexibleArm> {
    let mut combined = FlexibleArm::new(
        arm.robot().with_payload_at(payload, ee)?,
        arm.joints().clone(),
    )?
    .with_method(arm.method());
    if let Some(wheels) = arm.wheels() {
        combined = combined.with_wheels(wheels.clone())?;
    }
    Ok(combined)
}

/// `X = Φ_{e,t}`: motions from the target frame `t` to the frame of end-effector `ee`, from the
/// inertial placements `E_e, o_e` (base pose and `Φ_{e,B}(q)`) and `E_t, o_t`:
/// `R_{e,t} = E_eᵀ E_t`, `p_{t,e} = E_tᵀ (o_e − o_t)`.
pub(crate) fn target_to_ee(
    robot: &Robot,
    base_pose: &[f64],
    q: &[f64],
    target: &Target,
    ee: usize,
) -> Transform {
    let base_axes = quaternion_to_rotation(&base_pose[3..7]);
    let base_origin = Vec3::new(base_pose[0], base_pose[1], base_pose[2]);
    let ee_from_base = algorithms::ee_from_base(robot, q, ee); // Φ_{e,B}
    let ee_axes = base_axes * ee_from_base.rotation.transpose();
    let ee_origin = base_origin + base_axes * ee_from_base.translation;
    let (target_axes, target_origin) = target.placement();
    Transform::new(
        ee_axes.tr_mul(&target_axes),
        target_axes.tr_mul(&(ee_origin - target_origin)),
    )
}

/// `V_e = G ν`: the twist of end-effector `ee` (EE frame) at the arm state `x`.
pub(crate) fn ee_twist(
    robot: &Robot,
    data: &mut Data,
    x: &[f64],
    layout: &crate::state::StateLayout,
    ee: usize,
) -> Motion {
    let s = layout.split(x);
    algorithms::velocities_unchecked(robot, data, &RigidState::new(s.q, s.base_twist, s.qd));
    let body = robot.end_effectors()[ee].body;
    robot.frame_ee_transform(ee).apply_motion(&data.v[body])
}

/// The target's centre of mass `R_{e,t} (c − p_{t,e})` and its rotational inertia about it
/// `R_{e,t} I_c R_{e,t}ᵀ` (made exactly symmetric) in the EE frame.
fn payload_in_ee(target: &Target, x_et: &Transform) -> (Vec3, crate::spatial::Mat3) {
    let r = &x_et.rotation;
    let com = r * (target.com() - x_et.translation);
    let rotated = r * target.inertia_about_com() * r.transpose();
    (com, (rotated + rotated.transpose()) * 0.5)
}

/// `𝓜⁻¹ Gᵀ` ((6+n)×6) and `Λ_e⁻¹ = G 𝓜⁻¹ Gᵀ` (symmetric): column `k` from the forward dynamics
/// at rest with the unit EE wrench `e_k`, which is `−𝓜⁻¹ Gᵀ e_k` (no bias at zero velocity);
/// the EE's classical acceleration then is `G` of it.
fn unit_impulse_responses(
    robot: &Robot,
    data: &mut Data,
    q: &[f64],
    ee: usize,
) -> Result<(DMatrix<f64>, Mat6)> {
    let n = robot.dof();
    let zeros = vec![0.0; n];
    let mut wrench = vec![0.0; 6 * robot.end_effectors().len()];
    let mut solves = DMatrix::zeros(6 + n, 6);
    let mut lambda_inv = Mat6::zeros();
    let to_ee = *robot.frame_ee_transform(ee);
    let body = robot.end_effectors()[ee].body;
    for k in 0..6 {
        wrench.fill(0.0);
        wrench[6 * ee + k] = 1.0;
        let loads = Loads {
            base_wrench: Force::ZERO,
            ee_wrench: &wrench,
        };
        let ddq = algorithms::aba(robot, data, &RigidState::at_rest(q, &zeros), &zeros, &loads)?;
        solves.set_column(k, &(-ddq));
        let ee_acc = to_ee.apply_motion(&data.acc[body]).to_vector();
        lambda_inv.set_column(k, &(-ee_acc));
    }
    Ok((solves, symmetric(&lambda_inv)))
}

fn symmetric(m: &Mat6) -> Mat6 {
    (m + m.transpose()) * 0.5
}

#[cold]
fn singular(what: &str) -> Error {
    Error::InvalidArgument {
        what: "capture".into(),
        message: format!("{what} is not positive definite here"),
    }
}

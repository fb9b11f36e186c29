//! Flexible-joint inverse dynamics by differential flatness (docs/model.md §8).
//!
//! The link angles `q` are a flat output of Spong's model: given `q(t)` and its first four time
//! derivatives at an instant, everything else follows without integrating anything.
//!
//! 1. The rigid bodies: in [`BaseMode::Held`] the base is inertially still (`V_B = 0`,
//!    `α_B = 0`) and the Newton–Euler recursion gives the joint torques `τ` and the base wrench
//!    `f_B = M_rb q̈ + C_B` that holds it. In [`BaseMode::Free`] the total momentum is zero (free
//!    floating from rest), so `V_B = −M_b⁻¹ M_rb q̇` with `M_b` the composite inertia of the whole
//!    system about the base; `α_B` is its time derivative, and (A.19) with `f_B = 0` gives `τ`.
//! 2. The joints: `τ = k δ + d δ̇` with the deflection `δ = θ − q`. With `d = 0`, `δ = τ/k`,
//!    `δ̇ = τ̇/k`, `δ̈ = τ̈/k`. With `d > 0`, `δ` obeys `d δ̇ + k δ = τ(t)` along the motion, so it
//!    depends on the motion's history: the caller passes `δ` and `δ̇ = (τ − k δ)/d`,
//!    `δ̈ = (τ̇ − k δ̇)/d` follow.
//! 3. The motors: `θ = q + δ` and `u = j θ̈ + β θ̇ + τ`.
//!
//! `τ̇` and `τ̈` come exactly from running the recursion on time jets ([`super::jets`]): every
//! body velocity is carried with its first three time derivatives, its acceleration is the
//! derivative of that jet, and forces and torques follow by the Leibniz rule.

use super::arm::FlexibleArm;
use super::jets::{derivative, joint_rotation, leibniz, solve6, Jet, TERMS};
use super::joints::FlexibleJoints;
use crate::args::check_vector;
use crate::error::{Error, Result};
use crate::model::Robot;
use crate::spatial::{Force, Mat3, Motion, Transform, Vec3};
use nalgebra::{Matrix6, Vector6};

/// What holds the base during a planned motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BaseMode {
    /// The base's actuators hold it inertially still: `V_B = 0`, `α_B = 0`; they apply
    /// `f_B = M_rb q̈ + C_B`.
    #[default]
    Held,
    /// Free floating from rest: zero total momentum, `f_B = 0`; the base moves in reaction.
    Free,
}

impl BaseMode {
    /// `"held"` or `"free"`.
    pub fn name(self) -> &'static str {
        match self {
            BaseMode::Held => "held",
            BaseMode::Free => "free",
        }
    }

    /// Parses `"held"` or `"free"`.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "held" => Ok(BaseMode::Held),
            "free" => Ok(BaseMode::Free),
            _ => Err(Error::InvalidArgument {
                what: "base".into(),
                message: format!("expected \"held\" or \"free\", given {name:?}"),
            }),
        }
    }
}

/// The link motion at one instant: `q` (rad) and its first four time derivatives (rad/s … rad/s⁴).
#[derive(Debug, Clone, Copy)]
pub struct LinkMotion<'a> {
    /// `q` (rad).
    pub q: &'a [f64],
    /// `q̇` (rad/s).
    pub qd: &'a [f64],
    /// `q̈` (rad/s²).
    pub qdd: &'a [f64],
    /// `q⃛` (rad/s³).
    pub qddd: &'a [f64],
    /// `q⁗` (rad/s⁴).
    pub qdddd: &'a [f64],
}

impl LinkMotion<'_> {
    /// Checks every part for length `n` and finiteness.
    pub fn check(&self, n: usize) -> Result<()> {
        for (what, v) in [
            ("q", self.q),
            ("qd", self.qd),
            ("qdd", self.qdd),
            ("qddd", self.qddd),
            ("qdddd", self.qdddd),
        ] {
            check_vector(what, v, n)?;
        }
        Ok(())
    }

    /// Joint `i`'s angle jet `[q, q̇, q̈, q⃛]` and rate jet `[q̇, q̈, q⃛, q⁗]`.
    fn jets(&self, i: usize) -> (Jet<f64>, Jet<f64>) {
        (
            [self.q[i], self.qd[i], self.qdd[i], self.qddd[i]],
            [self.qd[i], self.qdd[i], self.qddd[i], self.qdddd[i]],
        )
    }
}

/// The result of [`FlexibleArm::inverse_dynamics`]: what the motors and the base do so that the
/// links move as given. Joint quantities are link side (n each); base quantities are in the base
/// frame, `[angular; linear]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FlexibleInverse {
    /// Motor angles `θ = q + δ` (rad).
    pub theta: Vec<f64>,
    /// `θ̇` (rad/s).
    pub theta_dot: Vec<f64>,
    /// `θ̈` (rad/s²).
    pub theta_ddot: Vec<f64>,
    /// Motor torques `u = j θ̈ + β θ̇ + τ` (N·m).
    pub u: Vec<f64>,
    /// Spring torques `τ = k δ + d δ̇` acting on the links (N·m), equal to the rigid inverse
    /// dynamics.
    pub tau: Vec<f64>,
    /// `V_B = [ω_B; v_B]` (rad/s, m/s): zero when held.
    pub base_twist: [f64; 6],
    /// The classical base acceleration `α_B = [ω̇_B; v̇_B + ω_B × v_B]` as in (A.19): zero when
    /// held.
    pub base_acc: [f64; 6],
    /// `f_B = [moment; force]` (N·m, N) the base actuators apply: zero when free.
    pub base_wrench: [f64; 6],
}

impl FlexibleInverse {
    /// All zeros, for `n` joints.
    pub fn zeros(n: usize) -> Self {
        Self {
            theta: vec![0.0; n],
            theta_dot: vec![0.0; n],
            theta_ddot: vec![0.0; n],
            u: vec![0.0; n],
            tau: vec![0.0; n],
            base_twist: [0.0; 6],
            base_acc: [0.0; 6],
            base_wrench: [0.0; 6],
        }
    }

    /// Joint `i`'s motor side (step 3 of the module docs) from its link motion
    /// `link = [q, q̇, q̈]`, its deflection `[δ, δ̇, δ̈]` and its spring torque `τ`:
    /// `θ = q + δ`, `θ̇ = q̇ + δ̇`, `θ̈ = q̈ + δ̈`, `u = j θ̈ + β θ̇ + τ`.
    #[inline]
    pub(crate) fn set_joint(
        &mut self,
        joints: &FlexibleJoints,
        i: usize,
        link: [f64; 3],
        deflection: [f64; 3],
        tau: f64,
    ) {
        let [q, qd, qdd] = link;
        let [delta, rate, acc] = deflection;
        self.theta[i] = q + delta;
        self.theta_dot[i] = qd + rate;
        self.theta_ddot[i] = qdd + acc;
        self.tau[i] = tau;
        self.u[i] = joints.motor_inertia[i] * self.theta_ddot[i]
            + joints.motor_damping[i] * self.theta_dot[i]
            + tau;
    }
}

/// The rigid-body dynamics along a motion, as time jets.
#[derive(Debug, Clone)]
pub(crate) struct RigidJets {
    /// `τ_i` with `τ̇_i`, `τ̈_i` (the last term is not known).
    pub tau: Vec<Jet<f64>>,
    /// `V_B` (body components) and its first three derivatives; zero when held.
    pub base_twist: Jet<Motion>,
    /// `f_B` with two derivatives; zero when free.
    pub base_wrench: Jet<Force>,
}

/// Scratch memory for the jet recursion.
#[derive(Debug, Clone)]
pub(crate) struct JetScratch {
    rotation: Vec<Jet<Mat3>>,
    velocity: Vec<Jet<Motion>>,
    force: Vec<Jet<Force>>,
    q: Vec<Jet<f64>>,
    qd: Vec<Jet<f64>>,
}

impl JetScratch {
    pub fn new(robot: &Robot) -> Self {
        let bodies = robot.dof() + 1;
        Self {
            rotation: vec![[Mat3::identity(); TERMS]; bodies],
            velocity: vec![[Motion::zero(); TERMS]; bodies],
            force: vec![[Force::zero(); TERMS]; bodies],
            q: vec![[0.0; TERMS]; robot.dof()],
            qd: vec![[0.0; TERMS]; robot.dof()],
        }
    }

    /// Sets joint `i`'s angle and rate jets.
    pub fn set_joint(&mut self, i: usize, q: Jet<f64>, qd: Jet<f64>) {
        self.q[i] = q;
        self.qd[i] = qd;
    }
}

/// `Φ(t) V(t)` for a joint transform whose rotation is the jet `rotation` about a fixed offset.
fn transform_motion(rotation: &Jet<Mat3>, offset: &Vec3, v: &Jet<Motion>) -> Jet<Motion> {
    leibniz(rotation, v, |r, m| {
        Transform::new(*r, *offset).apply_motion(m)
    })
}

/// `Φ(t)ᵀ f(t)`.
fn transform_force_transpose(rotation: &Jet<Mat3>, offset: &Vec3, f: &Jet<Force>) -> Jet<Force> {
    leibniz(rotation, f, |r, x| {
        Transform::new(*r, *offset).apply_force_transpose(x)
    })
}

/// Body velocities from the base twist jet and the joint jets in `s` (A.4):
/// `V_i = Φ_{i,λ} V_λ + h_i q̇_i`. With `joint_rates = false`, `q̇ = 0` (the base alone moves).
fn velocities(robot: &Robot, s: &mut JetScratch, base: Jet<Motion>, joint_rates: bool) {
    s.velocity[0] = base;
    for i in 1..=robot.dof() {
        let joint = &robot.joints()[i - 1];
        let mut v = transform_motion(
            &s.rotation[i],
            &joint.origin.translation,
            &s.velocity[robot.parents()[i]],
        );
        if joint_rates {
            for (vk, rate) in v.iter_mut().zip(s.qd[i - 1]) {
                vk.angular += joint.axis * rate;
            }
        }
        s.velocity[i] = v;
    }
}

/// The total momentum about the base origin in base components, for the velocities in `s`.
fn momentum(robot: &Robot, s: &mut JetScratch) -> Jet<Force> {
    for ((force, velocity), inertia) in s.force.iter_mut().zip(&s.velocity).zip(robot.inertias()) {
        *force = velocity.map(|v| inertia.apply(&v));
    }
    gather(robot, s)
}

/// Adds every body's force into its parent's, tip to base, and returns the base's.
fn gather(robot: &Robot, s: &mut JetScratch) -> Jet<Force> {
    for i in (1..=robot.dof()).rev() {
        let joint = &robot.joints()[i - 1];
        let moved =
            transform_force_transpose(&s.rotation[i], &joint.origin.translation, &s.force[i]);
        let parent = &mut s.force[robot.parents()[i]];
        for (p, m) in parent.iter_mut().zip(moved) {
            *p += m;
        }
    }
    s.force[0]
}

fn as_vector(f: &Force) -> Vector6<f64> {
    Vector6::from_column_slice(&f.to_array())
}

/// The rigid dynamics along the motion whose joint jets are in `s`: the joint torques and the
/// base twist and wrench, each with their time derivatives.
pub(crate) fn rigid_jets(robot: &Robot, s: &mut JetScratch, base: BaseMode) -> Result<RigidJets> {
    let n = robot.dof();
    for i in 1..=n {
        let joint = &robot.joints()[i - 1];
        s.rotation[i] = joint_rotation(&joint.axis, &s.q[i - 1], &joint.origin.rotation);
    }
    let base_twist = match base {
        BaseMode::Held => [Motion::zero(); TERMS],
        BaseMode::Free => free_base_twist(robot, s)?,
    };
    // Newton–Euler on jets: the acceleration is the derivative of the body-frame velocity
    // jet, so f_i = I_i V̇_i + V_i ×* I_i V_i (the spatial form of (A.8)).
    velocities(robot, s, base_twist, true);
    for ((force, v), inertia) in s.force.iter_mut().zip(&s.velocity).zip(robot.inertias()) {
        let momentum = v.map(|vk| inertia.apply(&vk));
        let acc = derivative(v);
        let bias = leibniz(v, &momentum, |a, b| a.cross_force(b));
        *force = std::array::from_fn(|k| inertia.apply(&acc[k]) + bias[k]);
    }
    let base_wrench = gather(robot, s);
    let tau = (1..=n)
        .map(|i| s.force[i].map(|f| robot.joints()[i - 1].axis.dot(&f.angular)))
        .collect();
    Ok(RigidJets {
        tau,
        base_twist,
        base_wrench: match base {
            BaseMode::Held => base_wrench,
            BaseMode::Free => [Force::zero(); TERMS],
        },
    })
}

/// The system centre of mass relative to the base origin, base frame (m), at the joint angles
/// whose rotation jets `s` holds (set by [`rigid_jets`]). A unit base translation `v = e_k` with
/// the joints still moves every body at `e_k`, so the momentum about the base origin is
/// `[m r_c × e_k; m e_k]`: `m r_c × e_x = m (0, c_z, −c_y)` and `m r_c × e_y = m (−c_z, 0, c_x)`.
pub(crate) fn system_com(robot: &Robot, s: &mut JetScratch) -> Vec3 {
    let mut unit_momentum = |k: usize| {
        let mut twist = [Motion::zero(); TERMS];
        let mut unit = [0.0; 6];
        unit[3 + k] = 1.0;
        twist[0] = Motion::from_slice(&unit);
        velocities(robot, s, twist, false);
        momentum(robot, s)[0]
    };
    let (hx, hy) = (unit_momentum(0), unit_momentum(1));
    let mass = hx.linear.x;
    Vec3::new(hy.angular.z, -hx.angular.z, hx.angular.y) / mass
}

/// `V_B` with zero total momentum: `M_b(t) V_B(t) = −h_arm(t)`, where `M_b` is the composite
/// inertia of all bodies about the base (its columns are the momenta of unit base twists) and
/// `h_arm` the momentum of the joint rates with the base still; solved order by order.
fn free_base_twist(robot: &Robot, s: &mut JetScratch) -> Result<Jet<Motion>> {
    let mut composite = [Matrix6::zeros(); TERMS];
    for c in 0..6 {
        let mut unit = [0.0; 6];
        unit[c] = 1.0;
        let mut twist = [Motion::zero(); TERMS];
        twist[0] = Motion::from_slice(&unit);
        velocities(robot, s, twist, false);
        let h = momentum(robot, s);
        for (m, hk) in composite.iter_mut().zip(h) {
            m.set_column(c, &as_vector(&hk));
        }
    }
    velocities(robot, s, [Motion::zero(); TERMS], true);
    let arm = momentum(robot, s).map(|h| -as_vector(&h));
    let twist = solve6(&composite, &arm).ok_or_else(|| Error::InvalidModel {
        source_name: robot.source().to_string(),
        message: "the composite inertia about the base is singular".into(),
    })?;
    Ok(twist.map(|v| Motion::from_slice(v.as_slice())))
}

/// The joint deflection `δ = θ − q` and its first two rates, given `τ` with two derivatives.
/// With `d_i = 0`: `δ = τ/k` and so on. With `d_i > 0`: `δ` is the given `deflection` and the
/// rates follow from `d δ̇ + k δ = τ`.
pub(crate) fn deflection_rates(
    k: f64,
    d: f64,
    tau: &Jet<f64>,
    deflection: Option<f64>,
) -> [f64; 3] {
    match deflection {
        Some(delta) if d > 0.0 => {
            let rate = (tau[0] - k * delta) / d;
            [delta, rate, (tau[1] - k * rate) / d]
        }
        _ => [tau[0] / k, tau[1] / k, tau[2] / k],
    }
}

impl FlexibleArm {
    /// Flexible-joint inverse dynamics (module [`crate::flex::inverse`]): the motor angles,
    /// rates, accelerations and torques, the spring torques, and the base twist, acceleration and
    /// wrench that make the links move with `motion` (no external wrench on the EE).
    ///
    /// `base` is [`BaseMode::Held`] (the base is held inertially still and the result says with
    /// which wrench) or [`BaseMode::Free`] (free floating with zero momentum, as from rest).
    ///
    /// `deflection`, the current `θ − q` (rad, n), is needed exactly when some joint has damping
    /// `d > 0`: then the deflection obeys `d δ̇ + k δ = τ` along the motion and is not a function
    /// of the instant. [`crate::planning::plan_slew`] integrates it exactly. With `d = 0` it
    /// must be omitted (`θ = q + τ/k`).
    ///
    /// ```
    /// use orbitflex::{BaseMode, FlexibleArm, FlexibleJoints, LinkMotion, Robot};
    /// let robot = Robot::space_arm();
    /// let n = robot.dof();
    /// // k = 2e4 N·m/rad, j = 1 kg·m², no damping
    /// let arm = FlexibleArm::new(robot, FlexibleJoints::uniform(n, 2e4, 1.0, 0.0, 0.0)?)?;
    /// let (q, zero, acc) = (vec![0.2; n], vec![0.0; n], vec![0.5; n]);
    /// let motion = LinkMotion { q: &q, qd: &zero, qdd: &acc, qddd: &zero, qdddd: &zero };
    /// let out = arm.inverse_dynamics(&motion, BaseMode::Held, None)?;
    /// for i in 0..n {
    ///     assert!((out.theta[i] - q[i] - out.tau[i] / 2e4).abs() < 1e-15); // θ = q + τ/k
    ///     assert!((out.u[i] - (out.theta_ddot[i] + out.tau[i])).abs() < 1e-12); // u = j θ̈ + τ
    /// }
    /// # Ok::<(), orbitflex::Error>(())
    /// ```
    pub fn inverse_dynamics(
        &self,
        motion: &LinkMotion,
        base: BaseMode,
        deflection: Option<&[f64]>,
    ) -> Result<FlexibleInverse> {
        let n = self.dof();
        motion.check(n)?;
        let joints = self.joints();
        deflection_given_if_damped(joints, deflection, n)?;
        let mut scratch = JetScratch::new(self.rigid_model());
        for i in 0..n {
            let (q, qd) = motion.jets(i);
            scratch.set_joint(i, q, qd);
        }
        let rigid = rigid_jets(self.rigid_model(), &mut scratch, base)?;
        let mut out = FlexibleInverse {
            theta: vec![0.0; n],
            theta_dot: vec![0.0; n],
            theta_ddot: vec![0.0; n],
            u: vec![0.0; n],
            tau: vec![0.0; n],
            base_twist: rigid.base_twist[0].to_array(),
            base_acc: classical(&rigid.base_twist),
            base_wrench: rigid.base_wrench[0].to_array(),
        };
        for i in 0..n {
            let tau = &rigid.tau[i];
            let deflection = deflection_rates(
                joints.stiffness[i],
                joints.damping[i],
                tau,
                deflection.map(|d| d[i]),
            );
            let link = [motion.q[i], motion.qd[i], motion.qdd[i]];
            out.set_joint(joints, i, link, deflection, tau[0]);
        }
        out.check_finite(deflection)?;
        Ok(out)
    }
}

/// `deflection` is given (`n` finite values) exactly when some joint is damped: see
/// [`FlexibleArm::inverse_dynamics`].
fn deflection_given_if_damped(
    joints: &FlexibleJoints,
    deflection: Option<&[f64]>,
    n: usize,
) -> Result<()> {
    let damped = joints.damping.iter().any(|&d| d > 0.0);
    match (damped, deflection) {
        (true, None) => Err(Error::InvalidArgument {
            what: "deflection".into(),
            message: "the joints have damping d > 0, so the deflection θ − q depends on \
                      the motion's history; pass the current deflection (n values, rad), \
                      or plan the whole motion with plan_slew"
                .into(),
        }),
        (false, Some(_)) => Err(Error::InvalidArgument {
            what: "deflection".into(),
            message: "every joint has damping d = 0, so θ − q = τ/k is determined by \
                      the instant; omit the deflection"
                .into(),
        }),
        (_, Some(delta)) => check_vector("deflection", delta, n),
        _ => Ok(()),
    }
}

impl FlexibleInverse {
    /// An error unless every number is finite: one naming the deflection when only the motor
    /// side overflowed from it, otherwise one naming the motion.
    fn check_finite(&self, deflection: Option<&[f64]>) -> Result<()> {
        let finite = [
            &self.theta[..],
            &self.theta_dot,
            &self.theta_ddot,
            &self.u,
            &self.base_twist,
            &self.base_acc,
            &self.base_wrench,
        ]
        .iter()
        .all(|v| v.iter().all(|x| x.is_finite()));
        let rigid_finite = [
            &self.tau[..],
            &self.base_twist,
            &self.base_acc,
            &self.base_wrench,
        ]
        .iter()
        .all(|v| v.iter().all(|x| x.is_finite()));
        if let (false, true, Some(delta)) = (finite, rigid_finite, deflection) {
            // the links' dynamics are finite: the motor side overflowed, from the deflection
            crate::overflow::check_result(
                "inverse_dynamics",
                &[&self.theta, &self.theta_dot, &self.theta_ddot, &self.u],
                &[("deflection", delta, 1)],
            )?;
        }
        if !finite {
            return Err(Error::InvalidArgument {
                what: "motion".into(),
                message: "too large for floating point: the inverse dynamics of q, qd, qdd, \
                          qddd, qdddd overflowed (the torques grow as q̇² and the motor terms \
                          with the higher derivatives)"
                    .into(),
            });
        }
        Ok(())
    }
}

/// The classical acceleration `[ω̇; v̇ + ω × v]` of a body-frame twist jet.
pub(crate) fn classical(twist: &Jet<Motion>) -> [f64; 6] {
    let (v, rate) = (&twist[0], &twist[1]);
    Motion::new(rate.angular, rate.linear + v.angular.cross(&v.linear)).to_array()
}

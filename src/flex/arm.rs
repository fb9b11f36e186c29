//! [`FlexibleArm`]: a floating-base arm with Spong flexible joints, its state derivative and the
//! quantities an engineer checks a run against (energy, momentum, EE pose).

use super::jacobians::{self, Jacobians, StepScratch};
use super::joints::FlexibleJoints;
use super::stability::{self, StabilityLimit};
use super::wheels::ReactionWheels;
use crate::algorithms::{self, Data};
use crate::args::{check_base_pose, check_length, check_vector, Loads, RigidState};
use crate::control::Controller;
use crate::dynamics::{momentum_in_inertial_frame, Method};
use crate::error::{Error, Result};
use crate::model::Robot;
use crate::overflow::{check_result_named, Input};
use crate::spatial::{base_pose_rate, normalise_quaternion, quaternion_to_rotation, Vec3};
use crate::state::{StateLayout, StateParts};

/// A floating-base arm with Spong flexible joints: the robot, its joint parameters and the
/// rigid-body dynamics method used by [`FlexibleArm::derivative`].
///
/// ```
/// use orbitflex::{FlexibleArm, FlexibleJoints, Inputs, Robot, StateSpec};
/// let robot = Robot::space_arm();
/// let n = robot.dof();
/// let arm = FlexibleArm::new(robot, FlexibleJoints::uniform(n, 2e4, 1.0, 2.0, 1.0)?)?;
/// let q = vec![0.1; n];
/// let x = arm.state(&StateSpec { q: Some(&q), ..StateSpec::default() })?;
/// let mut ws = arm.workspace(); // the integrator's workspace, which holds a `ModelWorkspace`
/// let mut xdot = vec![0.0; x.len()];
/// arm.derivative(&mut ws, &x, &Inputs::torques(&vec![1.0; n]), &mut xdot)?;
/// // θ̈ = (u − τ − β θ̇) / j with relaxed springs and motors at rest: u / j = 1
/// assert!((xdot[arm.layout().theta_dot()][0] - 1.0).abs() < 1e-12);
/// # Ok::<(), orbitflex::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct FlexibleArm {
    robot: Robot,
    joints: FlexibleJoints,
    method: Method,
    /// The reaction wheels and the rigid model they make, if any ([`FlexibleArm::with_wheels`]).
    wheels: Option<Box<Mounted>>,
}

/// Reaction wheels mounted on the bus: the wheels, and the robot whose base inertia includes
/// their locked parts ([`ReactionWheels::locked_inertia`]), built once.
#[derive(Debug, Clone)]
pub(super) struct Mounted {
    pub(super) wheels: ReactionWheels,
    pub(super) robot: Robot,
}

/// The inputs held over a step: motor torques `u` (n, link side, N·m), the external [`Loads`]
/// and the reaction-wheel torque commands.
#[derive(Debug, Clone, Copy)]
pub struct Inputs<'a> {
    /// Motor torques `u` (N·m), reflected to the link side.
    pub u: &'a [f64],
    /// `f_B` (base frame) and `[f_1; …; f_k]` (each in its EE frame, exerted by the
    /// end-effector on its environment).
    pub loads: Loads<'a>,
    /// Torques commanded to the reaction wheels (N·m, applied to each wheel about its axis; the
    /// bus feels the opposite), one per wheel, or empty for none. Saturated once per step
    /// ([`ReactionWheels::saturate`]).
    pub wheel_torque: &'a [f64],
}

impl<'a> Inputs<'a> {
    /// Motor torques `u` and no external load.
    pub fn torques(u: &'a [f64]) -> Self {
        Self {
            u,
            loads: Loads::ZERO,
            wheel_torque: &[],
        }
    }

    /// Checks `u` against the robot's `n` joints, and the loads for finiteness and one wrench
    /// per end-effector (or none).
    pub fn check(&self, robot: &Robot) -> Result<()> {
        check_vector("u", self.u, robot.dof())?;
        self.loads.check_for(robot)
    }
}

/// The parts of a state given to [`FlexibleArm::state`]; `None` takes the default.
#[derive(Debug, Clone, Copy, Default)]
pub struct StateSpec<'a> {
    /// Link angles `q` (rad); default zero.
    pub q: Option<&'a [f64]>,
    /// Motor angles `θ` (rad, link side); default `q` (relaxed springs).
    pub theta: Option<&'a [f64]>,
    /// Link rates `q̇` (rad/s); default zero.
    pub qd: Option<&'a [f64]>,
    /// Motor rates `θ̇` (rad/s); default zero.
    pub theta_dot: Option<&'a [f64]>,
    /// `[r_B; quat_B (x, y, z, w)]`; default the origin with identity attitude.
    pub base_pose: Option<&'a [f64]>,
    /// `[ω_B; v_B]` (base frame); default at rest.
    pub base_twist: Option<&'a [f64]>,
}

/// Scratch memory of the model's calls on one [`FlexibleArm`]: the rigid-body [`Data`], the
/// spring torques and, from the first [`FlexibleArm::step_jacobians`] on, that call's O(n²)
/// buffers (reused by the next calls). One per thread. The integrator's `ArmWorkspace` (made by
/// `FlexibleArm::workspace`) holds one and the RK4 stages, and stands in for it wherever a
/// `&mut ModelWorkspace` is asked for.
#[derive(Debug, Clone)]
pub struct ModelWorkspace {
    pub(crate) data: Data,
    pub(crate) tau: Vec<f64>,
    /// The step Jacobians' buffers, sized by their first call.
    pub(crate) jacobians: StepScratch,
    /// The wheel torques applied over a step (k), after saturation.
    pub(crate) wheel_torque: Vec<f64>,
}

impl ModelWorkspace {
    /// Buffers for `arm`.
    pub fn new(arm: &FlexibleArm) -> Self {
        Self {
            data: Data::new(&arm.robot),
            tau: vec![0.0; arm.robot.dof()],
            jacobians: StepScratch::default(),
            wheel_torque: vec![0.0; arm.layout().wheels],
        }
    }

    pub(crate) fn check(&self, arm: &FlexibleArm) -> Result<()> {
        algorithms::check_data(&arm.robot, &self.data)
    }
}

impl FlexibleArm {
    /// Couples a robot with joint parameters of matching length.
    pub fn new(robot: Robot, joints: FlexibleJoints) -> Result<Self> {
        if joints.len() != robot.dof() {
            return Err(Error::Dimension {
                what: "FlexibleJoints".into(),
                expected: format!("{} joints (the robot's dof)", robot.dof()),
                given: format!("{} joints", joints.len()),
            });
        }
        Ok(Self {
            robot,
            joints,
            method: Method::Recursive,
            wheels: None,
        })
    }

    /// This arm with reaction wheels on its bus (replacing any it had). The robot's base inertia
    /// excludes the wheels: the model adds their masses and locked inertias to it once, here
    /// ([`ReactionWheels::locked_inertia`]); [`robot`](Self::robot) stays the robot given. The
    /// state gains the `k` wheel speeds at its end ([`StateLayout::wheel_speed`]).
    pub fn with_wheels(mut self, wheels: ReactionWheels) -> Result<Self> {
        let base = self.robot.inertias()[0].add(&wheels.locked_inertia());
        let robot = self.robot.with_base_inertia(base)?;
        self.wheels = Some(Box::new(Mounted { wheels, robot }));
        Ok(self)
    }

    /// The reaction wheels on the bus, if any.
    pub fn wheels(&self) -> Option<&ReactionWheels> {
        self.wheels.as_ref().map(|m| &m.wheels)
    }

    /// The rigid model the dynamics run on: [`robot`](Self::robot), its base inertia augmented
    /// by the wheels' locked parts when there are wheels.
    #[inline]
    pub fn rigid_model(&self) -> &Robot {
        self.wheels.as_ref().map_or(&self.robot, |m| &m.robot)
    }

    /// Checks `inputs` for this arm: [`Inputs::check`], and wheel torques of length `k` (or
    /// none), finite.
    pub fn check_inputs(&self, inputs: &Inputs) -> Result<()> {
        inputs.check(&self.robot)?;
        match self.wheels() {
            Some(wheels) => wheels.check_torque(inputs.wheel_torque),
            None if inputs.wheel_torque.is_empty() => Ok(()),
            None => Err(Error::Dimension {
                what: "wheel_torque".into(),
                expected: "none (the arm has no reaction wheels)".into(),
                given: format!("length {}", inputs.wheel_torque.len()),
            }),
        }
    }

    /// The wheel torques applied over a step from `x` ([`ReactionWheels::saturate`] of the
    /// commands in `inputs`) into `applied` (k; untouched without wheels).
    #[inline]
    pub(crate) fn saturate_wheels(&self, x: &[f64], inputs: &Inputs, applied: &mut [f64]) {
        if let Some(m) = &self.wheels {
            let speed = &x[self.layout().wheel_speed()];
            m.wheels.saturate(inputs.wheel_torque, speed, applied);
        }
    }

    /// An error for the calls not yet available with reaction wheels.
    fn refuse_wheels(&self, call: &str) -> Result<()> {
        match self.wheels {
            Some(_) => Err(Error::InvalidArgument {
                what: call.into(),
                message: "not available yet for an arm with reaction wheels".into(),
            }),
            None => Ok(()),
        }
    }

    /// Selects the rigid-body dynamics used by the derivative (default: recursive).
    pub fn with_method(mut self, method: Method) -> Self {
        self.method = method;
        self
    }

    /// The dynamics method in use.
    pub fn method(&self) -> Method {
        self.method
    }

    /// The rigid robot.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The joint parameters.
    pub fn joints(&self) -> &FlexibleJoints {
        &self.joints
    }

    /// Number of joints `n`.
    pub fn dof(&self) -> usize {
        self.robot.dof()
    }

    /// The layout of the state vector.
    pub fn layout(&self) -> StateLayout {
        StateLayout::with_wheels(
            self.robot.dof(),
            self.wheels().map_or(0, ReactionWheels::len),
        )
    }

    /// Builds a state `x` (model §4) from the parts in `spec`. Defaults: zero angles and rates,
    /// base at the origin with identity attitude, at rest; `θ = q` (relaxed springs). The
    /// quaternion is normalised.
    pub fn state(&self, spec: &StateSpec) -> Result<Vec<f64>> {
        let layout = self.layout();
        let mut x = vec![0.0; layout.len()];
        x[layout.quaternion().end - 1] = 1.0;
        if let Some(pose) = spec.base_pose {
            check_base_pose(pose)?;
        }
        for (what, value, range) in [
            ("q", spec.q, layout.q()),
            ("theta", spec.theta.or(spec.q), layout.theta()),
            ("qd", spec.qd, layout.qd()),
            ("theta_dot", spec.theta_dot, layout.theta_dot()),
            ("base_pose", spec.base_pose, layout.base_pose()),
            ("base_twist", spec.base_twist, layout.base_twist()),
        ] {
            if let Some(v) = value {
                check_vector(what, v, range.len())?;
                x[range].copy_from_slice(v);
            }
        }
        normalise_quaternion(&mut x[layout.quaternion()]);
        Ok(x)
    }

    /// The state at rest: zero angles and rates, base at the origin, identity attitude.
    pub fn rest_state(&self) -> Vec<f64> {
        self.state(&StateSpec::default())
            .expect("the default state is valid")
    }

    /// Checks a state vector's length, finiteness and quaternion.
    pub fn check_state(&self, x: &[f64]) -> Result<()> {
        let layout = self.layout();
        check_vector("x (state)", x, layout.len())?;
        check_base_pose(&x[layout.base_pose()])
    }

    /// Length `12 + 4n` of the tangent `dx` ([`StateLayout::tangent_len`]).
    pub fn tangent_size(&self) -> usize {
        self.layout().tangent_len()
    }

    /// `x ⊕ dx`: `r_B + δr_B`, `quat_B ⊗ Exp(δφ_B)`, every other block added
    /// ([`StateLayout::integrate`]). Checked: `x` a state, `dx` of length `12 + 4n`, finite.
    pub fn integrate(&self, x: &[f64], dx: &[f64]) -> Result<Vec<f64>> {
        self.check_state(x)?;
        check_vector("dx", dx, self.tangent_size())?;
        let mut out = vec![0.0; x.len()];
        self.layout().integrate(x, dx, &mut out);
        self.check_overflow("integrate", &[&out], &[("dx", dx, 1), ("x", x, 1)])?;
        Ok(out)
    }

    /// `x1 ⊖ x0`, the tangent with `integrate(x0, difference(x0, x1)) = x1`
    /// ([`StateLayout::difference`]). Both states are checked; their quaternions are
    /// normalised first.
    pub fn difference(&self, x0: &[f64], x1: &[f64]) -> Result<Vec<f64>> {
        self.check_state(x0)?;
        self.check_state(x1)?;
        let layout = self.layout();
        let (mut a, mut b) = (x0.to_vec(), x1.to_vec());
        normalise_quaternion(&mut a[layout.quaternion()]);
        normalise_quaternion(&mut b[layout.quaternion()]);
        let mut out = vec![0.0; self.tangent_size()];
        layout.difference(&a, &b, &mut out);
        self.check_overflow("difference", &[&out], &[("x1", x1, 1), ("x0", x0, 1)])?;
        Ok(out)
    }

    /// `ẋ` (model §4) into `xdot`:
    ///
    /// ```text
    /// ṙ_B = R_B v_B,   quat_B' = ½ quat_B ⊗ (ω_B, 0)
    /// τ = k (θ − q) + d (θ̇ − q̇)
    /// [α_B; q̈] = 𝓜⁻¹ ([f_B; τ] − [C_B; C_r] − [Φ_{n+1,B}ᵀ; Jᵀ] f)          (A.19)
    /// ω̇_B = α_B[0:3],  v̇_B = α_B[3:6] − ω_B × v_B,  θ̈ = (u − τ − β θ̇) / j
    /// ```
    /// With reaction wheels ([`super::wheels`]) the rigid model is the augmented one, `f_B`
    /// gains the wheels' moment `Σ n_w` (W2), and `Ω̇ = (u_w − c Ω)/J_s − a·ω̇_B` (W1), with the
    /// wheel torques saturated at `x` as a step from `x` would apply them.
    pub fn derivative(
        &self,
        ws: &mut ModelWorkspace,
        x: &[f64],
        inputs: &Inputs,
        xdot: &mut [f64],
    ) -> Result<()> {
        ws.check(self)?;
        self.check_state(x)?;
        self.check_inputs(inputs)?;
        check_length("xdot", xdot.len(), self.layout().len())?;
        self.saturate_wheels(x, inputs, &mut ws.wheel_torque);
        let applied = Inputs {
            wheel_torque: &ws.wheel_torque,
            ..*inputs
        };
        self.derivative_unchecked(&mut ws.data, &mut ws.tau, x, &applied, xdot)?;
        let base_wrench = inputs.loads.base_wrench.to_array();
        self.check_overflow(
            "derivative",
            &[xdot],
            &overflow_inputs(x, inputs, &base_wrench, None),
        )
    }

    /// The derivative without argument checks; allocation-free on the recursive path. `tau`
    /// receives the spring torques. The wheel torques in `inputs` are applied as given (already
    /// saturated).
    pub(crate) fn derivative_unchecked(
        &self,
        data: &mut Data,
        tau: &mut [f64],
        x: &[f64],
        inputs: &Inputs,
        xdot: &mut [f64],
    ) -> Result<()> {
        let layout = self.layout();
        // split once: the spring torques and the assembly read the same blocks
        let s = layout.split(x);
        self.spring_torque_of(&s, tau);
        let rigid = RigidState::new(s.q, s.base_twist, s.qd);
        if let Some(m) = &self.wheels {
            return super::wheels::derivative_with_wheels(self, m, data, tau, x, inputs, xdot);
        }
        self.method
            .forward_dynamics_unchecked(&self.robot, data, &rigid, tau, &inputs.loads)?;
        self.assemble_derivative_of(&s, inputs, tau, data.ddq.as_slice(), xdot);
        Ok(())
    }

    /// The state derivative at `x` from the spring torques `tau` and the rigid accelerations
    /// `acc = [α_B; q̈]` already computed there.
    #[inline]
    pub(crate) fn assemble_derivative(
        &self,
        x: &[f64],
        inputs: &Inputs,
        tau: &[f64],
        acc: &[f64],
        xdot: &mut [f64],
    ) {
        self.assemble_derivative_of(&self.layout().split(x), inputs, tau, acc, xdot);
    }

    /// [`assemble_derivative`](Self::assemble_derivative) from the blocks of `x`, already split.
    #[inline]
    fn assemble_derivative_of(
        &self,
        s: &StateParts,
        inputs: &Inputs,
        tau: &[f64],
        acc: &[f64],
        xdot: &mut [f64],
    ) {
        let layout = self.layout();
        let (omega, v) = (s.omega(), s.velocity());
        base_pose_rate(s.quaternion, &omega, &v, &mut xdot[layout.base_pose()]);
        xdot[layout.q()].copy_from_slice(s.qd);
        xdot[layout.theta()].copy_from_slice(s.theta_dot);
        let v_dot = Vec3::new(acc[3], acc[4], acc[5]) - omega.cross(&v);
        let twist_rate = &mut xdot[layout.base_twist()];
        twist_rate[..3].copy_from_slice(&acc[..3]);
        twist_rate[3..].copy_from_slice(v_dot.as_slice());
        xdot[layout.qd()].copy_from_slice(&acc[6..]);
        let p = &self.joints;
        let motors = xdot[layout.theta_dot()].iter_mut().zip(inputs.u).zip(tau);
        let params = p
            .motor_damping
            .iter()
            .zip(&p.motor_inertia)
            .zip(s.theta_dot);
        for (((motor, u), tau), ((damping, inertia), rate)) in motors.zip(params) {
            *motor = (u - tau - damping * rate) / inertia;
        }
    }

    /// The Jacobians of [`derivative`](Self::derivative) at `x` with `inputs`, in tangent
    /// coordinates: `d(dx)/dt = F dx + G du + G_B df_B + G_E df + G_W du_W`
    /// ([`super::jacobians`]). With reaction wheels the tangent ends with `δΩ` (k) and `G_W` is
    /// the wheel torque commands' ([`super::wheels`], (W1) and (W2) differentiated).
    pub fn derivative_jacobians(
        &self,
        ws: &mut ModelWorkspace,
        x: &[f64],
        inputs: &Inputs,
    ) -> Result<Jacobians> {
        ws.check(self)?;
        self.check_state(x)?;
        self.check_inputs(inputs)?;
        let mut x = x.to_vec();
        normalise_quaternion(&mut x[self.layout().quaternion()]);
        self.saturate_wheels(&x, inputs, &mut ws.wheel_torque);
        let out = jacobians::derivative_jacobians(self, ws, &x, inputs)?;
        let base_wrench = inputs.loads.base_wrench.to_array();
        self.check_overflow(
            "derivative_jacobians",
            &out.blocks(),
            &overflow_inputs(&x, inputs, &base_wrench, None),
        )?;
        Ok(out)
    }

    /// The Jacobians of one RK4 [`step`](Self::step) of `dt` from `x` with `inputs` held, in
    /// tangent coordinates at `x` and at the new state, including the quaternion's
    /// renormalisation ([`super::jacobians`]).
    pub fn step_jacobians(
        &self,
        ws: &mut ModelWorkspace,
        x: &[f64],
        dt: f64,
        inputs: &Inputs,
    ) -> Result<Jacobians> {
        self.refuse_wheels("step_jacobians")?;
        crate::args::check_dt(dt)?;
        ws.check(self)?;
        self.check_state(x)?;
        inputs.check(&self.robot)?;
        let mut x = x.to_vec();
        normalise_quaternion(&mut x[self.layout().quaternion()]);
        let out = jacobians::step_jacobians(self, ws, &x, dt, inputs)?.0;
        let base_wrench = inputs.loads.base_wrench.to_array();
        self.check_overflow(
            "step_jacobians",
            &out.blocks(),
            &overflow_inputs(&x, inputs, &base_wrench, Some(&[dt])),
        )?;
        Ok(out)
    }

    /// [`check_result`] for a call at a state, naming the state's element (`x[33]` is
    /// `qd[wrist_roll]`) in the message.
    pub(crate) fn check_overflow(
        &self,
        call: &str,
        results: &[&[f64]],
        inputs: &[Input<'_>],
    ) -> Result<()> {
        let element = |input: &str, index: usize| {
            let names = self.robot.joint_names();
            (input == "x" || input == "x0" || input == "x1")
                .then(|| self.layout().element_names(&names).swap_remove(index))
        };
        check_result_named(call, results, inputs, &element)
    }

    /// Spring torques `τ = k (θ − q) + d (θ̇ − q̇)` (N·m) at state `x` into `out` (n).
    ///
    /// # Panics
    /// If `out` does not hold exactly n torques (a buffer sized for another arm).
    pub fn spring_torque(&self, x: &[f64], out: &mut [f64]) {
        assert_eq!(
            out.len(),
            self.dof(),
            "spring_torque: out holds {} torques, the arm has n = {}",
            out.len(),
            self.dof()
        );
        self.spring_torque_of(&self.layout().split(x), out);
    }

    /// [`spring_torque`](Self::spring_torque) from the blocks of `x`, already split.
    #[inline]
    fn spring_torque_of(&self, s: &StateParts, out: &mut [f64]) {
        let p = &self.joints;
        let gains = p.stiffness.iter().zip(&p.damping);
        let states = s.theta.iter().zip(s.q).zip(s.theta_dot.iter().zip(s.qd));
        for ((tau, (k, d)), ((theta, q), (theta_dot, qd))) in out.iter_mut().zip(gains).zip(states)
        {
            *tau = k * (theta - q) + d * (theta_dot - qd);
        }
    }

    /// Total energy (model §6.2): rigid kinetic energy `½ νᵀ 𝓜 ν`, motor kinetic energy
    /// `½ θ̇ᵀ diag(j) θ̇` and spring energy `½ (θ − q)ᵀ diag(k) (θ − q)` (J). With reaction
    /// wheels, `𝓜` includes their locked parts and the spin energy `Σ ½ J_s (a·ω_B + Ω)²` is
    /// added.
    pub fn energy(&self, ws: &mut ModelWorkspace, x: &[f64]) -> f64 {
        let s = self.layout().split(x);
        let rigid = RigidState::new(s.q, s.base_twist, s.qd);
        let robot = self.rigid_model();
        algorithms::velocities_unchecked(robot, &mut ws.data, &rigid);
        let mut e = algorithms::kinetic_energy_from_velocities(robot, &ws.data);
        if let Some(wheels) = self.wheels() {
            e += wheels.spin_energy(&s.omega(), s.wheel_speed);
        }
        let p = &self.joints;
        for i in 0..self.dof() {
            let stretch = s.theta[i] - s.q[i];
            e += 0.5 * p.motor_inertia[i] * s.theta_dot[i] * s.theta_dot[i]
                + 0.5 * p.stiffness[i] * stretch * stretch;
        }
        e
    }

    /// Total spatial momentum `[angular; linear]` of base and links in the inertial frame, about
    /// the inertial origin (model §6.1). The motors' spin is not included (model §3). With
    /// reaction wheels it includes them whole: their locked parts through the augmented base,
    /// and their spin momentum `R_B Σ J_s (a·ω_B + Ω) a` (a free vector) in the angular part.
    pub fn momentum(&self, ws: &mut ModelWorkspace, x: &[f64]) -> [f64; 6] {
        let layout = self.layout();
        let s = layout.split(x);
        let rigid = RigidState::new(s.q, s.base_twist, s.qd);
        let robot = self.rigid_model();
        algorithms::velocities_unchecked(robot, &mut ws.data, &rigid);
        let h = algorithms::momentum_from_velocities(robot, &mut ws.data);
        let mut out = momentum_in_inertial_frame(&x[layout.base_pose()], &h);
        if let Some(wheels) = self.wheels() {
            let spin = quaternion_to_rotation(s.quaternion)
                * wheels.spin_momentum(&s.omega(), s.wheel_speed);
            out[..3]
                .iter_mut()
                .zip(spin.iter())
                .for_each(|(o, v)| *o += v);
        }
        out
    }

    /// The pose `[position (m); quaternion (x, y, z, w), w ≥ 0]` of end-effector `ee` (an index
    /// into [`Robot::end_effectors`], `0` on a chain) in the inertial frame at state `x`.
    ///
    /// # Panics
    /// If `ee` is out of range.
    pub fn ee_pose(&self, x: &[f64], ee: usize) -> [f64; 7] {
        let s = self.layout().split(x);
        let base_rotation = quaternion_to_rotation(s.quaternion); // base -> inertial
        let to_ee = algorithms::ee_from_base(&self.robot, s.q, ee); // Φ_{e,B}
                                                                    // The EE origin is at p_{B,e} in base axes; R_{e,B}ᵀ turns EE axes into base axes.
        let position = Vec3::from_column_slice(s.position) + base_rotation * to_ee.translation;
        algorithms::pose(&position, &(base_rotation * to_ee.rotation.transpose()))
    }

    /// The largest stable RK4 step at state `x` for the closed loop of the joints, the arm and
    /// the controller `u` (its feedback, if it declares one): see [`stability`].
    ///
    /// With reaction wheels the limit is that of the arm on its augmented bus with the wheels
    /// held at their speeds (the spin's gyroscopic coupling is left out), and at most the
    /// wheels' friction limit `2.785 J_s / c` (RK4 on the pole `−c/J_s`).
    pub fn rk4_stability_limit(&self, x: &[f64], u: &dyn Controller) -> Result<StabilityLimit> {
        self.stability_limit_until(x, u, f64::INFINITY)
    }

    /// Whether `dt` exceeds [`FlexibleArm::rk4_stability_limit`]`(x, u)`: that limit when it
    /// does, `None` when `dt` is within it. The same answer as comparing `dt` with the limit,
    /// for fewer eigenvalue solves when `dt` is within it (the search stops once it has found a
    /// stable step at or above `dt`, before the bisection that would fix the limit to 1e-4).
    pub fn rk4_stability_exceeded(
        &self,
        x: &[f64],
        u: &dyn Controller,
        dt: f64,
    ) -> Result<Option<StabilityLimit>> {
        // below `dt` the result is the limit itself; at or above it, a lower bound of the limit
        let limit = self.stability_limit_until(x, u, dt)?;
        Ok((dt > limit.dt).then_some(limit))
    }

    /// The limit, or a lower bound of it at or above `enough` (`stability::limit_until`): every
    /// term of the minimum below is the limit's own term when the minimum is below `enough`.
    fn stability_limit_until(
        &self,
        x: &[f64],
        u: &dyn Controller,
        enough: f64,
    ) -> Result<StabilityLimit> {
        let Some(m) = &self.wheels else {
            return stability::limit_until(self, x, &u.feedback(), enough);
        };
        let locked = FlexibleArm {
            robot: m.robot.clone(),
            joints: self.joints.clone(),
            method: self.method,
            wheels: None,
        };
        self.check_state(x)?;
        let mut limit =
            stability::limit_until(&locked, &x[..locked.layout().len()], &u.feedback(), enough)?;
        for wheel in m.wheels.wheels() {
            limit.dt = limit.dt.min(2.785 * wheel.spin_inertia / wheel.friction);
        }
        Ok(limit)
    }
}

/// The inputs of a call at state `x` for [`check_result`]: the step `dt` (a step's Jacobians
/// grow as its fourth power), the state (its rates enter squared), the motor torques and the
/// wrenches.
fn overflow_inputs<'a>(
    x: &'a [f64],
    inputs: &'a Inputs,
    base_wrench: &'a [f64; 6],
    dt: Option<&'a [f64]>,
) -> [Input<'a>; 5] {
    [
        ("dt", dt.unwrap_or(&[]), 4),
        ("x", x, 2),
        ("u", inputs.u, 1),
        ("base_wrench", base_wrench, 1),
        ("ee_wrench", inputs.loads.ee_wrench, 1),
    ]
}

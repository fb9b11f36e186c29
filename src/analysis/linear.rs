//! The linear model of the arm about a state: `d(dx)/dt = A dx + B du`, `dy = C dx + D du`, with
//! the base free or held and the motors free or clamped, open loop or closed by a motor PD
//! (see the [module documentation](super) for the derivation of each case).

use crate::algorithms;
use crate::args::RigidState;
use crate::control::{AttitudePD, AttitudeTarget, Controller};
use crate::error::{Error, Result};
use crate::flex::{FlexibleArm, Inputs, ModelWorkspace};
use crate::integrate::Feedback;
use crate::planning::BaseMode;
use crate::spatial::{quaternion_to_rotation, skew, Mat3};
use nalgebra::{DMatrix, DVector};

/// What the motors do in the linear model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Motors {
    /// The motors turn under their torques `u`, held at their values (`δu = 0`) or closed by a
    /// feedback.
    #[default]
    Free,
    /// Brakes on: `θ` is held where `x` has it (`θ̇ = 0`); the motor states leave the model.
    Clamped,
}

impl Motors {
    /// `"free"` or `"clamped"`.
    pub fn name(self) -> &'static str {
        match self {
            Motors::Free => "free",
            Motors::Clamped => "clamped",
        }
    }

    /// Parses `"free"` or `"clamped"`.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "free" => Ok(Motors::Free),
            "clamped" => Ok(Motors::Clamped),
            _ => Err(Error::InvalidArgument {
                what: "motors".into(),
                message: format!("expected \"free\" or \"clamped\", given {name:?}"),
            }),
        }
    }
}

/// A group of inputs of the linear model, by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputGroup {
    /// `"motor_torque"`: `δu` (n, N·m, link side), added to whatever the feedback commands.
    MotorTorque,
    /// `"theta_ref"`: the motor PD's reference `δθ_ref` (n, rad); needs a motor PD.
    ThetaRef,
    /// `"base_wrench"`: `δf_B = [moment (N·m); force (N)]` on the base, base frame (free base).
    BaseWrench,
    /// `"ee_wrench"`: `δf_e = [moment; force]` exerted by each end-effector on its environment,
    /// in its own frame (6 per end-effector, in `ee_links` order).
    EeWrench,
    /// `"wheel_torque"`: `δu_W` (k, N·m) commanded to each reaction wheel about its axis (the
    /// bus feels the opposite), added to what an attitude controller commands; needs wheels.
    WheelTorque,
}

impl InputGroup {
    /// Every group, in the order of their names.
    pub const ALL: [InputGroup; 5] = [
        InputGroup::MotorTorque,
        InputGroup::ThetaRef,
        InputGroup::BaseWrench,
        InputGroup::EeWrench,
        InputGroup::WheelTorque,
    ];

    /// The group's name.
    pub fn name(self) -> &'static str {
        match self {
            InputGroup::MotorTorque => "motor_torque",
            InputGroup::ThetaRef => "theta_ref",
            InputGroup::BaseWrench => "base_wrench",
            InputGroup::EeWrench => "ee_wrench",
            InputGroup::WheelTorque => "wheel_torque",
        }
    }

    /// Parses a group's name.
    pub fn from_name(name: &str) -> Result<Self> {
        by_name("inputs", name, &Self::ALL, Self::name)
    }
}

/// A group of outputs of the linear model, by name. Every output is a function of the state
/// alone (`D = 0`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputGroup {
    /// `"q"`: link angles (rad).
    Q,
    /// `"theta"`: motor angles, link side (rad).
    Theta,
    /// `"deflection"`: `θ − q` (rad).
    Deflection,
    /// `"spring_torque"`: `k (θ − q) + d (θ̇ − q̇)` (N·m).
    SpringTorque,
    /// `"ee_position"`: each end-effector's origin, inertial frame (m), 3 per end-effector.
    EePosition,
    /// `"base_attitude"`: the small rotation `δφ_B` of the base, about the base axes (rad).
    BaseAttitude,
    /// `"base_position"`: `δr_B`, inertial frame (m).
    BasePosition,
    /// `"base_rate"`: the bus's angular velocity `δω_B`, base frame (rad/s).
    BaseRate,
    /// `"wheel_speed"`: the reaction wheels' speeds `δΩ` relative to the bus (rad/s, k);
    /// needs wheels.
    WheelSpeed,
}

impl OutputGroup {
    /// Every group, in the order of their names.
    pub const ALL: [OutputGroup; 9] = [
        OutputGroup::Q,
        OutputGroup::Theta,
        OutputGroup::Deflection,
        OutputGroup::SpringTorque,
        OutputGroup::EePosition,
        OutputGroup::BaseAttitude,
        OutputGroup::BasePosition,
        OutputGroup::BaseRate,
        OutputGroup::WheelSpeed,
    ];

    /// The group's name.
    pub fn name(self) -> &'static str {
        match self {
            OutputGroup::Q => "q",
            OutputGroup::Theta => "theta",
            OutputGroup::Deflection => "deflection",
            OutputGroup::SpringTorque => "spring_torque",
            OutputGroup::EePosition => "ee_position",
            OutputGroup::BaseAttitude => "base_attitude",
            OutputGroup::BasePosition => "base_position",
            OutputGroup::BaseRate => "base_rate",
            OutputGroup::WheelSpeed => "wheel_speed",
        }
    }

    /// Parses a group's name.
    pub fn from_name(name: &str) -> Result<Self> {
        by_name("outputs", name, &Self::ALL, Self::name)
    }
}

/// The member of `all` called `name`, or an error for the argument `what` that lists the names.
fn by_name<T: Copy>(
    what: &str,
    name: &str,
    all: &[T],
    name_of: fn(T) -> &'static str,
) -> Result<T> {
    all.iter()
        .copied()
        .find(|&g| name_of(g) == name)
        .ok_or_else(|| Error::InvalidArgument {
            what: what.into(),
            message: format!(
                "unknown name {name:?}; expected one of {}",
                all.iter()
                    .map(|&g| name_of(g))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        })
}

/// What the linear model describes: the base, the motors, the feedbacks closing the loop (on
/// the motors, and on the bus through its reaction wheels), and the named inputs and outputs.
#[derive(Debug, Clone, Copy)]
pub struct LinearSpec<'a> {
    /// Free floating, or held inertially still by its actuators (`V_B = 0`, `α_B = 0`).
    pub base: BaseMode,
    /// Free or clamped (brakes on).
    pub motors: Motors,
    /// [`Feedback::None`] (open loop) or [`Feedback::MotorPd`] (closed loop);
    /// [`Feedback::Unknown`] is refused.
    pub feedback: Feedback<'a>,
    /// An [`AttitudePD`] on the reaction wheels closing the bus's attitude loop (free base;
    /// target the state's own attitude or a constant one), or `None` (wheel torques held).
    pub attitude: Option<&'a AttitudePD>,
    /// The input groups, in order (`B`'s columns).
    pub inputs: &'a [InputGroup],
    /// The output groups, in order (`C`'s rows).
    pub outputs: &'a [OutputGroup],
}

impl Default for LinearSpec<'_> {
    /// Free base, free motors, open loop, no inputs or outputs.
    fn default() -> Self {
        Self {
            base: BaseMode::Free,
            motors: Motors::Free,
            feedback: Feedback::None,
            attitude: None,
            inputs: &[],
            outputs: &[],
        }
    }
}

/// The linear model `d(dx)/dt = A dx + B du`, `dy = C dx + D du` about a state, with its names.
///
/// The states are the elements of the tangent
/// `[δr_B | δφ_B | δq | δθ | δω_B | δv_B | δq̇ | δθ̇ | δΩ]` the model keeps: all `12 + 4n + k`
/// (free base, free motors, `k` reaction wheels), without `δθ, δθ̇` (clamped motors), without
/// the base's pose and twist (held base); the wheel speeds `δΩ` are always kept.
/// `tangent_index[i]` is where state `i` sits in the tangent.
#[derive(Debug, Clone, PartialEq)]
pub struct StateSpace {
    /// State matrix (1/s and 1/s², as the states' units require).
    pub a: DMatrix<f64>,
    /// Input matrix.
    pub b: DMatrix<f64>,
    /// Output matrix.
    pub c: DMatrix<f64>,
    /// Feedthrough (zero: every output is a function of the state).
    pub d: DMatrix<f64>,
    /// State names (`r_x`, `phi_x`, `q[joint]`, `theta[joint]`, `omega_x`, `v_x`, `qd[joint]`,
    /// `theta_dot[joint]`, `wheel_speed[w]`).
    pub states: Vec<String>,
    /// Input names (`u[joint]`, `theta_ref[joint]`, `base_moment_x`, `base_force_x`,
    /// `ee_moment_x[ee]`, `ee_force_x[ee]`, `wheel_torque[w]`, …).
    pub inputs: Vec<String>,
    /// Output names (`q[joint]`, `deflection[joint]`, `ee_x[ee]`, `base_attitude_x`,
    /// `base_rate_x`, `wheel_speed[w]`, …).
    pub outputs: Vec<String>,
    /// Where each state sits in the tangent (`12 + 4n + k`).
    pub tangent_index: Vec<usize>,
}

/// Offsets of the tangent's blocks for `n` joints and `k` reaction wheels.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tangent {
    pub n: usize,
    pub k: usize,
}

impl Tangent {
    /// The tangent of `arm`'s state.
    pub fn of(arm: &FlexibleArm) -> Self {
        let layout = arm.layout();
        Self {
            n: layout.n,
            k: layout.wheels,
        }
    }
    pub fn len(self) -> usize {
        12 + 4 * self.n + self.k
    }
    pub fn wheel(self) -> usize {
        12 + 4 * self.n
    }
    pub fn q(self) -> usize {
        6
    }
    pub fn theta(self) -> usize {
        6 + self.n
    }
    pub fn twist(self) -> usize {
        6 + 2 * self.n
    }
    pub fn qd(self) -> usize {
        12 + 2 * self.n
    }
    pub fn theta_dot(self) -> usize {
        12 + 3 * self.n
    }

    /// The tangent's element names.
    pub fn names(self, joints: &[&str]) -> Vec<String> {
        let per_joint = |prefix: &'static str| joints.iter().map(move |j| format!("{prefix}[{j}]"));
        let fixed = |names: [&'static str; 6]| names.into_iter().map(String::from);
        fixed(["r_x", "r_y", "r_z", "phi_x", "phi_y", "phi_z"])
            .chain(per_joint("q"))
            .chain(per_joint("theta"))
            .chain(fixed([
                "omega_x", "omega_y", "omega_z", "v_x", "v_y", "v_z",
            ]))
            .chain(per_joint("qd"))
            .chain(per_joint("theta_dot"))
            .chain((0..self.k).map(|w| format!("wheel_speed[{w}]")))
            .collect()
    }

    /// The tangent indices a model keeps, in order.
    pub fn kept(self, base: BaseMode, motors: Motors) -> Vec<usize> {
        let n = self.n;
        let mut keep = Vec::with_capacity(self.len());
        let mut block = |start: usize, len: usize| keep.extend(start..start + len);
        if base == BaseMode::Free {
            block(0, 6);
        }
        block(self.q(), n);
        if motors == Motors::Free {
            block(self.theta(), n);
        }
        if base == BaseMode::Free {
            block(self.twist(), 6);
        }
        block(self.qd(), n);
        if motors == Motors::Free {
            block(self.theta_dot(), n);
        }
        block(self.wheel(), self.k);
        keep
    }
}

/// Checks that `spec` describes a model that exists at `x` (a checked state): a held base must be
/// at rest, clamped motors must not turn and take no motor input or feedback, a base wrench needs
/// a free base, `theta_ref` needs a motor PD, and a PD's gains have one entry per joint.
pub(crate) fn check_spec(arm: &FlexibleArm, x: &[f64], spec: &LinearSpec) -> Result<()> {
    let s = arm.layout().split(x);
    let n = arm.dof();
    if let Feedback::MotorPd { kp, kd } = spec.feedback {
        crate::args::check_vector("kp", kp, n)?;
        crate::args::check_vector("kd", kd, n)?;
    }
    if spec.feedback == Feedback::Unknown {
        return invalid(
            "u",
            "the controller's feedback is not known (a Python callable, say); the linear model \
             takes None (open loop) or a MotorPD"
                .into(),
        );
    }
    check_held_base(s.base_twist, spec)?;
    check_clamped_motors(s.theta_dot, spec)?;
    if spec.inputs.contains(&InputGroup::ThetaRef)
        && !matches!(spec.feedback, Feedback::MotorPd { .. })
    {
        return invalid(
            "inputs",
            "\"theta_ref\" is the motor PD's reference: give u=MotorPD(...)".into(),
        );
    }
    check_wheels(arm, x, spec)
}

/// An `InvalidArgument` error on `what`.
fn invalid(what: &str, message: String) -> Result<()> {
    Err(Error::InvalidArgument {
        what: what.into(),
        message,
    })
}

/// The held base's part of [`check_spec`]: the base at rest (`base_twist` zero) and no base
/// wrench input.
fn check_held_base(base_twist: &[f64], spec: &LinearSpec) -> Result<()> {
    if spec.base != BaseMode::Held {
        return Ok(());
    }
    if let Some(i) = base_twist.iter().position(|v| *v != 0.0) {
        return invalid(
            "x",
            format!(
                "base=\"held\" clamps the base, but x has a base twist (element {i} is {}); \
                 give a state with base_twist = 0",
                base_twist[i]
            ),
        );
    }
    if spec.inputs.contains(&InputGroup::BaseWrench) {
        return invalid(
            "inputs",
            "\"base_wrench\" drives a free base; with base=\"held\" the base's actuators \
             absorb it"
                .into(),
        );
    }
    Ok(())
}

/// The clamped motors' part of [`check_spec`]: the motors still (`theta_dot` zero), no motor
/// feedback and no motor input.
fn check_clamped_motors(theta_dot: &[f64], spec: &LinearSpec) -> Result<()> {
    if spec.motors != Motors::Clamped {
        return Ok(());
    }
    if let Some(i) = theta_dot.iter().position(|v| *v != 0.0) {
        return invalid(
            "x",
            format!(
                "motors=\"clamped\" holds the motors still, but x has theta_dot[{i}] = {}; \
                 give a state with theta_dot = 0",
                theta_dot[i]
            ),
        );
    }
    if spec.feedback != Feedback::None {
        return invalid(
            "u",
            "a motor PD drives the motors, which motors=\"clamped\" holds still".into(),
        );
    }
    for group in [InputGroup::MotorTorque, InputGroup::ThetaRef] {
        if spec.inputs.contains(&group) {
            return invalid(
                "inputs",
                format!(
                    "{:?} drives the motors, which motors=\"clamped\" holds still; take \
                     \"ee_wrench\" or \"base_wrench\" as inputs",
                    group.name()
                ),
            );
        }
    }
    Ok(())
}

/// The wheels' part of [`check_spec`]: wheel inputs, outputs and an attitude loop need wheels;
/// an attitude loop needs a free base, an allocation for the arm's `k` wheels and a fixed
/// target; and no wheel may sit at its speed limit, where the applied torque is not a
/// differentiable function of the command (the limit cuts one side of it).
fn check_wheels(arm: &FlexibleArm, x: &[f64], spec: &LinearSpec) -> Result<()> {
    let Some(wheels) = arm.wheels() else {
        if spec.inputs.contains(&InputGroup::WheelTorque) {
            return invalid(
                "inputs",
                "\"wheel_torque\" drives reaction wheels, and the arm has none".into(),
            );
        }
        if spec.outputs.contains(&OutputGroup::WheelSpeed) {
            return invalid(
                "outputs",
                "\"wheel_speed\" is a reaction wheel's, and the arm has none".into(),
            );
        }
        if spec.attitude.is_some() {
            return invalid(
                "u",
                "an AttitudePD drives reaction wheels, and the arm has none: build the arm with \
                 wheels=ReactionWheels(...)"
                    .into(),
            );
        }
        return Ok(());
    };
    let speed = &x[arm.layout().wheel_speed()];
    for (w, wheel) in wheels.wheels().iter().enumerate() {
        if speed[w].abs() >= wheel.max_speed {
            return invalid(
                "x",
                format!(
                    "wheel {w} turns at {} rad/s, at its speed limit max_speed = {} rad/s: the \
                     limit cuts the torques that would speed it up, so the dynamics have no \
                     linear model there; linearise at a speed within the limit",
                    speed[w], wheel.max_speed
                ),
            );
        }
    }
    if let Some(pd) = spec.attitude {
        if spec.base == BaseMode::Held {
            return invalid(
                "u",
                "an AttitudePD turns the bus, which base=\"held\" holds still; take \
                 base=\"free\""
                    .into(),
            );
        }
        if pd.wheels() != wheels.len() {
            return Err(Error::Dimension {
                what: "AttitudePD".into(),
                expected: format!("an allocation for the arm's {} wheels", wheels.len()),
                given: format!("an allocation for {} wheels", pd.wheels()),
            });
        }
        if matches!(pd.target(), AttitudeTarget::Table { .. }) {
            return invalid(
                "u",
                "the linear model takes an AttitudePD holding a fixed attitude (attitude=None \
                 or one quaternion); a table of attitudes is a trajectory, not an operating \
                 point"
                    .into(),
            );
        }
    }
    Ok(())
}

/// The attitude loop's gain `K_W = ∂u_W/∂dx` (k × tangent) and the wheel torques it commands at
/// `x`. With `q_e = q_ref* ⊗ q_B` (the shorter way round) and `q_B = q̄_B ⊗ Exp(δφ_B)`,
/// `δe = 2 δvec(q_e) = (w_e 𝟙 + [v_e]×) δφ_B`, so from `T = −k_p ∘ e − k_d ∘ ω_B` and
/// `u_W = −M T`:
///
/// ```text
/// δu_W = M (diag(k_p) (w_e 𝟙 + [v_e]×) δφ_B + diag(k_d) δω_B)
/// ```
/// (`= M (diag(k_p) δφ_B + diag(k_d) δω_B)` at the target, `q_e = 1`).
pub(crate) fn attitude_gain(
    pd: &AttitudePD,
    x: &[f64],
    t: Tangent,
    layout: crate::StateLayout,
) -> Result<(DMatrix<f64>, Vec<f64>)> {
    let k = pd.wheels();
    let quat = &x[layout.quaternion()];
    let reference = match pd.target() {
        AttitudeTarget::Constant(q) => *q,
        _ => [quat[0], quat[1], quat[2], quat[3]],
    };
    let conj = [-reference[0], -reference[1], -reference[2], reference[3]];
    let mut q_e = crate::spatial::quaternion_product(&conj, quat);
    if q_e[3] < 0.0 {
        q_e.iter_mut().for_each(|v| *v = -*v);
    }
    let e_phi =
        Mat3::identity() * q_e[3] + skew(&crate::spatial::Vec3::new(q_e[0], q_e[1], q_e[2]));
    let m = pd.allocation();
    let mut gain = DMatrix::zeros(k, t.len());
    for w in 0..k {
        for a in 0..3 {
            for c in 0..3 {
                gain[(w, 3 + c)] += m[3 * w + a] * pd.kp[a] * e_phi[(a, c)];
            }
            gain[(w, t.twist() + a)] += m[3 * w + a] * pd.kd[a];
        }
    }
    let mut command = vec![0.0; k];
    pd.clone().output(0, 0.0, x, &mut command)?;
    Ok((gain, command))
}

/// The full-tangent Jacobians of the model at `x`: `F` ((12+4n)², rows and columns of the states
/// the model drops are zero), and `G_u` (n), `G_B` (6), `G_E` (6k) columns.
pub(crate) struct FullJacobians {
    pub f: DMatrix<f64>,
    pub u: DMatrix<f64>,
    pub base_wrench: DMatrix<f64>,
    pub ee_wrench: DMatrix<f64>,
    pub wheel_torque: DMatrix<f64>,
}

/// `F` and `G` of the free base ([`FlexibleArm::derivative_jacobians`] at zero loads), or of the
/// held base (see the module documentation), with the PD's feedback closed into `F`.
pub(crate) fn jacobians(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    x: &[f64],
    spec: &LinearSpec,
) -> Result<FullJacobians> {
    let n = arm.dof();
    let zeros = vec![0.0; n];
    let t = Tangent::of(arm);
    // the attitude loop's gain, and the wheel torques it commands at x (the operating point)
    let attitude = spec
        .attitude
        .map(|pd| attitude_gain(pd, x, t, arm.layout()))
        .transpose()?;
    let mut full = match spec.base {
        BaseMode::Free => {
            let inputs = Inputs {
                wheel_torque: attitude.as_ref().map_or(&[], |(_, u)| &u[..]),
                ..Inputs::torques(&zeros)
            };
            let j = arm.derivative_jacobians(ws, x, &inputs)?;
            FullJacobians {
                f: j.x,
                u: j.u,
                base_wrench: j.base_wrench,
                ee_wrench: j.ee_wrench,
                wheel_torque: j.wheel_torque,
            }
        }
        BaseMode::Held => held_jacobians(arm, ws, x)?,
    };
    if let Some((gain, _)) = &attitude {
        // u_W = … + K_W dx: A = F + G_W K_W
        full.f += &full.wheel_torque * gain;
    }
    if let Feedback::MotorPd { kp, kd } = spec.feedback {
        // u = … − k_p θ − k_d θ̇: θ̈_i gains −k_p/j, −k_d/j
        let j = &arm.joints().motor_inertia;
        for i in 0..n {
            full.f[(t.theta_dot() + i, t.theta() + i)] -= kp[i] / j[i];
            full.f[(t.theta_dot() + i, t.theta_dot() + i)] -= kd[i] / j[i];
        }
    }
    Ok(full)
}

/// The held base's Jacobians in the full tangent (zero base rows and columns).
///
/// With `V_B = 0` and `α_B = 0` the links obey the fixed-base equation, the joint rows of (A.19):
/// `M_r q̈ + ID_r(q, q̇, 0) = τ`, `ID_r` the joint rows of the inverse dynamics at `α_B = 0`
/// (which include `Jᵀ f`). By the implicit-function theorem, at `q̈_h = M_r⁻¹ (τ − ID_r(q, q̇, 0))`:
///
/// ```text
/// δq̈ = M_r⁻¹ (δτ − ∂ID_r/∂q δq − ∂ID_r/∂q̇ δq̇ − J_eᵀ δf_e),   δτ = k (δθ − δq) + d (δθ̇ − δq̇)
/// ```
///
/// with `∂ID_r/∂(q, q̇)` from [`algorithms::rnea_derivatives`] at `(q, 0, q̇, α_B = 0, q̈_h)`.
/// This is not a sub-block of the free base's Jacobian: holding the base changes the link
/// accelerations (`M_r` against the free system's `𝓜`).
fn held_jacobians(arm: &FlexibleArm, ws: &mut ModelWorkspace, x: &[f64]) -> Result<FullJacobians> {
    let robot = arm.robot();
    let n = arm.dof();
    let k_ee = robot.end_effectors().len();
    let t = Tangent::of(arm);
    let s = arm.layout().split(x);
    let p = arm.joints();
    let zero6 = [0.0; 6];
    let state = RigidState::new(s.q, &zero6, s.qd);
    let data = &mut ws.data;
    let mass = algorithms::crba(robot, data, s.q)?;
    let m_r = mass.view((6, 6), (n, n)).into_owned();
    let chol = m_r.cholesky().ok_or_else(|| Error::InvalidArgument {
        what: "x".into(),
        message: "the joint-space mass matrix M_r is not positive definite at this q".into(),
    })?;
    // q̈_h = M_r⁻¹ (τ − ID_r(q, q̇, α_B = 0, q̈ = 0))
    let mut tau = vec![0.0; n];
    arm.spring_torque(x, &mut tau);
    let zeros = vec![0.0; n];
    let bias = algorithms::rnea(robot, data, &state, &zero6, &zeros, &[])?;
    let rhs = DVector::from_iterator(n, (0..n).map(|i| tau[i] - bias[6 + i]));
    let qdd = chol.solve(&rhs);
    let d = algorithms::rnea_derivatives(robot, data, &state, &zero6, qdd.as_slice(), &[])?;
    let size = t.len();
    let mut f = DMatrix::zeros(size, size);
    let mut g_u = DMatrix::zeros(size, n);
    let mut g_e = DMatrix::zeros(size, 6 * k_ee);
    // −M_r⁻¹ (∂ID_r/∂q + K), −M_r⁻¹ (∂ID_r/∂q̇ + D), M_r⁻¹ K, M_r⁻¹ D, −M_r⁻¹ J_eᵀ
    let mut rhs = DMatrix::zeros(n, 4 * n + 6 * k_ee);
    for i in 0..n {
        let (k, damping) = (p.stiffness[i], p.damping[i]);
        for r in 0..n {
            rhs[(r, i)] = -d.id_q[(6 + r, i)];
            rhs[(r, 2 * n + i)] = -d.id_v[(6 + r, 6 + i)];
        }
        rhs[(i, i)] -= k;
        rhs[(i, n + i)] = k;
        rhs[(i, 2 * n + i)] -= damping;
        rhs[(i, 3 * n + i)] = damping;
    }
    for c in 0..6 * k_ee {
        for r in 0..n {
            rhs[(r, 4 * n + c)] = -d.id_ee_wrench[(6 + r, c)];
        }
    }
    let solved = chol.solve(&rhs);
    for r in 0..n {
        let row = t.qd() + r;
        for i in 0..n {
            f[(row, t.q() + i)] = solved[(r, i)];
            f[(row, t.theta() + i)] = solved[(r, n + i)];
            f[(row, t.qd() + i)] = solved[(r, 2 * n + i)];
            f[(row, t.theta_dot() + i)] = solved[(r, 3 * n + i)];
        }
        for c in 0..6 * k_ee {
            g_e[(row, c)] = solved[(r, 4 * n + c)];
        }
    }
    // q̇, θ̇ rows, and θ̈ = (u − τ − β θ̇)/j
    for i in 0..n {
        f[(t.q() + i, t.qd() + i)] = 1.0;
        f[(t.theta() + i, t.theta_dot() + i)] = 1.0;
        let (k, damping, j, beta) = (
            p.stiffness[i],
            p.damping[i],
            p.motor_inertia[i],
            p.motor_damping[i],
        );
        let row = t.theta_dot() + i;
        f[(row, t.q() + i)] = k / j;
        f[(row, t.theta() + i)] = -k / j;
        f[(row, t.qd() + i)] = damping / j;
        f[(row, t.theta_dot() + i)] = -(damping + beta) / j;
        g_u[(row, i)] = 1.0 / j;
    }
    // the wheels on a bus held still (ω̇_B = 0): Ω̇ = (u_W − c Ω)/J_s (W1)
    let wheels = arm.wheels().map_or(&[][..], |w| w.wheels());
    let mut g_w = DMatrix::zeros(size, wheels.len());
    for (w, wheel) in wheels.iter().enumerate() {
        let row = t.wheel() + w;
        f[(row, row)] = -wheel.friction / wheel.spin_inertia;
        g_w[(row, w)] = 1.0 / wheel.spin_inertia;
    }
    Ok(FullJacobians {
        f,
        u: g_u,
        base_wrench: DMatrix::zeros(size, 6),
        ee_wrench: g_e,
        wheel_torque: g_w,
    })
}

/// The linear model of `arm` about the state `x` described by `spec` (see [`StateSpace`] and the
/// [module documentation](super)).
///
/// ```
/// use orbitflex::analysis::{state_space, InputGroup, LinearSpec, OutputGroup};
/// use orbitflex::{FlexibleArm, FlexibleJoints, Robot};
/// let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
/// let spec = LinearSpec {
///     inputs: &[InputGroup::MotorTorque],
///     outputs: &[OutputGroup::Q],
///     ..LinearSpec::default()
/// };
/// let ss = state_space(&arm, &mut arm.workspace(), &arm.rest_state(), &spec)?;
/// assert_eq!((ss.a.nrows(), ss.b.ncols(), ss.c.nrows()), (40, 7, 7));
/// assert_eq!(ss.states[6], "q[shoulder_roll]");
/// # Ok::<(), orbitflex::Error>(())
/// ```
pub fn state_space(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    x: &[f64],
    spec: &LinearSpec,
) -> Result<StateSpace> {
    arm.check_state(x)?;
    let mut x = x.to_vec();
    crate::flex::normalise_quaternion(&mut x[arm.layout().quaternion()]);
    check_spec(arm, &x, spec)?;
    let full = jacobians(arm, ws, &x, spec)?;
    let t = Tangent::of(arm);
    let keep = t.kept(spec.base, spec.motors);
    let robot = arm.robot();
    let joints = robot.joint_names();
    let ees = robot.ee_links();
    let a = DMatrix::from_fn(keep.len(), keep.len(), |r, c| full.f[(keep[r], keep[c])]);
    // B, column group by column group
    let mut b_columns: Vec<DVector<f64>> = Vec::new();
    let mut inputs = Vec::new();
    for group in spec.inputs {
        match group {
            InputGroup::MotorTorque => {
                for (i, name) in joints.iter().enumerate() {
                    b_columns.push(full.u.column(i).into_owned());
                    inputs.push(format!("u[{name}]"));
                }
            }
            InputGroup::ThetaRef => {
                let Feedback::MotorPd { kp, .. } = spec.feedback else {
                    unreachable!("checked: theta_ref needs a motor PD")
                };
                for (i, name) in joints.iter().enumerate() {
                    b_columns.push(full.u.column(i) * kp[i]);
                    inputs.push(format!("theta_ref[{name}]"));
                }
            }
            InputGroup::BaseWrench => {
                for (c, name) in WRENCH.iter().enumerate() {
                    b_columns.push(full.base_wrench.column(c).into_owned());
                    inputs.push(format!("base_{name}"));
                }
            }
            InputGroup::EeWrench => {
                for (e, ee) in ees.iter().enumerate() {
                    for (c, name) in WRENCH.iter().enumerate() {
                        b_columns.push(full.ee_wrench.column(6 * e + c).into_owned());
                        inputs.push(format!("ee_{name}[{ee}]"));
                    }
                }
            }
            InputGroup::WheelTorque => {
                for w in 0..t.k {
                    b_columns.push(full.wheel_torque.column(w).into_owned());
                    inputs.push(format!("wheel_torque[{w}]"));
                }
            }
        }
    }
    let b = DMatrix::from_fn(keep.len(), b_columns.len(), |r, c| b_columns[c][keep[r]]);
    let (c_full, outputs) = output_rows(arm, &x, spec.outputs);
    let c = DMatrix::from_fn(outputs.len(), keep.len(), |r, col| c_full[(r, keep[col])]);
    let all_names = t.names(&joints);
    Ok(StateSpace {
        d: DMatrix::zeros(outputs.len(), inputs.len()),
        a,
        b,
        c,
        states: keep.iter().map(|&i| all_names[i].clone()).collect(),
        inputs,
        outputs,
        tangent_index: keep,
    })
}

/// The entries `(tangent index, value)` of the row of joint `i` with stiffness `k` and damping
/// `d`.
type JointRow = fn(Tangent, usize, f64, f64) -> Vec<(usize, f64)>;

/// The components of a wrench `[moment; force]`, as named in inputs.
const WRENCH: [&str; 6] = [
    "moment_x", "moment_y", "moment_z", "force_x", "force_y", "force_z",
];

/// `C` over the full tangent for the output `groups` at `x`, with the output names.
fn output_rows(
    arm: &FlexibleArm,
    x: &[f64],
    groups: &[OutputGroup],
) -> (DMatrix<f64>, Vec<String>) {
    let t = Tangent::of(arm);
    let robot = arm.robot();
    let joints = robot.joint_names();
    let p = arm.joints();
    let mut rows: Vec<DVector<f64>> = Vec::new();
    let mut names = Vec::new();
    let unit = |entries: &[(usize, f64)]| {
        let mut row = DVector::zeros(t.len());
        for &(i, v) in entries {
            row[i] += v;
        }
        row
    };
    let s = arm.layout().split(x);
    let rotation = quaternion_to_rotation(s.quaternion);
    for group in groups {
        let per_joint = per_joint_row(*group);
        if let Some((prefix, entries)) = per_joint {
            for (i, name) in joints.iter().enumerate() {
                rows.push(unit(&entries(t, i, p.stiffness[i], p.damping[i])));
                names.push(format!("{prefix}[{name}]"));
            }
            continue;
        }
        match group {
            OutputGroup::WheelSpeed => {
                for w in 0..t.k {
                    rows.push(unit(&[(t.wheel() + w, 1.0)]));
                    names.push(format!("wheel_speed[{w}]"));
                }
            }
            OutputGroup::BasePosition | OutputGroup::BaseAttitude | OutputGroup::BaseRate => {
                let (start, prefix) = match group {
                    OutputGroup::BasePosition => (0, "base_position"),
                    OutputGroup::BaseAttitude => (3, "base_attitude"),
                    _ => (t.twist(), "base_rate"),
                };
                for (a, axis) in ["x", "y", "z"].iter().enumerate() {
                    rows.push(unit(&[(start + a, 1.0)]));
                    names.push(format!("{prefix}_{axis}"));
                }
            }
            OutputGroup::EePosition => ee_position_rows(arm, s.q, &rotation, &mut rows, &mut names),
            _ => unreachable!("per-joint groups handled above"),
        }
    }
    let c = DMatrix::from_fn(rows.len(), t.len(), |r, col| rows[r][col]);
    (c, names)
}

/// The output name and row of a per-joint output group (`None` for the others).
fn per_joint_row(group: OutputGroup) -> Option<(&'static str, JointRow)> {
    match group {
        OutputGroup::Q => Some(("q", |t, i, _, _| vec![(t.q() + i, 1.0)])),
        OutputGroup::Theta => Some(("theta", |t, i, _, _| vec![(t.theta() + i, 1.0)])),
        OutputGroup::Deflection => Some(("deflection", |t, i, _, _| {
            vec![(t.theta() + i, 1.0), (t.q() + i, -1.0)]
        })),
        OutputGroup::SpringTorque => Some(("spring_torque", |t, i, k, d| {
            vec![
                (t.theta() + i, k),
                (t.q() + i, -k),
                (t.theta_dot() + i, d),
                (t.qd() + i, -d),
            ]
        })),
        _ => None,
    }
}

/// The rows of the end-effector positions (inertial frame, three per end-effector) at joint
/// angles `q` and base attitude `rotation` (base to inertial), with their names:
/// `δp_e = δr_B − R_B [p_{B,e}]× δφ_B + R_B R_{e,B}ᵀ J_e,lin δq`.
fn ee_position_rows(
    arm: &FlexibleArm,
    q: &[f64],
    rotation: &Mat3,
    rows: &mut Vec<DVector<f64>>,
    names: &mut Vec<String>,
) {
    let n = arm.dof();
    let t = Tangent::of(arm);
    let robot = arm.robot();
    let mut data = algorithms::Data::new(robot);
    for (e, ee) in robot.ee_links().iter().enumerate() {
        let to_ee = algorithms::ee_from_base(robot, q, e);
        algorithms::ee_jacobian(robot, &mut data, q, e)
            .expect("checked state and end-effector index");
        let attitude: Mat3 = -rotation * skew(&to_ee.translation);
        let linear = data.jacobian.rows(3, 3);
        let to_inertial = rotation * to_ee.rotation.transpose();
        for (a, axis) in ["x", "y", "z"].iter().enumerate() {
            let mut row = DVector::zeros(t.len());
            row[a] = 1.0;
            for c in 0..3 {
                row[3 + c] = attitude[(a, c)];
            }
            for i in 0..n {
                row[t.q() + i] = (0..3).map(|m| to_inertial[(a, m)] * linear[(m, i)]).sum();
            }
            rows.push(row);
            names.push(format!("ee_{axis}[{ee}]"));
        }
    }
}

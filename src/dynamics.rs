//! The one place that chooses between the recursive algorithms and the operator form
//! ([`Method`]), and the floating-base dynamics as methods of [`Robot`] with their public names.
//!
//! [`Method`]'s functions work over a caller's [`Data`] and leave their results in it, whichever
//! implementation runs; the Python bindings and [`crate::FlexibleArm`] call them. The `Robot`
//! methods allocate a fresh [`Data`] (or [`Operators`]) per call, for convenience: loops that call
//! the dynamics many times should keep a [`Data`] and call [`Method`] or
//! [`crate::algorithms`] directly.
//!
//! ```
//! use orbitflex::{Loads, Method, RigidState, Robot};
//!
//! let robot = Robot::space_arm();
//! let n = robot.dof();
//! let (q, qd, tau) = (vec![0.3; n], vec![0.2; n], vec![1.0; n]);
//! let state = RigidState::new(&q, &[0.0, 0.0, 0.1, 0.0, 0.0, 0.0], &qd);
//! let fast = robot.forward_dynamics(&state, &tau, &Loads::ZERO, Method::Recursive)?;
//! let reference = robot.forward_dynamics(&state, &tau, &Loads::ZERO, Method::Operator)?;
//! assert!((fast - reference).amax() < 1e-9);
//! # Ok::<(), orbitflex::Error>(())
//! ```

use crate::algorithms::{self, Data};
use crate::args::{check_base_pose, check_vector, Loads, RigidState};
use crate::error::Result;
use crate::model::Robot;
use crate::operators::Operators;
use crate::overflow::{check_result, Input};
use crate::spatial::{quaternion_to_rotation, Force, Mat6, Vec3};
use nalgebra::{DMatrix, DVector};

/// Which implementation of the rigid-body dynamics to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// The recursive algorithms of [`crate::algorithms`] (O(n), allocation-free). The default.
    #[default]
    Recursive,
    /// The paper's dense operator form (A.13)–(A.19): O(n³), the reference for validation.
    Operator,
}

impl Method {
    /// `"recursive"` or `"operator"`.
    pub fn name(self) -> &'static str {
        match self {
            Method::Recursive => "recursive",
            Method::Operator => "operator",
        }
    }

    /// Parses [`Method::name`].
    pub fn from_name(name: &str) -> Result<Method> {
        match name {
            "recursive" => Ok(Method::Recursive),
            "operator" => Ok(Method::Operator),
            other => Err(crate::Error::InvalidArgument {
                what: "method".into(),
                message: format!("expected \"recursive\" or \"operator\", given {other:?}"),
            }),
        }
    }

    /// The mass matrix `𝓜 = [[M_b, M_rb], [M_br, M_r]]` (A.19) into `data.mass_matrix`.
    pub fn mass_matrix<'a>(
        self,
        robot: &Robot,
        data: &'a mut Data,
        q: &[f64],
    ) -> Result<&'a DMatrix<f64>> {
        match self {
            Method::Recursive => algorithms::crba(robot, data, q),
            Method::Operator => {
                algorithms::check_data(robot, data)?;
                let zeros = vec![0.0; robot.dof()];
                let o = Operators::new(robot, &RigidState::at_rest(q, &zeros))?;
                data.mass_matrix = o.mass_matrix();
                Ok(&data.mass_matrix)
            }
        }
    }

    /// The bias `[C_B; C_r]` (A.19) into `data.tau`. A result that overflows (rates too large
    /// for floating point) is an error naming the rate.
    pub fn bias_forces<'a>(
        self,
        robot: &Robot,
        data: &'a mut Data,
        state: &RigidState,
    ) -> Result<&'a DVector<f64>> {
        match self {
            Method::Recursive => {
                algorithms::bias_forces(robot, data, state)?;
            }
            Method::Operator => {
                algorithms::check_data(robot, data)?;
                data.tau = Operators::new(robot, state)?.bias_forces();
            }
        }
        check_result("bias_forces", &[data.tau.as_slice()], &rates(state))?;
        Ok(&data.tau)
    }

    /// Forward dynamics `[α_B; q̈]` (A.19) into `data.ddq`. A result that overflows (inputs
    /// too large for floating point) is an error naming the input.
    pub fn forward_dynamics<'a>(
        self,
        robot: &Robot,
        data: &'a mut Data,
        state: &RigidState,
        tau: &[f64],
        loads: &Loads,
    ) -> Result<&'a DVector<f64>> {
        match self {
            Method::Recursive => {
                algorithms::aba(robot, data, state, tau, loads)?;
            }
            Method::Operator => {
                algorithms::check_data(robot, data)?;
                data.ddq = Operators::new(robot, state)?.forward_dynamics(tau, loads)?;
            }
        }
        let base_wrench = loads.base_wrench.to_array();
        let inputs = forward_inputs(state, tau, loads, &base_wrench);
        check_result("forward_dynamics", &[data.ddq.as_slice()], &inputs)?;
        Ok(&data.ddq)
    }

    /// [`Method::forward_dynamics`] for arguments the caller has already checked; the recursive
    /// path allocates nothing.
    pub(crate) fn forward_dynamics_unchecked(
        self,
        robot: &Robot,
        data: &mut Data,
        state: &RigidState,
        tau: &[f64],
        loads: &Loads,
    ) -> Result<()> {
        match self {
            Method::Recursive => algorithms::aba_unchecked(robot, data, state, tau, loads),
            Method::Operator => {
                let acc = Operators::new(robot, state)?.forward_dynamics(tau, loads)?;
                data.ddq.copy_from(&acc);
                Ok(())
            }
        }
    }

    /// Inverse dynamics `[f_B; τ]` (A.19) into `data.tau`, for the classical base acceleration
    /// `base_acc = α_B` (base frame), joint accelerations `qdd` and the EE wrench `f`. A result
    /// that overflows (inputs too large for floating point) is an error naming the input.
    pub fn inverse_dynamics<'a>(
        self,
        robot: &Robot,
        data: &'a mut Data,
        state: &RigidState,
        base_acc: &[f64],
        qdd: &[f64],
        ee_wrench: &[f64],
    ) -> Result<&'a DVector<f64>> {
        match self {
            Method::Recursive => {
                algorithms::rnea(robot, data, state, base_acc, qdd, ee_wrench)?;
            }
            Method::Operator => {
                algorithms::check_data(robot, data)?;
                data.tau =
                    Operators::new(robot, state)?.inverse_dynamics(base_acc, qdd, ee_wrench)?;
            }
        }
        let inputs = inverse_inputs(state, base_acc, qdd, ee_wrench);
        check_result("inverse_dynamics", &[data.tau.as_slice()], &inputs)?;
        Ok(&data.tau)
    }
}

/// The rates of a state as inputs of [`check_result`]: velocity products grow as their square.
pub(crate) fn rates<'a>(state: &RigidState<'a>) -> [Input<'a>; 2] {
    [("base_twist", state.base_twist, 2), ("qd", state.qd, 2)]
}

/// The inputs of the forward dynamics (and of its derivatives) for [`check_result`]: the
/// rates, and the torques and wrenches, which the accelerations grow with linearly.
pub(crate) fn forward_inputs<'a>(
    state: &RigidState<'a>,
    tau: &'a [f64],
    loads: &Loads<'a>,
    base_wrench: &'a [f64; 6],
) -> [Input<'a>; 5] {
    let [twist, qd] = rates(state);
    [
        twist,
        qd,
        ("tau", tau, 1),
        ("base_wrench", base_wrench, 1),
        ("ee_wrench", loads.ee_wrench, 1),
    ]
}

/// The inputs of the inverse dynamics (and of its derivatives) for [`check_result`].
pub(crate) fn inverse_inputs<'a>(
    state: &RigidState<'a>,
    base_acc: &'a [f64],
    qdd: &'a [f64],
    ee_wrench: &'a [f64],
) -> [Input<'a>; 5] {
    let [twist, qd] = rates(state);
    [
        twist,
        qd,
        ("base_acc", base_acc, 1),
        ("qdd", qdd, 1),
        ("ee_wrench", ee_wrench, 1),
    ]
}

/// Expresses a momentum about the base origin in base axes (`h_B`) about the inertial origin in
/// inertial axes, given the base pose `[r_B; quat_B]` (model §1, §6.1): `L = R_B h_lin`,
/// `K = R_B h_ang + r_B × L`. Returns `[K; L]`.
pub fn momentum_in_inertial_frame(base_pose: &[f64], h_base: &Force) -> [f64; 6] {
    let r = quaternion_to_rotation(&base_pose[crate::spatial::POSE_QUATERNION]);
    let position = Vec3::new(base_pose[0], base_pose[1], base_pose[2]);
    let linear = r * h_base.linear;
    let angular = r * h_base.angular + position.cross(&linear);
    Force::new(angular, linear).to_array()
}

impl Robot {
    /// The (6+n)×(6+n) mass matrix `𝓜 = [[M_b, M_rb], [M_br, M_r]]` (A.19), symmetric positive
    /// definite. Rows/columns: base `[ω; v]`, then joints.
    pub fn mass_matrix(&self, q: &[f64], method: Method) -> Result<DMatrix<f64>> {
        Ok(method.mass_matrix(self, &mut Data::new(self), q)?.clone())
    }

    /// The bias `[C_B; C_r]` (A.19): the generalized force that holds the accelerations at zero.
    pub fn bias_forces(&self, state: &RigidState, method: Method) -> Result<DVector<f64>> {
        Ok(method
            .bias_forces(self, &mut Data::new(self), state)?
            .clone())
    }

    /// `J_e` (6×n): joint rates to the twist `[ω; v]` of end-effector `ee` in its own frame with
    /// the base at rest (model §2: `J = Bᵀ Φ H`). `ee` indexes [`Robot::ee_links`]; `None` is
    /// the only end-effector (an error listing them when there are several).
    pub fn ee_jacobian(&self, q: &[f64], ee: Option<usize>) -> Result<DMatrix<f64>> {
        let ee = self.ee_choice(ee)?;
        let mut data = Data::new(self);
        algorithms::ee_jacobian(self, &mut data, q, ee)?;
        Ok(data.jacobian)
    }

    /// The generalized Jacobian of the free-floating arm with zero momentum (model §2), 6×n:
    /// `V_e = (J_e − Φ_{e,B} M_b⁻¹ M_rb) q̇` in the frame of end-effector `ee` (as in
    /// [`ee_jacobian`](Self::ee_jacobian)), the EE twist the joint rates give once the base has
    /// reacted (`V_B = −M_b⁻¹ M_rb q̇`).
    ///
    /// ```
    /// use nalgebra::{DVector, Vector6};
    /// use orbitflex::{RigidState, Robot};
    /// let robot = Robot::space_arm();
    /// let (q, qd) = (vec![0.3; 7], DVector::from_vec(vec![0.1, -0.2, 0.3, -0.1, 0.2, 0.1, 0.5]));
    /// let m = robot.mass_matrix(&q, orbitflex::Method::Recursive)?;
    /// // the base's reaction that keeps the momentum zero
    /// let m_b = m.fixed_view::<6, 6>(0, 0).into_owned();
    /// let base = -m_b.cholesky().unwrap().solve(&(m.view((0, 6), (6, 7)) * &qd));
    /// let h = robot.momentum(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], &RigidState::new(&q, base.as_slice(), qd.as_slice()))?;
    /// assert!(h.iter().all(|v| v.abs() < 1e-9));
    /// // the EE twist Φ_{n+1,B} V_B + J q̇ is what the generalized Jacobian gives
    /// let twist = robot.ee_base_operator(&q, None)? * Vector6::from_column_slice(base.as_slice())
    ///     + Vector6::from_column_slice((robot.ee_jacobian(&q, None)? * &qd).as_slice());
    /// let direct = robot.generalized_jacobian(&q, None)? * &qd;
    /// assert!((twist - Vector6::from_column_slice(direct.as_slice())).amax() < 1e-12);
    /// # Ok::<(), orbitflex::Error>(())
    /// ```
    pub fn generalized_jacobian(&self, q: &[f64], ee: Option<usize>) -> Result<DMatrix<f64>> {
        let ee = self.ee_choice(ee)?;
        let mut data = Data::new(self);
        let m = algorithms::crba(self, &mut data, q)?;
        let n = self.dof();
        let m_b = m.fixed_view::<6, 6>(0, 0).into_owned();
        let m_rb = m.view((0, 6), (6, n)).into_owned();
        let reaction = m_b
            .cholesky()
            .ok_or_else(|| crate::Error::InvalidArgument {
                what: "mass matrix".into(),
                message: "the base block M_b is not positive definite here".into(),
            })?
            .solve(&m_rb);
        algorithms::ee_jacobian(self, &mut data, q, ee)?;
        let correction = data.ee_base * reaction;
        Ok(&data.jacobian - DMatrix::from_column_slice(6, n, correction.as_slice()))
    }

    /// `Φ_{e,B}` (6×6): base twist to the twist of end-effector `ee`, both in their own frames
    /// (`ee` as in [`ee_jacobian`](Self::ee_jacobian)).
    pub fn ee_base_operator(&self, q: &[f64], ee: Option<usize>) -> Result<Mat6> {
        let ee = self.ee_choice(ee)?;
        check_vector("q", q, self.dof())?;
        Ok(algorithms::ee_from_base(self, q, ee).matrix())
    }

    /// Forward dynamics `[α_B; q̈]` (A.19): `α_B` is the base's classical acceleration
    /// `[ω̇_B; v̇_B]` in the base frame (model §1), for joint torques `tau` (N·m) and the external
    /// [`Loads`].
    pub fn forward_dynamics(
        &self,
        state: &RigidState,
        tau: &[f64],
        loads: &Loads,
        method: Method,
    ) -> Result<DVector<f64>> {
        Ok(method
            .forward_dynamics(self, &mut Data::new(self), state, tau, loads)?
            .clone())
    }

    /// Inverse dynamics `[f_B; τ]` (A.19) for the classical base acceleration `α_B` (base frame)
    /// and joint accelerations `q̈`, with the EE wrenches `[f_1; …; f_k]` (the force each
    /// end-effector exerts on its environment, in its own frame; 6 numbers per end-effector, or
    /// empty for none).
    pub fn inverse_dynamics(
        &self,
        state: &RigidState,
        base_acc: &[f64],
        qdd: &[f64],
        ee_wrench: &[f64],
        method: Method,
    ) -> Result<DVector<f64>> {
        Ok(method
            .inverse_dynamics(self, &mut Data::new(self), state, base_acc, qdd, ee_wrench)?
            .clone())
    }

    /// The dense operators of the paper's derivation at this state (A.13)–(A.19).
    pub fn operators(&self, state: &RigidState) -> Result<Operators> {
        Operators::new(self, state)
    }

    /// Total spatial momentum of base and links `[angular; linear]` in the inertial frame, about
    /// the inertial origin (model §6.1); `base_pose = [r_B; quat_B (x, y, z, w)]`.
    pub fn momentum(&self, base_pose: &[f64], state: &RigidState) -> Result<[f64; 6]> {
        check_base_pose(base_pose)?;
        let h = algorithms::momentum(self, &mut Data::new(self), state)?;
        Ok(momentum_in_inertial_frame(base_pose, &h))
    }

    /// Kinetic energy of base and links `½ νᵀ 𝓜 ν`, `ν = [V_B; q̇]` (J).
    pub fn kinetic_energy(&self, state: &RigidState) -> Result<f64> {
        algorithms::kinetic_energy(self, &mut Data::new(self), state)
    }
}

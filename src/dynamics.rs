//! The floating-base dynamics as methods of [`Robot`], with the names of SPEC §8.
//!
//! These allocate a fresh [`Data`] (or [`Operators`]) per call, for convenience. Loops that call
//! the dynamics many times should keep a [`Data`] and call [`crate::algorithms`] directly.

use crate::algorithms::{self, Data, Method};
use crate::error::{check_vector, Result};
use crate::model::Robot;
use crate::operators::Operators;
use crate::spatial::{quaternion_to_rotation, Force, Mat6, Vec3};
use nalgebra::{DMatrix, DVector};

const ZERO6: [f64; 6] = [0.0; 6];

/// Expresses a momentum about the base origin in base axes (`h_B`) about the inertial origin in
/// inertial axes, given the base pose `[r_B; quat_B]` (SPEC §1, §6.1): `L = R_B h_lin`,
/// `K = R_B h_ang + r_B × L`. Returns `[K; L]`.
pub fn momentum_in_inertial_frame(base_pose: &[f64], h_base: &Force) -> [f64; 6] {
    let r = quaternion_to_rotation(&base_pose[3..7]);
    let position = Vec3::new(base_pose[0], base_pose[1], base_pose[2]);
    let linear = r * h_base.linear;
    let angular = r * h_base.angular + position.cross(&linear);
    [
        angular.x, angular.y, angular.z, linear.x, linear.y, linear.z,
    ]
}

/// Checks a base pose `[r_B (3); quat_B (4) as (x, y, z, w)]`: 7 finite numbers, quaternion of
/// non-zero norm (it is normalised where used).
pub(crate) fn check_base_pose(base_pose: &[f64]) -> Result<()> {
    check_vector("base_pose", base_pose, 7)?;
    let norm = base_pose[3..7].iter().map(|v| v * v).sum::<f64>().sqrt();
    if norm < 1e-9 {
        return Err(crate::Error::InvalidArgument {
            what: "base_pose".into(),
            message:
                "the quaternion (elements 3..7, x y z w) has zero norm; expected a unit quaternion"
                    .into(),
        });
    }
    Ok(())
}

impl Robot {
    /// The (6+n)×(6+n) mass matrix `𝓜 = [[M_b, M_rb], [M_br, M_r]]` (A.19), symmetric positive
    /// definite. Rows/columns: base `[ω; v]`, then joints.
    pub fn mass_matrix(&self, q: &[f64], method: Method) -> Result<DMatrix<f64>> {
        match method {
            Method::Recursive => Ok(algorithms::crba(self, &mut Data::new(self), q)?.clone()),
            Method::Operator => {
                let zeros = vec![0.0; self.dof()];
                Ok(Operators::new(self, q, &ZERO6, &zeros)?.mass_matrix())
            }
        }
    }

    /// The bias `[C_B; C_r]` (A.19) at base twist `[ω_B; v_B]` (base frame) and joint rates.
    pub fn bias_forces(
        &self,
        q: &[f64],
        base_twist: &[f64],
        qd: &[f64],
        method: Method,
    ) -> Result<DVector<f64>> {
        match method {
            Method::Recursive => {
                Ok(algorithms::bias_forces(self, &mut Data::new(self), q, base_twist, qd)?.clone())
            }
            Method::Operator => Ok(Operators::new(self, q, base_twist, qd)?.bias_forces()),
        }
    }

    /// `J` (6×n): joint rates to EE twist `[ω; v]` in the EE frame with the base at rest
    /// (SPEC §2: `J = Bᵀ Φ H`).
    pub fn ee_jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        let mut data = Data::new(self);
        algorithms::ee_jacobian(self, &mut data, q)?;
        Ok(data.jacobian)
    }

    /// `Φ_{n+1,B}` (6×6): base twist to EE twist, both in their own frames.
    pub fn ee_base_operator(&self, q: &[f64]) -> Result<Mat6> {
        let mut data = Data::new(self);
        algorithms::ee_jacobian(self, &mut data, q)?;
        Ok(data.ee_base)
    }

    /// Forward dynamics `[α_B; q̈]` (A.19): `α_B` is the base's classical acceleration
    /// `[ω̇_B; v̇_B]` in the base frame (SPEC §1). `base_wrench = f_B` (base frame, about the base
    /// origin) and `ee_wrench = f` (EE frame; the force the EE exerts on its environment) default to
    /// zero.
    #[allow(clippy::too_many_arguments)]
    pub fn forward_dynamics(
        &self,
        q: &[f64],
        base_twist: &[f64],
        qd: &[f64],
        tau: &[f64],
        base_wrench: Option<&[f64]>,
        ee_wrench: Option<&[f64]>,
        method: Method,
    ) -> Result<DVector<f64>> {
        let base_wrench = base_wrench.unwrap_or(&ZERO6);
        let ee_wrench = ee_wrench.unwrap_or(&ZERO6);
        match method {
            Method::Recursive => Ok(algorithms::aba(
                self,
                &mut Data::new(self),
                q,
                base_twist,
                qd,
                tau,
                base_wrench,
                ee_wrench,
            )?
            .clone()),
            Method::Operator => Operators::new(self, q, base_twist, qd)?.forward_dynamics(
                tau,
                base_wrench,
                ee_wrench,
            ),
        }
    }

    /// Inverse dynamics `[f_B; τ]` (A.19) for base acceleration `α_B` (classical, base frame) and
    /// joint accelerations `q̈`, with the EE wrench `f` (default zero).
    #[allow(clippy::too_many_arguments)]
    pub fn inverse_dynamics(
        &self,
        q: &[f64],
        base_twist: &[f64],
        qd: &[f64],
        base_acc: &[f64],
        qdd: &[f64],
        ee_wrench: Option<&[f64]>,
        method: Method,
    ) -> Result<DVector<f64>> {
        let ee_wrench = ee_wrench.unwrap_or(&ZERO6);
        match method {
            Method::Recursive => Ok(algorithms::rnea(
                self,
                &mut Data::new(self),
                q,
                base_twist,
                qd,
                base_acc,
                qdd,
                ee_wrench,
            )?
            .clone()),
            Method::Operator => {
                Operators::new(self, q, base_twist, qd)?.inverse_dynamics(base_acc, qdd, ee_wrench)
            }
        }
    }

    /// The dense operators of the seed at this state (A.13)–(A.19).
    pub fn operators(&self, q: &[f64], base_twist: &[f64], qd: &[f64]) -> Result<Operators> {
        Operators::new(self, q, base_twist, qd)
    }

    /// Total spatial momentum of base and links `[angular; linear]` in the inertial frame, about
    /// the inertial origin (SPEC §6.1); `base_pose = [r_B; quat_B (x, y, z, w)]`.
    pub fn momentum(
        &self,
        base_pose: &[f64],
        q: &[f64],
        base_twist: &[f64],
        qd: &[f64],
    ) -> Result<[f64; 6]> {
        check_base_pose(base_pose)?;
        let h = algorithms::momentum(self, &mut Data::new(self), q, base_twist, qd)?;
        Ok(momentum_in_inertial_frame(base_pose, &h))
    }

    /// Kinetic energy of base and links `½ νᵀ 𝓜 ν`, `ν = [V_B; q̇]` (J).
    pub fn kinetic_energy(&self, q: &[f64], base_twist: &[f64], qd: &[f64]) -> Result<f64> {
        algorithms::kinetic_energy(self, &mut Data::new(self), q, base_twist, qd)
    }
}

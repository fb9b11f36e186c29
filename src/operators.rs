//! The paper's operator form (A.11)–(A.19): dense stacked operators and, from them, the
//! floating-base equations of motion.
//!
//! This is the literal, O(n³), allocating reference. Every recursive algorithm in
//! [`crate::algorithms`] is tested against it.
//!
//! ```
//! use orbitflex::{Operators, RigidState, Robot};
//! let robot = Robot::space_arm();
//! let n = robot.dof();
//! let (q, qd) = (vec![0.2; n], vec![0.1; n]);
//! let ops = Operators::new(&robot, &RigidState::new(&q, &[0.0; 6], &qd))?;
//! assert_eq!(ops.phi.shape(), (6 * n, 6 * n));
//! // M_br = M_rbᵀ (A.19), and the mass matrix is symmetric
//! assert!((&ops.m_br - ops.m_rb.transpose()).amax() < 1e-9);
//! let m = ops.mass_matrix();
//! assert!((&m - m.transpose()).amax() < 1e-9);
//! # Ok::<(), orbitflex::Error>(())
//! ```

use crate::args::{check_vector, Loads, RigidState};
use crate::error::{Error, Result};
use crate::model::Robot;
use crate::spatial::{bias_force, coriolis_acceleration, Force, Mat6, Motion, Transform};
use nalgebra::{DMatrix, DVector};

/// Dense operators of the paper's derivation at one state `(q, V_B, q̇)`. Stacked quantities run over links
/// `1..n`, six rows per link, `[angular; linear]` per block.
///
/// Block `(i, k)` of `Φ` is `Φ_{ik}` when body `k` is body `i` or one of its ancestors (every
/// `k ≤ i` on a chain) and zero otherwise, so the same assembly serves a tree.
#[derive(Debug, Clone)]
pub struct Operators {
    /// `Φ` (6n×6n), lower block-triangular, block `(i,k) = Φ_{ik}` for `i ≥ k` (A.13 ff.).
    pub phi: DMatrix<f64>,
    /// `H` (6n×n), block-diagonal `H_i = [h_i; 0]` (A.1).
    pub h: DMatrix<f64>,
    /// `M` (6n×6n), block-diagonal link inertias `M_i` (A.9).
    pub m: DMatrix<f64>,
    /// `a` (6n), stacked Coriolis accelerations `a_i` (A.7).
    pub a: DVector<f64>,
    /// `b` (6n), stacked bias forces `b_i` (A.10).
    pub b: DVector<f64>,
    /// `B` (6n×6k): one block column per end-effector `e`, zero except in the row block of the
    /// body `b` carrying it, which holds `Φ_{e,b}ᵀ` (on a chain, `k = 1` and the one block is
    /// the last).
    pub b_ee: DMatrix<f64>,
    /// `Φ̂₁` (6n×6), blocks `Φ_{iB}` (A.17).
    pub phi_hat1: DMatrix<f64>,
    /// `Φ̂₂ = Φ̂₁ᵀ` (6×6n) (A.18).
    pub phi_hat2: DMatrix<f64>,
    /// Base inertia `M_B` (6×6) (A.9).
    pub m_base: Mat6,
    /// Base bias force `b_B` (6) (A.10).
    pub b_base: DVector<f64>,
    /// `M_b = M_B + Φ̂₂ M Φ̂₁` (A.19).
    pub m_b: DMatrix<f64>,
    /// `M_rb = Φ̂₂ M Φ H` (A.19).
    pub m_rb: DMatrix<f64>,
    /// `M_br = Hᵀ Φᵀ M Φ̂₁` (A.19).
    pub m_br: DMatrix<f64>,
    /// `M_r = Hᵀ Φᵀ M Φ H` (A.19), the fixed-base mass matrix.
    pub m_r: DMatrix<f64>,
    /// `C_B = Φ̂₂ M Φ a + b_B + Φ̂₂ b` (A.19).
    pub c_b: DVector<f64>,
    /// `C_r = Hᵀ Φᵀ M Φ a + Hᵀ Φᵀ b` (A.19), the fixed-base Coriolis/centrifugal torques.
    pub c_r: DVector<f64>,
    /// `J = Bᵀ Φ H` (6k×n), the end-effectors' Jacobians `J_e` stacked: the paper's
    /// `J = Hᵀ Φᵀ B` is a typo (model §2); `Jᵀ = Hᵀ Φᵀ B`.
    pub j: DMatrix<f64>,
    /// `Φ_{e,B} = Φ_{e,b} Φ_{bB}` stacked over the end-effectors (6k×6), `b` the body carrying
    /// end-effector `e`.
    pub phi_ee_base: DMatrix<f64>,
}

impl Operators {
    /// Assembles every operator at `state`: `q`, `V_B = [ω_B; v_B]` (base frame) and `q̇`.
    /// Per link `Φ_{i,λ(i)}`, the velocities (A.4), `a_i` (A.7) and `b_i` (A.10); then the
    /// block operators `Φ`, `H`, `M`, `Φ̂₁`, `B` and the products of (A.19).
    // Block indices (i, k) are the equations' indices; iterator chains would hide them.
    #[allow(clippy::needless_range_loop)]
    pub fn new(robot: &Robot, state: &RigidState) -> Result<Self> {
        state.check(robot)?;
        let (q, qd) = (state.q, state.qd);
        let n = robot.dof();
        // Φ, M and the products formed from them are (6n)² each.
        crate::args::check_dense(
            "operators",
            6 * n,
            6 * n,
            4,
            "the recursive algorithms give the same quantities in O(n) memory",
        )?;
        let inertias = robot.inertias();
        let parents = robot.parents();

        // Per-link Φ_{i,λ(i)}, velocities (A.4), a_i (A.7), b_i (A.10).
        let mut step = vec![Transform::identity()];
        let mut velocity = vec![Motion::from_slice(state.base_twist)];
        let mut a = DVector::zeros(6 * n);
        let mut b = DVector::zeros(6 * n);
        for (i, joint) in robot.joints().iter().enumerate() {
            let phi = joint.transform(q[i]);
            let h = Motion::new(joint.axis, nalgebra::Vector3::zeros());
            let parent = &velocity[parents[i + 1]];
            let v = phi.apply_motion(parent) + h * qd[i];
            coriolis_acceleration(&phi, &parent.angular, &v.angular)
                .write_to(&mut a.as_mut_slice()[6 * i..]);
            bias_force(&inertias[i + 1], &v.angular).write_to(&mut b.as_mut_slice()[6 * i..]);
            step.push(phi);
            velocity.push(v);
        }

        // Φ_{ik} = Φ_{i,λ(i)} Φ_{λ(i),k} for k an ancestor of i (k = 0 is the base), Φ_{ii} = I;
        // None where k does not support i.
        let mut phi_to: Vec<Vec<Option<Transform>>> = vec![vec![None; n + 1]; n + 1];
        phi_to[0][0] = Some(Transform::identity());
        for i in 1..=n {
            phi_to[i][i] = Some(Transform::identity());
            for k in 0..i {
                phi_to[i][k] = phi_to[parents[i]][k].map(|t| step[i].compose(&t));
            }
        }

        let mut phi = DMatrix::zeros(6 * n, 6 * n);
        let mut h = DMatrix::zeros(6 * n, n);
        let mut m = DMatrix::zeros(6 * n, 6 * n);
        let mut phi_hat1 = DMatrix::zeros(6 * n, 6);
        for i in 1..=n {
            let r = 6 * (i - 1);
            for k in 1..=i {
                if let Some(t) = &phi_to[i][k] {
                    phi.view_mut((r, 6 * (k - 1)), (6, 6))
                        .copy_from(&t.matrix());
                }
            }
            h.view_mut((r, i - 1), (3, 1))
                .copy_from(&robot.joints()[i - 1].axis);
            m.view_mut((r, r), (6, 6)).copy_from(&inertias[i].matrix());
            let to_base = phi_to[i][0].expect("the base supports every body");
            phi_hat1
                .view_mut((r, 0), (6, 6))
                .copy_from(&to_base.matrix());
        }
        let k = robot.end_effectors().len();
        let mut b_ee = DMatrix::zeros(6 * n, 6 * k);
        let mut phi_ee_base = DMatrix::zeros(6 * k, 6);
        for (e, ee) in robot.end_effectors().iter().enumerate() {
            if ee.body > 0 {
                b_ee.view_mut((6 * (ee.body - 1), 6 * e), (6, 6))
                    .copy_from(&ee.transform.matrix().transpose());
            }
            let to_base = phi_to[ee.body][0].expect("the base supports every body");
            phi_ee_base
                .view_mut((6 * e, 0), (6, 6))
                .copy_from(&ee.transform.compose(&to_base).matrix());
        }

        let phi_hat2 = phi_hat1.transpose();
        let m_base = inertias[0].matrix();
        let b_base = DVector::from_column_slice(
            bias_force(&inertias[0], &velocity[0].angular)
                .to_vector()
                .as_slice(),
        );
        let phi_h = &phi * &h;
        let m_phi_h = &m * &phi_h;
        let m_phi_a = &m * (&phi * &a);
        let m_b = DMatrix::from_iterator(6, 6, m_base.iter().copied()) + &phi_hat2 * &m * &phi_hat1;
        let m_rb = &phi_hat2 * &m_phi_h;
        let m_br = phi_h.transpose() * &m * &phi_hat1;
        let m_r = phi_h.transpose() * &m_phi_h;
        let c_b = &phi_hat2 * &m_phi_a + &b_base + &phi_hat2 * &b;
        let c_r = phi_h.transpose() * &m_phi_a + phi_h.transpose() * &b;
        let j = b_ee.transpose() * &phi_h;
        Ok(Self {
            phi,
            h,
            m,
            a,
            b,
            b_ee,
            phi_hat1,
            phi_hat2,
            m_base,
            b_base,
            m_b,
            m_rb,
            m_br,
            m_r,
            c_b,
            c_r,
            j,
            phi_ee_base,
        })
    }

    /// The (6+n)×(6+n) mass matrix `𝓜 = [[M_b, M_rb], [M_br, M_r]]` (A.19).
    pub fn mass_matrix(&self) -> DMatrix<f64> {
        let n = self.m_r.nrows();
        let mut out = DMatrix::zeros(6 + n, 6 + n);
        out.view_mut((0, 0), (6, 6)).copy_from(&self.m_b);
        out.view_mut((0, 6), (6, n)).copy_from(&self.m_rb);
        out.view_mut((6, 0), (n, 6)).copy_from(&self.m_br);
        out.view_mut((6, 6), (n, n)).copy_from(&self.m_r);
        out
    }

    /// The bias `[C_B; C_r]` (A.19).
    pub fn bias_forces(&self) -> DVector<f64> {
        let n = self.c_r.len();
        let mut out = DVector::zeros(6 + n);
        out.rows_mut(0, 6).copy_from(&self.c_b);
        out.rows_mut(6, n).copy_from(&self.c_r);
        out
    }

    /// `[Φ_{e,B}ᵀ; J_eᵀ]` side by side over the end-effectors ((6+n)×6k): maps the EE wrenches
    /// `[f_1; …; f_k]` into generalized forces (A.19).
    pub fn ee_force_map(&self) -> DMatrix<f64> {
        let (k6, n) = self.j.shape();
        let mut out = DMatrix::zeros(6 + n, k6);
        out.view_mut((0, 0), (6, k6))
            .copy_from(&self.phi_ee_base.transpose());
        out.view_mut((6, 0), (n, k6)).copy_from(&self.j.transpose());
        out
    }

    /// Forward dynamics from (A.19) by a Cholesky solve:
    /// `[α_B; q̈] = 𝓜⁻¹ ([f_B; τ] − [C_B; C_r] − Σ_e [Φ_{e,B}ᵀ; J_eᵀ] f_e)`.
    pub fn forward_dynamics(&self, tau: &[f64], loads: &Loads) -> Result<DVector<f64>> {
        let n = self.m_r.nrows();
        check_vector("tau", tau, n)?;
        loads.check()?;
        check_ee_length(self.j.nrows(), loads.ee_wrench)?;
        let mut rhs = DVector::zeros(6 + n);
        rhs.rows_mut(0, 6)
            .copy_from_slice(&loads.base_wrench.to_array());
        rhs.rows_mut(6, n).copy_from_slice(tau);
        rhs -= self.bias_forces();
        if !loads.ee_wrench.is_empty() {
            rhs -= self.ee_force_map() * DVector::from_column_slice(loads.ee_wrench);
        }
        let chol = self
            .mass_matrix()
            .cholesky()
            .ok_or_else(|| Error::InvalidArgument {
                what: "mass matrix".into(),
                message: "not positive definite at this configuration".into(),
            })?;
        Ok(chol.solve(&rhs))
    }

    /// Inverse dynamics from (A.19):
    /// `[f_B; τ] = 𝓜 [α_B; q̈] + [C_B; C_r] + Σ_e [Φ_{e,B}ᵀ; J_eᵀ] f_e` (`ee_wrench` empty: none).
    pub fn inverse_dynamics(
        &self,
        base_acc: &[f64],
        qdd: &[f64],
        ee_wrench: &[f64],
    ) -> Result<DVector<f64>> {
        let n = self.m_r.nrows();
        check_vector("base_acc", base_acc, 6)?;
        check_vector("qdd", qdd, n)?;
        crate::args::check_finite("ee_wrench", ee_wrench)?;
        check_ee_length(self.j.nrows(), ee_wrench)?;
        let mut acc = DVector::zeros(6 + n);
        acc.rows_mut(0, 6).copy_from_slice(base_acc);
        acc.rows_mut(6, n).copy_from_slice(qdd);
        let mut out = self.mass_matrix() * acc + self.bias_forces();
        if !ee_wrench.is_empty() {
            out += self.ee_force_map() * DVector::from_column_slice(ee_wrench);
        }
        Ok(out)
    }

    /// Spatial momentum about the base origin in the base frame, `[M_b M_rb] [V_B; q̇]`: the sum
    /// of `Φ_{iB}ᵀ M_i V_i` over base and links.
    pub fn base_momentum(&self, base_twist: &[f64], qd: &[f64]) -> Force {
        let v = nalgebra::Vector6::from_column_slice(base_twist);
        let h = &self.m_b * DVector::from_column_slice(v.as_slice())
            + &self.m_rb * DVector::from_column_slice(qd);
        Force::from_slice(h.as_slice())
    }
}

/// An EE wrench is empty or has the `6k` numbers of the stacked Jacobian's rows.
fn check_ee_length(rows: usize, ee_wrench: &[f64]) -> Result<()> {
    if ee_wrench.is_empty() || ee_wrench.len() == rows {
        return Ok(());
    }
    Err(Error::InvalidArgument {
        what: "ee_wrench".into(),
        message: format!(
            "expected {rows} numbers (one [moment; force] per end-effector), given {}",
            ee_wrench.len()
        ),
    })
}

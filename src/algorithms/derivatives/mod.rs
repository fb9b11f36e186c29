//! Analytical derivatives of inverse and forward dynamics (RNEA and ABA), O(n²), in the paper's
//! conventions: `[ω; v]` vectors, the base's classical acceleration `α_B` as an input of the
//! inverse dynamics and an output of the forward dynamics.
//!
//! **Inverse dynamics.** Everything is expressed in the base frame `B` (body 0) at the current
//! instant, where the recursions need no transforms: with `S_i` joint `i`'s axis as a motion,
//! `v_i = v_λ + S_i q̇_i`, `a_i = a_λ + S_i q̈_i + v_i ×ₘ S_i q̇_i` (spatial accelerations, the base's
//! `a_B = α_B − [0; ω_B × v_B]`), `f_i = I_i a_i + v_i ×* I_i v_i`, and the composites
//! `F_i = Σ_{j ⪰ i} f_j` (plus the EE wrench), `I^c_i = Σ I_j`, `H_i = Σ I_j v_j`, give
//! `τ_i = S_iᵀ F_i` and `f_B = F_B`.
//!
//! Turning joint `k` by `δq_k` turns its whole subtree about `S_k`. Split off that rigid turn
//! (which leaves every `τ_i` of the subtree unchanged and adds `S_k ×* F_k` to `δF_k`); what is
//! left is a uniform velocity change `u_k = v_k ×ₘ S_k` and an acceleration change
//! `c_k + u_k ×ₘ v_j`, `c_k = a_k ×ₘ S_k + v_k ×ₘ u_k`, on every body `j` of the subtree. Summed over
//! a subtree, a velocity change `u` and an acceleration change `c + u ×ₘ v_j` change the force by
//! `I^c_i c + B_i u + u ×* H_i`, where `B_i = Σ_{j ⪰ i} (v_j ×* I_j − I_j v_j ×ₘ)` is symmetric:
//! with `v_j = [ω_j; v̄_j]`, `P = Ī_j [ω_j]×` (`Ī_j` the rotational inertia about the base origin,
//! `m_j c_j` the first moment), `B_j = [[T_j, [b_j]×], [−[b_j]×, 0]]` with
//! `T_j = −(P + Pᵀ) − (v̄_j (m c_j)ᵀ + (m c_j) v̄_jᵀ) + 2 (m c_j · v̄_j) 𝟙` and `b_j` the body's linear
//! momentum. So, for `i` in the subtree of `k` (`i ⪰ k`),
//!
//! ```text
//! ∂τ_i/∂q_k = α_i · c_k + β_i · u_k          ∂τ_i/∂q̇_k = 2 α_i · u_k + β_i · S_k
//! α_i = I^c_i S_i,  β_i = B_i S_i − S_i ×* H_i = [T_i s + 2 b_i × s_lin + H_ang × s; 0]
//! ```
//!
//! and for the ancestors `i ≺ k` and the base, `S_iᵀ` and `𝟙` of the subtree's force change
//! `δF_k = S_k ×* F_k + I^c_k c_k + B_k u_k + u_k ×* H_k` (angle) or
//! `2 I^c_k u_k + B_k S_k + S_k ×* H_k` (rate). A change `δV` of the base twist is the same with
//! `u = δV` and `c = [ω_B × δω; 2 v_B × δω]` (the classical `α_B` is held, which is where these
//! derivatives differ from Pinocchio's, whose base acceleration is spatial). O(n) 6-vector work
//! per body and two dot products per pair of joints.
//!
//! **Forward dynamics.** `ID(q, ν, FD(q, ν, u)) = u` for every input, so
//! `∂FD/∂(q, ν) = −𝓜⁻¹ ∂ID/∂(q, ν)` at `a = FD`, `∂FD/∂τ = 𝓜⁻¹ [0; 𝟙]`,
//! `∂FD/∂f_B = 𝓜⁻¹ [𝟙; 0]` and `∂FD/∂f = −𝓜⁻¹ [Φ_{n+1,B}ᵀ; Jᵀ]`. The articulated-body
//! factorisation that the forward dynamics has just built (`U`, `D`, `I^A_B`, valid at any
//! velocity) applies `𝓜⁻¹` to a column in O(n) (no mass matrix is formed): to the 6+n unit
//! columns for `𝓜⁻¹` itself, whose columns are `∂FD/∂τ` and `∂FD/∂f_B`; then, up to
//! [`DENSE_PRODUCTS_UP_TO`](forward::DENSE_PRODUCTS_UP_TO) joints, `−𝓜⁻¹ ∂ID/∂x` is a dense product (O(n³) with a small
//! constant, cheaper there), and above it the factorisation runs on the columns of `∂ID/∂x`,
//! so the whole is O(n²).
//!
//! **Directional derivatives.** [`fd_directional`] applies `∂FD/∂(q, ν, τ)` to many directions
//! without the matrices: the path and subtree sums of the formulas above give the inverse
//! dynamics' change in O(n) per direction, and the factorisation the `𝓜⁻¹`. The step Jacobians
//! of long arms use it.

// Loops run over body indices `i`, the equations' indices; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

mod directional;
mod forward;
mod inverse;
mod solve;

pub(crate) use directional::fd_directional;
use directional::Tile;
pub use forward::aba_derivatives;
pub(crate) use forward::aba_derivatives_into;
use inverse::id_derivatives;
pub use inverse::rnea_derivatives;
#[cfg(test)]
use solve::apply_inverse_kernel;
use solve::{apply_inverse, factorisation};

use super::data::{check_data, Data};
use crate::args::{check_vector, Loads, RigidState};
use crate::dynamics::{forward_inputs, inverse_inputs};
use crate::error::{Error, Result};
use crate::model::Robot;
use crate::overflow::check_result;
use crate::spatial::{skew, Force, Inertia, Mat3, Mat6, Motion, Transform, Vec3};
use nalgebra::DMatrix;

/// The derivatives of [`rnea_derivatives`] and [`aba_derivatives`], and their scratch memory.
/// Rows follow the generalized coordinates `[base (6); joints (n)]`; `ν = [V_B; q̇]`.
#[derive(Debug, Clone, Default)]
pub struct Derivatives {
    /// `∂[f_B; τ]/∂q`, (6+n)×n.
    pub id_q: DMatrix<f64>,
    /// `∂[f_B; τ]/∂ν`, (6+n)×(6+n).
    pub id_v: DMatrix<f64>,
    /// `∂[f_B; τ]/∂f = [Φ_{e,B}ᵀ; J_eᵀ]` per end-effector `e` (block column `e`), (6+n)×6k.
    pub id_ee_wrench: DMatrix<f64>,
    /// `∂[α_B; q̈]/∂q`, (6+n)×n.
    pub fd_q: DMatrix<f64>,
    /// `∂[α_B; q̈]/∂ν`, (6+n)×(6+n).
    pub fd_v: DMatrix<f64>,
    /// `∂[α_B; q̈]/∂τ = 𝓜⁻¹[0; 𝟙]`, (6+n)×n.
    pub fd_tau: DMatrix<f64>,
    /// `∂[α_B; q̈]/∂f_B = 𝓜⁻¹[𝟙; 0]`, (6+n)×6.
    pub fd_base_wrench: DMatrix<f64>,
    /// `∂[α_B; q̈]/∂f`, one block column per end-effector, (6+n)×6k.
    pub fd_ee_wrench: DMatrix<f64>,
    scratch: Scratch,
}

/// Per-body quantities of the inverse-dynamics derivatives, all in base-frame components, and
/// the buffers of the `𝓜⁻¹` solve.
#[derive(Debug, Clone, Default)]
struct Scratch {
    /// `Φ_{i,B}`: from the base to body `i`.
    to_body: Vec<Transform>,
    /// `S_i`, the joint axis as a motion.
    axis: Vec<Motion>,
    /// `v_i` and the spatial `a_i`.
    v: Vec<Motion>,
    a: Vec<Motion>,
    /// Subtree sums: `I^c_i`, `H_i = Σ I_j v_j`, `F_i = Σ f_j` (+ EE wrench), `T_i` of `B_i`.
    inertia: Vec<Composite>,
    momentum: Vec<Force>,
    force: Vec<Force>,
    t: Vec<Mat3>,
    /// `α_i = I^c_i S_i` and the angular part of `β_i` (its linear part is zero).
    alpha: Vec<Force>,
    beta: Vec<Vec3>,
    /// `u_k`, `c_k`, and the subtree's force change for `q_k` and for `q̇_k`.
    u: Vec<Motion>,
    c: Vec<Motion>,
    angle_force: Vec<Force>,
    rate_force: Vec<Force>,
    /// Which `k` last claimed body `i` for its subtree.
    stamp: Vec<usize>,
    /// `𝓜⁻¹`; the ABA's `U_i` in base components and `1/D_i`; `u_i` and `a_i` of every column
    /// (body-major).
    inverse: DMatrix<f64>,
    u_base: Vec<Force>,
    inverse_d: Vec<f64>,
    base_inverse: Mat6,
    /// Per body and direction (body-major): the solve's `p_i`, `a_i`; the directional
    /// derivative's path sums (`c`, `u`) and subtree sums.
    column_p: Vec<Force>,
    column_acc: Vec<Motion>,
    path_c: Vec<Motion>,
    path_u: Vec<Motion>,
    subtree: Vec<Force>,
    /// Right-hand sides, one row per generalized coordinate, one column per direction.
    rhs: Vec<f64>,
    tile: Tile,
    qdd: Vec<f64>,
}

impl Derivatives {
    /// Buffers for `n` joints and `k` end-effectors, allocated fallibly: the O(n²) ones take
    /// hundreds of megabytes for a thousand joints.
    fn try_new(n: usize, k: usize) -> Result<Self> {
        let (rows, bodies) = (6 + n, n + 1);
        let columns = 3 * n + 18;
        // the O(n²) buffers: six matrices of rows × (n or rows or 6k), 𝓜⁻¹, the per-direction
        // forces and motions (48 bytes each) and the right-hand sides
        let bytes = || -> Option<usize> {
            let matrices = rows.checked_mul(3 * n + 3 * rows + 6 + 12 * k)?;
            let directions = bodies.checked_mul(columns)?.checked_mul(2 * 48)?;
            matrices
                .checked_add(rows.checked_mul(columns)?)?
                .checked_mul(8)?
                .checked_add(directions)
        };
        let need = || Error::OutOfMemory {
            what: "the derivatives".into(),
            bytes: bytes(),
            hint: format!(
                "their buffers grow as n² (n = {n} joints); differentiate a smaller model"
            ),
        };
        let matrix = |r: usize, c: usize| -> Result<DMatrix<f64>> {
            Ok(DMatrix::from_vec(r, c, filled(r * c, 0.0, &need)?))
        };
        Ok(Self {
            id_q: matrix(rows, n)?,
            id_v: matrix(rows, rows)?,
            id_ee_wrench: matrix(rows, 6 * k)?,
            fd_q: matrix(rows, n)?,
            fd_v: matrix(rows, rows)?,
            fd_tau: matrix(rows, n)?,
            fd_base_wrench: matrix(rows, 6)?,
            fd_ee_wrench: matrix(rows, 6 * k)?,
            scratch: Scratch {
                to_body: vec![Transform::identity(); bodies],
                axis: vec![Motion::zero(); bodies],
                v: vec![Motion::zero(); bodies],
                a: vec![Motion::zero(); bodies],
                inertia: vec![Composite::default(); bodies],
                momentum: vec![Force::zero(); bodies],
                force: vec![Force::zero(); bodies],
                t: vec![Mat3::zeros(); bodies],
                alpha: vec![Force::zero(); bodies],
                beta: vec![Vec3::zeros(); bodies],
                u: vec![Motion::zero(); bodies],
                c: vec![Motion::zero(); bodies],
                angle_force: vec![Force::zero(); bodies],
                rate_force: vec![Force::zero(); bodies],
                stamp: vec![0; bodies],
                inverse: matrix(rows, rows)?,
                u_base: vec![Force::zero(); bodies],
                inverse_d: vec![0.0; bodies],
                base_inverse: Mat6::zeros(),
                column_p: filled(bodies * columns, Force::zero(), &need)?,
                column_acc: filled(bodies * columns, Motion::zero(), &need)?,
                path_c: Vec::new(),
                path_u: Vec::new(),
                subtree: Vec::new(),
                rhs: filled(rows * columns, 0.0, &need)?,
                tile: Tile::default(),
                qdd: vec![0.0; n],
            },
        })
    }
}

/// `len` copies of `value`, allocated fallibly: `Err(need())` when they do not fit.
fn filled<T: Clone>(len: usize, value: T, need: &dyn Fn() -> Error) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| need())?;
    v.resize(len, value);
    Ok(v)
}

/// A spatial inertia about the base origin in base axes, as subtree sums want it: mass `m`,
/// first moment `m c` and rotational inertia `Ī` (about the origin).
#[derive(Debug, Clone, Copy)]
struct Composite {
    mass: f64,
    first_moment: Vec3,
    rotational: Mat3,
}

impl Default for Composite {
    fn default() -> Self {
        Self {
            mass: 0.0,
            first_moment: Vec3::zeros(),
            rotational: Mat3::zeros(),
        }
    }
}

impl Composite {
    fn of(inertia: &Inertia) -> Self {
        Self {
            mass: inertia.mass,
            first_moment: inertia.com * inertia.mass,
            rotational: inertia.rotational,
        }
    }

    /// `I m = [Ī ω + m c × v; m v + ω × m c]`.
    #[inline]
    fn apply(&self, m: &Motion) -> Force {
        Force::new(
            self.rotational * m.angular + self.first_moment.cross(&m.linear),
            m.linear * self.mass + m.angular.cross(&self.first_moment),
        )
    }

    fn add(&mut self, other: &Composite) {
        self.mass += other.mass;
        self.first_moment += other.first_moment;
        self.rotational += other.rotational;
    }
}

/// The `c` of a base-twist change `δV` (module docs): with the classical `α_B` held, the spatial
/// accelerations change by `δa_B + v_B ×ₘ δV = [ω_B × δω; 2 v_B × δω]`.
#[inline]
fn base_acceleration_change(v0: &Motion, dv: &Motion) -> Motion {
    Motion::new(
        v0.angular.cross(&dv.angular),
        2.0 * v0.linear.cross(&dv.angular),
    )
}

/// `B y + y ×* H` for a subtree with `B = [[T, [b]×], [−[b]×, 0]]` and momentum `H` (`b` its
/// linear part): `[T y_ang + y_ang × H_ang; 2 y_ang × b]`.
#[inline]
fn coriolis(t: &Mat3, momentum: &Force, y: &Motion) -> Force {
    Force::new(
        t * y.angular + y.angular.cross(&momentum.angular),
        2.0 * y.angular.cross(&momentum.linear),
    )
}

/// The derivative buffers in `data` sized for `n` joints and `k` end-effectors (allocated on
/// first use); the caller moves them out of `data` for the duration of the call (moved out
/// through a `Result`, the struct was copied once more: 250 instructions a call).
fn size_derivatives(data: &mut Data, n: usize, k: usize) -> Result<()> {
    let d = &data.derivatives;
    if d.id_q.nrows() != 6 + n || d.id_ee_wrench.ncols() != 6 * k {
        resize_derivatives(data, n, k)?;
    }
    Ok(())
}

/// New buffers for `n` joints and `k` end-effectors in `data` (the old ones go first).
#[cold]
#[inline(never)]
fn resize_derivatives(data: &mut Data, n: usize, k: usize) -> Result<()> {
    data.derivatives = Derivatives::default();
    data.derivatives = Derivatives::try_new(n, k)?;
    Ok(())
}

/// `∂ID/∂f = [Φ_{e,B}ᵀ; J_eᵀ]` per end-effector `e`, from the transforms and axes
/// [`id_derivatives`] left in the scratch: column `j` of block `e` is the unit wrench `e_j` of
/// that end-effector moved to the base, `F = Φ_{e,B}ᵀ e_j`, and its generalized force `S_kᵀ F`
/// for the joints `k` that move its body (0 for the others).
fn ee_force_map(robot: &Robot, d: &mut Derivatives) {
    let s = &d.scratch;
    let rows = 6 + robot.dof();
    let map = d.id_ee_wrench.as_mut_slice();
    for (e, ee) in robot.end_effectors().iter().enumerate() {
        let to_ee = robot.frame_ee_transform(e).compose(&s.to_body[ee.body]);
        let forces: [Force; 6] = std::array::from_fn(|j| {
            let mut unit = [0.0; 6];
            unit[j] = 1.0;
            to_ee.apply_force_transpose(&Force::from_slice(&unit))
        });
        // column-major: column j is one contiguous slice
        let block = &mut map[6 * e * rows..6 * (e + 1) * rows];
        for (column, f) in block.chunks_exact_mut(rows).zip(&forces) {
            column[..6].copy_from_slice(&f.to_array());
            column[6..].fill(0.0);
        }
        for k in robot.path_to_base(ee.body) {
            for (j, f) in forces.iter().enumerate() {
                block[j * rows + 5 + k] = s.axis[k].dot(f);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{random_chain, random_state};

    /// The dispatched `apply_inverse` (the AVX2 copy where the processor has it) gives the same
    /// bits as the portable kernel.
    #[test]
    fn apply_inverse_copies_give_the_same_bits() {
        let robot = random_chain(11, 6);
        let (q, v, qd) = random_state(&robot, 3);
        let state = RigidState::new(&q, &v, &qd);
        let tau = vec![0.5; robot.dof()];
        let mut data = Data::new(&robot);
        aba_derivatives(&robot, &mut data, &state, &tau, &Loads::ZERO).unwrap();
        let mut s = std::mem::take(&mut data.derivatives.scratch);
        let m = 6 + robot.dof();
        let columns = 5;
        let rhs: Vec<f64> = (0..m * columns).map(|k| (k as f64 * 0.37).sin()).collect();
        let (mut fast, mut portable) = (rhs.clone(), rhs);
        apply_inverse(&robot, &mut s, &mut fast, columns);
        apply_inverse_kernel(&robot, &mut s, &mut portable, columns);
        assert_eq!(fast, portable);
    }
}

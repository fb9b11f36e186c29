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
//! [`DENSE_PRODUCTS_UP_TO`] joints, `−𝓜⁻¹ ∂ID/∂x` is a dense product (O(n³) with a small
//! constant, cheaper there), and above it the factorisation runs on the columns of `∂ID/∂x`,
//! so the whole is O(n²).
//!
//! **Directional derivatives.** [`fd_directional`] applies `∂FD/∂(q, ν, τ)` to many directions
//! without the matrices: the path and subtree sums of the formulas above give the inverse
//! dynamics' change in O(n) per direction, and the factorisation the `𝓜⁻¹`. The step Jacobians
//! of long arms use it.

// Loops run over body indices `i`, the equations' indices; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

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

/// `∂[f_B; τ]` with respect to `q`, `ν = [V_B; q̇]`, and the EE wrench `f`, at the state, the
/// classical base acceleration `base_acc = α_B`, `qdd` and `ee_wrench` (all as in
/// [`crate::algorithms::rnea`]), into `data.derivatives` (`id_q`, `id_v`, `id_ee_wrench`).
/// `∂[f_B; τ]/∂[α_B; q̈]` is the mass matrix ([`crate::algorithms::crba`]).
///
/// Of the per-body buffers of `data`, only `x` (the joint transforms at `q`) is refreshed; the
/// velocities and forces of [`crate::algorithms::rnea`] are not computed. The first call
/// allocates the O(n²) outputs; later calls reuse them.
pub fn rnea_derivatives<'a>(
    robot: &Robot,
    data: &'a mut Data,
    state: &RigidState,
    base_acc: &[f64],
    qdd: &[f64],
    ee_wrench: &[f64],
) -> Result<&'a Derivatives> {
    check_data(robot, data)?;
    state.check(robot)?;
    check_vector("base_acc", base_acc, 6)?;
    check_vector("qdd", qdd, robot.dof())?;
    crate::args::check_ee_wrench(robot, ee_wrench)?;
    size_derivatives(data, robot.dof(), robot.end_effectors().len())?;
    let mut d = std::mem::take(&mut data.derivatives);
    for i in 1..=robot.dof() {
        data.x[i] = robot.joint_transform(i, state.q[i - 1]);
    }
    id_derivatives(
        robot,
        data,
        &mut d,
        state,
        &Motion::from_slice(base_acc),
        qdd,
        ee_wrench,
    );
    ee_force_map(robot, &mut d);
    data.derivatives = d;
    let d = &data.derivatives;
    // ∂ID/∂f depends on q alone (the EE Jacobians), finite for any finite q
    check_result(
        "inverse_dynamics_derivatives",
        &[d.id_q.as_slice(), d.id_v.as_slice()],
        &inverse_inputs(state, base_acc, qdd, ee_wrench),
    )?;
    Ok(&data.derivatives)
}

/// `∂[α_B; q̈]` with respect to `q`, `ν = [V_B; q̇]`, `τ`, `f_B` and `f`, at the state, torques
/// and loads of [`crate::algorithms::aba`], into `data.derivatives` (`fd_q`, `fd_v`, `fd_tau`,
/// `fd_base_wrench`, `fd_ee_wrench`; the inverse-dynamics derivatives at `a = FD` are left in
/// `id_q`, `id_v`, `id_ee_wrench`). `data.ddq` holds the forward dynamics.
///
/// The first call allocates the O(n²) outputs; later calls reuse them. Derivatives that
/// overflow (inputs too large for floating point) are an error naming the input.
pub fn aba_derivatives<'a>(
    robot: &Robot,
    data: &'a mut Data,
    state: &RigidState,
    tau: &[f64],
    loads: &Loads,
) -> Result<&'a Derivatives> {
    aba_derivatives_into(robot, data, state, tau, loads)?;
    let d = &data.derivatives;
    let base_wrench = loads.base_wrench.to_array();
    // ∂FD/∂τ, ∂FD/∂f_B and ∂FD/∂f are columns of 𝓜⁻¹ and depend on q alone, finite for any
    // finite q: only the blocks that grow with the inputs are scanned
    check_result(
        "forward_dynamics_derivatives",
        &[data.ddq.as_slice(), d.fd_q.as_slice(), d.fd_v.as_slice()],
        &forward_inputs(state, tau, loads, &base_wrench),
    )?;
    Ok(&data.derivatives)
}

/// [`aba_derivatives`] into `data.derivatives`, without looking at whether they overflowed
/// (for callers that check their own, final results).
pub(crate) fn aba_derivatives_into(
    robot: &Robot,
    data: &mut Data,
    state: &RigidState,
    tau: &[f64],
    loads: &Loads,
) -> Result<()> {
    super::aba(robot, data, state, tau, loads)?;
    let n = robot.dof();
    let k = robot.end_effectors().len();
    size_derivatives(data, n, k)?;
    let mut d = std::mem::take(&mut data.derivatives);
    let acc = Motion::from_slice(&data.ddq.as_slice()[..6]);
    let mut qdd = std::mem::take(&mut d.scratch.qdd);
    qdd.copy_from_slice(&data.ddq.as_slice()[6..]);
    id_derivatives(robot, data, &mut d, state, &acc, &qdd, loads.ee_wrench);
    d.scratch.qdd = qdd;
    ee_force_map(robot, &mut d);
    factorisation(robot, data, &mut d.scratch)?;
    // 𝓜⁻¹ on the unit columns; ∂FD/∂f_B, ∂FD/∂τ are its columns
    let m = 6 + n;
    let mut rhs = std::mem::take(&mut d.scratch.rhs);
    rhs.clear();
    rhs.resize(m * m, 0.0);
    for r in 0..m {
        rhs[r * m + r] = 1.0;
    }
    apply_inverse(robot, &mut d.scratch, &mut rhs, m);
    for (r, row) in rhs.chunks_exact(m).enumerate() {
        for (c, value) in row.iter().enumerate() {
            d.scratch.inverse[(r, c)] = *value;
        }
    }
    d.fd_base_wrench.copy_from(&d.scratch.inverse.columns(0, 6));
    d.fd_tau.copy_from(&d.scratch.inverse.columns(6, n));
    // ∂FD/∂x = −𝓜⁻¹ ∂ID/∂x for x = q, ν, f: dense products while they are cheaper, then the
    // factorisation on the columns (O(n) each, so O(n²) in all)
    if n <= DENSE_PRODUCTS_UP_TO {
        let inverse = &d.scratch.inverse;
        minus_product(inverse, &d.id_q, &mut d.fd_q);
        minus_product(inverse, &d.id_v, &mut d.fd_v);
        minus_product(inverse, &d.id_ee_wrench, &mut d.fd_ee_wrench);
    } else {
        let columns = 2 * n + 6 + 6 * k;
        rhs.clear();
        rhs.resize(m * columns, 0.0);
        for (offset, block) in [(0, &d.id_q), (n, &d.id_v), (2 * n + 6, &d.id_ee_wrench)] {
            for (c, column) in block.as_slice().chunks_exact(m).enumerate() {
                for (r, value) in column.iter().enumerate() {
                    rhs[r * columns + offset + c] = -value;
                }
            }
        }
        apply_inverse(robot, &mut d.scratch, &mut rhs, columns);
        for (r, row) in rhs.chunks_exact(columns).enumerate() {
            for k in 0..n {
                d.fd_q[(r, k)] = row[k];
            }
            for j in 0..m {
                d.fd_v[(r, j)] = row[n + j];
            }
            for j in 0..6 * k {
                d.fd_ee_wrench[(r, j)] = row[2 * n + 6 + j];
            }
        }
    }
    d.scratch.rhs = rhs;
    data.derivatives = d;
    Ok(())
}

/// Up to this many joints, `∂FD/∂x = −𝓜⁻¹ ∂ID/∂x` is a dense product with the formed `𝓜⁻¹`
/// (O(n³), small constant); above, the factorisation runs on the columns (O(n²)). Measured
/// crossover (BENCHMARKS.md, "Derivatives").
pub(crate) const DENSE_PRODUCTS_UP_TO: usize = 28;

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

/// Body `i`'s own terms, in base-frame components, from `v_i`, `a_i` and its inertia there:
/// `I_i`, `h_i = I_i v_i`, `f_i = I_i a_i + v_i ×* h_i`, and `T_i` of `B_i` (module docs).
#[inline(always)]
fn body_terms(s: &mut Scratch, i: usize, inertia: &Inertia) {
    let body = Composite::of(inertia);
    let (v, a) = (s.v[i], s.a[i]);
    let h = body.apply(&v);
    s.force[i] = body.apply(&a) + v.cross_force(&h);
    s.momentum[i] = h;
    let p = body.rotational * skew(&v.angular);
    let outer = v.linear * body.first_moment.transpose();
    s.t[i] = -(p + p.transpose()) - (outer + outer.transpose())
        + Mat3::from_diagonal_element(2.0 * body.first_moment.dot(&v.linear));
    s.inertia[i] = body;
}

/// The inverse-dynamics derivatives in base-frame components (module docs) into `id_q` and
/// `id_v`, from the joint transforms at `q` in `data.x` (left there by the forward dynamics, or
/// computed by the caller). (Its AVX2 build was about 10 % faster, but valgrind 3.19 cannot
/// decode one of its instructions, so it stays portable.)
fn id_derivatives(
    robot: &Robot,
    data: &mut Data,
    d: &mut Derivatives,
    state: &RigidState,
    base_acc: &Motion,
    qdd: &[f64],
    ee_wrench: &[f64],
) {
    let n = robot.dof();
    let parents = robot.parents();
    let inertias = robot.frame_inertias();
    let s = &mut d.scratch;
    let v0 = Motion::from_slice(state.base_twist);
    s.to_body[0] = Transform::identity();
    s.v[0] = v0;
    // a_B = α_B − [0; ω_B × v_B]
    s.a[0] = *base_acc - Motion::new(Vec3::zeros(), v0.angular.cross(&v0.linear));
    body_terms(s, 0, &inertias[0]);
    for i in 1..=n {
        let lambda = parents[i];
        let x = data.x[i];
        let to_body = x.compose(&s.to_body[lambda]);
        let axis = to_body.apply_motion_inverse(&Motion::new(Vec3::z(), Vec3::zeros()));
        let rate = axis * state.qd[i - 1];
        let v = s.v[lambda] + rate;
        s.a[i] = s.a[lambda] + axis * qdd[i - 1] + v.cross_motion(&rate);
        s.v[i] = v;
        s.axis[i] = axis;
        s.to_body[i] = to_body;
        body_terms(s, i, &inertias[i].transformed_to_parent(&to_body));
    }
    for (e, w) in ee_wrench.chunks_exact(6).enumerate() {
        let body = robot.end_effectors()[e].body;
        let at_body = robot
            .frame_ee_transform(e)
            .apply_force_transpose(&Force::from_slice(w));
        s.force[body] += s.to_body[body].apply_force_transpose(&at_body);
    }
    for i in (1..=n).rev() {
        let lambda = parents[i];
        let (inertia, momentum, force, t) = (s.inertia[i], s.momentum[i], s.force[i], s.t[i]);
        s.inertia[lambda].add(&inertia);
        s.momentum[lambda] += momentum;
        s.force[lambda] += force;
        s.t[lambda] += t;
    }
    for k in 1..=n {
        let (axis, v, inertia, momentum, t) =
            (s.axis[k], s.v[k], &s.inertia[k], s.momentum[k], &s.t[k]);
        let u = v.cross_motion(&axis);
        let c = s.a[k].cross_motion(&axis) + v.cross_motion(&u);
        s.alpha[k] = inertia.apply(&axis);
        s.beta[k] = t * axis.angular
            + 2.0 * momentum.linear.cross(&axis.linear)
            + momentum.angular.cross(&axis.angular);
        s.angle_force[k] =
            axis.cross_force(&s.force[k]) + inertia.apply(&c) + coriolis(t, &momentum, &u);
        s.rate_force[k] = inertia.apply(&u) * 2.0 + coriolis(t, &momentum, &axis);
        s.u[k] = u;
        s.c[k] = c;
    }
    // joint columns: the subtree rows (i ⪰ k), the ancestors' rows and the base rows
    d.id_q.as_mut_slice().fill(0.0);
    d.id_v.as_mut_slice().fill(0.0);
    s.stamp.fill(0);
    for k in 1..=n {
        let (u, c, axis) = (s.u[k], s.c[k], s.axis[k]);
        for i in k..=n {
            let lambda = parents[i];
            if i != k && (lambda < k || s.stamp[lambda] != k) {
                continue;
            }
            s.stamp[i] = k;
            let (alpha, beta) = (&s.alpha[i], &s.beta[i]);
            d.id_q[(5 + i, k - 1)] = c.dot(alpha) + beta.dot(&u.angular);
            d.id_v[(5 + i, 5 + k)] = 2.0 * u.dot(alpha) + beta.dot(&axis.angular);
        }
        let (angle, rate) = (s.angle_force[k], s.rate_force[k]);
        let mut p = parents[k];
        while p >= 1 {
            d.id_q[(5 + p, k - 1)] = s.axis[p].dot(&angle);
            d.id_v[(5 + p, 5 + k)] = s.axis[p].dot(&rate);
            p = parents[p];
        }
        for (r, (a, b)) in angle
            .to_array()
            .into_iter()
            .zip(rate.to_array())
            .enumerate()
        {
            d.id_q[(r, k - 1)] = a;
            d.id_v[(r, 5 + k)] = b;
        }
    }
    // base-twist columns: u = δV, c = [ω_B × δω; 2 v_B × δω]
    for j in 0..6 {
        let mut unit = [0.0; 6];
        unit[j] = 1.0;
        let u = Motion::from_slice(&unit);
        let c = base_acceleration_change(&v0, &u);
        for i in 1..=n {
            d.id_v[(5 + i, j)] = c.dot(&s.alpha[i]) + s.beta[i].dot(&u.angular);
        }
        let base = s.inertia[0].apply(&c) + coriolis(&s.t[0], &s.momentum[0], &u);
        for (r, value) in base.to_array().into_iter().enumerate() {
            d.id_v[(r, j)] = value;
        }
    }
}

/// `out = −a b` for a square `a`, column by column.
fn minus_product(a: &DMatrix<f64>, b: &DMatrix<f64>, out: &mut DMatrix<f64>) {
    let m = a.nrows();
    for (b_column, column) in b
        .as_slice()
        .chunks_exact(m)
        .zip(out.as_mut_slice().chunks_exact_mut(m))
    {
        crate::linalg::scaled_product(-1.0, a.as_slice(), m, b_column, column);
    }
}

/// Readies the forward dynamics' articulated-body factorisation in `data` (`U_i`, `D_i`,
/// `I^A_B`; valid at any velocity) for [`apply_inverse`]: `U_i` in base-frame components, `1/D_i`
/// and `(I^A_B)⁻¹`.
fn factorisation(robot: &Robot, data: &Data, s: &mut Scratch) -> Result<()> {
    for i in 1..=robot.dof() {
        s.u_base[i] = s.to_body[i].apply_force_transpose(&data.u_col[i]);
        s.inverse_d[i] = 1.0 / data.d[i];
    }
    // the forward dynamics' own base solve, so that it fails exactly when that one did (and it
    // has just succeeded)
    s.base_inverse = data.ia[0]
        .inverse()
        .ok_or_else(|| crate::Error::InvalidArgument {
            what: "articulated base inertia".into(),
            message: "not positive definite (the model's mass matrix is singular here)".into(),
        })?;
    Ok(())
}

/// `R ← 𝓜⁻¹ R` for `columns` right-hand sides at once, `R` stored one generalized coordinate
/// per row (`r[row * columns + j]`), by the factorisation [`factorisation`] readied. In
/// base-frame components the passes need no transforms: backwards `u_i = r_i − S_iᵀ p_i`,
/// `p_λ += p_i + U_i u_i/D_i`; the base solves `I^A_B a_B = r_B − p_B`; forwards
/// `q̈_i = (u_i − U_iᵀ a_λ)/D_i`, `a_i = a_λ + S_i q̈_i`. O(n) per column; each pass runs body by
/// body over all the columns, which are independent. Runs as AVX2 code where the processor has
/// it, with the same bits (`crate::simd`).
fn apply_inverse(robot: &Robot, s: &mut Scratch, r: &mut [f64], columns: usize) {
    crate::simd::dispatch!(apply_inverse_kernel(robot: &Robot, s: &mut Scratch, r: &mut [f64], columns: usize))
}

#[inline(always)]
fn apply_inverse_kernel(robot: &Robot, s: &mut Scratch, r: &mut [f64], columns: usize) {
    let n = robot.dof();
    debug_assert_eq!(r.len(), (6 + n) * columns);
    let parents = robot.parents();
    s.column_p.clear();
    s.column_p.resize((n + 1) * columns, Force::zero());
    s.column_acc.resize((n + 1) * columns, Motion::zero());
    for i in (1..=n).rev() {
        let (lambda, axis, u_base, inverse_d) =
            (parents[i], s.axis[i], s.u_base[i], s.inverse_d[i]);
        let row = &mut r[(5 + i) * columns..(6 + i) * columns];
        for (j, value) in row.iter_mut().enumerate() {
            let p = s.column_p[i * columns + j];
            let u = *value - axis.dot(&p);
            *value = u;
            s.column_p[lambda * columns + j] += p + u_base * (u * inverse_d);
        }
    }
    for j in 0..columns {
        let rhs: [f64; 6] = std::array::from_fn(|k| r[k * columns + j]);
        let base = s.base_inverse * (Force::from_slice(&rhs) - s.column_p[j]).to_vector();
        for (k, value) in base.iter().enumerate() {
            r[k * columns + j] = *value;
        }
        s.column_acc[j] = Motion::from_vector(&base);
    }
    for i in 1..=n {
        let (lambda, axis, u_base, inverse_d) =
            (parents[i], s.axis[i], s.u_base[i], s.inverse_d[i]);
        let row = &mut r[(5 + i) * columns..(6 + i) * columns];
        for (j, value) in row.iter_mut().enumerate() {
            let parent_acc = s.column_acc[lambda * columns + j];
            let qdd = (*value - parent_acc.dot(&u_base)) * inverse_d;
            s.column_acc[i * columns + j] = parent_acc + axis * qdd;
            *value = qdd;
        }
    }
}

/// After [`aba_derivatives`] at a state (same `data`): the forward dynamics' directional
/// derivatives `∂FD/∂q δq + ∂FD/∂ν δν + ∂FD/∂τ δτ` for `columns` directions at once, without the
/// dense matrices: the inverse dynamics' directional derivative (O(n) per direction, from the
/// per-body terms; module docs) then `𝓜⁻¹` by the factorisation (O(n)). All arrays hold one
/// coordinate per row and one direction per column: `dq` n rows, `dnu` 6+n, `dtau` n, `out` 6+n.
pub(crate) fn fd_directional(
    robot: &Robot,
    data: &mut Data,
    dq: &[f64],
    dnu: &[f64],
    dtau: &[f64],
    columns: usize,
    out: &mut [f64],
) {
    let n = robot.dof();
    debug_assert_eq!(out.len(), (6 + n) * columns);
    let s = &mut data.derivatives.scratch;
    // a few dozen directions at a time, so the per-body buffers stay in cache
    let mut tile = std::mem::take(&mut s.tile);
    for start in (0..columns).step_by(DIRECTIONS_PER_TILE) {
        let width = DIRECTIONS_PER_TILE.min(columns - start);
        let gather = |from: &[f64], rows: usize, into: &mut Vec<f64>| {
            into.clear();
            for r in 0..rows {
                into.extend_from_slice(&from[r * columns + start..r * columns + start + width]);
            }
        };
        gather(dq, n, &mut tile.dq);
        gather(dnu, 6 + n, &mut tile.dnu);
        tile.out.clear();
        tile.out.resize((6 + n) * width, 0.0);
        id_directional(robot, s, &tile.dq, &tile.dnu, width, &mut tile.out);
        gather(dtau, n, &mut tile.dq);
        for (o, t) in tile.out[6 * width..].iter_mut().zip(&tile.dq) {
            *o = t - *o;
        }
        tile.out[..6 * width].iter_mut().for_each(|o| *o = -*o);
        apply_inverse(robot, s, &mut tile.out, width);
        for r in 0..6 + n {
            out[r * columns + start..r * columns + start + width]
                .copy_from_slice(&tile.out[r * width..(r + 1) * width]);
        }
    }
    s.tile = tile;
}

/// Directions handled together by [`fd_directional`].
const DIRECTIONS_PER_TILE: usize = 32;

/// [`fd_directional`]'s gathered directions and results for one tile.
#[derive(Debug, Clone, Default)]
struct Tile {
    dq: Vec<f64>,
    dnu: Vec<f64>,
    out: Vec<f64>,
}

/// `∂ID/∂q δq + ∂ID/∂ν δν` for `columns` directions (layout of [`fd_directional`]). Row `i` is
/// `α_i · C_i + β_i · U_i + S_i · G_i` with the path sums `C_i = c(δV) + Σ_{k ⪯ i} (c_k δq_k +
/// 2 u_k δq̇_k)`, `U_i = δV + Σ_{k ⪯ i} (u_k δq_k + S_k δq̇_k)` and the strict-subtree sum
/// `G_i = Σ_{k ≻ i} (δF^angle_k δq_k + δF^rate_k δq̇_k)`; the base row is the whole sum `G_B`
/// plus the base twist's own term.
fn id_directional(
    robot: &Robot,
    s: &mut Scratch,
    dq: &[f64],
    dnu: &[f64],
    columns: usize,
    out: &mut [f64],
) {
    let n = robot.dof();
    debug_assert_eq!(out.len(), (6 + n) * columns);
    let parents = robot.parents();
    let size = (n + 1) * columns;
    for buffer in [&mut s.path_c, &mut s.path_u] {
        buffer.resize(size, Motion::zero());
    }
    s.subtree.clear();
    s.subtree.resize(size, Force::zero());
    let v0 = s.v[0];
    for j in 0..columns {
        let twist: [f64; 6] = std::array::from_fn(|k| dnu[k * columns + j]);
        let dv = Motion::from_slice(&twist);
        s.path_c[j] = base_acceleration_change(&v0, &dv);
        s.path_u[j] = dv;
    }
    for i in 1..=n {
        let (lambda, c, u, axis) = (parents[i], s.c[i], s.u[i], s.axis[i]);
        let (angles, rates) = (
            &dq[(i - 1) * columns..i * columns],
            &dnu[(5 + i) * columns..(6 + i) * columns],
        );
        for (j, (&angle, &rate)) in angles.iter().zip(rates).enumerate() {
            s.path_c[i * columns + j] =
                s.path_c[lambda * columns + j] + c * angle + u * (2.0 * rate);
            s.path_u[i * columns + j] = s.path_u[lambda * columns + j] + u * angle + axis * rate;
        }
    }
    for i in (1..=n).rev() {
        let (lambda, alpha, beta, axis) = (parents[i], s.alpha[i], s.beta[i], s.axis[i]);
        let (angle_force, rate_force) = (s.angle_force[i], s.rate_force[i]);
        let (angles, rates) = (
            &dq[(i - 1) * columns..i * columns],
            &dnu[(5 + i) * columns..(6 + i) * columns],
        );
        let row = &mut out[(5 + i) * columns..(6 + i) * columns];
        for (j, ((value, &angle), &rate)) in row.iter_mut().zip(angles).zip(rates).enumerate() {
            let at = i * columns + j;
            let below = s.subtree[at];
            *value = s.path_c[at].dot(&alpha) + beta.dot(&s.path_u[at].angular) + axis.dot(&below);
            s.subtree[lambda * columns + j] += below + angle_force * angle + rate_force * rate;
        }
    }
    let (inertia, t, momentum) = (s.inertia[0], s.t[0], s.momentum[0]);
    for j in 0..columns {
        let base =
            s.subtree[j] + inertia.apply(&s.path_c[j]) + coriolis(&t, &momentum, &s.path_u[j]);
        for (k, value) in base.to_array().into_iter().enumerate() {
            out[k * columns + j] = value;
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

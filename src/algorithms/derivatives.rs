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
//! (which leaves every `τ_i` of the subtree unchanged and turns `F_k` into `S_k ×* F_k`); what is
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
//! `∂FD/∂f_B = 𝓜⁻¹ [𝟙; 0]` and `∂FD/∂f = −𝓜⁻¹ [Φ_{n+1,B}ᵀ; Jᵀ]`. `𝓜⁻¹` comes from the
//! articulated-body factorisation that the forward dynamics has just built (`U`, `D`, `I^A_B`,
//! valid at any velocity), applied to the 6+n unit columns (a backward and a forward pass, O(n)
//! per column), and the products are dense (6+n)-row matrix products: no mass matrix is formed.

// Loops run over body indices `i`, the equations' indices; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

use super::data::{check_data, Data};
use crate::args::{check_vector, Loads, RigidState};
use crate::error::Result;
use crate::model::Robot;
use crate::spatial::{skew, Force, Inertia, Mat3, Motion, Transform, Vec3};
use nalgebra::DMatrix;

/// The derivatives of [`rnea_derivatives`] and [`aba_derivatives`], and their scratch memory.
/// Rows follow the generalized coordinates `[base (6); joints (n)]`; `ν = [V_B; q̇]`.
#[derive(Debug, Clone, Default)]
pub struct Derivatives {
    /// `∂[f_B; τ]/∂q`, (6+n)×n.
    pub id_q: DMatrix<f64>,
    /// `∂[f_B; τ]/∂ν`, (6+n)×(6+n).
    pub id_v: DMatrix<f64>,
    /// `∂[f_B; τ]/∂f = [Φ_{n+1,B}ᵀ; Jᵀ]`, (6+n)×6.
    pub id_ee_wrench: DMatrix<f64>,
    /// `∂[α_B; q̈]/∂q`, (6+n)×n.
    pub fd_q: DMatrix<f64>,
    /// `∂[α_B; q̈]/∂ν`, (6+n)×(6+n).
    pub fd_v: DMatrix<f64>,
    /// `∂[α_B; q̈]/∂τ = 𝓜⁻¹[0; 𝟙]`, (6+n)×n.
    pub fd_tau: DMatrix<f64>,
    /// `∂[α_B; q̈]/∂f_B = 𝓜⁻¹[𝟙; 0]`, (6+n)×6.
    pub fd_base_wrench: DMatrix<f64>,
    /// `∂[α_B; q̈]/∂f`, (6+n)×6.
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
    column_u: Vec<f64>,
    column_acc: Vec<Motion>,
    qdd: Vec<f64>,
}

impl Derivatives {
    /// Buffers for `n` joints.
    fn new(n: usize) -> Self {
        let (rows, bodies) = (6 + n, n + 1);
        Self {
            id_q: DMatrix::zeros(rows, n),
            id_v: DMatrix::zeros(rows, rows),
            id_ee_wrench: DMatrix::zeros(rows, 6),
            fd_q: DMatrix::zeros(rows, n),
            fd_v: DMatrix::zeros(rows, rows),
            fd_tau: DMatrix::zeros(rows, n),
            fd_base_wrench: DMatrix::zeros(rows, 6),
            fd_ee_wrench: DMatrix::zeros(rows, 6),
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
                inverse: DMatrix::zeros(rows, rows),
                u_base: vec![Force::zero(); bodies],
                inverse_d: vec![0.0; bodies],
                column_u: vec![0.0; bodies * rows],
                column_acc: vec![Motion::zero(); bodies * rows],
                qdd: vec![0.0; n],
            },
        }
    }
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
/// The first call allocates the O(n²) outputs; later calls reuse them.
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
    check_vector("ee_wrench", ee_wrench, 6)?;
    let mut d = take_derivatives(data, robot.dof());
    id_derivatives(
        robot,
        data,
        &mut d,
        state,
        &Motion::from_slice(base_acc),
        qdd,
        &Force::from_slice(ee_wrench),
    );
    ee_force_map(robot, data, &mut d, state.q)?;
    data.derivatives = d;
    Ok(&data.derivatives)
}

/// `∂[α_B; q̈]` with respect to `q`, `ν = [V_B; q̇]`, `τ`, `f_B` and `f`, at the state, torques
/// and loads of [`crate::algorithms::aba`], into `data.derivatives` (`fd_q`, `fd_v`, `fd_tau`,
/// `fd_base_wrench`, `fd_ee_wrench`; the inverse-dynamics derivatives at `a = FD` are left in
/// `id_q`, `id_v`, `id_ee_wrench`). `data.ddq` holds the forward dynamics.
///
/// The first call allocates the O(n²) outputs; later calls reuse them.
pub fn aba_derivatives<'a>(
    robot: &Robot,
    data: &'a mut Data,
    state: &RigidState,
    tau: &[f64],
    loads: &Loads,
) -> Result<&'a Derivatives> {
    super::aba(robot, data, state, tau, loads)?;
    let n = robot.dof();
    let mut d = take_derivatives(data, n);
    let acc = Motion::from_slice(&data.ddq.as_slice()[..6]);
    let mut qdd = std::mem::take(&mut d.scratch.qdd);
    qdd.copy_from_slice(&data.ddq.as_slice()[6..]);
    id_derivatives(robot, data, &mut d, state, &acc, &qdd, &loads.ee_wrench);
    d.scratch.qdd = qdd;
    ee_force_map(robot, data, &mut d, state.q)?;
    inverse_mass_matrix(robot, data, &mut d.scratch)?;
    // ∂FD/∂f_B, ∂FD/∂τ are columns of 𝓜⁻¹; ∂FD/∂x = −𝓜⁻¹ ∂ID/∂x for the others
    let inverse = &d.scratch.inverse;
    d.fd_base_wrench.copy_from(&inverse.columns(0, 6));
    d.fd_tau.copy_from(&inverse.columns(6, n));
    minus_product(inverse, &d.id_q, &mut d.fd_q);
    minus_product(inverse, &d.id_v, &mut d.fd_v);
    minus_product(inverse, &d.id_ee_wrench, &mut d.fd_ee_wrench);
    data.derivatives = d;
    Ok(&data.derivatives)
}

/// The derivative buffers, sized for `n` joints (allocated on first use), moved out of `data`
/// for the duration of a call.
fn take_derivatives(data: &mut Data, n: usize) -> Derivatives {
    if data.derivatives.id_q.nrows() != 6 + n {
        data.derivatives = Derivatives::new(n);
    }
    std::mem::take(&mut data.derivatives)
}

/// `∂ID/∂f = [Φ_{n+1,B}ᵀ; Jᵀ]`.
fn ee_force_map(robot: &Robot, data: &mut Data, d: &mut Derivatives, q: &[f64]) -> Result<()> {
    super::ee_jacobian(robot, data, q)?;
    d.id_ee_wrench
        .view_mut((0, 0), (6, 6))
        .tr_copy_from(&data.ee_base);
    d.id_ee_wrench
        .view_mut((6, 0), (robot.dof(), 6))
        .tr_copy_from(&data.jacobian);
    Ok(())
}

/// Body `i`'s own terms, in base-frame components, from `v_i`, `a_i` and its inertia there:
/// `I_i`, `h_i = I_i v_i`, `f_i = I_i a_i + v_i ×* h_i`, and `T_i` of `B_i` (module docs).
#[inline]
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
/// `id_v`; also refreshes `data.x` (the joint transforms at `q`).
fn id_derivatives(
    robot: &Robot,
    data: &mut Data,
    d: &mut Derivatives,
    state: &RigidState,
    base_acc: &Motion,
    qdd: &[f64],
    ee_wrench: &Force,
) {
    let n = robot.dof();
    let parents = robot.parents();
    let inertias = robot.inertias();
    let s = &mut d.scratch;
    let v0 = Motion::from_slice(state.base_twist);
    s.to_body[0] = Transform::identity();
    s.v[0] = v0;
    // a_B = α_B − [0; ω_B × v_B]
    s.a[0] = *base_acc - Motion::new(Vec3::zeros(), v0.angular.cross(&v0.linear));
    body_terms(s, 0, &inertias[0]);
    for i in 1..=n {
        let (joint, lambda) = (&robot.joints()[i - 1], parents[i]);
        let x = joint.transform(state.q[i - 1]);
        data.x[i] = x;
        let to_body = x.compose(&s.to_body[lambda]);
        let axis = to_body.apply_motion_inverse(&Motion::new(joint.axis, Vec3::zeros()));
        let rate = axis * state.qd[i - 1];
        let v = s.v[lambda] + rate;
        s.a[i] = s.a[lambda] + axis * qdd[i - 1] + v.cross_motion(&rate);
        s.v[i] = v;
        s.axis[i] = axis;
        s.to_body[i] = to_body;
        body_terms(s, i, &inertias[i].transformed_to_parent(&to_body));
    }
    let ee = robot.ee_body();
    let at_body = robot.ee_transform().apply_force_transpose(ee_wrench);
    s.force[ee] += s.to_body[ee].apply_force_transpose(&at_body);
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
        let c = Motion::new(
            v0.angular.cross(&u.angular),
            2.0 * v0.linear.cross(&u.angular),
        );
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

/// `𝓜⁻¹` into `s.inverse`, from the articulated-body factorisation the forward dynamics left in
/// `data` (`U_i`, `D_i`, `I^A_B`; valid at any velocity), applied to the 6+n unit columns. In
/// base-frame components (`U_i` moved there once, `S_i` from the derivative pass) the passes need
/// no transforms: backwards `u_i = r_i − S_iᵀ p_i`, `p_λ += p_i + U_i u_i/D_i`; the base solves
/// `I^A_B a_B = r_B − p_B`; forwards `q̈_i = (u_i − U_iᵀ a_λ)/D_i`, `a_i = a_λ + S_i q̈_i`. The
/// unit column of joint `k` has `p = 0` off the path from `k` to the base, so its backward pass
/// walks that path only: O(n) per column, O(n²) in all.
fn inverse_mass_matrix(robot: &Robot, data: &Data, s: &mut Scratch) -> Result<()> {
    let n = robot.dof();
    let parents = robot.parents();
    for i in 1..=n {
        s.u_base[i] = s.to_body[i].apply_force_transpose(&data.u_col[i]);
        s.inverse_d[i] = 1.0 / data.d[i];
    }
    let base = data.ia[0]
        .matrix()
        .cholesky()
        .ok_or_else(|| crate::Error::InvalidArgument {
            what: "articulated base inertia".into(),
            message: "not positive definite (the model's mass matrix is singular here)".into(),
        })?
        .inverse();
    let m = 6 + n;
    // backwards, each joint column along its path; u_i of every column, body-major
    s.column_u.clear();
    s.column_u.resize((n + 1) * m, 0.0);
    s.column_acc.clear();
    s.column_acc.resize((n + 1) * m, Motion::zero());
    for column in 0..m {
        let mut p = Force::zero();
        if column >= 6 {
            let k = column - 5;
            s.column_u[k * m + column] = 1.0;
            p = s.u_base[k] * s.inverse_d[k];
            let mut i = parents[k];
            while i >= 1 {
                let u = -s.axis[i].dot(&p);
                s.column_u[i * m + column] = u;
                p += s.u_base[i] * (u * s.inverse_d[i]);
                i = parents[i];
            }
        }
        let mut rhs = -p.to_vector();
        if column < 6 {
            rhs[column] += 1.0;
        }
        let base_acc = Motion::from_vector(&(base * rhs));
        s.column_acc[column] = base_acc;
        for (r, value) in base_acc.to_array().into_iter().enumerate() {
            s.inverse[(r, column)] = value;
        }
    }
    // forwards, body by body over all columns (independent chains for the processor)
    for i in 1..=n {
        let lambda = parents[i];
        let (u_base, inverse_d, axis) = (s.u_base[i], s.inverse_d[i], s.axis[i]);
        for column in 0..m {
            let parent_acc = s.column_acc[lambda * m + column];
            let qdd = (s.column_u[i * m + column] - parent_acc.dot(&u_base)) * inverse_d;
            s.column_acc[i * m + column] = parent_acc + axis * qdd;
            s.inverse[(5 + i, column)] = qdd;
        }
    }
    Ok(())
}

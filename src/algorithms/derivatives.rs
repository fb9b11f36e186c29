//! Analytical derivatives of inverse and forward dynamics (RNEA and ABA), O(n²), in the paper's
//! conventions: `[ω; v]` vectors, the base's classical acceleration `α_B` as an input of the
//! inverse dynamics and an output of the forward dynamics.
//!
//! **Inverse dynamics.** The recursion is differentiated in forward mode, one input coordinate
//! at a time. It runs in Featherstone's spatial-acceleration form, which gives the same body
//! forces as (A.6)–(A.10): `v_i = X_i v_λ + S_i q̇_i`, `a_i = X_i a_λ + S_i q̈_i + v_i ×ₘ S_i q̇_i`,
//! `f_i = I_i a_i + v_i ×* I_i v_i + Σ_children X_cᵀ f_c`, with the base's spatial acceleration
//! `a_B = α_B − [0; ω_B × v_B]`. A joint angle moves its own transform,
//! `∂X_k/∂q_k = −(S_k ×ₘ) X_k`, so a perturbation of `q_k`, `q̇_k` or `V_B` starts at its body
//! and travels out through the subtree (velocities, accelerations) and back to the base (forces):
//! O(n) per coordinate.
//!
//! Holding the classical `α_B` fixed, a change of the base twist changes `a_B` by
//! `−[0; δω × v + ω × δv]`; that is where these derivatives differ from Pinocchio's, whose base
//! acceleration is spatial.
//!
//! **Forward dynamics.** `ID(q, ν, FD(q, ν, u)) = u` for every input, so
//! `∂FD/∂(q, ν) = −𝓜⁻¹ ∂ID/∂(q, ν)` at `a = FD`, `∂FD/∂τ = 𝓜⁻¹ [0; 𝟙]`,
//! `∂FD/∂f_B = 𝓜⁻¹ [𝟙; 0]` and `∂FD/∂f = −𝓜⁻¹ [Φ_{n+1,B}ᵀ; Jᵀ]`. `𝓜⁻¹` is applied to all
//! these columns at once by the articulated-body factorisation that the forward dynamics has
//! just built (`U`, `D`, `I^A_B`, valid at any velocity): a backward and a forward pass, O(n) per
//! column, so O(n²) in all and no dense mass matrix.

// Loops run over body indices `i`, the equations' indices; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

use super::data::{check_data, Data};
use super::kinematics::body_velocity;
use crate::args::{check_vector, Loads, RigidState};
use crate::error::Result;
use crate::model::Robot;
use crate::spatial::{Force, Motion, Vec3};
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
    // scratch: the nominal spatial accelerations and body forces, one direction's
    // perturbations, which bodies it moves, and the columns of the 𝓜⁻¹ solves
    a: Vec<Motion>,
    f: Vec<Force>,
    dv: Vec<Motion>,
    da: Vec<Motion>,
    df: Vec<Force>,
    moved: Vec<bool>,
    solve_p: Vec<Force>,
    solve_acc: Vec<Motion>,
    rhs: Vec<f64>,
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
            a: vec![Motion::zero(); bodies],
            f: vec![Force::zero(); bodies],
            dv: vec![Motion::zero(); bodies],
            da: vec![Motion::zero(); bodies],
            df: vec![Force::zero(); bodies],
            moved: vec![false; bodies],
            solve_p: vec![Force::zero(); bodies * (3 * n + 18)],
            solve_acc: vec![Motion::zero(); bodies * (3 * n + 18)],
            rhs: vec![0.0; rows * (3 * n + 18)],
            qdd: vec![0.0; n],
        }
    }
}

/// Which input coordinate a forward-mode pass perturbs.
#[derive(Clone, Copy)]
enum Direction {
    /// `q_k` of joint (body) `k ≥ 1`.
    Angle(usize),
    /// `q̇_k` of joint (body) `k ≥ 1`.
    Rate(usize),
    /// Component `j` of the base twist `[ω_B; v_B]`.
    Base(usize),
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
    let mut qdd = std::mem::take(&mut d.qdd);
    qdd.copy_from_slice(&data.ddq.as_slice()[6..]);
    id_derivatives(robot, data, &mut d, state, &acc, &qdd, &loads.ee_wrench);
    d.qdd = qdd;
    ee_force_map(robot, data, &mut d, state.q)?;
    // ∂FD/∂x = −𝓜⁻¹ ∂ID/∂x, and 𝓜⁻¹ on the unit inputs, through the articulated-body
    // factorisation, all columns at once: [−∂ID/∂q | −∂ID/∂ν | [0; 𝟙] | [𝟙; 0] | −∂ID/∂f].
    let m = 3 * n + 18;
    d.rhs.resize((6 + n) * m, 0.0);
    for r in 0..6 + n {
        let row = &mut d.rhs[r * m..(r + 1) * m];
        for k in 0..n {
            row[k] = -d.id_q[(r, k)];
            row[2 * n + 6 + k] = f64::from(u8::from(r == 6 + k));
        }
        for j in 0..6 + n {
            row[n + j] = -d.id_v[(r, j)];
        }
        for j in 0..6 {
            row[3 * n + 6 + j] = f64::from(u8::from(r == j));
            row[3 * n + 12 + j] = -d.id_ee_wrench[(r, j)];
        }
    }
    solve_columns(robot, data, &mut d, m)?;
    for r in 0..6 + n {
        let row = &d.rhs[r * m..(r + 1) * m];
        for k in 0..n {
            d.fd_q[(r, k)] = row[k];
            d.fd_tau[(r, k)] = row[2 * n + 6 + k];
        }
        for j in 0..6 + n {
            d.fd_v[(r, j)] = row[n + j];
        }
        for j in 0..6 {
            d.fd_base_wrench[(r, j)] = row[3 * n + 6 + j];
            d.fd_ee_wrench[(r, j)] = row[3 * n + 12 + j];
        }
    }
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

/// The nominal RNEA in spatial-acceleration form, then one forward-mode pass per input
/// coordinate into `id_q` and `id_v`.
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
    data.v[0] = Motion::from_slice(state.base_twist);
    data.c[0] = Motion::zero();
    let v0 = data.v[0];
    // a_B = α_B − [0; ω_B × v_B]
    d.a[0] = *base_acc - Motion::new(Vec3::zeros(), v0.angular.cross(&v0.linear));
    for i in 1..=n {
        body_velocity(robot, data, i, state);
        let s = joint_motion(robot, i);
        let v = data.v[i];
        d.a[i] = data.x[i].apply_motion(&d.a[parents[i]])
            + s * qdd[i - 1]
            + v.cross_motion(&(s * state.qd[i - 1]));
    }
    for i in 0..=n {
        let (v, inertia) = (data.v[i], &inertias[i]);
        d.f[i] = inertia.apply(&d.a[i]) + v.cross_force(&inertia.apply(&v));
    }
    d.f[robot.ee_body()] += robot.ee_transform().apply_force_transpose(ee_wrench);
    for i in (1..=n).rev() {
        let moved = data.x[i].apply_force_transpose(&d.f[i]);
        d.f[parents[i]] += moved;
    }
    for k in 1..=n {
        directional(robot, data, d, state, Direction::Angle(k));
        write_column(robot, d, |d, r, value| d.id_q[(r, k - 1)] = value);
        directional(robot, data, d, state, Direction::Rate(k));
        write_column(robot, d, |d, r, value| d.id_v[(r, 5 + k)] = value);
    }
    for j in 0..6 {
        directional(robot, data, d, state, Direction::Base(j));
        write_column(robot, d, |d, r, value| d.id_v[(r, j)] = value);
    }
}

/// `S_i = H_i = [h_i; 0]`.
#[inline]
fn joint_motion(robot: &Robot, i: usize) -> Motion {
    Motion::new(robot.joints()[i - 1].axis, Vec3::zeros())
}

/// One forward-mode pass: `dv`, `da` over the bodies the coordinate moves, then `df` back to
/// the base.
fn directional(
    robot: &Robot,
    data: &Data,
    d: &mut Derivatives,
    state: &RigidState,
    direction: Direction,
) {
    let n = robot.dof();
    let parents = robot.parents();
    let inertias = robot.inertias();
    let start = match direction {
        Direction::Angle(k) | Direction::Rate(k) => k,
        Direction::Base(_) => 0,
    };
    d.moved.iter_mut().for_each(|m| *m = false);
    d.df.iter_mut().for_each(|f| *f = Force::zero());
    if let Direction::Base(j) = direction {
        let mut unit = [0.0; 6];
        unit[j] = 1.0;
        let dv = Motion::from_slice(&unit);
        let v = data.v[0];
        d.dv[0] = dv;
        // a_B = α_B − [0; ω × v] with α_B held: δa_B = −[0; δω × v + ω × δv]
        d.da[0] = Motion::new(
            Vec3::zeros(),
            -(dv.angular.cross(&v.linear) + v.angular.cross(&dv.linear)),
        );
        d.moved[0] = true;
    }
    for i in start.max(1)..=n {
        let parent = parents[i];
        let from_parent = d.moved[parent];
        if !(from_parent || i == start) {
            continue;
        }
        d.moved[i] = true;
        let x = &data.x[i];
        let s = joint_motion(robot, i);
        let rate = s * state.qd[i - 1];
        let (mut dv, mut da) = if from_parent {
            (x.apply_motion(&d.dv[parent]), x.apply_motion(&d.da[parent]))
        } else {
            (Motion::zero(), Motion::zero())
        };
        if i == start {
            match direction {
                // ∂X_k/∂q_k = −(S_k ×ₘ) X_k: δv_k = −S_k × (X_k v_λ) = v_k × S_k, and
                // δa_k gets −S_k × (X_k a_λ)
                Direction::Angle(_) => {
                    dv += data.v[i].cross_motion(&s);
                    da -= s.cross_motion(&x.apply_motion(&d.a[parent]));
                }
                // δv_k = S_k, and the product v_k × S_k q̇_k gives v_k × S_k
                Direction::Rate(_) => {
                    dv += s;
                    da += data.v[i].cross_motion(&s);
                }
                Direction::Base(_) => {}
            }
        }
        da += dv.cross_motion(&rate);
        d.dv[i] = dv;
        d.da[i] = da;
    }
    for i in 0..=n {
        if d.moved[i] {
            let (v, dv, inertia) = (data.v[i], d.dv[i], &inertias[i]);
            d.df[i] = inertia.apply(&d.da[i])
                + dv.cross_force(&inertia.apply(&v))
                + v.cross_force(&inertia.apply(&dv));
        }
    }
    for i in (1..=n).rev() {
        let x = &data.x[i];
        let mut moved = x.apply_force_transpose(&d.df[i]);
        if let Direction::Angle(k) = direction {
            if i == k {
                // (∂X_kᵀ/∂q_k) f_k = X_kᵀ (S_k ×* f_k)
                moved += x.apply_force_transpose(&joint_motion(robot, k).cross_force(&d.f[k]));
            }
        }
        d.df[parents[i]] += moved;
    }
}

/// `[δf_B; H_iᵀ δf_i]`, the column of one pass, handed out row by row.
fn write_column(
    robot: &Robot,
    d: &mut Derivatives,
    mut put: impl FnMut(&mut Derivatives, usize, f64),
) {
    let base = d.df[0].to_array();
    for (r, value) in base.into_iter().enumerate() {
        put(d, r, value);
    }
    for i in 1..=robot.dof() {
        let value = robot.joints()[i - 1].axis.dot(&d.df[i].angular);
        put(d, 5 + i, value);
    }
}

/// `𝓜⁻¹ R` in place for the `m` columns of `d.rhs` (row-major, `(6 + n) × m`), by the
/// articulated-body factorisation in `data` (`x`, `u_col`, `d`, `ia[0]` from the forward dynamics
/// at this configuration). For every column at once: backwards `u_i = r_i − H_iᵀ p_i`,
/// `p_λ += X_iᵀ (p_i + U_i u_i/D_i)`; the base solves `I^A_B α_B = r_B − p_B` (one inverse for
/// all columns); forwards `q̈_i = (u_i − U_iᵀ X_i α_λ)/D_i`, `α_i = X_i α_λ + H_i q̈_i`. O(n) per
/// column.
fn solve_columns(robot: &Robot, data: &Data, d: &mut Derivatives, m: usize) -> Result<()> {
    let n = robot.dof();
    let parents = robot.parents();
    d.solve_p.clear();
    d.solve_p.resize((n + 1) * m, Force::zero());
    d.solve_acc.clear();
    d.solve_acc.resize((n + 1) * m, Motion::zero());
    for i in (1..=n).rev() {
        let (h, x, lambda) = (&robot.joints()[i - 1].axis, &data.x[i], parents[i]);
        let scaled = data.u_col[i] * (1.0 / data.d[i]);
        for c in 0..m {
            let p = d.solve_p[i * m + c];
            let u = d.rhs[(5 + i) * m + c] - h.dot(&p.angular);
            d.rhs[(5 + i) * m + c] = u;
            let moved = x.apply_force_transpose(&(p + scaled * u));
            d.solve_p[lambda * m + c] += moved;
        }
    }
    let mut inverse = crate::spatial::Mat6::zeros();
    for j in 0..6 {
        let mut unit = [0.0; 6];
        unit[j] = 1.0;
        let column = data.ia[0].solve(&Force::from_slice(&unit)).ok_or_else(|| {
            crate::Error::InvalidArgument {
                what: "articulated base inertia".into(),
                message: "not positive definite (the model's mass matrix is singular here)".into(),
            }
        })?;
        inverse.set_column(j, &column.to_vector());
    }
    for c in 0..m {
        let rhs: [f64; 6] = std::array::from_fn(|r| d.rhs[r * m + c]);
        let base =
            Motion::from_vector(&(inverse * (Force::from_slice(&rhs) - d.solve_p[c]).to_vector()));
        d.solve_acc[c] = base;
        for (r, value) in base.to_array().into_iter().enumerate() {
            d.rhs[r * m + c] = value;
        }
    }
    for i in 1..=n {
        let (s, x, lambda) = (joint_motion(robot, i), &data.x[i], parents[i]);
        let (u_col, inverse_d) = (data.u_col[i], 1.0 / data.d[i]);
        for c in 0..m {
            let acc = x.apply_motion(&d.solve_acc[lambda * m + c]);
            let qdd = (d.rhs[(5 + i) * m + c] - acc.dot(&u_col)) * inverse_d;
            d.solve_acc[i * m + c] = acc + s * qdd;
            d.rhs[(5 + i) * m + c] = qdd;
        }
    }
    Ok(())
}

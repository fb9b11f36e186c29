//! The inverse dynamics' derivatives (module docs of [`super`]): `∂[f_B; τ]/∂(q, ν, f)` by the
//! subtree sums of each body's terms, O(n²).

// Loops run over body indices `i`, the equations' indices; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

use super::*;

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
/// computed by the caller): `∂τ_i/∂q_k = α_i · c_k + β_i · u_k`, `∂τ_i/∂q̇_k = 2 α_i · u_k + β_i · S_k`
/// within a subtree, the subtree's force change `δF_k` for its ancestors and the base, and the
/// base twist's columns with `u = δV`. (Its AVX2 build was about 10 % faster, but valgrind 3.19 cannot
/// decode one of its instructions, so it stays portable.)
pub(super) fn id_derivatives(
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

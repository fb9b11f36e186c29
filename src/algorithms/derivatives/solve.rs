//! The O(n) `𝓜⁻¹` solve: the forward dynamics' articulated-body factorisation applied to many
//! columns at once, without forming the mass matrix.

// Loops run over body indices `i`, the equations' indices; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

use super::*;

/// Readies the forward dynamics' articulated-body factorisation in `data` (`U_i`, `D_i`,
/// `I^A_B`; valid at any velocity) for [`apply_inverse`]: `U_i` in base-frame components, `1/D_i`
/// and `(I^A_B)⁻¹`.
pub(super) fn factorisation(robot: &Robot, data: &Data, s: &mut Scratch) -> Result<()> {
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
pub(super) fn apply_inverse(robot: &Robot, s: &mut Scratch, r: &mut [f64], columns: usize) {
    crate::simd::dispatch!(apply_inverse_kernel(robot: &Robot, s: &mut Scratch, r: &mut [f64], columns: usize))
}

#[inline(always)]
pub(super) fn apply_inverse_kernel(robot: &Robot, s: &mut Scratch, r: &mut [f64], columns: usize) {
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

//! Composite-rigid-body algorithm for the (6+n)×(6+n) floating-base mass matrix, O(n²).

use super::data::{check_data, Data};
use crate::args::check_vector;
use crate::error::Result;
use crate::model::Robot;
use crate::spatial::Force;
use nalgebra::DMatrix;

/// Fills `data.mass_matrix = 𝓜 = [[M_b, M_rb], [M_br, M_r]]` (A.19), both triangles.
///
/// In joint frames (`H_i = [e_z; 0]`, so `H_jᵀ F` is the moment's z entry). Backwards from the tips, body `i`'s composite inertia `I^c_i = M_i + Σ_children Φᵀ I^c Φ` is
/// complete when its turn comes, and goes to its parent. Column `i` is `F = I^c_i H_i` carried
/// towards the base along the joints that support body `i`: `𝓜[j, i] = H_jᵀ Φ_{ij}ᵀ F` for each
/// such joint `j`, and `M_rb[:, i] = Φ_{iB}ᵀ F`. Finally `M_b = I^c_B`.
///
/// On a tree, `𝓜[i, j] = 0` for joints on different branches; only the pairs where one joint
/// supports the other are computed, O(Σ_i depth(i)) of them.
///
/// The first call allocates the matrix; later calls reuse it.
///
/// Runs as AVX2 code where the processor has it, with the same bits (`crate::simd`).
pub fn crba<'a>(robot: &Robot, data: &'a mut Data, q: &[f64]) -> Result<&'a DMatrix<f64>> {
    check_data(robot, data)?;
    check_vector("q", q, robot.dof())?;
    data.mass_matrix_buffer()?;
    crate::simd::dispatch!(crba_kernel(robot: &Robot, data: &mut Data, q: &[f64]));
    Ok(&data.mass_matrix)
}

/// The CRBA passes of [`crba`] into the allocated `data.mass_matrix`.
#[inline(always)]
pub(crate) fn crba_kernel(robot: &Robot, data: &mut Data, q: &[f64]) {
    let parents = robot.parents();
    for i in 1..=robot.dof() {
        data.x[i] = robot.joint_transform(i, q[i - 1]);
    }
    data.ic.copy_from_slice(robot.frame_inertias());
    let m = &mut data.mass_matrix;
    if !robot.is_chain() {
        // on a tree, 𝓜[i, j] = 0 where neither joint supports the other, and nothing below
        // writes there: clear what an earlier call (or another model's) may have left
        m.fill(0.0);
    }
    for i in (1..=robot.dof()).rev() {
        let moved = data.ic[i].transformed_to_parent(&data.x[i]);
        data.ic[parents[i]] = data.ic[parents[i]].add(&moved);
        let mut f = data.ic[i].apply_z();
        m[(5 + i, 5 + i)] = f.angular.z;
        let mut j = i;
        while parents[j] > 0 {
            f = data.x[j].apply_force_transpose(&f);
            j = parents[j];
            let value = f.angular.z;
            m[(5 + j, 5 + i)] = value;
            m[(5 + i, 5 + j)] = value;
        }
        f = data.x[j].apply_force_transpose(&f);
        write_base_column(m, i, &f);
    }
    m.fixed_view_mut::<6, 6>(0, 0)
        .copy_from(&data.ic[0].matrix());
}

/// `M_rb[:, i] = M_br[i, :]ᵀ = F` (A.19), `F` the column's force at the base.
fn write_base_column(m: &mut DMatrix<f64>, i: usize, f: &Force) {
    for (r, value) in f.to_array().into_iter().enumerate() {
        m[(r, 5 + i)] = value;
        m[(5 + i, r)] = value;
    }
}

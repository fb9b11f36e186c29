//! Composite-rigid-body algorithm for the (6+n)×(6+n) floating-base mass matrix, O(n²).

use super::{check_data, Data};
use crate::error::{check_vector, Result};
use crate::model::Robot;
use crate::spatial::{Force, Vec3};
use nalgebra::DMatrix;

/// Fills `data.mass_matrix = 𝓜 = [[M_b, M_rb], [M_br, M_r]]` (A.19), both triangles.
///
/// Composite inertias `I^c_i = M_i + Σ_children Φᵀ I^c Φ`, then column `i` is `F = I^c_i H_i`
/// carried towards the base: `𝓜[j, i] = H_jᵀ Φ_{ij}ᵀ F` for `j ≤ i`, and `M_rb[:, i] = Φ_{iB}ᵀ F`.
/// `M_b = I^c_B`.
pub fn crba<'a>(robot: &Robot, data: &'a mut Data, q: &[f64]) -> Result<&'a DMatrix<f64>> {
    check_data(robot, data)?;
    check_vector("q", q, robot.dof())?;
    let n = robot.dof();
    let joints = robot.joints();
    for (i, joint) in joints.iter().enumerate() {
        data.x[i + 1] = joint.transform(q[i]);
    }
    data.ic.copy_from_slice(robot.inertias());
    for i in (1..=n).rev() {
        let moved = data.ic[i].transformed_to_parent(&data.x[i]);
        data.ic[i - 1] = data.ic[i - 1].add(&moved);
    }
    let m = &mut data.mass_matrix;
    for i in 1..=n {
        let h = joints[i - 1].axis;
        let mut f = data.ic[i].apply(&crate::spatial::Motion::new(h, Vec3::zeros()));
        m[(5 + i, 5 + i)] = h.dot(&f.angular);
        for j in (1..i).rev() {
            f = data.x[j + 1].apply_force_transpose(&f);
            let value = joints[j - 1].axis.dot(&f.angular);
            m[(5 + j, 5 + i)] = value;
            m[(5 + i, 5 + j)] = value;
        }
        f = data.x[1].apply_force_transpose(&f);
        write_column(m, i, &f);
    }
    m.fixed_view_mut::<6, 6>(0, 0)
        .copy_from(&data.ic[0].matrix());
    Ok(&data.mass_matrix)
}

fn write_column(m: &mut DMatrix<f64>, i: usize, f: &Force) {
    for r in 0..3 {
        m[(r, 5 + i)] = f.angular[r];
        m[(5 + i, r)] = f.angular[r];
        m[(3 + r, 5 + i)] = f.linear[r];
        m[(5 + i, 3 + r)] = f.linear[r];
    }
}

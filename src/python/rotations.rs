//! Rotations for Python: rotation matrices, Euler angles and the angle between attitudes, from
//! the crate's one home of quaternion arithmetic (`crate::spatial`), one quaternion or a stack.

use super::convert::{as_float_array, matrix, vector};
use super::errors::ModelError;
use crate::spatial;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;

/// Quaternions `(x, y, z, w)` from Python: one (4,) or a stack (k, 4); `None` rows for one.
fn quaternions(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<(Option<usize>, Vec<f64>)> {
    let a = as_float_array(obj, what)?;
    let ndim: usize = a.getattr("ndim")?.extract()?;
    let (rows, values) = match ndim {
        1 => (None, vector(&a, what, Some(4))?),
        2 => {
            let (rows, values) = matrix(&a, what, 4)?;
            (Some(rows), values)
        }
        _ => {
            return Err(ModelError::new_err(format!(
                "{what}: expected shape (4,) or (k, 4), given a {ndim}-D array"
            )))
        }
    };
    crate::args::check_finite(what, &values)?;
    Ok((rows, values))
}

/// `f` of each quaternion, `width` numbers each, shaped `shape` after the leading `(k,)` if any.
fn each<'py>(
    py: Python<'py>,
    (rows, values): (Option<usize>, Vec<f64>),
    shape: &[usize],
    f: impl Fn(&[f64], &mut [f64]),
) -> PyResult<Bound<'py, PyAny>> {
    let width: usize = shape.iter().product();
    let mut out = vec![0.0; values.len() / 4 * width];
    for (q, o) in values.chunks_exact(4).zip(out.chunks_exact_mut(width)) {
        f(q, o);
    }
    let full: Vec<usize> = rows.into_iter().chain(shape.iter().copied()).collect();
    Ok(PyArray1::from_vec(py, out).reshape(full)?.into_any())
}

/// The rotation matrix of a quaternion ``(x, y, z, w)`` (scalar last; normalised first): it maps
/// body-frame components to parent-frame (for the base, inertial) components. ``quat`` (4,)
/// gives (3, 3); a stack (k, 4) gives (k, 3, 3).
#[pyfunction]
pub(crate) fn rotation_matrix<'py>(
    py: Python<'py>,
    quat: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    each(py, quaternions(quat, "quat")?, &[3, 3], |q, out| {
        let r = spatial::quaternion_to_rotation(q);
        for i in 0..3 {
            for j in 0..3 {
                out[3 * i + j] = r[(i, j)];
            }
        }
    })
}

/// The intrinsic z-y\'-x\'\' Euler angles ``[yaw, pitch, roll]`` (rad) of unit quaternions
/// ``(x, y, z, w)``: ``R = Rz(yaw) Ry(pitch) Rx(roll)``; yaw and roll in (−π, π], pitch in
/// [−π/2, π/2]. ``quat`` (4,) gives (3,); a stack (k, 4) gives (k, 3) (not unwrapped in time:
/// ``numpy.unwrap`` does that along a run).
#[pyfunction]
pub(crate) fn euler_zyx<'py>(
    py: Python<'py>,
    quat: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    each(py, quaternions(quat, "quat")?, &[3], |q, out| {
        out.copy_from_slice(&spatial::euler_zyx(q))
    })
}

/// The angle (rad, in [0, π]) of the rotation from attitude ``q0`` to attitude ``q1`` (unit
/// quaternions ``(x, y, z, w)``): ``2 atan2(|vec(q0* ⊗ q1)|, |w(q0* ⊗ q1)|)``, accurate for tiny
/// angles too. Each is (4,) or a stack (k, 4); a (4,) pairs with every row of the other. Returns
/// a float for two (4,), else (k,).
#[pyfunction]
pub(crate) fn rotation_angle<'py>(
    py: Python<'py>,
    q0: &Bound<'py, PyAny>,
    q1: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let (a_rows, a) = quaternions(q0, "q0")?;
    let (b_rows, b) = quaternions(q1, "q1")?;
    let rows = match (a_rows, b_rows) {
        (Some(r), Some(s)) if r != s => {
            return Err(ModelError::new_err(format!(
                "q1: expected shape (4,) or ({r}, 4) (as q0), given ({s}, 4)"
            )))
        }
        (r, s) => r.or(s),
    };
    let angle = |k: usize| {
        // a stack's row k, or the one quaternion for every k
        let pick = |stacked: bool| if stacked { k * 4 } else { 0 };
        let (i, j) = (pick(a_rows.is_some()), pick(b_rows.is_some()));
        spatial::rotation_angle(&a[i..i + 4], &b[j..j + 4])
    };
    match rows {
        None => Ok(angle(0).into_pyobject(py)?.into_any()),
        Some(k) => Ok(PyArray1::from_vec(py, (0..k).map(angle).collect()).into_any()),
    }
}

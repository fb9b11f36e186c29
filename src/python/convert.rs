//! numpy ⇄ Rust conversions with shape and finiteness checks.

use super::errors::ModelError;
use crate::args::check_finite;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// Any 1-D float array-like (numpy array, list, tuple) as a `Vec<f64>` of `expected` length
/// (`None`: any length), all finite.
pub fn vector(obj: &Bound<'_, PyAny>, what: &str, expected: Option<usize>) -> PyResult<Vec<f64>> {
    let values = if let Ok(a) = obj.downcast::<PyArray1<f64>>() {
        match direct_values(a) {
            Some(values) => values?,
            None => aligned_copy(a.as_any())?, // strided or misaligned
        }
    } else {
        let a = as_float_array(obj, what)?;
        let shape = a.getattr("shape")?.extract::<Vec<usize>>()?;
        if shape.len() != 1 {
            return Err(ModelError::new_err(format!(
                "{what}: expected a 1-D array{}, given shape {shape:?}",
                expected.map_or(String::new(), |n| format!(" of length {n}"))
            )));
        }
        aligned_copy(&a)?
    };
    if let Some(n) = expected {
        if values.len() != n {
            return Err(ModelError::new_err(format!(
                "{what}: expected length {n}, given length {}",
                values.len()
            )));
        }
    }
    check_finite(what, &values)?;
    Ok(values)
}

/// The values of a C-contiguous, aligned float64 array, copied at once; `None` for any other
/// layout (see [`aligned_copy`]).
///
/// No Rust code in orbitflex holds a reference into a numpy array while the GIL is released
/// (batched calls compute into their own buffer and copy into `out=` under the GIL), so a copy
/// made while this thread holds the GIL cannot race with a write; this skips rust-numpy's borrow
/// tracking, which is most of the per-call cost of a small array.
/// The copy is fallible: an array too large to copy is a `MemoryError`, not an abort.
pub fn direct_values<D: numpy::ndarray::Dimension>(
    a: &Bound<'_, numpy::PyArray<f64, D>>,
) -> Option<PyResult<Vec<f64>>> {
    let wanted = numpy::npyffi::NPY_ARRAY_C_CONTIGUOUS | numpy::npyffi::NPY_ARRAY_ALIGNED;
    // SAFETY: reads the flags of a live array object
    let flags = unsafe { (*a.as_array_ptr()).flags };
    if flags & wanted != wanted {
        return None;
    }
    // SAFETY: contiguous and aligned (checked), read while this thread holds the GIL (above)
    let values = unsafe { a.as_slice() }.ok()?;
    let mut copy = Vec::new();
    if copy.try_reserve_exact(values.len()).is_err() {
        return Some(Err(pyo3::exceptions::PyMemoryError::new_err(format!(
            "a copy of {} numbers does not fit in memory",
            values.len()
        ))));
    }
    copy.extend_from_slice(values);
    Some(Ok(copy))
}

/// The values of any float array-like in C order, through a C-contiguous, aligned float64 copy
/// that numpy makes (`numpy.require`).
pub fn aligned_copy(obj: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let np = obj.py().import("numpy")?;
    let a = np
        .call_method1("require", (obj, np.getattr("float64")?, "CA"))?
        .call_method1("reshape", (-1,))?;
    let a = a.downcast::<PyArray1<f64>>()?;
    direct_values(a)
        .unwrap_or_else(|| Err(ModelError::new_err("numpy.require gave an unaligned copy")))
}

/// Like [`vector`] but `None` gives `default`.
pub fn vector_or(
    obj: Option<&Bound<'_, PyAny>>,
    what: &str,
    n: usize,
    default: f64,
) -> PyResult<Vec<f64>> {
    match obj {
        Some(o) if !o.is_none() => vector(o, what, Some(n)),
        _ => Ok(vec![default; n]),
    }
}

/// A 2-D float array of `width` columns as (rows, row-major values), all finite.
pub fn matrix(obj: &Bound<'_, PyAny>, what: &str, width: usize) -> PyResult<(usize, Vec<f64>)> {
    let a = as_float_array(obj, what)?;
    let a = a.extract::<PyReadonlyArray2<f64>>().map_err(|_| {
        let shape = a
            .getattr("shape")
            .and_then(|s| s.extract::<Vec<usize>>())
            .unwrap_or_default();
        ModelError::new_err(format!(
            "{what}: expected a 2-D array of shape (rows, {width}), given shape {shape:?}"
        ))
    })?;
    let shape = a.shape().to_vec();
    if shape[1] != width {
        return Err(ModelError::new_err(format!(
            "{what}: expected shape (rows, {width}), given shape ({}, {})",
            shape[0], shape[1]
        )));
    }
    let values: Vec<f64> = a.as_array().iter().copied().collect();
    // name the row: `u[12]: element 3 is not finite (NaN)`
    if let Some(at) = values.iter().position(|v| !v.is_finite()) {
        check_finite(
            &format!("{what}[{}]", at / width),
            &values[at - at % width..][..width],
        )?;
    }
    Ok((shape[0], values))
}

/// `numpy.asarray(obj, dtype=float64)` for integer or floating-point input, with a clear error
/// for anything else (strings, bools, complex numbers, objects), which numpy would otherwise
/// convert or reject with a message that does not name the argument.
pub fn as_float_array<'py>(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Bound<'py, PyAny>> {
    let np = obj.py().import("numpy")?;
    let raw = np.call_method1("asarray", (obj,)).map_err(|e| {
        ModelError::new_err(format!(
            "{what}: expected an array of numbers, given {} ({e})",
            type_name(obj)
        ))
    })?;
    let kind: String = raw.getattr("dtype")?.getattr("kind")?.extract()?;
    if !matches!(kind.as_str(), "i" | "u" | "f") {
        let given = match kind.as_str() {
            "c" => "a complex array".to_string(),
            "b" => "bools".to_string(),
            "U" | "S" => "text".to_string(),
            _ => format!("{} of dtype {}", type_name(obj), raw.getattr("dtype")?),
        };
        return Err(ModelError::new_err(format!(
            "{what}: expected real numbers, given {given}"
        )));
    }
    np.call_method1("asarray", (raw, np.getattr("float64")?))
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// A new 1-D numpy array.
pub fn array1<'py>(py: Python<'py>, values: &[f64]) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, values)
}

/// A new 2-D numpy array from a column-major nalgebra matrix.
pub fn array2<'py, R: nalgebra::Dim, C: nalgebra::Dim, S: nalgebra::RawStorage<f64, R, C>>(
    py: Python<'py>,
    m: &nalgebra::Matrix<f64, R, C, S>,
) -> Bound<'py, PyArray2<f64>> {
    let (rows, cols) = m.shape();
    let data: Vec<f64> = (0..rows)
        .flat_map(|r| (0..cols).map(move |c| m[(r, c)]))
        .collect();
    row_major(py, rows, cols, data)
}

/// [`array2`] with its row-major copy allocated fallibly: a matrix too large for memory is a
/// `MemoryError` naming `what` and the size, not an abort (Jacobians of a large arm are hundreds
/// of megabytes each).
pub fn try_array2<'py, R: nalgebra::Dim, C: nalgebra::Dim, S: nalgebra::RawStorage<f64, R, C>>(
    py: Python<'py>,
    m: &nalgebra::Matrix<f64, R, C, S>,
    what: &str,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (rows, cols) = m.shape();
    let mut data = Vec::new();
    if data.try_reserve_exact(rows * cols).is_err() {
        return Err(crate::Error::OutOfMemory {
            what: what.into(),
            bytes: Some(8 * rows * cols),
            hint: format!("a copy of this {rows} × {cols} matrix for numpy"),
        }
        .into());
    }
    data.extend((0..rows).flat_map(|r| (0..cols).map(move |c| m[(r, c)])));
    Ok(row_major(py, rows, cols, data))
}

/// A new 2-D numpy array from row-major values.
pub fn row_major(
    py: Python<'_>,
    rows: usize,
    cols: usize,
    data: Vec<f64>,
) -> Bound<'_, PyArray2<f64>> {
    numpy::ndarray::Array2::from_shape_vec((rows, cols), data)
        .map(|a| PyArray2::from_owned_array(py, a))
        .expect("shape matches data")
}

/// Parses `method="recursive" | "operator"`.
pub fn method(name: &str) -> PyResult<crate::Method> {
    Ok(crate::Method::from_name(name)?)
}

/// A real number given as a Python int, float or numpy scalar: not a bool, a string or a
/// complex number, which Python would otherwise convert or reject with a message that does not
/// name the argument.
pub fn real(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<f64> {
    let wrong = || {
        ModelError::new_err(format!(
            "{what}: expected a real number, given {} ({})",
            type_name(obj),
            obj.repr().map(|r| r.to_string()).unwrap_or_default()
        ))
    };
    if obj.is_instance_of::<pyo3::types::PyBool>()
        || obj.is_instance_of::<pyo3::types::PyString>()
        || obj.is_instance_of::<pyo3::types::PyBytes>()
        || obj.is_instance_of::<pyo3::types::PyComplex>()
        || obj.is_none()
    {
        return Err(wrong());
    }
    obj.extract::<f64>().map_err(|_| wrong())
}

/// A count (an integer ≥ 0) given as a Python int or numpy integer, not a bool or a float.
pub fn count(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<usize> {
    let given = || obj.repr().map(|r| r.to_string()).unwrap_or_default();
    if obj.is_instance_of::<pyo3::types::PyBool>() || obj.hasattr("__index__").ok() != Some(true) {
        return Err(ModelError::new_err(format!(
            "{what}: expected an integer >= 0, given {} ({})",
            type_name(obj),
            given()
        )));
    }
    let index = obj.call_method0("__index__")?;
    index.extract::<usize>().map_err(|_| {
        ModelError::new_err(format!(
            "{what}: expected an integer from 0 to {}, given {}",
            usize::MAX,
            given()
        ))
    })
}

/// `record_every` as the runs take it: None (every row) or an integer ≥ 1.
pub fn record_every_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<usize> {
    match obj.filter(|o| !o.is_none()) {
        Some(k) => positive_count(k, "record_every"),
        None => Ok(1),
    }
}

/// A count of at least 1 (an int or numpy integer, not a bool or a float), for `record_every`
/// and `chunk_rows`.
pub fn positive_count(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<usize> {
    let wrong = || {
        ModelError::new_err(format!(
            "{what}: expected an integer >= 1, given {} ({})",
            type_name(obj),
            obj.repr().map(|r| r.to_string()).unwrap_or_default()
        ))
    };
    if obj.is_instance_of::<pyo3::types::PyBool>() || obj.hasattr("__index__").ok() != Some(true) {
        return Err(wrong());
    }
    let index = obj.call_method0("__index__")?;
    match index.extract::<usize>() {
        Ok(k) if k >= 1 => Ok(k),
        // an int past the largest count is not "below 1"
        Err(_) if index.gt(1).unwrap_or(false) => Err(ModelError::new_err(format!(
            "{what}: expected an integer from 1 to {}, given {}",
            usize::MAX,
            obj.repr().map(|r| r.to_string()).unwrap_or_default()
        ))),
        _ => Err(wrong()),
    }
}

/// ``ee_wrench`` as the Python functions take it, with one row of `6k` numbers per call or step
/// (`k` end-effectors): `None` for none; for a robot with one end-effector, the argument as
/// given; for several, `(…, k, 6)` reshaped to `(…, 6k)`; a dict from end-effector link name to
/// `(…, 6)` (every value the same shape; end-effectors left out get zero) stacked the same way.
pub(crate) fn ee_wrench_arg<'py>(
    robot: &crate::Robot,
    obj: Option<&Bound<'py, PyAny>>,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    use super::batched::shape_and_values;
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let k = robot.end_effectors().len();
    let (lead, flat) = if let Ok(dict) = obj.downcast::<pyo3::types::PyDict>() {
        ee_wrench_dict(robot, dict)?
    } else if k == 1 {
        return Ok(Some(obj.clone()));
    } else {
        let (shape, values) = shape_and_values(obj, "ee_wrench")?;
        let d = shape.len();
        if d < 2 || shape[d - 2..] != [k, 6] {
            return Err(ModelError::new_err(format!(
                "ee_wrench: the robot has {k} end-effectors ({}); give one [moment; force] row \
                 each, shape ({k}, 6) (or (rows, {k}, 6) where rows are allowed), or a dict from \
                 link name to (6,); given shape {shape:?}",
                robot.ee_links().join(", ")
            )));
        }
        (shape[..d - 2].to_vec(), values)
    };
    let mut shape = lead;
    shape.push(6 * k);
    let array = PyArray1::from_vec(obj.py(), flat);
    Ok(Some(array.reshape(shape)?.into_any()))
}

/// A dict of ``ee_wrench`` from end-effector link name to ``(…, 6)`` (every value the same
/// shape), stacked: the leading shape `…` and the rows of `6k` numbers (zero for the
/// end-effectors left out).
fn ee_wrench_dict(
    robot: &crate::Robot,
    dict: &Bound<'_, pyo3::types::PyDict>,
) -> PyResult<(Vec<usize>, Vec<f64>)> {
    let k = robot.end_effectors().len();
    let mut lead: Option<Vec<usize>> = None;
    let mut parts = Vec::with_capacity(dict.len());
    for (key, value) in dict.iter() {
        let (e, name) = ee_wrench_key(robot, &key)?;
        let what = format!("ee_wrench[{name:?}]");
        let (shape, values) = super::batched::shape_and_values(&value, &what)?;
        check_finite(&what, &values)?;
        if shape.last() != Some(&6) {
            return Err(ModelError::new_err(format!(
                "{what}: expected [moment; force], shape (6,) or (rows, 6), given shape {shape:?}"
            )));
        }
        let here = shape[..shape.len() - 1].to_vec();
        match &lead {
            Some(first) if *first != here => {
                return Err(ModelError::new_err(format!(
                    "{what}: shape {shape:?} differs from the other entries' (every entry of \
                     the dict must have the same shape)"
                )))
            }
            _ => lead = Some(here),
        }
        parts.push((e, values));
    }
    let lead = lead.unwrap_or_default();
    let rows: usize = lead.iter().product();
    let mut flat = vec![0.0; rows * 6 * k];
    for (e, values) in parts {
        for r in 0..rows {
            flat[r * 6 * k + 6 * e..r * 6 * k + 6 * e + 6]
                .copy_from_slice(&values[6 * r..6 * r + 6]);
        }
    }
    Ok((lead, flat))
}

/// A key of an ``ee_wrench`` dict: the index of the end-effector it names, and the name.
fn ee_wrench_key(robot: &crate::Robot, key: &Bound<'_, PyAny>) -> PyResult<(usize, String)> {
    let name: String = key.extract().map_err(|_| {
        ModelError::new_err(format!(
            "ee_wrench: a dict's keys are end-effector link names ({}); given a key of type {}",
            robot.ee_links().join(", "),
            key.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))
    })?;
    let e = robot.ee_index(&name).map_err(|_| {
        ModelError::new_err(format!(
            "ee_wrench: no end-effector named {name:?}; the end-effectors are {}",
            robot.ee_links().join(", ")
        ))
    })?;
    Ok((e, name))
}

/// The ``ee=`` argument: an end-effector link name, an index into ``ee_links``, or ``None`` for
/// the only end-effector (an error listing them when there are several).
pub(crate) fn ee_arg(robot: &crate::Robot, ee: Option<&Bound<'_, PyAny>>) -> PyResult<usize> {
    let Some(ee) = ee.filter(|o| !o.is_none()) else {
        return Ok(robot.ee_choice(None)?);
    };
    if let Ok(name) = ee.extract::<String>() {
        return Ok(robot.ee_index(&name)?);
    }
    if ee.is_instance_of::<pyo3::types::PyBool>() {
        return Err(ModelError::new_err(
            "ee: expected an end-effector link name or index, given a bool",
        ));
    }
    match ee.extract::<i64>() {
        Ok(i) if i >= 0 => Ok(robot.ee_choice(Some(i as usize))?),
        Ok(i) => Err(ModelError::new_err(format!(
            "ee: expected an index from 0 to {}, given {i}",
            robot.end_effectors().len() - 1
        ))),
        Err(_) if ee.is_instance_of::<pyo3::types::PyInt>() => Err(ModelError::new_err(format!(
            "ee: expected an index from 0 to {}, given {}",
            robot.end_effectors().len() - 1,
            ee.str().map(|s| s.to_string()).unwrap_or_default()
        ))),
        Err(_) => Err(ModelError::new_err(format!(
            "ee: expected an end-effector link name (str) or index (int), given {}",
            ee.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))),
    }
}

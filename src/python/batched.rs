//! Per-call dynamics with a leading batch axis, and ``out=``: the arguments of one call as
//! vectors, or as stacks of rows broadcast over a batch evaluated in parallel without the GIL;
//! the result written into a new array or into the caller's.

use super::convert::{aligned_copy, as_float_array, direct_values, vector_or};
use super::errors::ModelError;
use super::parallel::compute_rows;
use super::workspaces::Pool;
use crate::algorithms::Data;
use crate::integrate::batch::BatchInput;
use crate::model::Robot;
use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// One argument of a batched call, as read: its name, shape and values (C order), or zeros.
struct Column<'a> {
    what: &'a str,
    width: usize,
    shape: Vec<usize>,
    values: Vec<f64>,
}

/// The arguments of a call with a leading batch axis of `rows` rows, each broadcast over the rows
/// by the batch's rule ([`BatchInput`]): `(width,)`, the same for every row, or `(rows, width)`.
pub(crate) struct Batched<'a> {
    pub rows: usize,
    columns: Vec<Column<'a>>,
}

impl Batched<'_> {
    /// The arguments, in the order given to [`call_args`], as inputs over the rows, for the
    /// caller to name: `let [q, qd] = b.inputs()?;`, then `q.row_or_empty(r)` is row `r` of `q`.
    /// An argument whose shape does not broadcast is an error naming it, the shapes expected
    /// and the one given.
    pub fn inputs<const N: usize>(&self) -> PyResult<[BatchInput<'_>; N]> {
        let inputs = self
            .columns
            .iter()
            .map(|c| BatchInput::for_rows(c.what, &c.values, &c.shape, self.rows, c.width))
            .collect::<crate::Result<Vec<_>>>()?;
        let given = inputs.len();
        inputs.try_into().map_err(|_| {
            pyo3::exceptions::PyRuntimeError::new_err(format!(
                "internal: {N} arguments asked of a call that read {given}"
            ))
        })
    }
}

/// An argument of a per-call function: its name, the object given (None: zeros), its width.
pub(crate) type Arg<'a, 'py> = (&'a str, Option<&'a Bound<'py, PyAny>>, usize);

/// The arguments of one per-call function call: one vector each (the single call), or a batch.
pub(crate) enum Call<'a> {
    /// One vector per argument (zeros for an argument not given), checked: its width, finite.
    Single(Vec<Vec<f64>>),
    /// A leading batch axis on at least one argument.
    Batch(Batched<'a>),
}

/// Reads the arguments of a per-call function: when every given argument is a contiguous 1-D
/// float64 array (the common case) they are copied at once, in one pass, for the single call;
/// anything else goes through numpy: all 1-D (or lists) is still the single call, and a leading
/// axis on any argument makes a batch, each argument `(width,)` (the same for every row) or
/// `(B, width)` with one `B` for all. An error names the argument, the shape (or length)
/// expected and the one given.
pub(crate) fn call_args<'a>(args: &[Arg<'a, '_>]) -> PyResult<Call<'a>> {
    let mut fast = Vec::with_capacity(args.len());
    for (_, obj, width) in args {
        match obj {
            None => fast.push(vec![0.0; *width]),
            Some(o) if o.is_none() => fast.push(vec![0.0; *width]),
            Some(o) => match o
                .downcast::<numpy::PyArray1<f64>>()
                .ok()
                .and_then(direct_values)
            {
                Some(values) => fast.push(values?),
                None => break,
            },
        }
    }
    if fast.len() == args.len() {
        for ((what, _, width), values) in args.iter().zip(&fast) {
            checked(what, values, *width)?;
        }
        return Ok(Call::Single(fast));
    }
    if let Some(batch) = batched(args)? {
        return Ok(Call::Batch(batch));
    }
    let mut single = Vec::with_capacity(args.len());
    for (what, obj, width) in args {
        single.push(vector_or(*obj, what, *width, 0.0)?);
    }
    Ok(Call::Single(single))
}

/// The length and finiteness checks of `convert::vector`, with its messages.
fn checked(what: &str, values: &[f64], width: usize) -> PyResult<()> {
    if values.len() != width {
        return Err(ModelError::new_err(format!(
            "{what}: expected length {width}, given length {}",
            values.len()
        )));
    }
    crate::args::check_finite(what, values)?;
    Ok(())
}

/// The arguments as a batch, or `None` when none has a leading axis (scalars, lists, 1-D).
fn batched<'a>(args: &[Arg<'a, '_>]) -> PyResult<Option<Batched<'a>>> {
    // each argument's shape and values (C order): float64 arrays are read directly, anything
    // else through numpy.asarray
    let mut shapes = Vec::with_capacity(args.len());
    let mut arrays: Vec<Option<Vec<f64>>> = Vec::with_capacity(args.len());
    for (what, obj, _) in args {
        match obj.filter(|o| !o.is_none()) {
            None => {
                shapes.push(None);
                arrays.push(None);
            }
            Some(o) => {
                let (shape, values) = shape_and_values(o, what)?;
                shapes.push(Some(shape));
                arrays.push(Some(values));
            }
        }
    }
    if shapes.iter().flatten().all(|s| s.len() <= 1) {
        return Ok(None);
    }
    let mut rows: Option<(&str, usize)> = None;
    for ((what, _, _), shape) in args.iter().zip(&shapes) {
        if let Some(shape) = shape {
            if shape.len() == 2 {
                match rows {
                    None => rows = Some((what, shape[0])),
                    Some((first, b)) if b != shape[0] => {
                        return Err(ModelError::new_err(format!(
                            "{what}: expected {b} rows (as {first}) or one vector for every row, \
                             given shape {}",
                            shown(shape)
                        )))
                    }
                    _ => {}
                }
            }
        }
    }
    let rows = rows.map_or(1, |(_, b)| b);
    let columns = args
        .iter()
        .zip(shapes)
        .zip(arrays)
        .map(
            |((&(what, _, width), shape), values)| match (shape, values) {
                (Some(shape), Some(values)) => Column {
                    what,
                    width,
                    shape,
                    values,
                },
                _ => Column {
                    what,
                    width,
                    shape: vec![width],
                    values: vec![0.0; width],
                },
            },
        )
        .collect();
    Ok(Some(Batched { rows, columns }))
}

/// The shape and the values (C order) of an array-like argument.
pub(crate) fn shape_and_values(
    obj: &Bound<'_, PyAny>,
    what: &str,
) -> PyResult<(Vec<usize>, Vec<f64>)> {
    if let Ok(a) = obj.downcast::<PyArrayDyn<f64>>() {
        if let Some(values) = direct_values(a) {
            return Ok((a.shape().to_vec(), values?));
        }
    }
    let a = as_float_array(obj, what)?;
    let shape: Vec<usize> = a.getattr("shape")?.extract()?;
    Ok((shape, aligned_copy(&a)?))
}

use crate::args::describe_shape as shown;

/// `out`, checked: a float64 numpy array of this shape, C-contiguous and writeable.
fn checked_out<'py>(
    o: &Bound<'py, PyAny>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let array = o.downcast::<PyArrayDyn<f64>>().map_err(|_| {
        ModelError::new_err(format!(
            "out: expected a float64 numpy array of shape {}, given {}",
            shown(shape),
            o.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))
    })?;
    if array.shape() != shape {
        return Err(ModelError::new_err(format!(
            "out: expected shape {}, given shape {}",
            shown(shape),
            shown(array.shape())
        )));
    }
    // SAFETY: reads the flags of a live array object
    let flags = unsafe { (*array.as_array_ptr()).flags };
    let wanted = numpy::npyffi::NPY_ARRAY_C_CONTIGUOUS
        | numpy::npyffi::NPY_ARRAY_ALIGNED
        | numpy::npyffi::NPY_ARRAY_WRITEABLE;
    if flags & wanted != wanted {
        return Err(ModelError::new_err(
            "out: expected a C-contiguous, aligned, writeable array",
        ));
    }
    Ok(array.clone())
}

/// A single call's vector result: a new 1-D array, or written into `out` (checked), which is
/// returned.
pub(crate) fn single_vector<'py>(
    py: Python<'py>,
    out: Option<&Bound<'py, PyAny>>,
    values: &[f64],
) -> PyResult<Bound<'py, PyAny>> {
    match out.filter(|o| !o.is_none()) {
        None => Ok(numpy::PyArray1::from_slice(py, values).into_any()),
        Some(o) => {
            let array = checked_out(o, &[values.len()])?;
            // SAFETY: written at once while this thread holds the GIL, so no Python code runs
            // meanwhile; the array is C-contiguous, writeable and of this length (checked)
            unsafe { array.as_slice_mut() }?.copy_from_slice(values);
            Ok(array.into_any())
        }
    }
}

/// A single call's result of any `shape` (`values` in C order): a new array, or written into
/// `out` (checked), which is returned.
pub(crate) fn single_array<'py>(
    py: Python<'py>,
    out: Option<&Bound<'py, PyAny>>,
    shape: &[usize],
    values: &[f64],
) -> PyResult<Bound<'py, PyAny>> {
    match out.filter(|o| !o.is_none()) {
        None => Ok(numpy::PyArray1::from_slice(py, values)
            .reshape(shape)?
            .into_any()),
        Some(o) => {
            let array = checked_out(o, shape)?;
            // SAFETY: as in `single_vector`
            unsafe { array.as_slice_mut() }?.copy_from_slice(values);
            Ok(array.into_any())
        }
    }
}

/// A single call's `size × size` matrix result: `write` fills a new array, or `out` (checked),
/// which is returned, in row-major order.
pub(crate) fn single_matrix<'py>(
    py: Python<'py>,
    out: Option<&Bound<'py, PyAny>>,
    size: usize,
    write: impl FnOnce(&mut [f64]),
) -> PyResult<Bound<'py, PyAny>> {
    match out.filter(|o| !o.is_none()) {
        None => {
            let array = numpy::PyArray2::<f64>::zeros(py, [size, size], false);
            // SAFETY: a new array that nothing else refers to
            write(unsafe { array.as_slice_mut() }?);
            Ok(array.into_any())
        }
        Some(o) => {
            let array = checked_out(o, &[size, size])?;
            // SAFETY: as in `single_vector`
            write(unsafe { array.as_slice_mut() }?);
            Ok(array.into_any())
        }
    }
}

/// Evaluates `f(data, row, out_row)` for every row of a batch of `shape = (rows, …)`, a row of
/// the product of the other axes, in parallel without the GIL ([`compute_rows`]), into a buffer of its own. The
/// result goes to a new array of `shape`, or is copied into `out` (checked first) once the GIL
/// is back, so no numpy array is touched without it. The first error (lowest row) is raised,
/// naming its row. Ctrl-C stops the rows within [`super::run::SIGNAL_CHECK`] and raises
/// `KeyboardInterrupt`.
pub(crate) fn evaluate<'py>(
    py: Python<'py>,
    robot: &Robot,
    workspaces: &Pool<Data>,
    out: Option<&Bound<'py, PyAny>>,
    shape: &[usize],
    f: impl Fn(&mut Data, usize, &mut [f64]) -> crate::Result<()> + Sync,
) -> PyResult<Bound<'py, PyAny>> {
    // `shape` is `(rows, …)`: a row holds the product of the other axes
    let rows = shape[0];
    let width = shape[1..].iter().product::<usize>();
    let out = out
        .filter(|o| !o.is_none())
        .map(|o| checked_out(o, shape))
        .transpose()?;
    let too_big = || -> PyErr {
        crate::Error::OutOfMemory {
            what: "the result".into(),
            bytes: rows.checked_mul(width).and_then(|len| len.checked_mul(8)),
            hint: format!("it has {rows} rows of {width} numbers; give fewer rows per call"),
        }
        .into()
    };
    let len = rows.checked_mul(width).ok_or_else(too_big)?;
    let mut values = Vec::new();
    values.try_reserve_exact(len).map_err(|_| too_big())?;
    values.resize(len, 0.0);
    compute_rows(py, robot, workspaces, &mut values, width, &f)?;
    match out {
        Some(array) => {
            // SAFETY: written at once while this thread holds the GIL; C-contiguous, aligned,
            // writeable and of this shape (checked)
            unsafe { array.as_slice_mut() }?.copy_from_slice(&values);
            Ok(array.into_any())
        }
        None => Ok(numpy::PyArray1::from_vec(py, values)
            .reshape(shape)?
            .into_any()),
    }
}

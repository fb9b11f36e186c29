//! The Python exceptions of orbitflex, created here and registered by the module: the one place
//! where [`Error`] is mapped onto Python.

use crate::error::Error;
use pyo3::create_exception;
use pyo3::exceptions::{
    PyFileNotFoundError, PyIsADirectoryError, PyKeyboardInterrupt, PyMemoryError, PyRuntimeError,
    PyValueError,
};
use pyo3::prelude::*;

create_exception!(
    orbitflex,
    ModelError,
    PyValueError,
    "An invalid model, model file or argument (a ValueError). The message says what is wrong, \
     where, and what was expected."
);

create_exception!(
    orbitflex,
    SimulationError,
    PyRuntimeError,
    "A run that stopped early: the state diverged, the controller failed, or the run was \
     interrupted.\n\n\
     Attributes: ``step``, the index k of the failed step (from ``t = k dt`` to ``(k+1) dt``); \
     ``time = k dt`` (s); ``trajectory``, an ``orbitflex.Trajectory`` with the k + 1 valid states \
     computed before the failure. When a Python controller raised, ``__cause__`` is its \
     exception."
);

create_exception!(
    orbitflex,
    LimitWarning,
    pyo3::exceptions::PyUserWarning,
    "Limits given to the planner that allow more than the robot's model states (a URDF's \
     ``<limit effort velocity>``): the plan uses them as given."
);

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        match e {
            Error::FileNotFound { .. } => PyFileNotFoundError::new_err(e.to_string()),
            Error::IsADirectory { .. } => PyIsADirectoryError::new_err(e.to_string()),
            Error::OutOfMemory { .. } => PyMemoryError::new_err(e.to_string()),
            Error::Interrupted { .. } => PyKeyboardInterrupt::new_err(e.to_string()),
            _ => ModelError::new_err(e.to_string()),
        }
    }
}

/// A `SimulationError` for a failed run, with its attributes and cause.
pub fn simulation_error(
    py: Python<'_>,
    message: String,
    step: usize,
    time: f64,
    trajectory: PyObject,
    cause: Option<PyErr>,
) -> PyResult<PyErr> {
    let err = SimulationError::new_err(message);
    let value = err.value(py);
    value.setattr("step", step)?;
    value.setattr("time", time)?;
    value.setattr("trajectory", trajectory)?;
    err.set_cause(py, cause);
    Ok(err)
}

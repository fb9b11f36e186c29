//! Python bindings (feature `python`): the `orbitflex._core` extension module.
//!
//! Arrays cross as numpy float64, are converted once to Rust values, the work runs in Rust and
//! results return as new arrays. Long-running calls (URDF loading, `simulate` without a Python
//! controller, trajectory diagnostics) release the GIL; per-call dynamics keep it, as releasing
//! it would cost more than the call.

mod arm;
mod convert;
mod robot;

use crate::error::Error;
use pyo3::create_exception;
use pyo3::exceptions::{PyFileNotFoundError, PyValueError};
use pyo3::prelude::*;

create_exception!(
    orbitflex,
    ModelError,
    PyValueError,
    "An invalid model, model file or argument (a ValueError)."
);

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        match e {
            Error::FileNotFound { .. } => PyFileNotFoundError::new_err(e.to_string()),
            _ => ModelError::new_err(e.to_string()),
        }
    }
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("ModelError", m.py().get_type::<ModelError>())?;
    m.add("SPACE_ARM_URDF", crate::SPACE_ARM_URDF)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<robot::PyRobot>()?;
    m.add_class::<arm::PyFlexibleJoints>()?;
    m.add_class::<arm::PyFlexibleArm>()?;
    m.add_class::<arm::PyMotorPD>()?;
    Ok(())
}

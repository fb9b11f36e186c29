//! Running a simulation from Python: without the GIL when the controller is Rust, with it when
//! it is a Python callable; honouring Ctrl-C and reporting progress either way.

use crate::flex::FlexibleArm;
use crate::integrate::{self, Controller, Observer, SimulationFailure, Trajectory, Wrenches};
use pyo3::prelude::*;

/// How often (in steps) a run looks for Ctrl-C and reports progress.
const EVERY: usize = 1024;

/// An optional Python callable `progress(done, steps)`.
pub(crate) struct Progress {
    callback: Option<Py<PyAny>>,
}

impl Progress {
    pub fn new(callback: Option<Bound<'_, PyAny>>) -> Self {
        Self {
            callback: callback.map(Bound::unbind),
        }
    }

    fn report(&self, py: Python<'_>, done: usize, steps: usize) -> PyResult<()> {
        if let Some(callback) = &self.callback {
            callback.call1(py, (done, steps))?;
        }
        Ok(())
    }

    /// The last report, once the run is over.
    pub fn finish(&self, py: Python<'_>, done: usize, steps: usize) -> PyResult<()> {
        self.report(py, done, steps)
    }
}

/// Looks for signals and reports progress, taking the GIL back for it; the first Python error
/// (a `KeyboardInterrupt`, or an exception from the progress callback) stops the run.
struct Watch<'a> {
    progress: &'a Progress,
    error: Option<PyErr>,
}

impl Watch<'_> {
    fn check(&mut self, py: Python<'_>, step: usize, steps: usize) -> bool {
        match py
            .check_signals()
            .and_then(|_| self.progress.report(py, step, steps))
        {
            Ok(()) => true,
            Err(e) => {
                self.error = Some(e);
                false
            }
        }
    }
}

impl Observer for Watch<'_> {
    fn every(&self) -> usize {
        EVERY
    }
    fn observe(&mut self, step: usize, steps: usize) -> bool {
        Python::with_gil(|py| self.check(py, step, steps))
    }
}

type RunResult = Result<Trajectory, Box<SimulationFailure>>;

/// [`integrate::simulate()`] without the GIL. A pending `KeyboardInterrupt` (or an exception from
/// the progress callback) stops the run and is raised as it is.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run_releasing_gil(
    py: Python<'_>,
    arm: &FlexibleArm,
    x0: &[f64],
    dt: f64,
    steps: usize,
    u: &mut (dyn Controller + Send),
    wrenches: &Wrenches,
    progress: &mut Progress,
) -> PyResult<RunResult> {
    let mut watch = Watch {
        progress,
        error: None,
    };
    let result =
        py.allow_threads(|| integrate::simulate(arm, x0, dt, steps, u, wrenches, &mut watch));
    match watch.error {
        Some(e) => Err(e),
        None => Ok(result),
    }
}

/// [`integrate::simulate()`] holding the GIL, for a controller that calls Python.
pub(crate) fn run_with_gil(
    arm: &FlexibleArm,
    x0: &[f64],
    dt: f64,
    steps: usize,
    u: &mut dyn Controller,
    wrenches: &Wrenches,
    progress: &mut Progress,
) -> PyResult<RunResult> {
    let mut watch = Watch {
        progress,
        error: None,
    };
    let result = integrate::simulate(arm, x0, dt, steps, u, wrenches, &mut watch);
    match watch.error {
        Some(e) => Err(e),
        None => Ok(result),
    }
}

//! Python bindings (feature `python`): the `orbitflex._core` extension module, which the
//! `orbitflex` package re-exports.
//!
//! Arrays cross as numpy float64, are converted once to Rust values, the work runs in Rust and
//! results return as new arrays (or into the caller's `out=`). Long-running calls (URDF loading,
//! `simulate` without a Python controller, `simulate_batch`, batched per-call dynamics,
//! trajectory diagnostics, planning and tracking slews) release the GIL; a single per-call
//! dynamics call keeps it, as releasing it would cost more than the call.
//!
//! **Threads.** An object may be called from several Python threads at once: each call takes a
//! workspace of its own from the object's `workspaces::Pool`, whose lock is only tried, so no
//! thread ever waits for a Rust lock while it holds the GIL, and no lock is held across a call
//! into Python or numpy (numpy may release the GIL while it allocates). **Ctrl-C.** Every long
//! computation without the GIL looks for signals every `run::SIGNAL_CHECK` (50 ms) on the
//! calling thread (`run::watched`, `parallel::compute_rows`, the run's `Observer`) and stops
//! its workers through a flag. docs/threads_and_interrupts.md says it for users.
//!
//! One file per class: `robot` (`Robot`), `joints` (`FlexibleJoints`), `control` (`MotorPD`,
//! input schedules, Python controllers), `arm` (`FlexibleArm`), `trajectory` (`Trajectory`),
//! `plan` (`Limits`, `Plan`, `plan_slew`), `stability` (`StabilityLimit`), `batch` (`simulate_batch`, `BatchTrajectory`), `capture`
//! (`Target`, `capture`, `Capture`); `simulator` (`Simulator`); `fmu` (the FMU's files); `memory` (`recorded_rows`, `run_bytes`, `check_run_memory`, `available_memory`); `analysis` (the linear analysis's private
//! functions, wrapped by `orbitflex.analysis`);
//! `batched` gives the per-call dynamics their leading batch axis and `out=`; `run` drives a
//! simulation with or without the GIL; `errors` maps [`crate::Error`] onto the Python
//! exceptions; `convert` turns numpy arrays into Rust values.

mod analysis;
mod appearance;
mod arm;
mod batch;
mod batched;
mod capture;
mod capture_run;
mod control;
mod convert;
mod errors;
mod fmu;
mod joints;
mod memory;
mod parallel;
mod plan;
mod robot;
mod rotations;
mod run;
mod simulator;
mod stability;
mod state_columns;
mod trajectory;
mod wheels;
mod workspaces;

use pyo3::prelude::*;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("ModelError", py.get_type::<errors::ModelError>())?;
    m.add("SimulationError", py.get_type::<errors::SimulationError>())?;
    m.add("LimitWarning", py.get_type::<errors::LimitWarning>())?;
    m.add("SPACE_ARM_URDF", crate::SPACE_ARM_URDF)?;
    m.add("DUAL_ARM_URDF", crate::DUAL_ARM_URDF)?;
    m.add("DEFAULT_BUS_SIDE", crate::model::DEFAULT_BUS_SIDE)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<robot::PyRobot>()?;
    m.add_class::<joints::PyFlexibleJoints>()?;
    m.add_class::<control::PyMotorPD>()?;
    m.add_class::<control::PyAttitudePD>()?;
    m.add_class::<control::PySampled>()?;
    m.add_class::<arm::PyFlexibleArm>()?;
    m.add_class::<wheels::PyReactionWheels>()?;
    m.add_class::<trajectory::PyTrajectory>()?;
    m.add_class::<stability::PyStabilityLimit>()?;
    m.add_class::<plan::PyLimits>()?;
    m.add_class::<plan::PyPlan>()?;
    m.add_class::<batch::PyBatchTrajectory>()?;
    m.add_class::<simulator::PySimulator>()?;
    m.add_class::<capture::PyTarget>()?;
    m.add_class::<capture::PyCapture>()?;
    m.add_class::<capture_run::PyCaptureWhen>()?;
    m.add_class::<capture_run::PyCaptureEvent>()?;
    m.add_function(wrap_pyfunction!(capture::py_capture, m)?)?;
    m.add_function(wrap_pyfunction!(capture_run::py_capture_scenario, m)?)?;
    m.add_function(wrap_pyfunction!(capture_run::py_simulate_capture_batch, m)?)?;
    m.add_function(wrap_pyfunction!(plan::py_plan_slew, m)?)?;
    m.add_function(wrap_pyfunction!(batch::py_simulate_batch, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::py_state_space, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::py_modes, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::py_frequency_response, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::py_sweep, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::py_sampled_loop, m)?)?;
    m.add_function(wrap_pyfunction!(rotations::rotation_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(rotations::euler_zyx, m)?)?;
    m.add_function(wrap_pyfunction!(rotations::rotation_angle, m)?)?;
    m.add_function(wrap_pyfunction!(fmu::py_fmu_files, m)?)?;
    m.add_function(wrap_pyfunction!(control::py_quintic_reference, m)?)?;
    m.add_function(wrap_pyfunction!(control::py_quintic_profile, m)?)?;
    m.add_function(wrap_pyfunction!(memory::py_recorded_rows, m)?)?;
    m.add_function(wrap_pyfunction!(memory::py_run_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(memory::py_check_run_memory, m)?)?;
    m.add_function(wrap_pyfunction!(memory::available_memory, m)?)?;
    Ok(())
}

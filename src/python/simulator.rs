//! `orbitflex.Simulator`: a run stepped from Python ([`crate::Simulator`]).
//!
//! The simulator is mutable, so it sits behind a `Mutex` that is only ever *tried* (the rule of
//! `workspaces`): a second thread calling the same simulator while one steps it gets an error at
//! once, never a wait while it holds the GIL. Numbers are copied out of the lock before numpy
//! arrays are built, so no lock is held across a numpy call. `step(n)` releases the GIL for
//! long calls and looks for Ctrl-C as `simulate` does.

use super::arm::PyFlexibleArm;
use super::convert::{array1, positive_count, row_major, vector};
use super::errors::simulation_error;
use super::errors::ModelError;
use super::run::SIGNAL_CHECK;
use crate::error::Error;
use crate::integrate::{Observer, Outputs, Simulator};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use std::sync::{Mutex, MutexGuard, TryLockError};
use std::time::Instant;

/// Steps of one call from which `step` releases the GIL: below it, releasing and taking back
/// the GIL (a few µs) would cost more than it frees, and a Python loop of `step()` pays one
/// call's overhead per step.
const RELEASE_GIL_FROM: usize = 64;

/// How often (in steps) a long `step` looks at the clock (as `simulate` does).
const CLOCK_EVERY: usize = 16;

/// A flexible arm's run, stepped by the caller: the co-simulation building block.
///
/// ``Simulator(arm, x0, dt)`` starts at ``t = 0`` in state ``x0`` (13+4n; the quaternion is
/// normalised) with step ``dt`` (s) and every input zero.
///
/// ``step(u=None, base_wrench=None, ee_wrench=None, wheel_torque=None, n=1)`` takes ``n`` RK4
/// steps. Inputs are *held* (zero-order hold): an input given replaces the held one from this
/// step on; an input left ``None`` keeps its held value. ``u``: motor torques (n, N·m, link
/// side); ``base_wrench``: ``[moment; force]`` applied to the base, base frame;
/// ``ee_wrench``: 6 per end-effector (each in its EE frame, exerted by the EE on its
/// environment; a dict keyed by EE link names works too); ``wheel_torque``: the reaction-wheel
/// torque commands (k, N·m) of an arm with wheels, saturated at the start of each step as a run
/// saturates them.
///
/// A sequence of ``step`` calls gives, bit for bit, the states of ``arm.simulate`` with the same
/// inputs. A step that diverges is undone and raises ``SimulationError`` (``step``, ``time``;
/// the simulator keeps its last good state).
///
/// ``t``, ``x`` (copies), ``dt``, ``steps``, ``inputs`` (the held inputs), ``outputs()``
/// (q, qd, theta, theta_dot, deflection, spring_torque, base_pose, base_twist, ee_poses,
/// momentum, energy), ``save()`` → bytes and ``restore(blob)`` (bit-exact; the bytes carry a
/// format version and the arm's fingerprint: a blob of another arm is refused),
/// ``reset(x0)``.
///
/// Threads: one thread at a time. A call made while another thread is stepping the same
/// simulator raises ``RuntimeError`` at once (it never waits). ``step`` with ``n >= 64``
/// releases the GIL and stops on Ctrl-C (``KeyboardInterrupt``; the steps already taken are
/// kept).
#[pyclass(name = "Simulator", module = "orbitflex", frozen)]
pub struct PySimulator {
    sim: Mutex<Simulator>,
    arm: Py<PyFlexibleArm>,
}

impl PySimulator {
    /// The simulator, if no other thread is using it.
    fn lock(&self) -> PyResult<MutexGuard<'_, Simulator>> {
        match self.sim.try_lock() {
            Ok(guard) => Ok(guard),
            // a panic in a step left a valid simulator (a failed step is undone)
            Err(TryLockError::Poisoned(p)) => Ok(p.into_inner()),
            Err(TryLockError::WouldBlock) => Err(pyo3::exceptions::PyRuntimeError::new_err(
                "Simulator: another thread is using this simulator; call one simulator from one \
                 thread at a time (make one Simulator per thread)",
            )),
        }
    }
}

/// Looks for Ctrl-C every [`SIGNAL_CHECK`] while a long `step` runs without the GIL.
struct Signals {
    error: Option<PyErr>,
    last: Instant,
}

impl Observer for Signals {
    fn every(&self) -> usize {
        CLOCK_EVERY
    }
    fn observe(&mut self, _: usize, _: usize) -> bool {
        if self.last.elapsed() < SIGNAL_CHECK {
            return true;
        }
        self.last = Instant::now();
        Python::with_gil(|py| match py.check_signals() {
            Ok(()) => true,
            Err(e) => {
                self.error = Some(e);
                false
            }
        })
    }
}

/// The held inputs given to one `step`, parsed before the simulator is locked.
struct StepInputs {
    u: Option<Vec<f64>>,
    base_wrench: Option<Vec<f64>>,
    ee_wrench: Option<Vec<f64>>,
    wheel_torque: Option<Vec<f64>>,
}

impl StepInputs {
    /// The inputs given (None: keep the held one), in the order the messages report them: the
    /// wheel torques, the motor torques, the base wrench, the EE wrenches.
    fn parse(
        arm: &crate::FlexibleArm,
        u: Option<&Bound<'_, PyAny>>,
        base_wrench: Option<&Bound<'_, PyAny>>,
        ee_wrench: Option<&Bound<'_, PyAny>>,
        wheel_torque: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let robot = arm.robot();
        let given = |obj: Option<&Bound<'_, PyAny>>, what: &str, len: usize| {
            obj.filter(|o| !o.is_none())
                .map(|v| vector(v, what, Some(len)))
                .transpose()
        };
        let wheel_torque =
            match (wheel_torque.filter(|o| !o.is_none()), arm.layout().wheels) {
                (Some(_), 0) => return Err(ModelError::new_err(
                    "wheel_torque: the arm has no reaction wheels; pass None (or build the arm \
                     with wheels=)",
                )),
                (w, k) => given(w, "wheel_torque", k)?,
            };
        Ok(StepInputs {
            wheel_torque,
            u: given(u, "u", robot.dof())?,
            base_wrench: given(base_wrench, "base_wrench", 6)?,
            ee_wrench: match super::convert::ee_wrench_arg(robot, ee_wrench)? {
                Some(f) => Some(vector(
                    &f,
                    "ee_wrench",
                    Some(6 * robot.end_effectors().len()),
                )?),
                None => None,
            },
        })
    }

    /// Holds the inputs given from now on.
    fn hold(&self, sim: &mut Simulator) -> PyResult<()> {
        if let Some(u) = &self.u {
            sim.set_motor_torque(u)?;
        }
        if let Some(w) = &self.base_wrench {
            sim.set_base_wrench(w)?;
        }
        if let Some(f) = &self.ee_wrench {
            sim.set_ee_wrench(Some(f))?;
        }
        if let Some(w) = &self.wheel_torque {
            sim.set_wheel_torque(w)?;
        }
        Ok(())
    }
}

#[pymethods]
impl PySimulator {
    #[new]
    #[pyo3(signature = (arm, x0, dt))]
    fn new(arm: Bound<'_, PyFlexibleArm>, x0: &Bound<'_, PyAny>, dt: f64) -> PyResult<Self> {
        let flexible = arm.get().arm.clone();
        let x0 = vector(x0, "x0", Some(flexible.layout().len()))?;
        let sim = Simulator::new(flexible, &x0, dt)?;
        Ok(Self {
            sim: Mutex::new(sim),
            arm: arm.unbind(),
        })
    }

    /// Takes ``n`` RK4 steps with the held inputs, after replacing those given (see the class).
    #[pyo3(signature = (u=None, base_wrench=None, ee_wrench=None, wheel_torque=None, n=None))]
    fn step(
        &self,
        py: Python<'_>,
        u: Option<&Bound<'_, PyAny>>,
        base_wrench: Option<&Bound<'_, PyAny>>,
        ee_wrench: Option<&Bound<'_, PyAny>>,
        wheel_torque: Option<&Bound<'_, PyAny>>,
        n: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let n = match n {
            Some(n) => positive_count(n, "n")?,
            None => 1,
        };
        let arm = &self.arm.bind(py).get().arm;
        let inputs = StepInputs::parse(arm, u, base_wrench, ee_wrench, wheel_torque)?;
        let mut sim = self.lock()?;
        inputs.hold(&mut sim)?;
        let mut signals = Signals {
            error: None,
            last: Instant::now(),
        };
        let outcome = if n < RELEASE_GIL_FROM {
            sim.step(n)
        } else {
            let sim = &mut *sim;
            py.allow_threads(|| sim.step_observed(n, &mut signals))
        };
        drop(sim);
        match (signals.error, outcome) {
            (Some(e), _) => Err(e),
            (None, Ok(())) => Ok(()),
            (
                None,
                Err(Error::Simulation {
                    step,
                    time,
                    message,
                }),
            ) => {
                let text = Error::Simulation {
                    step,
                    time,
                    message,
                }
                .to_string();
                Err(simulation_error(py, text, step, time, py.None(), None)?)
            }
            (None, Err(e)) => Err(e.into()),
        }
    }

    /// Time ``t = k dt`` (s), from the step count (no accumulated round-off).
    #[getter]
    fn t(&self) -> PyResult<f64> {
        Ok(self.lock()?.t())
    }

    /// A copy of the state (13+4n).
    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let x = self.lock()?.state().to_vec();
        Ok(PyArray1::from_vec(py, x))
    }

    /// The step dt (s).
    #[getter]
    fn dt(&self) -> PyResult<f64> {
        Ok(self.lock()?.dt())
    }

    /// Steps taken since the start (or the last ``reset``).
    #[getter]
    fn steps(&self) -> PyResult<u64> {
        Ok(self.lock()?.steps())
    }

    /// The arm.
    #[getter]
    fn arm(&self, py: Python<'_>) -> Py<PyFlexibleArm> {
        self.arm.clone_ref(py)
    }

    /// The held inputs: ``{"u": (n,), "base_wrench": (6,), "ee_wrench": (6k,) or None}``.
    #[getter]
    fn inputs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (u, base, ee) = {
            let sim = self.lock()?;
            let ee = sim.ee_wrench();
            (
                sim.motor_torque().to_vec(),
                sim.base_wrench().to_vec(),
                (!ee.is_empty()).then(|| ee.to_vec()),
            )
        };
        let out = PyDict::new(py);
        out.set_item("u", PyArray1::from_vec(py, u))?;
        out.set_item("base_wrench", PyArray1::from_vec(py, base))?;
        out.set_item("ee_wrench", ee.map(|f| PyArray1::from_vec(py, f)))?;
        Ok(out)
    }

    /// The outputs at the current state, as a dict of new arrays: ``q``, ``qd``, ``theta``,
    /// ``theta_dot``, ``deflection`` (θ − q), ``spring_torque`` (N·m) (each (n,)),
    /// ``base_pose`` (7: position, quaternion x, y, z, w), ``base_twist`` (6: ω_B, v_B, base
    /// frame), ``ee_poses`` ((k, 7), inertial frame, ``robot.ee_links`` order), ``momentum``
    /// (6: angular, linear; inertial frame, about the origin), ``energy`` (J); with reaction
    /// wheels also ``wheel_speed`` (k, rad/s, relative to the bus) and
    /// ``applied_wheel_torque`` (k, N·m: the torques the wheel motors applied over the last
    /// step, after the limits; zero before the first step).
    fn outputs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out: Outputs = self.lock()?.outputs();
        let dict = PyDict::new(py);
        for (name, values) in [
            ("q", &out.q),
            ("qd", &out.qd),
            ("theta", &out.theta),
            ("theta_dot", &out.theta_dot),
            ("deflection", &out.deflection),
            ("spring_torque", &out.spring_torque),
        ] {
            dict.set_item(name, array1(py, values))?;
        }
        dict.set_item("base_pose", array1(py, &out.base_pose))?;
        dict.set_item("base_twist", array1(py, &out.base_twist))?;
        let k = out.ee_poses.len() / 7;
        dict.set_item("ee_poses", row_major(py, k, 7, out.ee_poses))?;
        dict.set_item("momentum", array1(py, &out.momentum))?;
        dict.set_item("energy", out.energy)?;
        if !out.wheel_speed.is_empty() {
            dict.set_item("wheel_speed", array1(py, &out.wheel_speed))?;
            dict.set_item(
                "applied_wheel_torque",
                array1(py, &out.applied_wheel_torque),
            )?;
        }
        Ok(dict)
    }

    /// The simulator's state as bytes (state, time, held inputs; a format version and the
    /// arm's fingerprint). ``restore`` puts it back bit for bit.
    fn save<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let blob = self.lock()?.save();
        Ok(PyBytes::new(py, &blob))
    }

    /// Puts back a state from ``save`` of a simulator of the same arm and dt. A blob of another
    /// arm, another format version, or damaged, raises ``ModelError`` and changes nothing.
    fn restore(&self, blob: &[u8]) -> PyResult<()> {
        Ok(self.lock()?.restore(blob)?)
    }

    /// Back to ``t = 0`` at state ``x0``, every input zero.
    fn reset(&self, x0: &Bound<'_, PyAny>) -> PyResult<()> {
        let len = self.lock()?.state().len();
        let x0 = vector(x0, "x0", Some(len))?;
        Ok(self.lock()?.reset(&x0)?)
    }

    fn __repr__(&self) -> PyResult<String> {
        let sim = self.lock()?;
        Ok(format!(
            "Simulator(n={}, dt={:e} s, t={} s, steps={})",
            sim.arm().dof(),
            sim.dt(),
            sim.t(),
            sim.steps()
        ))
    }
}

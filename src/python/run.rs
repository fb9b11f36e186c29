//! Running a simulation from Python: without the GIL when the controller is Rust, with it when
//! it is a Python callable; honouring Ctrl-C and reporting progress either way.

use super::control::{base_wrench_controller, controller, schedule, wheel_controller};
use super::convert::row_major;
use crate::control::{Controller, Schedule};
use crate::error::Error;
use crate::flex::{FlexibleArm, StateLayout};
use crate::integrate::{
    self, Chunk, Chunks, Drive, Observer, Recorder, Run, SimulationFailure, Trajectory,
};
use numpy::PyArray1;
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// How often (in steps) a run reports progress.
const EVERY: usize = 1024;

/// How often a computation without the GIL looks for Ctrl-C: well within the half second a
/// user waits for a stop. Taking the GIL for it costs microseconds.
pub(crate) const SIGNAL_CHECK: Duration = Duration::from_millis(50);

/// How often (in steps) a run looks at the clock to see whether [`SIGNAL_CHECK`] has passed:
/// a step of a large model takes a millisecond, so [`EVERY`] steps would be too long to wait.
const CLOCK_EVERY: usize = 16;

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

    /// The `progress` argument of a run: a callable, or None (no reports).
    pub fn from_arg(progress: Option<&Bound<'_, PyAny>>) -> Self {
        Self::new(progress.filter(|p| !p.is_none()).cloned())
    }

    pub(crate) fn report(&self, py: Python<'_>, done: usize, steps: usize) -> PyResult<()> {
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

/// Warns `message` as a `RuntimeWarning` (a step past the RK4 stability limit, an unstable
/// sampled loop), at the caller's line.
pub(crate) fn runtime_warning(py: Python<'_>, message: String) -> PyResult<()> {
    PyErr::warn(
        py,
        &py.get_type::<pyo3::exceptions::PyRuntimeWarning>(),
        &std::ffi::CString::new(message).expect("no NUL in the message"),
        1,
    )
}

/// Looks for signals every [`SIGNAL_CHECK`] and reports progress every [`EVERY`] steps, taking
/// the GIL back for it; the first Python error (a `KeyboardInterrupt`, or an exception from the
/// progress callback) stops the run.
pub(crate) struct Watch<'a> {
    progress: &'a Progress,
    pub(crate) error: Option<PyErr>,
    last: Instant,
}

impl<'a> Watch<'a> {
    pub(crate) fn new(progress: &'a Progress) -> Self {
        Self {
            progress,
            error: None,
            last: Instant::now(),
        }
    }

    fn check(&mut self, py: Python<'_>, step: usize, steps: usize) -> bool {
        let report = step % EVERY == 0;
        match py.check_signals().and_then(|_| match report {
            true => self.progress.report(py, step, steps),
            false => Ok(()),
        }) {
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
        CLOCK_EVERY
    }
    fn observe(&mut self, step: usize, steps: usize) -> bool {
        if step % EVERY != 0 && self.last.elapsed() < SIGNAL_CHECK {
            return true;
        }
        self.last = Instant::now();
        Python::with_gil(|py| self.check(py, step, steps))
    }
}

/// Runs `work` without the GIL on a scoped thread of its own while this thread, every
/// [`SIGNAL_CHECK`], takes the GIL back to look for signals and to call `tick` (progress
/// reports). The first exception (a `KeyboardInterrupt` for Ctrl-C, or one from `tick`) sets
/// `cancel`, which `work` must poll (between runs or steps), and is raised once `work` has
/// returned. For long work: starting the thread and waking this one cost tens of µs (batched
/// per-call rows use `parallel::compute_rows` instead).
pub(crate) fn watched<R: Send>(
    py: Python<'_>,
    cancel: &AtomicBool,
    mut tick: impl FnMut(Python<'_>) -> PyResult<()> + Send,
    work: impl FnOnce() -> R + Send,
) -> PyResult<R> {
    let mut raised: Option<PyErr> = None;
    let result = py.allow_threads(|| {
        let (done, finished) = mpsc::channel::<R>();
        let mut poll = |raised: &mut Option<PyErr>| loop {
            match finished.recv_timeout(SIGNAL_CHECK) {
                Ok(result) => return Some(result),
                Err(mpsc::RecvTimeoutError::Timeout) if raised.is_none() => {
                    Python::with_gil(|py| {
                        if let Err(e) = py.check_signals().and_then(|_| tick(py)) {
                            *raised = Some(e);
                            cancel.store(true, Ordering::Relaxed);
                        }
                    });
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                // `work` panicked: the scope re-raises the panic
                Err(mpsc::RecvTimeoutError::Disconnected) => return None,
            }
        };
        std::thread::scope(|scope| {
            scope.spawn(move || {
                let _ = done.send(work());
            });
            poll(&mut raised)
        })
    });
    match (raised, result) {
        (Some(e), _) => Err(e),
        (None, Some(result)) => Ok(result),
        (None, None) => unreachable!("a panic in `work` is raised by its scope"),
    }
}

type RunResult = Result<Trajectory, Box<SimulationFailure>>;

/// The channels of a run from Python, owned and `Send`, so that the run can leave the GIL (a
/// Python callable takes it back for each of its calls).
pub(crate) struct Channels<'a> {
    /// The motor torques.
    pub u: Box<dyn Controller + Send + 'a>,
    /// The base wrench.
    pub base_wrench: Box<dyn Controller + Send + 'a>,
    /// The end-effector wrenches.
    pub ee_wrench: Schedule,
    /// The reaction-wheel torque commands.
    pub wheel_torque: Box<dyn Controller + Send + 'a>,
}

/// The first exception of each callable channel of a run, one slot per channel.
#[derive(Default)]
pub(crate) struct ChannelErrors {
    u: Option<PyErr>,
    wheel_torque: Option<PyErr>,
    base_wrench: Option<PyErr>,
}

impl ChannelErrors {
    /// The exception that stopped the run: the motors', else the wheels', else the base
    /// wrench's.
    pub fn first(self) -> Option<PyErr> {
        self.u.or(self.wheel_torque).or(self.base_wrench)
    }
}

impl<'a> Channels<'a> {
    /// The channels of ``FlexibleArm.simulate``'s arguments, read in this order (the first bad
    /// argument is the one reported): the base wrench, the EE wrenches, the wheel torques, the
    /// motor torques. A callable channel's exception goes to its slot of `errors`.
    pub fn from_args(
        arm: &FlexibleArm,
        u: Option<&Bound<'_, PyAny>>,
        base_wrench: Option<&Bound<'_, PyAny>>,
        ee_wrench: Option<&Bound<'_, PyAny>>,
        wheel_torque: Option<&Bound<'_, PyAny>>,
        errors: &'a mut ChannelErrors,
    ) -> PyResult<Self> {
        let ChannelErrors {
            u: u_error,
            wheel_torque: wheel_error,
            base_wrench: base_error,
        } = errors;
        let robot = arm.robot();
        Ok(Channels {
            base_wrench: base_wrench_controller(base_wrench, base_error)?,
            ee_wrench: schedule(
                super::convert::ee_wrench_arg(robot, ee_wrench)?.as_ref(),
                "ee_wrench",
                6 * robot.end_effectors().len(),
            )?,
            wheel_torque: wheel_controller(wheel_torque, arm, wheel_error)?,
            u: controller(u, arm.dof(), u_error)?,
        })
    }
}

impl Channels<'_> {
    /// The channels as the [`Drive`] of a run.
    pub fn drive(&mut self) -> Drive<'_> {
        Drive {
            u: &mut *self.u,
            base_wrench: &mut *self.base_wrench,
            ee_wrench: &mut self.ee_wrench,
            wheel_torque: &mut *self.wheel_torque,
        }
    }
}

/// [`integrate::simulate()`] without the GIL. A pending `KeyboardInterrupt` (or an exception from
/// the progress callback) stops the run and is raised as it is.
pub(crate) fn run_releasing_gil(
    py: Python<'_>,
    arm: &FlexibleArm,
    run: &Run<'_>,
    channels: &mut Channels<'_>,
    progress: &mut Progress,
) -> PyResult<RunResult> {
    let mut watch = Watch::new(progress);
    let result =
        py.allow_threads(|| integrate::simulate(arm, run, &mut channels.drive(), &mut watch));
    match watch.error {
        Some(e) => Err(e),
        None => Ok(result),
    }
}

/// [`integrate::simulate_into()`] without the GIL. A pending `KeyboardInterrupt` (or an
/// exception from the progress callback) stops the run and is raised as it is.
pub(crate) fn record_releasing_gil(
    py: Python<'_>,
    arm: &FlexibleArm,
    run: &Run<'_>,
    channels: &mut Channels<'_>,
    progress: &mut Progress,
    recorder: &mut (dyn Recorder + Send),
) -> PyResult<crate::Result<()>> {
    let mut watch = Watch::new(progress);
    let result = py.allow_threads(|| {
        integrate::simulate_into(arm, run, &mut channels.drive(), &mut watch, recorder)
    });
    match watch.error {
        Some(e) => Err(e),
        None => Ok(result),
    }
}

/// Delivers one chunk to the Python callable `on_rows(t, x, u)` as new numpy arrays, taking the
/// GIL back for it; the callable's exception is kept in `error` (and stops the run).
pub(crate) fn deliver(
    callback: &Py<PyAny>,
    chunk: Chunk<'_>,
    error: &mut Option<PyErr>,
) -> crate::Result<()> {
    Python::with_gil(|py| {
        let layout = chunk.layout;
        let t = PyArray1::from_slice(py, chunk.t);
        let x = row_major(py, chunk.len(), layout.len(), chunk.x.to_vec());
        let u = row_major(py, chunk.inputs, layout.inputs_len(), chunk.u.to_vec());
        callback.call1(py, (t, x, u)).map(drop)
    })
    .map_err(|e| {
        let message = format!("on_rows raised {e}");
        *error = Some(e);
        Error::InvalidArgument {
            what: "on_rows".into(),
            message,
        }
    })
}

/// Streams the kept rows in chunks and keeps only the last row (the final state of the run, or
/// the last good state of a failed one).
pub(crate) struct Stream<F> {
    chunks: Chunks<F>,
    last: Trajectory,
}

impl<F: FnMut(Chunk<'_>) -> crate::Result<()>> Stream<F> {
    pub fn new(layout: StateLayout, chunks: Chunks<F>) -> Self {
        let last = Trajectory {
            t: vec![0.0],
            x: vec![0.0; layout.len()],
            u: Vec::new(),
            layout,
        };
        Self { chunks, last }
    }

    /// The last row recorded, as a one-row record (empty if none was).
    pub fn last_row(self) -> Trajectory {
        if self.chunks.received() == 0 {
            Trajectory::empty(self.last.layout)
        } else {
            self.last
        }
    }
}

impl<F: FnMut(Chunk<'_>) -> crate::Result<()>> Recorder for Stream<F> {
    fn state(&mut self, t: f64, x: &[f64]) -> crate::Result<()> {
        self.last.t[0] = t;
        self.last.x.copy_from_slice(x);
        self.chunks.state(t, x)
    }
    fn input(&mut self, u: &[f64]) -> crate::Result<()> {
        self.chunks.input(u)
    }
    fn finish(&mut self) -> crate::Result<()> {
        self.chunks.finish()
    }
}

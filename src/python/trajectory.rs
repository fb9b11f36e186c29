//! `orbitflex.Trajectory`: the record of a run, its views and its diagnostics.

use super::arm::PyFlexibleArm;
use super::convert::{matrix, row_major, vector};
use super::errors::ModelError;
use super::state_columns::{state_getters, StateRecord};
use crate::flex::StateLayout;
use crate::integrate::{StateRows, Trajectory};
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyMemoryError;
use pyo3::prelude::*;
use pyo3::sync::GILOnceCell;
use pyo3::types::PyDict;
use std::io::Write;

/// About how many numbers a diagnostic computes between two looks for Ctrl-C.
const CHUNK_NUMBERS: usize = 1 << 16;

/// The record of a run: ``t`` (k,), ``x`` (k, 13+4n) and ``u`` (k-1, n), k = steps + 1 for a
/// complete run. The arrays are read-only.
///
/// Views of ``x`` (no copy): ``base_pose`` (k, 7) ``[r_B; quat (x, y, z, w)]``, ``q``, ``theta``
/// (rad), ``base_twist`` (k, 6) ``[ω_B; v_B]`` in base-frame components, ``qd``, ``theta_dot``
/// (rad/s). ``u`` holds the motor torques (N·m, link side) applied during each step.
///
/// Diagnostics, computed in Rust from the stored rows: ``deflection`` ``θ − q`` (rad),
/// ``spring_torque`` ``k (θ − q) + d (θ̇ − q̇)`` (N·m), and, computed once on first access,
/// ``momentum`` (k, 6) ``[angular (N·m·s) about the inertial origin; linear (N·s)]`` in the
/// inertial frame, ``energy`` (k,) in J (rigid kinetic + motor kinetic + spring), ``ee_pose``
/// (k, 7) ``[position (m); quat (x, y, z, w)]`` in the inertial frame ((k, e, 7) for a robot with
/// ``e`` end-effectors).
#[pyclass(name = "Trajectory", module = "orbitflex", frozen)]
pub struct PyTrajectory {
    arm: Py<PyFlexibleArm>,
    t: Py<PyArray1<f64>>,
    x: Py<PyArray2<f64>>,
    u: Py<PyArray2<f64>>,
    layout: StateLayout,
    momentum: GILOnceCell<Py<PyArray2<f64>>>,
    energy: GILOnceCell<Py<PyArray1<f64>>>,
    ee_pose: GILOnceCell<Py<PyArray2<f64>>>,
    /// A run with a target: its rows, events and combined arm.
    capture: Option<super::capture_run::CaptureInfo>,
}

/// A read-only 2-D array that takes over `values` (no copy).
pub(crate) fn frozen_rows(
    py: Python<'_>,
    rows: usize,
    cols: usize,
    values: Vec<f64>,
) -> PyResult<Py<PyArray2<f64>>> {
    let array = row_major(py, rows, cols, values);
    freeze(array.as_any())?;
    Ok(array.unbind())
}

/// Makes a numpy array read-only.
pub(crate) fn freeze(array: &Bound<'_, PyAny>) -> PyResult<()> {
    let kwargs = PyDict::new(array.py());
    kwargs.set_item("write", false)?;
    array.call_method("setflags", (), Some(&kwargs))?;
    Ok(())
}

impl PyTrajectory {
    /// Wraps a run's record; the vectors become numpy arrays without a copy.
    pub(crate) fn from_run(
        py: Python<'_>,
        arm: Py<PyFlexibleArm>,
        traj: Trajectory,
    ) -> PyResult<Self> {
        let layout = traj.layout;
        let rows = traj.len();
        let t = PyArray1::from_vec(py, traj.t);
        freeze(t.as_any())?;
        let steps = traj
            .u
            .len()
            .checked_div(layout.inputs_len())
            .unwrap_or(rows.saturating_sub(1));
        Ok(Self {
            arm,
            t: t.unbind(),
            x: frozen_rows(py, rows, layout.len(), traj.x)?,
            u: frozen_rows(py, steps, layout.inputs_len(), traj.u)?,
            layout,
            momentum: GILOnceCell::new(),
            energy: GILOnceCell::new(),
            ee_pose: GILOnceCell::new(),
            capture: None,
        })
    }

    /// The record of a run with a target: its target rows, events and combined arm.
    pub(crate) fn with_capture(mut self, info: super::capture_run::CaptureInfo) -> Self {
        self.capture = Some(info);
        self
    }

    /// The total momentum (6 per row) or energy (1 per row) of a run with a target, `None`
    /// for a run without one.
    fn with_target(&self, py: Python<'_>, momentum: bool) -> PyResult<Option<Vec<f64>>> {
        let Some(info) = &self.capture else {
            return Ok(None);
        };
        let t = self.t.bind(py).readonly();
        let x = self.x.bind(py).readonly();
        let (t, x) = (t.as_slice()?, x.as_slice()?);
        let arm = &self.arm.get().arm;
        Ok(Some(py.allow_threads(|| match momentum {
            true => info.record.momentum(arm, t, x),
            false => info.record.energy(arm, t, x),
        })))
    }

    /// A diagnostic of `per_row` numbers per stored row, computed without the GIL by `f` over
    /// a range of rows ([`Self::in_chunks`]).
    /// The record as a Rust [`crate::Trajectory`] (a copy), for the analyses that need rows and
    /// inputs together; refused for a run with a target (its energy is not the arm's alone).
    fn record(&self, py: Python<'_>) -> PyResult<crate::Trajectory> {
        if self.capture.is_some() {
            return Err(super::errors::ModelError::new_err(
                "energy balance: a run with a target exchanges energy with it; not available",
            ));
        }
        let t = self.t.bind(py).readonly();
        let x = self.x.bind(py).readonly();
        let u = self.u.bind(py).readonly();
        Ok(crate::Trajectory {
            t: t.as_slice()?.to_vec(),
            x: x.as_slice()?.to_vec(),
            u: u.as_slice()?.to_vec(),
            layout: self.layout,
        })
    }

    fn along(
        &self,
        py: Python<'_>,
        per_row: usize,
        f: impl Fn(&crate::FlexibleArm, StateRows<'_>) -> Vec<f64> + Sync,
    ) -> PyResult<Vec<f64>> {
        let x = self.x.bind(py).readonly();
        let all = StateRows {
            layout: self.layout,
            x: x.as_slice()?,
        };
        let width = self.layout.len();
        let arm = &self.arm.get().arm;
        self.in_chunks(py, all.len(), per_row, |rows| {
            let x = &all.x[rows.start * width..rows.end * width];
            f(arm, StateRows { x, ..all })
        })
    }

    /// `per_item` numbers for each of `items` items, computed by `f` over ranges of items
    /// without the GIL, a few thousand numbers at a time (a millisecond or so), looking for
    /// Ctrl-C between them. The result is allocated once, fallibly: a result too large for
    /// memory is a `MemoryError`, not an abort.
    fn in_chunks(
        &self,
        py: Python<'_>,
        items: usize,
        per_item: usize,
        f: impl Fn(std::ops::Range<usize>) -> Vec<f64> + Sync,
    ) -> PyResult<Vec<f64>> {
        let total = items.checked_mul(per_item);
        let mut out = Vec::new();
        if total.map_or(true, |t| out.try_reserve_exact(t).is_err()) {
            return Err(PyMemoryError::new_err(format!(
                "the result, {items} rows of {per_item} numbers, needs {}, which could not be \
                 allocated; ask for fewer rows",
                crate::args::describe_bytes(total.and_then(|t| t.checked_mul(8)))
            )));
        }
        // a row costs about as much as it has numbers, in and out
        let chunk = (CHUNK_NUMBERS / per_item.max(self.layout.len())).max(1);
        for start in (0..items).step_by(chunk) {
            py.check_signals()?;
            let rows = start..(start + chunk).min(items);
            out.extend(py.allow_threads(|| f(rows)));
        }
        Ok(out)
    }

    fn rows(&self, py: Python<'_>) -> usize {
        self.t.bind(py).len()
    }
}

impl StateRecord for PyTrajectory {
    fn layout(&self) -> StateLayout {
        self.layout
    }
    fn states<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        self.x.bind(py).clone().into_any()
    }
    fn inputs<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        self.u.bind(py).clone().into_any()
    }
}

state_getters!(
    PyTrajectory,
    rows: "k",
    u: "Motor torques (N·m, link side) held during each step, shape (k-1, n).",
    wheel_torque: "Reaction-wheel torques applied during each step, after saturation (N·m, on each \
                   wheel about its axis), shape (k-1, w); (k-1, 0) without wheels."
);

#[pymethods]
impl PyTrajectory {
    /// Rebuilds a record from its arrays (as pickling does): ``t`` (k,), ``x`` (k, 13+4n+w),
    /// ``u`` (k-1, n) and, for an arm with w reaction wheels, ``wheel_torque`` (k-1, w). The
    /// arrays are copied, and checked: finite numbers, and each row of ``x`` a valid state (a
    /// quaternion of non-zero norm).
    #[new]
    #[pyo3(signature = (arm, t, x, u, wheel_torque=None))]
    fn new(
        py: Python<'_>,
        arm: Py<PyFlexibleArm>,
        t: &Bound<'_, PyAny>,
        x: &Bound<'_, PyAny>,
        u: &Bound<'_, PyAny>,
        wheel_torque: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let layout = arm.get().arm.layout();
        let t = vector(t, "t", None)?;
        let (rows, x) = matrix(x, "x", layout.len())?;
        let (steps, mut u) = matrix(u, "u", layout.n)?;
        match (wheel_torque.filter(|o| !o.is_none()), layout.wheels) {
            (None, 0) => {}
            (Some(_), 0) => {
                return Err(ModelError::new_err(
                    "wheel_torque: the arm has no reaction wheels; give none",
                ))
            }
            (None, k) => {
                return Err(ModelError::new_err(format!(
                    "wheel_torque: the arm has {k} reaction wheels; give their applied torques \
                     (k-1, {k})"
                )))
            }
            (Some(w), k) => {
                let (wheel_steps, w) = matrix(w, "wheel_torque", k)?;
                if wheel_steps != steps {
                    return Err(ModelError::new_err(format!(
                        "wheel_torque: expected {steps} rows (as u), given {wheel_steps}"
                    )));
                }
                let n = layout.n;
                u = (0..steps)
                    .flat_map(|r| u[r * n..(r + 1) * n].iter().chain(&w[r * k..(r + 1) * k]))
                    .copied()
                    .collect();
            }
        }
        if rows != t.len() || steps != rows.saturating_sub(1) {
            return Err(ModelError::new_err(format!(
                "Trajectory: expected t (k,), x (k, {}) and u (k-1, {}), given {} times, {rows} \
                 states and {steps} inputs",
                layout.len(),
                layout.n,
                t.len()
            )));
        }
        for (k, row) in x.chunks_exact(layout.len()).enumerate() {
            arm.get()
                .arm
                .check_state(row)
                .map_err(|e| ModelError::new_err(format!("x[{k}]: {e}")))?;
        }
        let traj = Trajectory { t, x, u, layout };
        Self::from_run(py, arm, traj)
    }

    /// The arm that made the run.
    #[getter]
    fn arm(&self, py: Python<'_>) -> Py<PyFlexibleArm> {
        self.arm.clone_ref(py)
    }
    /// The target's state ``[r_t; quat_t (x, y, z, w); ω; v]`` at each row, (k, 13), in a run
    /// with a target (``None`` otherwise): the free body before the capture, then the body
    /// welded to the end-effector.
    #[getter]
    fn target(&self, py: Python<'_>) -> Option<Py<PyArray2<f64>>> {
        self.capture.as_ref().map(|c| c.target.clone_ref(py))
    }
    /// What happened in the run: a list of :class:`CaptureEvent` (empty for a run without one).
    #[getter]
    fn events<'py>(&self, py: Python<'py>) -> Bound<'py, pyo3::types::PyList> {
        match &self.capture {
            Some(c) => c.events.bind(py).clone(),
            None => pyo3::types::PyList::empty(py),
        }
    }
    /// The run's :class:`Target` at ``t = 0`` (mass, inertia, handle) in a run with a target,
    /// ``None`` otherwise.
    #[getter]
    fn target_body(&self, py: Python<'_>) -> Option<Py<super::capture::PyTarget>> {
        self.capture.as_ref().map(|c| c.body.clone_ref(py))
    }
    /// The combined arm (the target a payload of the EE) after a capture; ``None`` before or
    /// without one. The rows after the capture are states of this arm.
    #[getter]
    fn arm_after(&self, py: Python<'_>) -> Option<Py<PyFlexibleArm>> {
        self.capture
            .as_ref()
            .and_then(|c| c.arm_after.as_ref().map(|a| a.clone_ref(py)))
    }
    /// Times (s), shape (k,).
    #[getter]
    fn t(&self, py: Python<'_>) -> Py<PyArray1<f64>> {
        self.t.clone_ref(py)
    }
    /// States, shape (k, 13+4n): ``[r_B | quat_B | q | θ | ω_B | v_B | q̇ | θ̇]`` per row.
    #[getter]
    fn x(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.x.clone_ref(py)
    }
    /// Joint deflection ``θ − q`` (rad), (k, n).
    #[getter]
    fn deflection<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let values = self.along(py, self.layout.n, |_, rows| rows.deflection())?;
        Ok(row_major(py, self.rows(py), self.layout.n, values))
    }
    /// Spring torques ``k (θ − q) + d (θ̇ − q̇)`` (N·m), (k, n).
    #[getter]
    fn spring_torque<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let values = self.along(py, self.layout.n, |arm, rows| rows.spring_torque(arm))?;
        Ok(row_major(py, self.rows(py), self.layout.n, values))
    }
    /// Total momentum ``[angular (N·m·s); linear (N·s)]`` of base and links, inertial frame,
    /// about the inertial origin, (k, 6). In a run with a target, the target's is included: the
    /// free target's before the capture, the combined arm's after it.
    #[getter]
    fn momentum(&self, py: Python<'_>) -> PyResult<Py<PyArray2<f64>>> {
        self.momentum
            .get_or_try_init(py, || {
                let values = match self.with_target(py, true)? {
                    Some(values) => values,
                    None => self.along(py, 6, |arm, rows| rows.momentum(arm))?,
                };
                frozen_rows(py, self.rows(py), 6, values)
            })
            .map(|a| a.clone_ref(py))
    }
    /// Each step's energy flows (J), (steps, 3): the change of the arm's energy ``E(t_{k+1}) −
    /// E(t_k)``, the motors' work (trapezoid rule on ``u·θ̇``) and the energy the joint and motor
    /// damping dissipated (trapezoid rule on ``Σ d (θ̇ − q̇)² + β θ̇²``), for the steps whose torque
    /// the record holds. Needs every step recorded (``record_every=1``); not for runs with a
    /// target.
    fn energy_steps<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let steps = self.record(py)?.energy_steps(&self.arm.get().arm)?;
        let rows = steps.len();
        let values = steps.into_iter().flatten().collect();
        Ok(row_major(py, rows, 3, values).into_any())
    }

    /// ``(E(T) − E(0), motor work, dissipated)`` (J) over the steps whose torque the record
    /// holds (:meth:`energy_steps`, the works summed in step order with compensation); the
    /// residual ``E(T) − E(0) − (work − dissipated)`` is the quadrature's error, O(dt²).
    fn energy_balance(&self, py: Python<'_>) -> PyResult<(f64, f64, f64)> {
        let b = self.record(py)?.energy_balance(&self.arm.get().arm)?;
        Ok((b.change, b.motor_work, b.dissipated))
    }

    /// Total energy (J): rigid kinetic + motor kinetic + spring, (k,). In a run with a target,
    /// plus the free target's kinetic energy before the capture (the combined arm's after).
    #[getter]
    fn energy(&self, py: Python<'_>) -> PyResult<Py<PyArray1<f64>>> {
        self.energy
            .get_or_try_init(py, || {
                let values = match self.with_target(py, false)? {
                    Some(values) => values,
                    None => self.along(py, 1, |arm, rows| rows.energy(arm))?,
                };
                let array = PyArray1::from_vec(py, values);
                freeze(array.as_any())?;
                Ok::<_, PyErr>(array.unbind())
            })
            .map(|a| a.clone_ref(py))
    }
    /// EE ``[position (m); quat (x, y, z, w), w ≥ 0]`` in the inertial frame: (rows, 7) for a
    /// robot with one end-effector, (rows, k, 7) for ``k`` end-effectors in ``robot.ee_links``
    /// order.
    #[getter]
    fn ee_pose(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let k = self.arm.get().arm.robot().end_effectors().len();
        let flat = self
            .ee_pose
            .get_or_try_init(py, || {
                let values = self.along(py, 7 * k, |arm, rows| rows.ee_pose(arm))?;
                frozen_rows(py, self.rows(py), 7 * k, values)
            })?
            .clone_ref(py);
        if k == 1 {
            return Ok(flat.into_any());
        }
        let rows = flat.bind(py).shape()[0];
        Ok(flat.bind(py).reshape([rows, k, 7])?.into_any().unbind())
    }

    /// Inertial poses of every frame of ``arm.robot.frame_names`` at every row, shape
    /// ``(k, len(frame_names), 7)``: ``[position (m); quat (x, y, z, w), w ≥ 0]``, computed in
    /// Rust without the GIL (one workspace for all rows).
    ///
    /// ``motor_side=None`` poses the links at ``q``; ``motor_side=s`` poses them at
    /// ``q + s (θ − q)``: the motor side (the "ghost" arm) for ``s = 1``, the deflection drawn
    /// ``s`` times larger beyond it. ``rows`` (a sequence of row indices) computes only those
    /// rows, in that order: shape ``(len(rows), len(frame_names), 7)``.
    #[pyo3(signature = (motor_side=None, rows=None))]
    fn frame_poses<'py>(
        &self,
        py: Python<'py>,
        motor_side: Option<f64>,
        rows: Option<Vec<i64>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        if let Some(s) = motor_side {
            crate::args::check_finite("motor_side", &[s])?;
        }
        let frames = self.arm.get().arm.robot().frames().len();
        let len = self.rows(py);
        let rows: Vec<usize> = match rows {
            None => (0..len).collect(),
            Some(rows) => rows
                .iter()
                .enumerate()
                .map(|(k, &r)| {
                    usize::try_from(r).ok().filter(|&r| r < len).ok_or_else(|| {
                        ModelError::new_err(format!(
                            "rows[{k}]: expected a row index in 0..{len}, given {r}"
                        ))
                    })
                })
                .collect::<PyResult<_>>()?,
        };
        let count = rows.len();
        let x = self.x.bind(py).readonly();
        let all = StateRows {
            layout: self.layout,
            x: x.as_slice()?,
        };
        let arm = &self.arm.get().arm;
        let values = self.in_chunks(py, count, 7 * frames, |range| {
            all.frame_poses_at(arm, motor_side, &rows[range])
        })?;
        Ok(numpy::PyArray1::from_vec(py, values)
            .reshape([count, frames, 7])?
            .into_any())
    }

    /// Writes this run as one self-contained HTML animation (``orbitflex.viz.write_animation``)
    /// and returns its path: the bus, the links, the EE trail and the inertial axes, played
    /// with play/pause, a time slider and speeds; offline, paused at ``t = 0`` (``#t=SECONDS``
    /// in the URL opens it at that time). ``fps`` frames per second of simulated time are kept;
    /// ``ghost=True`` (or a factor) also draws the motor-side arm, its deflection exaggerated;
    /// ``packages`` maps ROS package names to directories for ``package://`` meshes; ``shapes``
    /// adds shapes (dicts like ``Robot.scene``'s). Needs ``pip install 'orbitflex[viz]'``.
    #[pyo3(signature = (path, fps=30.0, ghost=None, packages=None, title=None, shapes=None))]
    fn animate<'py>(
        slf: &Bound<'py, Self>,
        path: &Bound<'py, PyAny>,
        fps: f64,
        ghost: Option<&Bound<'py, PyAny>>,
        packages: Option<&Bound<'py, PyAny>>,
        title: Option<&str>,
        shapes: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let py = slf.py();
        let kwargs = PyDict::new(py);
        kwargs.set_item("fps", fps)?;
        if let Some(ghost) = ghost {
            kwargs.set_item("ghost", ghost)?;
        }
        kwargs.set_item("packages", packages)?;
        kwargs.set_item("title", title)?;
        if let Some(shapes) = shapes {
            kwargs.set_item("shapes", shapes)?;
        }
        py.import("orbitflex.viz")?
            .getattr("write_animation")?
            .call((slf, path), Some(&kwargs))
    }

    /// Names of the columns of ``x``, in order (``r_x``, …, ``q[joint]``, …, ``theta_dot[joint]``).
    fn column_names(&self) -> Vec<String> {
        let arm = &self.arm.get().arm;
        self.layout.element_names(&arm.robot().joint_names())
    }

    /// Writes ``t``, ``x``, ``u``, ``columns`` (the names of ``x``'s columns), ``momentum``,
    /// ``energy``, ``ee_pose``, ``spring_torque``, ``deflection``, ``wheel_speed`` and
    /// ``wheel_torque`` (the applied torques; both with 0 columns without wheels) to a ``.npz``
    /// file.
    fn save_npz(&self, py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<()> {
        let np = py.import("numpy")?;
        let kwargs = PyDict::new(py);
        kwargs.set_item("t", self.t(py))?;
        kwargs.set_item("x", self.x(py))?;
        kwargs.set_item("u", self.u(py)?)?;
        kwargs.set_item("columns", np.call_method1("array", (self.column_names(),))?)?;
        kwargs.set_item("momentum", self.momentum(py)?)?;
        kwargs.set_item("energy", self.energy(py)?)?;
        kwargs.set_item("ee_pose", self.ee_pose(py)?)?;
        kwargs.set_item("spring_torque", self.spring_torque(py)?)?;
        kwargs.set_item("deflection", self.deflection(py)?)?;
        kwargs.set_item("wheel_speed", self.wheel_speed(py)?)?;
        kwargs.set_item("wheel_torque", self.wheel_torque(py)?)?;
        np.call_method("savez", (path,), Some(&kwargs))?;
        Ok(())
    }

    /// Writes one row per state with a header naming each column (``t``, then ``x``'s columns);
    /// numbers are written in full precision (they read back exactly).
    fn save_csv(&self, py: Python<'_>, path: std::path::PathBuf) -> PyResult<()> {
        let header = self.column_names();
        let t = self.t.bind(py).readonly();
        let x = self.x.bind(py).readonly();
        let (t, x) = (t.as_slice()?, x.as_slice()?);
        let width = self.layout.len();
        py.allow_threads(|| -> std::io::Result<()> {
            let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
            writeln!(out, "t,{}", header.join(","))?;
            for (time, row) in t.iter().zip(x.chunks_exact(width)) {
                write!(out, "{time:?}")?;
                for v in row {
                    write!(out, ",{v:?}")?;
                }
                writeln!(out)?;
            }
            out.flush()
        })?;
        Ok(())
    }

    fn __len__(&self, py: Python<'_>) -> usize {
        self.rows(py)
    }

    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let me = slf.get();
        let args = (
            me.arm(py),
            me.t(py),
            me.x(py),
            me.u(py)?,
            (me.layout.wheels > 0)
                .then(|| me.wheel_torque(py))
                .transpose()?,
        );
        if let Some(info) = &me.capture {
            // a run with a target: its events, target rows, combined arm and target too
            let capture = (
                info.events.clone_ref(py),
                info.record.target.clone(),
                info.arm_after.as_ref().map(|a| a.clone_ref(py)),
                info.body.clone_ref(py),
            );
            return Ok((
                slf.get_type().getattr("_restore_capture")?.unbind(),
                (args, capture).into_pyobject(py)?.into_any().unbind(),
            ));
        }
        Ok((
            slf.get_type().into_any().unbind(),
            args.into_pyobject(py)?.into_any().unbind(),
        ))
    }

    /// A pickled run with a target (for pickle): the arm's rows as ``Trajectory(...)`` takes
    /// them, then the events, the target's rows, the combined arm and the target.
    #[staticmethod]
    #[pyo3(name = "_restore_capture")]
    #[allow(clippy::type_complexity)]
    fn restore_capture(
        py: Python<'_>,
        rows: (
            Py<PyFlexibleArm>,
            Bound<'_, PyAny>,
            Bound<'_, PyAny>,
            Bound<'_, PyAny>,
            Option<Bound<'_, PyAny>>,
        ),
        capture: (
            Bound<'_, PyAny>,
            Vec<f64>,
            Option<Bound<'_, PyFlexibleArm>>,
            Bound<'_, super::capture::PyTarget>,
        ),
    ) -> PyResult<Self> {
        let (arm, t, x, u, wheel_torque) = rows;
        let (events, target, arm_after, body) = capture;
        let arm_bound = arm.bind(py).clone();
        let traj = Self::new(py, arm, &t, &x, &u, wheel_torque.as_ref())?;
        let record = super::capture_run::restore_record(
            &events,
            target,
            arm_after.as_ref(),
            &body.get().target,
        )?;
        if record.rows() != traj.rows(py) {
            return Err(super::errors::ModelError::new_err(format!(
                "target: expected {} rows (one per row of x), given {}",
                traj.rows(py),
                record.rows()
            )));
        }
        let info =
            super::capture_run::CaptureInfo::new(py, &arm_bound, record, &body.get().target)?;
        Ok(traj.with_capture(info))
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let rows = self.rows(py);
        let t_end = if rows > 0 {
            self.t.bind(py).readonly().as_slice()?[rows - 1]
        } else {
            0.0
        };
        Ok(format!(
            "Trajectory(states={rows}, t_end={t_end} s, dof={})",
            self.layout.n
        ))
    }
}

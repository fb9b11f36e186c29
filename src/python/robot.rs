//! `orbitflex.Robot`.

use super::batched::{call_args, evaluate, single_array, single_matrix, single_vector, Call};
use super::convert::{array1, array2, vector, vector_or};
use super::errors::ModelError;
use super::workspaces::{Lent, Pool};
use crate::algorithms::{self, Data};
use crate::args::{check_base_pose, Loads, RigidState};
use crate::model::{Robot, UrdfOptions};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A floating base carrying a chain or a tree of revolute joints, loaded from URDF (model §1,
/// §2.7, §7), with one or more end-effectors (:attr:`ee_links`).
///
/// Conventions: base twist ``[ω_B; v_B]`` in the base frame; joints depth-first from the base
/// (base to EE on a chain; :attr:`parents` gives the tree); spatial
/// vectors ``[angular; linear]``; base acceleration ``α_B`` is classical (the derivative of the
/// base-frame components of ``ω`` and of the origin velocity, expressed in the base frame); SI units.
///
/// Thread-safe: call it from several threads at once (each call has a workspace of its own).
/// Batched calls run without the GIL and stop on Ctrl-C (``KeyboardInterrupt``).
#[pyclass(name = "Robot", module = "orbitflex", frozen)]
pub struct PyRobot {
    pub(crate) robot: Robot,
    /// Workspaces, one lent to each call in flight (see `workspaces`: no lock is held during
    /// a call, so threads never wait for each other).
    workspaces: Pool<Data>,
}

impl PyRobot {
    pub(crate) fn wrap(robot: Robot) -> Self {
        Self {
            workspaces: Pool::with(Data::new(&robot)),
            robot,
        }
    }

    /// A workspace of this call's own.
    fn data(&self) -> Lent<'_, Data> {
        self.workspaces.take(|| Data::new(&self.robot))
    }

    /// One call's ``ee_wrench`` as `[f_1; …; f_k]` (empty for ``None``).
    fn ee_wrench(&self, obj: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<f64>> {
        let k6 = 6 * self.robot.end_effectors().len();
        match super::convert::ee_wrench_arg(&self.robot, obj)? {
            Some(f) => vector(&f, "ee_wrench", Some(k6)),
            None => Ok(Vec::new()),
        }
    }

    /// `q`, `V_B` and `q̇` as vectors of the robot's sizes, checked.
    fn state(
        &self,
        q: &Bound<'_, PyAny>,
        base_twist: &Bound<'_, PyAny>,
        qd: &Bound<'_, PyAny>,
    ) -> PyResult<StateArgs> {
        let n = self.robot.dof();
        Ok(StateArgs {
            q: vector(q, "q", Some(n))?,
            base_twist: vector(base_twist, "base_twist", Some(6))?,
            qd: vector(qd, "qd", Some(n))?,
        })
    }
}

/// A matrix into row-major order.
fn row_major_into(m: &nalgebra::DMatrix<f64>, out: &mut [f64]) {
    let cols = m.ncols();
    for (r, row) in out.chunks_exact_mut(cols).enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = m[(r, c)];
        }
    }
}

/// Owned `q`, `V_B`, `q̇` from Python, lent out as a [`RigidState`].
struct StateArgs {
    q: Vec<f64>,
    base_twist: Vec<f64>,
    qd: Vec<f64>,
}

impl StateArgs {
    fn rigid(&self) -> RigidState<'_> {
        RigidState::new(&self.q, &self.base_twist, &self.qd)
    }
}

/// A rotational inertia given as three principal moments (3,) or a matrix (3, 3), kg·m².
pub(super) fn inertia_matrix(
    inertia: &Bound<'_, PyAny>,
    what: &str,
) -> PyResult<crate::spatial::Mat3> {
    use crate::spatial::{Mat3, Vec3};
    let array = super::convert::as_float_array(inertia, what)?;
    let shape: Vec<usize> = array.getattr("shape")?.extract()?;
    match shape.as_slice() {
        [3] => Ok(Mat3::from_diagonal(&Vec3::from_column_slice(&vector(
            &array,
            what,
            Some(3),
        )?))),
        [3, 3] => {
            let (_, values) = super::convert::matrix(&array, what, 3)?;
            Ok(Mat3::from_row_slice(&values))
        }
        other => Err(ModelError::new_err(format!(
            "{what}: expected three principal moments (3,) or a matrix (3, 3), given shape \
             {other:?}"
        ))),
    }
}

fn options(
    ee_link: Option<String>,
    locked_joints: Option<Vec<String>>,
    ee_links: Option<Vec<String>>,
) -> UrdfOptions {
    UrdfOptions {
        ee_link,
        locked_joints: locked_joints.unwrap_or_default(),
        ee_links: ee_links.unwrap_or_default(),
    }
}

#[pymethods]
impl PyRobot {
    /// Loads a URDF file. The model is a tree of revolute and continuous joints on the root
    /// link (the base), numbered depth-first. ``ee_links`` names the end-effector links, in the
    /// order wrenches and Jacobians use (default: every leaf link, depth-first, leaves behind a
    /// locked joint left out); ``ee_link="x"`` means ``ee_links=["x"]``. ``locked_joints`` are
    /// held at zero and treated as fixed (e.g. gripper fingers, prismatic joints).
    #[staticmethod]
    #[pyo3(signature = (path, ee_link=None, locked_joints=None, ee_links=None))]
    fn from_urdf(
        py: Python<'_>,
        path: std::path::PathBuf,
        ee_link: Option<String>,
        locked_joints: Option<Vec<String>>,
        ee_links: Option<Vec<String>>,
    ) -> PyResult<Self> {
        let opts = options(ee_link, locked_joints, ee_links);
        Ok(Self::wrap(
            py.allow_threads(|| Robot::from_urdf(&path, &opts))?,
        ))
    }

    /// Loads a URDF from its XML text; options as :meth:`from_urdf`.
    #[staticmethod]
    #[pyo3(signature = (xml, ee_link=None, locked_joints=None, ee_links=None))]
    fn from_urdf_string(
        py: Python<'_>,
        xml: &str,
        ee_link: Option<String>,
        locked_joints: Option<Vec<String>>,
        ee_links: Option<Vec<String>>,
    ) -> PyResult<Self> {
        let opts = options(ee_link, locked_joints, ee_links);
        Ok(Self::wrap(
            py.allow_threads(|| Robot::from_urdf_string(xml, &opts))?,
        ))
    }

    /// Rebuilds a model from :meth:`__reduce__`'s parts (for pickling).
    #[staticmethod]
    #[allow(clippy::type_complexity)]
    #[pyo3(signature = (name, source, bodies, joints, ees, appearance=None))]
    fn _from_parts(
        name: String,
        source: String,
        bodies: Vec<(String, f64, [f64; 3], [f64; 9])>,
        joints: Vec<(String, [f64; 3], [f64; 9], [f64; 3], usize)>,
        ees: Vec<(String, usize, [f64; 9], [f64; 3])>,
        appearance: Option<super::appearance::Appearance>,
    ) -> PyResult<Self> {
        use crate::spatial::{Inertia, Mat3, Transform, Vec3};
        let transform =
            |r: &[f64; 9], p: &[f64; 3]| Transform::new(Mat3::from_row_slice(r), Vec3::from(*p));
        let inertia = |m: f64, c: &[f64; 3], i: &[f64; 9]| Inertia {
            mass: m,
            com: Vec3::from(*c),
            rotational: Mat3::from_row_slice(i),
        };
        let Some(((base, m, c, i), links)) = bodies.split_first() else {
            return Err(ModelError::new_err("Robot parts: no base body"));
        };
        if links.len() != joints.len() {
            return Err(ModelError::new_err(
                "Robot parts: one joint per link expected",
            ));
        }
        let mut builder = crate::RobotBuilder::new(&name, base, inertia(*m, c, i)).source(&source);
        for ((link, m, c, i), (joint, axis, r, p, parent)) in links.iter().zip(&joints) {
            builder = builder.joint_at(
                *parent,
                joint,
                transform(r, p),
                Vec3::from(*axis),
                link,
                inertia(*m, c, i),
            );
        }
        for (name, body, r, p) in &ees {
            builder = builder.end_effector_at(name, *body, transform(r, p));
        }
        if let Some(appearance) = appearance {
            builder = super::appearance::rebuild(builder, appearance)?;
        }
        Ok(Self::wrap(builder.build()?))
    }

    /// Pickle support: the model's parts (bodies, joints with their parents, end-effectors), rebuilt and re-validated
    /// by ``Robot._from_parts``.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let robot = &slf.get().robot;
        let rows =
            |m: &crate::spatial::Mat3| -> [f64; 9] { std::array::from_fn(|k| m[(k / 3, k % 3)]) };
        let vec3 = |v: &crate::spatial::Vec3| -> [f64; 3] { [v.x, v.y, v.z] };
        let bodies: Vec<_> = robot
            .body_names()
            .iter()
            .zip(robot.inertias())
            .map(|(name, i)| (name.clone(), i.mass, vec3(&i.com), rows(&i.rotational)))
            .collect();
        let joints: Vec<_> = robot
            .joints()
            .iter()
            .map(|j| {
                (
                    j.name.clone(),
                    vec3(&j.axis),
                    rows(&j.origin.rotation),
                    vec3(&j.origin.translation),
                )
            })
            .zip(&robot.parents()[1..])
            .map(|((name, axis, r, p), &parent)| (name, axis, r, p, parent))
            .collect();
        let ee: Vec<_> = robot
            .end_effectors()
            .iter()
            .map(|e| {
                (
                    e.link.clone(),
                    e.body,
                    rows(&e.transform.rotation),
                    vec3(&e.transform.translation),
                )
            })
            .collect();
        let args = (
            robot.name().to_string(),
            robot.source().to_string(),
            bodies,
            joints,
            ee,
            super::appearance::parts(robot),
        );
        let constructor = slf.get_type().getattr("_from_parts")?;
        Ok((
            constructor.unbind(),
            args.into_pyobject(py)?.into_any().unbind(),
        ))
    }

    /// The built-in default model (see ``orbitflex.models.space_arm``).
    #[staticmethod]
    fn space_arm() -> Self {
        Self::wrap(Robot::space_arm())
    }

    /// The built-in dual-arm servicer (see ``orbitflex.models.dual_arm``).
    #[staticmethod]
    fn dual_arm() -> Self {
        Self::wrap(Robot::dual_arm())
    }

    /// Number of joints ``n``.
    #[getter]
    fn dof(&self) -> usize {
        self.robot.dof()
    }

    /// Joint names, base to EE.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.robot
            .joint_names()
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    /// Body names: the base (root link), then the child link of each joint.
    #[getter]
    fn body_names(&self) -> Vec<String> {
        self.robot.body_names().to_vec()
    }

    /// Each joint's position limits ``[lower, upper]`` (rad), shape (n, 2), from the URDF's
    /// ``<limit lower upper>``; ``[-inf, inf]`` for a continuous joint (or one whose limits the
    /// model does not state).
    #[getter]
    fn position_limits<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let values = self
            .robot
            .position_limits()
            .iter()
            .flat_map(|&(lower, upper)| [lower, upper])
            .collect();
        super::convert::row_major(py, self.robot.dof(), 2, values)
    }

    /// Each joint's speed limit ``|q̇|`` (rad/s), shape (n,), from the URDF's ``<limit
    /// velocity>``; ``inf`` where the model states none.
    #[getter]
    fn velocity_limits<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.robot.velocity_limits())
    }

    /// Each joint's effort limit ``|τ|`` (N·m, link side: for a flexible joint, the motor torque
    /// after the gearbox), shape (n,), from the URDF's ``<limit effort>``; ``inf`` where the
    /// model states none.
    #[getter]
    fn effort_limits<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.robot.effort_limits())
    }

    /// The URDF robot name.
    #[getter]
    fn name(&self) -> String {
        self.robot.name().to_string()
    }

    /// The EE link name of a robot with one end-effector (an error listing them when it has
    /// several: see :attr:`ee_links`).
    #[getter]
    fn ee_link(&self) -> PyResult<String> {
        let e = self.robot.ee_choice(None)?;
        Ok(self.robot.ee_links()[e].to_string())
    }

    /// The end-effector link names, in the order ``ee_wrench`` rows, stacked Jacobians and the
    /// operator ``B`` use.
    #[getter]
    fn ee_links(&self) -> Vec<String> {
        self.robot
            .ee_links()
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    /// The body carrying each end-effector, in :attr:`ee_links` order: ``0`` is the base and
    /// ``i + 1`` the child link of joint ``i`` (the rows of :meth:`body_poses`).
    #[getter]
    fn ee_bodies(&self) -> Vec<usize> {
        self.robot.end_effectors().iter().map(|e| e.body).collect()
    }

    /// Each joint's parent joint index, ``-1`` where the parent is the base: a list of ``n``
    /// ints. Joints are numbered depth-first from the base, so ``parents[i] < i``; on a serial
    /// chain ``parents == [-1, 0, 1, …, n-2]``.
    #[getter]
    fn parents(&self) -> Vec<i64> {
        self.robot.parents()[1..]
            .iter()
            .map(|&p| p as i64 - 1)
            .collect()
    }

    /// Total mass of base and links (kg).
    #[getter]
    fn total_mass(&self) -> f64 {
        self.robot.total_mass()
    }

    /// This robot with its base body replaced: ``mass`` (kg), ``inertia`` about the base's
    /// centre of mass in base axes (kg·m²; three principal moments, or a 3×3 matrix; default
    /// ``None``: a solid cube of ``DEFAULT_BUS_SIDE`` = 1.5 m, ``mass·side²/6`` about every
    /// axis, the default ``orbitflex simulate --base-mass`` uses too), and the centre of mass
    /// ``com`` in the base frame (m, default the base origin). For example, to mount an arm whose
    /// root link weighs a few kilograms on a spacecraft bus.
    #[pyo3(signature = (mass, inertia=None, com=None))]
    fn with_base_inertia(
        &self,
        mass: &Bound<'_, PyAny>,
        inertia: Option<&Bound<'_, PyAny>>,
        com: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        use crate::spatial::{Inertia, Vec3};
        let mass = super::convert::real(mass, "mass")?;
        let com = vector_or(com, "com", 3, 0.0)?;
        let about_com = match inertia.filter(|o| !o.is_none()) {
            Some(inertia) => inertia_matrix(inertia, "inertia")?,
            None => Inertia::solid_cube(mass, crate::model::DEFAULT_BUS_SIDE, Vec3::zeros())
                .inertia_about_com(),
        };
        crate::model::check_inertia(mass, &Vec3::from_column_slice(&com), &about_com).map_err(
            |message| {
                ModelError::new_err(format!("base '{}': {message}", self.robot.body_names()[0]))
            },
        )?;
        let inertia = Inertia::from_com(mass, Vec3::from_column_slice(&com), about_com);
        Ok(Self::wrap(self.robot.with_base_inertia(inertia)?))
    }

    /// This robot holding a rigid payload at an end-effector, joined to the body carrying it as
    /// a merged fixed link would be: ``mass`` (kg), ``com`` its centre of mass in the EE frame (m,
    /// default the EE origin) and ``inertia`` about that centre in EE axes (kg·m²; three
    /// principal moments or a 3×3 matrix; default zero, a point mass). ``ee``: which
    /// end-effector (a link name or an index; ``None`` is the only one). For example, a grasped
    /// object whose mass a campaign disperses.
    #[pyo3(signature = (mass, inertia=None, com=None, ee=None))]
    fn with_payload(
        &self,
        mass: &Bound<'_, PyAny>,
        inertia: Option<&Bound<'_, PyAny>>,
        com: Option<&Bound<'_, PyAny>>,
        ee: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        use crate::spatial::{Inertia, Mat3, Vec3};
        let e = super::convert::ee_arg(&self.robot, ee)?;
        let mass = super::convert::real(mass, "mass")?;
        let com = Vec3::from_column_slice(&vector_or(com, "com", 3, 0.0)?);
        let about_com = match inertia.filter(|o| !o.is_none()) {
            None => Mat3::zeros(),
            Some(inertia) => inertia_matrix(inertia, "inertia")?,
        };
        if !(mass.is_finite() && mass >= 0.0) {
            return Err(ModelError::new_err(format!(
                "mass: expected a payload mass >= 0 kg, given {mass}"
            )));
        }
        crate::args::check_finite("com", com.as_slice())?;
        crate::args::check_finite("inertia", about_com.as_slice())?;
        let payload = Inertia::from_com(mass, com, about_com);
        Ok(Self::wrap(self.robot.with_payload_at(payload, e)?))
    }

    /// This model as URDF text: one link per body (links merged by fixed joints written as one,
    /// with the merged inertia), one joint per degree of freedom (``revolute`` with its limits
    /// where the model has position limits, ``continuous`` otherwise), and each end-effector
    /// frame that is not a body's own as a massless link on a fixed joint. Visuals and the other
    /// named frames are not written. Loading it again gives the same dynamics.
    fn to_urdf(&self) -> String {
        self.robot.to_urdf()
    }

    /// Inertial poses ``[position (m); quaternion (x, y, z, w), w ≥ 0]`` of the base, of each
    /// body (the child link of each joint, after merging fixed links) and of the EE frame, shape
    /// (n+2, 7) (n+1+k rows with k end-effectors: every EE frame in ``ee_links`` order), for the
    /// base pose ``[r_B; quat_B]`` and joint angles ``q``.
    fn body_poses<'py>(
        &self,
        py: Python<'py>,
        base_pose: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let pose = vector(base_pose, "base_pose", Some(7))?;
        let q = vector(q, "q", Some(self.robot.dof()))?;
        let poses = algorithms::body_poses(&self.robot, &pose, &q)?;
        Ok(super::convert::row_major(
            py,
            poses.len(),
            7,
            poses.concat(),
        ))
    }

    /// The names of the model's frames: every URDF link, links merged by fixed or locked joints
    /// included, in depth-first tree order from the root link (children in file order). A
    /// model not read from URDF has one frame per body, and one for its EE frame.
    #[getter]
    fn frame_names(&self) -> Vec<String> {
        self.robot
            .frame_names()
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    /// Inertial poses of every frame of :attr:`frame_names`, shape ``(len(frame_names), 7)``:
    /// ``[position (m); quaternion (x, y, z, w), w ≥ 0]``, the frame's origin and the rotation
    /// taking its components to inertial ones, for the base pose ``[r_B (m); quat_B (x, y, z,
    /// w)]`` and joint angles ``q`` (rad). Links behind a locked joint are posed at the locked
    /// value (zero).
    ///
    /// **Batches.** ``base_pose`` (B, 7) and/or ``q`` (B, n) give a result (B, frames, 7),
    /// evaluated in parallel without the GIL. ``out=`` takes a float64 C-contiguous array of
    /// the result's shape to write into (and returns it).
    #[pyo3(signature = (base_pose, q, *, out=None))]
    fn frame_poses<'py>(
        &self,
        py: Python<'py>,
        base_pose: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let n = self.robot.dof();
        let frames = self.robot.frames().len();
        let robot = &self.robot;
        match call_args(&[("base_pose", Some(base_pose), 7), ("q", Some(q), n)])? {
            Call::Batch(b) => {
                let [base_pose, q] = b.inputs()?;
                let each = |data: &mut Data, r: usize, row: &mut [f64]| {
                    let (base_pose, q) = (base_pose.row_or_empty(r), q.row_or_empty(r));
                    algorithms::frame_poses(robot, data, base_pose, q, row)
                };
                let shape = [b.rows, frames, 7];
                evaluate(py, robot, &self.workspaces, out, &shape, each)
            }
            Call::Single(v) => {
                let mut values = vec![0.0; 7 * frames];
                algorithms::frame_poses(robot, &mut self.data(), &v[0], &v[1], &mut values)?;
                single_array(py, out, &[frames, 7], &values)
            }
        }
    }

    /// What to draw, for viewers (:mod:`orbitflex.viz`): ``(shapes, warnings)``. ``shapes`` is
    /// a list of dicts, one per shape, with ``frame`` (index into :attr:`frame_names`),
    /// ``origin`` (the shape's pose in its frame, ``[position (m); quat (x, y, z, w)]``),
    /// ``kind`` (``"box"``, ``"cylinder"``, ``"sphere"``, ``"capsule"`` or ``"mesh"``), its
    /// sizes (``size``, ``radius``, ``length``, m; cylinders and capsules along their z axis),
    /// for a mesh ``path`` (the file found), ``format`` (``"stl"``, ``"dae"``, ``"obj"``) and
    /// ``scale``, ``color`` (RGBA 0..1, or None) and ``stand_in``. ``warnings`` has one line per
    /// missing or bad visual, naming the link and the file: such a visual is drawn as a
    /// stand-in (the link's capsule), and a link without visuals as a capsule from its joint to
    /// each child's joint.
    ///
    /// Mesh files named ``package://pkg/…`` are looked for in ``packages`` (a dict from package
    /// name to its directory), then in each directory of ``ROS_PACKAGE_PATH``, then in the
    /// directories above the URDF file; relative names start at the URDF file's directory.
    ///
    /// ``skeleton=True`` gives the model as a stick figure instead, ignoring its visuals: for
    /// every frame a capsule to each child's joint (a sphere for a leaf), with ``color`` None.
    #[pyo3(signature = (packages=None, skeleton=false))]
    fn scene<'py>(
        &self,
        py: Python<'py>,
        packages: Option<std::collections::BTreeMap<String, std::path::PathBuf>>,
        skeleton: bool,
    ) -> PyResult<(Vec<Bound<'py, PyDict>>, Vec<String>)> {
        super::appearance::scene(py, &self.robot, packages.unwrap_or_default(), skeleton)
    }

    /// Body masses (kg), base first, after merging fixed links.
    #[getter]
    fn body_masses<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let m: Vec<f64> = self.robot.inertias().iter().map(|i| i.mass).collect();
        array1(py, &m)
    }

    /// Mass matrix ``[[M_b, M_rb], [M_br, M_r]]``, shape (6+n, 6+n) (A.19). ``method``:
    /// ``"recursive"`` (CRBA, default) or ``"operator"`` (the paper's dense operator form).
    ///
    /// **Batches.** Give any argument a leading axis, ``(B, ...)``, to evaluate B calls at once
    /// in parallel without the GIL (the others, 1-D, are shared by every row); the result has a
    /// leading axis too. ``out=`` takes a float64 C-contiguous array of the result's shape to
    /// write into (and returns it), saving the allocation of a new one.
    #[pyo3(signature = (q, method="recursive", *, out=None))]
    fn mass_matrix<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        method: &str,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let n = self.robot.dof();
        let method = super::convert::method(method)?;
        let size = 6 + n;
        match call_args(&[("q", Some(q), n)])? {
            Call::Batch(b) => {
                let [q] = b.inputs()?;
                let robot = &self.robot;
                let shape = [b.rows, size, size];
                let each = |data: &mut Data, r: usize, row: &mut [f64]| {
                    row_major_into(method.mass_matrix(robot, data, q.row_or_empty(r))?, row);
                    Ok(())
                };
                evaluate(py, robot, &self.workspaces, out, &shape, each)
            }
            Call::Single(v) => {
                let mut data = self.data();
                let m = method.mass_matrix(&self.robot, &mut data, &v[0])?;
                single_matrix(py, out, size, |row| row_major_into(m, row))
            }
        }
    }

    /// Bias ``[C_B; C_r]``, shape (6+n,) (A.19): the generalized force needed for zero
    /// accelerations at this velocity.
    ///
    /// **Batches.** Give any argument a leading axis, ``(B, ...)``, to evaluate B calls at once
    /// in parallel without the GIL (the others, 1-D, are shared by every row); the result has a
    /// leading axis too. ``out=`` takes a float64 C-contiguous array of the result's shape to
    /// write into (and returns it), saving the allocation of a new one.
    #[pyo3(signature = (q, base_twist, qd, method="recursive", *, out=None))]
    fn bias_forces<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        base_twist: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        method: &str,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let n = self.robot.dof();
        let method = super::convert::method(method)?;
        let args = [
            ("q", Some(q), n),
            ("base_twist", Some(base_twist), 6),
            ("qd", Some(qd), n),
        ];
        match call_args(&args)? {
            Call::Batch(b) => {
                let [q, base_twist, qd] = b.inputs()?;
                let robot = &self.robot;
                let shape = [b.rows, 6 + n];
                evaluate(py, robot, &self.workspaces, out, &shape, |data, r, row| {
                    let state = RigidState::new(
                        q.row_or_empty(r),
                        base_twist.row_or_empty(r),
                        qd.row_or_empty(r),
                    );
                    row.copy_from_slice(method.bias_forces(robot, data, &state)?.as_slice());
                    Ok(())
                })
            }
            Call::Single(v) => {
                let mut data = self.data();
                let state = RigidState::new(&v[0], &v[1], &v[2]);
                let c = method.bias_forces(&self.robot, &mut data, &state)?;
                single_vector(py, out, c.as_slice())
            }
        }
    }

    /// EE Jacobian ``J``, shape (6, n): joint rates to EE twist ``[ω; v]`` in the EE frame,
    /// base at rest (model §2, ``J = Bᵀ Φ H``); columns of joints that do not move the EE are
    /// zero. ``ee``: an end-effector link name or an index into :attr:`ee_links`; ``None`` is the
    /// only one (an error listing them when the robot has several).
    #[pyo3(signature = (q, ee=None))]
    fn ee_jacobian<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        ee: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let e = super::convert::ee_arg(&self.robot, ee)?;
        let q = vector(q, "q", Some(self.robot.dof()))?;
        let mut data = self.data();
        algorithms::ee_jacobian(&self.robot, &mut data, &q, e)?;
        Ok(array2(py, &data.jacobian))
    }

    /// ``Φ_{e,B}``, shape (6, 6): base twist to the twist of end-effector ``ee`` (each in its
    /// own frame; ``ee`` as in :meth:`ee_jacobian`).
    #[pyo3(signature = (q, ee=None))]
    fn ee_base_operator<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        ee: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let e = super::convert::ee_arg(&self.robot, ee)?;
        let q = vector(q, "q", Some(self.robot.dof()))?;
        Ok(array2(py, &self.robot.ee_base_operator(&q, Some(e))?))
    }

    /// Forward dynamics ``[α_B; q̈]``, shape (6+n,) (A.19). ``tau``: joint torques (N·m);
    /// ``base_wrench`` ``f_B``: ``[moment; force]`` applied to the base, base frame, about its
    /// origin; ``ee_wrench`` ``f``: ``[moment; force]`` the EE exerts ON its environment, EE frame
    /// (a load applied to the EE is ``-f``). ``α_B`` is the classical base acceleration.
    ///
    /// **Batches.** Give any argument a leading axis, ``(B, ...)``, to evaluate B calls at once
    /// in parallel without the GIL (the others, 1-D, are shared by every row); the result has a
    /// leading axis too. ``out=`` takes a float64 C-contiguous array of the result's shape to
    /// write into (and returns it), saving the allocation of a new one.
    #[pyo3(signature = (q, base_twist, qd, tau, base_wrench=None, ee_wrench=None, method="recursive", *, out=None))]
    fn forward_dynamics<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        base_twist: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>,
        base_wrench: Option<&Bound<'py, PyAny>>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
        method: &str,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let n = self.robot.dof();
        let method = super::convert::method(method)?;
        let ee = super::convert::ee_wrench_arg(&self.robot, ee_wrench)?;
        let k6 = 6 * self.robot.end_effectors().len();
        let args = [
            ("q", Some(q), n),
            ("base_twist", Some(base_twist), 6),
            ("qd", Some(qd), n),
            ("tau", Some(tau), n),
            ("base_wrench", base_wrench, 6),
            ("ee_wrench", ee.as_ref(), k6),
        ];
        match call_args(&args)? {
            Call::Batch(b) => {
                let [q, base_twist, qd, tau, base_wrench, ee_wrench] = b.inputs()?;
                let robot = &self.robot;
                let shape = [b.rows, 6 + n];
                evaluate(py, robot, &self.workspaces, out, &shape, |data, r, row| {
                    let state = RigidState::new(
                        q.row_or_empty(r),
                        base_twist.row_or_empty(r),
                        qd.row_or_empty(r),
                    );
                    let loads = Loads::from_slices(
                        Some(base_wrench.row_or_empty(r)),
                        Some(ee_wrench.row_or_empty(r)),
                    )?;
                    let tau = tau.row_or_empty(r);
                    let acc = method.forward_dynamics(robot, data, &state, tau, &loads)?;
                    row.copy_from_slice(acc.as_slice());
                    Ok(())
                })
            }
            Call::Single(v) => {
                let loads = Loads::from_slices(Some(&v[4]), Some(&v[5]))?;
                let mut data = self.data();
                let state = RigidState::new(&v[0], &v[1], &v[2]);
                let acc = method.forward_dynamics(&self.robot, &mut data, &state, &v[3], &loads)?;
                single_vector(py, out, acc.as_slice())
            }
        }
    }

    /// Inverse dynamics ``[f_B; τ]``, shape (6+n,) (A.19), for classical base acceleration
    /// ``base_acc`` and joint accelerations ``qdd``, with the EE wrench ``ee_wrench``.
    ///
    /// **Batches.** Give any argument a leading axis, ``(B, ...)``, to evaluate B calls at once
    /// in parallel without the GIL (the others, 1-D, are shared by every row); the result has a
    /// leading axis too. ``out=`` takes a float64 C-contiguous array of the result's shape to
    /// write into (and returns it), saving the allocation of a new one.
    #[pyo3(signature = (q, base_twist, qd, base_acc, qdd, ee_wrench=None, method="recursive", *, out=None))]
    fn inverse_dynamics<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        base_twist: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        base_acc: &Bound<'py, PyAny>,
        qdd: &Bound<'py, PyAny>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
        method: &str,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let n = self.robot.dof();
        let method = super::convert::method(method)?;
        let ee = super::convert::ee_wrench_arg(&self.robot, ee_wrench)?;
        let k6 = 6 * self.robot.end_effectors().len();
        let args = [
            ("q", Some(q), n),
            ("base_twist", Some(base_twist), 6),
            ("qd", Some(qd), n),
            ("base_acc", Some(base_acc), 6),
            ("qdd", Some(qdd), n),
            ("ee_wrench", ee.as_ref(), k6),
        ];
        match call_args(&args)? {
            Call::Batch(b) => {
                let [q, base_twist, qd, base_acc, qdd, ee_wrench] = b.inputs()?;
                let robot = &self.robot;
                let shape = [b.rows, 6 + n];
                evaluate(py, robot, &self.workspaces, out, &shape, |data, r, row| {
                    let state = RigidState::new(
                        q.row_or_empty(r),
                        base_twist.row_or_empty(r),
                        qd.row_or_empty(r),
                    );
                    let gen = method.inverse_dynamics(
                        robot,
                        data,
                        &state,
                        base_acc.row_or_empty(r),
                        qdd.row_or_empty(r),
                        ee_wrench.row_or_empty(r),
                    )?;
                    row.copy_from_slice(gen.as_slice());
                    Ok(())
                })
            }
            Call::Single(v) => {
                let mut data = self.data();
                let state = RigidState::new(&v[0], &v[1], &v[2]);
                let gen =
                    method.inverse_dynamics(&self.robot, &mut data, &state, &v[3], &v[4], &v[5])?;
                single_vector(py, out, gen.as_slice())
            }
        }
    }

    /// The paper's dense operators at this state, as a dict of numpy arrays: ``Phi``, ``H``,
    /// ``M``, ``a``, ``b``, ``B``, ``Phi_hat1``, ``Phi_hat2``, ``M_b``, ``M_rb``, ``M_br``,
    /// ``M_r``, ``C_B``, ``C_r``, ``J``, and also ``M_B``, ``b_B`` and ``Phi_n1_B``
    /// (``Φ_{n+1,B}``). Stacked quantities have six rows per link (A.13–A.19). With ``k``
    /// end-effectors (model §2.7) ``B`` is (6n, 6k), ``J`` (6k, n) and ``Phi_n1_B`` (6k, 6), one
    /// block per end-effector in :attr:`ee_links` order.
    fn operators<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        base_twist: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let state = self.state(q, base_twist, qd)?;
        let o = self.robot.operators(&state.rigid())?;
        let d = PyDict::new(py);
        d.set_item("Phi", array2(py, &o.phi))?;
        d.set_item("H", array2(py, &o.h))?;
        d.set_item("M", array2(py, &o.m))?;
        d.set_item("a", array1(py, o.a.as_slice()))?;
        d.set_item("b", array1(py, o.b.as_slice()))?;
        d.set_item("B", array2(py, &o.b_ee))?;
        d.set_item("Phi_hat1", array2(py, &o.phi_hat1))?;
        d.set_item("Phi_hat2", array2(py, &o.phi_hat2))?;
        d.set_item("M_B", array2(py, &o.m_base))?;
        d.set_item("b_B", array1(py, o.b_base.as_slice()))?;
        d.set_item("M_b", array2(py, &o.m_b))?;
        d.set_item("M_rb", array2(py, &o.m_rb))?;
        d.set_item("M_br", array2(py, &o.m_br))?;
        d.set_item("M_r", array2(py, &o.m_r))?;
        d.set_item("C_B", array1(py, o.c_b.as_slice()))?;
        d.set_item("C_r", array1(py, o.c_r.as_slice()))?;
        d.set_item("J", array2(py, &o.j))?;
        d.set_item("Phi_n1_B", array2(py, &o.phi_ee_base))?;
        Ok(d)
    }

    /// The generalized Jacobian of the free-floating arm with zero momentum, shape (6, n):
    /// ``V_e = (J_e − Φ_{e,B} M_b⁻¹ M_rb) q̇``, the twist ``[ω; v]`` of end-effector ``ee`` (its
    /// own frame; ``ee`` as in :meth:`ee_jacobian`) that joint rates give once the base has
    /// reacted.
    #[pyo3(signature = (q, ee=None))]
    fn generalized_jacobian<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        ee: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let e = super::convert::ee_arg(&self.robot, ee)?;
        let q = vector(q, "q", Some(self.robot.dof()))?;
        Ok(array2(py, &self.robot.generalized_jacobian(&q, Some(e))?))
    }

    /// Derivatives of :meth:`forward_dynamics` ``[α_B; q̈]``, as a dict of arrays: ``"q"``
    /// (6+n, n), ``"v"`` (6+n, 6+n) with respect to ``[base_twist; qd]``, ``"tau"`` (6+n, n),
    /// ``"base_wrench"`` (6+n, 6) and ``"ee_wrench"`` (6+n, 6k), one 6-column block per
    /// end-effector in ``ee_links`` order. Analytical, O(n²).
    #[pyo3(signature = (q, base_twist, qd, tau, base_wrench=None, ee_wrench=None))]
    fn forward_dynamics_derivatives<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        base_twist: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>,
        base_wrench: Option<&Bound<'py, PyAny>>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let state = self.state(q, base_twist, qd)?;
        let tau = vector(tau, "tau", Some(self.robot.dof()))?;
        let fb = vector_or(base_wrench, "base_wrench", 6, 0.0)?;
        let f = self.ee_wrench(ee_wrench)?;
        let loads = Loads::from_slices(Some(&fb), Some(&f))?;
        let mut data = self.data();
        let d = algorithms::aba_derivatives(&self.robot, &mut data, &state.rigid(), &tau, &loads)?;
        let out = PyDict::new(py);
        out.set_item("q", array2(py, &d.fd_q))?;
        out.set_item("v", array2(py, &d.fd_v))?;
        out.set_item("tau", array2(py, &d.fd_tau))?;
        out.set_item("base_wrench", array2(py, &d.fd_base_wrench))?;
        out.set_item("ee_wrench", array2(py, &d.fd_ee_wrench))?;
        Ok(out)
    }

    /// Derivatives of :meth:`inverse_dynamics` ``[f_B; τ]``, as a dict of arrays: ``"q"``
    /// (6+n, n), ``"v"`` (6+n, 6+n) with respect to ``[base_twist; qd]`` (the classical base
    /// acceleration held), ``"a"`` (6+n, 6+n) with respect to ``[base_acc; qdd]`` (the mass
    /// matrix) and ``"ee_wrench"`` (6+n, 6k), one block per end-effector. Analytical, O(n²).
    #[pyo3(signature = (q, base_twist, qd, base_acc, qdd, ee_wrench=None))]
    fn inverse_dynamics_derivatives<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        base_twist: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        base_acc: &Bound<'py, PyAny>,
        qdd: &Bound<'py, PyAny>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let state = self.state(q, base_twist, qd)?;
        let acc = vector(base_acc, "base_acc", Some(6))?;
        let qdd = vector(qdd, "qdd", Some(self.robot.dof()))?;
        let f = self.ee_wrench(ee_wrench)?;
        let mut data = self.data();
        let rigid = state.rigid();
        let d = algorithms::rnea_derivatives(&self.robot, &mut data, &rigid, &acc, &qdd, &f)?;
        let out = PyDict::new(py);
        out.set_item("q", array2(py, &d.id_q))?;
        out.set_item("v", array2(py, &d.id_v))?;
        out.set_item("ee_wrench", array2(py, &d.id_ee_wrench))?;
        out.set_item(
            "a",
            array2(py, algorithms::crba(&self.robot, &mut data, &state.q)?),
        )?;
        Ok(out)
    }

    /// Total spatial momentum ``[angular; linear]`` of base and links, shape (6,), in the
    /// inertial frame about the inertial origin (model §6.1). ``base_pose = [r_B; x, y, z, w]``.
    fn momentum<'py>(
        &self,
        py: Python<'py>,
        base_pose: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
        base_twist: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let pose = vector(base_pose, "base_pose", Some(7))?;
        let state = self.state(q, base_twist, qd)?;
        check_base_pose(&pose)?;
        let h = algorithms::momentum(&self.robot, &mut self.data(), &state.rigid())?;
        let h = crate::dynamics::momentum_in_inertial_frame(&pose, &h);
        let [twist, qd] = crate::dynamics::rates(&state.rigid());
        let inputs = [
            (twist.0, twist.1, 1),
            (qd.0, qd.1, 1),
            ("base_pose", &pose, 1),
        ];
        crate::overflow::check_result("momentum", &[&h], &inputs)?;
        Ok(array1(py, &h))
    }

    /// Kinetic energy of base and links ``½ νᵀ 𝓜 ν`` (J), ``ν = [V_B; q̇]``.
    fn kinetic_energy(
        &self,
        q: &Bound<'_, PyAny>,
        base_twist: &Bound<'_, PyAny>,
        qd: &Bound<'_, PyAny>,
    ) -> PyResult<f64> {
        let state = self.state(q, base_twist, qd)?;
        let e = algorithms::kinetic_energy(&self.robot, &mut self.data(), &state.rigid())?;
        let rates = crate::dynamics::rates(&state.rigid());
        crate::overflow::check_result("kinetic_energy", &[&[e]], &rates)?;
        Ok(e)
    }

    fn __repr__(&self) -> String {
        let ee = match self.robot.ee_links().as_slice() {
            [one] => format!("ee_link={one:?}"),
            many => format!("ee_links={many:?}"),
        };
        format!(
            "Robot(name={:?}, dof={}, base={:?}, {ee}, total_mass={:.3} kg)",
            self.robot.name(),
            self.robot.dof(),
            self.robot.body_names()[0],
            self.robot.total_mass()
        )
    }
}

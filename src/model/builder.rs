//! Building and validating a [`Robot`] in code.

use super::{JointLimits, JointModel, Robot};
use crate::error::{Error, Result};
use crate::spatial::{congruence, Inertia, Mat3, Transform, Vec3, Vec6};

/// Builds a [`Robot`] joint by joint, base to EE.
///
/// ```
/// use orbitflex::{RobotBuilder, spatial::{Inertia, Mat3, Transform, Vec3}};
/// let link = Inertia::from_com(2.0, Vec3::new(0.5, 0.0, 0.0), Mat3::identity() * 0.1);
/// let robot = RobotBuilder::new("two_link", "bus", Inertia::from_com(100.0, Vec3::zeros(), Mat3::identity() * 20.0))
///     .joint("shoulder", Transform::from_xyz_rpy([0.5, 0.0, 0.0], [0.0; 3]), Vec3::z(), "upper", link)
///     .joint("elbow", Transform::from_xyz_rpy([1.0, 0.0, 0.0], [0.0; 3]), Vec3::z(), "lower", link)
///     .ee("tool", Transform::from_xyz_rpy([1.0, 0.0, 0.0], [0.0; 3]))
///     .build()
///     .unwrap();
/// assert_eq!(robot.dof(), 2);
/// ```
#[derive(Debug, Clone)]
pub struct RobotBuilder {
    robot: Robot,
}

impl RobotBuilder {
    /// Starts a model with its base body (`base_inertia` about the base origin, base frame).
    pub fn new(name: &str, base_name: &str, base_inertia: Inertia) -> Self {
        Self {
            robot: Robot {
                name: name.to_string(),
                source: "<builder>".to_string(),
                link_names: vec![base_name.to_string()],
                joints: Vec::new(),
                parents: vec![0],
                inertias: vec![base_inertia],
                ees: Vec::new(),
                frames: Default::default(),
                link_frames: Vec::new(),
                visuals: Vec::new(),
                urdf_dir: None,
            },
        }
    }

    /// Appends revolute joint `i`, carried by the last body added (a serial chain): `origin =
    /// Φ_{i,i-1}` at `q = 0`, axis `h_i` in frame `i` (normalised by [`build`](Self::build)), and
    /// the inertia of link `i` in its own frame.
    pub fn joint(
        self,
        name: &str,
        origin: Transform,
        axis: Vec3,
        link_name: &str,
        inertia: Inertia,
    ) -> Self {
        let parent = self.robot.joints.len();
        self.joint_at(parent, name, origin, axis, link_name, inertia)
    }

    /// Appends revolute joint `i` carried by the body named `parent_link` (the base, or a link
    /// added before), for a tree: `origin = Φ_{i,λ(i)}` at `q = 0` from the parent's frame, the
    /// rest as [`joint`](Self::joint). Bodies must come depth-first: `parent_link` is the last
    /// body added or one of its ancestors, so each subtree is a contiguous range of bodies
    /// ([`build`](Self::build) refuses other orders, and unknown names).
    pub fn joint_on(
        self,
        parent_link: &str,
        name: &str,
        origin: Transform,
        axis: Vec3,
        link_name: &str,
        inertia: Inertia,
    ) -> Self {
        let parent = self.body_named(parent_link);
        self.joint_at(parent, name, origin, axis, link_name, inertia)
    }

    /// [`joint_on`](Self::joint_on) with the parent given by its body index.
    pub(crate) fn joint_at(
        mut self,
        parent: usize,
        name: &str,
        origin: Transform,
        axis: Vec3,
        link_name: &str,
        inertia: Inertia,
    ) -> Self {
        self.robot.parents.push(parent);
        self.robot.joints.push(JointModel {
            name: name.to_string(),
            axis,
            origin,
            limits: JointLimits::NONE,
        });
        self.robot.link_names.push(link_name.to_string());
        self.robot.inertias.push(inertia);
        self
    }

    /// Sets the limits of the last joint added (position, speed, effort; link side), checked by
    /// [`build`](Self::build).
    pub fn limits(mut self, limits: JointLimits) -> Self {
        if let Some(joint) = self.robot.joints.last_mut() {
            joint.limits = limits;
        }
        self
    }

    /// [`end_effector`](Self::end_effector) with the body given by its index.
    pub(crate) fn end_effector_at(mut self, name: &str, body: usize, transform: Transform) -> Self {
        self.robot.ees.push(super::EndEffector {
            link: name.to_string(),
            body,
            transform,
        });
        self
    }

    /// The index of the body named `link`; an unknown name gives an index out of range, which
    /// [`build`](Self::build) reports.
    fn body_named(&self, link: &str) -> usize {
        self.robot
            .link_names
            .iter()
            .position(|l| l == link)
            .unwrap_or(usize::MAX)
    }

    /// Adds an end-effector frame on the last body added: `transform = Φ_{e,b}` from that body's
    /// frame (`Φ_{n+1,n}` on a chain). Without any [`ee`](Self::ee) or
    /// [`end_effector`](Self::end_effector), [`build`](Self::build) puts one end-effector at the
    /// origin of every leaf body (the last link of a chain), named after its link.
    pub fn ee(self, name: &str, transform: Transform) -> Self {
        let body = self.robot.joints.len();
        self.end_effector_at(name, body, transform)
    }

    /// Adds an end-effector frame named `name` on the body named `link` (any body, the base
    /// included): `transform = Φ_{e,b}` from that body's frame. End-effectors keep the order
    /// they are added in.
    pub fn end_effector(self, name: &str, link: &str, transform: Transform) -> Self {
        let body = self.body_named(link);
        self.end_effector_at(name, body, transform)
    }

    /// Rebuilds a model from its parts (tests and the crate's own derived models).
    pub(crate) fn from_robot(robot: Robot) -> Self {
        Self { robot }
    }

    /// Names the frames of the model's links, for viewers and [`crate::algorithms::frame_poses`]
    /// (the URDF loader gives one per URDF link, merged links included). Without it, `build`
    /// makes one per body and one for the EE frame if it names a link of its own.
    pub fn frames(mut self, frames: Vec<super::LinkFrame>) -> Self {
        self.robot.link_frames = frames;
        self
    }

    /// The shapes that draw the links ([`Robot::scene`]); `Visual::frame` indexes the frames.
    pub fn visuals(mut self, visuals: Vec<super::Visual>) -> Self {
        self.robot.visuals = visuals;
        self
    }

    /// The directory relative mesh file names start from (the URDF file's).
    pub fn urdf_dir(mut self, dir: impl Into<std::path::PathBuf>) -> Self {
        self.robot.urdf_dir = Some(dir.into());
        self
    }

    /// Names where the model came from, for error messages (e.g. a file path).
    pub fn source(mut self, source: &str) -> Self {
        self.robot.source = source.to_string();
        self
    }

    /// Validates and returns the model: finite numbers, orthonormal rotations, non-zero axes
    /// (then normalised), consistent joint limits, physical inertias, and a positive-definite mass matrix at `q = 0`.
    pub fn build(mut self) -> Result<Robot> {
        let source = self.robot.source.clone();
        let invalid = |message: String| Error::InvalidModel {
            source_name: source.clone(),
            message,
        };
        for joint in &mut self.robot.joints {
            joint.axis = unit_axis(&joint.axis).ok_or_else(|| {
                invalid(format!(
                    "joint '{}': axis {:?} is zero or not finite; expected a non-zero 3-vector",
                    joint.name,
                    joint.axis.as_slice()
                ))
            })?;
            check_transform(&joint.origin)
                .map_err(|m| invalid(format!("joint '{}': origin {m}", joint.name)))?;
            joint
                .limits
                .check()
                .map_err(|m| invalid(format!("joint '{}': {m}", joint.name)))?;
        }
        check_tree(&self.robot).map_err(invalid)?;
        if self.robot.ees.is_empty() {
            self.robot.ees = leaf_end_effectors(&self.robot);
        }
        check_end_effectors(&self.robot).map_err(invalid)?;
        for (inertia, link) in self.robot.inertias.iter().zip(&self.robot.link_names) {
            check_inertia(inertia.mass, &inertia.com, &inertia.inertia_about_com()).map_err(
                |message| Error::InvalidInertia {
                    source_name: source.clone(),
                    link: link.clone(),
                    message,
                },
            )?;
        }
        if self.robot.link_frames.is_empty() {
            self.robot.link_frames = super::visual::body_frames(&self.robot);
        }
        check_frames(&self.robot).map_err(invalid)?;
        self.robot.frames = super::JointFrames::new(&self.robot);
        check_mass_matrix(&self.robot)?;
        Ok(self.robot)
    }
}

/// Every joint hangs from a body that exists, in depth-first order: the parent of body `i` is
/// body `i − 1` or one of its ancestors (so each subtree is a contiguous range of bodies).
fn check_tree(robot: &Robot) -> std::result::Result<(), String> {
    for i in 1..robot.parents.len() {
        let parent = robot.parents[i];
        let name = &robot.joints[i - 1].name;
        if parent >= i {
            return Err(format!(
                "joint '{name}': its parent link is not defined before it (parents must be added \
                 before their children)"
            ));
        }
        let on_path = parent == i - 1
            || robot
                .path_to_base(i - 1)
                .any(|b| robot.parents[b] == parent);
        if !on_path {
            return Err(format!(
                "joint '{name}' hangs from '{}', whose subtree was already closed by '{}': add \
                 the bodies depth-first (each branch complete before the next)",
                robot.link_names[parent],
                robot.link_names[i - 1]
            ));
        }
    }
    Ok(())
}

/// One end-effector at the origin of every leaf body, named after its link.
fn leaf_end_effectors(robot: &Robot) -> Vec<super::EndEffector> {
    let mut has_child = vec![false; robot.parents.len()];
    for &p in &robot.parents[1..] {
        has_child[p] = true;
    }
    (0..robot.parents.len())
        .filter(|&b| !has_child[b])
        .map(|b| super::EndEffector {
            link: robot.link_names[b].clone(),
            body: b,
            transform: Transform::identity(),
        })
        .collect()
}

/// End-effectors on bodies that exist, with unique names and valid placements.
fn check_end_effectors(robot: &Robot) -> std::result::Result<(), String> {
    let mut names = std::collections::HashSet::new();
    for ee in &robot.ees {
        if ee.body > robot.joints.len() {
            return Err(format!(
                "end-effector '{}' is placed on a link that is not defined (links: {})",
                ee.link,
                robot.link_names.join(", ")
            ));
        }
        if !names.insert(ee.link.as_str()) {
            return Err(format!("end-effector '{}' is named twice", ee.link));
        }
        check_transform(&ee.transform).map_err(|m| format!("EE frame '{}': {m}", ee.link))?;
    }
    Ok(())
}

/// The named frames and visuals refer to bodies and frames that exist, parents first, with
/// valid placements and unique names.
fn check_frames(robot: &Robot) -> std::result::Result<(), String> {
    let mut names = std::collections::HashSet::new();
    for (k, frame) in robot.link_frames.iter().enumerate() {
        if !names.insert(frame.name.as_str()) {
            return Err(format!("frame '{}' is named twice", frame.name));
        }
        if frame.body > robot.joints.len() {
            return Err(format!(
                "frame '{}': body {} does not exist (the model has {} bodies)",
                frame.name,
                frame.body,
                robot.joints.len() + 1
            ));
        }
        if frame.parent.is_some_and(|p| p >= k) {
            return Err(format!(
                "frame '{}': its parent frame must come before it",
                frame.name
            ));
        }
        check_transform(&frame.placement)
            .and_then(|_| check_transform(&frame.joint_origin))
            .map_err(|m| format!("frame '{}': {m}", frame.name))?;
    }
    for visual in &robot.visuals {
        if visual.frame >= robot.link_frames.len() {
            return Err(format!(
                "a visual names frame {}; the model has {} frames",
                visual.frame,
                robot.link_frames.len()
            ));
        }
        check_transform(&visual.origin).map_err(|m| {
            format!(
                "visual of '{}': origin {m}",
                robot.link_frames[visual.frame].name
            )
        })?;
    }
    Ok(())
}

/// The largest mass accepted (kg). Beyond it, with distances up to [`MAX_LENGTH`], products in
/// the dynamics could overflow.
pub const MAX_MASS: f64 = 1e30;

/// The smallest positive mass accepted (kg); a massless link has mass 0. Below it, `1/m` and the
/// products of the dynamics could overflow.
pub const MIN_MASS: f64 = 1e-30;

/// The largest distance accepted (m): joint origins, centres of mass, the EE frame.
pub const MAX_LENGTH: f64 = 1e10;

/// The largest entry of a rotational inertia accepted (kg·m²).
pub const MAX_INERTIA: f64 = 1e50;

/// `axis` scaled to unit length, or `None` for a zero or non-finite axis. It is divided by its
/// largest component first, so that a huge but finite axis (`1e200 1e200 0`) does not overflow,
/// and an axis that is already a unit vector to round-off is kept bit for bit (so that a model
/// rebuilt from its own numbers, as unpickling does, is the same model).
fn unit_axis(axis: &Vec3) -> Option<Vec3> {
    let largest = axis.amax();
    if !axis.iter().all(|v| v.is_finite()) || largest == 0.0 {
        return None;
    }
    if (axis.norm() - 1.0).abs() <= 4.0 * f64::EPSILON {
        return Some(*axis);
    }
    let scaled = axis / largest;
    Some(scaled / scaled.norm())
}

/// A finite distance within [`MAX_LENGTH`] (a message naming the value otherwise).
pub(crate) fn check_length(value: &Vec3) -> std::result::Result<(), String> {
    if !value.iter().all(|v| v.is_finite()) {
        return Err(format!("{:?} has non-finite numbers", value.as_slice()));
    }
    if value.amax() > MAX_LENGTH {
        return Err(format!(
            "{:?} m is farther than the {MAX_LENGTH:e} m supported (beyond it the dynamics \
             overflow)",
            value.as_slice()
        ));
    }
    Ok(())
}

pub(crate) fn check_transform(t: &Transform) -> std::result::Result<(), String> {
    if !t.rotation.iter().all(|v| v.is_finite()) {
        return Err("rotation has non-finite numbers".into());
    }
    check_length(&t.translation).map_err(|m| format!("translation {m}"))?;
    let error = (t.rotation.transpose() * t.rotation - Mat3::identity()).norm();
    if error > 1e-9 || t.rotation.determinant() < 0.0 {
        return Err(format!(
            "rotation is not a proper orthonormal matrix (|RᵀR - I| = {error:.3e})"
        ));
    }
    Ok(())
}

/// Checks that `mass` and the inertia about the COM are physical: mass ≥ 0, a symmetric inertia
/// whose principal moments are ≥ 0 and satisfy the triangle inequality `I₁ + I₂ ≥ I₃`.
/// A point mass (zero inertia) and a massless, inertia-free link are accepted. Masses, distances
/// and inertias beyond [`MAX_MASS`], [`MAX_LENGTH`] and [`MAX_INERTIA`] are refused, and so are
/// positive masses below [`MIN_MASS`].
pub fn check_inertia(mass: f64, com: &Vec3, about_com: &Mat3) -> std::result::Result<(), String> {
    if !mass.is_finite() || !com.iter().chain(about_com.iter()).all(|v| v.is_finite()) {
        return Err("mass, centre of mass or inertia is not finite".into());
    }
    if mass < 0.0 {
        return Err(format!("negative mass {mass} kg; expected mass >= 0"));
    }
    if mass > 0.0 && mass < MIN_MASS {
        return Err(format!(
            "mass {mass:e} kg is smaller than the {MIN_MASS:e} kg supported (below it the \
             dynamics overflow); use 0 for a massless link"
        ));
    }
    if mass > MAX_MASS {
        return Err(format!(
            "mass {mass:e} kg is larger than the {MAX_MASS:e} kg supported (beyond it the \
             dynamics overflow)"
        ));
    }
    check_length(com).map_err(|m| format!("centre of mass {m}"))?;
    if about_com.amax() > MAX_INERTIA {
        return Err(format!(
            "inertia entry {:e} kg·m² is larger than the {MAX_INERTIA:e} kg·m² supported \
             (beyond it the dynamics overflow)",
            about_com.amax()
        ));
    }
    let asym = (about_com - about_com.transpose()).norm();
    let scale = about_com.norm();
    if asym > 1e-9 * scale.max(1e-300) {
        return Err("inertia matrix is not symmetric".into());
    }
    let moments = about_com.symmetric_eigenvalues();
    let mut m = [moments[0], moments[1], moments[2]];
    m.sort_by(|a, b| a.total_cmp(b));
    let tol = 1e-9 * scale;
    if m[0] < -tol {
        return Err(format!(
            "inertia is not positive definite: principal moments {:.6e}, {:.6e}, {:.6e} kg·m²",
            m[0], m[1], m[2]
        ));
    }
    if m[0] + m[1] < m[2] - tol {
        return Err(format!(
            "inertia violates the triangle inequality: principal moments {:.6e} + {:.6e} < {:.6e} kg·m²",
            m[0], m[1], m[2]
        ));
    }
    if mass == 0.0 && scale > 0.0 {
        return Err("rotational inertia without mass; expected mass > 0".into());
    }
    Ok(())
}

/// The mass matrix is positive definite at `q = 0` iff every articulated-body pivot
/// `D_i = H_iᵀ I^A_i H_i` is positive and the base's articulated inertia is positive definite.
///
/// A pivot counts as zero at round-off level relative to the inertia of the links the joint
/// moves (the trace of `I^A_i`'s rotational block, about the joint), as the articulated-body
/// algorithm's own check does: never relative to the whole model, so that a heavy bus (a
/// near-held base, 1e10 kg) does not make the arm's light wrist look singular.
fn check_mass_matrix(robot: &Robot) -> Result<()> {
    let n = robot.dof();
    let mut articulated: Vec<_> = robot.inertias.iter().map(Inertia::matrix).collect();
    for i in (1..=n).rev() {
        let joint = &robot.joints[i - 1];
        let parent = robot.parents[i];
        let h = Vec6::new(joint.axis.x, joint.axis.y, joint.axis.z, 0.0, 0.0, 0.0);
        let u = articulated[i] * h;
        let d = h.dot(&u);
        let own = articulated[i].fixed_view::<3, 3>(0, 0).trace();
        if d <= 1e-12 * own {
            return Err(Error::InvalidModel {
                source_name: robot.source.clone(),
                message: format!(
                    "joint '{}' moves links with no inertia about its axis ({}): the mass matrix \
                     is singular; give these links mass and inertia, or lock the joint",
                    joint.name,
                    subtree(robot, i).join(", ")
                ),
            });
        }
        let reduced = articulated[i] - u * u.transpose() / d;
        articulated[parent] += congruence(&joint.transform(0.0), &reduced);
    }
    if articulated[0].cholesky().is_none() {
        return Err(Error::InvalidModel {
            source_name: robot.source.clone(),
            message: format!(
                "the base '{}' and the bodies attached to it have no mass (or no rotational \
                 inertia): the base block of the mass matrix is singular",
                robot.link_names[0]
            ),
        });
    }
    Ok(())
}

/// The names of body `i` and of every body below it.
fn subtree(robot: &Robot, i: usize) -> Vec<&str> {
    (i..=robot.dof())
        .filter(|&b| b == i || robot.path_to_base(b).any(|a| a == i))
        .map(|b| robot.link_names[b].as_str())
        .collect()
}

/// Edge (m) of the solid cube that stands for a spacecraft bus given by its mass alone
/// ([`crate::spatial::Inertia::solid_cube`]): the built-in bus's size.
pub const DEFAULT_BUS_SIDE: f64 = 1.5;

impl Robot {
    /// This robot with its base body's inertia replaced, validated like any new model: for
    /// example to mount an arm whose root link weighs a few kilograms on a spacecraft bus.
    /// `inertia` is about the base origin, in the base frame. Joints, links and the EE frame are
    /// unchanged.
    ///
    /// ```
    /// use orbitflex::spatial::{Inertia, Mat3, Vec3};
    /// let arm = orbitflex::Robot::space_arm();
    /// let bus = Inertia::from_com(2000.0, Vec3::zeros(), Mat3::from_diagonal(&Vec3::new(900.0, 900.0, 700.0)));
    /// let heavier = arm.with_base_inertia(bus)?;
    /// assert_eq!(heavier.inertias()[0].mass, 2000.0);
    /// assert_eq!(heavier.dof(), arm.dof());
    /// # Ok::<(), orbitflex::Error>(())
    /// ```
    pub fn with_base_inertia(&self, inertia: Inertia) -> Result<Robot> {
        let mut robot = self.clone();
        robot.inertias[0] = inertia;
        RobotBuilder { robot }.build()
    }

    /// This robot holding a rigid payload at its end-effector (a robot with several end-effectors
    /// is an error that lists them): `payload` (its mass, centre of
    /// mass and rotational inertia about the EE origin, all in the EE frame) is joined to the
    /// body that carries the EE frame, as a fixed link merged into it would be. Validated like any new model. For
    /// dispersing a grasped object's mass in a campaign.
    ///
    /// ```
    /// use orbitflex::spatial::{Inertia, Mat3, Vec3};
    /// let arm = orbitflex::Robot::space_arm();
    /// // 20 kg, 10 cm beyond the EE origin along its z axis, a point mass
    /// let payload = Inertia::from_com(20.0, Vec3::new(0.0, 0.0, 0.1), Mat3::zeros());
    /// let loaded = arm.with_payload(payload)?;
    /// let mass = |r: &orbitflex::Robot| r.inertias().iter().map(|i| i.mass).sum::<f64>();
    /// assert!((mass(&loaded) - mass(&arm) - 20.0).abs() < 1e-9);
    /// # Ok::<(), orbitflex::Error>(())
    /// ```
    pub fn with_payload(&self, payload: Inertia) -> Result<Robot> {
        self.with_payload_at(payload, self.ee_choice(None)?)
    }

    /// [`with_payload`](Self::with_payload) at end-effector `ee` (an index into
    /// [`Robot::ee_links`]), for a robot with several.
    pub fn with_payload_at(&self, payload: Inertia, ee: usize) -> Result<Robot> {
        let mut robot = self.clone();
        let ee = &robot.ees[robot.ee_choice(Some(ee))?];
        let held = payload.transformed_to_parent(&ee.transform);
        let body = ee.body;
        robot.inertias[body] = robot.inertias[body].add(&held);
        RobotBuilder { robot }.build()
    }
}

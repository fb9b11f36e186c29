//! Loading a [`Robot`] from URDF (model §7), in named steps:
//!
//! 1. [`parse`]: XML text to URDF elements;
//! 2. [`tree`]: links and joints into one kinematic tree, checked (one root, one parent per link,
//!    every name defined, every link reached);
//! 3. [`ees`]: the end-effector links (those asked for, or every leaf), and the check that every
//!    moving joint is revolute or continuous;
//! 4. [`merge`]: fixed and locked joints merged away, so each link belongs to a body with its
//!    inertia added in; bodies numbered depth-first from the root;
//! 5. [`frames`]: one named frame per link, depth-first, placed on its body, and the visuals;
//! 6. the model: the bodies, joints and frames handed to [`RobotBuilder`], which validates the
//!    result.
//!
//! The root link is the base `B`. Revolute and continuous joints are the degrees of freedom, on a
//! chain or on a tree of several arms; fixed joints, and joints named in `locked_joints` (held at
//! zero), are merged.

mod ees;
mod frames;
mod merge;
mod parse;
mod tree;
pub(crate) mod write;

use super::{Robot, RobotBuilder};
use crate::error::Result;
use crate::spatial::Vec3;
use std::path::Path;

/// Options for URDF loading.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UrdfOptions {
    /// The link whose frame is the EE frame, for one end-effector: the same as
    /// `ee_links = vec![link]`. Give at most one of `ee_link` and `ee_links`.
    pub ee_link: Option<String>,
    /// The end-effector links, in the order wrenches and Jacobians use. Empty (and no `ee_link`):
    /// every leaf link, depth-first from the root, not counting leaves behind a locked joint
    /// unless they are all there is.
    pub ee_links: Vec<String>,
    /// Joints held at zero and treated as fixed (any type), e.g. gripper fingers.
    pub locked_joints: Vec<String>,
}

impl Robot {
    /// Loads a URDF file (model §7). Errors name the file and the offending element.
    ///
    /// ```no_run
    /// use orbitflex::{Robot, UrdfOptions};
    /// let options = UrdfOptions { ee_link: Some("tool0".into()), ..UrdfOptions::default() };
    /// let robot = Robot::from_urdf("ur5.urdf", &options)?;
    /// # Ok::<(), orbitflex::Error>(())
    /// ```
    pub fn from_urdf(path: impl AsRef<Path>, options: &UrdfOptions) -> Result<Robot> {
        let path = path.as_ref();
        let text = crate::io::read_text(path, "URDF")?;
        let robot = load(&text, &path.display().to_string(), options)?;
        // absolute, so that a model pickled elsewhere or used after a `chdir` still finds them
        let dir = path.parent().map(|d| {
            let cwd = std::env::current_dir().unwrap_or_default();
            if d.is_absolute() {
                d.to_path_buf()
            } else {
                cwd.join(d)
            }
        });
        Ok(Robot {
            urdf_dir: dir,
            ..robot
        })
    }

    /// Loads a URDF from its XML text (model §7).
    ///
    /// ```
    /// use orbitflex::{Robot, UrdfOptions, SPACE_ARM_URDF};
    /// let robot = Robot::from_urdf_string(SPACE_ARM_URDF, &UrdfOptions::default())?;
    /// assert_eq!(robot.dof(), 7);
    /// # Ok::<(), orbitflex::Error>(())
    /// ```
    pub fn from_urdf_string(xml: &str, options: &UrdfOptions) -> Result<Robot> {
        load(xml, "<urdf string>", options)
    }
}

fn load(xml: &str, source: &str, options: &UrdfOptions) -> Result<Robot> {
    let urdf = parse::parse(xml, source)?;
    let tree = tree::Tree::new(&urdf, &options.locked_joints, source)?;
    let asked: Vec<String> = match (&options.ee_link, options.ee_links.as_slice()) {
        (Some(_), [_, ..]) => {
            return Err(crate::Error::InvalidArgument {
                what: "ee_link".into(),
                message: "give ee_link (one end-effector) or ee_links (several), not both".into(),
            })
        }
        (Some(link), []) => vec![link.clone()],
        (None, links) => links.to_vec(),
    };
    let option = if options.ee_link.is_some() {
        "link (ee_link)"
    } else {
        "link (ee_links)"
    };
    let ee_links = ees::ee_links(&tree, &asked, option, source)?;
    ees::check_joint_kinds(&tree, &options.locked_joints, source)?;
    let bodies = merge::merge(&tree, source)?;

    let base = &bodies.bodies[0];
    let mut builder = RobotBuilder::new(&urdf.name, base.link, base.inertia).source(source);
    for body in &bodies.bodies[1..] {
        let (joint, origin) = body.joint.expect("every body after the base has a joint");
        let axis = Vec3::from(joint.axis);
        let parent = bodies.placement[joint.parent.as_str()].0;
        builder = builder
            .joint_at(parent, &joint.name, origin, axis, body.link, body.inertia)
            .limits(joint_limits(joint));
    }
    for link in ee_links {
        let (body, in_body) = bodies.placement[link];
        builder = builder.end_effector_at(link, body, in_body);
    }
    let (frames, visuals) = frames::frames(&tree, &bodies);
    builder.frames(frames).visuals(visuals).build()
}

/// A joint's limits from its `<limit>`: URDF's `lower` and `upper` (rad; a missing one is 0, as
/// URDF specifies, but a `<limit>` with neither states no position range) bound a revolute joint
/// only, a continuous joint turning freely; `effort` (N·m) and `velocity` (rad/s) bound both.
fn joint_limits(joint: &parse::Joint) -> crate::model::JointLimits {
    let Some(limit) = joint.limit else {
        return crate::model::JointLimits::NONE;
    };
    let position = match (joint.kind, limit.lower, limit.upper) {
        (parse::JointKind::Revolute, lower, upper) if lower.is_some() || upper.is_some() => {
            Some((lower.unwrap_or(0.0), upper.unwrap_or(0.0)))
        }
        _ => None,
    };
    crate::model::JointLimits {
        position,
        velocity: limit.velocity,
        effort: limit.effort,
    }
}

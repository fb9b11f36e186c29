//! Loading a [`Robot`] from URDF (model §7), in named steps:
//!
//! 1. [`parse`]: XML text to URDF elements;
//! 2. [`tree`]: links and joints into one kinematic tree, checked (one root, one parent per link,
//!    every name defined, every link reached);
//! 3. [`chain`]: the EE link and the joints from the root to it; every other moving joint is an
//!    error;
//! 4. [`merge`]: fixed and locked joints merged away, so each link belongs to a body with its
//!    inertia added in;
//! 5. [`frames`]: one named frame per link, depth-first, placed on its body, and the visuals;
//! 6. the model: the bodies, joints and frames handed to [`RobotBuilder`], which validates the
//!    result.
//!
//! The root link is the base `B`. Revolute and continuous joints on the chain are the degrees of
//! freedom; fixed joints, and joints named in `locked_joints` (held at zero), are merged.

mod chain;
mod frames;
mod merge;
mod parse;
mod tree;

use super::{Robot, RobotBuilder};
use crate::error::Result;
use crate::spatial::Vec3;
use std::path::Path;

/// Options for URDF loading.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UrdfOptions {
    /// The link whose frame is the EE frame; `None` picks the unique leaf link of the tree, not
    /// counting leaves behind a locked joint.
    pub ee_link: Option<String>,
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
    let ee_link = chain::ee_link(&tree, options.ee_link.as_deref(), source)?;
    let chain = chain::chain(&tree, ee_link, source)?;
    let bodies = merge::merge(&tree, &chain, source)?;

    let base = &bodies.bodies[0];
    let mut builder = RobotBuilder::new(&urdf.name, base.link, base.inertia).source(source);
    for body in &bodies.bodies[1..] {
        let (joint, origin) = body.joint.expect("every body after the base has a joint");
        let axis = Vec3::from(joint.axis);
        builder = builder.joint(&joint.name, origin, axis, body.link, body.inertia);
    }
    let (ee_body, ee_in_body) = bodies.placement[ee_link];
    debug_assert_eq!(ee_body, bodies.bodies.len() - 1);
    let (frames, visuals) = frames::frames(&tree, &bodies);
    builder
        .ee(ee_link, ee_in_body)
        .frames(frames)
        .visuals(visuals)
        .build()
}

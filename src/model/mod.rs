//! The robot model: a floating base carrying a tree of revolute joints (a serial chain, or several
//! arms), and its end-effector frames.
//!
//! A [`Robot`] is immutable once built, either from the [`RobotBuilder`] or from a URDF
//! ([`Robot::from_urdf`], model §7). Per-call scratch memory lives in a separate workspace
//! (`crate::Data`), so a `Robot` can be shared between threads.

mod builder;
mod frames;
mod robot;
mod urdf;
mod visual;

pub use builder::{
    check_inertia, RobotBuilder, DEFAULT_BUS_SIDE, MAX_INERTIA, MAX_LENGTH, MAX_MASS, MIN_MASS,
};
pub(crate) use frames::{to_z, JointFrames};
pub use robot::{EndEffector, JointLimits, JointModel, Robot};
pub(crate) use urdf::write as urdf_write;
pub use urdf::UrdfOptions;
pub use visual::{
    check_mesh_bytes, check_mesh_file, Geometry, LinkFrame, MeshFormat, MeshSearch, Scene, Shape,
    Visual, MAX_MESH_BYTES, MAX_SCENE_MESH_BYTES,
};

/// The built-in default model: a 500 kg, 1.5 m spacecraft bus carrying a 7-joint space arm
/// (see `models/README.md`). The URDF text is embedded in the crate.
pub const SPACE_ARM_URDF: &str = include_str!("../../models/space_arm.urdf");

/// The built-in dual-arm servicer: the bus of [`SPACE_ARM_URDF`] carrying two copies of its
/// 7-joint arm, mounted 0.9 m apart on the same face, the right arm the mirror image of the left
/// (see `models/README.md`). End-effectors `left_ee` and `right_ee`.
pub const DUAL_ARM_URDF: &str = include_str!("../../models/dual_arm.urdf");

impl Robot {
    /// Loads the built-in dual-arm servicer ([`DUAL_ARM_URDF`]): bus, 14 revolute joints
    /// (`left_*` are joints 1–7, `right_*` 8–14), end-effectors `left_ee` and `right_ee`.
    ///
    /// ```
    /// let robot = orbitflex::Robot::dual_arm();
    /// assert_eq!(robot.dof(), 14);
    /// assert_eq!(robot.ee_links(), ["left_ee", "right_ee"]);
    /// assert_eq!(robot.parents()[8], 0); // the right shoulder hangs from the bus
    /// ```
    pub fn dual_arm() -> Robot {
        Robot::from_urdf_string(DUAL_ARM_URDF, &UrdfOptions::default())
            .expect("the built-in dual-arm model is valid")
    }

    /// Loads the built-in default model ([`SPACE_ARM_URDF`]): bus, 7 revolute joints, EE `ee`.
    pub fn space_arm() -> Robot {
        Robot::from_urdf_string(SPACE_ARM_URDF, &UrdfOptions::default())
            .expect("the built-in space arm model is valid")
    }
}

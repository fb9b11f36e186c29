//! The robot model: a floating base carrying a serial chain of revolute joints, and its EE frame.
//!
//! A [`Robot`] is immutable once built, either from the [`RobotBuilder`] or from a URDF
//! ([`Robot::from_urdf`], model §7). Per-call scratch memory lives in a separate workspace
//! (`crate::Data`), so a `Robot` can be shared between threads.

mod builder;
mod frames;
mod robot;
mod urdf;
mod visual;

pub use builder::{check_inertia, RobotBuilder, MAX_INERTIA, MAX_LENGTH, MAX_MASS, MIN_MASS};
pub(crate) use frames::JointFrames;
pub use robot::{JointModel, Robot};
pub use urdf::UrdfOptions;
pub(crate) use visual::body_frames;
pub use visual::{
    check_mesh_bytes, check_mesh_file, Geometry, LinkFrame, MeshFormat, MeshSearch, Scene, Shape,
    Visual, MAX_MESH_BYTES, MAX_SCENE_MESH_BYTES,
};

/// The built-in default model: a 500 kg, 1.5 m spacecraft bus carrying a 7-joint space arm
/// (see `models/README.md`). The URDF text is embedded in the crate.
pub const SPACE_ARM_URDF: &str = include_str!("../../models/space_arm.urdf");

impl Robot {
    /// Loads the built-in default model ([`SPACE_ARM_URDF`]): bus, 7 revolute joints, EE `ee`.
    pub fn space_arm() -> Robot {
        Robot::from_urdf_string(SPACE_ARM_URDF, &UrdfOptions::default())
            .expect("the built-in space arm model is valid")
    }
}

#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
//!
//! The model (conventions, equations with their (A.n) numbers, state layout, integrator and
//! invariants) is documented in `docs/model.md`, rendered here as [`model_documentation`];
//! "model §n" in these docs refers to its sections. "The paper" is the source derivation:
//! Appendix A of "Trajectory Generation for Flexible-Joint Space Manipulators", Frontiers in
//! Robotics and AI, 2022, whose equations are numbered (A.1)–(A.19).

pub mod algorithms;
pub mod analysis;
pub mod args;
pub mod capture;
pub mod control;
pub mod dynamics;
pub mod error;
pub mod flex;
pub mod fmu;
pub mod integrate;
pub mod io;
pub mod lanes;
pub mod linalg;
pub mod model;
pub mod operators;
pub(crate) mod overflow;
pub mod planning;
mod simd;
pub mod spatial;
pub mod state;
#[doc(hidden)]
pub mod testing;

pub use algorithms::Data;
pub use args::{Loads, RigidState};
pub use capture::{capture, Capture, Target};
pub use control::{Controller, MotorPD, Quintic, Schedule, Wrenches};
pub use dynamics::Method;
pub use error::{Error, Result};
pub use flex::{
    FlexibleArm, FlexibleJoints, Inputs, ModelWorkspace, MotorGains, ReactionWheels, StateLayout,
    StateSpec, Wheel,
};
pub use integrate::{ArmWorkspace, SimulationFailure, Simulator, Trajectory};
pub use model::{
    check_mesh_bytes, check_mesh_file, EndEffector, Geometry, JointLimits, JointModel, LinkFrame,
    MeshFormat, MeshSearch, Robot, RobotBuilder, Scene, Shape, UrdfOptions, Visual, DUAL_ARM_URDF,
    MAX_MESH_BYTES, MAX_SCENE_MESH_BYTES, SPACE_ARM_URDF,
};
pub use operators::Operators;
pub use planning::{plan_slew, BaseMode, FlexibleInverse, Limits, LinkMotion, Plan};

// The bindings' functions take one parameter per Python keyword argument: their signatures are
// the Python API's, fixed by it, so the lint on long parameter lists is off for them (and only
// for them: everything they call takes its arguments as values, `Run`, `Drive`, `Batch`, …).
#[cfg(feature = "python")]
#[allow(clippy::too_many_arguments)]
mod python;

#[doc = include_str!("../docs/model.md")]
pub mod model_documentation {}

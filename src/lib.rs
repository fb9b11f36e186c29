#![doc = include_str!("../README.md")]
//!
//! Conventions, equations and names follow `SPEC.md`; equation numbers (A.n) in the documentation
//! refer to Appendix A of the seed derivation.

pub mod algorithms;
pub mod dynamics;
pub mod error;
pub mod flex;
pub mod integrate;
pub mod model;
pub mod operators;
pub mod spatial;
#[doc(hidden)]
pub mod testing;

pub use algorithms::{Data, Method};
pub use error::{Error, Result};
pub use flex::{ArmWorkspace, FlexibleArm, FlexibleJoints, StateLayout};
pub use integrate::{Controller, MotorPD, Schedule, SimulationFailure, Trajectory};
pub use model::{JointModel, Robot, RobotBuilder, UrdfOptions, SPACE_ARM_URDF};
pub use operators::Operators;

#[cfg(feature = "python")]
mod python;

//! Trajectory generation for flexible-joint arms: the flexible-joint inverse dynamics
//! ([`flatness`]) and minimum-time rest-to-rest slews under motor-torque, joint-speed and
//! base-actuation limits ([`slew`]). The method is the one of "Trajectory Generation for
//! Flexible-Joint Space Manipulators" (Frontiers in Robotics and AI, 2022); docs/model.md §8
//! describes it.

pub(crate) mod deflection;
pub mod flatness;
pub mod taylor;

pub use flatness::{BaseMode, FlexibleInverse, LinkMotion};
pub mod slew;
pub use slew::{
    plan_slew, plan_slew_watched, sigma, Binding, Constraint, Limits, Plan, PlanPoint, Reference,
    Samples,
};
pub mod tracking;
pub use tracking::{Tracking, TrackingSetup};

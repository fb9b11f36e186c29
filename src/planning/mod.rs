//! Trajectory generation for flexible-joint arms: the flexible-joint inverse dynamics
//! ([`flatness`]) and minimum-time rest-to-rest slews under motor-torque, joint-speed and
//! base-actuation limits ([`slew`]). The method is the one of "Trajectory Generation for
//! Flexible-Joint Space Manipulators" (Frontiers in Robotics and AI, 2022); docs/model.md §8
//! describes it.

pub(crate) mod deflection;
// the flexible-joint inverse dynamics and the time jets it runs on are the model's (`crate::flex`);
// re-exported where they have always been found
pub use crate::flex::inverse as flatness;
pub use crate::flex::jets as taylor;

pub use crate::flex::{BaseMode, FlexibleInverse, LinkMotion};
pub mod limits;
pub mod slew;
pub use limits::{BaseBound, BaseLimits, BasePoint};
pub use slew::{
    plan_slew, plan_slew_watched, sigma, Binding, Constraint, Limits, Plan, PlanPoint, Reference,
    Samples,
};
pub mod tracking;
pub mod wheel_demand;
pub use tracking::{Tracking, TrackingSetup};
pub use wheel_demand::{WheelBinding, WheelDemand};

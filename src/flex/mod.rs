//! Spong (1987) flexible joints on the floating-base arm (model §3, §4).
//!
//! Each joint `i` has a motor whose angle, reflected through its gearbox to the link side, is
//! `θ_i`. The spring torque on link `i` and the motor equation are
//!
//! ```text
//! τ_i = k_i (θ_i − q_i) + d_i (θ̇_i − q̇_i)
//! j_i θ̈_i + β_i θ̇_i + τ_i = u_i
//! ```
//! with `u_i` the motor torque reflected to the link side (N·m).
//!
//! - [`joints`]: the parameters `k, d, j, β` ([`FlexibleJoints`]), from arrays, gear data or TOML;
//! - [`StateLayout`]: the state vector's layout (defined in [`crate::state`]);
//! - [`inverse`]: the flexible-joint inverse dynamics (differential flatness), on the time jets of
//!   [`jets`];
//! - [`arm`]: [`FlexibleArm`], its derivative, energy, momentum and EE pose;
//! - [`jacobians`]: the Jacobians of the derivative and of one RK4 step, in tangent coordinates;
//! - [`gains`]: motor PD gains from a bandwidth and a damping ratio;
//! - [`stability`]: the closed-loop RK4 step limit;
//! - [`wheels`]: reaction wheels on the bus ([`ReactionWheels`]), their equations and limits.

pub mod arm;
pub mod gains;
pub mod inverse;
pub mod jacobians;
pub mod jets;
pub mod joints;
pub mod stability;
pub mod wheels;

pub use arm::{FlexibleArm, Inputs, ModelWorkspace, StateSpec};
pub use gains::MotorGains;
pub use inverse::{BaseMode, FlexibleInverse, LinkMotion};
pub use jacobians::Jacobians;
pub use joints::{reflected_inertia, FlexibleJoints};
pub use stability::StabilityLimit;
// the layout is defined below the model (`crate::state`), the quaternions in `crate::spatial`;
// re-exported here where they have always been found
pub use crate::spatial::{
    normalise_quaternion, quaternion_exp, quaternion_log, quaternion_product, quaternion_rate,
};
pub use crate::state::{StateLayout, StateParts};
pub use wheels::{saturated_torque, saturation_slope, ReactionWheels, Wheel};

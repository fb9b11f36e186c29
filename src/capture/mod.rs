//! Capture of a free-flying target: the [`Target`] (a torque-free rigid body with a handle) and
//! the grasp as an instantaneous, perfectly inelastic impulse ([`capture`]), after which the
//! target is a payload of the arm. The balance and why the motor rates do not jump are derived in
//! [`capture`]'s module docs and in model §9.

mod impulse;
mod target;

pub use impulse::{capture, Capture};
pub use target::{
    grasp_transform, rigid_body_derivative, rigid_body_momentum, Target,
    GRASP_QUATERNION_TOLERANCE, TARGET_STATE_LEN,
};

//! Capture of a free-flying target: the [`Target`] (a torque-free rigid body with a handle), the
//! grasp as an instantaneous, perfectly inelastic impulse ([`capture`]), after which the target is
//! a payload of the arm, and runs that carry a target and capture it when the end-effector meets
//! its handle ([`simulate_capture_into`], [`CaptureWhen`]). The balance and why the motor rates do
//! not jump are derived in [`capture`]'s module docs and in model §9.

mod batch;
mod impulse;
mod run;
pub mod scenario;
mod target;
mod when;

pub use batch::{simulate_capture_batch, CaptureBatchSettings, CaptureCase, CaptureOutcome};
pub use impulse::{capture, Capture};
pub use run::{
    simulate_capture_into, CaptureEvent, CaptureFailure, CaptureRecord, CaptureRun, TargetMotion,
};
pub use scenario::{capture_scenario, capture_scenario_with, CaptureScenario};
pub use target::{
    grasp_transform, rigid_body_derivative, rigid_body_momentum, Target,
    GRASP_QUATERNION_TOLERANCE, TARGET_STATE_LEN,
};
pub use when::{Approach, CaptureWhen};

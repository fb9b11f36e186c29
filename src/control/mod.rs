//! What drives a run, below the model: the [`Controller`] trait (one row of a channel per step,
//! from the step, the time and the state), the [`Feedback`] a controller declares, the input
//! holders ([`Schedule`], [`Wrenches`]), the [`Quintic`] reference slew, the built-in [`MotorPD`] (the joints) and
//! [`AttitudePD`] (the bus, through its reaction wheels).
//!
//! A controller knows nothing of the arm it drives but the state layout ([`crate::state`]); the
//! model ([`crate::flex`]) reads a controller's [`Feedback`] for its stability limit, and the run
//! ([`crate::integrate`]) calls [`Controller::output`] once per step for each channel.

mod attitude_pd;
mod controller;
mod motor_pd;
mod quintic;
mod sampled;
mod schedule;
mod wrenches;

pub use attitude_pd::{min_norm_allocation, AttitudePD, AttitudeTarget};
pub use controller::{Controller, Feedback};
pub use motor_pd::MotorPD;
pub use quintic::{quintic_profile, Quintic};
pub use sampled::Sampled;
pub use schedule::Schedule;
pub use wrenches::Wrenches;

//! The one error type of orbitflex.
//!
//! Every fallible public function returns [`Result`]. The Python bindings map these variants once
//! onto Python exceptions (`FileNotFoundError`, `orbitflex.ModelError`, `orbitflex.SimulationError`).

use std::path::PathBuf;

/// Everything that can go wrong in orbitflex, with enough context to fix it.
#[derive(Debug, Clone, thiserror::Error)]
pub enum Error {
    /// A URDF (or parameter) file that does not exist or cannot be read.
    #[error("{}: file not found or not readable: {reason}", path.display())]
    FileNotFound { path: PathBuf, reason: String },

    /// A file that is not well-formed XML/URDF (or TOML).
    #[error("{source_name}: malformed {format}: {message}")]
    Malformed {
        source_name: String,
        format: &'static str,
        message: String,
    },

    /// A joint type orbitflex does not model (prismatic, planar, floating, spherical).
    #[error("{source_name}: joint '{joint}' has type '{kind}'; orbitflex models revolute and continuous joints only (lock it with locked_joints=[\"{joint}\"] to treat it as fixed)")]
    UnsupportedJoint {
        source_name: String,
        joint: String,
        kind: String,
    },

    /// The kinematic tree has moving joints off the chain from the root to the EE link.
    #[error("{source_name}: {message}")]
    Branching {
        source_name: String,
        message: String,
    },

    /// A link or joint name that does not exist in the file.
    #[error("{source_name}: unknown {what} '{name}'; the file has: {available}")]
    UnknownName {
        source_name: String,
        what: &'static str,
        name: String,
        available: String,
    },

    /// Inertial data that is not physical.
    #[error("{source_name}: link '{link}': {message}")]
    InvalidInertia {
        source_name: String,
        link: String,
        message: String,
    },

    /// Any other structural problem with a model (zero axis, cycles, singular mass matrix...).
    #[error("{source_name}: {message}")]
    InvalidModel {
        source_name: String,
        message: String,
    },

    /// An argument with the wrong length or shape.
    #[error("{what}: expected {expected}, given {given}")]
    Dimension {
        what: String,
        expected: String,
        given: String,
    },

    /// An argument containing NaN or infinity.
    #[error("{what}: element {index} is not finite ({value})")]
    NonFinite {
        what: String,
        index: usize,
        value: f64,
    },

    /// An argument outside its domain (non-positive stiffness, dt <= 0, ...).
    #[error("{what}: {message}")]
    InvalidArgument { what: String, message: String },

    /// A simulation whose state turned non-finite, or whose controller failed.
    #[error("simulation stopped at step {step} (t = {} s): {message}", round_time(*time))]
    Simulation {
        step: usize,
        time: f64,
        message: String,
    },
}

/// Shorthand used throughout the crate.
pub type Result<T> = std::result::Result<T, Error>;

/// Times in messages without float noise (`0.30000000000000004` prints as `0.3`).
fn round_time(t: f64) -> f64 {
    (t * 1e9).round() / 1e9
}

//! The one error type of orbitflex.
//!
//! Every fallible public function returns [`Result`]. The Python bindings map these variants once
//! onto Python exceptions: [`Error::FileNotFound`] is `FileNotFoundError`, [`Error::IsADirectory`]
//! is `IsADirectoryError`, [`Error::OutOfMemory`] is `MemoryError`, [`Error::Interrupted`] is
//! `KeyboardInterrupt`, [`Error::Simulation`] is `orbitflex.SimulationError`, and every other
//! variant is `orbitflex.ModelError` (a `ValueError`).
//!
//! ```
//! use orbitflex::{Error, FlexibleJoints};
//! match FlexibleJoints::uniform(3, -1.0, 1.0, 0.0, 0.0) {
//!     Err(Error::InvalidArgument { what, message }) => {
//!         assert_eq!(what, "stiffness[0]");
//!         assert_eq!(message, "expected > 0, given -1");
//!     }
//!     other => panic!("{other:?}"),
//! }
//! ```

use std::path::PathBuf;

/// Everything that can go wrong in orbitflex, with enough context to fix it: what is wrong,
/// where, and what was expected against what was given.
#[derive(Debug, Clone, thiserror::Error)]
pub enum Error {
    /// A URDF (or parameter) file that does not exist or cannot be read.
    #[error("{}: file not found or not readable: {reason}", path.display())]
    FileNotFound {
        /// The path given.
        path: PathBuf,
        /// The operating system's reason.
        reason: String,
    },

    /// A directory given where a file was expected.
    #[error("{}: is a directory; expected a file", path.display())]
    IsADirectory {
        /// The path given.
        path: PathBuf,
    },

    /// A file that is not well-formed XML/URDF (or TOML), or not text.
    #[error("{source_name}: malformed {format}: {message}")]
    Malformed {
        /// The file path, or `<urdf string>` / `<toml string>`.
        source_name: String,
        /// `"URDF"` or `"joint-parameter TOML"`.
        format: &'static str,
        /// What is wrong, with the line where the parser says.
        message: String,
    },

    /// Joints of types orbitflex does not model (prismatic, planar, floating, spherical): every
    /// such joint of the file, with the one `locked_joints` list that holds them all (those
    /// already locked first).
    #[error("{source_name}: {}; orbitflex models revolute and continuous joints only (lock {} with locked_joints=[{}] to treat {} as fixed)", unsupported_list(joints), if joints.len() == 1 { "it" } else { "them" }, locked.iter().chain(joints.iter().map(|(j, _)| j)).map(|j| format!("\"{j}\"")).collect::<Vec<_>>().join(", "), if joints.len() == 1 { "it" } else { "them" })]
    UnsupportedJoint {
        /// The file.
        source_name: String,
        /// Each such joint's name and URDF type, in file order.
        joints: Vec<(String, String)>,
        /// The joints locked already (`locked_joints`), in the order given.
        locked: Vec<String>,
    },

    /// A link or joint name that does not exist in the file.
    #[error("{source_name}: unknown {what} '{name}'; the file has: {available}")]
    UnknownName {
        /// The file.
        source_name: String,
        /// What kind of name, and where it was given.
        what: &'static str,
        /// The name given.
        name: String,
        /// The names the file has.
        available: String,
    },

    /// Inertial data that is not physical, or too large to compute with.
    #[error("{source_name}: link '{link}': {message}")]
    InvalidInertia {
        /// The file.
        source_name: String,
        /// The link's name.
        link: String,
        /// What is wrong with its inertia.
        message: String,
    },

    /// Any other structural problem with a model (zero axis, cycles, singular mass matrix...).
    #[error("{source_name}: {message}")]
    InvalidModel {
        /// The file.
        source_name: String,
        /// What is wrong, naming the element.
        message: String,
    },

    /// An argument with the wrong length or shape.
    #[error("{what}: expected {expected}, given {given}")]
    Dimension {
        /// The argument.
        what: String,
        /// The length or shape expected.
        expected: String,
        /// The length or shape given.
        given: String,
    },

    /// An argument containing NaN or infinity.
    #[error("{what}: element {index} is not finite ({value})")]
    NonFinite {
        /// The argument.
        what: String,
        /// The index of the first bad element.
        index: usize,
        /// Its value.
        value: f64,
    },

    /// An argument outside its domain (non-positive stiffness, dt <= 0, ...).
    #[error("{what}: {message}")]
    InvalidArgument {
        /// The argument (with its element, as `stiffness[2]`).
        what: String,
        /// What was expected and what was given.
        message: String,
    },

    /// A buffer a call needs that could not be allocated: the call stops with this error
    /// instead of aborting the process.
    #[error("{what}: needs {}, which could not be allocated; {hint}", crate::args::describe_bytes(*bytes))]
    OutOfMemory {
        /// The call or argument whose buffers did not fit.
        what: String,
        /// The bytes asked for (`None`: more than an address can hold).
        bytes: Option<usize>,
        /// What to change.
        hint: String,
    },

    /// A long computation stopped by its caller (a cancel flag, Ctrl-C in Python) before it
    /// finished.
    #[error("{what}: interrupted by the caller")]
    Interrupted {
        /// What was interrupted.
        what: String,
    },

    /// A simulation whose state turned non-finite, or whose controller failed.
    #[error("simulation stopped at step {step} (t = {} s): {message}", round_time(*time))]
    Simulation {
        /// The index `k` of the step that failed (from `t = k dt` to `(k+1) dt`).
        step: usize,
        /// `k dt` (s).
        time: f64,
        /// Why.
        message: String,
    },
}

impl Error {
    /// This error with `context` appended to the argument it names (`x0` becomes
    /// `x0 (run 3)`), for an argument of one run or row among many; other errors as they are.
    pub fn in_context(self, context: &str) -> Error {
        let tag = |what: String| format!("{what} ({context})");
        match self {
            Error::Dimension {
                what,
                expected,
                given,
            } => Error::Dimension {
                what: tag(what),
                expected,
                given,
            },
            Error::NonFinite { what, index, value } => Error::NonFinite {
                what: tag(what),
                index,
                value,
            },
            Error::InvalidArgument { what, message } => Error::InvalidArgument {
                what: tag(what),
                message,
            },
            other => other,
        }
    }
}

/// Shorthand used throughout the crate.
pub type Result<T> = std::result::Result<T, Error>;

/// Times in messages without float noise (`0.30000000000000004` prints as `0.3`).
fn round_time(t: f64) -> f64 {
    (t * 1e9).round() / 1e9
}

/// `joint 'a' has type 'prismatic'`, or `joints 'a' (prismatic) and 'b' (planar) have types …`.
fn unsupported_list(joints: &[(String, String)]) -> String {
    match joints {
        [(joint, kind)] => format!("joint '{joint}' has type '{kind}'"),
        _ => format!(
            "{} joints have types orbitflex does not model: {}",
            joints.len(),
            joints
                .iter()
                .map(|(joint, kind)| format!("'{joint}' ({kind})"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

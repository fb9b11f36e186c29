//! FMI co-simulation FMUs of a flexible arm (FMI 3.0 and 2.0): the variables, the model
//! description, the files an FMU carries and one instance's state machine. The C exports
//! (`fmi3*`, `fmi2*`) live in the `orbitflex-capi` crate and wrap [`FmuInstance`]; the
//! `orbitflex fmu` command writes the archive from [`FmuModel::files`].
//!
//! One generic runtime library serves every model: at instantiation it reads the model from
//! the FMU's `resources/` ([`FmuModel::from_resources`]) and rebuilds the same
//! [`VariableTable`] that wrote the description.

pub mod description;
pub mod instance;
pub mod model;
pub mod variables;

pub use description::model_description;
pub use instance::{FmuInstance, Initial, Mode};
pub use model::{BaseConfig, FmiVersion, FmuConfig, FmuModel};
pub use variables::{Causality, Parameter, Quantity, Slot, Variable, VariableTable};

//! `liborbitflex_c`: orbitflex's C API (`ofx_*`, declared in `include/orbitflex.h`) and the
//! runtime of the FMI co-simulation FMUs that `orbitflex fmu` writes (`fmi3*` and `fmi2*`).
//!
//! One library serves both: a C or C++ bench links it with `-lorbitflex_c`; an FMU carries it
//! as `binaries/<platform>/<modelIdentifier>.so` and it reads the model from the FMU's
//! `resources/` at instantiation.
//!
//! Every exported function catches panics (`catch_unwind`): none crosses into C. A caught panic
//! is a bug in orbitflex; it is reported as `OFX_STATUS_INTERNAL_ERROR` (or an FMI error with a
//! logged message), and the handle involved is left as it was before the call when the panic
//! came before any change.

mod api;
pub use api::*;

// The FMI exports are not part of the C API's header: cbindgen skips these modules.
/// cbindgen:ignore
mod fmi;
/// cbindgen:ignore
pub mod fmi2;
/// cbindgen:ignore
pub mod fmi3;

//! The FMI 2.0 co-simulation exports: all 44 functions of `fmi2Functions.h` (2.0.x). Those of
//! model exchange and of what this FMU does not have (Integer, Boolean and String variables,
//! derivatives, asynchronous steps) log why and return `fmi2Error`.
//!
//! FMI 2.0 differences handled here: `fmi2Boolean` is an `int`; the resource location is a
//! `file://` URI; the logger is printf-like; the model description declares
//! `canNotUseMemoryManagementFunctions="true"`, so the master's allocator is never used.
#![allow(non_snake_case, clippy::missing_safety_doc)]

use crate::fmi::{self, Instance, Logger};
use std::ffi::{c_char, c_int, c_void, CStr};

/// `fmi2CallbackFunctions`.
#[repr(C)]
pub struct CallbackFunctions {
    pub logger: fmi::Log2,
    pub allocate_memory: Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>,
    pub free_memory: Option<unsafe extern "C" fn(*mut c_void)>,
    pub step_finished: Option<unsafe extern "C" fn(*mut c_void, c_int)>,
    pub component_environment: *mut c_void,
}

/// `fmi2CoSimulation` in `fmi2Type`.
const CO_SIMULATION: c_int = 1;

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    b"default\0".as_ptr().cast()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    b"2.0\0".as_ptr().cast()
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: *mut c_void,
    _logging_on: c_int,
    n_categories: usize,
    categories: *const *const c_char,
) -> c_int {
    fmi::with(c, "fmi2SetDebugLogging", |_| {
        for &cat in fmi::slice(categories, n_categories, "categories")? {
            let name = fmi::text(cat, "a category")?;
            if name != "logStatusError" && name != "logStatusWarning" {
                return Err(format!(
                    "unknown log category '{name}' (this FMU has logStatusError and \
                     logStatusWarning)"
                ));
            }
        }
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: *const c_char,
    fmu_type: c_int,
    guid: *const c_char,
    resource_location: *const c_char,
    functions: *const CallbackFunctions,
    _visible: c_int,
    _logging_on: c_int,
) -> *mut c_void {
    // copy what is needed; the standard lets the master free `functions` afterwards
    let (logger, env) = match functions.as_ref() {
        Some(f) => (f.logger, f.component_environment),
        None => (None, std::ptr::null_mut()),
    };
    let name = if instance_name.is_null() {
        CStr::from_bytes_with_nul(b"\0").expect("NUL-terminated")
    } else {
        CStr::from_ptr(instance_name)
    };
    fmi::instantiate(Logger::V2(logger), env, name, || {
        if functions.is_null() {
            return Err("functions is NULL".into());
        }
        if instance_name.is_null() {
            return Err("instanceName is NULL".into());
        }
        if fmu_type != CO_SIMULATION {
            return Err(format!(
                "fmuType {fmu_type}: this FMU implements co-simulation (fmi2CoSimulation = 1) \
                 only"
            ));
        }
        let guid = fmi::text(guid, "fmuGUID")?;
        let location = fmi::text(resource_location, "fmuResourceLocation")?;
        fmi::load(fmi::uri_to_path(location)?, guid)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: *mut c_void) {
    fmi::free(c)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: *mut c_void,
    _tolerance_defined: c_int,
    _tolerance: f64,
    start_time: f64,
    _stop_time_defined: c_int,
    _stop_time: f64,
) -> c_int {
    fmi::with(c, "fmi2SetupExperiment", |i| i.core.setup(start_time))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: *mut c_void) -> c_int {
    fmi::with(c, "fmi2EnterInitializationMode", |i: &mut Instance| {
        // the start time is the one fmi2SetupExperiment gave (0 by default)
        let start = i.core.time();
        i.core.enter_initialization(start)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: *mut c_void) -> c_int {
    fmi::with(c, "fmi2ExitInitializationMode", |i| {
        i.core.exit_initialization()
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: *mut c_void) -> c_int {
    fmi::with(c, "fmi2Terminate", |i| i.core.terminate())
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: *mut c_void) -> c_int {
    fmi::with(c, "fmi2Reset", |i| {
        i.core.reset();
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: *mut c_void,
    vr: *const u32,
    nvr: usize,
    value: *mut f64,
) -> c_int {
    fmi::with(c, "fmi2GetReal", |i| {
        let vrs = fmi::slice(vr, nvr, "vr")?;
        let values = fmi::slice_mut(value, nvr, "value")?;
        i.core.get(vrs, values)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: *mut c_void,
    vr: *const u32,
    nvr: usize,
    value: *const f64,
) -> c_int {
    fmi::with(c, "fmi2SetReal", |i| {
        let vrs = fmi::slice(vr, nvr, "vr")?;
        let values = fmi::slice(value, nvr, "value")?;
        i.core.set(vrs, values)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(
    c: *mut c_void,
    current_communication_point: f64,
    communication_step_size: f64,
    _no_set_fmu_state_prior_to_current_point: c_int,
) -> c_int {
    fmi::with(c, "fmi2DoStep", |i| {
        i.core
            .do_step(current_communication_point, communication_step_size)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: *mut c_void, state: *mut *mut c_void) -> c_int {
    fmi::with(c, "fmi2GetFMUstate", |i| fmi::get_state(i, state))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: *mut c_void, state: *mut c_void) -> c_int {
    fmi::with(c, "fmi2SetFMUstate", |i| fmi::set_state(i, state))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: *mut c_void, state: *mut *mut c_void) -> c_int {
    fmi::with(c, "fmi2FreeFMUstate", |_| fmi::free_state(state))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: *mut c_void,
    state: *mut c_void,
    size: *mut usize,
) -> c_int {
    fmi::with(c, "fmi2SerializedFMUstateSize", |_| {
        fmi::state_size(state, size)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: *mut c_void,
    state: *mut c_void,
    serialized_state: *mut c_char,
    size: usize,
) -> c_int {
    fmi::with(c, "fmi2SerializeFMUstate", |_| {
        fmi::serialize(state, serialized_state.cast(), size)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: *mut c_void,
    serialized_state: *const c_char,
    size: usize,
    state: *mut *mut c_void,
) -> c_int {
    fmi::with(c, "fmi2DeSerializeFMUstate", |_| {
        fmi::deserialize(serialized_state.cast(), size, state)
    })
}

/// As in `fmi3`: functions for what this FMU does not have log `why` and return `fmi2Error`;
/// declared with the instance argument only (the caller owns its argument area under the
/// supported calling conventions).
macro_rules! unsupported {
    ($why:expr => $($name:ident)*) => {$(
        #[no_mangle]
        pub unsafe extern "C" fn $name(c: *mut c_void) -> c_int {
            fmi::unsupported(c, stringify!($name), $why)
        }
    )*};
}

unsupported!("this FMU's variables are all Real" =>
    fmi2GetInteger fmi2GetBoolean fmi2GetString fmi2SetInteger fmi2SetBoolean fmi2SetString);
unsupported!("this FMU provides no partial derivatives" =>
    fmi2GetDirectionalDerivative fmi2SetRealInputDerivatives fmi2GetRealOutputDerivatives);
unsupported!("this FMU's steps are synchronous: there is no pending step to cancel or ask about" =>
    fmi2CancelStep fmi2GetStatus fmi2GetRealStatus fmi2GetIntegerStatus fmi2GetBooleanStatus
    fmi2GetStringStatus);
unsupported!("this FMU implements co-simulation only, not model exchange" =>
    fmi2EnterEventMode fmi2NewDiscreteStates fmi2EnterContinuousTimeMode
    fmi2CompletedIntegratorStep fmi2SetTime fmi2SetContinuousStates fmi2GetDerivatives
    fmi2GetEventIndicators fmi2GetContinuousStates fmi2GetNominalsOfContinuousStates);

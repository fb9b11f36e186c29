//! The FMI 3.0 co-simulation exports: all 75 functions of `fmi3Functions.h` (v3.0.2). The
//! standard requires every one to exist (FMPy binds them all when it loads the binary); those
//! of interfaces or capabilities this FMU does not have (model exchange, scheduled execution,
//! event mode, clocks, derivatives, the other variable types) log why and return `fmi3Error`
//! (the instantiation ones return NULL).
//!
//! Each function's contract is the standard's; arguments are checked (NULL pointers, lengths,
//! modes, values) and every refusal is logged through the master's callback.
#![allow(non_snake_case, clippy::missing_safety_doc)]

use crate::fmi::{self, Instance, Logger, ERROR};
use std::ffi::{c_char, c_int, c_void, CStr};

/// `fmi3IntermediateUpdateCallback` (never called: no intermediate updates).
pub type IntermediateUpdate =
    Option<unsafe extern "C" fn(*mut c_void, f64, bool, bool, bool, bool, *mut bool, *mut f64)>;

#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    b"3.0\0".as_ptr().cast()
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    instance: *mut c_void,
    _logging_on: bool,
    n_categories: usize,
    categories: *const *const c_char,
) -> c_int {
    fmi::with(instance, "fmi3SetDebugLogging", |_| {
        for &c in fmi::slice(categories, n_categories, "categories")? {
            let name = fmi::text(c, "a category")?;
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
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instance_name: *const c_char,
    instantiation_token: *const c_char,
    resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    event_mode_used: bool,
    _early_return_allowed: bool,
    _required_intermediate_variables: *const u32,
    _n_required_intermediate_variables: usize,
    instance_environment: *mut c_void,
    log_message: fmi::Log3,
    _intermediate_update: IntermediateUpdate,
) -> *mut c_void {
    let logger = Logger::V3(log_message);
    let name = if instance_name.is_null() {
        CStr::from_bytes_with_nul(b"\0").expect("NUL-terminated")
    } else {
        CStr::from_ptr(instance_name)
    };
    fmi::instantiate(logger, instance_environment, name, || {
        if instance_name.is_null() {
            return Err("instanceName is NULL".into());
        }
        if event_mode_used {
            return Err("eventModeUsed = true, but this FMU has no event mode \
                        (hasEventMode is false)"
                .into());
        }
        let token = fmi::text(instantiation_token, "instantiationToken")?;
        let path = fmi::text(resource_path, "resourcePath")?;
        fmi::load(path.into(), token)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    instance_name: *const c_char,
    _token: *const c_char,
    _resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    instance_environment: *mut c_void,
    log_message: fmi::Log3,
) -> *mut c_void {
    refuse_instantiation(
        instance_name,
        instance_environment,
        log_message,
        "model exchange",
    )
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    instance_name: *const c_char,
    _token: *const c_char,
    _resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    instance_environment: *mut c_void,
    log_message: fmi::Log3,
    _clock_update: *const c_void,
    _lock_preemption: *const c_void,
    _unlock_preemption: *const c_void,
) -> *mut c_void {
    refuse_instantiation(
        instance_name,
        instance_environment,
        log_message,
        "scheduled execution",
    )
}

unsafe fn refuse_instantiation(
    instance_name: *const c_char,
    env: *mut c_void,
    log: fmi::Log3,
    interface: &str,
) -> *mut c_void {
    let name = if instance_name.is_null() {
        CStr::from_bytes_with_nul(b"\0").expect("NUL-terminated")
    } else {
        CStr::from_ptr(instance_name)
    };
    fmi::log(
        Logger::V3(log),
        env,
        name,
        ERROR,
        &format!("this FMU implements co-simulation only, not {interface}"),
    );
    std::ptr::null_mut()
}

#[no_mangle]
pub unsafe extern "C" fn fmi3FreeInstance(instance: *mut c_void) {
    fmi::free(instance)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    instance: *mut c_void,
    _tolerance_defined: bool,
    _tolerance: f64,
    start_time: f64,
    _stop_time_defined: bool,
    _stop_time: f64,
) -> c_int {
    fmi::with(instance, "fmi3EnterInitializationMode", |i| {
        i.core.enter_initialization(start_time)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3ExitInitializationMode(instance: *mut c_void) -> c_int {
    fmi::with(instance, "fmi3ExitInitializationMode", |i| {
        i.core.exit_initialization()
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3Terminate(instance: *mut c_void) -> c_int {
    fmi::with(instance, "fmi3Terminate", |i| i.core.terminate())
}

#[no_mangle]
pub unsafe extern "C" fn fmi3Reset(instance: *mut c_void) -> c_int {
    fmi::with(instance, "fmi3Reset", |i| {
        i.core.reset();
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetFloat64(
    instance: *mut c_void,
    value_references: *const u32,
    n_value_references: usize,
    values: *mut f64,
    n_values: usize,
) -> c_int {
    fmi::with(instance, "fmi3GetFloat64", |i| {
        let vrs = fmi::slice(value_references, n_value_references, "valueReferences")?;
        let values = fmi::slice_mut(values, n_values, "values")?;
        i.core.get(vrs, values)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetFloat64(
    instance: *mut c_void,
    value_references: *const u32,
    n_value_references: usize,
    values: *const f64,
    n_values: usize,
) -> c_int {
    fmi::with(instance, "fmi3SetFloat64", |i| {
        let vrs = fmi::slice(value_references, n_value_references, "valueReferences")?;
        let values = fmi::slice(values, n_values, "values")?;
        i.core.set(vrs, values)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3DoStep(
    instance: *mut c_void,
    current_communication_point: f64,
    communication_step_size: f64,
    _no_set_fmu_state_prior_to_current_point: bool,
    event_handling_needed: *mut bool,
    terminate_simulation: *mut bool,
    early_return: *mut bool,
    last_successful_time: *mut f64,
) -> c_int {
    fmi::with(instance, "fmi3DoStep", |i: &mut Instance| {
        let outcome = i
            .core
            .do_step(current_communication_point, communication_step_size);
        for flag in [event_handling_needed, terminate_simulation, early_return] {
            if let Some(flag) = flag.as_mut() {
                *flag = false;
            }
        }
        if let Some(t) = last_successful_time.as_mut() {
            *t = i.core.time();
        }
        outcome
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterStepMode(instance: *mut c_void) -> c_int {
    fmi::unsupported(
        instance,
        "fmi3EnterStepMode",
        "without event mode the FMU enters Step Mode when initialization ends",
    )
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetFMUState(instance: *mut c_void, state: *mut *mut c_void) -> c_int {
    fmi::with(instance, "fmi3GetFMUState", |i| fmi::get_state(i, state))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetFMUState(instance: *mut c_void, state: *mut c_void) -> c_int {
    fmi::with(instance, "fmi3SetFMUState", |i| fmi::set_state(i, state))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3FreeFMUState(instance: *mut c_void, state: *mut *mut c_void) -> c_int {
    fmi::with(instance, "fmi3FreeFMUState", |_| fmi::free_state(state))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
    instance: *mut c_void,
    state: *mut c_void,
    size: *mut usize,
) -> c_int {
    fmi::with(instance, "fmi3SerializedFMUStateSize", |_| {
        fmi::state_size(state, size)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SerializeFMUState(
    instance: *mut c_void,
    state: *mut c_void,
    serialized_state: *mut u8,
    size: usize,
) -> c_int {
    fmi::with(instance, "fmi3SerializeFMUState", |_| {
        fmi::serialize(state, serialized_state, size)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3DeserializeFMUState(
    instance: *mut c_void,
    serialized_state: *const u8,
    size: usize,
    state: *mut *mut c_void,
) -> c_int {
    fmi::with(instance, "fmi3DeserializeFMUState", |_| {
        fmi::deserialize(serialized_state, size, state)
    })
}

/// Functions for what this FMU does not have: each logs `why` and returns `fmi3Error`. They
/// are declared with the instance argument only: under the C calling conventions of the
/// supported platforms (System V x86-64, Windows x64, AArch64) the caller owns its argument
/// area, so a callee that reads fewer arguments than were passed is called correctly.
macro_rules! unsupported {
    ($why:expr => $($name:ident)*) => {$(
        #[no_mangle]
        pub unsafe extern "C" fn $name(instance: *mut c_void) -> c_int {
            fmi::unsupported(instance, stringify!($name), $why)
        }
    )*};
}

unsupported!("this FMU's variables are all Float64" =>
    fmi3GetFloat32 fmi3GetInt8 fmi3GetUInt8 fmi3GetInt16 fmi3GetUInt16 fmi3GetInt32
    fmi3GetUInt32 fmi3GetInt64 fmi3GetUInt64 fmi3GetBoolean fmi3GetString fmi3GetBinary
    fmi3SetFloat32 fmi3SetInt8 fmi3SetUInt8 fmi3SetInt16 fmi3SetUInt16 fmi3SetInt32
    fmi3SetUInt32 fmi3SetInt64 fmi3SetUInt64 fmi3SetBoolean fmi3SetString fmi3SetBinary);
unsupported!("this FMU has no clocks" =>
    fmi3GetClock fmi3SetClock fmi3GetIntervalDecimal fmi3GetIntervalFraction
    fmi3GetShiftDecimal fmi3GetShiftFraction fmi3SetIntervalDecimal fmi3SetIntervalFraction
    fmi3SetShiftDecimal fmi3SetShiftFraction fmi3ActivateModelPartition);
unsupported!("this FMU has no event mode and no discrete states" =>
    fmi3EnterEventMode fmi3EvaluateDiscreteStates fmi3UpdateDiscreteStates);
unsupported!("this FMU has no tunable structural parameters" =>
    fmi3EnterConfigurationMode fmi3ExitConfigurationMode);
unsupported!("dependencies are declared in the model description (outputs depend on no input)" =>
    fmi3GetNumberOfVariableDependencies fmi3GetVariableDependencies);
unsupported!("this FMU provides no partial derivatives" =>
    fmi3GetDirectionalDerivative fmi3GetAdjointDerivative fmi3GetOutputDerivatives);
unsupported!("this FMU implements co-simulation only, not model exchange" =>
    fmi3EnterContinuousTimeMode fmi3CompletedIntegratorStep fmi3SetTime
    fmi3SetContinuousStates fmi3GetContinuousStateDerivatives fmi3GetEventIndicators
    fmi3GetContinuousStates fmi3GetNominalsOfContinuousStates fmi3GetNumberOfEventIndicators
    fmi3GetNumberOfContinuousStates);

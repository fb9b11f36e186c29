//! What the FMI 2.0 and 3.0 exports share: the instance behind the C handle, its logger, the
//! panic guard, reading `resources/`, and the FMU-state records.
//!
//! Everything the model does is in `orbitflex::fmu::FmuInstance`; this is only the C side.

use orbitflex::fmu::{FmuInstance, FmuModel};
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;

/// `fmi2OK` / `fmi3OK`.
pub const OK: c_int = 0;
/// `fmi2Error` / `fmi3Error`.
pub const ERROR: c_int = 3;

/// FMI 3.0's `fmi3LogMessageCallback`.
pub type Log3 = Option<unsafe extern "C" fn(*mut c_void, c_int, *const c_char, *const c_char)>;
/// FMI 2.0's `fmi2CallbackLogger` (printf-like).
pub type Log2 = Option<
    unsafe extern "C" fn(*mut c_void, *const c_char, c_int, *const c_char, *const c_char, ...),
>;

/// The master's logger.
#[derive(Clone, Copy)]
pub enum Logger {
    V3(Log3),
    V2(Log2),
}

/// One FMU instance as the master holds it.
pub struct Instance {
    pub core: FmuInstance,
    pub name: CString,
    pub env: *mut c_void,
    pub logger: Logger,
}

impl Instance {
    /// Sends `message` to the master's logger with `status` (errors are always logged; FMI's
    /// debug-logging switch governs debug messages, and this FMU sends none).
    pub fn log(&self, status: c_int, message: &str) {
        log(self.logger, self.env, &self.name, status, message);
    }
}

/// Sends a message to a logger (also usable before an instance exists).
pub fn log(logger: Logger, env: *mut c_void, name: &CStr, status: c_int, message: &str) {
    let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
    let category = if status >= ERROR {
        b"logStatusError\0".as_ptr().cast()
    } else {
        b"logStatusWarning\0".as_ptr().cast()
    };
    // SAFETY: the callbacks are the master's, called with valid NUL-terminated strings; the
    // FMI 2.0 one is printf-like, so the text goes in as an argument of "%s", never as format.
    unsafe {
        match logger {
            Logger::V3(Some(f)) => f(env, status, category, text.as_ptr()),
            Logger::V2(Some(f)) => f(
                env,
                name.as_ptr(),
                status,
                category,
                b"%s\0".as_ptr().cast(),
                text.as_ptr(),
            ),
            _ => {}
        }
    }
}

/// Runs `body` on the instance at `handle`: a NULL handle, an `Err` (logged) or a panic
/// (logged) return Error; `Ok` returns OK. `function` names the call in messages.
pub unsafe fn with(
    handle: *mut c_void,
    function: &str,
    body: impl FnOnce(&mut Instance) -> Result<(), String>,
) -> c_int {
    if handle.is_null() {
        return ERROR; // no instance, hence no logger to tell
    }
    let instance = &mut *(handle as *mut Instance);
    match catch_unwind(AssertUnwindSafe(|| body(instance))) {
        Ok(Ok(())) => OK,
        Ok(Err(message)) => {
            instance.log(ERROR, &format!("{function}: {message}"));
            ERROR
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            instance.log(
                ERROR,
                &format!("{function}: internal error in orbitflex (a panic was caught: {what})"),
            );
            ERROR
        }
    }
}

/// Logs and refuses a function this FMU does not support.
pub unsafe fn unsupported(handle: *mut c_void, function: &str, why: &str) -> c_int {
    with(handle, function, |_| {
        Err(format!("not supported by this FMU ({why})"))
    })
}

/// `len` items at `ptr` (NULL allowed only when `len` is 0).
pub unsafe fn slice<'a, T>(ptr: *const T, len: usize, what: &str) -> Result<&'a [T], String> {
    if len == 0 {
        return Ok(&[]);
    }
    if ptr.is_null() {
        return Err(format!("{what} is NULL (with {len} elements)"));
    }
    Ok(std::slice::from_raw_parts(ptr, len))
}

/// `len` writable items at `ptr`.
pub unsafe fn slice_mut<'a, T>(ptr: *mut T, len: usize, what: &str) -> Result<&'a mut [T], String> {
    if len == 0 {
        return Ok(&mut []);
    }
    if ptr.is_null() {
        return Err(format!("{what} is NULL (with {len} elements)"));
    }
    Ok(std::slice::from_raw_parts_mut(ptr, len))
}

/// A C string argument, or a message naming it.
pub unsafe fn text<'a>(ptr: *const c_char, what: &str) -> Result<&'a str, String> {
    if ptr.is_null() {
        return Err(format!("{what} is NULL"));
    }
    CStr::from_ptr(ptr)
        .to_str()
        .map_err(|e| format!("{what} is not UTF-8 ({e})"))
}

/// The folder of an FMI 2.0 `resourceLocation` URI (`file:///dir`, `file://localhost/dir`,
/// `file:/dir`), percent-decoded.
pub fn uri_to_path(uri: &str) -> Result<PathBuf, String> {
    let rest = uri
        .strip_prefix("file://localhost/")
        .map(|r| format!("/{r}"))
        .or_else(|| uri.strip_prefix("file://").map(String::from))
        .or_else(|| uri.strip_prefix("file:").map(String::from))
        .ok_or_else(|| format!("resourceLocation '{uri}' is not a file:// URI"))?;
    let bytes = rest.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            let hex = std::str::from_utf8(&bytes[i + 1..i + 3]).unwrap_or("");
            if let Ok(b) = u8::from_str_radix(hex, 16) {
                out.push(b);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8(out)
        .map(PathBuf::from)
        .map_err(|_| format!("resourceLocation '{uri}' does not decode to UTF-8"))
}

/// Reads the model from `resources` and checks the instantiation token.
pub fn load(resources: PathBuf, token: &str) -> Result<FmuModel, String> {
    let model = FmuModel::from_resources(&resources)
        .map_err(|e| format!("cannot read the model from {}: {e}", resources.display()))?;
    let expected = model.token();
    if token != expected {
        return Err(format!(
            "instantiation token {token} is not this FMU's {expected} (the resources do not \
             belong to this model description)"
        ));
    }
    Ok(model)
}

/// Makes an instance, or logs why not and returns NULL.
pub fn instantiate(
    logger: Logger,
    env: *mut c_void,
    name: &CStr,
    make: impl FnOnce() -> Result<FmuModel, String>,
) -> *mut c_void {
    let outcome = catch_unwind(AssertUnwindSafe(make));
    let model = match outcome {
        Ok(Ok(model)) => model,
        Ok(Err(message)) => {
            log(logger, env, name, ERROR, &format!("instantiate: {message}"));
            return std::ptr::null_mut();
        }
        Err(_) => {
            log(
                logger,
                env,
                name,
                ERROR,
                "instantiate: internal error in orbitflex (a panic was caught)",
            );
            return std::ptr::null_mut();
        }
    };
    let instance = Instance {
        core: FmuInstance::new(model),
        name: name.to_owned(),
        env,
        logger,
    };
    Box::into_raw(Box::new(instance)).cast()
}

/// Frees an instance (NULL ignored).
pub unsafe fn free(handle: *mut c_void) {
    if !handle.is_null() {
        let _ = catch_unwind(AssertUnwindSafe(|| {
            drop(Box::from_raw(handle as *mut Instance))
        }));
    }
}

/// An FMU state handle: a saved record.
pub type State = Vec<u8>;

/// `GetFMUState`: a new record in `*state` when it is NULL, else overwrites the one there.
pub unsafe fn get_state(instance: &mut Instance, state: *mut *mut c_void) -> Result<(), String> {
    if state.is_null() {
        return Err("FMUState is NULL".into());
    }
    let blob = instance.core.save()?;
    if (*state).is_null() {
        *state = Box::into_raw(Box::new(blob)).cast();
    } else {
        let existing = &mut *((*state) as *mut State);
        existing.clear();
        existing.extend_from_slice(&blob);
    }
    Ok(())
}

/// `SetFMUState`: puts the record back (unchanged).
pub unsafe fn set_state(instance: &mut Instance, state: *mut c_void) -> Result<(), String> {
    if state.is_null() {
        return Err("FMUState is NULL".into());
    }
    instance.core.restore(&*(state as *const State))
}

/// `FreeFMUState`: frees `*state` (NULL ignored) and sets it to NULL.
pub unsafe fn free_state(state: *mut *mut c_void) -> Result<(), String> {
    if state.is_null() {
        return Ok(());
    }
    if !(*state).is_null() {
        drop(Box::from_raw((*state) as *mut State));
        *state = std::ptr::null_mut();
    }
    Ok(())
}

/// `SerializedFMUStateSize`.
pub unsafe fn state_size(state: *mut c_void, size: *mut usize) -> Result<(), String> {
    if state.is_null() || size.is_null() {
        return Err("FMUState or size is NULL".into());
    }
    *size = (*(state as *const State)).len();
    Ok(())
}

/// `SerializeFMUState`: copies the record into `buf` (`size` bytes, exactly its length).
pub unsafe fn serialize(state: *mut c_void, buf: *mut u8, size: usize) -> Result<(), String> {
    if state.is_null() || buf.is_null() {
        return Err("FMUState or the buffer is NULL".into());
    }
    let blob = &*(state as *const State);
    if size != blob.len() {
        return Err(format!(
            "the buffer holds {size} bytes; the serialized state has {}",
            blob.len()
        ));
    }
    std::ptr::copy_nonoverlapping(blob.as_ptr(), buf, size);
    Ok(())
}

/// `DeserializeFMUState`: a new record from the bytes (checked when it is set).
pub unsafe fn deserialize(
    buf: *const u8,
    size: usize,
    state: *mut *mut c_void,
) -> Result<(), String> {
    if state.is_null() {
        return Err("FMUState is NULL".into());
    }
    let bytes = slice(buf, size, "serializedState")?;
    if !bytes.starts_with(orbitflex::fmu::instance::STATE_MAGIC) {
        return Err("the bytes are not a serialized state of an orbitflex FMU".into());
    }
    *state = Box::into_raw(Box::new(bytes.to_vec())).cast();
    Ok(())
}

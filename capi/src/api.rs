//! The `ofx_*` C API. cbindgen turns this file's documentation into `include/orbitflex.h`, so
//! it is written for C programmers.

use orbitflex::flex::{ReactionWheels, Wheel};
use orbitflex::integrate::Outputs;
use orbitflex::{Error, FlexibleArm, FlexibleJoints, Robot, Simulator, StateSpec, UrdfOptions};
use std::cell::RefCell;
use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Mutex, TryLockError};

/// What every `ofx_*` call returns. `OFX_STATUS_OK` is zero; on any other status,
/// `ofx_last_error()` says what went wrong, and no output argument was written.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OfxStatus {
    /// Success.
    Ok = 0,
    /// An argument is invalid: a NULL pointer, a buffer of the wrong length, a non-finite
    /// number, an unknown name or output, a string that is not UTF-8.
    InvalidArgument = 1,
    /// A model could not be loaded: a file missing or malformed, a joint type orbitflex does
    /// not model, joint parameters outside their domain.
    ModelError = 2,
    /// A step diverged (non-finite state). The step was undone: the simulator keeps its last
    /// good state and time.
    SimulationError = 3,
    /// Another thread is using this simulator right now (a simulator is used by one thread
    /// at a time; make one per thread).
    Busy = 4,
    /// A bug in orbitflex (a Rust panic, caught at the boundary). Please report it with the
    /// message.
    InternalError = 5,
}

/// The output quantities `ofx_simulator_output` reads (pass the value as `uint32_t`). Every
/// quantity in SI units, angles in rad; `n` is the number of joints, `k` of end-effectors, `w`
/// of reaction wheels (`ofx_arm_wheel_count`; 0 without wheels, and the wheel outputs are
/// then empty: length 0).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OfxOutput {
    /// Link angles `q` (n, rad).
    Q = 0,
    /// Link rates `dq/dt` (n, rad/s).
    Qd = 1,
    /// Motor angles `theta` (n, rad, link side).
    Theta = 2,
    /// Motor rates (n, rad/s, link side).
    ThetaDot = 3,
    /// Joint deflections `theta - q` (n, rad).
    Deflection = 4,
    /// Spring torques `k (theta - q) + d (dtheta - dq)` (n, N m).
    SpringTorque = 5,
    /// Base pose: position of the base origin (m, inertial frame), then its attitude quaternion
    /// `x, y, z, w` (base to inertial) (7).
    BasePose = 6,
    /// Base twist: angular velocity (rad/s) then origin velocity (m/s), base-frame components (6).
    BaseTwist = 7,
    /// End-effector poses: per end-effector, position (m) then quaternion `x, y, z, w`,
    /// inertial frame (7 k, in the robot's end-effector order).
    EePoses = 8,
    /// Total momentum: angular (N m s, about the inertial origin) then linear (N s), inertial
    /// frame (6).
    Momentum = 9,
    /// Total energy (1, J).
    Energy = 10,
    /// Reaction-wheel speeds relative to the bus (w, rad/s).
    WheelSpeed = 11,
    /// The torques the wheel motors applied over the last step (w, N m): the held commands
    /// after the torque and speed limits, at that step's start; zero before the first step.
    AppliedWheelTorque = 12,
}

/// One reaction wheel fixed in the bus, base-frame components, SI units (see docs/model.md,
/// "Reaction wheels"). The motor applies its torque to the wheel about `axis`; the bus feels
/// the opposite.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct OfxWheel {
    /// Unit spin axis (norm 1 within 1e-5; normalised).
    pub axis: [f64; 3],
    /// Centre of the wheel (m).
    pub position: [f64; 3],
    /// Mass (kg), > 0.
    pub mass: f64,
    /// Inertia about the spin axis (kg m^2), > 0.
    pub spin_inertia: f64,
    /// Inertia about any axis through the centre normal to the spin axis (kg m^2),
    /// >= spin_inertia / 2.
    pub transverse_inertia: f64,
    /// Motor torque limit (N m), > 0; `INFINITY` for none.
    pub max_torque: f64,
    /// Speed limit relative to the bus (rad/s), > 0; `INFINITY` for none.
    pub max_speed: f64,
    /// Viscous friction on the wheel speed (N m s/rad), >= 0.
    pub friction: f64,
}

/// A robot model (the rigid multibody: links, joints, end-effectors). Opaque. Immutable once
/// made: one robot may be read from several threads at once. Free with `ofx_robot_free`.
pub struct OfxRobot {
    robot: Robot,
}

/// A flexible-joint arm: a robot and its joint parameters. Opaque. Immutable once made: one
/// arm may be read from several threads at once. Free with `ofx_arm_free`.
pub struct OfxArm {
    arm: FlexibleArm,
}

/// A stepping simulation: an arm, a state, the time, the step `dt` and the held inputs.
/// Opaque. Used by one thread at a time (a call while another thread is in a call on the
/// same simulator returns `OFX_STATUS_BUSY`; different simulators are independent). Free with
/// `ofx_simulator_free`.
pub struct OfxSimulator {
    inner: Mutex<Stepping>,
}

struct Stepping {
    sim: Simulator,
    outputs: Outputs,
    fresh: bool,
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_last_error(message: &str) {
    let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = text);
}

/// A failed call: its status and message.
struct Failure(OfxStatus, String);

impl From<Error> for Failure {
    fn from(e: Error) -> Self {
        let status = match e {
            Error::Simulation { .. } => OfxStatus::SimulationError,
            Error::Dimension { .. }
            | Error::NonFinite { .. }
            | Error::InvalidArgument { .. }
            | Error::OutOfMemory { .. }
            | Error::Interrupted { .. } => OfxStatus::InvalidArgument,
            _ => OfxStatus::ModelError,
        };
        Failure(status, e.to_string())
    }
}

fn invalid(message: String) -> Failure {
    Failure(OfxStatus::InvalidArgument, message)
}

/// Runs `body`, turning its error or a panic into a status and the thread's last error,
/// prefixed with the function's name.
fn guard(function: &str, body: impl FnOnce() -> Result<(), Failure>) -> OfxStatus {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => OfxStatus::Ok,
        Ok(Err(Failure(status, message))) => {
            set_last_error(&format!("{function}: {message}"));
            status
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "no message".into());
            set_last_error(&format!(
                "{function}: internal error (a panic was caught at the C boundary: {what}); \
                 please report it"
            ));
            OfxStatus::InternalError
        }
    }
}

/// `ptr` as a reference, or an error naming `what`.
unsafe fn reference<'a, T>(ptr: *const T, what: &str) -> Result<&'a T, Failure> {
    ptr.as_ref()
        .ok_or_else(|| invalid(format!("{what} is NULL")))
}

/// A UTF-8 C string, or an error naming `what`.
unsafe fn text<'a>(ptr: *const c_char, what: &str) -> Result<&'a str, Failure> {
    if ptr.is_null() {
        return Err(invalid(format!("{what} is NULL")));
    }
    CStr::from_ptr(ptr)
        .to_str()
        .map_err(|e| invalid(format!("{what} is not UTF-8 ({e})")))
}

/// A comma-separated list (NULL or empty: none).
unsafe fn list(ptr: *const c_char, what: &str) -> Result<Vec<String>, Failure> {
    if ptr.is_null() {
        return Ok(Vec::new());
    }
    Ok(text(ptr, what)?
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(String::from)
        .collect())
}

/// `len` numbers at `ptr` (exactly `expected` if given), or an error naming `what`.
unsafe fn numbers<'a>(
    ptr: *const f64,
    len: usize,
    expected: Option<usize>,
    what: &str,
) -> Result<&'a [f64], Failure> {
    if let Some(expected) = expected {
        if len != expected {
            return Err(invalid(format!(
                "{what}: expected length {expected}, given {len}"
            )));
        }
    }
    if len == 0 {
        return Ok(&[]);
    }
    if ptr.is_null() {
        return Err(invalid(format!("{what} is NULL")));
    }
    Ok(std::slice::from_raw_parts(ptr, len))
}

/// A caller buffer of exactly `expected` numbers.
unsafe fn buffer<'a>(
    ptr: *mut f64,
    len: usize,
    expected: usize,
    what: &str,
) -> Result<&'a mut [f64], Failure> {
    if len != expected {
        return Err(invalid(format!(
            "{what}: the buffer must hold exactly {expected} numbers, given length {len}"
        )));
    }
    if len == 0 {
        return Ok(&mut []);
    }
    if ptr.is_null() {
        return Err(invalid(format!("{what} is NULL")));
    }
    Ok(std::slice::from_raw_parts_mut(ptr, len))
}

/// Writes a new handle into `*out`.
unsafe fn give<T>(out: *mut *mut T, value: T) -> Result<(), Failure> {
    if out.is_null() {
        return Err(invalid("out is NULL".into()));
    }
    *out = Box::into_raw(Box::new(value));
    Ok(())
}

unsafe fn write<T>(out: *mut T, value: T) -> Result<(), Failure> {
    if out.is_null() {
        return Err(invalid("out is NULL".into()));
    }
    *out = value;
    Ok(())
}

/// The version of the library, e.g. `"0.1.0"` (a static string, never NULL).
#[no_mangle]
pub extern "C" fn ofx_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

/// The message of the last failed `ofx_*` call on the calling thread (UTF-8, NUL-terminated;
/// empty if none failed yet). Never NULL. Owned by the library: valid until the next `ofx_*`
/// call on the same thread; copy it to keep it. Each thread has its own.
#[no_mangle]
pub extern "C" fn ofx_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

fn urdf_options(ee_links: Vec<String>, locked_joints: Vec<String>) -> UrdfOptions {
    UrdfOptions {
        ee_link: None,
        ee_links,
        locked_joints,
    }
}

/// Loads a robot from the URDF file at `path`. The root link is the floating base.
/// `ee_links`: the end-effector links, comma-separated (NULL or "": every leaf link).
/// `locked_joints`: joints held at zero and treated as fixed, comma-separated (NULL or "":
/// none). On success `*out` is a new robot, owned by the caller.
///
/// # Safety
/// `path` is a NUL-terminated string; `ee_links` and `locked_joints` are NUL-terminated or
/// NULL; `out` points to writable storage for one pointer.
#[no_mangle]
pub unsafe extern "C" fn ofx_robot_from_urdf_file(
    path: *const c_char,
    ee_links: *const c_char,
    locked_joints: *const c_char,
    out: *mut *mut OfxRobot,
) -> OfxStatus {
    guard("ofx_robot_from_urdf_file", || {
        let options = urdf_options(
            list(ee_links, "ee_links")?,
            list(locked_joints, "locked_joints")?,
        );
        let robot = Robot::from_urdf(text(path, "path")?, &options)?;
        give(out, OfxRobot { robot })
    })
}

/// Loads a robot from URDF text (`xml`), as `ofx_robot_from_urdf_file` does.
///
/// # Safety
/// As `ofx_robot_from_urdf_file`, with `xml` a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn ofx_robot_from_urdf_string(
    xml: *const c_char,
    ee_links: *const c_char,
    locked_joints: *const c_char,
    out: *mut *mut OfxRobot,
) -> OfxStatus {
    guard("ofx_robot_from_urdf_string", || {
        let options = urdf_options(
            list(ee_links, "ee_links")?,
            list(locked_joints, "locked_joints")?,
        );
        let robot = Robot::from_urdf_string(text(xml, "xml")?, &options)?;
        give(out, OfxRobot { robot })
    })
}

fn builtin_robot(name: &str) -> Result<Robot, Failure> {
    match name {
        "space_arm" => Ok(Robot::space_arm()),
        "dual_arm" => Ok(Robot::dual_arm()),
        _ => Err(invalid(format!(
            "unknown built-in model '{name}' (expected \"space_arm\" or \"dual_arm\")"
        ))),
    }
}

/// A built-in robot: `"space_arm"` (a 500 kg bus with a 7-joint arm, end-effector `ee`) or
/// `"dual_arm"` (the same bus with two such arms, end-effectors `left_ee`, `right_ee`).
///
/// # Safety
/// `name` is a NUL-terminated string; `out` points to writable storage for one pointer.
#[no_mangle]
pub unsafe extern "C" fn ofx_robot_builtin(
    name: *const c_char,
    out: *mut *mut OfxRobot,
) -> OfxStatus {
    guard("ofx_robot_builtin", || {
        let robot = builtin_robot(text(name, "name")?)?;
        give(out, OfxRobot { robot })
    })
}

/// The number of joints `n` of `robot` into `*out`.
///
/// # Safety
/// `robot` from `ofx_robot_*` (not freed); `out` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_robot_dof(robot: *const OfxRobot, out: *mut usize) -> OfxStatus {
    guard("ofx_robot_dof", || {
        write(out, reference(robot, "robot")?.robot.dof())
    })
}

/// The number of end-effectors `k` of `robot` into `*out`.
///
/// # Safety
/// `robot` from `ofx_robot_*` (not freed); `out` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_robot_ee_count(robot: *const OfxRobot, out: *mut usize) -> OfxStatus {
    guard("ofx_robot_ee_count", || {
        write(out, reference(robot, "robot")?.robot.end_effectors().len())
    })
}

/// The name of joint `i` (0-based, in the state's joint order) into `buf` (`len` bytes, NUL
/// included). `*needed` (if not NULL) receives the length the name needs, NUL included; a
/// buffer too short is an error (call first with `buf` NULL and `len` 0 to learn the length).
///
/// # Safety
/// `robot` from `ofx_robot_*`; `buf` writable for `len` bytes or NULL with `len` 0; `needed`
/// writable or NULL.
#[no_mangle]
pub unsafe extern "C" fn ofx_robot_joint_name(
    robot: *const OfxRobot,
    i: usize,
    buf: *mut c_char,
    len: usize,
    needed: *mut usize,
) -> OfxStatus {
    guard("ofx_robot_joint_name", || {
        let robot = &reference(robot, "robot")?.robot;
        let names = robot.joint_names();
        let name = names.get(i).ok_or_else(|| {
            invalid(format!(
                "joint {i} does not exist (the robot has {} joints)",
                names.len()
            ))
        })?;
        let size = name.len() + 1;
        if let Some(needed) = needed.as_mut() {
            *needed = size;
        }
        if buf.is_null() && len == 0 {
            return Ok(());
        }
        if buf.is_null() || len < size {
            return Err(invalid(format!(
                "the buffer holds {len} bytes; the name needs {size}"
            )));
        }
        std::ptr::copy_nonoverlapping(name.as_ptr().cast(), buf, name.len());
        *buf.add(name.len()) = 0;
        Ok(())
    })
}

/// Frees a robot. NULL is a no-op. Arms made from it stay valid (they hold their own copy).
///
/// # Safety
/// `robot` from `ofx_robot_*` or NULL, not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn ofx_robot_free(robot: *mut OfxRobot) {
    if !robot.is_null() {
        let _ = catch_unwind(AssertUnwindSafe(|| drop(Box::from_raw(robot))));
    }
}

/// An arm of `robot` with the Spong joint parameters given per joint (arrays of `n` numbers,
/// link side): `stiffness` k > 0 (N m/rad), `motor_inertia` j > 0 (kg m^2), `damping` d >= 0
/// and `motor_damping` beta >= 0 (N m s/rad). The robot is copied.
///
/// # Safety
/// `robot` from `ofx_robot_*`; the four arrays readable for `n` numbers; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_arm_new(
    robot: *const OfxRobot,
    stiffness: *const f64,
    motor_inertia: *const f64,
    damping: *const f64,
    motor_damping: *const f64,
    n: usize,
    out: *mut *mut OfxArm,
) -> OfxStatus {
    guard("ofx_arm_new", || {
        let robot = &reference(robot, "robot")?.robot;
        let dof = Some(robot.dof());
        let joints = FlexibleJoints::new(
            numbers(stiffness, n, dof, "stiffness")?.to_vec(),
            numbers(motor_inertia, n, dof, "motor_inertia")?.to_vec(),
            numbers(damping, n, dof, "damping")?.to_vec(),
            numbers(motor_damping, n, dof, "motor_damping")?.to_vec(),
        )?;
        let arm = FlexibleArm::new(robot.clone(), joints)?;
        give(out, OfxArm { arm })
    })
}

/// An arm of `robot` with the joint parameters of the TOML file at `path`: one table per
/// joint, `[joints.<name>]` with `stiffness`, `motor_inertia`, `damping`, `motor_damping`
/// (or the gear form; see docs/model.md). The robot is copied.
///
/// # Safety
/// `robot` from `ofx_robot_*`; `path` NUL-terminated; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_arm_from_toml_file(
    robot: *const OfxRobot,
    path: *const c_char,
    out: *mut *mut OfxArm,
) -> OfxStatus {
    guard("ofx_arm_from_toml_file", || {
        let robot = &reference(robot, "robot")?.robot;
        let joints = FlexibleJoints::from_toml_file(text(path, "path")?, &robot.joint_names())?;
        give(
            out,
            OfxArm {
                arm: FlexibleArm::new(robot.clone(), joints)?,
            },
        )
    })
}

/// As `ofx_arm_from_toml_file`, from the TOML text.
///
/// # Safety
/// As `ofx_arm_from_toml_file`, with `toml` NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ofx_arm_from_toml_string(
    robot: *const OfxRobot,
    toml: *const c_char,
    out: *mut *mut OfxArm,
) -> OfxStatus {
    guard("ofx_arm_from_toml_string", || {
        let robot = &reference(robot, "robot")?.robot;
        let joints =
            FlexibleJoints::from_toml_str(text(toml, "toml")?, &robot.joint_names(), "<toml>")?;
        give(
            out,
            OfxArm {
                arm: FlexibleArm::new(robot.clone(), joints)?,
            },
        )
    })
}

/// A built-in arm: `"space_arm"` or `"dual_arm"` (see `ofx_robot_builtin`) with its built-in
/// joint parameters (the same as Python's `orbitflex.models`).
///
/// # Safety
/// `name` NUL-terminated; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_arm_builtin(name: *const c_char, out: *mut *mut OfxArm) -> OfxStatus {
    guard("ofx_arm_builtin", || {
        let name = text(name, "name")?;
        let robot = builtin_robot(name)?;
        let joints = match name {
            "dual_arm" => FlexibleJoints::dual_arm(),
            _ => FlexibleJoints::space_arm(),
        };
        give(
            out,
            OfxArm {
                arm: FlexibleArm::new(robot, joints)?,
            },
        )
    })
}

/// A new arm: `arm` (copied) with the `count` reaction wheels `wheels` on its bus (replacing
/// any it had). The bus's inertia is the robot's base plus the wheels' masses and their
/// inertias locked to it; the state gains the `count` wheel speeds at its end, and simulators
/// of the new arm take wheel torque commands (`ofx_simulator_set_wheel_torque`). An invalid
/// wheel is refused, naming it (`spin_inertia[2]: expected ...`).
///
/// # Safety
/// `arm` from `ofx_arm_*`; `wheels` readable for `count` `OfxWheel`s; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_arm_with_wheels(
    arm: *const OfxArm,
    wheels: *const OfxWheel,
    count: usize,
    out: *mut *mut OfxArm,
) -> OfxStatus {
    guard("ofx_arm_with_wheels", || {
        let arm = &reference(arm, "arm")?.arm;
        if count == 0 {
            return Err(invalid(
                "count: expected at least one wheel, given 0 (an arm without wheels needs no \
                 call)"
                    .into(),
            ));
        }
        if wheels.is_null() {
            return Err(invalid("wheels is NULL".into()));
        }
        let given = std::slice::from_raw_parts(wheels, count);
        let wheels = given
            .iter()
            .map(|w| Wheel {
                axis: w.axis,
                position: w.position,
                mass: w.mass,
                spin_inertia: w.spin_inertia,
                transverse_inertia: w.transverse_inertia,
                max_torque: w.max_torque,
                max_speed: w.max_speed,
                friction: w.friction,
            })
            .collect();
        let wheels = ReactionWheels::new(wheels).map_err(|e| invalid(e.to_string()))?;
        give(
            out,
            OfxArm {
                arm: arm.clone().with_wheels(wheels)?,
            },
        )
    })
}

/// The number of reaction wheels of `arm` (0 without) into `*out`.
///
/// # Safety
/// `arm` from `ofx_arm_*`; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_arm_wheel_count(arm: *const OfxArm, out: *mut usize) -> OfxStatus {
    guard("ofx_arm_wheel_count", || {
        write(out, reference(arm, "arm")?.arm.layout().wheels)
    })
}

/// The number of joints `n` of `arm` into `*out`.
///
/// # Safety
/// `arm` from `ofx_arm_*`; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_arm_dof(arm: *const OfxArm, out: *mut usize) -> OfxStatus {
    guard("ofx_arm_dof", || {
        write(out, reference(arm, "arm")?.arm.dof())
    })
}

/// The length of `arm`'s state, `13 + 4 n + w` (`w` reaction wheels, 0 without), into
/// `*out`. The state is `[r_B (3, m, inertial); quat_B (4: x, y, z, w, base to inertial);
/// q (n, rad); theta (n, rad, link side); omega_B (3, rad/s, base frame); v_B (3, m/s, base
/// frame); dq (n, rad/s); dtheta (n, rad/s); wheel speeds (w, rad/s, relative to the bus)]`.
///
/// # Safety
/// `arm` from `ofx_arm_*`; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_arm_state_len(arm: *const OfxArm, out: *mut usize) -> OfxStatus {
    guard("ofx_arm_state_len", || {
        write(out, reference(arm, "arm")?.arm.layout().len())
    })
}

/// A state at rest into `x` (`len` = `ofx_arm_state_len`): the base at the origin with identity
/// attitude, link angles `q` (n numbers, or NULL for zero), motors at the same angles (springs
/// relaxed), the wheels (if any) still relative to the bus.
///
/// # Safety
/// `arm` from `ofx_arm_*`; `q` readable for n numbers or NULL; `x` writable for `len` numbers.
#[no_mangle]
pub unsafe extern "C" fn ofx_arm_rest_state(
    arm: *const OfxArm,
    q: *const f64,
    x: *mut f64,
    len: usize,
) -> OfxStatus {
    guard("ofx_arm_rest_state", || {
        let arm = &reference(arm, "arm")?.arm;
        let q = if q.is_null() {
            None
        } else {
            Some(numbers(q, arm.dof(), None, "q")?)
        };
        let state = arm.state(&StateSpec {
            q,
            ..StateSpec::default()
        })?;
        buffer(x, len, state.len(), "x")?.copy_from_slice(&state);
        Ok(())
    })
}

/// Frees an arm. NULL is a no-op. Simulators made from it stay valid (they hold their own copy).
///
/// # Safety
/// `arm` from `ofx_arm_*` or NULL, not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn ofx_arm_free(arm: *mut OfxArm) {
    if !arm.is_null() {
        let _ = catch_unwind(AssertUnwindSafe(|| drop(Box::from_raw(arm))));
    }
}

/// A simulator of `arm` (copied) at state `x0` (`len` = `ofx_arm_state_len`; the quaternion
/// is normalised), time 0, RK4 step `dt` (s, finite and > 0), every input zero.
///
/// A sequence of `ofx_simulator_step` calls computes, bit for bit, the states of orbitflex's
/// `simulate` (Rust and Python) with the same inputs held over the same steps.
///
/// # Safety
/// `arm` from `ofx_arm_*`; `x0` readable for `len` numbers; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_new(
    arm: *const OfxArm,
    x0: *const f64,
    len: usize,
    dt: f64,
    out: *mut *mut OfxSimulator,
) -> OfxStatus {
    guard("ofx_simulator_new", || {
        let arm = &reference(arm, "arm")?.arm;
        let x0 = numbers(x0, len, Some(arm.layout().len()), "x0")?;
        let sim = Simulator::new(arm.clone(), x0, dt)?;
        let outputs = Outputs::for_arm(sim.arm());
        give(
            out,
            OfxSimulator {
                inner: Mutex::new(Stepping {
                    sim,
                    outputs,
                    fresh: false,
                }),
            },
        )
    })
}

/// Runs `body` on the simulator, if no other thread is using it.
unsafe fn with_sim(
    function: &str,
    sim: *mut OfxSimulator,
    body: impl FnOnce(&mut Stepping) -> Result<(), Failure>,
) -> OfxStatus {
    guard(function, || {
        let sim = reference(sim, "sim")?;
        let mut inner = match sim.inner.try_lock() {
            Ok(inner) => inner,
            // a panic left it valid: a failed step is undone
            Err(TryLockError::Poisoned(p)) => p.into_inner(),
            Err(TryLockError::WouldBlock) => {
                return Err(Failure(
                    OfxStatus::Busy,
                    "another thread is using this simulator (use one simulator from one \
                     thread at a time)"
                        .into(),
                ))
            }
        };
        body(&mut inner)
    })
}

/// Holds the motor torques `u` (`n` numbers, N m, link side) from the next step on.
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `u` readable for `n` numbers.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_set_motor_torque(
    sim: *mut OfxSimulator,
    u: *const f64,
    n: usize,
) -> OfxStatus {
    with_sim("ofx_simulator_set_motor_torque", sim, |s| {
        let u = numbers(u, n, Some(s.sim.arm().dof()), "u")?;
        Ok(s.sim.set_motor_torque(u)?)
    })
}

/// Holds the base wrench `[moment (N m); force (N)]` (6 numbers, base frame, applied to the
/// base by its actuators) from the next step on.
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `wrench` readable for `len` numbers.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_set_base_wrench(
    sim: *mut OfxSimulator,
    wrench: *const f64,
    len: usize,
) -> OfxStatus {
    with_sim("ofx_simulator_set_base_wrench", sim, |s| {
        Ok(s.sim
            .set_base_wrench(numbers(wrench, len, Some(6), "wrench")?)?)
    })
}

/// Holds the reaction-wheel torque commands (`w` numbers, N m, each applied to its wheel about
/// its axis; the bus feels the opposite) from the next step on. Each step clips them, at its
/// start, to the wheel's `max_torque` and, for a wheel at or beyond `max_speed`, to none that
/// would speed it up (as orbitflex's `simulate` does); `OFX_OUTPUT_APPLIED_WHEEL_TORQUE`
/// gives what was applied. An arm without wheels refuses any command.
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `torque` readable for `w` numbers.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_set_wheel_torque(
    sim: *mut OfxSimulator,
    torque: *const f64,
    w: usize,
) -> OfxStatus {
    with_sim("ofx_simulator_set_wheel_torque", sim, |s| {
        let k = s.sim.arm().layout().wheels;
        if k == 0 {
            return Err(invalid(
                "the arm has no reaction wheels (add them with ofx_arm_with_wheels)".into(),
            ));
        }
        let torque = numbers(torque, w, Some(k), "torque")?;
        Ok(s.sim.set_wheel_torque(torque)?)
    })
}

/// Holds the end-effector wrenches (6 k numbers: per end-effector `[moment (N m); force (N)]`
/// in its EE frame, exerted by the end-effector on its environment) from the next step on;
/// `len` 0 (with `wrench` NULL) holds none.
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `wrench` readable for `len` numbers.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_set_ee_wrench(
    sim: *mut OfxSimulator,
    wrench: *const f64,
    len: usize,
) -> OfxStatus {
    with_sim("ofx_simulator_set_ee_wrench", sim, |s| {
        let k = s.sim.arm().robot().end_effectors().len();
        if len != 0 && len != 6 * k {
            return Err(invalid(format!(
                "wrench: expected length 0 (none) or {} (6 per end-effector), given {len}",
                6 * k
            )));
        }
        let f = numbers(wrench, len, None, "wrench")?;
        Ok(s.sim.set_ee_wrench((len > 0).then_some(f))?)
    })
}

/// Takes `n` RK4 steps of `dt` with the held inputs. Allocates nothing. A step that diverges
/// is undone and returns `OFX_STATUS_SIMULATION_ERROR` (the message names the step and
/// time); the simulator keeps the state and time before that step.
///
/// # Safety
/// `sim` from `ofx_simulator_new`.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_step(sim: *mut OfxSimulator, n: usize) -> OfxStatus {
    with_sim("ofx_simulator_step", sim, |s| {
        s.fresh = false;
        Ok(s.sim.step(n)?)
    })
}

/// The time `t = k dt` (s) into `*t` (from the step count `k`: no accumulated round-off).
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `t` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_time(sim: *mut OfxSimulator, t: *mut f64) -> OfxStatus {
    with_sim("ofx_simulator_time", sim, |s| write(t, s.sim.t()))
}

/// The number of steps taken since the start (or the last reset) into `*steps`.
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `steps` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_steps(sim: *mut OfxSimulator, steps: *mut u64) -> OfxStatus {
    with_sim("ofx_simulator_steps", sim, |s| write(steps, s.sim.steps()))
}

/// The state (`ofx_arm_state_len` numbers; layout there) into `x` (`len` numbers).
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `x` writable for `len` numbers.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_state(
    sim: *mut OfxSimulator,
    x: *mut f64,
    len: usize,
) -> OfxStatus {
    with_sim("ofx_simulator_state", sim, |s| {
        let state = s.sim.state();
        buffer(x, len, state.len(), "x")?.copy_from_slice(state);
        Ok(())
    })
}

fn output_slice(out: &Outputs, which: u32) -> Result<&[f64], Failure> {
    Ok(match which {
        0 => &out.q,
        1 => &out.qd,
        2 => &out.theta,
        3 => &out.theta_dot,
        4 => &out.deflection,
        5 => &out.spring_torque,
        6 => &out.base_pose,
        7 => &out.base_twist,
        8 => &out.ee_poses,
        9 => &out.momentum,
        10 => std::slice::from_ref(&out.energy),
        11 => &out.wheel_speed,
        12 => &out.applied_wheel_torque,
        _ => {
            return Err(invalid(format!(
                "unknown output {which} (expected an OfxOutput, 0 to 12)"
            )))
        }
    })
}

/// The number of values of output `which` (an `OfxOutput`) into `*len`.
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `len` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_output_len(
    sim: *mut OfxSimulator,
    which: u32,
    len: *mut usize,
) -> OfxStatus {
    with_sim("ofx_simulator_output_len", sim, |s| {
        write(len, output_slice(&s.outputs, which)?.len())
    })
}

/// Output `which` (an `OfxOutput`) at the current state into `buf` (`len` numbers, exactly
/// `ofx_simulator_output_len`'s). The outputs are computed once per state and reused by the
/// next reads. Allocates nothing.
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `buf` writable for `len` numbers.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_output(
    sim: *mut OfxSimulator,
    which: u32,
    buf: *mut f64,
    len: usize,
) -> OfxStatus {
    with_sim("ofx_simulator_output", sim, |s| {
        let expected = output_slice(&s.outputs, which)?.len();
        let buf = buffer(buf, len, expected, "buf")?;
        // the parts of the state are copied from it: a loop reading q or theta every step
        // does not pay for the momentum and energy
        let layout = s.sim.arm().layout();
        let x = s.sim.state();
        let part = match which {
            0 => Some(layout.q()),
            1 => Some(layout.qd()),
            2 => Some(layout.theta()),
            3 => Some(layout.theta_dot()),
            6 => Some(layout.base_pose()),
            7 => Some(layout.base_twist()),
            11 => Some(layout.wheel_speed()),
            _ => None,
        };
        if let Some(range) = part {
            buf.copy_from_slice(&x[range]);
            return Ok(());
        }
        if which == 12 {
            buf.copy_from_slice(s.sim.applied_wheel_torque());
            return Ok(());
        }
        if which == 4 {
            let (q, theta) = (&x[layout.q()], &x[layout.theta()]);
            for ((d, t), q) in buf.iter_mut().zip(theta).zip(q) {
                *d = t - q;
            }
            return Ok(());
        }
        if !s.fresh {
            s.sim.outputs_into(&mut s.outputs);
            s.fresh = true;
        }
        buf.copy_from_slice(output_slice(&s.outputs, which)?);
        Ok(())
    })
}

/// The length in bytes of `ofx_simulator_save`'s record into `*len` (it changes only when
/// end-effector wrenches start or stop being held).
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `len` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_saved_len(
    sim: *mut OfxSimulator,
    len: *mut usize,
) -> OfxStatus {
    with_sim("ofx_simulator_saved_len", sim, |s| {
        write(len, s.sim.saved_len())
    })
}

/// Saves the simulator (state, step count, dt, held inputs, with a format version and the
/// arm's fingerprint) into `buf` (`len` bytes, at least `ofx_simulator_saved_len`);
/// `*written` receives the bytes written. The record is little-endian and portable between
/// machines; `ofx_simulator_restore` puts it back bit for bit.
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `buf` writable for `len` bytes; `written` writable.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_save(
    sim: *mut OfxSimulator,
    buf: *mut u8,
    len: usize,
    written: *mut usize,
) -> OfxStatus {
    with_sim("ofx_simulator_save", sim, |s| {
        let blob = s.sim.save();
        if written.is_null() {
            return Err(invalid("written is NULL".into()));
        }
        if len < blob.len() {
            return Err(invalid(format!(
                "the buffer holds {len} bytes; the record needs {}",
                blob.len()
            )));
        }
        if buf.is_null() {
            return Err(invalid("buf is NULL".into()));
        }
        std::ptr::copy_nonoverlapping(blob.as_ptr(), buf, blob.len());
        *written = blob.len();
        Ok(())
    })
}

/// Puts back a record from `ofx_simulator_save` of a simulator of the same arm (model, joint
/// parameters) and dt. A record of another arm or format version, or damaged, is refused
/// (`OFX_STATUS_INVALID_ARGUMENT`, saying which) and changes nothing.
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `buf` readable for `len` bytes.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_restore(
    sim: *mut OfxSimulator,
    buf: *const u8,
    len: usize,
) -> OfxStatus {
    with_sim("ofx_simulator_restore", sim, |s| {
        if buf.is_null() {
            return Err(invalid("buf is NULL".into()));
        }
        s.sim.restore(std::slice::from_raw_parts(buf, len))?;
        s.fresh = false;
        Ok(())
    })
}

/// Back to time 0 at state `x0` (`len` = `ofx_arm_state_len`), every input zero.
///
/// # Safety
/// `sim` from `ofx_simulator_new`; `x0` readable for `len` numbers.
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_reset(
    sim: *mut OfxSimulator,
    x0: *const f64,
    len: usize,
) -> OfxStatus {
    with_sim("ofx_simulator_reset", sim, |s| {
        let x0 = numbers(x0, len, Some(s.sim.state().len()), "x0")?;
        s.sim.reset(x0)?;
        s.fresh = false;
        Ok(())
    })
}

/// Frees a simulator. NULL is a no-op.
///
/// # Safety
/// `sim` from `ofx_simulator_new` or NULL, not used afterwards (and not in use by another
/// thread).
#[no_mangle]
pub unsafe extern "C" fn ofx_simulator_free(sim: *mut OfxSimulator) {
    if !sim.is_null() {
        let _ = catch_unwind(AssertUnwindSafe(|| drop(Box::from_raw(sim))));
    }
}

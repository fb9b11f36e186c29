//! The arguments every dynamics function takes, as small types, and the checks each public entry
//! point runs on them.
//!
//! This module sits below both the recursive algorithms ([`crate::algorithms`]) and the operator
//! form ([`crate::operators`]), so neither depends on the other for its argument checks.
//!
//! ```
//! use orbitflex::{Loads, RigidState, Robot};
//! let robot = Robot::space_arm();
//! let q = vec![0.0; 7];
//! assert!(RigidState::new(&q, &[0.0; 6], &q).check(&robot).is_ok());
//! let err = RigidState::new(&q[..6], &[0.0; 6], &q).check(&robot).unwrap_err();
//! assert_eq!(err.to_string(), "q: expected length 7, given length 6");
//! // a 10 N push along the base x axis, nothing at the EE
//! let loads = Loads::from_slices(Some(&[0.0, 0.0, 0.0, 10.0, 0.0, 0.0]), None)?;
//! assert_eq!(loads.base_wrench.linear.x, 10.0);
//! # Ok::<(), orbitflex::Error>(())
//! ```

use crate::error::{Error, Result};
use crate::model::Robot;
use crate::spatial::Force;

/// The rigid system's configuration and velocity: joint angles `q` (rad, n), the base twist
/// `V_B = [ω_B; v_B]` (rad/s, m/s; base-frame components, 6) and joint rates `q̇` (rad/s, n).
///
/// The base pose is not part of it: without gravity the dynamics do not depend on it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidState<'a> {
    /// Joint angles `q` (rad), base to tip.
    pub q: &'a [f64],
    /// Base twist `[ω_B; v_B]` in base-frame components.
    pub base_twist: &'a [f64],
    /// Joint rates `q̇` (rad/s).
    pub qd: &'a [f64],
}

/// Zero twist, for states at rest.
const ZERO6: [f64; 6] = [0.0; 6];

impl<'a> RigidState<'a> {
    /// Bundles `q`, `V_B` and `q̇`; [`RigidState::check`] validates them against a robot.
    pub fn new(q: &'a [f64], base_twist: &'a [f64], qd: &'a [f64]) -> Self {
        Self { q, base_twist, qd }
    }

    /// The system at rest at angles `q`: `V_B = 0`, and `q̇ = zeros` (a slice of `q.len()` zeros
    /// supplied by the caller, so that nothing is allocated).
    pub fn at_rest(q: &'a [f64], zeros: &'a [f64]) -> Self {
        Self {
            q,
            base_twist: &ZERO6,
            qd: zeros,
        }
    }

    /// Checks the lengths against `robot` (n, 6, n) and that every element is finite.
    #[inline]
    pub fn check(&self, robot: &Robot) -> Result<()> {
        let n = robot.dof();
        check_vector("q", self.q, n)?;
        check_vector("base_twist", self.base_twist, 6)?;
        check_vector("qd", self.qd, n)
    }
}

/// External loads on the rigid system (A.19).
///
/// - `base_wrench` is `f_B`: the spatial force `[moment; force]` the base's own actuators apply
///   to it (thrusters, reaction-wheel torque), base frame, about the base origin (N·m, N).
/// - `ee_wrench` is `[f_1; …; f_k]`, six numbers per end-effector in
///   [`Robot::ee_links`](crate::Robot::ee_links) order: `f_e` is the spatial force `[moment;
///   force]` end-effector `e` exerts ON its environment, in its own frame, about its origin. A
///   load the environment applies to the EE is `−f_e`. An empty slice means no EE wrench; a
///   robot with one end-effector takes the six numbers of `f`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Loads<'a> {
    /// `f_B`, base frame.
    pub base_wrench: Force,
    /// `[f_1; …; f_k]` (6k numbers), or empty for none.
    pub ee_wrench: &'a [f64],
}

impl<'a> Loads<'a> {
    /// No external load: `f_B = 0`, `f = 0` (free floating).
    pub const ZERO: Loads<'static> = Loads {
        base_wrench: Force::ZERO,
        ee_wrench: &[],
    };

    /// From `[moment; force]` slices (`None`: zero): `base_wrench` of length 6, `ee_wrench` of
    /// length 6 per end-effector, checked for finiteness and for a whole number of wrenches (the
    /// count is checked against the robot where the loads are used).
    pub fn from_slices(base_wrench: Option<&[f64]>, ee_wrench: Option<&'a [f64]>) -> Result<Self> {
        let base_wrench = match base_wrench {
            Some(v) => {
                check_vector("base_wrench", v, 6)?;
                Force::from_slice(v)
            }
            None => Force::ZERO,
        };
        let ee_wrench = ee_wrench.unwrap_or(&[]);
        let loads = Self {
            base_wrench,
            ee_wrench,
        };
        loads.check()?;
        if ee_wrench.len() % 6 != 0 {
            return Err(Error::InvalidArgument {
                what: "ee_wrench".into(),
                message: format!(
                    "expected 6 numbers per end-effector, given {}",
                    ee_wrench.len()
                ),
            });
        }
        Ok(loads)
    }

    /// Checks that every wrench is finite.
    #[inline]
    pub fn check(&self) -> Result<()> {
        let base = self.base_wrench.to_array();
        if base.iter().chain(self.ee_wrench).all(|v| v.is_finite()) {
            return Ok(());
        }
        check_finite("base_wrench", &base)?;
        check_finite("ee_wrench", self.ee_wrench)
    }

    /// [`check`](Self::check), and that `ee_wrench` has one wrench per end-effector of `robot`
    /// (or none).
    #[inline]
    pub fn check_for(&self, robot: &crate::Robot) -> Result<()> {
        let base = self.base_wrench.to_array();
        if !base.iter().all(|v| v.is_finite()) {
            return check_finite("base_wrench", &base);
        }
        check_ee_wrench(robot, self.ee_wrench)
    }
}

/// The error for an EE wrench of the wrong length, naming the end-effectors.
#[cold]
pub(crate) fn ee_wrench_length_error(robot: &crate::Robot, given: usize) -> Error {
    let k = robot.end_effectors().len();
    Error::InvalidArgument {
        what: "ee_wrench".into(),
        message: format!(
            "expected {} numbers (one [moment; force] per end-effector: {}), given {given}",
            6 * k,
            robot.ee_links().join(", ")
        ),
    }
}

/// Checks an EE wrench slice against the robot: empty, or 6 finite numbers per end-effector.
#[inline]
pub fn check_ee_wrench(robot: &crate::Robot, ee_wrench: &[f64]) -> Result<()> {
    let k = robot.end_effectors().len();
    if !ee_wrench.is_empty() && ee_wrench.len() != 6 * k {
        return Err(ee_wrench_length_error(robot, ee_wrench.len()));
    }
    // the common case in a few instructions per element; the message only when it fails
    if ee_wrench.iter().all(|v| v.is_finite()) {
        return Ok(());
    }
    check_finite("ee_wrench", ee_wrench)
}

/// Checks that `values` has `expected` elements, all finite.
#[inline]
pub fn check_vector(what: &str, values: &[f64], expected: usize) -> Result<()> {
    // the common case in a few instructions per element; the messages only when it fails
    if values.len() == expected && values.iter().all(|v| v.is_finite()) {
        return Ok(());
    }
    vector_error(what, values, expected)
}

#[cold]
#[inline(never)]
fn vector_error(what: &str, values: &[f64], expected: usize) -> Result<()> {
    check_length(what, values.len(), expected)?;
    check_finite(what, values)
}

/// Checks a length: `what: expected length N, given length M`.
pub fn check_length(what: &str, given: usize, expected: usize) -> Result<()> {
    if given != expected {
        return Err(Error::Dimension {
            what: what.to_string(),
            expected: format!("length {expected}"),
            given: format!("length {given}"),
        });
    }
    Ok(())
}

/// Checks that every element of `values` is finite.
pub fn check_finite(what: &str, values: &[f64]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(Error::NonFinite {
            what: what.to_string(),
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}

/// Checks a base pose `[r_B (3); quat_B (4) as (x, y, z, w)]`: 7 finite numbers and a quaternion
/// of non-zero norm (it is normalised where it is used).
pub fn check_base_pose(base_pose: &[f64]) -> Result<()> {
    check_vector("base_pose", base_pose, 7)?;
    let norm = base_pose[crate::spatial::POSE_QUATERNION]
        .iter()
        .map(|v| v * v)
        .sum::<f64>()
        .sqrt();
    if !norm.is_finite() {
        return Err(Error::InvalidArgument {
            what: "base_pose".into(),
            message: "the quaternion (elements 3..7, x y z w) is too large to normalise; expected \
                      a unit quaternion"
                .into(),
        });
    }
    if norm < 1e-9 {
        return Err(Error::InvalidArgument {
            what: "base_pose".into(),
            message:
                "the quaternion (elements 3..7, x y z w) has zero norm; expected a unit quaternion"
                    .into(),
        });
    }
    Ok(())
}

/// The largest dense buffer allocated on request, in bytes (1 GiB): the operator form of about
/// 1,800 joints, or the mass matrix of about 11,000.
pub const MAX_DENSE_BYTES: usize = 1 << 30;

/// Checks, before allocating, that `count` dense `rows × cols` matrices of `f64` fit within
/// [`MAX_DENSE_BYTES`]; `what` and `instead` say what was asked and what to use otherwise.
pub fn check_dense(
    what: &str,
    rows: usize,
    cols: usize,
    count: usize,
    instead: &str,
) -> Result<()> {
    let bytes = rows
        .checked_mul(cols)
        .and_then(|v| v.checked_mul(count))
        .and_then(|v| v.checked_mul(8));
    match bytes {
        Some(b) if b <= MAX_DENSE_BYTES => Ok(()),
        _ => Err(Error::InvalidArgument {
            what: what.to_string(),
            message: format!(
                "the dense form needs {count} matrices of {rows}×{cols} ({}), more than the \
                 {} allowed; {instead}",
                describe_bytes(bytes),
                describe_bytes(Some(MAX_DENSE_BYTES))
            ),
        }),
    }
}

/// A number for a message: plain between 1e-3 and 1e6 (`30`, `0.5`), in exponent form outside
/// (`1e-320`, `2.5e299`), never hundreds of digits.
pub fn number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-3..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// [`number`] rounded to four significant digits, for measured quantities in messages
/// (`105.9`, not `105.88242839002942`).
pub fn short(x: f64) -> String {
    number(format!("{x:.3e}").parse().unwrap_or(x))
}

/// A byte count for messages: `2.6 GB`.
pub fn describe_bytes(bytes: Option<usize>) -> String {
    match bytes {
        Some(b) if b >= 1_000_000_000 => format!("{:.1} GB", b as f64 / 1e9),
        Some(b) => format!("{:.1} MB", b as f64 / 1e6),
        None => "more bytes than an address can hold".into(),
    }
}

/// An array shape as numpy prints it: `(7,)`, `(4, 60, 7)`.
pub fn describe_shape(shape: &[usize]) -> String {
    match shape {
        [a] => format!("({a},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Checks a time step: finite and `> 0` (s).
pub fn check_dt(dt: f64) -> Result<()> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(Error::InvalidArgument {
            what: "dt".into(),
            message: format!("expected a finite step > 0 s, given {dt}"),
        });
    }
    Ok(())
}

/// The domain of a parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Domain {
    /// `> 0`
    Positive,
    /// `≥ 0`
    NonNegative,
}

impl Domain {
    pub(crate) fn contains(self, v: f64) -> bool {
        match self {
            Domain::Positive => v > 0.0,
            Domain::NonNegative => v >= 0.0,
        }
    }
    pub(crate) fn describe(self) -> &'static str {
        match self {
            Domain::Positive => "> 0",
            Domain::NonNegative => ">= 0",
        }
    }
}

/// Checks `n` finite values in `domain`; errors name the element, e.g. `stiffness[2]`.
pub(crate) fn check_parameter(what: &str, values: &[f64], n: usize, domain: Domain) -> Result<()> {
    check_vector(what, values, n)?;
    match values.iter().position(|&v| !domain.contains(v)) {
        Some(i) => Err(Error::InvalidArgument {
            what: format!("{what}[{i}]"),
            message: format!("expected {}, given {}", domain.describe(), values[i]),
        }),
        None => Ok(()),
    }
}

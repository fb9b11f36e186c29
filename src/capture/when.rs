//! When a run captures its target: [`CaptureWhen`], three tolerances on how the end-effector
//! meets the handle, and [`Approach`], the three numbers they are judged on.
//!
//! With `e` the end-effector frame and `g` the handle's frame (fixed in the target, [`Target`]'s
//! `grasp`), at a state of the arm and of the target:
//!
//! - `distance = |o_g − o_e|` (m): how far the handle's origin is from the EE origin;
//! - `speed = |v_rel|` (m/s): the linear part of `V_rel = V_e − Φ_{e,t} W` (EE frame), the
//!   velocity of the EE origin relative to the point of the target that it is passing through;
//! - `angle` (rad, in `[0, π]`): the angle of the rotation from `e`'s axes to `g`'s.
//!
//! A run captures at the first step whose starting state has all three within their
//! tolerances (each test `≤`). The relative angular rate is not gated: the impulse absorbs it,
//! and its share of the energy loss is reported with the event.

use super::impulse::ee_twist;
use super::target::Target;
use crate::algorithms::Data;
use crate::error::{Error, Result};
use crate::flex::FlexibleArm;
use crate::spatial::rotation_angle;

/// The tolerances of a capture in a run (module docs): the EE within `distance` (m) of the
/// handle, moving relative to the target at at most `speed` (m/s), its axes within `angle`
/// (rad) of the handle's. Each must be finite and > 0.
///
/// ```
/// use orbitflex::capture::CaptureWhen;
/// let when = CaptureWhen::new(0.02, 0.05, 5f64.to_radians())?;
/// assert!(CaptureWhen::new(0.0, 0.05, 0.1).is_err()); // a tolerance must be > 0
/// # Ok::<(), orbitflex::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CaptureWhen {
    /// Largest distance from the EE origin to the handle's origin (m).
    pub distance: f64,
    /// Largest speed of the EE origin relative to the target (m/s).
    pub speed: f64,
    /// Largest angle between the EE's axes and the handle's (rad).
    pub angle: f64,
}

impl CaptureWhen {
    /// The three tolerances, each checked finite and > 0.
    pub fn new(distance: f64, speed: f64, angle: f64) -> Result<Self> {
        let when = Self {
            distance,
            speed,
            angle,
        };
        when.check()?;
        Ok(when)
    }

    /// Each tolerance finite and > 0 (a tolerance of 0 could only trigger on an exact
    /// coincidence of floating-point numbers).
    pub fn check(&self) -> Result<()> {
        for (what, value, unit) in [
            ("distance", self.distance, "m"),
            ("speed", self.speed, "m/s"),
            ("angle", self.angle, "rad"),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(Error::InvalidArgument {
                    what: format!("CaptureWhen.{what}"),
                    message: format!("expected a finite tolerance > 0 {unit}, given {value}"),
                });
            }
        }
        Ok(())
    }

    /// Whether `approach` is within all three tolerances.
    pub fn is_met(&self, approach: &Approach) -> bool {
        approach.distance <= self.distance
            && approach.speed <= self.speed
            && approach.angle <= self.angle
    }
}

/// How end-effector `ee` meets the handle (module docs): distance (m), relative speed (m/s) and
/// angle (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Approach {
    /// `|o_g − o_e|` (m).
    pub distance: f64,
    /// `|v_rel|` (m/s).
    pub speed: f64,
    /// The angle from the EE's axes to the handle's (rad).
    pub angle: f64,
}

impl Approach {
    /// The approach of end-effector `ee` of `arm` at state `x` (unchecked) to `target`'s handle,
    /// with `data` as scratch.
    pub fn measure(
        arm: &FlexibleArm,
        data: &mut Data,
        x: &[f64],
        target: &Target,
        ee: usize,
    ) -> Self {
        let ee_pose = arm.ee_pose(x, ee);
        let handle = target.grasp_pose();
        let distance = (0..3)
            .map(|i| (handle[i] - ee_pose[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        let angle = rotation_angle(&ee_pose[3..], &handle[3..]);
        let layout = arm.layout();
        let x_et = super::impulse::target_to_ee(
            arm.robot(),
            &x[layout.base_pose()],
            &x[layout.q()],
            target,
            ee,
        );
        let relative =
            ee_twist(arm.robot(), data, x, &layout, ee) - x_et.apply_motion(target.twist());
        Self {
            distance,
            speed: relative.linear.norm(),
            angle,
        }
    }
}

//! Minimum-time rest-to-rest slews under motor-torque, joint-speed and base-actuation limits
//! (docs/model.md §8.2), and their per-step tables for [`crate::integrate::simulate()`].
//!
//! The path shape is fixed and time-scaled, as in the paper: between consecutive stops (start,
//! waypoints, goal) `q(t) = q_a + (q_b − q_a) σ(t/T)` with the degree-9 polynomial
//! `σ(s) = 126 s⁵ − 420 s⁶ + 540 s⁷ − 315 s⁸ + 70 s⁹`, whose derivatives 1–4 vanish at both
//! ends: the arm starts and stops at rest, and `u`, which depends on `q⁗`, starts and ends at zero
//! rate. The planner finds, per segment, the shortest `T` for which every limit holds.
//!
//! Time scaling makes this cheap. With `w = 1/T`, in zero gravity the rigid dynamics scale
//! exactly: `τ(t) = τ₁(s) w²`, `τ̇ = τ₁'(s) w³`, `τ̈ = τ₁''(s) w⁴`, `V_B = V₁(s) w`,
//! `f_B = f₁(s) w²`, where `τ₁`, `V₁`, `f₁` are the inverse dynamics of the unit-duration path
//! with their `s`-derivatives. So the jet recursion runs once per sample; every trial duration
//! only rescales, integrates the deflection (when the joints are damped) and compares with the
//! limits. The shortest duration is bracketed and bisected to 1e-10 relative. Samples: 512
//! intervals per segment, plus, after each solve, the vertex of a parabola through every local
//! peak within 2% of its limit (then solved again; a vertex closer than 1e-4 to a sample moves
//! that sample onto it), up to six rounds, so a peak between samples is not missed.

use super::deflection;
use super::limits::{BaseBound, BaseLimits, BasePoint};
use crate::args::{check_dt, check_vector, number};
use crate::error::{Error, Result};
use crate::flex::inverse::{
    classical, rigid_jets, system_com, BaseMode, FlexibleInverse, JetScratch, RigidJets,
};
use crate::flex::FlexibleArm;
use crate::integrate::{OdeSystem, Rk4};
use crate::spatial::{base_pose_rate, normalise_quaternion, Motion, Vec3, POSE_QUATERNION};
use std::sync::atomic::{AtomicBool, Ordering};

/// Sample intervals per segment (a power of two, so `s = 1/2`, where the speed peaks, is one).
const INTERVALS: usize = 512;
/// Relative width of the final duration bracket.
const BISECTION_TOLERANCE: f64 = 1e-10;
/// Peaks within this fraction of their limit are refined between samples.
const REFINE_ABOVE: f64 = 0.98;
/// The closest two samples may be (in `s`): shorter intervals would amplify round-off in the
/// deflection's second rate (`deflection::advance`).
const MIN_SPACING: f64 = 1e-4;
/// A peak's vertex closer than [`MIN_SPACING`] to a sample moves that sample onto it, unless it
/// is already this close.
const MOVE_AT_LEAST: f64 = 1e-12;
/// Rounds of solving and refining the peaks (each round adds or moves samples at the vertices).
const REFINE_ROUNDS: usize = 6;
/// How far back (in `s`) [`Plan::evaluate`] starts integrating the deflection from a sample.
const LOOKBACK: f64 = 1.0 / 1024.0;
/// Consecutive stops closer than this in every joint (rad) are refused.
pub const NOTHING_TO_SLEW: f64 = 1e-12;
/// The shortest segment duration tried (s): a speed limit that allows less (a huge number given
/// to mean "no speed limit") starts the search here.
const SHORTEST_TRIED: f64 = 1e-9;
/// The longest segment duration tried (s, about 32 years): limits that need more are refused.
const LONGEST_TRIED: f64 = 1e9;

/// `σ(s)` and its first four derivatives, for `s ∈ [0, 1]`.
///
/// `σ` is the regularised incomplete beta function `I_s(5, 5)`, so its derivatives factor in
/// `u = s (1 − s)` and `v = 1 − 2s`:
/// `σ' = 630 u⁴`, `σ'' = 2520 u³ v`, `σ''' = 2520 u² (3v² − 2u)`, `σ'''' = 15120 u v (v² − 3u)`,
/// and `σ` itself is the Bernstein sum `Σ_{j=5}^{9} C(9, j) sʲ (1 − s)^{9−j}`, whose terms are all
/// positive. Each value is then within a few ulps of the exact one (or, near a root of `σ'''` or
/// `σ''''`, within a few ulps of the function's scale). The monomial coefficients
/// `126, −420, 540, −315, 70` would cancel: up to 1471 ulps of error in `σ` and 10⁶ in `σ''''`
/// (up to 350 ulps in a planned `q̇`), so that any other evaluation of the same path (numpy's,
/// whose `power` rounds differently on AVX-512) disagrees with it in those digits.
pub fn sigma(s: f64) -> [f64; 5] {
    let r = 1.0 - s;
    let u = s * r;
    let v = 1.0 - 2.0 * s;
    let (s2, r2) = (s * s, r * r);
    let bernstein = s2
        * s2
        * s
        * (126.0 * r2 * r2 + 84.0 * s * r2 * r + 36.0 * s2 * r2 + 9.0 * s2 * s * r + s2 * s2);
    let u2 = u * u;
    [
        bernstein,
        630.0 * u2 * u2,
        2520.0 * u2 * u * v,
        2520.0 * u2 * (3.0 * v * v - 2.0 * u),
        15120.0 * u * v * (v * v - 3.0 * u),
    ]
}

/// Bounds for a slew. Motor torque and joint speed are per joint (n values); the base limits
/// bound the Euclidean norms of the force and the moment the base actuators apply (held base
/// only; `None` means unbounded, and they do not apply to a free-floating base).
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    /// `u_max,i` > 0: `|u_i| ≤ u_max,i` (N·m, link side).
    pub motor_torque: Vec<f64>,
    /// `q̇_max,i` > 0: `|q̇_i| ≤ q̇_max,i` (rad/s).
    pub joint_speed: Vec<f64>,
    /// `|F_B| ≤` this (N).
    pub base_force: Option<f64>,
    /// `|n_B| ≤` this (N·m, about the base origin).
    pub base_torque: Option<f64>,
    /// Bounds per base axis (held: the holding wrench; free: the bus's rates) and on the free
    /// bus's rates by norm ([`BaseLimits`]); none by default.
    pub base_axes: BaseLimits,
}

impl Limits {
    /// The limits the robot's model states ([`crate::Robot::effort_limits`],
    /// [`crate::Robot::velocity_limits`]: a URDF's `<limit effort velocity>`): the effort is the
    /// motor torque at the link (after the gearbox), the velocity the joint speed. Errors name
    /// every joint whose model states no limit (or a zero one), for either.
    pub fn from_robot(
        robot: &crate::Robot,
        base_force: Option<f64>,
        base_torque: Option<f64>,
    ) -> Result<Self> {
        let names = robot.joint_names();
        for (what, tag, values) in [
            ("motor_torque", "effort", robot.effort_limits()),
            ("joint_speed", "velocity", robot.velocity_limits()),
        ] {
            let missing: Vec<String> = values
                .iter()
                .zip(&names)
                .filter(|(v, _)| !(v.is_finite() && **v > 0.0))
                .map(|(v, name)| {
                    if v.is_finite() {
                        format!("'{name}' (0)")
                    } else {
                        format!("'{name}'")
                    }
                })
                .collect();
            if !missing.is_empty() {
                return Err(Error::InvalidArgument {
                    what: what.into(),
                    message: format!(
                        "the model ({}) states no {tag} limit (<limit {tag}=\"…\">), or a zero one, \
                         for {}; give {what} yourself",
                        robot.source(),
                        missing.join(", ")
                    ),
                });
            }
        }
        Limits::new(
            robot.effort_limits(),
            robot.velocity_limits(),
            base_force,
            base_torque,
        )
    }

    /// Where these limits allow more than the robot's model states (effort, velocity): one
    /// phrase per quantity, `joint_speed (rad/s): 'a' 0.5 > 0.15, 'b' 0.5 > 0.2`, empty when
    /// they stay within it (or the model states none).
    pub fn exceeding(&self, robot: &crate::Robot) -> Result<Vec<String>> {
        let limits = self.for_joints(robot.dof())?;
        let names = robot.joint_names();
        let mut over = Vec::new();
        for (what, unit, given, rated) in [
            (
                "motor_torque",
                "N·m",
                &limits.motor_torque,
                robot.effort_limits(),
            ),
            (
                "joint_speed",
                "rad/s",
                &limits.joint_speed,
                robot.velocity_limits(),
            ),
        ] {
            let joints: Vec<String> = given
                .iter()
                .zip(&rated)
                .zip(&names)
                .filter(|((g, r), _)| g > r)
                .map(|((g, r), name)| format!("'{name}' {} > {}", number(*g), number(*r)))
                .collect();
            if !joints.is_empty() {
                over.push(format!("{what} ({unit}): {}", joints.join(", ")));
            }
        }
        Ok(over)
    }
}

fn check_positive(what: &str, values: &[f64]) -> Result<()> {
    for (i, &v) in values.iter().enumerate() {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::InvalidArgument {
                what: if values.len() == 1 {
                    what.to_string()
                } else {
                    format!("{what}[{i}]")
                },
                message: format!("expected a finite limit > 0, given {v}"),
            });
        }
    }
    Ok(())
}

impl Limits {
    /// Validated limits: every value finite and `> 0`. `motor_torque` and `joint_speed` have one
    /// value per joint, or a single value for all joints.
    pub fn new(
        motor_torque: Vec<f64>,
        joint_speed: Vec<f64>,
        base_force: Option<f64>,
        base_torque: Option<f64>,
    ) -> Result<Self> {
        for (what, v) in [
            ("motor_torque", &motor_torque),
            ("joint_speed", &joint_speed),
        ] {
            if v.is_empty() {
                return Err(Error::Dimension {
                    what: what.into(),
                    expected: "one value per joint, or one for all".into(),
                    given: "no values".into(),
                });
            }
            check_positive(what, v)?;
        }
        if let Some(f) = base_force {
            check_positive("base_force", &[f])?;
        }
        if let Some(t) = base_torque {
            check_positive("base_torque", &[t])?;
        }
        Ok(Self {
            motor_torque,
            joint_speed,
            base_force,
            base_torque,
            base_axes: BaseLimits::default(),
        })
    }

    /// These limits with the per-axis (and free-base rate) bounds `base_axes`, checked.
    pub fn with_base_axes(self, base_axes: BaseLimits) -> Result<Self> {
        base_axes.check()?;
        Ok(Self { base_axes, ..self })
    }

    /// The same motor-torque and joint-speed bound on all joints, no base limit.
    pub fn uniform(motor_torque: f64, joint_speed: f64) -> Result<Self> {
        Self::new(vec![motor_torque], vec![joint_speed], None, None)
    }

    /// These limits for `n` joints: single values repeated, others checked for length `n`; every
    /// value checked again (the fields are public).
    pub fn for_joints(&self, n: usize) -> Result<Limits> {
        check_positive("motor_torque", &self.motor_torque)?;
        check_positive("joint_speed", &self.joint_speed)?;
        for (what, v) in [
            ("base_force", self.base_force),
            ("base_torque", self.base_torque),
        ] {
            if let Some(v) = v {
                check_positive(what, &[v])?;
            }
        }
        self.base_axes.check()?;
        let expand = |what: &str, v: &Vec<f64>| match v.len() {
            1 => Ok(vec![v[0]; n]),
            len if len == n => Ok(v.clone()),
            len => Err(Error::Dimension {
                what: format!("limits.{what}"),
                expected: format!("{n} values (one per joint) or 1 (for all)"),
                given: format!("{len} values"),
            }),
        };
        Ok(Limits {
            motor_torque: expand("motor_torque", &self.motor_torque)?,
            joint_speed: expand("joint_speed", &self.joint_speed)?,
            ..self.clone()
        })
    }
}

/// Which limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Constraint {
    /// `|u_i| ≤ u_max,i`.
    MotorTorque,
    /// `|q̇_i| ≤ q̇_max,i`.
    JointSpeed,
    /// `|F_B| ≤ base_force`.
    BaseForce,
    /// `|n_B| ≤ base_torque`.
    BaseTorque,
    /// A bound of [`BaseLimits`] (per base axis, or a free bus's rate by norm).
    Base(BaseBound),
}

impl Constraint {
    /// `"motor_torque"`, `"joint_speed"`, `"base_force"` or `"base_torque"`.
    pub fn name(self) -> &'static str {
        match self {
            Constraint::MotorTorque => "motor_torque",
            Constraint::JointSpeed => "joint_speed",
            Constraint::BaseForce => "base_force",
            Constraint::BaseTorque => "base_torque",
            Constraint::Base(BaseBound::TorqueAxis) => "base_torque_axes",
            Constraint::Base(BaseBound::ForceAxis) => "base_force_axes",
            Constraint::Base(BaseBound::RateAxis) => "base_rate_axes",
            Constraint::Base(BaseBound::SpeedAxis) => "base_speed_axes",
            Constraint::Base(BaseBound::Rate) => "base_rate",
            Constraint::Base(BaseBound::Speed) => "base_speed",
        }
    }
}

/// The limit that sets a segment's duration: the largest ratio of a quantity to its bound.
#[derive(Debug, Clone, PartialEq)]
pub struct Binding {
    /// Which limit.
    pub constraint: Constraint,
    /// The joint (0-based) for per-joint limits.
    pub joint: Option<usize>,
    /// The base axis (0, 1, 2 for x, y, z of the base frame) for per-axis base limits.
    pub axis: Option<usize>,
    /// The point a held moment bound is taken about (`base_torque`, `base_torque_axes`); `None`
    /// for every other limit.
    pub point: Option<BasePoint>,
    /// The segment (0-based; one per waypoint, plus one).
    pub segment: usize,
    /// When it peaks (s from the start of the plan).
    pub time: f64,
    /// The peak value (N·m, rad/s, N or N·m; for torques and speeds the magnitude).
    pub value: f64,
    /// The bound.
    pub limit: f64,
}

/// One rest-to-rest piece of a plan.
#[derive(Debug, Clone)]
struct Segment {
    start: Vec<f64>,
    delta: Vec<f64>,
    /// Start time in the plan (s) and duration (s).
    t0: f64,
    duration: f64,
    /// Sorted samples of `s ∈ [0, 1]` with the unit-duration inverse dynamics at each.
    s: Vec<f64>,
    jets: Vec<RigidJets>,
    /// `r_c`, the system COM relative to the base origin (base frame, m), at each sample when
    /// the held moment is bounded about it ([`BasePoint::SystemCom`]); empty otherwise.
    com: Vec<[f64; 3]>,
    /// `δ` at each sample for the solved duration (n per sample; zero for a rigid plan).
    deflection: Vec<f64>,
    /// `δ` at `s = 0`.
    deflection0: Vec<f64>,
    binding: Binding,
}

/// Everything at one instant of a plan ([`Plan::evaluate`]): the link motion and deflection
/// (n each), and what the motors and the base do for it (`flexible`, the arm's
/// [`FlexibleInverse`]: `θ`, `θ̇`, `θ̈`, `u`, `τ` per joint, and the base's `V_B`, classical
/// `α_B` and `f_B` in the base frame, `[angular; linear]`: `V_B` and `α_B` zero unless the base is
/// free, `f_B` zero unless it is held).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlanPoint {
    /// Time (s).
    pub t: f64,
    /// `q` (rad).
    pub q: Vec<f64>,
    /// `q̇` (rad/s).
    pub qd: Vec<f64>,
    /// `q̈` (rad/s²).
    pub qdd: Vec<f64>,
    /// The deflection `θ − q` (rad) at full precision (not the difference of `flexible.theta`
    /// and `q`, which loses the digits below the angle's rounding); what
    /// [`FlexibleArm::inverse_dynamics`] takes for damped joints.
    pub deflection: Vec<f64>,
    /// The motors and the base at this instant.
    pub flexible: FlexibleInverse,
}

/// Everything at one instant of a plan, link side: the link motion, what the motors and the base
/// do for it ([`FlexibleInverse`], the result of [`FlexibleArm::inverse_dynamics`]), and the
/// deflection with the scaled torque jets it is integrated from.
#[derive(Debug, Clone)]
struct Point {
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    /// The motors and the base.
    flexible: FlexibleInverse,
    /// Scaled `[τ, τ̇, τ̈]` per joint, for the deflection integration.
    tau_jet: Vec<[f64; 3]>,
    deflection: Vec<f64>,
    /// `r_c` at this sample (zero unless [`Segment::com`] is kept).
    com: [f64; 3],
}

impl Point {
    fn new(n: usize) -> Self {
        Self {
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
            flexible: FlexibleInverse::zeros(n),
            tau_jet: vec![[0.0; 3]; n],
            deflection: vec![0.0; n],
            com: [0.0; 3],
        }
    }
}

/// A planned slew: its samples, its duration and what limits it. Made by [`plan_slew`].
#[derive(Debug, Clone)]
pub struct Plan {
    arm: FlexibleArm,
    base: BaseMode,
    rigid: bool,
    limits: Limits,
    stops: Vec<Vec<f64>>,
    base_pose0: [f64; 7],
    segments: Vec<Segment>,
}

/// Per-step tables for [`crate::integrate::simulate()`] from a plan ([`Plan::reference`]); each
/// is `steps × width`, row-major, row `k` for step `k` (time `k dt` to `(k+1) dt`).
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// The step (s).
    pub dt: f64,
    /// Number of steps.
    pub steps: usize,
    /// Feedforward motor torque: the plan's `u` averaged over the step (Simpson's rule), n wide.
    pub u: Vec<f64>,
    /// `θ` at the start of each step (n wide).
    pub theta_ref: Vec<f64>,
    /// `θ̇` at the start of each step (n wide).
    pub theta_dot_ref: Vec<f64>,
    /// The base wrench averaged over the step (6 wide; zero unless held).
    pub base_wrench: Vec<f64>,
    /// The planned link angles at every state time `k dt`, `k = 0 … steps` (`steps + 1` rows, n
    /// wide), to measure tracking.
    pub q: Vec<f64>,
    /// The planned base pose `[r_B; quat_B]` at every state time (`steps + 1` rows, 7 wide).
    pub base_pose: Vec<f64>,
}

impl Reference {
    /// Empty tables with room for `steps` steps of `n` joints.
    fn reserved(dt: f64, steps: usize, n: usize) -> Self {
        Self {
            dt,
            steps,
            u: Vec::with_capacity(steps * n),
            theta_ref: Vec::with_capacity(steps * n),
            theta_dot_ref: Vec::with_capacity(steps * n),
            base_wrench: Vec::with_capacity(steps * 6),
            q: Vec::with_capacity((steps + 1) * n),
            base_pose: Vec::with_capacity((steps + 1) * 7),
        }
    }
}

/// The arrays of a plan at its samples ([`Plan::samples`]); row-major, one row per sample.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Samples {
    /// Times (s), increasing; denser near the peaks that bind.
    pub t: Vec<f64>,
    /// `q` (n wide, rad).
    pub q: Vec<f64>,
    /// `q̇` (rad/s).
    pub qd: Vec<f64>,
    /// `q̈` (rad/s²).
    pub qdd: Vec<f64>,
    /// `θ` (rad).
    pub theta: Vec<f64>,
    /// `θ̇` (rad/s).
    pub theta_dot: Vec<f64>,
    /// `u` (N·m).
    pub u: Vec<f64>,
    /// `τ` (N·m).
    pub tau: Vec<f64>,
    /// `f_B = [moment; force]` (6 wide; zero unless held).
    pub base_wrench: Vec<f64>,
    /// `V_B = [ω_B; v_B]` (6 wide, base frame; zero unless free).
    pub base_twist: Vec<f64>,
    /// `[r_B; quat_B (x, y, z, w)]` (7 wide).
    pub base_pose: Vec<f64>,
}

/// Plans the shortest rest-to-rest slew of the fixed path shape from `q_start` (default zero)
/// to `q_goal` through `waypoints` (stopping at each) under `limits` (module docs). The arm
/// starts at rest with relaxed springs (`θ = q`), its base at the origin with identity attitude:
/// a free base's planned pose is relative to where it starts.
///
/// Errors: wrong lengths, non-finite values, non-positive limits, base limits with a free base,
/// two consecutive stops closer than [`NOTHING_TO_SLEW`], or limits no duration can meet.
pub fn plan_slew(
    arm: &FlexibleArm,
    q_goal: &[f64],
    q_start: Option<&[f64]>,
    limits: &Limits,
    base: BaseMode,
    waypoints: &[Vec<f64>],
) -> Result<Plan> {
    let never = AtomicBool::new(false);
    plan_slew_watched(arm, q_goal, q_start, limits, base, waypoints, &never)
}

/// [`plan_slew`], stopping with [`Error::Interrupted`] once `cancel` is set: it looks before
/// every trial duration and every few samples, a few milliseconds apart even for an arm of
/// hundreds of joints (whose plan takes seconds).
pub fn plan_slew_watched(
    arm: &FlexibleArm,
    q_goal: &[f64],
    q_start: Option<&[f64]>,
    limits: &Limits,
    base: BaseMode,
    waypoints: &[Vec<f64>],
    cancel: &AtomicBool,
) -> Result<Plan> {
    free_wheels_without_friction(arm, base)?;
    let limits = limits.for_joints(arm.dof())?;
    limits_fit_the_base(&limits, base)?;
    let stops = slew_stops(arm, q_goal, q_start, waypoints)?;
    Plan::solve(arm.clone(), base, false, limits, stops, cancel)
}

/// With reaction wheels the plan sees the bus with their locked parts (mass, transverse
/// inertia; `rigid_model`). A held bus does not turn, so the wheels' spin does not enter and
/// the plan and its holding wrench are exact (the wrench is what the wheels and thrusters must
/// deliver; `Plan::wheel_demand`). A free bus with the wheels unpowered and at rest: each wheel
/// keeps a·ω_B + Ω = 0, so its spin carries no momentum and the plan is exact too, unless
/// friction couples the spin back to the bus: that case is refused.
fn free_wheels_without_friction(arm: &FlexibleArm, base: BaseMode) -> Result<()> {
    if let Some(wheels) = arm.wheels() {
        if base == BaseMode::Free && wheels.wheels().iter().any(|w| w.friction != 0.0) {
            return Err(Error::InvalidArgument {
                what: "plan_slew".into(),
                message: "a free-floating plan on an arm whose reaction wheels have friction: \
                          the unpowered wheels' friction turns the bus, which the plan does not \
                          model; plan with base = \"held\" (the wheels then hold the bus), or \
                          with frictionless wheels"
                    .into(),
            });
        }
    }
    Ok(())
}

/// The base limits given are the ones `base` can meet: wrench bounds for a held base, motion
/// bounds (about the origin) for a free one.
fn limits_fit_the_base(limits: &Limits, base: BaseMode) -> Result<()> {
    if base == BaseMode::Free && (limits.base_force.is_some() || limits.base_torque.is_some()) {
        return Err(Error::InvalidArgument {
            what: "limits".into(),
            message: "base_force and base_torque bound the wrench that holds a held base; a free \
                      base receives none (base = \"free\"): leave them out"
                .into(),
        });
    }
    if base == BaseMode::Free && limits.base_axes.point != BasePoint::Origin {
        return Err(Error::InvalidArgument {
            what: "limits.base_point".into(),
            message: format!(
                "{:?} names the point a held base's moment bounds are taken about; a free base \
                 (base = \"free\") receives no wrench, its rates are the same about every point, \
                 and from rest (zero momentum) the system COM stays still, so the base origin's \
                 velocity relative to it is v_B itself: the COM would bound exactly what \
                 \"origin\" does. Leave base_point at \"origin\"",
                limits.base_axes.point.name()
            ),
        });
    }
    let misplaced = limits.base_axes.given_for(base == BaseMode::Free);
    if let Some(first) = misplaced.first() {
        let message = if base == BaseMode::Free {
            "bounds the wrench that holds a held base; a free base receives none (base = \"free\"): \
             leave it out"
        } else {
            "bounds the motion of a free-floating base; a held base does not move (base = \"held\"): \
             leave it out, or bound the holding wrench"
        };
        return Err(Error::InvalidArgument {
            what: format!("limits.{first}"),
            message: message.into(),
        });
    }
    Ok(())
}

/// The stops of the slew, `[q_start, waypoints…, q_goal]`: each `n` long, finite, within the
/// position limits, and each apart from the one before.
fn slew_stops(
    arm: &FlexibleArm,
    q_goal: &[f64],
    q_start: Option<&[f64]>,
    waypoints: &[Vec<f64>],
) -> Result<Vec<Vec<f64>>> {
    let n = arm.dof();
    let zeros = vec![0.0; n];
    let start = q_start.unwrap_or(&zeros);
    check_vector("q_start", start, n)?;
    check_vector("q_goal", q_goal, n)?;
    let mut stops = vec![start.to_vec()];
    for (i, w) in waypoints.iter().enumerate() {
        check_vector(&format!("waypoints[{i}]"), w, n)?;
        stops.push(w.clone());
    }
    stops.push(q_goal.to_vec());
    let name = |k: usize| match k {
        0 => "q_start".to_string(),
        k if k == stops.len() - 1 => "q_goal".to_string(),
        k => format!("waypoints[{}]", k - 1),
    };
    // σ is monotone, so each segment stays between its stops: the stops within the position
    // limits keep the whole path within them
    for (k, stop) in stops.iter().enumerate() {
        let outside = outside_position_limits(arm.robot(), stop);
        if !outside.is_empty() {
            return Err(Error::InvalidArgument {
                what: name(k),
                message: format!("{} (the model's <limit lower upper>)", outside.join("; ")),
            });
        }
    }
    for k in 1..stops.len() {
        let step = stops[k]
            .iter()
            .zip(&stops[k - 1])
            .fold(0.0_f64, |m, (b, a)| m.max((b - a).abs()));
        if step <= NOTHING_TO_SLEW {
            return Err(Error::InvalidArgument {
                what: name(k),
                message: format!(
                    "equals {} (to {NOTHING_TO_SLEW:e} rad): there is nothing to slew",
                    name(k - 1)
                ),
            });
        }
    }
    Ok(stops)
}

/// One line per joint of `q` outside the robot's position limits.
fn outside_position_limits(robot: &crate::Robot, q: &[f64]) -> Vec<String> {
    q.iter()
        .zip(robot.position_limits())
        .zip(robot.joint_names())
        .enumerate()
        .filter(|(_, ((q, (lower, upper)), _))| *q < lower || *q > upper)
        .map(|(i, ((q, (lower, upper)), joint))| {
            format!(
                "joint {i} ('{joint}') = {} rad is outside its position limits [{}, {}] rad",
                number(*q),
                number(lower),
                number(upper)
            )
        })
        .collect()
}

/// `Err(Error::Interrupted)` once `cancel` is set.
fn go_on(cancel: &AtomicBool) -> Result<()> {
    match cancel.load(Ordering::Relaxed) {
        true => Err(Error::Interrupted {
            what: "plan_slew".into(),
        }),
        false => Ok(()),
    }
}

impl Plan {
    fn solve(
        arm: FlexibleArm,
        base: BaseMode,
        rigid: bool,
        limits: Limits,
        stops: Vec<Vec<f64>>,
        cancel: &AtomicBool,
    ) -> Result<Plan> {
        let n = arm.dof();
        let mut plan = Plan {
            arm,
            base,
            rigid,
            limits,
            stops,
            base_pose0: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            segments: Vec::new(),
        };
        let mut scratch = JetScratch::new(plan.arm.rigid_model());
        let mut t0 = 0.0;
        let mut deflection0 = vec![0.0; n];
        for k in 1..plan.stops.len() {
            let start = plan.stops[k - 1].clone();
            let delta: Vec<f64> = plan.stops[k]
                .iter()
                .zip(&start)
                .map(|(b, a)| b - a)
                .collect();
            let mut segment = Segment {
                start,
                delta,
                t0,
                duration: 0.0,
                s: Vec::new(),
                jets: Vec::new(),
                com: Vec::new(),
                deflection: Vec::new(),
                deflection0: deflection0.clone(),
                binding: Binding {
                    constraint: Constraint::JointSpeed,
                    joint: None,
                    axis: None,
                    point: None,
                    segment: k - 1,
                    time: 0.0,
                    value: 0.0,
                    limit: 0.0,
                },
            };
            for j in 0..=INTERVALS {
                if j % 64 == 0 {
                    go_on(cancel)?;
                }
                let s = j as f64 / INTERVALS as f64;
                let jets = plan.unit_jets(&mut scratch, &segment, s)?;
                segment.s.push(s);
                segment.jets.push(jets);
                if let Some(com) = plan.sample_com(&mut scratch) {
                    segment.com.push(com);
                }
            }
            plan.solve_segment(&mut scratch, &mut segment, cancel)?;
            t0 += segment.duration;
            deflection0 = segment.deflection[(segment.s.len() - 1) * n..].to_vec();
            plan.segments.push(segment);
        }
        Ok(plan)
    }

    /// The unit-duration inverse dynamics of a segment at `s`.
    fn unit_jets(&self, scratch: &mut JetScratch, seg: &Segment, s: f64) -> Result<RigidJets> {
        let sig = sigma(s);
        for i in 0..seg.start.len() {
            let d = seg.delta[i];
            scratch.set_joint(
                i,
                [
                    seg.start[i] + d * sig[0],
                    d * sig[1],
                    d * sig[2],
                    d * sig[3],
                ],
                [d * sig[1], d * sig[2], d * sig[3], d * sig[4]],
            );
        }
        rigid_jets(self.arm.rigid_model(), scratch, self.base)
    }

    /// `r_c` at the sample [`unit_jets`](Self::unit_jets) just computed, when the held moment is
    /// bounded about the system COM; `None` otherwise (nothing is computed).
    fn sample_com(&self, scratch: &mut JetScratch) -> Option<[f64; 3]> {
        let about_com = self.limits.base_axes.point == BasePoint::SystemCom;
        (about_com && self.base == BaseMode::Held)
            .then(|| system_com(self.arm.rigid_model(), scratch).into())
    }

    /// The holding wrench at `p` about the point the limits name (the base origin: `f_B` as it
    /// is).
    fn bounded_wrench(&self, p: &Point) -> [f64; 6] {
        self.limits
            .base_axes
            .point
            .wrench(&p.flexible.base_wrench, &p.com)
    }

    /// Fills `p` for sample `j` of `seg` at duration `T = 1/w`. `previous` is the point at sample
    /// `j − 1` (for the deflection of damped joints), `None` at `j = 0`.
    fn point(
        &self,
        seg: &Segment,
        s: f64,
        jets: &RigidJets,
        w: f64,
        prev: Option<(f64, &Point)>,
        p: &mut Point,
    ) {
        let joints = self.arm.joints();
        let sig = sigma(s);
        let (w2, w3, w4) = (w * w, w * w * w, w * w * w * w);
        for i in 0..seg.start.len() {
            let d = seg.delta[i];
            p.q[i] = seg.start[i] + d * sig[0];
            p.qd[i] = d * sig[1] * w;
            p.qdd[i] = d * sig[2] * w2;
            let tj = &jets.tau[i];
            let tau = [tj[0] * w2, tj[1] * w3, tj[2] * w4];
            p.tau_jet[i] = tau;
            let (k, damping) = (joints.stiffness[i], joints.damping[i]);
            let [delta, rate, acc] = if self.rigid {
                [0.0; 3]
            } else if damping > 0.0 {
                match prev {
                    Some((ds, before)) => deflection::advance(
                        k,
                        damping,
                        ds / w,
                        before.deflection[i],
                        &before.tau_jet[i],
                        &tau,
                    ),
                    None => deflection::advance(k, damping, 0.0, seg.deflection0[i], &tau, &tau),
                }
            } else {
                [tau[0] / k, tau[1] / k, tau[2] / k]
            };
            p.deflection[i] = delta;
            let link = [p.q[i], p.qd[i], p.qdd[i]];
            p.flexible
                .set_joint(joints, i, link, [delta, rate, acc], tau[0]);
        }
        p.flexible.base_twist = (jets.base_twist[0] * w).to_array();
        p.flexible.base_acc = classical(&[
            jets.base_twist[0] * w,
            jets.base_twist[1] * w2,
            Motion::zero(),
            Motion::zero(),
        ]);
        p.flexible.base_wrench = (jets.base_wrench[0] * w2).to_array();
    }

    /// The largest ratio of a quantity to its limit at `p`, and which.
    fn worst(&self, p: &Point) -> (f64, Constraint, Option<usize>, f64, f64) {
        let mut worst = (0.0, Constraint::JointSpeed, None, 0.0, 0.0);
        let mut consider = |value: f64, limit: f64, c: Constraint, joint: Option<usize>| {
            // a NaN (an overflowing trial duration) breaches every limit
            let ratio = if value.is_nan() {
                f64::INFINITY
            } else {
                value / limit
            };
            if ratio > worst.0 {
                worst = (ratio, c, joint, value, limit);
            }
        };
        for i in 0..p.flexible.u.len() {
            consider(
                p.flexible.u[i].abs(),
                self.limits.motor_torque[i],
                Constraint::MotorTorque,
                Some(i),
            );
            consider(
                p.qd[i].abs(),
                self.limits.joint_speed[i],
                Constraint::JointSpeed,
                Some(i),
            );
        }
        let wrench = self.bounded_wrench(p);
        self.limits.base_axes.visit(
            self.base == BaseMode::Held,
            &wrench,
            &p.flexible.base_twist,
            |value, limit, which, axis| consider(value, limit, Constraint::Base(which), axis),
        );
        if self.base == BaseMode::Held {
            let f = &wrench;
            if let Some(limit) = self.limits.base_torque {
                consider(
                    Vec3::new(f[0], f[1], f[2]).norm(),
                    limit,
                    Constraint::BaseTorque,
                    None,
                );
            }
            if let Some(limit) = self.limits.base_force {
                consider(
                    Vec3::new(f[3], f[4], f[5]).norm(),
                    limit,
                    Constraint::BaseForce,
                    None,
                );
            }
        }
        worst
    }

    /// Walks the samples of `seg` at duration `1/w`, calling `visit(j, point)` while it returns
    /// `true`.
    fn walk(&self, seg: &Segment, w: f64, mut visit: impl FnMut(usize, &Point) -> bool) {
        let n = seg.start.len();
        let (mut now, mut before) = (Point::new(n), Point::new(n));
        for j in 0..seg.s.len() {
            let prev = (j > 0).then(|| (seg.s[j] - seg.s[j - 1], &before));
            self.point(seg, seg.s[j], &seg.jets[j], w, prev, &mut now);
            if let Some(com) = seg.com.get(j) {
                now.com = *com;
            }
            if !visit(j, &now) {
                return;
            }
            std::mem::swap(&mut now, &mut before);
        }
    }

    /// Whether every limit holds at every sample at duration `1/w` (stops at the first breach).
    fn feasible(&self, seg: &Segment, w: f64) -> bool {
        let mut ok = true;
        self.walk(seg, w, |_, p| {
            ok = self.worst(p).0 <= 1.0;
            ok
        });
        ok
    }

    /// The largest limit ratio over the samples at `1/w`, with the sample where it occurs.
    fn peak(&self, seg: &Segment, w: f64) -> (f64, usize, Constraint, Option<usize>, f64, f64) {
        let mut best = (0.0, 0, Constraint::JointSpeed, None, 0.0, 0.0);
        self.walk(seg, w, |j, p| {
            let (r, c, joint, value, limit) = self.worst(p);
            if r > best.0 {
                best = (r, j, c, joint, value, limit);
            }
            true
        });
        best
    }

    fn solve_segment(
        &self,
        scratch: &mut JetScratch,
        seg: &mut Segment,
        cancel: &AtomicBool,
    ) -> Result<()> {
        let mut hint = None;
        for round in 0..REFINE_ROUNDS {
            let w = self.shortest(seg, hint, cancel)?;
            hint = Some(w);
            // refine every local peak near its limit between its neighbours
            let ratios = self.channel_ratios(seg, w);
            let mut added = Vec::new();
            for channel in &ratios {
                for j in 1..channel.len() - 1 {
                    let (a, b, c) = (channel[j - 1], channel[j], channel[j + 1]);
                    if b >= REFINE_ABOVE && b >= a && b >= c && (b > a || b > c) {
                        if let Some(s) = vertex(seg.s[j - 1], seg.s[j], seg.s[j + 1], a, b, c) {
                            added.push(s);
                        }
                    }
                }
            }
            added.sort_by(f64::total_cmp);
            added.dedup_by(|a, b| (*a - *b).abs() < MIN_SPACING);
            let mut changed = false;
            for s in added {
                let at = seg.s.partition_point(|x| *x < s);
                // the nearest sample, if closer than MIN_SPACING: move it onto the vertex when
                // that keeps it MIN_SPACING from its neighbours (the ends never move)
                let near = [at.wrapping_sub(1), at]
                    .into_iter()
                    .filter(|&j| j < seg.s.len() && (seg.s[j] - s).abs() < MIN_SPACING)
                    .min_by(|&a, &b| (seg.s[a] - s).abs().total_cmp(&(seg.s[b] - s).abs()));
                match near {
                    None => {
                        let jets = self.unit_jets(scratch, seg, s)?;
                        seg.s.insert(at, s);
                        seg.jets.insert(at, jets);
                        if let Some(com) = self.sample_com(scratch) {
                            seg.com.insert(at, com);
                        }
                        changed = true;
                    }
                    Some(j) => {
                        let movable = j > 0
                            && j + 1 < seg.s.len()
                            && s - seg.s[j - 1] >= MIN_SPACING
                            && seg.s[j + 1] - s >= MIN_SPACING
                            && (seg.s[j] - s).abs() > MOVE_AT_LEAST;
                        if movable {
                            seg.jets[j] = self.unit_jets(scratch, seg, s)?;
                            if let Some(com) = self.sample_com(scratch) {
                                seg.com[j] = com;
                            }
                            seg.s[j] = s;
                            changed = true;
                        }
                    }
                }
            }
            if !changed || round == REFINE_ROUNDS - 1 {
                self.finish(seg, w);
                return Ok(());
            }
        }
        unreachable!("the loop returns in its last round")
    }

    /// Per channel (motor torque and speed per joint, base force and torque) the ratio at each
    /// sample.
    fn channel_ratios(&self, seg: &Segment, w: f64) -> Vec<Vec<f64>> {
        let n = seg.start.len();
        let mut out = vec![Vec::with_capacity(seg.s.len()); 2 * n + 2 + BaseLimits::CHANNELS];
        self.walk(seg, w, |_, p| {
            for i in 0..n {
                out[i].push(p.flexible.u[i].abs() / self.limits.motor_torque[i]);
                out[n + i].push(p.qd[i].abs() / self.limits.joint_speed[i]);
            }
            let f = &self.bounded_wrench(p);
            let held = self.base == BaseMode::Held;
            out[2 * n].push(match (held, self.limits.base_torque) {
                (true, Some(l)) => Vec3::new(f[0], f[1], f[2]).norm() / l,
                _ => 0.0,
            });
            out[2 * n + 1].push(match (held, self.limits.base_force) {
                (true, Some(l)) => Vec3::new(f[3], f[4], f[5]).norm() / l,
                _ => 0.0,
            });
            let mut base = [0.0; BaseLimits::CHANNELS];
            self.limits
                .base_axes
                .visit(held, f, &p.flexible.base_twist, |v, l, which, axis| {
                    base[BaseLimits::channel(which, axis)] = v / l;
                });
            for (c, r) in base.iter().enumerate() {
                out[2 * n + 2 + c].push(*r);
            }
            true
        });
        out
    }

    /// The largest `w = 1/T` at which every limit holds at the samples, to
    /// [`BISECTION_TOLERANCE`]. `hint` is the answer before samples were added: still
    /// infeasible just above it, so the bracket starts there.
    fn shortest(&self, seg: &Segment, hint: Option<f64>, cancel: &AtomicBool) -> Result<f64> {
        // the speed bound alone: T ≥ max |Δ_i| σ'_max / q̇_max,i
        let speed_w = seg
            .delta
            .iter()
            .zip(&self.limits.joint_speed)
            .map(|(d, l)| l / (d.abs() * sigma(0.5)[1]))
            .fold(f64::INFINITY, f64::min);
        let start = hint.unwrap_or(speed_w).min(1.0 / SHORTEST_TRIED);
        if start < 1.0 / LONGEST_TRIED {
            // the speed limit alone asks for longer than any segment is planned
            return Err(self.unreachable(seg, 1.0 / LONGEST_TRIED));
        }
        if self.feasible(seg, start) {
            if hint.is_none() && speed_w > start {
                // the floor binds, not a limit: a plan of 1 ns would only report a limit that
                // its values are nowhere near
                let (_, _, c, joint, value, limit) = self.peak(seg, start);
                return Err(Error::InvalidArgument {
                    what: "limits".into(),
                    message: format!(
                        "every limit holds even at {SHORTEST_TRIED:e} s, the shortest segment \
                         duration planned, so none of them binds (at {SHORTEST_TRIED:e} s \
                         {}{} peaks at {value:.3e}, against its limit of {}); give the \
                         hardware's limits",
                        c.name(),
                        joint.map_or(String::new(), |j| format!("[{j}]")),
                        crate::args::number(limit),
                    ),
                });
            }
            return Ok(start);
        }
        // widen downwards (longer durations) until feasible: from a 1e-4 cut after a hint, by
        // halves without one, then by squares of the factor (1/2, 1/4, 1/16, …) so that even a
        // start 18 orders of magnitude too short is bracketed in a few steps
        let mut factor: f64 = if hint.is_some() { 1.0 - 1e-4 } else { 0.5 };
        let (mut hi, mut lo) = (start, start * factor);
        while !self.feasible(seg, lo) {
            go_on(cancel)?;
            if lo <= 1.0 / LONGEST_TRIED {
                return Err(self.unreachable(seg, lo));
            }
            hi = lo;
            factor = if factor > 0.5 {
                (1.0 - 4.0 * (1.0 - factor)).max(0.5)
            } else {
                factor * factor
            };
            // the longest duration tried is the longest planned: no segment is longer
            lo = (hi * factor).max(1.0 / LONGEST_TRIED);
        }
        // bisect: geometrically while the bracket spans more than a factor 2, then arithmetically
        while hi - lo > BISECTION_TOLERANCE * hi {
            go_on(cancel)?;
            let mid = if hi > 2.0 * lo {
                (lo * hi).sqrt()
            } else {
                0.5 * (lo + hi)
            };
            if self.feasible(seg, mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Ok(lo)
    }

    /// Why no duration up to [`LONGEST_TRIED`] meets the limits (`w` is its inverse): a limit
    /// still breached there, or, when the inverse dynamics overflow there, a slew too large for
    /// floating point (named by the stop it ends at).
    fn unreachable(&self, seg: &Segment, w: f64) -> Error {
        let (_, _, c, joint, value, limit) = self.peak(seg, w);
        if value.is_finite() {
            return Error::InvalidArgument {
                what: "limits".into(),
                message: format!(
                    "no duration up to {LONGEST_TRIED:.0e} s meets them: {}{} still needs \
                     {value:.3e} at {LONGEST_TRIED:.0e} s, over its limit of {}",
                    c.name(),
                    joint.map_or(String::new(), |j| format!("[{j}]")),
                    crate::args::number(limit),
                ),
            };
        }
        let k = seg.binding.segment + 1;
        let stop = |k: usize| match k {
            0 => "q_start".to_string(),
            k if k == self.stops.len() - 1 => "q_goal".to_string(),
            k => format!("waypoints[{}]", k - 1),
        };
        let (joint, step) = seg
            .delta
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .map_or((0, 0.0), |(j, d)| (j, *d));
        Error::InvalidArgument {
            what: stop(k),
            message: format!(
                "too large for floating point: the slew from {} to it, {} rad on joint {joint}, \
                 makes the inverse dynamics overflow at every duration up to {LONGEST_TRIED:.0e} s",
                stop(k - 1),
                crate::args::number(step)
            ),
        }
    }

    /// Stores the solved duration, the deflection at each sample and the binding limit.
    fn finish(&self, seg: &mut Segment, w: f64) {
        let n = seg.start.len();
        let (_, j, constraint, joint, value, limit) = self.peak(seg, w);
        let mut deflection = Vec::with_capacity(seg.s.len() * n);
        self.walk(seg, w, |_, p| {
            deflection.extend_from_slice(&p.deflection);
            true
        });
        seg.deflection = deflection;
        seg.duration = 1.0 / w;
        let per_axis = matches!(constraint, Constraint::Base(_));
        seg.binding = Binding {
            constraint,
            // the per-axis base bounds report their axis where the joint limits their joint
            joint: if per_axis { None } else { joint },
            axis: if per_axis { joint } else { None },
            point: match constraint {
                Constraint::BaseTorque | Constraint::Base(BaseBound::TorqueAxis) => {
                    Some(self.limits.base_axes.point)
                }
                _ => None,
            },
            segment: seg.binding.segment,
            time: seg.t0 + seg.s[j] * seg.duration,
            value,
            limit,
        };
    }

    /// Total duration (s).
    pub fn duration(&self) -> f64 {
        self.segments.iter().map(|s| s.duration).sum()
    }

    /// Each segment's duration (s).
    pub fn segment_durations(&self) -> Vec<f64> {
        self.segments.iter().map(|s| s.duration).collect()
    }

    /// The limit that binds the plan: that of its longest segment (every segment is as short as
    /// its limits allow, so each has a binding limit at ratio 1; [`Plan::bindings`] lists them).
    pub fn binding(&self) -> &Binding {
        let mut best = &self.segments[0];
        for seg in &self.segments {
            if seg.duration > best.duration {
                best = seg;
            }
        }
        &best.binding
    }

    /// The binding limit of each segment.
    pub fn bindings(&self) -> Vec<Binding> {
        self.segments.iter().map(|s| s.binding.clone()).collect()
    }

    /// The base mode planned for.
    pub fn base(&self) -> BaseMode {
        self.base
    }

    /// Whether this is the rigid-joint plan ([`Plan::rigid`]).
    pub fn is_rigid(&self) -> bool {
        self.rigid
    }

    /// The limits planned for.
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    /// The arm planned for.
    pub fn arm(&self) -> &FlexibleArm {
        &self.arm
    }

    /// The stops: start, waypoints, goal.
    pub fn stops(&self) -> &[Vec<f64>] {
        &self.stops
    }

    /// The state at which a simulation of this plan starts: `q = θ = q_start`, at rest, base at
    /// its initial pose.
    pub fn initial_state(&self) -> Vec<f64> {
        self.arm
            .state(&crate::flex::StateSpec {
                q: Some(&self.stops[0]),
                base_pose: Some(&self.base_pose0),
                ..Default::default()
            })
            .expect("the stops are checked")
    }

    /// The same slew planned as if the joints were rigid (`θ = q`, `u = j q̈ + β q̇ + τ`), under
    /// the same limits and base mode: what a planner that ignores joint flexibility produces.
    pub fn rigid(&self) -> Result<Plan> {
        self.rigid_watched(&AtomicBool::new(false))
    }

    /// [`Plan::rigid`], stopping with [`Error::Interrupted`] once `cancel` is set (as
    /// [`plan_slew_watched`]).
    pub fn rigid_watched(&self, cancel: &AtomicBool) -> Result<Plan> {
        Plan::solve(
            self.arm.clone(),
            self.base,
            true,
            self.limits.clone(),
            self.stops.clone(),
            cancel,
        )
    }

    /// The plan's arrays at its samples (one row per sample, the segment joins once).
    pub fn samples(&self) -> Samples {
        let n = self.arm.dof();
        let mut out = Samples::default();
        let mut pose = self.base_pose0;
        let mut rk4 = Rk4::new(7);
        for (k, seg) in self.segments.iter().enumerate() {
            let w = 1.0 / seg.duration;
            let mut previous_twist: Option<(f64, [Motion; 2])> = None;
            self.walk(seg, w, |j, p| {
                // integrate the base pose in s (the path of a free base does not depend on T)
                let twist = [seg.jets[j].base_twist[0], seg.jets[j].base_twist[1]];
                if let Some((s_prev, a)) = previous_twist {
                    // the middle by cubic Hermite interpolation in s: fourth-order accurate
                    let ds = seg.s[j] - s_prev;
                    let mid = (a[0] + twist[0]) * 0.5 + (a[1] - twist[1]) * (ds / 8.0);
                    rk4_pose(&mut rk4, &mut pose, [a[0], mid, twist[0]], ds);
                }
                previous_twist = Some((seg.s[j], twist));
                if k > 0 && j == 0 {
                    return true; // the join is the previous segment's last row
                }
                out.t.push(seg.t0 + seg.s[j] * seg.duration);
                out.q.extend_from_slice(&p.q);
                out.qd.extend_from_slice(&p.qd);
                out.qdd.extend_from_slice(&p.qdd);
                out.theta.extend_from_slice(&p.flexible.theta);
                out.theta_dot.extend_from_slice(&p.flexible.theta_dot);
                out.u.extend_from_slice(&p.flexible.u);
                out.tau.extend_from_slice(&p.flexible.tau);
                out.base_wrench.extend_from_slice(&p.flexible.base_wrench);
                out.base_twist.extend_from_slice(&p.flexible.base_twist);
                out.base_pose.extend_from_slice(&pose);
                true
            });
        }
        debug_assert_eq!(out.q.len(), out.t.len() * n);
        out
    }

    /// Everything at time `t` (s), computed afresh (not interpolated); after the end, the arm
    /// rests at the goal.
    fn at(&self, scratch: &mut JetScratch, t: f64, out: &mut Point) -> Result<()> {
        let overtime = self.at_unsettled(scratch, t, out)?;
        if overtime > 0.0 {
            self.settle(out, overtime);
        }
        Ok(())
    }

    /// [`Plan::at`] without the settling after the end: returns how far `t` is past the end.
    fn at_unsettled(&self, scratch: &mut JetScratch, t: f64, out: &mut Point) -> Result<f64> {
        let n = self.arm.dof();
        let last = self.segments.len() - 1;
        let k = self
            .segments
            .iter()
            .position(|seg| t < seg.t0 + seg.duration)
            .unwrap_or(last);
        let seg = &self.segments[k];
        let w = 1.0 / seg.duration;
        // a division, not `* w`: `s` is then the correctly rounded `(t − t₀)/T`
        let mut s = ((t - seg.t0) / seg.duration).clamp(0.0, 1.0);
        if s < 1e-12 {
            s = 0.0; // at rest; avoids intervals that underflow
        }
        // integrate from a sample at least LOOKBACK back (short intervals amplify round-off)
        let j = seg.s.partition_point(|x| *x <= s - LOOKBACK).max(1) - 1;
        let mut before = Point::new(n);
        self.point(seg, seg.s[j], &seg.jets[j], w, None, &mut before);
        before
            .deflection
            .copy_from_slice(&seg.deflection[j * n..(j + 1) * n]);
        let jets = self.unit_jets(scratch, seg, s)?;
        self.point(seg, s, &jets, w, Some((s - seg.s[j], &before)), out);
        // after the end the links rest (τ = 0) and a damped joint's leftover deflection decays
        Ok(t - (seg.t0 + seg.duration))
    }

    /// The point at the plan's end (`s = 1` of the last segment) moved on by `overtime` s at
    /// rest: the links stay, a damped joint's deflection decays as `e^{−k t/d}`.
    fn settle(&self, out: &mut Point, overtime: f64) {
        if self.rigid {
            return;
        }
        let joints = self.arm.joints();
        for i in 0..self.arm.dof() {
            let (k, d) = (joints.stiffness[i], joints.damping[i]);
            if d > 0.0 {
                let [delta, rate, acc] =
                    deflection::advance(k, d, overtime, out.deflection[i], &[0.0; 3], &[0.0; 3]);
                out.deflection[i] = delta;
                out.flexible.theta[i] = out.q[i] + delta;
                out.flexible.theta_dot[i] = rate;
                out.flexible.theta_ddot[i] = acc;
                out.flexible.u[i] = joints.motor_inertia[i] * acc + joints.motor_damping[i] * rate;
            }
        }
    }

    /// Everything at time `t` (s) of the plan, computed afresh from the inverse dynamics at that
    /// instant (not interpolated between samples; the deflection of damped joints is integrated
    /// exactly from a sample before). Before the start the arm rests at the first stop. After the
    /// end the links rest at the goal; a damped joint's motor may still settle (its deflection
    /// decays as `e^{−k t/d}`).
    pub fn evaluate(&self, t: f64) -> Result<PlanPoint> {
        crate::args::check_finite("t", &[t])?;
        let mut p = Point::new(self.arm.dof());
        self.at(&mut JetScratch::new(self.arm.rigid_model()), t, &mut p)?;
        Ok(PlanPoint {
            t,
            q: p.q,
            qd: p.qd,
            qdd: p.qdd,
            deflection: p.deflection,
            flexible: p.flexible,
        })
    }

    /// Per-step tables for a run of `steps` steps of `dt` (default: enough to cover the plan;
    /// more steps hold the goal at rest): the feedforward `u` (the plan's `u` averaged over each
    /// step, Simpson's rule), `θ_ref` and `θ̇_ref` at each step's start for a
    /// [`crate::MotorPD`] around it, and the base wrench (averaged) that holds a held base.
    pub fn reference(&self, dt: f64, steps: Option<usize>) -> Result<Reference> {
        self.reference_with(dt, steps, &mut |_| true)
            .map(|r| r.expect("never stopped"))
    }

    /// [`Plan::reference`], asking `keep_going(k)` every 4096 steps whether to go on: `None`
    /// when it says no (to stop a long computation on a user's interrupt).
    pub fn reference_with(
        &self,
        dt: f64,
        steps: Option<usize>,
        keep_going: &mut dyn FnMut(usize) -> bool,
    ) -> Result<Option<Reference>> {
        check_dt(dt)?;
        let n = self.arm.dof();
        let covering = (self.duration() / dt).ceil() as usize;
        let steps = steps.unwrap_or(covering);
        if !(steps as f64 * dt).is_finite() {
            return Err(Error::InvalidArgument {
                what: "dt".into(),
                message: format!(
                    "{steps} steps of {} s do not end at a finite time",
                    crate::args::number(dt)
                ),
            });
        }
        let mut r = Reference::reserved(dt, steps, n);
        let mut pose = self.base_pose0;
        let mut rk4 = Rk4::new(7);
        let mut scratch = JetScratch::new(self.arm.rigid_model());
        // the plan's end, once: every instant after it is this point settled (as in `at`)
        let last = self.segments.last().expect("a plan has a segment");
        let end_time = last.t0 + last.duration;
        let mut rest = Point::new(n);
        self.at_unsettled(&mut scratch, 2.0 * end_time + 1.0, &mut rest)?;
        let evaluate = |scratch: &mut JetScratch, t: f64, out: &mut Point| -> Result<()> {
            if t > end_time {
                out.clone_from(&rest);
                self.settle(out, t - end_time);
                Ok(())
            } else {
                self.at(scratch, t, out)
            }
        };
        let (mut start, mut mid, mut end) = (Point::new(n), Point::new(n), Point::new(n));
        evaluate(&mut scratch, 0.0, &mut start)?;
        for k in 0..steps {
            if k % 4096 == 4095 && !keep_going(k) {
                return Ok(None);
            }
            let t = k as f64 * dt;
            evaluate(&mut scratch, t + 0.5 * dt, &mut mid)?;
            evaluate(&mut scratch, t + dt, &mut end)?;
            r.theta_ref.extend_from_slice(&start.flexible.theta);
            r.theta_dot_ref.extend_from_slice(&start.flexible.theta_dot);
            r.q.extend_from_slice(&start.q);
            r.base_pose.extend_from_slice(&pose);
            let twist = |p: &Point| Motion::from_slice(&p.flexible.base_twist);
            rk4_pose(
                &mut rk4,
                &mut pose,
                [twist(&start), twist(&mid), twist(&end)],
                dt,
            );
            for i in 0..n {
                r.u.push((start.flexible.u[i] + 4.0 * mid.flexible.u[i] + end.flexible.u[i]) / 6.0);
            }
            for c in 0..6 {
                r.base_wrench.push(
                    (start.flexible.base_wrench[c]
                        + 4.0 * mid.flexible.base_wrench[c]
                        + end.flexible.base_wrench[c])
                        / 6.0,
                );
            }
            std::mem::swap(&mut start, &mut end);
        }
        r.q.extend_from_slice(&start.q);
        r.base_pose.extend_from_slice(&pose);
        Ok(Some(r))
    }
}

/// The vertex of the parabola through three samples, if it lies strictly between the outer two.
fn vertex(x0: f64, x1: f64, x2: f64, y0: f64, y1: f64, y2: f64) -> Option<f64> {
    let d01 = (y1 - y0) / (x1 - x0);
    let d12 = (y2 - y1) / (x2 - x1);
    let curvature = (d12 - d01) / (x2 - x0);
    if curvature >= 0.0 {
        return None;
    }
    let x = 0.5 * (x0 + x1) - d01 / (2.0 * curvature);
    (x > x0 && x < x2).then_some(x)
}

/// The base pose `[r_B; quat_B]` under a twist given at the start, the middle and the end of a
/// step: the system [`Rk4`] integrates for the free base of a plan ([`base_pose_rate`]). Its
/// stages are called in order, `k₁` at the start, `k₂` and `k₃` at the middle, `k₄` at the end.
struct PoseKinematics {
    /// The twist at the start, the middle and the end of the step.
    twists: [Motion; 3],
    /// The stage the next derivative is for (0 to 3).
    stage: usize,
}

impl OdeSystem for PoseKinematics {
    fn state_len(&self) -> usize {
        7
    }
    fn derivative(&mut self, x: &[f64], xdot: &mut [f64]) -> Result<()> {
        let v = &self.twists[match self.stage {
            0 => 0,
            1 | 2 => 1,
            _ => 2,
        }];
        self.stage += 1;
        base_pose_rate(&x[POSE_QUATERNION], &v.angular, &v.linear, xdot);
        Ok(())
    }
    fn project(&mut self, x: &mut [f64]) {
        normalise_quaternion(&mut x[POSE_QUATERNION]);
    }
}

/// One RK4 step of the base pose over `h` with the twist at the start, middle and end of the
/// step (`rk4`: buffers of length 7, reused from step to step).
fn rk4_pose(rk4: &mut Rk4, pose: &mut [f64; 7], twists: [Motion; 3], h: f64) {
    let mut system = PoseKinematics { twists, stage: 0 };
    rk4.step(&mut system, pose, h)
        .expect("the pose kinematics cannot fail, and their buffers have its length");
}

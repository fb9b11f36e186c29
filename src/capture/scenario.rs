//! The built-in capture scenario ([`capture_scenario`]): the built-in space arm (a 500 kg bus and a
//! 7-joint flexible arm) holding a pre-grasp posture under its motor PD while a 200 kg target,
//! spinning at 2 deg/s about its major axis, drifts onto the end-effector.

use super::target::Target;
use super::when::CaptureWhen;
use crate::control::{MotorPD, Schedule};
use crate::error::Result;
use crate::flex::{FlexibleArm, FlexibleJoints, StateSpec};
use crate::model::Robot;
use crate::spatial::{quaternion_exp, quaternion_product, quaternion_to_rotation, Mat3, Vec3};

/// The pre-grasp posture (rad): shoulder, elbow and wrist bent, away from the stretched-out
/// singularity of `q = 0`.
pub const PRE_GRASP: [f64; 7] = [0.3, 0.5, -1.0, 0.2, 0.5, -0.2, 0.1];

/// The target's box (m, body x, y, z) and mass (kg).
pub const TARGET_BOX: [f64; 3] = [1.0, 1.2, 1.4];
/// The target's mass (kg).
pub const TARGET_MASS: f64 = 200.0;
/// The spin rate (deg/s) about the target's body x axis (its major axis: stable).
pub const TUMBLE_DEG_S: f64 = 2.0;
/// How far the handle stands off the face of the box (m).
pub const HANDLE_STANDOFF: f64 = 0.1;

/// The built-in capture scenario: what a run needs, as values.
#[derive(Debug, Clone)]
pub struct CaptureScenario {
    /// The built-in space arm with its built-in joints.
    pub arm: FlexibleArm,
    /// The arm at rest in the pre-grasp posture [`PRE_GRASP`] (springs relaxed).
    pub x0: Vec<f64>,
    /// The target at `t = 0`.
    pub target: Target,
    /// The trigger: 1 cm, 5 cm/s, 5 deg.
    pub when: CaptureWhen,
    /// The motor PD that holds [`PRE_GRASP`] before and after the capture (0.25 Hz, ζ = 1).
    pub controller: MotorPD,
    /// The step (s).
    pub dt: f64,
    /// The run's length (s).
    pub duration: f64,
    /// When the handle would reach the EE exactly (s); the trigger fires once within 1 cm of it.
    pub meet: f64,
}

/// The box's rotational inertia about its centre (kg·m², body axes): `m/12 (b² + c²)`, ….
pub fn box_inertia(mass: f64, sides: [f64; 3]) -> Mat3 {
    let [a, b, c] = sides.map(|s| s * s);
    Mat3::from_diagonal(&Vec3::new(b + c, a + c, a + b)) * (mass / 12.0)
}

/// The built-in capture scenario (module docs), with the target drifting at `drift` (m/s) and
/// spinning at `tumble_deg_s` (deg/s), reaching the EE at `meet` (s):
///
/// - at `meet`, the handle's frame is the EE's frame in the pre-grasp posture: the target's body
///   x axis points along the EE's −z (the approach axis), its centre `0.5 + 0.1` m beyond the EE
///   along z, spinning about body x (a stable spin: ω is constant in body axes);
/// - going back `meet` seconds: the centre drifts along the approach axis towards the EE at
///   `drift`, and the attitude is `R(0) = R(meet) exp(−[ω]× meet)`.
pub fn capture_scenario_with(tumble_deg_s: f64, drift: f64, meet: f64) -> Result<CaptureScenario> {
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
    let x0 = arm.state(&StateSpec {
        q: Some(&PRE_GRASP),
        theta: Some(&PRE_GRASP),
        ..StateSpec::default()
    })?;
    let ee = arm.ee_pose(&x0, 0);
    let ee_axes = quaternion_to_rotation(&ee[3..]);
    let (ee_origin, approach) = (
        Vec3::new(ee[0], ee[1], ee[2]),
        ee_axes.column(2).into_owned(),
    );
    // E_t = E_e M, M = rotation by −90° about y: body x = −z_e, body y = y_e, body z = x_e
    let m_quat = [
        0.0,
        -std::f64::consts::FRAC_1_SQRT_2,
        0.0,
        std::f64::consts::FRAC_1_SQRT_2,
    ];
    let quat_meet = quaternion_product(&ee[3..], &m_quat);
    let reach = 0.5 * TARGET_BOX[0] + HANDLE_STANDOFF;
    let centre_meet = ee_origin + approach * reach;
    let rate = tumble_deg_s.to_radians();
    let omega = Vec3::new(rate, 0.0, 0.0);
    let quat0 = quaternion_product(&quat_meet, &quaternion_exp(&(-omega * meet)));
    let velocity = -approach * drift; // inertial, towards the EE
    let centre0 = centre_meet - velocity * meet;
    let v_body = quaternion_to_rotation(&quat0).transpose() * velocity;
    // the handle at body (−reach, 0, 0) (towards the EE), its axes the EE's: R_{t,g} = Mᵀ
    let grasp = [-reach, 0.0, 0.0, 0.0, -m_quat[1], 0.0, m_quat[3]];
    let pose0 = [
        centre0[0], centre0[1], centre0[2], quat0[0], quat0[1], quat0[2], quat0[3],
    ];
    let twist0 = [
        omega[0], omega[1], omega[2], v_body[0], v_body[1], v_body[2],
    ];
    let target = Target::new(
        TARGET_MASS,
        box_inertia(TARGET_MASS, TARGET_BOX),
        &pose0,
        &twist0,
        &grasp,
    )?
    .named("client");
    let gains = arm.motor_pd_gains(&PRE_GRASP, 0.25, 1.0)?;
    let controller = MotorPD::new(
        gains.kp,
        gains.kd,
        Schedule::Constant(PRE_GRASP.to_vec()),
        Schedule::Zero,
        Schedule::Zero,
    )?;
    Ok(CaptureScenario {
        arm,
        x0,
        target,
        when: CaptureWhen::new(0.01, 0.05, 5f64.to_radians())?,
        controller,
        dt: 1e-3,
        duration: 40.0,
        meet,
    })
}

/// [`capture_scenario_with`] at 2 deg/s, drifting in at 2 cm/s, meeting the EE at 5 s.
pub fn capture_scenario() -> Result<CaptureScenario> {
    capture_scenario_with(TUMBLE_DEG_S, 0.02, 5.0)
}

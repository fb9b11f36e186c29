//! Spong (1987) flexible joints (SPEC §3) and the floating-base flexible arm's state (SPEC §4).
//!
//! Each joint `i` has a motor whose angle, reflected through its gearbox to the link side, is
//! `θ_i`. The spring torque on link `i` and the motor equation are
//!
//! ```text
//! τ_i = k_i (θ_i − q_i) + d_i (θ̇_i − q̇_i)
//! j_i θ̈_i + β_i θ̇_i + τ_i = u_i
//! ```
//! with `u_i` the motor torque reflected to the link side (N·m).

use crate::algorithms::{aba::aba_from_velocities, kinematics, Data, Method};
use crate::dynamics::{check_base_pose, momentum_in_inertial_frame};
use crate::error::{check_finite, check_vector, Error, Result};
use crate::model::Robot;
use crate::operators::Operators;
use crate::spatial::{quaternion_to_rotation, Force, Vec3};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

/// Per-joint Spong parameters, all on the link side (SPEC §3).
#[derive(Debug, Clone, PartialEq)]
pub struct FlexibleJoints {
    /// `k_i` > 0, joint stiffness (N·m/rad).
    pub stiffness: Vec<f64>,
    /// `j_i` > 0, motor inertia reflected to the link side, `N² J_rotor` (kg·m²).
    pub motor_inertia: Vec<f64>,
    /// `d_i` ≥ 0, joint (spring) damping (N·m·s/rad).
    pub damping: Vec<f64>,
    /// `β_i` ≥ 0, motor viscous friction (N·m·s/rad).
    pub motor_damping: Vec<f64>,
}

fn check_parameter(what: &str, values: &[f64], n: usize, positive: bool) -> Result<()> {
    check_vector(what, values, n)?;
    for (i, &v) in values.iter().enumerate() {
        if (positive && v <= 0.0) || v < 0.0 {
            return Err(Error::InvalidArgument {
                what: format!("{what}[{i}]"),
                message: format!(
                    "expected {}, given {v}",
                    if positive { "> 0" } else { ">= 0" }
                ),
            });
        }
    }
    Ok(())
}

impl FlexibleJoints {
    /// Validated parameters for `n` joints: `k > 0`, `j > 0`, `d ≥ 0`, `β ≥ 0`, each of length n.
    pub fn new(
        stiffness: Vec<f64>,
        motor_inertia: Vec<f64>,
        damping: Vec<f64>,
        motor_damping: Vec<f64>,
    ) -> Result<Self> {
        let n = stiffness.len();
        check_parameter("stiffness", &stiffness, n, true)?;
        check_parameter("motor_inertia", &motor_inertia, n, true)?;
        check_parameter("damping", &damping, n, false)?;
        check_parameter("motor_damping", &motor_damping, n, false)?;
        Ok(Self {
            stiffness,
            motor_inertia,
            damping,
            motor_damping,
        })
    }

    /// The same scalar parameters for all `n` joints.
    pub fn uniform(
        n: usize,
        stiffness: f64,
        motor_inertia: f64,
        damping: f64,
        motor_damping: f64,
    ) -> Result<Self> {
        Self::new(
            vec![stiffness; n],
            vec![motor_inertia; n],
            vec![damping; n],
            vec![motor_damping; n],
        )
    }

    /// From gearbox data: `j_i = N_i² J_rotor,i` (SPEC §3). `u` and `θ` are then link-side
    /// quantities: `u = N × (motor torque)`, `θ = (motor angle) / N`.
    pub fn from_gear(
        stiffness: Vec<f64>,
        gear_ratio: &[f64],
        rotor_inertia: &[f64],
        damping: Vec<f64>,
        motor_damping: Vec<f64>,
    ) -> Result<Self> {
        let n = stiffness.len();
        check_parameter("gear_ratio", gear_ratio, n, true)?;
        check_parameter("rotor_inertia", rotor_inertia, n, true)?;
        let j = gear_ratio
            .iter()
            .zip(rotor_inertia)
            .map(|(g, r)| g * g * r)
            .collect();
        Self::new(stiffness, j, damping, motor_damping)
    }

    /// Number of joints.
    pub fn len(&self) -> usize {
        self.stiffness.len()
    }

    /// True when there are no joints.
    pub fn is_empty(&self) -> bool {
        self.stiffness.is_empty()
    }

    /// Reads parameters keyed by joint name from TOML text (see [`FlexibleJoints::from_toml_file`]).
    pub fn from_toml_str(text: &str, joint_names: &[&str], source: &str) -> Result<Self> {
        #[derive(Deserialize, Default, Clone, Copy)]
        #[serde(deny_unknown_fields)]
        struct Entry {
            stiffness: Option<f64>,
            motor_inertia: Option<f64>,
            gear_ratio: Option<f64>,
            rotor_inertia: Option<f64>,
            damping: Option<f64>,
            motor_damping: Option<f64>,
        }
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct File {
            #[serde(default)]
            defaults: Entry,
            #[serde(default)]
            joints: BTreeMap<String, Entry>,
        }
        let malformed = |message: String| Error::Malformed {
            source_name: source.to_string(),
            format: "joint-parameter TOML",
            message,
        };
        let file: File = toml::from_str(text).map_err(|e| malformed(e.to_string()))?;
        for name in file.joints.keys() {
            if !joint_names.contains(&name.as_str()) {
                return Err(Error::UnknownName {
                    source_name: source.to_string(),
                    what: "joint ([joints.<name>] table)",
                    name: name.clone(),
                    available: joint_names.join(", "),
                });
            }
        }
        // motor_inertia, or gear_ratio and rotor_inertia, from one table; None if it gives neither.
        let inertia_in = |entry: &Entry, where_: &str| -> Result<Option<f64>> {
            match (entry.motor_inertia, entry.gear_ratio, entry.rotor_inertia) {
                (Some(value), None, None) => Ok(Some(value)),
                (None, Some(g), Some(r)) => {
                    if !(g > 0.0 && r > 0.0) {
                        return Err(malformed(format!(
                            "{where_}: gear_ratio and rotor_inertia must be > 0, given {g} and {r}"
                        )));
                    }
                    Ok(Some(g * g * r))
                }
                (None, None, None) => Ok(None),
                _ => Err(malformed(format!(
                    "{where_}: give either motor_inertia, or both gear_ratio and rotor_inertia"
                ))),
            }
        };
        let default_inertia = inertia_in(&file.defaults, "[defaults]")?;
        let n = joint_names.len();
        let (mut k, mut j, mut d, mut beta) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        for name in joint_names {
            let own = file.joints.get(*name).copied().unwrap_or_default();
            let d0 = file.defaults;
            let missing = |key: &str| {
                malformed(format!(
                    "joint '{name}': no {key} (give it in [joints.{name}] or [defaults])"
                ))
            };
            let table = format!("joint '{name}' ([joints.{name}])");
            let stiffness = own
                .stiffness
                .or(d0.stiffness)
                .ok_or_else(|| missing("stiffness"))?;
            let inertia = inertia_in(&own, &table)?
                .or(default_inertia)
                .ok_or_else(|| missing("motor_inertia (or gear_ratio and rotor_inertia)"))?;
            let damping = own.damping.or(d0.damping).unwrap_or(0.0);
            let motor_damping = own.motor_damping.or(d0.motor_damping).unwrap_or(0.0);
            for (key, value, positive) in [
                ("stiffness", stiffness, true),
                ("motor_inertia", inertia, true),
                ("damping", damping, false),
                ("motor_damping", motor_damping, false),
            ] {
                if !value.is_finite() || value < 0.0 || (positive && value <= 0.0) {
                    return Err(malformed(format!(
                        "joint '{name}': {key} must be {}, given {value}",
                        if positive { "> 0" } else { ">= 0" }
                    )));
                }
            }
            k.push(stiffness);
            j.push(inertia);
            d.push(damping);
            beta.push(motor_damping);
        }
        Self::new(k, j, d, beta).map_err(|e| malformed(e.to_string()))
    }

    /// Reads parameters keyed by joint name from a TOML file, kept beside a robot's URDF:
    ///
    /// ```toml
    /// [defaults]              # optional; used for every joint not given below
    /// stiffness = 2.0e4       # N·m/rad
    /// motor_inertia = 0.5     # kg·m², link side; or gear_ratio and rotor_inertia
    /// damping = 5.0           # N·m·s/rad (default 0)
    /// motor_damping = 0.0     # N·m·s/rad (default 0)
    ///
    /// [joints.elbow_pitch]
    /// stiffness = 1.0e4
    /// gear_ratio = 160.0
    /// rotor_inertia = 2.0e-5  # j = gear_ratio² · rotor_inertia
    /// ```
    pub fn from_toml_file(path: impl AsRef<Path>, joint_names: &[&str]) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::FileNotFound {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Self::from_toml_str(&text, joint_names, &path.display().to_string())
    }
}

/// Offsets of the blocks of the state `x ∈ R^{13+4n}` (SPEC §4):
/// `[r_B (3) | quat_B (4) | q (n) | θ (n) | ω_B (3) | v_B (3) | q̇ (n) | θ̇ (n)]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StateLayout {
    pub n: usize,
}

impl StateLayout {
    /// Length `13 + 4n`.
    pub fn len(&self) -> usize {
        13 + 4 * self.n
    }
    /// Never empty (the base alone has 13 states).
    pub fn is_empty(&self) -> bool {
        false
    }
    /// `r_B`: base origin in the inertial frame (m).
    pub fn position(&self) -> std::ops::Range<usize> {
        0..3
    }
    /// `quat_B = (x, y, z, w)`: base-frame to inertial-frame components.
    pub fn quaternion(&self) -> std::ops::Range<usize> {
        3..7
    }
    /// `[r_B; quat_B]`.
    pub fn base_pose(&self) -> std::ops::Range<usize> {
        0..7
    }
    /// Link angles `q` (rad).
    pub fn q(&self) -> std::ops::Range<usize> {
        7..7 + self.n
    }
    /// Motor angles `θ` (rad, link side).
    pub fn theta(&self) -> std::ops::Range<usize> {
        7 + self.n..7 + 2 * self.n
    }
    /// Base twist `[ω_B; v_B]` in base-frame components.
    pub fn base_twist(&self) -> std::ops::Range<usize> {
        7 + 2 * self.n..13 + 2 * self.n
    }
    /// Link rates `q̇`.
    pub fn qd(&self) -> std::ops::Range<usize> {
        13 + 2 * self.n..13 + 3 * self.n
    }
    /// Motor rates `θ̇`.
    pub fn theta_dot(&self) -> std::ops::Range<usize> {
        13 + 3 * self.n..13 + 4 * self.n
    }
}

/// A floating-base arm with Spong flexible joints: the robot, its joint parameters and the
/// dynamics method used by [`FlexibleArm::derivative`].
#[derive(Debug, Clone)]
pub struct FlexibleArm {
    robot: Robot,
    joints: FlexibleJoints,
    method: Method,
}

/// Scratch memory for [`FlexibleArm::derivative`] and the integrator, allocated once.
#[derive(Debug, Clone)]
pub struct ArmWorkspace {
    pub(crate) data: Data,
    pub(crate) tau: Vec<f64>,
    pub(crate) stages: [Vec<f64>; 4],
    pub(crate) trial: Vec<f64>,
}

impl ArmWorkspace {
    /// Buffers for `arm`.
    pub fn new(arm: &FlexibleArm) -> Self {
        let len = arm.layout().len();
        Self {
            data: Data::new(&arm.robot),
            tau: vec![0.0; arm.robot.dof()],
            stages: [
                vec![0.0; len],
                vec![0.0; len],
                vec![0.0; len],
                vec![0.0; len],
            ],
            trial: vec![0.0; len],
        }
    }
}

impl FlexibleArm {
    /// Couples a robot with joint parameters of matching length.
    pub fn new(robot: Robot, joints: FlexibleJoints) -> Result<Self> {
        if joints.len() != robot.dof() {
            return Err(Error::Dimension {
                what: "FlexibleJoints".into(),
                expected: format!("{} joints (the robot's dof)", robot.dof()),
                given: format!("{} joints", joints.len()),
            });
        }
        Ok(Self {
            robot,
            joints,
            method: Method::Recursive,
        })
    }

    /// Selects the rigid-body dynamics used by the derivative (default: recursive).
    pub fn with_method(mut self, method: Method) -> Self {
        self.method = method;
        self
    }

    /// The dynamics method in use.
    pub fn method(&self) -> Method {
        self.method
    }

    /// The rigid robot.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The joint parameters.
    pub fn joints(&self) -> &FlexibleJoints {
        &self.joints
    }

    /// The layout of the state vector.
    pub fn layout(&self) -> StateLayout {
        StateLayout {
            n: self.robot.dof(),
        }
    }

    /// Builds a state `x` (SPEC §4). Defaults: zero angles and rates, base at the origin with
    /// identity attitude, at rest; `θ = q` (springs relaxed).
    pub fn state(
        &self,
        q: Option<&[f64]>,
        theta: Option<&[f64]>,
        qd: Option<&[f64]>,
        theta_dot: Option<&[f64]>,
        base_pose: Option<&[f64]>,
        base_twist: Option<&[f64]>,
    ) -> Result<Vec<f64>> {
        let layout = self.layout();
        let n = layout.n;
        let mut x = vec![0.0; layout.len()];
        x[6] = 1.0;
        let mut put =
            |what: &str, value: Option<&[f64]>, range: std::ops::Range<usize>| -> Result<()> {
                if let Some(v) = value {
                    check_vector(what, v, range.len())?;
                    x[range].copy_from_slice(v);
                }
                Ok(())
            };
        put("q", q, layout.q())?;
        put("theta", theta.or(q), layout.theta())?;
        put("qd", qd, layout.qd())?;
        put("theta_dot", theta_dot, layout.theta_dot())?;
        if let Some(pose) = base_pose {
            check_base_pose(pose)?;
        }
        put("base_pose", base_pose, layout.base_pose())?;
        put("base_twist", base_twist, layout.base_twist())?;
        normalise_quaternion(&mut x[layout.quaternion()]);
        debug_assert_eq!(x.len(), 13 + 4 * n);
        Ok(x)
    }

    /// Checks a state vector's length and finiteness.
    pub fn check_state(&self, x: &[f64]) -> Result<()> {
        check_vector("x (state)", x, self.layout().len())?;
        check_base_pose(&x[self.layout().base_pose()])
    }

    /// `ẋ` (SPEC §4) into `xdot`, inputs `u` (n), `f_B` and `f` (6 each):
    ///
    /// ```text
    /// ṙ_B = R_B v_B,   quat_B' = ½ quat_B ⊗ (ω_B, 0)
    /// τ = k (θ − q) + d (θ̇ − q̇)
    /// [α_B; q̈] = 𝓜⁻¹ ([f_B; τ] − [C_B; C_r] − [Φ_{n+1,B}ᵀ; Jᵀ] f)          (A.19)
    /// ω̇_B = α_B[0:3],  v̇_B = α_B[3:6] − ω_B × v_B,  θ̈ = (u − τ − β θ̇) / j
    /// ```
    #[allow(clippy::too_many_arguments)]
    pub fn derivative(
        &self,
        ws: &mut ArmWorkspace,
        x: &[f64],
        u: &[f64],
        base_wrench: &[f64],
        ee_wrench: &[f64],
        xdot: &mut [f64],
    ) -> Result<()> {
        let layout = self.layout();
        crate::algorithms::check_data(&self.robot, &ws.data)?;
        self.check_state(x)?;
        check_vector("u", u, layout.n)?;
        check_vector("base_wrench", base_wrench, 6)?;
        check_vector("ee_wrench", ee_wrench, 6)?;
        if xdot.len() != layout.len() {
            return Err(Error::Dimension {
                what: "xdot".into(),
                expected: format!("length {}", layout.len()),
                given: format!("length {}", xdot.len()),
            });
        }
        self.derivative_unchecked(ws, x, u, base_wrench, ee_wrench, xdot)
    }

    /// The derivative without argument checks; allocation-free on the recursive path.
    pub(crate) fn derivative_unchecked(
        &self,
        ws: &mut ArmWorkspace,
        x: &[f64],
        u: &[f64],
        base_wrench: &[f64],
        ee_wrench: &[f64],
        xdot: &mut [f64],
    ) -> Result<()> {
        let layout = self.layout();
        let n = layout.n;
        let p = &self.joints;
        let q = &x[layout.q()];
        let twist = &x[layout.base_twist()];
        let qd = &x[layout.qd()];
        let theta_dot = &x[layout.theta_dot()];
        self.spring_torque(x, &mut ws.tau);

        let acc: &[f64] = match self.method {
            Method::Recursive => {
                kinematics::velocities_unchecked(&self.robot, &mut ws.data, q, twist, qd);
                aba_from_velocities(
                    &self.robot,
                    &mut ws.data,
                    &ws.tau,
                    &Force::from_slice(base_wrench),
                    &Force::from_slice(ee_wrench),
                )?;
                ws.data.out.as_slice()
            }
            Method::Operator => {
                let a = Operators::new(&self.robot, q, twist, qd)?.forward_dynamics(
                    &ws.tau,
                    base_wrench,
                    ee_wrench,
                )?;
                ws.data.out.copy_from(&a);
                ws.data.out.as_slice()
            }
        };

        let quat = &x[layout.quaternion()];
        let omega = Vec3::new(twist[0], twist[1], twist[2]);
        let v = Vec3::new(twist[3], twist[4], twist[5]);
        let r_dot = quaternion_to_rotation(quat) * v;
        xdot[layout.position()].copy_from_slice(r_dot.as_slice());
        // ½ quat ⊗ (ω, 0), Hamilton product, scalar last.
        let qv = Vec3::new(quat[0], quat[1], quat[2]);
        let quat_dot = (omega * quat[3] + qv.cross(&omega)) * 0.5;
        xdot[3..6].copy_from_slice(quat_dot.as_slice());
        xdot[6] = -0.5 * qv.dot(&omega);
        xdot[layout.q()].copy_from_slice(qd);
        xdot[layout.theta()].copy_from_slice(theta_dot);
        let omega_dot = Vec3::new(acc[0], acc[1], acc[2]);
        let v_dot = Vec3::new(acc[3], acc[4], acc[5]) - omega.cross(&v);
        let tw = layout.base_twist().start;
        xdot[tw..tw + 3].copy_from_slice(omega_dot.as_slice());
        xdot[tw + 3..tw + 6].copy_from_slice(v_dot.as_slice());
        xdot[layout.qd()].copy_from_slice(&acc[6..6 + n]);
        let td = layout.theta_dot().start;
        for i in 0..n {
            xdot[td + i] =
                (u[i] - ws.tau[i] - p.motor_damping[i] * theta_dot[i]) / p.motor_inertia[i];
        }
        Ok(())
    }

    /// Spring torques `τ = k (θ − q) + d (θ̇ − q̇)` at state `x` into `out` (n).
    pub fn spring_torque(&self, x: &[f64], out: &mut [f64]) {
        let l = self.layout();
        let p = &self.joints;
        for i in 0..l.n {
            out[i] = p.stiffness[i] * (x[l.theta().start + i] - x[l.q().start + i])
                + p.damping[i] * (x[l.theta_dot().start + i] - x[l.qd().start + i]);
        }
    }

    /// Total energy (SPEC §6.2): rigid kinetic energy `½ νᵀ 𝓜 ν`, motor kinetic energy
    /// `½ θ̇ᵀ diag(j) θ̇` and spring energy `½ (θ − q)ᵀ diag(k) (θ − q)` (J).
    pub fn energy(&self, ws: &mut ArmWorkspace, x: &[f64]) -> f64 {
        let l = self.layout();
        let p = &self.joints;
        kinematics::velocities_unchecked(
            &self.robot,
            &mut ws.data,
            &x[l.q()],
            &x[l.base_twist()],
            &x[l.qd()],
        );
        let mut e = kinematics::kinetic_energy_from_velocities(&self.robot, &ws.data);
        for i in 0..l.n {
            let td = x[l.theta_dot().start + i];
            let stretch = x[l.theta().start + i] - x[l.q().start + i];
            e += 0.5 * p.motor_inertia[i] * td * td + 0.5 * p.stiffness[i] * stretch * stretch;
        }
        e
    }

    /// Total spatial momentum `[angular; linear]` of base and links in the inertial frame, about
    /// the inertial origin (SPEC §6.1). The motors' spin is not included (SPEC §3).
    pub fn momentum(&self, ws: &mut ArmWorkspace, x: &[f64]) -> [f64; 6] {
        let l = self.layout();
        kinematics::velocities_unchecked(
            &self.robot,
            &mut ws.data,
            &x[l.q()],
            &x[l.base_twist()],
            &x[l.qd()],
        );
        let h = kinematics::momentum_from_velocities(&self.robot, &ws.data);
        momentum_in_inertial_frame(&x[l.base_pose()], &h)
    }

    /// The EE pose `[position (3); quaternion (x, y, z, w)]` in the inertial frame at state `x`.
    pub fn ee_pose(&self, x: &[f64]) -> [f64; 7] {
        let l = self.layout();
        let pose = &x[l.base_pose()];
        let mut rotation = quaternion_to_rotation(&pose[3..7]); // body -> inertial
        let mut position = Vec3::new(pose[0], pose[1], pose[2]);
        for (i, joint) in self.robot.joints().iter().enumerate() {
            let t = joint.transform(x[l.q().start + i]);
            position += rotation * t.translation;
            rotation *= t.rotation.transpose();
        }
        let ee = self.robot.ee_transform();
        position += rotation * ee.translation;
        rotation *= ee.rotation.transpose();
        // Closed form (no iteration), exact for the orthonormal product above.
        let quat = nalgebra::UnitQuaternion::from_rotation_matrix(
            &nalgebra::Rotation3::from_matrix_unchecked(rotation),
        );
        let c = quat.coords; // (i, j, k, w)
        [position.x, position.y, position.z, c[0], c[1], c[2], c[3]]
    }

    /// Largest stable RK4 step for the stiffest joint mode at link angles `q` (SPEC §5):
    /// `2√2 / ω_max`, `ω_max = max_i sqrt(k_i (1/j_i + 1/m_i))`, `m_i` the diagonal of `M_r`.
    pub fn rk4_stability_limit(&self, q: &[f64]) -> Result<f64> {
        check_vector("q", q, self.robot.dof())?;
        let mut data = Data::new(&self.robot);
        let m = crate::algorithms::crba(&self.robot, &mut data, q)?;
        let p = &self.joints;
        let omega_max = (0..self.robot.dof())
            .map(|i| (p.stiffness[i] * (1.0 / p.motor_inertia[i] + 1.0 / m[(6 + i, 6 + i)])).sqrt())
            .fold(0.0, f64::max);
        Ok(if omega_max > 0.0 {
            2.0 * std::f64::consts::SQRT_2 / omega_max
        } else {
            f64::INFINITY
        })
    }
}

/// Scales the quaternion part of a state to unit norm.
/// Scales the quaternion part of a state to unit norm. The norm is taken after dividing by the
/// largest component, so huge but finite components do not overflow into a zero quaternion; a
/// zero or non-finite quaternion is left as it is (and is then caught as a diverged state).
pub(crate) fn normalise_quaternion(quat: &mut [f64]) {
    let squares: f64 = quat.iter().map(|v| v * v).sum();
    let norm = if squares.is_finite() && squares > f64::MIN_POSITIVE {
        squares.sqrt()
    } else {
        let scale = quat.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if !(scale.is_finite() && scale > 0.0) {
            return;
        }
        scale * quat.iter().map(|v| (v / scale).powi(2)).sum::<f64>().sqrt()
    };
    quat.iter_mut().for_each(|v| *v /= norm);
}

/// Why `x` is not a valid state, if it is not: a non-finite element or a zero quaternion.
pub(crate) fn state_defect(x: &[f64]) -> Option<String> {
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return Some(format!("element {i} turned non-finite"));
    }
    let scale = x[3..7].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if scale == 0.0 {
        return Some("the base quaternion collapsed to zero".into());
    }
    None
}

/// Checks `values` are finite; used on controller output.
pub(crate) fn check_output(what: &str, values: &[f64]) -> Result<()> {
    check_finite(what, values)
}

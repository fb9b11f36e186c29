//! The FMU's variables: one table, built from the arm, that both writes the model description
//! and serves the runtime's value references, so the two cannot disagree.
//!
//! Value references are positions in the table: `0` is `time` (declared as FMI 3.0's independent
//! variable; FMI 2.0 has none), then the parameters, the inputs and the outputs, each group in
//! joint order. The same names have the same references in FMI 2.0 and 3.0.

use crate::flex::{FlexibleArm, StateLayout};
use crate::integrate::Outputs;

/// What a variable is to the master (FMI `causality`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    /// FMI 3.0's independent variable, `time`.
    Independent,
    /// Set before initialisation, fixed afterwards (`variability="fixed"`).
    Parameter,
    /// Set by the master between steps, held over each step.
    Input,
    /// Read by the master; a function of the state only (no direct feedthrough).
    Output,
}

/// A Spong joint parameter (model §3), or the initial link angle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Parameter {
    /// `k_i` > 0 (N·m/rad).
    Stiffness,
    /// `j_i` > 0 (kg·m², link side).
    MotorInertia,
    /// `d_i` ≥ 0 (N·m·s/rad).
    Damping,
    /// `β_i` ≥ 0 (N·m·s/rad).
    MotorDamping,
    /// `q_i(0)` (rad); the motor starts at the same angle (`θ_i(0) = q_i(0)`), everything at rest.
    InitialAngle,
    /// `Ω_w(0)` (rad/s): reaction wheel `w`'s initial speed relative to the bus (its momentum
    /// bias); the index is the wheel's, not a joint's.
    InitialWheelSpeed,
}

impl Parameter {
    /// Whether `value` is in the parameter's domain, and the domain's description.
    pub fn admits(self, value: f64) -> (bool, &'static str) {
        match self {
            Parameter::Stiffness | Parameter::MotorInertia => (value > 0.0, "> 0"),
            Parameter::Damping | Parameter::MotorDamping => (value >= 0.0, ">= 0"),
            Parameter::InitialAngle | Parameter::InitialWheelSpeed => (true, "finite"),
        }
    }
}

/// An output quantity of [`Outputs`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// `q` (per joint).
    Q,
    /// `q̇` (per joint).
    Qd,
    /// `θ` (per joint).
    Theta,
    /// `θ̇` (per joint).
    ThetaDot,
    /// `θ − q` (per joint).
    Deflection,
    /// `τ` (per joint).
    SpringTorque,
    /// `[r_B; quat_B]` (7).
    BasePose,
    /// `[ω_B; v_B]` (6).
    BaseTwist,
    /// The end-effector poses, 7 each.
    EePoses,
    /// `[angular; linear]` momentum (6).
    Momentum,
    /// Total energy (1).
    Energy,
    /// Reaction-wheel speeds `Ω` (per wheel).
    WheelSpeed,
    /// The wheel torques applied over the last step (per wheel).
    AppliedWheelTorque,
}

impl Quantity {
    /// Element `i` of this quantity read straight from the state `x` (laid out by `layout`),
    /// for the quantities that are parts of it (or, for the deflection, a difference of two);
    /// `None` for those computed from the whole state (spring torques, poses, momentum,
    /// energy). Bit for bit what [`Simulator::outputs_into`](crate::Simulator::outputs_into)
    /// gives.
    pub fn from_state(self, layout: &StateLayout, x: &[f64], i: usize) -> Option<f64> {
        let part = |range: std::ops::Range<usize>| x[range.start + i];
        Some(match self {
            Quantity::Q => part(layout.q()),
            Quantity::Qd => part(layout.qd()),
            Quantity::Theta => part(layout.theta()),
            Quantity::ThetaDot => part(layout.theta_dot()),
            Quantity::Deflection => part(layout.theta()) - part(layout.q()),
            Quantity::BasePose => part(layout.base_pose()),
            Quantity::BaseTwist => part(layout.base_twist()),
            Quantity::WheelSpeed => part(layout.wheel_speed()),
            _ => return None,
        })
    }

    /// Element `i` of this quantity in `out`.
    pub fn read(self, out: &Outputs, i: usize) -> f64 {
        match self {
            Quantity::Q => out.q[i],
            Quantity::Qd => out.qd[i],
            Quantity::Theta => out.theta[i],
            Quantity::ThetaDot => out.theta_dot[i],
            Quantity::Deflection => out.deflection[i],
            Quantity::SpringTorque => out.spring_torque[i],
            Quantity::BasePose => out.base_pose[i],
            Quantity::BaseTwist => out.base_twist[i],
            Quantity::EePoses => out.ee_poses[i],
            Quantity::Momentum => out.momentum[i],
            Quantity::Energy => out.energy,
            Quantity::WheelSpeed => out.wheel_speed[i],
            Quantity::AppliedWheelTorque => out.applied_wheel_torque[i],
        }
    }
}

/// Where a variable's value lives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// The simulation time.
    Time,
    /// Parameter `p` of joint `i`.
    Parameter(Parameter, usize),
    /// The motor torque `u_i`.
    MotorTorque(usize),
    /// Element `i` of `f_B = [moment; force]` (base frame).
    BaseWrench(usize),
    /// The torque command to reaction wheel `w`.
    WheelTorque(usize),
    /// Element `i` of an output quantity.
    Output(Quantity, usize),
}

/// One FMU variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// Its name (`q.elbow_pitch`); flat naming, any characters but control characters.
    pub name: String,
    /// FMI causality.
    pub causality: Causality,
    /// Its unit, one of [`UNITS`] (`None`: dimensionless).
    pub unit: Option<&'static str>,
    /// What it is, for the model description.
    pub description: String,
    /// Where its value lives.
    pub slot: Slot,
}

/// The units the variables use, with their SI base-unit exponents
/// `(name, kg, m, s, rad)`, for the model description's `UnitDefinitions`.
pub const UNITS: [(&str, i32, i32, i32, i32); 12] = [
    ("s", 0, 0, 1, 0),
    ("m", 0, 1, 0, 0),
    ("m/s", 0, 1, -1, 0),
    ("rad", 0, 0, 0, 1),
    ("rad/s", 0, 0, -1, 1),
    ("N", 1, 1, -2, 0),
    ("N.m", 1, 2, -2, 0),
    ("N.s", 1, 1, -1, 0),
    ("N.m.s", 1, 2, -1, 0),
    ("J", 1, 2, -2, 0),
    ("kg.m2", 1, 2, 0, 0),
    ("N.m/rad", 1, 2, -2, -1),
];

/// The unit of damping, `N.m.s/rad`, declared beside [`UNITS`].
pub const DAMPING_UNIT: (&str, i32, i32, i32, i32) = ("N.m.s/rad", 1, 2, -1, -1);

/// The variable table of an arm's FMU, in value-reference order.
#[derive(Debug, Clone, PartialEq)]
pub struct VariableTable {
    /// `variables[vr]` has value reference `vr`.
    pub variables: Vec<Variable>,
}

const XYZ: [&str; 3] = ["x", "y", "z"];
const XYZW: [&str; 4] = ["x", "y", "z", "w"];

impl VariableTable {
    /// The variables of `arm`'s FMU: `time`; per joint the parameters `stiffness.<j>`,
    /// `motor_inertia.<j>`, `damping.<j>`, `motor_damping.<j>`, `q0.<j>`; the inputs
    /// `motor_torque.<j>`, `base_moment.{x,y,z}`, `base_force.{x,y,z}`; the outputs `q.<j>`,
    /// `qd.<j>`, `theta.<j>`, `theta_dot.<j>`, `deflection.<j>`, `spring_torque.<j>`,
    /// `base_position.{x,y,z}`, `base_quaternion.{x,y,z,w}`, `base_angular_velocity.{x,y,z}`,
    /// `base_velocity.{x,y,z}`, `ee_position.<ee>.{x,y,z}`, `ee_quaternion.<ee>.{x,y,z,w}`,
    /// `momentum.angular.{x,y,z}`, `momentum.linear.{x,y,z}`, `energy`.
    ///
    /// An arm with `k` reaction wheels adds, per wheel `w` (0 to k−1, the arm's wheel order),
    /// the parameter `wheel_speed0.<w>` after the `q0.<j>`, the input `wheel_torque.<w>` after
    /// the base wrench, and the outputs `wheel_speed.<w>` and `applied_wheel_torque.<w>` after
    /// `energy`; the variables of an arm without wheels are unchanged.
    pub fn new(arm: &FlexibleArm) -> Self {
        let robot = arm.robot();
        let joints = robot.joint_names();
        let wheels = arm.layout().wheels;
        let mut table = Rows::default();
        table.push(
            "time".into(),
            Causality::Independent,
            Some("s"),
            "simulation time".into(),
            Slot::Time,
        );
        table.parameters(&joints, wheels);
        table.inputs(&joints, wheels);
        table.joint_outputs(&joints);
        table.body_outputs(&robot.ee_links());
        table.push(
            "energy".into(),
            Causality::Output,
            Some("J"),
            "total energy (rigid kinetic, motor kinetic, spring)".into(),
            Slot::Output(Quantity::Energy, 0),
        );
        table.wheel_outputs(wheels);
        Self {
            variables: table.variables,
        }
    }

    /// The variable with value reference `vr`, or a message naming the valid range.
    pub fn get(&self, vr: u32) -> Result<&Variable, String> {
        self.variables.get(vr as usize).ok_or_else(|| {
            format!(
                "unknown value reference {vr} (this FMU's are 0 to {})",
                self.variables.len() - 1
            )
        })
    }

    /// The value reference of the variable named `name`.
    pub fn value_reference(&self, name: &str) -> Option<u32> {
        self.variables
            .iter()
            .position(|v| v.name == name)
            .map(|i| i as u32)
    }

    /// The names in value-reference order.
    pub fn names(&self) -> Vec<String> {
        self.variables.iter().map(|v| v.name.clone()).collect()
    }
}

/// The table while it is built: variables pushed in value-reference order, one group per method.
#[derive(Default)]
struct Rows {
    variables: Vec<Variable>,
}

impl Rows {
    fn push(
        &mut self,
        name: String,
        causality: Causality,
        unit: Option<&'static str>,
        description: String,
        slot: Slot,
    ) {
        self.variables.push(Variable {
            name,
            causality,
            unit,
            description,
            slot,
        });
    }

    /// The Spong parameters and initial angles per joint, then the wheels' initial speeds.
    fn parameters(&mut self, joints: &[&str], wheels: usize) {
        let parameters = [
            (
                Parameter::Stiffness,
                "stiffness",
                "N.m/rad",
                "joint stiffness k",
            ),
            (
                Parameter::MotorInertia,
                "motor_inertia",
                "kg.m2",
                "motor inertia j reflected to the link side",
            ),
            (
                Parameter::Damping,
                "damping",
                DAMPING_UNIT.0,
                "joint (spring) damping d",
            ),
            (
                Parameter::MotorDamping,
                "motor_damping",
                DAMPING_UNIT.0,
                "motor viscous friction beta",
            ),
            (
                Parameter::InitialAngle,
                "q0",
                "rad",
                "initial link angle (motor at the same angle, at rest)",
            ),
        ];
        for (p, prefix, unit, what) in parameters {
            for (i, j) in joints.iter().enumerate() {
                self.push(
                    format!("{prefix}.{j}"),
                    Causality::Parameter,
                    Some(unit),
                    format!("{what} of joint {j}"),
                    Slot::Parameter(p, i),
                );
            }
        }
        for w in 0..wheels {
            self.push(
                format!("wheel_speed0.{w}"),
                Causality::Parameter,
                Some("rad/s"),
                format!("initial speed of reaction wheel {w} relative to the bus (momentum bias)"),
                Slot::Parameter(Parameter::InitialWheelSpeed, w),
            );
        }
    }

    /// The motor torques, the base wrench (moment, then force) and the wheel torque commands.
    fn inputs(&mut self, joints: &[&str], wheels: usize) {
        for (i, j) in joints.iter().enumerate() {
            self.push(
                format!("motor_torque.{j}"),
                Causality::Input,
                Some("N.m"),
                format!("motor torque u of joint {j}, link side"),
                Slot::MotorTorque(i),
            );
        }
        for (i, axis) in XYZ.iter().enumerate() {
            self.push(
                format!("base_moment.{axis}"),
                Causality::Input,
                Some("N.m"),
                format!("moment on the base about its origin, base-frame {axis}"),
                Slot::BaseWrench(i),
            );
        }
        for (i, axis) in XYZ.iter().enumerate() {
            self.push(
                format!("base_force.{axis}"),
                Causality::Input,
                Some("N"),
                format!("force on the base, base-frame {axis}"),
                Slot::BaseWrench(3 + i),
            );
        }
        for w in 0..wheels {
            self.push(
                format!("wheel_torque.{w}"),
                Causality::Input,
                Some("N.m"),
                format!(
                    "torque command to reaction wheel {w} about its spin axis (the bus feels the \
                     opposite); clipped to its max_torque, and to none that speeds it up at its \
                     max_speed"
                ),
                Slot::WheelTorque(w),
            );
        }
    }

    /// The per-joint outputs: angles, rates, deflections and spring torques.
    fn joint_outputs(&mut self, joints: &[&str]) {
        let per_joint = [
            (Quantity::Q, "q", "rad", "link angle"),
            (Quantity::Qd, "qd", "rad/s", "link rate"),
            (Quantity::Theta, "theta", "rad", "motor angle, link side"),
            (
                Quantity::ThetaDot,
                "theta_dot",
                "rad/s",
                "motor rate, link side",
            ),
            (
                Quantity::Deflection,
                "deflection",
                "rad",
                "joint deflection theta - q",
            ),
            (
                Quantity::SpringTorque,
                "spring_torque",
                "N.m",
                "spring torque k (theta - q) + d (theta_dot - qd)",
            ),
        ];
        for (quantity, prefix, unit, what) in per_joint {
            for (i, j) in joints.iter().enumerate() {
                self.push(
                    format!("{prefix}.{j}"),
                    Causality::Output,
                    Some(unit),
                    format!("{what} of joint {j}"),
                    Slot::Output(quantity, i),
                );
            }
        }
    }

    /// One output per axis of a vector quantity, `<name>.<axis>`, at `offset + axis index`.
    fn vector(
        &mut self,
        name: &str,
        axes: &[&str],
        unit: Option<&'static str>,
        what: &str,
        (quantity, offset): (Quantity, usize),
    ) {
        for (i, axis) in axes.iter().enumerate() {
            self.push(
                format!("{name}.{axis}"),
                Causality::Output,
                unit,
                format!("{what}, {axis}"),
                Slot::Output(quantity, offset + i),
            );
        }
    }

    /// The outputs of the bodies: the base pose and twist, each end-effector's pose, momentum.
    fn body_outputs(&mut self, ees: &[&str]) {
        self.vector(
            "base_position",
            &XYZ,
            Some("m"),
            "base origin in the inertial frame",
            (Quantity::BasePose, 0),
        );
        self.vector(
            "base_quaternion",
            &XYZW,
            None,
            "base attitude (base to inertial), scalar last",
            (Quantity::BasePose, 3),
        );
        self.vector(
            "base_angular_velocity",
            &XYZ,
            Some("rad/s"),
            "base angular velocity, base frame",
            (Quantity::BaseTwist, 0),
        );
        self.vector(
            "base_velocity",
            &XYZ,
            Some("m/s"),
            "base origin velocity, base frame",
            (Quantity::BaseTwist, 3),
        );
        for (e, ee) in ees.iter().enumerate() {
            self.vector(
                &format!("ee_position.{ee}"),
                &XYZ,
                Some("m"),
                &format!("end-effector {ee} origin in the inertial frame"),
                (Quantity::EePoses, 7 * e),
            );
            self.vector(
                &format!("ee_quaternion.{ee}"),
                &XYZW,
                None,
                &format!("end-effector {ee} attitude (EE to inertial), scalar last, w >= 0"),
                (Quantity::EePoses, 7 * e + 3),
            );
        }
        self.vector(
            "momentum.angular",
            &XYZ,
            Some("N.m.s"),
            "angular momentum about the inertial origin, inertial frame",
            (Quantity::Momentum, 0),
        );
        self.vector(
            "momentum.linear",
            &XYZ,
            Some("N.s"),
            "linear momentum, inertial frame",
            (Quantity::Momentum, 3),
        );
    }

    /// Per wheel: its speed relative to the bus and the torque applied over the last step.
    fn wheel_outputs(&mut self, wheels: usize) {
        for (quantity, prefix, unit, what) in [
            (
                Quantity::WheelSpeed,
                "wheel_speed",
                "rad/s",
                "speed relative to the bus",
            ),
            (
                Quantity::AppliedWheelTorque,
                "applied_wheel_torque",
                "N.m",
                "motor torque applied over the last step, after the limits",
            ),
        ] {
            for w in 0..wheels {
                self.push(
                    format!("{prefix}.{w}"),
                    Causality::Output,
                    Some(unit),
                    format!("{what} of reaction wheel {w}"),
                    Slot::Output(quantity, w),
                );
            }
        }
    }
}

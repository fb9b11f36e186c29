//! [`FmuInstance`]: one FMU instance's state machine, independent of the FMI version and of C.
//! The FMI 2.0 and 3.0 exports (the `orbitflex-capi` crate) are thin wrappers around it.
//!
//! States (FMI 3.0 names; FMI 2.0 has the same for co-simulation): *Instantiated* (parameters
//! and inputs may be set) → *Initialization* (the same) → *Step* (inputs set, `do_step`,
//! outputs read; parameters are fixed) → *Terminated*. `reset` goes back to *Instantiated*
//! with the exported parameter values.
//!
//! Every refusal is an `Err` with a message for the master's log: unknown value references,
//! non-finite values, a parameter outside its domain or set after initialisation, an output
//! set, a step before initialisation, a communication point that is not the FMU's time, a
//! communication step that is not a whole multiple of dt, a step that diverges (undone).

use super::model::FmuModel;
use super::variables::{Causality, Parameter, Slot};
use crate::flex::{FlexibleArm, FlexibleJoints, StateSpec};
use crate::integrate::{Outputs, Simulator};

/// The first bytes of a saved FMU state.
pub const STATE_MAGIC: &[u8; 8] = b"OFXFMU\0\0";
/// The layout of a saved FMU state (the simulator's blob carries its own version). Version 2:
/// the initial wheel speeds after the start time, and the simulator's blob of version 2 (the
/// wheel speeds in the state, the wheel commands and the torques last applied).
pub const FORMAT_VERSION: u32 = 2;

/// The FMI state of an instance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Instantiated: parameters and inputs may be set.
    Instantiated,
    /// Initialization mode: the same.
    Initialization,
    /// Step mode: inputs, steps and outputs.
    Step,
    /// Terminated: outputs may be read, nothing else.
    Terminated,
}

/// The value of parameter `p` of joint (or wheel) `i` in `joints` and `initial` (the initial
/// link angles and wheel speeds; zero if empty).
pub fn parameter_value(joints: &FlexibleJoints, initial: &Initial, p: Parameter, i: usize) -> f64 {
    match p {
        Parameter::Stiffness => joints.stiffness[i],
        Parameter::MotorInertia => joints.motor_inertia[i],
        Parameter::Damping => joints.damping[i],
        Parameter::MotorDamping => joints.motor_damping[i],
        Parameter::InitialAngle => initial.q0.get(i).copied().unwrap_or(0.0),
        Parameter::InitialWheelSpeed => initial.wheel_speed0.get(i).copied().unwrap_or(0.0),
    }
}

/// The initial conditions an FMU's parameters set: everything else starts at rest.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Initial {
    /// `q(0)` (n, rad); the motors start at the same angles.
    pub q0: Vec<f64>,
    /// `Ω(0)` (k, rad/s): the wheel speeds relative to the bus.
    pub wheel_speed0: Vec<f64>,
}

/// One FMU instance.
#[derive(Debug, Clone)]
pub struct FmuInstance {
    model: FmuModel,
    mode: Mode,
    /// The parameter values (the exported ones until set).
    joints: FlexibleJoints,
    initial: Initial,
    /// The inputs set (held), copied into the simulator when it exists.
    u: Vec<f64>,
    base_wrench: [f64; 6],
    /// The wheel torque commands (k; empty without wheels).
    wheel_torque: Vec<f64>,
    /// The start time of the run (s): the FMU's time is `start + k dt`.
    start: f64,
    /// The run, built from the parameters when first needed (outputs in Initialization mode,
    /// or leaving it); dropped when a parameter changes.
    sim: Option<Simulator>,
    /// The outputs of the current state, if computed since the last change.
    outputs: Outputs,
    fresh: bool,
}

impl FmuInstance {
    /// A new instance of `model`, in *Instantiated* mode with the exported parameter values.
    pub fn new(model: FmuModel) -> Self {
        let n = model.arm.dof();
        let k = model.arm.layout().wheels;
        Self {
            joints: model.arm.joints().clone(),
            initial: Initial {
                q0: vec![0.0; n],
                wheel_speed0: vec![0.0; k],
            },
            u: vec![0.0; n],
            base_wrench: [0.0; 6],
            wheel_torque: vec![0.0; k],
            start: 0.0,
            sim: None,
            outputs: Outputs::for_arm(&model.arm),
            fresh: false,
            mode: Mode::Instantiated,
            model,
        }
    }

    /// The model.
    pub fn model(&self) -> &FmuModel {
        &self.model
    }

    /// The current mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The FMU's time (s): `start + k dt`.
    pub fn time(&self) -> f64 {
        let k = self.sim.as_ref().map_or(0, Simulator::steps);
        self.start + k as f64 * self.model.config.dt
    }

    /// Enters *Initialization* mode with the run starting at `start` (s).
    pub fn enter_initialization(&mut self, start: f64) -> Result<(), String> {
        self.expect(&[Mode::Instantiated], "enter initialization mode")?;
        if !start.is_finite() {
            return Err(format!("startTime must be finite, given {start}"));
        }
        self.start = start;
        self.mode = Mode::Initialization;
        Ok(())
    }

    /// Sets the start time before initialisation (FMI 2.0 `fmi2SetupExperiment`).
    pub fn setup(&mut self, start: f64) -> Result<(), String> {
        self.expect(&[Mode::Instantiated], "set up the experiment")?;
        if !start.is_finite() {
            return Err(format!("startTime must be finite, given {start}"));
        }
        self.start = start;
        Ok(())
    }

    /// Leaves *Initialization* mode for *Step* mode: the arm is built from the parameters.
    pub fn exit_initialization(&mut self) -> Result<(), String> {
        self.expect(&[Mode::Initialization], "exit initialization mode")?;
        self.simulator()?;
        self.mode = Mode::Step;
        Ok(())
    }

    /// *Terminated*.
    pub fn terminate(&mut self) -> Result<(), String> {
        self.expect(
            &[Mode::Step, Mode::Initialization, Mode::Terminated],
            "terminate",
        )?;
        self.mode = Mode::Terminated;
        Ok(())
    }

    /// Back to *Instantiated* with the exported parameters, zero inputs, time 0.
    pub fn reset(&mut self) {
        *self = Self::new(self.model.clone());
    }

    fn expect(&self, modes: &[Mode], what: &str) -> Result<(), String> {
        if modes.contains(&self.mode) {
            return Ok(());
        }
        Err(format!(
            "cannot {what} in {} mode (allowed in: {})",
            name(self.mode),
            modes
                .iter()
                .map(|m| name(*m))
                .collect::<Vec<_>>()
                .join(", ")
        ))
    }

    /// The run, built from the parameters if it does not exist yet.
    fn simulator(&mut self) -> Result<&mut Simulator, String> {
        if self.sim.is_none() {
            let robot = self.model.arm.robot().clone();
            let made = |arm: crate::Result<FlexibleArm>| {
                arm.map_err(|e| format!("the parameters do not make an arm: {e}"))
            };
            let mut arm = made(FlexibleArm::new(robot, self.joints.clone()))?
                .with_method(self.model.arm.method());
            if let Some(wheels) = self.model.arm.wheels() {
                arm = made(arm.with_wheels(wheels.clone()))?;
            }
            let mut x0 = arm
                .state(&StateSpec {
                    q: Some(&self.initial.q0),
                    ..StateSpec::default()
                })
                .map_err(|e| format!("q0: {e}"))?;
            x0[arm.layout().wheel_speed()].copy_from_slice(&self.initial.wheel_speed0);
            let mut sim =
                Simulator::new(arm, &x0, self.model.config.dt).map_err(|e| e.to_string())?;
            self.hold(&mut sim)?;
            self.sim = Some(sim);
            self.fresh = false;
        }
        Ok(self.sim.as_mut().expect("just built"))
    }

    /// The held inputs into `sim`.
    fn hold(&self, sim: &mut Simulator) -> Result<(), String> {
        sim.set_motor_torque(&self.u).map_err(|e| e.to_string())?;
        sim.set_base_wrench(&self.base_wrench)
            .map_err(|e| e.to_string())?;
        if !self.wheel_torque.is_empty() {
            sim.set_wheel_torque(&self.wheel_torque)
                .map_err(|e| e.to_string())?;
        }
        Ok(())
    }

    /// The values of the variables `vrs` into `values` (same lengths).
    pub fn get(&mut self, vrs: &[u32], values: &mut [f64]) -> Result<(), String> {
        if vrs.len() != values.len() {
            return Err(format!(
                "{} values for {} value references",
                values.len(),
                vrs.len()
            ));
        }
        for (value, &vr) in values.iter_mut().zip(vrs) {
            let slot = self.model.table.get(vr)?.slot;
            *value = match slot {
                Slot::Time => self.time(),
                Slot::Parameter(p, i) => parameter_value(&self.joints, &self.initial, p, i),
                Slot::MotorTorque(i) => self.u[i],
                Slot::BaseWrench(i) => self.base_wrench[i],
                Slot::WheelTorque(i) => self.wheel_torque[i],
                Slot::Output(quantity, i) => {
                    // parts of the state are read from it: a master reading q or theta every
                    // step does not pay for the momentum and energy
                    let direct = match self.mode {
                        Mode::Instantiated => None,
                        _ => {
                            let sim = self.simulator()?;
                            quantity.from_state(&sim.arm().layout(), sim.state(), i)
                        }
                    };
                    if let Some(v) = direct {
                        v
                    } else {
                        if !self.fresh {
                            if self.mode == Mode::Instantiated {
                                return Err(format!(
                                    "output {} cannot be read before initialization mode",
                                    self.model.table.variables[vr as usize].name
                                ));
                            }
                            let mut outputs = std::mem::take(&mut self.outputs);
                            self.simulator()?.outputs_into(&mut outputs);
                            self.outputs = outputs;
                            self.fresh = true;
                        }
                        quantity.read(&self.outputs, i)
                    }
                }
            };
        }
        Ok(())
    }

    /// Sets the variables `vrs` to `values` (same lengths), all or none: a refused value
    /// changes nothing.
    pub fn set(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        if vrs.len() != values.len() {
            return Err(format!(
                "{} values for {} value references",
                values.len(),
                vrs.len()
            ));
        }
        // check every value first, so that a refusal leaves the instance as it was
        for (&vr, &value) in vrs.iter().zip(values) {
            let var = self.model.table.get(vr)?;
            if !value.is_finite() {
                return Err(format!("{} = {value}: the value must be finite", var.name));
            }
            match (var.causality, var.slot) {
                (Causality::Parameter, Slot::Parameter(p, _)) => {
                    if !matches!(self.mode, Mode::Instantiated | Mode::Initialization) {
                        return Err(format!(
                            "{} is a fixed parameter: it can be set only before leaving \
                             initialization mode (now in {} mode)",
                            var.name,
                            name(self.mode)
                        ));
                    }
                    let (ok, domain) = p.admits(value);
                    if !ok {
                        return Err(format!("{} = {value}: expected {domain}", var.name));
                    }
                }
                (Causality::Input, _) => {
                    if self.mode == Mode::Terminated {
                        return Err(format!("{}: cannot set an input once terminated", var.name));
                    }
                }
                (causality, _) => {
                    return Err(format!(
                        "{} is {}: it cannot be set",
                        var.name,
                        match causality {
                            Causality::Output => "an output",
                            _ => "the independent variable",
                        }
                    ))
                }
            }
        }
        for (&vr, &value) in vrs.iter().zip(values) {
            match self.model.table.variables[vr as usize].slot {
                Slot::Parameter(p, i) => {
                    let j = &mut self.joints;
                    let field = match p {
                        Parameter::Stiffness => &mut j.stiffness[i],
                        Parameter::MotorInertia => &mut j.motor_inertia[i],
                        Parameter::Damping => &mut j.damping[i],
                        Parameter::MotorDamping => &mut j.motor_damping[i],
                        Parameter::InitialAngle => &mut self.initial.q0[i],
                        Parameter::InitialWheelSpeed => &mut self.initial.wheel_speed0[i],
                    };
                    if field.to_bits() != value.to_bits() {
                        *field = value;
                        self.sim = None;
                        self.fresh = false;
                    }
                }
                Slot::MotorTorque(i) => self.u[i] = value,
                Slot::BaseWrench(i) => self.base_wrench[i] = value,
                Slot::WheelTorque(i) => self.wheel_torque[i] = value,
                _ => unreachable!("checked above"),
            }
        }
        if let Some(mut sim) = self.sim.take() {
            // checked finite above: this cannot fail
            let held = self.hold(&mut sim);
            self.sim = Some(sim);
            held?;
        }
        Ok(())
    }

    /// One communication step from `t` (which must be the FMU's time) of length `h` (a whole
    /// multiple of dt, ≥ dt): `h / dt` RK4 steps with the inputs held. A step that diverges is
    /// undone and refused, naming the time.
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), String> {
        self.expect(&[Mode::Step], "do a step")?;
        let dt = self.model.config.dt;
        let now = self.time();
        if !t.is_finite() || (t - now).abs() > tolerance(dt, now) {
            return Err(format!(
                "currentCommunicationPoint {t} is not the FMU's time {now} (start + k dt)"
            ));
        }
        let n = (h / dt).round();
        if !(h.is_finite() && n >= 1.0 && (n * dt - h).abs() <= tolerance(dt, h)) {
            return Err(format!(
                "communicationStepSize {h} s is not a whole multiple of the FMU's dt = {dt} s \
                 (set the master's communication step to k * {dt} s)"
            ));
        }
        if n > 1e15 {
            return Err(format!(
                "communicationStepSize {h} s is too long: {n} steps of dt"
            ));
        }
        self.fresh = false;
        let sim = self.simulator()?;
        sim.step(n as usize).map_err(|e| e.to_string())
    }

    /// The instance's state as bytes (mode, start time, the simulator's blob). Only once
    /// initialised: before, there is no run to save.
    pub fn save(&self) -> Result<Vec<u8>, String> {
        let Some(sim) = self
            .sim
            .as_ref()
            .filter(|_| self.mode != Mode::Instantiated)
        else {
            return Err("the FMU state can be saved once initialized".into());
        };
        let mut blob = Vec::with_capacity(8 + 4 + 1 + 8 + sim.saved_len());
        blob.extend_from_slice(STATE_MAGIC);
        blob.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        blob.push(self.mode as u8);
        blob.extend_from_slice(&self.start.to_bits().to_le_bytes());
        sim.save_into(&mut blob);
        Ok(blob)
    }

    /// Puts back a state from [`save`](Self::save) of an instance of the same FMU with the
    /// same parameters; a foreign or damaged blob is refused and changes nothing.
    pub fn restore(&mut self, blob: &[u8]) -> Result<(), String> {
        if blob.len() < 21 || &blob[..8] != STATE_MAGIC {
            return Err("not a saved orbitflex FMU state".into());
        }
        let version = u32::from_le_bytes(blob[8..12].try_into().expect("4 bytes"));
        if version != FORMAT_VERSION {
            return Err(format!(
                "FMU state saved in format version {version}; this runtime reads version \
                 {FORMAT_VERSION}"
            ));
        }
        let mode = match blob[12] {
            1 => Mode::Initialization,
            2 => Mode::Step,
            3 => Mode::Terminated,
            m => return Err(format!("FMU state with an unknown mode {m}")),
        };
        let start = f64::from_bits(u64::from_le_bytes(
            blob[13..21].try_into().expect("8 bytes"),
        ));
        if !start.is_finite() {
            return Err("FMU state with a non-finite start time".into());
        }
        let Some(sim) = self.sim.as_mut() else {
            return Err(
                "an FMU state can be restored once this instance is initialized (its \
                 parameters make the arm the state belongs to)"
                    .into(),
            );
        };
        sim.restore(&blob[21..]).map_err(|e| e.to_string())?;
        self.u.copy_from_slice(sim.motor_torque());
        self.base_wrench = *sim.base_wrench();
        self.wheel_torque.copy_from_slice(sim.wheel_torque());
        self.mode = mode;
        self.start = start;
        self.fresh = false;
        Ok(())
    }
}

/// How far a time may be from a multiple of dt and still count as one: float noise in
/// `start + k h` and `n dt`, not a real fraction of a step.
fn tolerance(dt: f64, value: f64) -> f64 {
    1e-6 * dt + 8.0 * f64::EPSILON * value.abs()
}

fn name(mode: Mode) -> &'static str {
    match mode {
        Mode::Instantiated => "Instantiated",
        Mode::Initialization => "Initialization",
        Mode::Step => "Step",
        Mode::Terminated => "Terminated",
    }
}

//! [`Simulator`]: a run advanced by its caller, a step (or `n` steps) at a time, with inputs
//! held between calls. It is what co-simulation is built on: the C API and the FMI
//! co-simulation FMU step one, and a Python master steps one.
//!
//! A sequence of [`Simulator::step`] calls computes, bit for bit, the states [`simulate`]
//! computes with the same inputs: both take the same RK4 step ([`step`](super::step)'s kernel)
//! on the same state, with the same checks after it. The step allocates nothing.
//!
//! Inputs are held (zero-order hold): each setter replaces one input, which then stays until it
//! is set again. The reaction-wheel torque commands are one more held input; like a run, each
//! step saturates them at the state it starts from (torque, then speed limits) and applies that.
//!
//! [`simulate`]: super::simulate()

use super::simulate::{step_unchecked, Observer, Unobserved};
use super::ArmWorkspace;
use crate::args::{check_dt, check_vector};
use crate::error::{Error, Result};
use crate::flex::{FlexibleArm, Inputs};
use crate::spatial::normalise_quaternion;
use crate::spatial::Force;
use crate::state::state_defect;
use crate::Loads;

/// The first bytes of a [`Simulator::save`] blob.
const MAGIC: &[u8; 8] = b"OFXSIM\0\0";

/// The layout of a [`Simulator::save`] blob. Raise it whenever the layout changes: a blob of
/// another version is refused, never misread. Version 2 added the reaction-wheel count to the
/// header and the wheel torques applied over the last step to the numbers.
pub const STATE_FORMAT_VERSION: u32 = 2;

/// A stepping simulation of one [`FlexibleArm`]: the arm, a workspace, the state `x`
/// (model §4), the step count `k` (time `t = k dt`), the step `dt` and the held inputs.
///
/// ```
/// use orbitflex::{FlexibleArm, FlexibleJoints, Robot, Simulator};
/// let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
/// let x0 = arm.rest_state();
/// let mut sim = Simulator::new(arm, &x0, 1e-3)?;
/// sim.set_motor_torque(&[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])?; // held until set again
/// sim.step(100)?;
/// assert_eq!(sim.steps(), 100);
/// assert!((sim.t() - 0.1).abs() < 1e-15);
/// let blob = sim.save();
/// sim.step(10)?;
/// sim.restore(&blob)?; // back at t = 0.1 s, bit for bit
/// assert_eq!(sim.steps(), 100);
/// # Ok::<(), orbitflex::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct Simulator {
    arm: FlexibleArm,
    ws: ArmWorkspace,
    /// The state (13 + 4n).
    x: Vec<f64>,
    /// The state before the step in progress: a failed step puts it back.
    before: Vec<f64>,
    /// Steps taken since the start: `t = k dt`.
    k: u64,
    dt: f64,
    /// Held motor torques `u` (n, N·m, link side).
    u: Vec<f64>,
    /// Held `f_B` (`[moment; force]`, base frame).
    base_wrench: [f64; 6],
    /// Held `[f_1; …; f_k]`, or empty for none.
    ee_wrench: Vec<f64>,
    /// Held reaction-wheel torque commands (k, N·m; empty without wheels).
    wheel_torque: Vec<f64>,
    /// The wheel torques applied over the last step taken (k, after saturation; zero before
    /// the first).
    applied: Vec<f64>,
    /// `applied` before the step in progress: a failed step puts it back.
    before_applied: Vec<f64>,
    /// [`arm_fingerprint`] of `arm`, written into saved states.
    fingerprint: u64,
}

/// What a co-simulation master reads after a step (see [`Simulator::outputs_into`]); every
/// quantity in SI units, angles in rad.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Outputs {
    /// Link angles `q` (n).
    pub q: Vec<f64>,
    /// Link rates `q̇` (n, rad/s).
    pub qd: Vec<f64>,
    /// Motor angles `θ` (n, link side).
    pub theta: Vec<f64>,
    /// Motor rates `θ̇` (n, rad/s, link side).
    pub theta_dot: Vec<f64>,
    /// Joint deflections `θ − q` (n).
    pub deflection: Vec<f64>,
    /// Spring torques `τ = k (θ − q) + d (θ̇ − q̇)` (n, N·m).
    pub spring_torque: Vec<f64>,
    /// `[r_B (m, inertial frame); quat_B (x, y, z, w)]`.
    pub base_pose: [f64; 7],
    /// `[ω_B (rad/s); v_B (m/s)]`, base-frame components.
    pub base_twist: [f64; 6],
    /// `[position (m); quaternion (x, y, z, w)]` of each end-effector in the inertial frame
    /// (7 per end-effector, in [`crate::Robot::ee_links`] order).
    pub ee_poses: Vec<f64>,
    /// Total spatial momentum `[angular (N·m·s); linear (N·s)]`, inertial frame, about the
    /// inertial origin (model §6.1).
    pub momentum: [f64; 6],
    /// Total energy (J), model §6.2.
    pub energy: f64,
    /// Reaction-wheel speeds `Ω` relative to the bus (k, rad/s; empty without wheels).
    pub wheel_speed: Vec<f64>,
    /// The torques the wheel motors applied over the last step (k, N·m, after saturation;
    /// zero before the first step; empty without wheels): after step `k`, the wheel columns of
    /// row `k` of a run's held inputs ([`Trajectory::u`](crate::Trajectory::u)).
    pub applied_wheel_torque: Vec<f64>,
}

impl Outputs {
    /// Buffers of the right sizes for `arm`.
    pub fn for_arm(arm: &FlexibleArm) -> Self {
        let n = arm.dof();
        Self {
            q: vec![0.0; n],
            qd: vec![0.0; n],
            theta: vec![0.0; n],
            theta_dot: vec![0.0; n],
            deflection: vec![0.0; n],
            spring_torque: vec![0.0; n],
            ee_poses: vec![0.0; 7 * arm.robot().end_effectors().len()],
            wheel_speed: vec![0.0; arm.layout().wheels],
            applied_wheel_torque: vec![0.0; arm.layout().wheels],
            ..Self::default()
        }
    }
}

impl Simulator {
    /// A simulator of `arm` at state `x0` (its quaternion normalised, as [`simulate`] does),
    /// time 0, step `dt` (s, finite and > 0), every input zero.
    ///
    /// [`simulate`]: super::simulate()
    pub fn new(arm: FlexibleArm, x0: &[f64], dt: f64) -> Result<Self> {
        check_dt(dt)?;
        let len = arm.layout().len();
        let n = arm.dof();
        let mut sim = Self {
            ws: arm.workspace(),
            x: vec![0.0; len],
            before: vec![0.0; len],
            k: 0,
            dt,
            u: vec![0.0; n],
            base_wrench: [0.0; 6],
            ee_wrench: Vec::new(),
            wheel_torque: vec![0.0; arm.layout().wheels],
            applied: vec![0.0; arm.layout().wheels],
            before_applied: vec![0.0; arm.layout().wheels],
            fingerprint: arm_fingerprint(&arm),
            arm,
        };
        sim.reset(x0)?;
        Ok(sim)
    }

    /// Back to time 0 at state `x0` (checked, quaternion normalised), every input zero.
    pub fn reset(&mut self, x0: &[f64]) -> Result<()> {
        self.arm.check_state(x0).map_err(|e| rename(e, "x0"))?;
        self.x.copy_from_slice(x0);
        normalise_quaternion(&mut self.x[self.arm.layout().quaternion()]);
        self.k = 0;
        self.u.fill(0.0);
        self.base_wrench = [0.0; 6];
        self.ee_wrench.clear();
        self.wheel_torque.fill(0.0);
        self.applied.fill(0.0);
        Ok(())
    }

    /// The arm.
    pub fn arm(&self) -> &FlexibleArm {
        &self.arm
    }

    /// The state `x` (13 + 4n, model §4).
    pub fn state(&self) -> &[f64] {
        &self.x
    }

    /// The step `dt` (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The steps taken since the start (or the last [`reset`](Self::reset)).
    pub fn steps(&self) -> u64 {
        self.k
    }

    /// The time `t = k dt` (s), computed from the step count as [`simulate`] does, so that it
    /// carries no accumulated round-off.
    ///
    /// [`simulate`]: super::simulate()
    pub fn t(&self) -> f64 {
        self.k as f64 * self.dt
    }

    /// The held motor torques `u` (n, N·m, link side).
    pub fn motor_torque(&self) -> &[f64] {
        &self.u
    }

    /// The held base wrench `f_B = [moment; force]` (base frame, applied to the base).
    pub fn base_wrench(&self) -> &[f64; 6] {
        &self.base_wrench
    }

    /// The held end-effector wrenches `[f_1; …; f_k]` (empty: none).
    pub fn ee_wrench(&self) -> &[f64] {
        &self.ee_wrench
    }

    /// The held reaction-wheel torque commands (k, N·m; empty without wheels).
    pub fn wheel_torque(&self) -> &[f64] {
        &self.wheel_torque
    }

    /// The torques the wheel motors applied over the last step (k, N·m: the held commands
    /// saturated at that step's start; zero before the first step; empty without wheels).
    pub fn applied_wheel_torque(&self) -> &[f64] {
        &self.applied
    }

    /// Holds the reaction-wheel torque commands (k, N·m, applied to each wheel about its axis;
    /// the bus feels the opposite) from the next step on; each step saturates them at its
    /// start. An error on an arm without wheels.
    pub fn set_wheel_torque(&mut self, wheel_torque: &[f64]) -> Result<()> {
        if self.arm.wheels().is_none() {
            return Err(Error::InvalidArgument {
                what: "wheel_torque".into(),
                message: "the arm has no reaction wheels; build it with wheels".into(),
            });
        }
        check_vector("wheel_torque", wheel_torque, self.wheel_torque.len())?;
        self.wheel_torque.copy_from_slice(wheel_torque);
        Ok(())
    }

    /// Holds the motor torques `u` (n, N·m, link side) from the next step on.
    pub fn set_motor_torque(&mut self, u: &[f64]) -> Result<()> {
        check_vector("u", u, self.arm.dof())?;
        self.u.copy_from_slice(u);
        Ok(())
    }

    /// Holds the base wrench `f_B = [moment (N·m); force (N)]` (base frame, applied to the
    /// base by its actuators) from the next step on.
    pub fn set_base_wrench(&mut self, base_wrench: &[f64]) -> Result<()> {
        check_vector("base_wrench", base_wrench, 6)?;
        self.base_wrench.copy_from_slice(base_wrench);
        Ok(())
    }

    /// Holds the end-effector wrenches `[f_1; …; f_k]` (6 per end-effector, each in its EE
    /// frame, exerted by the end-effector on its environment), or none (`None`). Allocates
    /// only the first time wrenches are given.
    pub fn set_ee_wrench(&mut self, ee_wrench: Option<&[f64]>) -> Result<()> {
        match ee_wrench {
            None => self.ee_wrench.clear(),
            Some(f) => {
                crate::args::check_ee_wrench(self.arm.robot(), f)?;
                if f.is_empty() {
                    self.ee_wrench.clear();
                } else {
                    self.ee_wrench.clear();
                    self.ee_wrench.extend_from_slice(f);
                }
            }
        }
        Ok(())
    }

    /// Takes `n` RK4 steps of `dt` with the held inputs. See [`step_observed`](Self::step_observed).
    pub fn step(&mut self, n: usize) -> Result<()> {
        self.step_observed(n, &mut Unobserved)
    }

    /// Takes `n` RK4 steps of `dt` with the held inputs, asking `observer` before every
    /// `observer.every()`-th step (after the first) whether to go on. Allocation-free.
    ///
    /// A step whose state turns non-finite (or whose quaternion collapses) is undone: the
    /// simulator stays at the last good state and time, and the [`Error::Simulation`] names
    /// the failing step `k` (from `t = k dt`). An observer that says stop leaves the simulator
    /// after the steps already taken, with the same error ("interrupted by the caller").
    pub fn step_observed(&mut self, n: usize, observer: &mut dyn Observer) -> Result<()> {
        let every = observer.every();
        let Self {
            arm,
            ws,
            x,
            before,
            k,
            dt,
            u,
            base_wrench,
            ee_wrench,
            wheel_torque,
            applied,
            before_applied,
            ..
        } = self;
        let layout = arm.layout();
        for i in 0..n {
            let stop = |message: String| Error::Simulation {
                step: *k as usize,
                time: *k as f64 * *dt,
                message,
            };
            if every > 0 && i > 0 && i % every == 0 && !observer.observe(i, n) {
                return Err(stop("interrupted by the caller".into()));
            }
            before.copy_from_slice(x);
            if let Some(wheels) = arm.wheels() {
                before_applied.copy_from_slice(applied);
                wheels.saturate(wheel_torque, &x[layout.wheel_speed()], applied);
            }
            let inputs = Inputs {
                u,
                loads: Loads {
                    base_wrench: Force::from_slice(base_wrench),
                    ee_wrench,
                },
                wheel_torque: applied,
            };
            let outcome = match step_unchecked(arm, ws, x, *dt, &inputs) {
                Err(e) => Some(format!("the state diverged during the step ({e})")),
                Ok(()) => state_defect(&layout, x).map(|d| format!("the state diverged: {d}")),
            };
            if let Some(message) = outcome {
                x.copy_from_slice(before);
                applied.copy_from_slice(before_applied);
                return Err(stop(format!(
                    "{message}; dt = {dt} s may be past the RK4 stability limit"
                )));
            }
            *k += 1;
        }
        Ok(())
    }

    /// The outputs at the current state into `out` (sized by [`Outputs::for_arm`]);
    /// allocation-free.
    ///
    /// # Panics
    /// If `out` was not sized for this arm.
    pub fn outputs_into(&mut self, out: &mut Outputs) {
        let layout = self.arm.layout();
        let x = &self.x;
        out.q.copy_from_slice(&x[layout.q()]);
        out.qd.copy_from_slice(&x[layout.qd()]);
        out.theta.copy_from_slice(&x[layout.theta()]);
        out.theta_dot.copy_from_slice(&x[layout.theta_dot()]);
        for ((d, theta), q) in out.deflection.iter_mut().zip(&out.theta).zip(&out.q) {
            *d = theta - q;
        }
        self.arm.spring_torque(x, &mut out.spring_torque);
        out.base_pose.copy_from_slice(&x[layout.base_pose()]);
        out.base_twist.copy_from_slice(&x[layout.base_twist()]);
        for (e, pose) in out.ee_poses.chunks_exact_mut(7).enumerate() {
            pose.copy_from_slice(&self.arm.ee_pose(x, e));
        }
        out.momentum = self.arm.momentum(&mut self.ws, x);
        out.energy = self.arm.energy(&mut self.ws, x);
        out.wheel_speed.copy_from_slice(&x[layout.wheel_speed()]);
        out.applied_wheel_torque.copy_from_slice(&self.applied);
    }

    /// The outputs at the current state ([`outputs_into`](Self::outputs_into) into new buffers).
    pub fn outputs(&mut self) -> Outputs {
        let mut out = Outputs::for_arm(&self.arm);
        self.outputs_into(&mut out);
        out
    }

    /// The length of a [`save`](Self::save) blob for this simulator (it changes only when EE
    /// wrenches start or stop being held).
    pub fn saved_len(&self) -> usize {
        8 + 4
            + 8
            + 4
            + 4
            + 4
            + 8
            + 8
            + 8 * (self.x.len()
                + self.u.len()
                + 2 * self.wheel_torque.len()
                + 6
                + self.ee_wrench.len())
    }

    /// The simulator's state as bytes: the state (with the wheel speeds), the step count, `dt`,
    /// the held inputs and the wheel torques applied over the last step, with a format version ([`STATE_FORMAT_VERSION`]) and a fingerprint of the arm.
    /// [`restore`](Self::restore) puts it back bit for bit.
    pub fn save(&self) -> Vec<u8> {
        let mut blob = Vec::with_capacity(self.saved_len());
        self.save_into(&mut blob);
        blob
    }

    /// [`save`](Self::save), appending to `blob` (allocation-free when it has room).
    pub fn save_into(&self, blob: &mut Vec<u8>) {
        blob.extend_from_slice(MAGIC);
        blob.extend_from_slice(&STATE_FORMAT_VERSION.to_le_bytes());
        blob.extend_from_slice(&self.fingerprint.to_le_bytes());
        blob.extend_from_slice(&(self.arm.dof() as u32).to_le_bytes());
        blob.extend_from_slice(&(self.ee_wrench.len() as u32).to_le_bytes());
        blob.extend_from_slice(&(self.wheel_torque.len() as u32).to_le_bytes());
        blob.extend_from_slice(&self.dt.to_bits().to_le_bytes());
        blob.extend_from_slice(&self.k.to_le_bytes());
        // the wheel commands and the torques last applied (none without wheels) after u
        let numbers = self
            .x
            .iter()
            .chain(&self.u)
            .chain(&self.wheel_torque)
            .chain(&self.applied)
            .chain(&self.base_wrench);
        for v in numbers.chain(&self.ee_wrench) {
            blob.extend_from_slice(&v.to_bits().to_le_bytes());
        }
    }

    /// Puts back a state saved by [`save`](Self::save) from a simulator of the same arm (same
    /// model, joint parameters and dynamics method) and the same `dt`. A blob of another
    /// format version, of another arm, truncated, or holding non-finite numbers is refused
    /// with an error saying which, and the simulator is left as it was.
    pub fn restore(&mut self, blob: &[u8]) -> Result<()> {
        let mut r = Reader { blob, at: 0 };
        let (ee, k) = self.read_header(&mut r)?;
        let (len, own_wheels) = (self.x.len(), self.wheel_torque.len());
        let expected = len + self.u.len() + 2 * own_wheels + 6 + ee;
        let wrenches = 6 * self.arm.robot().end_effectors().len();
        if ee != 0 && ee != wrenches {
            return Err(bad_state(format!(
                "holds {ee} EE-wrench numbers; this arm takes 0 or {wrenches}"
            )));
        }
        if r.remaining() != 8 * expected {
            return Err(bad_state(format!(
                "{} bytes of numbers after the header; expected {} ({expected} numbers)",
                r.remaining(),
                8 * expected
            )));
        }
        let numbers: Vec<f64> = (0..expected).map_while(|_| r.f64()).collect();
        if let Some(i) = numbers.iter().position(|v| !v.is_finite()) {
            return Err(bad_state(format!(
                "number {i} is not finite ({})",
                numbers[i]
            )));
        }
        let (x, rest) = numbers.split_at(len);
        self.arm
            .check_state(x)
            .map_err(|e| bad_state(e.to_string()))?;
        let (u, rest) = rest.split_at(self.u.len());
        let (wheel_torque, rest) = rest.split_at(own_wheels);
        let (applied, rest) = rest.split_at(own_wheels);
        let (base_wrench, ee_wrench) = rest.split_at(6);
        self.x.copy_from_slice(x);
        self.k = k;
        self.u.copy_from_slice(u);
        self.wheel_torque.copy_from_slice(wheel_torque);
        self.applied.copy_from_slice(applied);
        self.base_wrench.copy_from_slice(base_wrench);
        self.ee_wrench.clear();
        self.ee_wrench.extend_from_slice(ee_wrench);
        Ok(())
    }

    /// Reads and checks the header of a [`save`](Self::save) blob: its marker and format
    /// version, then the arm (wheels, fingerprint, joints) and `dt` it was saved from, which must
    /// be this simulator's. Returns the number of EE-wrench numbers it holds and its step count.
    fn read_header(&self, r: &mut Reader) -> Result<(usize, u64)> {
        if r.bytes(8) != Some(MAGIC.as_slice()) {
            return Err(bad_state(
                "not a saved orbitflex simulator state (it does not start with the format's \
                 marker)"
                    .into(),
            ));
        }
        let version = r
            .u32()
            .ok_or_else(|| bad_state("truncated after its marker".into()))?;
        if version != STATE_FORMAT_VERSION {
            return Err(bad_state(format!(
                "saved in format version {version}; this orbitflex reads version \
                 {STATE_FORMAT_VERSION}"
            )));
        }
        let header = (r.u64(), r.u32(), r.u32(), r.u32(), r.u64(), r.u64());
        let (Some(fingerprint), Some(n), Some(ee), Some(wheels), Some(dt_bits), Some(k)) = header
        else {
            return Err(bad_state("truncated in its header".into()));
        };
        let own_wheels = self.wheel_torque.len();
        if wheels as usize != own_wheels {
            let count = |k: usize| match k {
                0 => "no reaction wheels".to_string(),
                1 => "1 reaction wheel".to_string(),
                k => format!("{k} reaction wheels"),
            };
            return Err(bad_state(format!(
                "saved from an arm with {}; this simulator's arm has {} (a state holds the \
                 speeds of its own wheels)",
                count(wheels as usize),
                count(own_wheels)
            )));
        }
        if fingerprint != self.fingerprint || n as usize != self.arm.dof() {
            return Err(bad_state(format!(
                "saved from another arm ({n} joints, fingerprint {fingerprint:016x}); this \
                 simulator's arm has {} joints, fingerprint {:016x} (same model, joint \
                 parameters and dynamics method needed)",
                self.arm.dof(),
                self.fingerprint
            )));
        }
        if dt_bits != self.dt.to_bits() {
            return Err(bad_state(format!(
                "saved with dt = {:e} s; this simulator steps dt = {:e} s",
                f64::from_bits(dt_bits),
                self.dt
            )));
        }
        Ok((ee as usize, k))
    }

    /// The fingerprint of this simulator's arm ([`arm_fingerprint`]).
    pub fn fingerprint(&self) -> u64 {
        self.fingerprint
    }
}

/// A refused simulator state, with what is wrong with it.
fn bad_state(message: String) -> Error {
    Error::InvalidArgument {
        what: "simulator state".into(),
        message,
    }
}

/// The error `e` about a state, naming it `what`.
fn rename(e: Error, what: &str) -> Error {
    match e {
        Error::Dimension {
            expected, given, ..
        } => Error::Dimension {
            what: what.into(),
            expected,
            given,
        },
        other => other,
    }
}

/// Reads little-endian numbers from a blob.
struct Reader<'a> {
    blob: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn bytes(&mut self, len: usize) -> Option<&'a [u8]> {
        let out = self.blob.get(self.at..self.at.checked_add(len)?)?;
        self.at += len;
        Some(out)
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.bytes(4)?.try_into().ok()?))
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.bytes(8)?.try_into().ok()?))
    }
    fn f64(&mut self) -> Option<f64> {
        self.u64().map(f64::from_bits)
    }
    fn remaining(&self) -> usize {
        self.blob.len() - self.at
    }
}

/// A 64-bit FNV-1a hash of everything that makes an arm's dynamics: the joints (names, axes,
/// origins), the tree, the inertias, the end-effector frames, the joint parameters, the
/// dynamics method and the reaction wheels (an arm without wheels hashes as it did before
/// wheels existed). Two arms with the same fingerprint compute the same steps; the numbers are
/// hashed through their shortest round-trip decimal form, so the fingerprint is the same on
/// every machine.
pub fn arm_fingerprint(arm: &FlexibleArm) -> u64 {
    let robot = arm.robot();
    let mut text = format!(
        "{:?}|{:?}|{:?}|{:?}|{:?}|{:?}",
        robot.joints(),
        robot.parents(),
        robot.inertias(),
        robot.end_effectors(),
        arm.joints(),
        arm.method()
    );
    if let Some(wheels) = arm.wheels() {
        text.push_str(&format!("|{:?}", wheels.wheels()));
    }
    fnv1a(text.as_bytes())
}

/// The 64-bit FNV-1a hash of `bytes`.
pub(crate) fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

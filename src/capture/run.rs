//! A run that carries a target and captures it: [`simulate_capture_into`].
//!
//! **The target in the RK4 step.** Before the capture the target is a free, torque-free rigid
//! body: nothing it does acts on the arm, and nothing the arm does acts on it. Each step
//! integrates the system `[arm state | target state]` with one classic RK4 step of `dt`. Since
//! the two parts do not interact, its stages are the arm's stages and the target's stages at the
//! same times, and RK4's arithmetic is element by element, so the step is computed as the arm's
//! step ([`Stepper::step`]) and the target's ([`TargetMotion`], the same [`Rk4`]) one after the
//! other: the same numbers, bit for bit, as one [`OdeSystem`] over the pair (tested), and a run
//! without a target pays nothing for it.
//!
//! **The trigger.** At the start of each step `k` (state at `t = k dt`) before the capture, the
//! [`Approach`] of the EE to the handle is measured; at the first step where it is within the
//! [`CaptureWhen`] tolerances, [`capture`] is applied to that state: the arm becomes the combined
//! arm, `x` jumps to the post-capture state (same layout), and step `k` integrates from it. The
//! row kept at `t = k dt` is the state the run reached there, before the impulse; the event holds
//! both sides of the jump.
//!
//! **After the capture** the target is a part of the EE's body: its pose and twist follow from the
//! EE's at the relative pose fixed at the capture, and the rows of [`CaptureRecord::target`] are
//! computed from the arm's rows.

use super::impulse::{capture, ee_twist, target_to_ee};
use super::target::{rigid_body_derivative, Target, TARGET_STATE_LEN};
use super::when::{Approach, CaptureWhen};
use crate::algorithms::{self, Data};
use crate::error::{Error, Result};
use crate::flex::FlexibleArm;
use crate::integrate::{
    recorded_rows, run_steps, Drive, Observer, OdeSystem, Recorder, Rk4, Run, StepBody, Stepper,
};
use crate::spatial::{
    normalise_quaternion, quaternion_to_rotation, Force, Inertia, Motion, Transform, Vec3,
};

/// The torque-free target as the system RK4 integrates: state `[r; quat; ω; v]`
/// ([`rigid_body_derivative`]), its quaternion renormalised after each step as the base's.
#[derive(Debug, Clone, Copy)]
pub struct TargetMotion<'a> {
    /// The target's spatial inertia about its frame origin.
    pub inertia: &'a Inertia,
}

impl OdeSystem for TargetMotion<'_> {
    fn state_len(&self) -> usize {
        TARGET_STATE_LEN
    }
    fn derivative(&mut self, x: &[f64], xdot: &mut [f64]) -> Result<()> {
        rigid_body_derivative(self.inertia, x, xdot);
        Ok(())
    }
    fn project(&mut self, x: &mut [f64]) {
        normalise_quaternion(&mut x[3..7]);
    }
}

/// One capture in a run.
#[derive(Debug, Clone)]
pub struct CaptureEvent {
    /// The step `k` that started from the post-capture state.
    pub step: usize,
    /// `k dt` (s).
    pub time: f64,
    /// Which end-effector grasped.
    pub ee: usize,
    /// The approach that met the tolerances.
    pub approach: Approach,
    /// The impulse `[moment (N·m·s); force (N·s)]` the EE exerted on the target (EE frame).
    pub impulse: Force,
    /// The kinetic energy the grasp dissipated (J, ≥ 0).
    pub energy_loss: f64,
    /// The EE's twist relative to the target just before (EE frame).
    pub relative_twist: Motion,
    /// The arm's state just before and just after (13 + 4n each).
    pub x_before: Vec<f64>,
    /// See [`x_before`](Self::x_before).
    pub x_after: Vec<f64>,
    /// The target's state `[r; quat; ω; v]` just before and just after.
    pub target_before: [f64; TARGET_STATE_LEN],
    /// See [`target_before`](Self::target_before).
    pub target_after: [f64; TARGET_STATE_LEN],
    /// Total momentum `[K; L]` (inertial, about the inertial origin) of arm and target just
    /// before, and of the combined arm just after: equal up to round-off.
    pub momentum_before: [f64; 6],
    /// See [`momentum_before`](Self::momentum_before).
    pub momentum_after: [f64; 6],
}

/// What a run with a target records beside the arm's rows.
#[derive(Debug, Clone)]
pub struct CaptureRecord {
    /// The captures, in order (at most one: a captured target is gone).
    pub events: Vec<CaptureEvent>,
    /// The target's state `[r; quat; ω; v]` at each kept row (13 per row, row-major), the rows of
    /// the arm's record.
    pub target: Vec<f64>,
    /// The combined arm after the capture, if one happened.
    pub arm_after: Option<FlexibleArm>,
    /// The target's spatial inertia about its frame origin (its own frame).
    pub inertia: Inertia,
}

impl CaptureRecord {
    /// An empty record for a target of spatial inertia `inertia`.
    pub fn new(inertia: Inertia) -> Self {
        Self {
            events: Vec::new(),
            target: Vec::new(),
            arm_after: None,
            inertia,
        }
    }

    /// The number of target rows kept.
    pub fn rows(&self) -> usize {
        self.target.len() / TARGET_STATE_LEN
    }

    /// Which arm a kept row at time `t` belongs to: `arm` up to the capture (the row at the
    /// capture's time holds the state before the impulse), the combined arm after it.
    fn arm_at<'a>(&'a self, arm: &'a FlexibleArm, t: f64) -> (&'a FlexibleArm, bool) {
        match (self.events.first(), &self.arm_after) {
            (Some(event), Some(after)) if t > event.time => (after, false),
            _ => (arm, true),
        }
    }

    /// The total momentum `[K; L]` (inertial, about the inertial origin; 6 per row) of the kept
    /// rows `(t, x)` of a run of `arm` with this record: arm and free target before the capture,
    /// the combined arm after it.
    pub fn momentum(&self, arm: &FlexibleArm, t: &[f64], x: &[f64]) -> Vec<f64> {
        self.per_row(arm, t, x, 6, |arm, ws, x, target, out| {
            let mut h = arm.momentum(ws, x);
            if let Some(s) = target {
                let twist = Motion::from_slice(&s[7..]);
                let ht = super::target::rigid_body_momentum(&self.inertia, &s[..7], &twist);
                for (a, b) in h.iter_mut().zip(ht) {
                    *a += b;
                }
            }
            out.copy_from_slice(&h);
        })
    }

    /// The total energy (J, one per row) of the kept rows: the arm's (rigid kinetic, motor
    /// kinetic, spring) plus the free target's kinetic energy before the capture; the combined
    /// arm's after it.
    pub fn energy(&self, arm: &FlexibleArm, t: &[f64], x: &[f64]) -> Vec<f64> {
        self.per_row(arm, t, x, 1, |arm, ws, x, target, out| {
            out[0] = arm.energy(ws, x);
            if let Some(s) = target {
                let twist = Motion::from_slice(&s[7..]);
                out[0] += 0.5 * twist.dot(&self.inertia.apply(&twist));
            }
        })
    }

    fn per_row(
        &self,
        arm: &FlexibleArm,
        t: &[f64],
        x: &[f64],
        width: usize,
        f: impl Fn(&FlexibleArm, &mut crate::flex::ModelWorkspace, &[f64], Option<&[f64]>, &mut [f64]),
    ) -> Vec<f64> {
        let len = arm.layout().len();
        let mut out = vec![0.0; t.len() * width];
        // the combined arm has the arm's bodies and joints (only an inertia differs): one
        // workspace serves both
        let mut ws = crate::flex::ModelWorkspace::new(arm);
        for (k, &time) in t.iter().enumerate() {
            let (which, free) = self.arm_at(arm, time);
            let target =
                free.then(|| &self.target[k * TARGET_STATE_LEN..(k + 1) * TARGET_STATE_LEN]);
            f(
                which,
                &mut ws,
                &x[k * len..(k + 1) * len],
                target,
                &mut out[k * width..(k + 1) * width],
            );
        }
        out
    }
}

/// A run with a target ([`simulate_capture_into`]) that stopped early: the error and what it had
/// recorded of the target and the events.
#[derive(Debug, Clone)]
pub struct CaptureFailure {
    /// Why the run stopped.
    pub error: Error,
    /// The target rows and events kept before it stopped (the arm's rows are in the recorder).
    pub record: CaptureRecord,
}

/// The captured target, welded to end-effector `ee`: `Φ_{e,t}` fixed at the capture.
#[derive(Debug, Clone)]
struct Joined {
    arm: FlexibleArm,
    x_et: Transform,
}

/// The [`StepBody`] of a run with a target (module docs).
struct CaptureSteps<'a> {
    arm: &'a FlexibleArm,
    joined: Option<Joined>,
    stepper: Stepper,
    target: Target,
    state: [f64; TARGET_STATE_LEN],
    rk4: Rk4,
    when: CaptureWhen,
    ee: usize,
    data: Data,
    record: CaptureRecord,
}

impl CaptureSteps<'_> {
    /// Captures at state `x` if the approach is within the tolerances; `x` jumps in place.
    fn trigger(&mut self, x: &mut [f64], k: usize, dt: f64) -> Result<()> {
        // the distance first, from the states alone (no allocation): most steps stop here
        let ee = self.arm.ee_pose(x, self.ee);
        let g = self.target.grasp();
        let handle = Vec3::new(self.state[0], self.state[1], self.state[2])
            + quaternion_to_rotation(&self.state[3..7]) * Vec3::new(g[0], g[1], g[2]);
        if (handle - Vec3::new(ee[0], ee[1], ee[2])).norm() > self.when.distance {
            return Ok(());
        }
        let target = self.target.at_state(&self.state)?;
        let approach = Approach::measure(self.arm, &mut self.data, x, &target, self.ee);
        if !self.when.is_met(&approach) {
            return Ok(());
        }
        let grasp = capture(self.arm, x, &target, Some(self.ee))?;
        let layout = self.arm.layout();
        let x_et = target_to_ee(
            self.arm.robot(),
            &x[layout.base_pose()],
            &x[layout.q()],
            &target,
            self.ee,
        );
        let mut before = self.arm.momentum(&mut self.arm.workspace(), x);
        for (b, t) in before.iter_mut().zip(target.momentum()) {
            *b += t;
        }
        let after = grasp.arm.momentum(&mut grasp.arm.workspace(), &grasp.x);
        let mut target_after = self.state;
        grasp.target_twist.write_to(&mut target_after[7..]);
        self.record.events.push(CaptureEvent {
            step: k,
            time: k as f64 * dt,
            ee: self.ee,
            approach,
            impulse: grasp.impulse,
            energy_loss: grasp.energy_loss,
            relative_twist: grasp.relative_twist,
            x_before: x.to_vec(),
            x_after: grasp.x.clone(),
            target_before: self.state,
            target_after,
            momentum_before: before,
            momentum_after: after,
        });
        x.copy_from_slice(&grasp.x);
        self.stepper = Stepper::new(&grasp.arm);
        self.record.arm_after = Some(grasp.arm.clone());
        self.joined = Some(Joined {
            arm: grasp.arm,
            x_et,
        });
        Ok(())
    }

    /// The target's state at arm state `x`: the free body's, or, once joined, the EE's carried by
    /// the fixed `Φ_{e,t}`.
    fn target_state(&mut self, x: &[f64]) -> [f64; TARGET_STATE_LEN] {
        let Some(joined) = &self.joined else {
            return self.state;
        };
        let (arm, x_et) = (&joined.arm, &joined.x_et);
        let ee_pose = arm.ee_pose(x, self.ee);
        let ee_axes = quaternion_to_rotation(&ee_pose[3..]);
        let ee_origin = Vec3::new(ee_pose[0], ee_pose[1], ee_pose[2]);
        // R_{e,t} = E_eᵀ E_t and p_{t,e} = E_tᵀ (o_e − o_t)
        let axes = ee_axes * x_et.rotation;
        let origin = ee_origin - axes * x_et.translation;
        let twist = x_et.apply_motion_inverse(&ee_twist(
            arm.robot(),
            &mut self.data,
            x,
            &arm.layout(),
            self.ee,
        ));
        let mut s = [0.0; TARGET_STATE_LEN];
        s[..7].copy_from_slice(&algorithms::pose(&origin, &axes));
        twist.write_to(&mut s[7..]);
        s
    }
}

impl StepBody for CaptureSteps<'_> {
    fn step(&mut self, drive: &mut Drive<'_>, x: &mut [f64], k: usize, dt: f64) -> Result<()> {
        if self.joined.is_none() {
            self.trigger(x, k, dt).map_err(|e| Error::Simulation {
                step: k,
                time: k as f64 * dt,
                message: format!("the capture failed: {e}"),
            })?;
        }
        match &self.joined {
            Some(joined) => self.stepper.step(&joined.arm, drive, x, k, dt),
            None => {
                self.stepper.step(self.arm, drive, x, k, dt)?;
                let mut motion = TargetMotion {
                    inertia: self.target.spatial_inertia(),
                };
                self.rk4.step(&mut motion, &mut self.state, dt)
            }
        }
    }
    fn u(&self) -> &[f64] {
        self.stepper.u()
    }
    fn inputs(&self) -> &[f64] {
        self.stepper.inputs()
    }
    fn record(&mut self, recorder: &mut dyn Recorder, t: f64, x: &[f64]) -> Result<()> {
        recorder.state(t, x)?;
        let row = self.target_state(x);
        self.record.target.extend_from_slice(&row);
        Ok(())
    }
}

/// What a run captures, and when: the `target`, the tolerances `when`, and the end-effector `ee`
/// that grasps (an index into [`Robot::end_effectors`](crate::Robot::end_effectors); `None`: the
/// only one).
#[derive(Debug, Clone, Copy)]
pub struct CaptureRun<'a> {
    /// The target, at its state at `t = 0`.
    pub target: &'a Target,
    /// The tolerances of the trigger.
    pub when: CaptureWhen,
    /// The end-effector that grasps.
    pub ee: Option<usize>,
}

/// A [`Run`] of `arm` driven by `drive` that carries `capturing.target` and captures it with
/// end-effector `capturing.ee` when `capturing.when` is met (module docs): the arm's kept rows go to
/// `recorder` as in [`simulate_into`](crate::integrate::simulate_into) (same rows, same
/// failure rule, the same `observer`), the target's rows and the events into the returned
/// [`CaptureRecord`]. The controllers keep running after the capture, on the same state layout.
///
/// Errors: the run's checks ([`Run::check`]), the tolerances ([`CaptureWhen::check`]) and `ee`
/// before the first step, with nothing recorded; then an [`Error::Simulation`] naming the step
/// (a diverging state, a failing controller, a capture that cannot be solved), with what was
/// recorded before it.
pub fn simulate_capture_into(
    arm: &FlexibleArm,
    run: &Run<'_>,
    drive: &mut Drive<'_>,
    capturing: &CaptureRun<'_>,
    observer: &mut dyn Observer,
    recorder: &mut dyn Recorder,
) -> std::result::Result<CaptureRecord, Box<CaptureFailure>> {
    let fail = |error, record| Box::new(CaptureFailure { error, record });
    let CaptureRun { target, when, ee } = *capturing;
    let checked = run
        .check(arm, drive)
        .and_then(|_| when.check())
        .and_then(|_| arm.robot().ee_choice(ee));
    let empty = || CaptureRecord::new(*target.spatial_inertia());
    let ee = checked.map_err(|e| fail(e, empty()))?;
    let mut rows = Vec::new();
    rows.try_reserve_exact(
        recorded_rows(run.steps, run.record_every).saturating_mul(TARGET_STATE_LEN),
    )
    .map_err(|_| {
        fail(
            Error::InvalidArgument {
                what: "steps".into(),
                message: format!(
                    "the target's record of {} rows does not fit in memory; keep fewer rows \
                     (record_every)",
                    recorded_rows(run.steps, run.record_every)
                ),
            },
            empty(),
        )
    })?;
    let mut body = CaptureSteps {
        arm,
        joined: None,
        stepper: Stepper::new(arm),
        target: target.clone(),
        state: target.state(),
        rk4: Rk4::new(TARGET_STATE_LEN),
        when,
        ee,
        data: Data::new(arm.robot()),
        record: CaptureRecord {
            target: rows,
            ..empty()
        },
    };
    match run_steps(&mut body, arm.layout(), run, drive, observer, recorder) {
        Ok(()) => Ok(body.record),
        Err(error) => Err(fail(error, body.record)),
    }
}

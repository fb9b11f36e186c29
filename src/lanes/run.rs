//! Whole runs in lanes: [`simulate_lanes`] integrates up to `W` runs of arms with one robot
//! together, each exactly as [`simulate_into`] integrates it alone: the same rows handed to its
//! recorder, the same error at the same step, the same observer checks.
//!
//! The runs of a group share the structure of one robot (its tree and frames); each lane holds
//! its own body inertias and joint parameters.
//!
//! Per step, each live lane asks its own [`Drive`] for its rows through its own [`Stepper`]
//! (the scalar code: any controller, called per lane on the lane's state), the rows are packed
//! into lanes, and the [`LaneGroup`] takes the RK4 step. A lane whose step fails in the kernel
//! is stepped again by the scalar code from the state before the step, with the same held
//! inputs: that step fails with the scalar run's message (or, were the kernel ever stricter
//! than the scalar step, succeeds and the lane goes on). A run that fails is masked (its lane
//! parked on a live one) and never waited on: the group ends when its last live lane ends.

use super::lane::L;
use super::spatial::{Sv, V3};
use super::step::{LaneGroup, LaneInputs};
use crate::dynamics::Method;
use crate::error::{Error, Result};
use crate::flex::FlexibleArm;
use crate::integrate::simulate::Observer;
use crate::integrate::{is_recorded, simulate_into, Drive, Recorder, Run, Stepper};
use crate::model::Robot;

/// One run of a lane group: what [`simulate_into`] takes.
pub struct LaneRun<'a> {
    /// Its arm (every run of a group has the same robot: [`shares_kernel`]).
    pub arm: &'a FlexibleArm,
    /// Its start, step, length and the rows kept (the same `dt`, `steps` and `record_every` in
    /// every run of a group).
    pub run: Run<'a>,
    /// What drives it.
    pub drive: Drive<'a>,
    /// Where its rows go.
    pub recorder: &'a mut dyn Recorder,
}

/// Whether the lane kernel can step `arm`: the recursive ABA (the kernel's algorithm), with or
/// without reaction wheels.
pub fn lane_capable(arm: &FlexibleArm) -> bool {
    arm.method() == Method::Recursive
}

/// Whether runs of `a` and `b` can share a lane group: both [`lane_capable`], with robots of
/// one structure (the same tree, joint frames and end-effector frames) and as many reaction
/// wheels. Everything else may differ, each lane holding its own: the body masses and inertias
/// (a dispersed payload), the joint parameters (stiffness, damping, motor inertia and friction)
/// and the wheels (axes, masses, positions, inertias, friction and limits).
pub fn shares_kernel(a: &FlexibleArm, b: &FlexibleArm) -> bool {
    lane_capable(a)
        && lane_capable(b)
        && a.layout().wheels == b.layout().wheels
        && same_structure(a.robot(), b.robot())
}

fn same_structure(a: &Robot, b: &Robot) -> bool {
    if std::ptr::eq(a, b) {
        return true;
    }
    let (n, ees) = (a.dof(), a.end_effectors().len());
    n == b.dof()
        && ees == b.end_effectors().len()
        && a.parents() == b.parents()
        && (1..=n).all(|i| a.joint_frame(i) == b.joint_frame(i))
        && (0..ees).all(|e| {
            a.end_effectors()[e].body == b.end_effectors()[e].body
                && a.frame_ee_transform(e) == b.frame_ee_transform(e)
        })
}

/// Integrates every run of `runs` as [`simulate_into`] would, `width` runs at a time in lanes
/// (4 or 8; any other width, or runs that cannot share a group, run one by one), and returns
/// each run's outcome, in order. Every run is bit for bit its [`simulate_into`]: the same rows,
/// the same final state, the same error at the same step. `observer` is asked as for one run
/// (before every `observer.every()`-th step); when it says stop, every run still going stops
/// there as interrupted.
pub fn simulate_lanes(
    runs: &mut [LaneRun<'_>],
    width: usize,
    observer: &mut dyn Observer,
) -> Vec<Result<()>> {
    let shared = runs.first().is_some_and(|first| {
        runs.iter().all(|r| {
            shares_kernel(first.arm, r.arm)
                && (r.run.dt, r.run.steps, r.run.record_every)
                    == (first.run.dt, first.run.steps, first.run.record_every)
        })
    });
    if !shared || !matches!(width, 4 | 8) {
        return runs
            .iter_mut()
            .map(|r| simulate_into(r.arm, &r.run, &mut r.drive, observer, r.recorder))
            .collect();
    }
    let mut out = Vec::with_capacity(runs.len());
    for group in runs.chunks_mut(width) {
        match width {
            8 => out.extend(group_runs::<8>(group, observer)),
            _ => out.extend(group_runs::<4>(group, observer)),
        }
    }
    out
}

/// One lane's run: its stepper (rows held over the step), its state and its outcome.
struct Lane {
    stepper: Stepper,
    x: Vec<f64>,
    last_good: Vec<f64>,
    ee_given: bool,
    outcome: Option<Result<()>>,
}

impl Lane {
    fn live(&self) -> bool {
        self.outcome.is_none()
    }
}

/// The error of a recorder that failed at step `step`, as [`simulate_into`] words it.
fn recording(step: usize, dt: f64, e: Error) -> Error {
    Error::Simulation {
        step,
        time: step as f64 * dt,
        message: format!("the recorder failed: {e}"),
    }
}

/// Ends `lane` at step `k` with `error` as `run_steps` does: the last good state as the final
/// row when its row was not kept, then `finish`.
fn fail(lane: &mut Lane, run: &mut LaneRun<'_>, k: usize, kept: bool, error: Error) {
    let dt = run.run.dt;
    let ended = (|| {
        if !kept {
            run.recorder
                .state(k as f64 * dt, &lane.last_good)
                .map_err(|e| recording(k, dt, e))?;
        }
        run.recorder.finish().map_err(|e| recording(k, dt, e))?;
        Err(error)
    })();
    lane.outcome = Some(ended);
}

/// At most `W` runs (checked to share a kernel) in one group: the lanes set up, then per step
/// the rows asked for ([`prepare_step`]), the kernel's step and each lane's outcome
/// ([`finish_step`]), then each run's end.
fn group_runs<const W: usize>(
    runs: &mut [LaneRun<'_>],
    observer: &mut dyn Observer,
) -> Vec<Result<()>> {
    let arm = runs[0].arm;
    let Run { dt, steps, .. } = runs[0].run;
    let mut group = LaneGroup::<W>::new(arm);
    let mut lanes = start_lanes(&mut group, runs);
    let mut held = Held::<W>::new(arm);
    let every = observer.every();
    for k in 0..steps {
        if !lanes.iter().any(Lane::live) {
            break;
        }
        let stop = every > 0 && k > 0 && k % every == 0 && !observer.observe(k, steps);
        prepare_step(&mut lanes, runs, k, stop, &mut held);
        // the kernel adds the EE wrenches when the first live lane has them; a lane that
        // differs is stepped by the scalar code (adding a zero wrench is not bit-neutral)
        let Some(first) = lanes.iter().find(|l| l.live()) else {
            break;
        };
        let ee_kernel = first.ee_given;
        let inputs = LaneInputs {
            u: &held.u,
            base_wrench: &held.base,
            ee_wrench: if ee_kernel { &held.ee } else { &[] },
            wheel_torque: &held.wheel,
        };
        let ok = group.step(arm, dt, &inputs);
        finish_step(&mut group, &mut lanes, runs, k, ok, ee_kernel);
        park_dead(&mut group, &lanes);
    }
    lanes
        .into_iter()
        .zip(runs.iter_mut())
        .map(|(lane, r)| match lane.outcome {
            Some(outcome) => outcome,
            None => r.recorder.finish().map_err(|e| recording(steps, dt, e)),
        })
        .collect()
}

/// The lanes of `runs` in `group`: each run checked as [`simulate_into`] checks it before row
/// 0, its arm and start put in its lane and row 0 recorded; a run that fails there is masked.
fn start_lanes<const W: usize>(group: &mut LaneGroup<W>, runs: &mut [LaneRun<'_>]) -> Vec<Lane> {
    let Run {
        dt, record_every, ..
    } = runs[0].run;
    let len = runs[0].arm.layout().len();
    let mut lanes: Vec<Lane> = Vec::with_capacity(runs.len());
    for (k, r) in runs.iter_mut().enumerate() {
        let mut lane = Lane {
            stepper: Stepper::new(r.arm),
            x: vec![0.0; len],
            last_good: if record_every > 1 {
                vec![0.0; len]
            } else {
                Vec::new()
            },
            ee_given: false,
            outcome: None,
        };
        match r.run.check(r.arm, &r.drive) {
            Err(e) => lane.outcome = Some(Err(e)),
            Ok(()) => {
                group.set_arm(k, r.arm);
                group.set_state(k, r.run.x0);
                group.state(k, &mut lane.x);
                if let Err(e) = r.recorder.state(0.0, &lane.x) {
                    lane.outcome = Some(Err(recording(0, dt, e)));
                }
            }
        }
        lanes.push(lane);
    }
    park_dead(group, &lanes);
    lanes
}

/// The inputs of a step in lanes, each lane's from its [`Stepper`]: `u` (n), the wheel torques
/// applied (k), `f_B`, the EE wrenches.
struct Held<const W: usize> {
    u: Vec<L<W>>,
    wheel: Vec<L<W>>,
    base: Sv<W>,
    ee: Vec<Sv<W>>,
}

impl<const W: usize> Held<W> {
    fn new(arm: &FlexibleArm) -> Self {
        Self {
            u: vec![L::zero(); arm.dof()],
            wheel: vec![L::zero(); arm.layout().wheels],
            base: Sv::default(),
            ee: vec![Sv::default(); arm.robot().end_effectors().len()],
        }
    }
}

/// The first half of step `k` for every live lane: the last good state kept when its row is
/// not, the run stopped if the observer said so (`stop`), else its rows asked for through its
/// [`Stepper`] and packed into `held` (a controller that fails ends the run).
fn prepare_step<const W: usize>(
    lanes: &mut [Lane],
    runs: &mut [LaneRun<'_>],
    k: usize,
    stop: bool,
    held: &mut Held<W>,
) {
    let Run {
        dt, record_every, ..
    } = runs[0].run;
    let kept = k % record_every == 0;
    for (j, (lane, r)) in lanes.iter_mut().zip(runs.iter_mut()).enumerate() {
        if !lane.live() {
            continue;
        }
        if !kept {
            lane.last_good.copy_from_slice(&lane.x);
        }
        if stop {
            let error = simulation(k, dt, "interrupted by the caller".into());
            fail(lane, r, k, kept, error);
            continue;
        }
        match lane.stepper.prepare(r.arm, &mut r.drive, &lane.x, k, dt) {
            Err(message) => fail(lane, r, k, kept, simulation(k, dt, message)),
            Ok(ee_given) => {
                lane.ee_given = ee_given;
                pack(&lane.stepper, j, ee_given, held);
            }
        }
    }
}

/// The second half of step `k` for every live lane, after the kernel's step (`ok` per lane, the
/// EE wrenches added when `ee_kernel`): a lane the kernel failed, or whose EE channel is not the
/// kernel's, stepped again by the scalar code from the state before the step with the same held
/// inputs; then the new state (and the inputs, when the row is kept) to its recorder.
fn finish_step<const W: usize>(
    group: &mut LaneGroup<W>,
    lanes: &mut [Lane],
    runs: &mut [LaneRun<'_>],
    k: usize,
    ok: [bool; W],
    ee_kernel: bool,
) {
    let Run {
        dt,
        steps,
        record_every,
        ..
    } = runs[0].run;
    let kept = k % record_every == 0;
    for (j, (lane, r)) in lanes.iter_mut().zip(runs.iter_mut()).enumerate() {
        if !lane.live() {
            continue;
        }
        let stepped = if lane.ee_given != ee_kernel || !ok[j] {
            let done = lane.stepper.advance(r.arm, &mut lane.x, dt, lane.ee_given);
            if done.is_ok() {
                group.put_state(j, &lane.x);
            }
            done
        } else {
            // the kernel's `ok` holds the scalar step's state checks (`checked_state`): the
            // state is finite and its quaternion not zero
            group.state(j, &mut lane.x);
            Ok(())
        };
        if let Err(message) = stepped {
            fail(lane, r, k, kept, simulation(k, dt, message));
            continue;
        }
        let recorded = (|| {
            if kept {
                r.recorder
                    .input(lane.stepper.inputs())
                    .map_err(|e| recording(k, dt, e))?;
            }
            if is_recorded(k + 1, steps, record_every) {
                r.recorder
                    .state((k + 1) as f64 * dt, &lane.x)
                    .map_err(|e| recording(k, dt, e))?;
            }
            Ok(())
        })();
        if let Err(e) = recorded {
            lane.outcome = Some(Err(e));
        }
    }
}

fn simulation(step: usize, dt: f64, message: String) -> Error {
    Error::Simulation {
        step,
        time: step as f64 * dt,
        message,
    }
}

/// Lane `j` of the held inputs from `stepper`'s rows (the wheel torques as applied: saturated by
/// the lane's own `Stepper::prepare`).
fn pack<const W: usize>(stepper: &Stepper, j: usize, ee_given: bool, held: &mut Held<W>) {
    for (lane, v) in held.u.iter_mut().zip(stepper.u()) {
        lane.0[j] = *v;
    }
    for (lane, v) in held.wheel.iter_mut().zip(stepper.wheel_torque()) {
        lane.0[j] = *v;
    }
    let (base_row, ee_rows) = stepper.held_wrenches();
    set_sv(&mut held.base, j, base_row);
    if ee_given {
        for (e, w) in held.ee.iter_mut().enumerate() {
            set_sv(w, j, &ee_rows[6 * e..6 * e + 6]);
        }
    }
}

/// Lane `j` of `sv` from `[moment; force]`.
fn set_sv<const W: usize>(sv: &mut Sv<W>, j: usize, row: &[f64]) {
    let set = |v: &mut V3<W>, r: &[f64]| {
        (v.x.0[j], v.y.0[j], v.z.0[j]) = (r[0], r[1], r[2]);
    };
    set(&mut sv.angular, &row[..3]);
    set(&mut sv.linear, &row[3..6]);
}

/// Parks every lane without a live run (ended, or beyond the runs) on the first live one, so
/// that it computes on ordinary numbers.
fn park_dead<const W: usize>(group: &mut LaneGroup<W>, lanes: &[Lane]) {
    let Some(from) = lanes.iter().position(Lane::live) else {
        return;
    };
    for k in 0..W {
        if !lanes.get(k).is_some_and(Lane::live) {
            group.park(k, from);
        }
    }
}

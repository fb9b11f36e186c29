//! Many runs with a target at once ([`simulate_capture_batch`]): each run is exactly the single
//! run [`simulate_capture_into`] makes (the same arithmetic, bit for bit), over a pool of threads.

use super::run::{simulate_capture_into, CaptureRecord, CaptureRun};
use super::target::Target;
use super::when::CaptureWhen;
use crate::control::{AttitudePD, MotorPD, Wrenches};
use crate::error::{Error, Result};
use crate::flex::FlexibleArm;
use crate::integrate::batch::{in_pool, Cancel};
use crate::integrate::{Drive, Run, Trajectory};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// One run of a batch with targets: its arm, start, motor PD, target and, for an arm with
/// reaction wheels, the attitude controller that drives them.
#[derive(Debug, Clone)]
pub struct CaptureCase<'a> {
    /// The arm.
    pub arm: &'a FlexibleArm,
    /// The initial state (13 + 4n).
    pub x0: &'a [f64],
    /// The motor PD (each run starts from its own copy).
    pub controller: &'a MotorPD,
    /// The target at `t = 0`.
    pub target: &'a Target,
    /// The wheels' controller, bound to the arm (each run starts from its own copy); `None`:
    /// no wheel torque.
    pub wheel_torque: Option<&'a AttitudePD>,
}

/// What one run of a batch with targets produced: its rows and its capture record, and the error
/// that stopped it, if one did (the rows and record then hold what it computed before).
#[derive(Debug, Clone)]
pub struct CaptureOutcome {
    /// The arm's kept rows.
    pub trajectory: Trajectory,
    /// The target's rows and the events.
    pub record: CaptureRecord,
    /// `None` for a complete run.
    pub error: Option<Error>,
}

/// How the runs of a batch with targets go: step, length, rows kept, the trigger and the
/// grasping end-effector, threads (`None`: every core).
#[derive(Debug, Clone, Copy)]
pub struct CaptureBatchSettings {
    /// The step (s).
    pub dt: f64,
    /// Steps per run.
    pub steps: usize,
    /// Keep every `record_every`-th row (and the final one).
    pub record_every: usize,
    /// The trigger, the same for every run.
    pub when: CaptureWhen,
    /// The grasping end-effector (`None`: the only one).
    pub ee: Option<usize>,
    /// Worker threads.
    pub threads: Option<usize>,
}

/// Runs every case over a pool of `settings.threads` threads, each as the single run
/// [`simulate_capture_into`] (no wrenches; the case's motor PD and wheel controller), in order of
/// the cases. A run
/// that fails never stops the others; `cancel` stops those still going, and `done` counts the
/// runs over.
pub fn simulate_capture_batch(
    cases: &[CaptureCase<'_>],
    settings: &CaptureBatchSettings,
    cancel: &AtomicBool,
    done: &AtomicUsize,
) -> Result<Vec<CaptureOutcome>> {
    settings.when.check()?;
    in_pool(settings.threads, || {
        cases
            .par_iter()
            .with_max_len(1)
            .map(|case| {
                let outcome = one_run(case, settings, cancel);
                done.fetch_add(1, Ordering::Relaxed);
                outcome
            })
            .collect()
    })
}

fn one_run(
    case: &CaptureCase<'_>,
    s: &CaptureBatchSettings,
    cancel: &AtomicBool,
) -> CaptureOutcome {
    let mut pd = case.controller.clone();
    let mut wrenches = Wrenches::ZERO;
    let mut wheel_pd = case.wheel_torque.cloned();
    let mut drive = Drive::new(&mut pd, &mut wrenches);
    if let Some(wheels) = wheel_pd.as_mut() {
        drive.wheel_torque = wheels;
    }
    let layout = case.arm.layout();
    let run = Run::new(case.x0, s.dt, s.steps).recording_every(s.record_every);
    let mut trajectory = match Trajectory::reserved(layout, s.steps, s.record_every) {
        Ok(t) => t,
        Err(error) => {
            return CaptureOutcome {
                trajectory: Trajectory::empty(layout),
                record: CaptureRecord::new(*case.target.spatial_inertia()),
                error: Some(error),
            }
        }
    };
    let capturing = CaptureRun {
        target: case.target,
        when: s.when,
        ee: s.ee,
    };
    match simulate_capture_into(
        case.arm,
        &run,
        &mut drive,
        &capturing,
        &mut Cancel(cancel),
        &mut trajectory,
    ) {
        Ok(record) => CaptureOutcome {
            trajectory,
            record,
            error: None,
        },
        Err(failure) => CaptureOutcome {
            trajectory,
            record: failure.record,
            error: Some(failure.error),
        },
    }
}

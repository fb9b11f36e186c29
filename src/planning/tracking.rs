//! Running a plan on the flexible arm and measuring how well it went: [`Plan::track`].

use super::slew::{Plan, Reference};
use super::BaseMode;
use crate::error::{Error, Result};
use crate::integrate::{MotorPD, Schedule, Trajectory, Wrenches};
use crate::spatial::{quaternion_log, quaternion_product};

/// The outcome of [`Plan::track`]: the run, its reference and what a GNC engineer checks.
#[derive(Debug, Clone)]
pub struct Tracking {
    /// The simulated run (`steps + 1` states, `steps` commanded torques).
    pub trajectory: Trajectory,
    /// The tables it ran on.
    pub reference: Reference,
    /// The slew's end (s); the steps after it show the residual motion.
    pub slew_end: f64,
    /// Per joint, the peak commanded motor torque `max |u_i|` over the run (N·m): feedforward
    /// plus the PD's correction.
    pub peak_motor_torque: Vec<f64>,
    /// `max |q_i − q_plan,i|` over every state of the run, all joints (rad).
    pub tracking_error: f64,
    /// Over the states at or after the slew's end (the final state at least): the largest
    /// deflection `|θ_i − q_i|` (rad), the residual vibration of the joints (zero for an arm at
    /// rest).
    pub residual_deflection: f64,
    /// After the slew: the largest `|q_i − q_goal,i|` (rad).
    pub residual_link_error: f64,
    /// `max |r_B − r_B,plan|` over the run (m).
    pub base_position_error: f64,
    /// The largest rotation between the base's attitude and the plan's over the run (rad).
    pub base_attitude_error: f64,
}

/// What a tracking run of a plan runs on: its length, tables, controller and wrenches
/// ([`Plan::tracking_setup`]).
#[derive(Debug, Clone)]
pub struct TrackingSetup {
    /// RK4 steps: the slew plus the settling time, covered.
    pub steps: usize,
    /// The plan's per-step tables for the run.
    pub reference: Reference,
    /// The motor PD around the reference, with its feedforward.
    pub pd: MotorPD,
    /// The base wrench table (held base) or none.
    pub wrenches: Wrenches,
}

impl Plan {
    /// Simulates the plan on its arm from [`Plan::initial_state`] with RK4 steps of `dt`
    /// for the slew plus `settle` seconds: a [`MotorPD`] with gains `kp`, `kd` (per joint) around
    /// [`Plan::reference`]'s `θ_ref`, `θ̇_ref` with its feedforward `u`, and in held mode its base
    /// wrench (open loop: nothing else holds the base). Returns the run and its measures
    /// ([`Tracking`]).
    ///
    /// Errors: a bad `dt`, `settle` or gains; a `dt` longer than the plan; a `dt` past the RK4
    /// stability limit of the tracking loop (arm, joints and PD linearised at the start), where
    /// the run would diverge or mean nothing; a run that turns non-finite anyway.
    pub fn track(&self, dt: f64, kp: &[f64], kd: &[f64], settle: f64) -> Result<Tracking> {
        let TrackingSetup {
            steps,
            reference,
            mut pd,
            wrenches,
        } = self.tracking_setup(dt, kp, kd, settle)?;
        let trajectory = self
            .arm()
            .simulate(&self.initial_state(), dt, steps, &mut pd, &wrenches)
            .map_err(|failure| failure.error)?;
        Ok(self.measure(trajectory, reference))
    }

    /// Checks the arguments of [`Plan::track`] and builds what its run runs on, for callers
    /// that drive the simulation themselves (the Python binding, to keep a failed run's steps).
    pub fn tracking_setup(
        &self,
        dt: f64,
        kp: &[f64],
        kd: &[f64],
        settle: f64,
    ) -> Result<TrackingSetup> {
        self.tracking_setup_with(dt, kp, kd, settle, &mut |_| true)
            .map(|setup| setup.expect("never stopped"))
    }

    /// [`Plan::tracking_setup`], asking `keep_going` while the tables are built (as
    /// [`Plan::reference_with`]): `None` when it says no.
    pub fn tracking_setup_with(
        &self,
        dt: f64,
        kp: &[f64],
        kd: &[f64],
        settle: f64,
        keep_going: &mut dyn FnMut(usize) -> bool,
    ) -> Result<Option<TrackingSetup>> {
        let steps = self.tracking_steps(dt, kp, kd, settle)?;
        let Some(reference) = self.reference_with(dt, Some(steps), keep_going)? else {
            return Ok(None);
        };
        let n = self.arm().dof();
        let table = |values: &Vec<f64>, width| Schedule::Table {
            values: values.clone(),
            width,
        };
        let pd = MotorPD::new(
            kp.to_vec(),
            kd.to_vec(),
            table(&reference.theta_ref, n),
            table(&reference.theta_dot_ref, n),
            table(&reference.u, n),
        )?;
        let wrenches = Wrenches {
            base: match self.base() {
                BaseMode::Held => table(&reference.base_wrench, 6),
                BaseMode::Free => Schedule::Zero,
            },
            ee: Schedule::Zero,
            wheel_torque: crate::integrate::Schedule::Zero,
        };
        Ok(Some(TrackingSetup {
            steps,
            reference,
            pd,
            wrenches,
        }))
    }

    /// The number of steps of a tracking run (the slew and `settle` s after it), once the
    /// arguments are checked: `settle` finite and ≥ 0, `dt` valid and shorter than the plan,
    /// gains `n` long, and `dt` within the loop's RK4 stability limit.
    fn tracking_steps(&self, dt: f64, kp: &[f64], kd: &[f64], settle: f64) -> Result<usize> {
        if !(settle.is_finite() && settle >= 0.0) {
            return Err(Error::InvalidArgument {
                what: "settle".into(),
                message: format!("expected a finite time ≥ 0 (s), given {settle}"),
            });
        }
        let n = self.arm().dof();
        crate::args::check_dt(dt)?;
        if dt > self.duration() {
            return Err(Error::InvalidArgument {
                what: "dt".into(),
                message: format!(
                    "{} s is longer than the plan ({:.4} s): a tracking run needs steps shorter \
                     than the slew",
                    crate::args::number(dt),
                    Seconds(self.duration())
                ),
            });
        }
        crate::args::check_length("kp", kp.len(), n)?;
        crate::args::check_length("kd", kd.len(), n)?;
        self.tracking_is_stable(dt, kp, kd)?;
        let steps = ((self.duration() + settle) / dt).ceil();
        if steps >= 1e15 {
            return Err(Error::InvalidArgument {
                what: "settle".into(),
                message: format!(
                    "{} s of settling at dt = {} s makes {steps:.3e} steps; shorten it",
                    crate::args::number(settle),
                    crate::args::number(dt)
                ),
            });
        }
        Ok(steps as usize)
    }

    /// `dt` within the RK4 stability limit of the tracking loop at the start (the arm, its
    /// joints and the PD with gains `kp`, `kd`; the references do not enter it).
    fn tracking_is_stable(&self, dt: f64, kp: &[f64], kd: &[f64]) -> Result<()> {
        let probe = MotorPD::new(
            kp.to_vec(),
            kd.to_vec(),
            Schedule::Zero,
            Schedule::Zero,
            Schedule::Zero,
        )?;
        let exceeded = self
            .arm()
            .rk4_stability_exceeded(&self.initial_state(), &probe, dt)?;
        if let Some(limit) = exceeded {
            return Err(Error::InvalidArgument {
                what: "dt".into(),
                message: format!(
                    "{} s is past the RK4 stability limit {:.4e} s of the tracking loop (the arm, \
                     its joints and the PD with these gains, linearised at the start{}): the run \
                     would diverge or mean nothing; shorten dt or lower the gains",
                    crate::args::number(dt),
                    limit.dt,
                    if limit.estimated {
                        ", estimated joint by joint"
                    } else {
                        ""
                    }
                ),
            });
        }
        Ok(())
    }

    /// The measures of a tracking run on `reference` (every state of `trajectory` that the
    /// reference covers; a failed run's finite part too).
    pub fn measure(&self, trajectory: Trajectory, reference: Reference) -> Tracking {
        let n = self.arm().dof();
        let layout = self.arm().layout();
        let slew_end = self.duration();
        let goal = self.stops().last().expect("a plan has a goal");
        let mut out = Tracking {
            peak_motor_torque: vec![0.0; n],
            tracking_error: 0.0,
            residual_deflection: 0.0,
            residual_link_error: 0.0,
            base_position_error: 0.0,
            base_attitude_error: 0.0,
            slew_end,
            trajectory: Trajectory::empty(layout),
            reference: reference.clone(),
        };
        for row in trajectory.u.chunks_exact(n) {
            for (peak, u) in out.peak_motor_torque.iter_mut().zip(row) {
                *peak = peak.max(u.abs());
            }
        }
        // every state, the final one included
        for k in 0..=reference.steps.min(trajectory.len().saturating_sub(1)) {
            let x = trajectory.state(k);
            let (q, theta) = (&x[layout.q()], &x[layout.theta()]);
            let planned = &reference.q[k * n..(k + 1) * n];
            for i in 0..n {
                out.tracking_error = out.tracking_error.max((q[i] - planned[i]).abs());
            }
            let pose = &x[layout.base_pose()];
            let plan_pose = &reference.base_pose[7 * k..7 * k + 7];
            let position = (0..3)
                .map(|c| (pose[c] - plan_pose[c]).powi(2))
                .sum::<f64>()
                .sqrt();
            out.base_position_error = out.base_position_error.max(position);
            let inverse = [-plan_pose[3], -plan_pose[4], -plan_pose[5], plan_pose[6]];
            let relative = quaternion_product(&inverse, &pose[3..]);
            out.base_attitude_error = out
                .base_attitude_error
                .max(quaternion_log(&relative).norm());
            if trajectory.t[k] >= slew_end {
                for i in 0..n {
                    out.residual_deflection = out.residual_deflection.max((theta[i] - q[i]).abs());
                    out.residual_link_error = out.residual_link_error.max((q[i] - goal[i]).abs());
                }
            }
        }
        out.trajectory = trajectory;
        out
    }
}

/// A computed time for a message: four significant digits (`0.5789 s`, `4.040e-4 s`).
struct Seconds(f64);

impl std::fmt::Display for Seconds {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let digits = f.precision().unwrap_or(4);
        let x = self.0;
        if (1e-3..1e6).contains(&x.abs()) {
            let decimals = (digits as i32 - 1 - x.abs().log10().floor() as i32).max(0) as usize;
            write!(f, "{x:.decimals$}")
        } else {
            write!(f, "{x:.*e}", digits.saturating_sub(1))
        }
    }
}

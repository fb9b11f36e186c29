//! Fixed-step RK4 of the whole flexible floating-base state (SPEC §5), controllers and input
//! schedules, and [`simulate`] with its [`Trajectory`].

use crate::error::{check_vector, Error, Result};
use crate::flex::{check_output, normalise_quaternion, state_defect, ArmWorkspace, FlexibleArm};

/// A per-step input of fixed width: zero, a constant, or a table with one row per step
/// (row-major, `steps × width`). Held constant over each step (zero-order hold).
#[derive(Debug, Clone, PartialEq)]
pub enum Schedule {
    /// All zeros.
    Zero,
    /// The same row every step.
    Constant(Vec<f64>),
    /// Row `k` is used during step `k`; `rows × width`, row-major.
    Table { values: Vec<f64>, width: usize },
}

impl Schedule {
    /// Checks width (and table length against `steps`, if given) and finiteness.
    pub fn check(&self, what: &str, width: usize, steps: Option<usize>) -> Result<()> {
        match self {
            Schedule::Zero => Ok(()),
            Schedule::Constant(v) => check_vector(what, v, width),
            Schedule::Table { values, width: w } => {
                let rows = values.len().checked_div(*w).unwrap_or(0);
                if *w != width || values.len() != rows * w || steps.is_some_and(|s| s != rows) {
                    return Err(Error::Dimension {
                        what: what.to_string(),
                        expected: format!(
                            "a table of shape ({}, {width})",
                            steps.map_or("steps".into(), |s| s.to_string())
                        ),
                        given: format!("shape ({rows}, {w})"),
                    });
                }
                crate::error::check_finite(what, values)
            }
        }
    }

    /// Writes the row for `step` into `out`.
    #[inline]
    pub fn write(&self, step: usize, out: &mut [f64]) {
        match self {
            Schedule::Zero => out.fill(0.0),
            Schedule::Constant(v) => out.copy_from_slice(v),
            Schedule::Table { values, width } => {
                out.copy_from_slice(&values[step * width..(step + 1) * width])
            }
        }
    }
}

/// Computes the motor torques `u` (n) once per step, from the time and the state at the start of
/// the step. Built-in controllers implement it; users can too.
pub trait Controller {
    /// Writes `u` for step `step` (time `t`, state `x`) into `u`.
    fn torque(&mut self, step: usize, t: f64, x: &[f64], u: &mut [f64]) -> Result<()>;
}

impl Controller for Schedule {
    fn torque(&mut self, step: usize, _t: f64, _x: &[f64], u: &mut [f64]) -> Result<()> {
        let fits = match self {
            Schedule::Zero => true,
            Schedule::Constant(v) => v.len() == u.len(),
            Schedule::Table { values, width } => {
                *width == u.len() && values.len() >= (step + 1) * *width
            }
        };
        if !fits {
            self.check("u", u.len(), Some(step + 1))?;
            return Err(Error::Dimension {
                what: "u".into(),
                expected: format!("a row of {} torques for step {step}", u.len()),
                given: "a shorter table".into(),
            });
        }
        self.write(step, u);
        Ok(())
    }
}

/// Motor-side PD with feedforward:
/// `u = K_p (θ_ref − θ) + K_d (θ̇_ref − θ̇) + u_ff`, gains per joint, references constant or
/// tabulated per step.
#[derive(Debug, Clone, PartialEq)]
pub struct MotorPD {
    pub kp: Vec<f64>,
    pub kd: Vec<f64>,
    pub theta_ref: Schedule,
    pub theta_dot_ref: Schedule,
    pub feedforward: Schedule,
    n: usize,
    scratch: Vec<f64>,
}

impl MotorPD {
    /// Validated controller for `n` joints (gains ≥ 0, length n; references of width n).
    pub fn new(
        kp: Vec<f64>,
        kd: Vec<f64>,
        theta_ref: Schedule,
        theta_dot_ref: Schedule,
        feedforward: Schedule,
    ) -> Result<Self> {
        let n = kp.len();
        for (what, gains) in [("kp", &kp), ("kd", &kd)] {
            check_vector(what, gains, n)?;
            if let Some(i) = gains.iter().position(|&g| g < 0.0) {
                return Err(Error::InvalidArgument {
                    what: format!("{what}[{i}]"),
                    message: format!("expected >= 0, given {}", gains[i]),
                });
            }
        }
        theta_ref.check("theta_ref", n, None)?;
        theta_dot_ref.check("theta_dot_ref", n, None)?;
        feedforward.check("feedforward", n, None)?;
        Ok(Self {
            kp,
            kd,
            theta_ref,
            theta_dot_ref,
            feedforward,
            n,
            scratch: vec![0.0; 3 * n],
        })
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.n
    }

    /// Checks tabulated references against the number of steps of a run.
    pub fn check_steps(&self, steps: usize) -> Result<()> {
        for (what, s) in [
            ("theta_ref", &self.theta_ref),
            ("theta_dot_ref", &self.theta_dot_ref),
            ("feedforward", &self.feedforward),
        ] {
            if let Schedule::Table { values, width } = s {
                if values.len() < steps * width {
                    return Err(Error::Dimension {
                        what: what.to_string(),
                        expected: format!("at least {steps} rows (one per step)"),
                        given: format!("{} rows", values.len() / width),
                    });
                }
            }
        }
        Ok(())
    }
}

impl Controller for MotorPD {
    fn torque(&mut self, step: usize, _t: f64, x: &[f64], u: &mut [f64]) -> Result<()> {
        self.check_steps(step + 1)?;
        let n = self.n;
        let layout = crate::flex::StateLayout { n };
        if u.len() != n || x.len() != layout.len() {
            return Err(Error::Dimension {
                what: "MotorPD".into(),
                expected: format!("an arm with {n} joints (state length {})", layout.len()),
                given: format!("{} joints (state length {})", u.len(), x.len()),
            });
        }
        let theta = &x[layout.theta()];
        let theta_dot = &x[layout.theta_dot()];
        let (reference, rest) = self.scratch.split_at_mut(n);
        let (rate, ff) = rest.split_at_mut(n);
        self.theta_ref.write(step, reference);
        self.theta_dot_ref.write(step, rate);
        self.feedforward.write(step, ff);
        for i in 0..n {
            u[i] = self.kp[i] * (reference[i] - theta[i])
                + self.kd[i] * (rate[i] - theta_dot[i])
                + ff[i];
        }
        Ok(())
    }
}

/// The states of a run: `t` (steps+1) and `x` ((steps+1) × (13+4n), row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    pub t: Vec<f64>,
    pub x: Vec<f64>,
    pub state_len: usize,
}

impl Trajectory {
    /// Number of stored states (steps + 1 for a complete run).
    pub fn len(&self) -> usize {
        self.t.len()
    }
    /// True when no state is stored.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
    /// State `k`.
    pub fn state(&self, k: usize) -> &[f64] {
        &self.x[k * self.state_len..(k + 1) * self.state_len]
    }
}

/// A run that stopped early: the error and every state computed before it.
#[derive(Debug, Clone)]
pub struct SimulationFailure {
    pub error: Error,
    pub trajectory: Trajectory,
}

impl From<Box<SimulationFailure>> for Error {
    fn from(f: Box<SimulationFailure>) -> Error {
        f.error
    }
}

impl FlexibleArm {
    /// One classic RK4 step of length `dt` in place, inputs held over the step; the quaternion
    /// is renormalised afterwards (SPEC §5). Allocation-free.
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &self,
        ws: &mut ArmWorkspace,
        x: &mut [f64],
        dt: f64,
        u: &[f64],
        base_wrench: &[f64],
        ee_wrench: &[f64],
    ) -> Result<()> {
        check_dt(dt)?;
        self.check_state(x)?;
        check_vector("u", u, self.robot().dof())?;
        check_vector("base_wrench", base_wrench, 6)?;
        check_vector("ee_wrench", ee_wrench, 6)?;
        self.step_unchecked(ws, x, dt, u, base_wrench, ee_wrench)?;
        match state_defect(x) {
            Some(defect) => Err(Error::Simulation {
                step: 0,
                time: 0.0,
                message: format!(
                    "the state diverged: {defect}; dt = {dt} s may be past the RK4 stability limit"
                ),
            }),
            None => Ok(()),
        }
    }

    pub(crate) fn step_unchecked(
        &self,
        ws: &mut ArmWorkspace,
        x: &mut [f64],
        dt: f64,
        u: &[f64],
        fb: &[f64],
        f: &[f64],
    ) -> Result<()> {
        let mut stages = std::mem::take(&mut ws.stages);
        let mut trial = std::mem::take(&mut ws.trial);
        let result = (|| {
            let [k1, k2, k3, k4] = &mut stages;
            self.derivative_unchecked(ws, x, u, fb, f, k1)?;
            for (t, (xi, ki)) in trial.iter_mut().zip(x.iter().zip(k1.iter())) {
                *t = xi + 0.5 * dt * ki;
            }
            self.derivative_unchecked(ws, &trial, u, fb, f, k2)?;
            for (t, (xi, ki)) in trial.iter_mut().zip(x.iter().zip(k2.iter())) {
                *t = xi + 0.5 * dt * ki;
            }
            self.derivative_unchecked(ws, &trial, u, fb, f, k3)?;
            for (t, (xi, ki)) in trial.iter_mut().zip(x.iter().zip(k3.iter())) {
                *t = xi + dt * ki;
            }
            self.derivative_unchecked(ws, &trial, u, fb, f, k4)?;
            for i in 0..x.len() {
                x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
            normalise_quaternion(&mut x[3..7]);
            Ok(())
        })();
        ws.stages = stages;
        ws.trial = trial;
        result
    }

    /// Integrates `steps` RK4 steps of `dt` from `x0`. `u` is asked once per step; `base_wrench`
    /// and `ee_wrench` are schedules of width 6. A state that turns non-finite (or whose
    /// quaternion collapses), or a controller that fails or returns non-finite torques, stops the
    /// run: [`Error::Simulation`] names the failing step `k` (from `t = k dt` to `(k+1) dt`), and
    /// the failure keeps the `k + 1` valid states computed before it.
    pub fn simulate(
        &self,
        x0: &[f64],
        dt: f64,
        steps: usize,
        u: &mut dyn Controller,
        base_wrench: &Schedule,
        ee_wrench: &Schedule,
    ) -> std::result::Result<Trajectory, Box<SimulationFailure>> {
        self.simulate_with_hook(x0, dt, steps, u, base_wrench, ee_wrench, 0, &mut |_| true)
    }

    /// [`simulate`](Self::simulate) that calls `hook(k)` before step `k` every `every` steps
    /// (never if `every` is 0); a hook that returns `false` stops the run as interrupted, keeping
    /// the states computed so far. The Python bindings use it to honour Ctrl-C while the run
    /// holds no GIL.
    #[allow(clippy::too_many_arguments)]
    pub fn simulate_with_hook(
        &self,
        x0: &[f64],
        dt: f64,
        steps: usize,
        u: &mut dyn Controller,
        base_wrench: &Schedule,
        ee_wrench: &Schedule,
        every: usize,
        hook: &mut dyn FnMut(usize) -> bool,
    ) -> std::result::Result<Trajectory, Box<SimulationFailure>> {
        let len = self.layout().len();
        let empty = || Trajectory {
            t: Vec::new(),
            x: Vec::new(),
            state_len: len,
        };
        let fail = |error| {
            Box::new(SimulationFailure {
                error,
                trajectory: empty(),
            })
        };
        check_dt(dt).map_err(fail)?;
        self.check_state(x0).map_err(fail)?;
        base_wrench
            .check("base_wrench", 6, Some(steps))
            .map_err(fail)?;
        ee_wrench.check("ee_wrench", 6, Some(steps)).map_err(fail)?;
        let mut traj = empty();
        let rows = steps.checked_add(1);
        let reserved = rows
            .and_then(|r| r.checked_mul(len).map(|values| (r, values)))
            .and_then(|(r, values)| {
                traj.t.try_reserve_exact(r).ok()?;
                traj.x.try_reserve_exact(values).ok()
            });
        if reserved.is_none() {
            return Err(fail(Error::InvalidArgument {
                what: "steps".into(),
                message: format!(
                    "{steps} steps of a {len}-element state do not fit in memory; \
                     simulate in shorter pieces"
                ),
            }));
        }
        let mut ws = ArmWorkspace::new(self);
        let mut x = x0.to_vec();
        normalise_quaternion(&mut x[3..7]);
        traj.t.push(0.0);
        traj.x.extend_from_slice(&x);
        let n = self.robot().dof();
        let mut torque = vec![0.0; n];
        let mut fb = [0.0; 6];
        let mut f = [0.0; 6];
        for k in 0..steps {
            let t = k as f64 * dt;
            let stop = |message: String| Error::Simulation {
                step: k,
                time: t,
                message,
            };
            if every > 0 && k > 0 && k % every == 0 && !hook(k) {
                return Err(Box::new(SimulationFailure {
                    error: stop("interrupted by the caller".into()),
                    trajectory: traj,
                }));
            }
            let outcome = u
                .torque(k, t, &x, &mut torque)
                .map_err(|e| stop(format!("the controller failed: {e}")))
                .and_then(|_| check_output("u", &torque).map_err(|e| stop(format!("the controller returned {e}"))))
                .and_then(|_| {
                    base_wrench.write(k, &mut fb);
                    ee_wrench.write(k, &mut f);
                    self.step_unchecked(&mut ws, &mut x, dt, &torque, &fb, &f).map_err(|e| {
                        stop(format!("the state diverged during the step ({e}); dt = {dt} s may be past the RK4 stability limit"))
                    })
                })
                .and_then(|_| match state_defect(&x) {
                    Some(defect) => Err(stop(format!(
                        "the state diverged: {defect}; dt = {dt} s may be past the RK4 stability limit"
                    ))),
                    None => Ok(()),
                });
            if let Err(error) = outcome {
                return Err(Box::new(SimulationFailure {
                    error,
                    trajectory: traj,
                }));
            }
            traj.t.push((k + 1) as f64 * dt);
            traj.x.extend_from_slice(&x);
        }
        Ok(traj)
    }

    /// Momentum (SPEC §6.1) at every state of `traj`, row-major `len × 6`.
    pub fn momentum_along(&self, traj: &Trajectory) -> Vec<f64> {
        let mut ws = ArmWorkspace::new(self);
        (0..traj.len())
            .flat_map(|k| self.momentum(&mut ws, traj.state(k)))
            .collect()
    }

    /// Energy (SPEC §6.2) at every state of `traj`.
    pub fn energy_along(&self, traj: &Trajectory) -> Vec<f64> {
        let mut ws = ArmWorkspace::new(self);
        (0..traj.len())
            .map(|k| self.energy(&mut ws, traj.state(k)))
            .collect()
    }

    /// EE pose `[p; quat]` at every state of `traj`, row-major `len × 7`.
    pub fn ee_pose_along(&self, traj: &Trajectory) -> Vec<f64> {
        (0..traj.len())
            .flat_map(|k| self.ee_pose(traj.state(k)))
            .collect()
    }
}

/// `dt` must be positive and finite.
pub(crate) fn check_dt(dt: f64) -> Result<()> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(Error::InvalidArgument {
            what: "dt".into(),
            message: format!("expected a finite step > 0 s, given {dt}"),
        });
    }
    Ok(())
}

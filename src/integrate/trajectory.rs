//! [`Trajectory`]: the states and inputs of a run; [`StateRows`]: the diagnostics along rows of
//! states.
//!
//! ```
//! use orbitflex::{FlexibleArm, FlexibleJoints, Robot, Schedule, Wrenches};
//! let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
//! let traj = arm.simulate(&arm.rest_state(), 1e-3, 10, &mut Schedule::Constant(vec![1.0; 7]), &Wrenches::ZERO)?;
//! assert_eq!((traj.len(), traj.u.len()), (11, 70));
//! // at rest with relaxed springs, one newton-metre on each motor: the energy put in is positive
//! let energy = traj.rows().energy(&arm);
//! assert!(energy[10] > energy[0]);
//! # Ok::<(), orbitflex::Error>(())
//! ```

use super::record::{check_record_every, recorded_rows};
use crate::error::{Error, Result};
use crate::flex::{FlexibleArm, StateLayout};

/// The bytes of a record of `rows` rows: `t`, `x` and the `rows - 1` inputs (`None` if it
/// overflows).
pub(crate) fn rows_bytes(layout: StateLayout, rows: usize) -> Option<usize> {
    let values = rows
        .checked_mul(layout.len() + 1)?
        .checked_add(rows.saturating_sub(1).checked_mul(layout.inputs_len())?)?;
    values.checked_mul(8)
}

/// The record of a run: times `t` (rows), states `x` (rows × (13+4n+k), row-major) and the
/// inputs held during the step that starts at each row but the last ((rows − 1) × (n + k),
/// row-major): the motor torques `u` (N·m), then, with `k` reaction wheels, the wheel torques
/// applied (after saturation, N·m).
///
/// A complete run of `steps` steps has `steps + 1` states and `steps` inputs; a run that failed at
/// step `k` keeps the `k + 1` states before the failure and the `k` inputs that produced them.
/// With `record_every = k > 1` ([`crate::integrate::simulate_into`]) it keeps rows `0, k, 2k, …`
/// and the final row (the last good state of a failed run), see [`super::record`].
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Times (s), one per state.
    pub t: Vec<f64>,
    /// States, one row per time.
    pub x: Vec<f64>,
    /// Held inputs, one row of `n + k` per kept row but the last: the motor torques, then the
    /// applied wheel torques, of the step starting there.
    pub u: Vec<f64>,
    /// The state layout (number of joints).
    pub layout: StateLayout,
}

impl Trajectory {
    /// An empty record for an arm with this layout.
    pub fn empty(layout: StateLayout) -> Self {
        Self {
            t: Vec::new(),
            x: Vec::new(),
            u: Vec::new(),
            layout,
        }
    }

    /// An empty record with room for the rows a run of `steps` steps keeps with `record_every`
    /// ([`recorded_rows`]), or a clear error naming `steps`, before anything is allocated, if it
    /// needs more memory than the system has available.
    pub fn reserved(layout: StateLayout, steps: usize, record_every: usize) -> Result<Self> {
        check_record_every(record_every)?;
        let rows = recorded_rows(steps, record_every);
        let mut traj = Trajectory::empty(layout);
        let bytes = rows_bytes(layout, rows);
        let available = crate::io::available_memory();
        let every = if record_every > 1 {
            format!(" (record_every = {record_every}: {rows} rows)")
        } else {
            String::new()
        };
        let too_big = || Error::InvalidArgument {
            what: "steps".into(),
            message: format!(
                "the record of {steps} steps{every} of a {}-element state needs {}, more than the \
                 {} of memory available; simulate in shorter pieces, keep fewer rows \
                 (record_every) or stream them",
                layout.len(),
                crate::args::describe_bytes(bytes),
                available.map_or("memory".into(), |a| crate::args::describe_bytes(Some(
                    a as usize
                )))
            ),
        };
        match (bytes, available) {
            (None, _) => return Err(too_big()),
            (Some(b), Some(a)) if b as u64 > a => return Err(too_big()),
            _ => {}
        }
        traj.t.try_reserve_exact(rows).map_err(|_| too_big())?;
        traj.x
            .try_reserve_exact(rows * layout.len())
            .map_err(|_| too_big())?;
        traj.u
            .try_reserve_exact((rows - 1) * layout.inputs_len())
            .map_err(|_| too_big())?;
        Ok(traj)
    }

    /// Number of stored states (`steps + 1` for a complete run).
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when no state is stored.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// State `k`.
    pub fn state(&self, k: usize) -> &[f64] {
        self.rows().row(k)
    }

    /// The states, with the diagnostics along them.
    pub fn rows(&self) -> StateRows<'_> {
        StateRows {
            layout: self.layout,
            x: &self.x,
        }
    }
}

/// Rows of states (row-major, `13 + 4n` numbers each), borrowed: a trajectory's, or any table of
/// states. The diagnostics run along them without checking them again; each returns one row per
/// state.
#[derive(Debug, Clone, Copy)]
pub struct StateRows<'a> {
    /// The layout of each row.
    pub layout: StateLayout,
    /// The rows, one after the other (a multiple of `layout.len()` numbers).
    pub x: &'a [f64],
}

impl<'a> StateRows<'a> {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.x.len() / self.layout.len()
    }

    /// True when there is no row.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row `k`.
    pub fn row(&self, k: usize) -> &'a [f64] {
        let len = self.layout.len();
        &self.x[k * len..(k + 1) * len]
    }

    /// The rows one by one.
    pub fn iter(&self) -> std::slice::ChunksExact<'a, f64> {
        self.x.chunks_exact(self.layout.len())
    }

    /// Joint deflection `θ − q` (rad), row-major `len × n`.
    pub fn deflection(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.len() * self.layout.n);
        for x in self.iter() {
            let s = self.layout.split(x);
            out.extend(s.theta.iter().zip(s.q).map(|(theta, q)| theta - q));
        }
        out
    }

    /// Spring torques `k (θ − q) + d (θ̇ − q̇)` (N·m), row-major `len × n`.
    pub fn spring_torque(&self, arm: &FlexibleArm) -> Vec<f64> {
        let n = self.layout.n;
        let mut out = vec![0.0; self.len() * n];
        if n > 0 {
            for (x, row) in self.iter().zip(out.chunks_exact_mut(n)) {
                arm.spring_torque(x, row);
            }
        }
        out
    }

    /// Momentum (model §6.1), row-major `len × 6`.
    pub fn momentum(&self, arm: &FlexibleArm) -> Vec<f64> {
        let mut ws = arm.workspace();
        self.iter().flat_map(|x| arm.momentum(&mut ws, x)).collect()
    }

    /// Energy (model §6.2), J.
    pub fn energy(&self, arm: &FlexibleArm) -> Vec<f64> {
        let mut ws = arm.workspace();
        self.iter().map(|x| arm.energy(&mut ws, x)).collect()
    }

    /// Every end-effector's pose `[p; quat]` in the inertial frame, row-major `len × k × 7`
    /// (`len × 7` on a chain), end-effectors in [`crate::Robot::ee_links`] order.
    pub fn ee_pose(&self, arm: &FlexibleArm) -> Vec<f64> {
        let k = arm.robot().end_effectors().len();
        self.iter()
            .flat_map(|x| (0..k).flat_map(move |e| arm.ee_pose(x, e)))
            .collect()
    }

    /// The inertial pose `[p (m); quat (x, y, z, w), w ≥ 0]` of every named frame
    /// ([`crate::Robot::frames`]) at every row, row-major `len × frames × 7`
    /// ([`crate::algorithms::frame_poses`]). `motor_side = None` poses the links at `q`;
    /// `Some(s)` poses them at `q + s (θ − q)`: the motor side for `s = 1`, the deflection
    /// exaggerated `s` times beyond it. One workspace for all rows.
    pub fn frame_poses(&self, arm: &FlexibleArm, motor_side: Option<f64>) -> Vec<f64> {
        let rows: Vec<usize> = (0..self.len()).collect();
        self.frame_poses_at(arm, motor_side, &rows)
    }

    /// [`frame_poses`](Self::frame_poses) at the given rows only, in their order,
    /// `rows.len() × frames × 7` (a viewer's decimated frames). Panics on a row out of range.
    pub fn frame_poses_at(
        &self,
        arm: &FlexibleArm,
        motor_side: Option<f64>,
        rows: &[usize],
    ) -> Vec<f64> {
        let robot = arm.robot();
        let width = 7 * robot.frames().len();
        let mut out = vec![0.0; rows.len() * width];
        let mut data = crate::algorithms::Data::new(robot);
        let mut angles = vec![0.0; self.layout.n];
        for (&row, out) in rows.iter().zip(out.chunks_exact_mut(width)) {
            let s = self.layout.split(self.row(row));
            let q = match motor_side {
                None => s.q,
                Some(scale) => {
                    for ((a, q), theta) in angles.iter_mut().zip(s.q).zip(s.theta) {
                        *a = q + scale * (theta - q);
                    }
                    &angles
                }
            };
            let mut base = [0.0; 7];
            base[..3].copy_from_slice(s.position);
            base[3..].copy_from_slice(s.quaternion);
            crate::algorithms::frame_poses_unchecked(robot, &mut data, &base, q, out);
        }
        out
    }
}

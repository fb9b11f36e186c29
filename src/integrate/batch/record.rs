//! The record of a batch: every run's rows in one buffer, its status and summaries
//! ([`BatchRecord`], [`RunRecord`]), and the recorder that fills one run's part of it.

use crate::error::{Error, Result};
use crate::flex::StateLayout;
use crate::integrate::record::{is_recorded, Recorder};
use crate::integrate::trajectory::Trajectory;

/// How one run of a batch ended.
#[derive(Debug, Clone, PartialEq)]
pub enum RunStatus {
    /// Every step was taken.
    Finished,
    /// The run stopped during step `step` (from `t = step dt`), as
    /// [`simulate`](crate::integrate::simulate()) would have raised it: a diverged state, a failed
    /// controller, or an interruption.
    Failed {
        /// The failing step `k`; state `k` is the last good one.
        step: usize,
        /// `k dt` (s).
        time: f64,
        /// Why, as the [`Error::Simulation`] of a single run says it.
        message: String,
    },
}

impl RunStatus {
    /// The failing step, or `None` for a finished run.
    pub fn failed_step(&self) -> Option<usize> {
        match self {
            RunStatus::Finished => None,
            RunStatus::Failed { step, .. } => Some(*step),
        }
    }
}

/// The record of a batch: rows of every run in one buffer, plus per-run summaries.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchRecord {
    /// Number of runs `B`.
    pub runs: usize,
    /// Rows per run ([`recorded_rows`](crate::integrate::recorded_rows); 0 without rows).
    pub rows: usize,
    /// Steps per run.
    pub steps: usize,
    /// Rows `0, k, 2k, …` and the final row were kept.
    pub record_every: usize,
    /// The state layout.
    pub layout: StateLayout,
    /// Times of the rows (s), shared by every run: `(rows,)`.
    pub t: Vec<f64>,
    /// States, `(B, rows, 13 + 4n)` row-major; NaN after a run's failure.
    pub x: Vec<f64>,
    /// Motor torques (N·m) held during the step that starts at each kept row but the last,
    /// `(B, rows − 1, n)`; NaN after a run's failure.
    pub u: Vec<f64>,
    /// The last state of each run (the last good one for a failed run), `(B, 13 + 4n)`.
    pub final_state: Vec<f64>,
    /// `max |θ_i − q_i|` (rad) over every state of the run (kept or not), `(B, n)`.
    pub peak_deflection: Vec<f64>,
    /// `max |u_i|` (N·m) over every step of the run (kept or not), `(B, n)`; 0 without steps.
    pub peak_torque: Vec<f64>,
    /// How each run ended.
    pub status: Vec<RunStatus>,
}

impl BatchRecord {
    /// Run `run` as the [`Trajectory`] that [`simulate`](crate::integrate::simulate()) with the same
    /// `record_every` returns for it ([`RunRecord::to_trajectory`]). `None` without rows
    /// ([`BatchSettings::keep_rows`](super::BatchSettings::keep_rows) false) or for a run out of range.
    pub fn run(&self, run: usize) -> Option<Trajectory> {
        if self.rows == 0 || run >= self.runs {
            return None;
        }
        let (len, n) = (self.layout.len(), self.layout.inputs_len());
        let record = RunRecord {
            layout: self.layout,
            record_every: self.record_every,
            t: &self.t,
            x: &self.x[run * self.rows * len..(run + 1) * self.rows * len],
            u: &self.u[run * (self.rows - 1) * n..(run + 1) * (self.rows - 1) * n],
            final_state: &self.final_state[run * len..(run + 1) * len],
            status: &self.status[run],
        };
        Some(record.to_trajectory())
    }
}

/// The part of a [`BatchRecord`] that belongs to one run (with rows), borrowed.
#[derive(Debug, Clone, Copy)]
pub struct RunRecord<'a> {
    /// The state layout.
    pub layout: StateLayout,
    /// The batch's `record_every`.
    pub record_every: usize,
    /// The times of the rows, `(rows,)`.
    pub t: &'a [f64],
    /// The run's rows, `(rows, 13 + 4n)`.
    pub x: &'a [f64],
    /// The run's inputs, `(rows − 1, n + k)`: motor torques, then applied wheel torques.
    pub u: &'a [f64],
    /// Its final state.
    pub final_state: &'a [f64],
    /// How it ended.
    pub status: &'a RunStatus,
}

impl RunRecord<'_> {
    /// The [`Trajectory`] that [`simulate`](crate::integrate::simulate()) with the same `record_every`
    /// returns for this run: its kept rows and, for a failed run, the trajectory of its
    /// [`SimulationFailure`](crate::integrate::SimulationFailure): the rows kept up to the failing step,
    /// ending on the last good state.
    pub fn to_trajectory(&self) -> Trajectory {
        let (len, n, every) = (
            self.layout.len(),
            self.layout.inputs_len(),
            self.record_every,
        );
        let mut traj = Trajectory::empty(self.layout);
        match self.status {
            RunStatus::Finished => {
                traj.t = self.t.to_vec();
                traj.x = self.x.to_vec();
                traj.u = self.u.to_vec();
            }
            RunStatus::Failed { step, time, .. } => {
                let kept = step / every + 1;
                traj.t = self.t[..kept].to_vec();
                traj.x = self.x[..kept * len].to_vec();
                if step % every != 0 {
                    traj.t.push(*time);
                    traj.x.extend_from_slice(self.final_state);
                }
                traj.u = self.u[..(traj.t.len() - 1) * n].to_vec();
            }
        }
        traj
    }
}

/// The part of the record that belongs to one run.
pub(super) struct Slot<'a> {
    pub(super) x: &'a mut [f64],
    pub(super) u: &'a mut [f64],
    pub(super) last: &'a mut [f64],
    pub(super) deflection: &'a mut [f64],
    pub(super) torque: &'a mut [f64],
}

/// Receives every row of a run (`record_every = 1`), keeps the rows of the batch's rule in its
/// slot and the summaries of all. The summaries and the last state are kept in buffers of its
/// own and written to the slot at [`Recorder::finish`]: written every step, they would share
/// cache lines with the neighbouring runs' (false sharing between threads).
pub(super) struct SlotRecorder<'a> {
    pub(super) slot: Slot<'a>,
    pub(super) deflection: Vec<f64>,
    pub(super) torque: Vec<f64>,
    pub(super) last: Vec<f64>,
    pub(super) layout: StateLayout,
    pub(super) steps: usize,
    pub(super) every: usize,
    pub(super) rows: usize,
    pub(super) keep: bool,
    pub(super) next: usize,
}

impl Recorder for SlotRecorder<'_> {
    fn state(&mut self, _t: f64, x: &[f64]) -> Result<()> {
        let row = self.next;
        self.next += 1;
        let (q, theta) = (&x[self.layout.q()], &x[self.layout.theta()]);
        for ((peak, q), theta) in self.deflection.iter_mut().zip(q).zip(theta) {
            *peak = peak.max((theta - q).abs());
        }
        self.last.copy_from_slice(x);
        if self.keep && is_recorded(row, self.steps, self.every) {
            let index = if row % self.every == 0 {
                row / self.every
            } else {
                self.rows - 1
            };
            let len = x.len();
            self.slot.x[index * len..(index + 1) * len].copy_from_slice(x);
        }
        Ok(())
    }

    fn input(&mut self, u: &[f64]) -> Result<()> {
        let row = self.next - 1;
        for (peak, u) in self.torque.iter_mut().zip(u) {
            *peak = peak.max(u.abs());
        }
        if self.keep && row % self.every == 0 {
            let index = row / self.every;
            let n = u.len();
            self.slot.u[index * n..(index + 1) * n].copy_from_slice(u);
        }
        Ok(())
    }

    fn finish(&mut self) -> Result<()> {
        self.slot.deflection.copy_from_slice(&self.deflection);
        self.slot.torque.copy_from_slice(&self.torque);
        self.slot.last.copy_from_slice(&self.last);
        Ok(())
    }
}

/// Splits `buffer` into `runs` consecutive pieces of `size` numbers (empty pieces when `size`
/// is 0).
pub(super) fn per_run(buffer: &mut [f64], runs: usize, size: usize) -> Vec<&mut [f64]> {
    if size == 0 {
        return (0..runs).map(|_| <&mut [f64]>::default()).collect();
    }
    buffer.chunks_mut(size).collect()
}

/// A zero-filled or NaN-filled buffer of `len` numbers, or a clear error naming `runs` when it
/// does not fit in memory.
pub(super) fn buffer(len: usize, fill: f64, too_big: &dyn Fn() -> Error) -> Result<Vec<f64>> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| too_big())?;
    v.resize(len, fill);
    Ok(v)
}

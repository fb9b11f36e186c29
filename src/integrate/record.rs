//! Which rows of a run are kept (`record_every`), and where they go: the [`Recorder`] trait, the
//! in-memory [`Trajectory`] and the streaming [`Chunks`].
//!
//! **The row rule.** A run of `steps` steps has `steps + 1` states, row `j` at `t = j dt`. With
//! `record_every = k` (k ≥ 1) it keeps rows `0, k, 2k, …` and always the final row `steps`
//! ([`is_recorded`]): `steps / k + 1` rows when `k` divides `steps`, `steps / k + 2` otherwise
//! ([`recorded_rows`]). Each kept row is bit for bit the row of the same index of a run with
//! `k = 1`, and its time is computed as `j as f64 * dt` as in that run.
//!
//! **Inputs.** Next to each kept row but the final one, the record holds the motor torques held
//! during the step that *starts* at that row (from `t = j dt` to `(j + 1) dt`). With `k = 1` this
//! is every step's torque; with `k > 1` the torques of the other steps are not kept (the input
//! at a kept row is a sample, not an average over the interval to the next kept row). So a record
//! of `r` rows always holds `r - 1` input rows.
//!
//! **A run that fails** at step `s` (state `s` is the last good one) keeps the rows kept so far
//! and, if row `s` was not one of them, state `s` as its final row; inputs as above. So the final
//! row of any record is the last state computed, complete run or not.
//!
//! ```
//! use orbitflex::integrate::record::{is_recorded, recorded_rows};
//! // 10 steps, every 4th row: rows 0, 4, 8 and the final row 10
//! let rows: Vec<usize> = (0..=10).filter(|&j| is_recorded(j, 10, 4)).collect();
//! assert_eq!(rows, [0, 4, 8, 10]);
//! assert_eq!(recorded_rows(10, 4), 4);
//! assert_eq!(recorded_rows(12, 4), 4); // 0, 4, 8, 12
//! ```

use super::trajectory::Trajectory;
use crate::error::{Error, Result};
use crate::flex::StateLayout;

/// Whether row `row` (the state at `t = row dt`) of a run of `steps` steps is kept with
/// `record_every = every`: a multiple of `every`, or the final row. `every` must be ≥ 1
/// ([`check_record_every`]).
#[inline]
pub fn is_recorded(row: usize, steps: usize, every: usize) -> bool {
    row % every == 0 || row == steps
}

/// How many rows a complete run of `steps` steps keeps with `record_every = every` (≥ 1):
/// `steps / every + 1`, plus one for the final row when `every` does not divide `steps`.
/// Saturates at `usize::MAX` (no such record fits in memory).
pub fn recorded_rows(steps: usize, every: usize) -> usize {
    (steps / every)
        .saturating_add(1)
        .saturating_add(usize::from(steps % every != 0))
}

/// `record_every` must be at least 1.
pub fn check_record_every(every: usize) -> Result<()> {
    if every == 0 {
        return Err(Error::InvalidArgument {
            what: "record_every".into(),
            message: "expected an integer >= 1 (1 keeps every row), given 0".into(),
        });
    }
    Ok(())
}

/// Where the kept rows of a run go ([`crate::integrate::simulate_into`]). The run calls, in
/// order: [`state`](Self::state) for row 0; then, for each kept row but the final one,
/// [`input`](Self::input) once the step starting at that row has succeeded, followed by
/// [`state`](Self::state) for the next kept row; finally [`finish`](Self::finish), whether the
/// run completed or failed (not if its arguments were refused before row 0). Calls alternate
/// `state, input, state, …, state`.
///
/// An error from any of them stops the run ([`Error::Simulation`] naming the step, with the
/// recorder's message); `finish` is then not called.
pub trait Recorder {
    /// A kept row: its time `t` (s) and state `x` (13 + 4n numbers).
    fn state(&mut self, t: f64, x: &[f64]) -> Result<()>;
    /// The inputs held during the step that starts at the last kept row: the motor torques `u`
    /// (N·m, link side; n numbers), then the wheel torques applied (k numbers, after
    /// saturation; none without wheels).
    fn input(&mut self, u: &[f64]) -> Result<()>;
    /// The run is over: deliver anything still buffered.
    fn finish(&mut self) -> Result<()> {
        Ok(())
    }
}

/// The in-memory record: every kept row is appended to `t`, `x` and `u`.
impl Recorder for Trajectory {
    fn state(&mut self, t: f64, x: &[f64]) -> Result<()> {
        self.t.push(t);
        self.x.extend_from_slice(x);
        Ok(())
    }
    fn input(&mut self, u: &[f64]) -> Result<()> {
        self.u.extend_from_slice(u);
        Ok(())
    }
}

/// Consecutive kept rows handed over by [`Chunks`]: `t` (r,), `x` (r × (13+4n), row-major) and
/// `u` (r' × n), `r' = r` except in the chunk that holds the final row, where `r' = r - 1` (no
/// step starts at the final row). Concatenating the chunks gives the [`Trajectory`] of the same
/// run without streaming.
#[derive(Debug, Clone, Copy)]
pub struct Chunk<'a> {
    /// Index of this chunk's first row among the kept rows (0 for the first chunk).
    pub first: usize,
    /// Times (s).
    pub t: &'a [f64],
    /// States, one row per time.
    pub x: &'a [f64],
    /// Motor torques (N·m) held during the step starting at each row.
    pub u: &'a [f64],
    /// Rows of `u`: `len()`, or `len() - 1` in the chunk that holds the final row.
    pub inputs: usize,
    /// The layout of a state row.
    pub layout: StateLayout,
}

impl Chunk<'_> {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True for a chunk without rows (never delivered).
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// A [`Recorder`] that streams the kept rows to `deliver` in [`Chunk`]s of at most `capacity`
/// rows, each row exactly once and in order, the last partial chunk at [`Recorder::finish`] (also
/// after a failure, so it holds the last good state). The buffers are allocated once, in
/// [`new`](Self::new), and reused: nothing is allocated per step or per chunk.
///
/// ```
/// use orbitflex::integrate::{record::Chunks, simulate_into, Drive, Run, Schedule, Unobserved, Wrenches};
/// use orbitflex::{FlexibleArm, FlexibleJoints, Robot};
/// let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
/// let (mut rows, mut peak) = (0, 0.0f64);
/// let mut sink = Chunks::new(arm.layout(), 64, |chunk| {
///     rows += chunk.len();
///     let q0 = arm.layout().q().start; // first link angle, rad
///     peak = chunk.x.chunks(arm.layout().len()).fold(peak, |p, x| p.max(x[q0].abs()));
///     Ok(())
/// })?;
/// let x0 = arm.rest_state();
/// let run = Run::new(&x0, 1e-3, 1000).recording_every(10);
/// let (mut u, mut wrenches) = (Schedule::Constant(vec![1.0; 7]), Wrenches::ZERO);
/// simulate_into(&arm, &run, &mut Drive::new(&mut u, &mut wrenches), &mut Unobserved, &mut sink)?;
/// drop(sink);
/// assert_eq!(rows, 101); // rows 0, 10, …, 1000
/// assert!(peak > 0.0);
/// # Ok::<(), orbitflex::Error>(())
/// ```
pub struct Chunks<F> {
    layout: StateLayout,
    capacity: usize,
    t: Vec<f64>,
    x: Vec<f64>,
    u: Vec<f64>,
    inputs: usize,
    delivered: usize,
    received: usize,
    deliver: F,
}

impl<F: FnMut(Chunk<'_>) -> Result<()>> Chunks<F> {
    /// Buffers for chunks of `capacity` ≥ 1 rows of states with this layout. An error names
    /// `chunk_rows` when `capacity` is 0 or the buffers do not fit in memory.
    pub fn new(layout: StateLayout, capacity: usize, deliver: F) -> Result<Self> {
        if capacity == 0 {
            return Err(Error::InvalidArgument {
                what: "chunk_rows".into(),
                message: "expected an integer >= 1, given 0".into(),
            });
        }
        let too_big = || Error::InvalidArgument {
            what: "chunk_rows".into(),
            message: format!(
                "a chunk of {capacity} rows of {} numbers does not fit in memory; give fewer rows",
                layout.len() + 1 + layout.inputs_len()
            ),
        };
        let mut t = Vec::new();
        let mut x = Vec::new();
        let mut u = Vec::new();
        t.try_reserve_exact(capacity).map_err(|_| too_big())?;
        x.try_reserve_exact(capacity.checked_mul(layout.len()).ok_or_else(too_big)?)
            .map_err(|_| too_big())?;
        u.try_reserve_exact(
            capacity
                .checked_mul(layout.inputs_len())
                .ok_or_else(too_big)?,
        )
        .map_err(|_| too_big())?;
        Ok(Self {
            layout,
            capacity,
            t,
            x,
            u,
            inputs: 0,
            delivered: 0,
            received: 0,
            deliver,
        })
    }

    /// The most rows a chunk holds.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Rows delivered so far.
    pub fn delivered(&self) -> usize {
        self.delivered
    }

    /// Rows received so far (delivered or buffered).
    pub fn received(&self) -> usize {
        self.received
    }

    fn flush(&mut self) -> Result<()> {
        if self.t.is_empty() {
            return Ok(());
        }
        let chunk = Chunk {
            first: self.delivered,
            t: &self.t,
            x: &self.x,
            u: &self.u,
            inputs: self.inputs,
            layout: self.layout,
        };
        let rows = chunk.len();
        (self.deliver)(chunk)?;
        self.delivered += rows;
        self.t.clear();
        self.x.clear();
        self.u.clear();
        self.inputs = 0;
        Ok(())
    }
}

impl<F: FnMut(Chunk<'_>) -> Result<()>> Recorder for Chunks<F> {
    fn state(&mut self, t: f64, x: &[f64]) -> Result<()> {
        // a full chunk was delivered by `input`; the final row of a run may open a new one
        self.t.push(t);
        self.x.extend_from_slice(x);
        self.received += 1;
        Ok(())
    }
    fn input(&mut self, u: &[f64]) -> Result<()> {
        self.u.extend_from_slice(u);
        self.inputs += 1;
        if self.t.len() == self.capacity {
            self.flush()?;
        }
        Ok(())
    }
    fn finish(&mut self) -> Result<()> {
        self.flush()
    }
}

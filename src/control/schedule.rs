//! [`Schedule`]: a per-step input of fixed width (zero, a constant, or a table), and the
//! [`Controller`](super::Controller) it is.

use super::controller::{Controller, Feedback};
use crate::args::{check_finite, check_vector};
use crate::error::{Error, Result};

/// A per-step input of fixed width: zero, a constant, or a table with one row per step
/// (row-major, `steps × width`). Held constant over each step (zero-order hold).
#[derive(Debug, Clone, PartialEq)]
pub enum Schedule {
    /// All zeros.
    Zero,
    /// The same row every step.
    Constant(Vec<f64>),
    /// Row `k` is used during step `k`; `rows × width`, row-major.
    Table {
        /// The rows, one after the other.
        values: Vec<f64>,
        /// The length of one row.
        width: usize,
    },
}

impl Schedule {
    /// Number of rows of a table (`None` for zero and constant schedules).
    pub fn rows(&self) -> Option<usize> {
        match self {
            Schedule::Table { values, width } => {
                Some(values.len().checked_div(*width).unwrap_or(0))
            }
            _ => None,
        }
    }

    /// Checks the width, the number of rows of a table against `steps` (if given: exactly
    /// `steps` rows), and that every value is finite.
    pub fn check(&self, what: &str, width: usize, steps: Option<usize>) -> Result<()> {
        match self {
            Schedule::Zero => Ok(()),
            Schedule::Constant(v) => check_vector(what, v, width),
            Schedule::Table { values, width: w } => {
                let rows = self.rows().unwrap_or(0);
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
                check_finite(what, values)
            }
        }
    }

    /// Checks that a table has at least `steps` rows (zero and constant schedules always do).
    pub fn check_covers(&self, what: &str, steps: usize) -> Result<()> {
        match self.rows() {
            Some(rows) if rows < steps => Err(Error::Dimension {
                what: what.to_string(),
                expected: format!("at least {steps} rows (one per step)"),
                given: format!("{rows} rows"),
            }),
            _ => Ok(()),
        }
    }

    /// Writes the row for `step` into `out` (a table must cover `step`).
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

impl Controller for Schedule {
    /// Row `step`; the width and the coverage are checked here (O(1)), the values once per run
    /// by [`Controller::check_run`].
    fn output(&mut self, step: usize, t: f64, x: &[f64], out: &mut [f64]) -> Result<()> {
        (&*self).output(step, t, x, out)
    }

    fn feedback(&self) -> Feedback<'_> {
        Feedback::None
    }

    fn check_run(&self, what: &str, width: usize, steps: usize) -> Result<()> {
        self.check(what, width, self.rows().map(|_| steps))
    }

    fn is_zero(&self) -> bool {
        matches!(self, Schedule::Zero)
    }
}

/// A shared schedule drives a channel as the schedule itself does (a run reads it, never changes
/// it): what [`Wrenches`](super::Wrenches) lends a run.
impl Controller for &Schedule {
    fn output(&mut self, step: usize, _t: f64, _x: &[f64], out: &mut [f64]) -> Result<()> {
        let width = match self {
            Schedule::Zero => out.len(),
            Schedule::Constant(v) => v.len(),
            Schedule::Table { width, .. } => *width,
        };
        crate::args::check_length("u", width, out.len())?;
        self.check_covers("u", step + 1)?;
        self.write(step, out);
        Ok(())
    }

    fn feedback(&self) -> Feedback<'_> {
        (**self).feedback()
    }

    fn check_run(&self, what: &str, width: usize, steps: usize) -> Result<()> {
        (**self).check_run(what, width, steps)
    }

    fn is_zero(&self) -> bool {
        (**self).is_zero()
    }
}

//! The modes of the arm across many states at once (a Campbell diagram's data), in parallel over
//! a rayon pool.

use super::linear::LinearSpec;
use super::modes::{modes, Modes};
use crate::error::{Error, Result};
use crate::flex::FlexibleArm;
use rayon::prelude::*;

/// [`modes`] at each state of `states` (row-major, `13 + 4n` per row), on `threads` threads
/// (`None`: every core), each with its own workspace; one result per state, in order. A state
/// whose modes fail gives its error in its row; the others are unaffected.
///
/// ```
/// use orbitflex::analysis::{sweep, LinearSpec};
/// use orbitflex::{FlexibleArm, FlexibleJoints, Robot, StateSpec};
/// let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
/// let mut states = Vec::new();
/// for elbow in [0.0, 0.5, 1.0] {
///     let q = [0.0, 0.0, 0.0, elbow, 0.0, 0.0, 0.0];
///     states.extend(arm.state(&StateSpec { q: Some(&q), ..StateSpec::default() })?);
/// }
/// let rows = sweep(&arm, &states, &LinearSpec::default(), true, Some(1))?;
/// assert_eq!(rows.len(), 3);
/// assert!(rows.iter().all(|m| m.as_ref().unwrap().frequency_hz.len() == 7));
/// # Ok::<(), orbitflex::Error>(())
/// ```
pub fn sweep(
    arm: &FlexibleArm,
    states: &[f64],
    spec: &LinearSpec,
    damped: bool,
    threads: Option<usize>,
) -> Result<Vec<Result<Modes>>> {
    let width = arm.layout().len();
    if states.len() % width != 0 {
        return Err(Error::Dimension {
            what: "states".into(),
            expected: format!("rows of {width} numbers (13 + 4n)"),
            given: format!("{} numbers", states.len()),
        });
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()
        .map_err(|e| Error::InvalidArgument {
            what: "threads".into(),
            message: format!("cannot start the thread pool: {e}"),
        })?;
    Ok(pool.install(|| {
        states
            .par_chunks(width)
            .map_init(|| arm.workspace(), |ws, x| modes(arm, ws, x, spec, damped))
            .collect()
    }))
}

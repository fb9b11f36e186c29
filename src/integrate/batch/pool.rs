//! The pool of threads a batch runs on, and how a batch is stopped.

use crate::error::{Error, Result};
use crate::integrate::simulate::Observer;
use std::sync::atomic::{AtomicBool, Ordering};

/// The most threads a batch starts: more only spends time and memory starting them (20,000
/// threads once took over a minute to start, three pools per batch).
pub const MAX_THREADS: usize = 1024;

/// Runs `work` on a pool of `threads` threads (`None`: every core; at most [`MAX_THREADS`]).
pub fn in_pool<R: Send>(threads: Option<usize>, work: impl FnOnce() -> R + Send) -> Result<R> {
    let threads = threads.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    if threads == 0 || threads > MAX_THREADS {
        return Err(Error::InvalidArgument {
            what: "threads".into(),
            message: format!(
                "expected an integer from 1 to {MAX_THREADS} (or None for every core), given \
                 {threads}"
            ),
        });
    }
    // a pool even for one thread: the parallel iterators inside would otherwise run on rayon's
    // global pool, on every core
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("orbitflex-batch-{i}"))
        .build()
        .map_err(|e| Error::InvalidArgument {
            what: "threads".into(),
            message: format!("could not start {threads} threads: {e}"),
        })?;
    Ok(pool.install(work))
}

/// `Err(Error::Interrupted)` once `cancel` is set.
pub(super) fn interrupted(cancel: &AtomicBool, what: &str) -> Result<()> {
    match cancel.load(Ordering::Relaxed) {
        true => Err(Error::Interrupted { what: what.into() }),
        false => Ok(()),
    }
}

/// Stops a run when the batch is cancelled.
/// An observer that stops a run once its flag is set (checked every 16 steps).
pub struct Cancel<'a>(pub &'a AtomicBool);

impl Observer for Cancel<'_> {
    /// An atomic load every few steps, so that a run of a large model (a millisecond a step)
    /// stops within milliseconds.
    fn every(&self) -> usize {
        16
    }
    fn observe(&mut self, _: usize, _: usize) -> bool {
        !self.0.load(Ordering::Relaxed)
    }
}

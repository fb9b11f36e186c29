//! The rows of a batched call computed in parallel without the GIL, the calling thread among
//! the workers, stopping within [`SIGNAL_CHECK`] of Ctrl-C.
//!
//! Only the main thread can see a Python signal (`PyErr_CheckSignals` does nothing elsewhere),
//! so the calling thread must look for it while the rows are computed. Handing the rows to
//! rayon and waiting with a timeout costs two thread wake-ups per call (about 30 µs on a
//! virtual machine, more than a 4-row call takes), so instead the calling thread computes pieces
//! of rows itself, as rayon's threads do, and looks at the clock every few rows (as many as take
//! about 20 µs): every [`SIGNAL_CHECK`] it takes the GIL and looks for signals. A signal sets a
//! flag that every thread reads before each row.

use super::run::SIGNAL_CHECK;
use crate::algorithms::Data;
use crate::model::Robot;
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use super::workspaces::Pool;

/// The most rows in one piece: the calling thread looks at the clock between rows, but waits
/// for the other threads' last pieces at the end.
const MAX_PIECE_ROWS: usize = 256;

/// Work of about this long between two looks at the clock.
const CLOCK_WORK: Duration = Duration::from_micros(20);

/// Counts a piece as finished when dropped, and wakes the calling thread after the last one.
struct Finished<'a> {
    finished: &'a AtomicUsize,
    count: usize,
    caller: &'a std::thread::Thread,
}

impl Drop for Finished<'_> {
    fn drop(&mut self) {
        if self.finished.fetch_add(1, Ordering::AcqRel) + 1 == self.count {
            self.caller.unpark();
        }
    }
}

/// What the calling thread sees of the clock and the signals while it computes rows.
struct Lookout<'a> {
    cancel: &'a AtomicBool,
    raised: Option<PyErr>,
    /// When the signals were last looked at.
    last: Instant,
    /// Rows between two looks at the clock (measured on the first row), and rows since the
    /// last look.
    every: Option<usize>,
    since: usize,
}

impl Lookout<'_> {
    /// After each row the calling thread computed.
    fn row_done(&mut self) {
        let every = *self.every.get_or_insert_with(|| {
            // the first row, since the lookout was made just before it
            let row = self.last.elapsed().as_secs_f64().max(1e-9);
            ((CLOCK_WORK.as_secs_f64() / row) as usize).clamp(1, 64)
        });
        self.since += 1;
        if self.since >= every {
            self.since = 0;
            self.look();
        }
    }

    /// Looks for signals if [`SIGNAL_CHECK`] has passed; a pending one cancels the rows.
    fn look(&mut self) {
        if self.raised.is_some() || self.last.elapsed() < SIGNAL_CHECK {
            return;
        }
        self.last = Instant::now();
        Python::with_gil(|py| {
            if let Err(e) = py.check_signals() {
                self.raised = Some(e);
                self.cancel.store(true, Ordering::Relaxed);
            }
        });
    }
}

/// One row of a batched call: `f(data, row, out_row)`.
pub(crate) type RowFn<'a> = dyn Fn(&mut Data, usize, &mut [f64]) -> crate::Result<()> + Sync + 'a;

/// The rows of a batched call cut into pieces that the threads claim in turn, and what the
/// threads share: the next piece to claim, how many have finished, the cancel flag and the
/// first failure.
struct Pieces<'v> {
    pieces: Vec<Mutex<&'v mut [f64]>>,
    per_piece: usize,
    width: usize,
    next: AtomicUsize,
    finished: AtomicUsize,
    cancel: AtomicBool,
    /// The lowest piece with a failing row.
    failed_piece: AtomicUsize,
    /// The lowest failing row and its error.
    failure: Mutex<Option<(usize, crate::Error)>>,
}

impl<'v> Pieces<'v> {
    /// `values` (rows of `width` numbers) in pieces of `per_piece` rows.
    fn new(values: &'v mut [f64], width: usize, per_piece: usize) -> Self {
        Self {
            pieces: values
                .chunks_mut(per_piece * width)
                .map(Mutex::new)
                .collect(),
            per_piece,
            width,
            next: AtomicUsize::new(0),
            finished: AtomicUsize::new(0),
            cancel: AtomicBool::new(false),
            failed_piece: AtomicUsize::new(usize::MAX),
            failure: Mutex::new(None),
        }
    }

    fn count(&self) -> usize {
        self.pieces.len()
    }

    /// Claims pieces until none is left and computes their rows with `f` in `data`; `lookout`
    /// is the calling thread's. A piece counts as finished when it ends, even by a panic (which
    /// the scope then raises): the calling thread waits for every piece to finish.
    fn work(
        &self,
        data: &mut Data,
        f: &RowFn<'_>,
        caller: &std::thread::Thread,
        mut lookout: Option<&mut Lookout<'_>>,
    ) {
        let count = self.count();
        loop {
            let p = self.next.fetch_add(1, Ordering::Relaxed);
            if p >= count {
                break;
            }
            let _done = Finished {
                finished: &self.finished,
                count,
                caller,
            };
            if p < self.failed_piece.load(Ordering::Relaxed) {
                self.piece(p, data, f, lookout.as_deref_mut());
            }
        }
    }

    /// The rows of piece `p`, until one fails or the rows are cancelled.
    fn piece(
        &self,
        p: usize,
        data: &mut Data,
        f: &RowFn<'_>,
        mut lookout: Option<&mut Lookout<'_>>,
    ) {
        let mut block = self.pieces[p].lock().unwrap_or_else(|e| e.into_inner());
        for (k, out) in block.chunks_exact_mut(self.width).enumerate() {
            if self.cancel.load(Ordering::Relaxed) {
                break;
            }
            let row = p * self.per_piece + k;
            if let Err(e) = f(data, row, out) {
                self.failed_piece.fetch_min(p, Ordering::Relaxed);
                let mut first = self.failure.lock().unwrap_or_else(|e| e.into_inner());
                if first.as_ref().map_or(true, |(r, _)| row < *r) {
                    *first = Some((row, e.in_context(&format!("row {row}"))));
                }
                break;
            }
            if let Some(lookout) = lookout.as_deref_mut() {
                lookout.row_done();
            }
        }
    }
}

/// Computes `f(data, row, out_row)` for every row of `values` (rows of `width` numbers,
/// row-major) on rayon's global pool and the calling thread, without the GIL, each thread with
/// a workspace from `workspaces`. Returns the error of the lowest failing row (naming the row),
/// or the pending Python exception (`KeyboardInterrupt`) when a signal came.
pub(crate) fn compute_rows(
    py: Python<'_>,
    robot: &Robot,
    workspaces: &Pool<Data>,
    values: &mut [f64],
    width: usize,
    f: &RowFn<'_>,
) -> PyResult<()> {
    if values.is_empty() || width == 0 {
        return Ok(());
    }
    let rows = values.len() / width;
    let threads = rayon::current_num_threads();
    let per_piece = rows.div_ceil(4 * threads).clamp(1, MAX_PIECE_ROWS);
    let pieces = Pieces::new(values, width, per_piece);
    let count = pieces.count();
    let caller = std::thread::current();
    let work = |lookout: Option<&mut Lookout<'_>>| {
        let mut data = workspaces.take(|| Data::new(robot));
        pieces.work(&mut data, f, &caller, lookout);
    };
    let mut lookout = Lookout {
        cancel: &pieces.cancel,
        raised: None,
        last: Instant::now(),
        every: None,
        since: 0,
    };
    py.allow_threads(|| {
        rayon::in_place_scope(|scope| {
            for _ in 1..threads.min(count) {
                scope.spawn(|_| work(None));
            }
            work(Some(&mut lookout));
            // the other threads' last pieces
            while pieces.finished.load(Ordering::Acquire) < count {
                std::thread::park_timeout(SIGNAL_CHECK);
                lookout.look();
            }
        })
    });
    if let Some(e) = lookout.raised {
        return Err(e);
    }
    match pieces
        .failure
        .into_inner()
        .unwrap_or_else(|e| e.into_inner())
    {
        Some((_, e)) => Err(e.into()),
        None => Ok(()),
    }
}

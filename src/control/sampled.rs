//! [`Sampled`]: any controller run at its own rate, as flight software runs, with zero-order
//! hold between samples and a delay of whole samples; the dynamics keep their RK4 step.
//!
//! Sample `j` is due at `t_j = j / rate_hz`. It is taken at the first step whose start time
//! `t = k dt` is at or after `t_j` (within 1e-9 of the period, so that `k dt` rounding below a
//! whole multiple of the period does not slip a step): the wrapped controller is asked for its
//! row there, from that step's `(k, t, x)`. With `delay = d` the row computed at sample `j` is
//! applied from sample `j + d` on (zero until the first one arrives), and between samples the
//! applied row is held. When the period is a whole number `m` of steps, samples fall on steps
//! `0, m, 2m, …` exactly: the run equals the same run driven by the hand-held table.

use super::controller::{Controller, Feedback};
use crate::error::{Error, Result};

/// A controller sampled at `rate_hz` with a delay of `delay` samples: sample `j` is taken at the
/// first step starting at or after `j / rate_hz` (to 1e-9 of the period), its row applied from
/// sample `j + delay` on (zero before), held between samples.
pub struct Sampled<'a> {
    inner: Box<dyn Controller + Send + 'a>,
    rate_hz: f64,
    delay: usize,
    /// The next sample's index `j`.
    next: usize,
    /// The row applied now.
    held: Vec<f64>,
    /// The rows computed and not yet applied, oldest first (a ring of `delay` rows).
    queue: Vec<f64>,
    /// Where the oldest queued row starts, and how many rows are queued.
    head: usize,
    queued: usize,
    /// The row the wrapped controller writes at a sample.
    fresh: Vec<f64>,
}

impl<'a> Sampled<'a> {
    /// `inner` sampled at `rate_hz` (finite, > 0) with `delay` whole samples of delay.
    pub fn new(inner: Box<dyn Controller + Send + 'a>, rate_hz: f64, delay: usize) -> Result<Self> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(Error::InvalidArgument {
                what: "rate_hz".into(),
                message: format!("expected a finite rate > 0 (Hz), given {rate_hz}"),
            });
        }
        Ok(Self {
            inner,
            rate_hz,
            delay,
            next: 0,
            held: Vec::new(),
            queue: Vec::new(),
            head: 0,
            queued: 0,
            fresh: Vec::new(),
        })
    }

    /// The sample rate (Hz).
    pub fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// The delay (whole samples).
    pub fn delay(&self) -> usize {
        self.delay
    }

    /// The number of RK4 steps of `dt` per sample when the period is a whole number of them
    /// (to 1e-9), else `None`.
    pub fn steps_per_sample(&self, dt: f64) -> Option<usize> {
        let ratio = 1.0 / (self.rate_hz * dt);
        let m = ratio.round();
        ((ratio - m).abs() <= 1e-9 * ratio && m >= 1.0).then_some(m as usize)
    }

    /// Whether a sample is due at time `t` (s).
    #[inline]
    fn due(&self, t: f64) -> bool {
        t * self.rate_hz >= self.next as f64 - 1e-9
    }

    fn reset(&mut self, width: usize) {
        self.next = 0;
        self.held.clear();
        self.held.resize(width, 0.0);
        self.fresh.clear();
        self.fresh.resize(width, 0.0);
        self.queue.clear();
        self.queue.resize(self.delay * width, 0.0);
        self.head = 0;
        self.queued = 0;
    }
}

impl Controller for Sampled<'_> {
    fn output(&mut self, step: usize, t: f64, x: &[f64], out: &mut [f64]) -> Result<()> {
        let width = out.len();
        if step == 0 || self.held.len() != width {
            self.reset(width);
        }
        if self.due(t) {
            self.inner.output(step, t, x, &mut self.fresh)?;
            // the next sample after t (several periods may fit in one step)
            self.next = (t * self.rate_hz + 1e-9).floor() as usize + 1;
            if self.delay == 0 {
                self.held.copy_from_slice(&self.fresh);
            } else {
                let d = self.delay;
                if self.queued == d {
                    // the oldest row arrives; the fresh one takes its place at the back
                    let slot = self.head * width;
                    self.held.copy_from_slice(&self.queue[slot..slot + width]);
                    self.queue[slot..slot + width].copy_from_slice(&self.fresh);
                    self.head = (self.head + 1) % d;
                } else {
                    let slot = ((self.head + self.queued) % d) * width;
                    self.queue[slot..slot + width].copy_from_slice(&self.fresh);
                    self.queued += 1;
                }
            }
        }
        out.copy_from_slice(&self.held);
        Ok(())
    }

    /// Unknown: a sampled, delayed loop is not the per-step closed loop that
    /// [`Feedback::MotorPd`] describes, so the stability limit falls back to the open loop and
    /// says so (see [`Sampled::steps_per_sample`] for the period in steps).
    fn feedback(&self) -> Feedback<'_> {
        Feedback::Unknown
    }

    fn check_run(&self, what: &str, width: usize, steps: usize) -> Result<()> {
        self.inner.check_run(what, width, steps)
    }

    fn is_zero(&self) -> bool {
        self.inner.is_zero()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::Schedule;

    /// A table of rows 1, 2, 3, … sampled every 3 steps with a delay of 2 samples.
    #[test]
    fn holds_and_delays_whole_samples() {
        let values: Vec<f64> = (1..13).map(f64::from).collect();
        let table = Schedule::Table { values, width: 1 };
        let mut s = Sampled::new(Box::new(table), 1.0 / 0.003, 2).unwrap();
        let dt = 1e-3;
        assert_eq!(s.steps_per_sample(dt), Some(3));
        let mut got = Vec::new();
        for k in 0..12 {
            let mut out = [f64::NAN];
            s.output(k, k as f64 * dt, &[], &mut out).unwrap();
            got.push(out[0]);
        }
        // samples at steps 0, 3, 6, 9 read 1, 4, 7, 10; each applied two samples later, zero
        // before the first arrives
        assert_eq!(got, [0., 0., 0., 0., 0., 0., 1., 1., 1., 4., 4., 4.]);
        let mut none = Sampled::new(Box::new(Schedule::Zero), 0.0, 0);
        assert!(none.is_err());
        none = Sampled::new(Box::new(Schedule::Zero), 30.0, 0);
        assert_eq!(none.unwrap().steps_per_sample(dt), None);
    }
}
